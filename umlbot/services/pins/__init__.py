"""The connections of the two GPIO libraries, shared by the drivers of one process:
`umlbot.services.pins.pigpio` (the pigpio daemon) and `umlbot.services.pins.lgpio` (gpiochip)."""
