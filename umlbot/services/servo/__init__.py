"""The servo service: hobby servos (angle in degrees) served over the bus."""

from umlbot.services.servo.driver import Servo, ServoSettings

__all__ = ["Servo", "ServoSettings"]
