"""The gpio service: the system component's `readPin`/`writePin` on the pins the deployment allows."""

from umlbot.services.gpio.driver import GpioPins, GpioSettings, PinNotAllowed

__all__ = ["GpioPins", "GpioSettings", "PinNotAllowed"]
