"""The motor service: L298N H-bridge channels driven over the bus (feature names from the library)."""

from umlbot.services.motor.driver import L298NSettings, MotorChannel

__all__ = ["L298NSettings", "MotorChannel"]
