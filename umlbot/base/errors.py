"""The one exception hierarchy of umlbot.

Every error the project raises derives from `UmlbotError`; each subclass also inherits the builtin
exception it resembles, so `except TimeoutError` still catches a `CallTimeout`. Errors carry their
details as fields, not only in the message.
"""

from __future__ import annotations


class UmlbotError(Exception):
    """Root of every error raised by umlbot."""


class ConfigError(UmlbotError, ValueError):
    """A setting, argument or file given by the user is wrong (bad broker URL, bad deployment)."""


class ModelError(UmlbotError, ValueError):
    """A problem in a model source file, with its position (1-based line and column)."""

    def __init__(self, message: str, file: str = "<model>", line: int = 1, column: int = 1) -> None:
        super().__init__(f"{file}:{line}:{column}: {message}")
        self.message = message
        self.file = file
        self.line = line
        self.column = column


class CompiledModelError(UmlbotError, ValueError):
    """A compiled model file cannot be loaded (corrupt, or written by a newer format version)."""


class BusError(UmlbotError):
    """Root of the MQTT bus errors."""


class NotConnected(BusError, ConnectionError):
    """The bus has no connection to the broker right now."""


class CallTimeout(BusError, TimeoutError):
    """No reply arrived within the call's time-out."""

    def __init__(self, component: str, feature: str, timeout_s: float) -> None:
        super().__init__(f"no reply from {component}.{feature} within {timeout_s:g} s")
        self.component = component
        self.feature = feature
        self.timeout_s = timeout_s


class BrokerRefused(BusError, PermissionError):
    """The broker refused a publish or a subscription with an MQTT 5 reason code (e.g. its ACL).

    MQTT 3.1.1 has no such answer: there a refused publish is dropped without a word.
    """

    def __init__(self, what: str, reason: str) -> None:
        super().__init__(f"the broker refused {what}: {reason}")
        self.what = what
        self.reason = reason


class LoginRefused(BrokerRefused, NotConnected):
    """The broker refused the connection's login (CONNACK: bad user name or password, not
    authorised, banned): trying again with the same credentials cannot help."""

    def __init__(self, broker: str, username: str | None, reason: str) -> None:
        who = f"of user {username!r}" if username is not None else "without a user (anonymous)"
        BusError.__init__(self, f"the MQTT broker at {broker} refused the login {who}: {reason} "
                                "(check the user name and password in the broker URL)")
        self.what = "the login"
        self.reason = reason
        self.broker = broker
        self.username = username


class RemoteError(BusError):
    """The service answered a call with an error reply; `code` is the stable slug."""

    def __init__(self, code: str, message: str, component: str = "", feature: str = "") -> None:
        where = f"{component}.{feature}: " if component else ""
        super().__init__(f"{where}{code}: {message}")
        self.code = code
        self.message = message
        self.component = component
        self.feature = feature


class ArgumentError(UmlbotError, ValueError):
    """An argument a feature does not take: `code` is the wire's error code (`bad_args`,
    `out_of_range`), `message` says which argument and why."""

    def __init__(self, code: str, message: str) -> None:
        super().__init__(f"{code}: {message}")
        self.code = code
        self.message = message


class DriverError(UmlbotError, RuntimeError):
    """A hardware driver failed (pigpio daemon unreachable, pin refused, no echo)."""


class UnknownDriver(ConfigError):
    """A driver name that no registry entry knows."""


class OrchestratorError(UmlbotError, RuntimeError):
    """The orchestrator stopped the robot because of a fault (time-out, error reply, offline)."""


class SimError(UmlbotError, RuntimeError):
    """The simulator could not start or run (bad track file, world unreachable)."""


class MissingExtra(UmlbotError, ImportError):
    """An optional part of umlbot is used but its extra is not installed (`pip install umlbot[X]`)."""

    def __init__(self, module: str, extra: str, what: str) -> None:
        super().__init__(f"{what} need the Python package {module.split('.')[0]!r}, which is not "
                         f"installed: pip install 'umlbot[{extra}]'")
        self.module = module
        self.extra = extra
        self.what = what
