"""The sonar service: HC-SR04 ultrasonic range finders served over the bus."""

from umlbot.services.sonar.driver import DistanceSensor, HCSR04Settings

__all__ = ["DistanceSensor", "HCSR04Settings"]
