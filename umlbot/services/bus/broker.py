"""The embedded MQTT broker: amqtt in a background thread with its own event loop.

`umlbot broker` runs it in the foreground; `umlbot sim` runs it in-process beside the services.
It binds to loopback unless told otherwise. With a password file, anonymous clients are refused
(amqtt's FileAuthPlugin); with an ACL file, each user may subscribe (`acl`) and publish
(`publish_acl`) only to the listed topic filters (amqtt's TopicAccessControlListPlugin).
"""

from __future__ import annotations

import asyncio
import contextlib
import errno
import ipaddress
import socket
import threading
import warnings
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from pydantic import BaseModel, ConfigDict, Field, ValidationError

from umlbot.base.errors import ConfigError
from umlbot.base.files import load_yaml_node, read_text, validation_problem, where
from umlbot.base.logs import get_logger
from umlbot.services.bus.broker_limits import BrokerLimits as BrokerLimits

log = get_logger(__name__)


class BrokerAcl(BaseModel):
    """Per-user topic filters: `acl` limits subscriptions, `publish_acl` limits publishing.

    amqtt 0.12 accepts exactly these two keys; the user `anonymous` stands for clients without a
    user name. A user missing from a table may do nothing of that kind.
    """

    model_config = ConfigDict(extra="forbid")

    acl: dict[str, list[str]] = Field(default_factory=dict)
    publish_acl: dict[str, list[str]] = Field(default_factory=dict)


def load_acl(path: str | Path) -> BrokerAcl:
    """Read an ACL file (YAML or JSON with the keys `acl` and `publish_acl`)."""
    from umlbot.base.yamlsrc import to_python

    file = Path(path)
    root = load_yaml_node(read_text(file, "ACL file"), str(file))
    data = to_python(root)
    if data is not None and not isinstance(data, dict):
        raise ConfigError(f"{where(str(file), root)}: invalid ACL file: a mapping with the keys acl and "
                          "publish_acl, each user's topic filters a list")
    try:
        acl = BrokerAcl.model_validate(data or {})
    except ValidationError as exc:
        errors = exc.errors()
        message = validation_problem(errors, str(file), root, "invalid ACL file")
        if errors[0]["type"] == "extra_forbidden":
            message += " (allowed keys: acl, publish_acl)"
        elif errors[0]["type"] == "list_type":
            message += " (each user's topic filters are a list, e.g. robot: ['umlbot/#'])"
        raise ConfigError(message) from exc
    if not acl.acl:
        # amqtt treats a missing or empty `acl` as "nobody may subscribe to anything"
        raise ConfigError(
            f"ACL file {file}: `acl` is missing or empty, so no client could subscribe to anything; "
            "list each user's topic filters, e.g. acl: {robot: ['umlbot/#']}"
        )
    return acl


def password_line(user: str, password: str) -> str:
    """A line for the broker's password file: `user:<argon2 hash>`."""
    from pwdlib import PasswordHash
    from pwdlib.hashers.argon2 import Argon2Hasher

    return f"{check_user_name(user)}:{PasswordHash((Argon2Hasher(),)).hash(password)}"


def check_user_name(user: str) -> str:
    """`user` if it can be a password-file user name; ConfigError otherwise."""
    if not user or ":" in user:
        raise ConfigError(f"user name {user!r}: a user name must be non-empty and contain no ':'")
    return user


def check_password_file(path: Path) -> None:
    """Raise ConfigError naming the file (and line) unless it is a readable `user:hash` file.

    amqtt reports every problem with this file as "Plugin init failed", which says neither what
    nor where.
    """
    if not path.is_file():
        raise ConfigError(f"password file {path} does not exist")
    for lineno, raw in enumerate(read_text(path, "password file").splitlines(), start=1):
        line = raw.strip()
        if line and not line.startswith("#") and not line.partition(":")[2]:
            raise ConfigError(f"password file {path}:{lineno}: expected 'user:<argon2 hash>' "
                              "(umlbot broker --hash-password USER prints one)")


def broker_config(
    host: str, port: int, passwd_file: str | Path | None = None, acl: BrokerAcl | None = None
) -> dict[str, Any]:
    """The amqtt 0.12 configuration dictionary for one TCP listener and our plugins."""
    plugins: dict[str, Any] = {}
    if passwd_file is None:
        plugins["amqtt.plugins.authentication.AnonymousAuthPlugin"] = {"allow_anonymous": True}
    else:
        plugins["amqtt.plugins.authentication.FileAuthPlugin"] = {"password_file": str(passwd_file)}
    if acl is not None:
        plugins["amqtt.plugins.topic_checking.TopicAccessControlListPlugin"] = {
            "acl": acl.acl,
            "publish_acl": acl.publish_acl,
        }
    return {
        "listeners": {"default": {"type": "tcp", "bind": f"{host}:{port}", "max_connections": 0}},
        "timeout_disconnect_delay": 0,
        "plugins": plugins,
    }


def is_loopback(host: str) -> bool:
    """Whether `host` (an address or a name) reaches this machine only."""
    if host in ("", "0.0.0.0", "::"):  # noqa: S104
        return False
    try:
        return ipaddress.ip_address(host).is_loopback
    except ValueError:
        pass
    try:
        infos = socket.getaddrinfo(host, None)
    except OSError:
        return False
    addresses = {str(info[4][0]).split("%")[0] for info in infos}
    return bool(addresses) and all(ipaddress.ip_address(address).is_loopback for address in addresses)


def _check_port_free(host: str, port: int) -> None:
    """Raise ConfigError naming the port when something already listens there."""
    family = socket.AF_INET6 if ":" in host else socket.AF_INET
    with socket.socket(family, socket.SOCK_STREAM) as probe:
        probe.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        try:
            probe.bind((host, port))
        except OSError as exc:
            if exc.errno == errno.EADDRINUSE:
                raise ConfigError(
                    f"port {port} on {host} is already in use (another MQTT broker?); "
                    f"choose another with --port, or use that broker with --broker mqtt://{host}:{port}"
                ) from exc
            raise ConfigError(f"cannot listen on {host}:{port}: {exc.strerror or exc}") from exc


class EmbeddedBroker:
    """An amqtt broker running on its own thread and event loop; `start()` returns once it listens.

    Safe to use as a context manager; `stop()` is idempotent.
    """

    def __init__(
        self,
        host: str = "127.0.0.1",
        port: int = 1883,
        passwd_file: str | Path | None = None,
        acl: BrokerAcl | Mapping[str, Any] | str | Path | None = None,
        limits: BrokerLimits | None = None,
    ) -> None:
        self.host = host
        self.limits = limits or BrokerLimits()
        self.port = port
        self.passwd_file = Path(passwd_file) if passwd_file is not None else None
        if acl is None or isinstance(acl, BrokerAcl):
            self.acl = acl
        elif isinstance(acl, str | Path):
            self.acl = load_acl(acl)
        else:
            self.acl = BrokerAcl.model_validate(dict(acl))
        self._loop: asyncio.AbstractEventLoop | None = None
        self._thread: threading.Thread | None = None
        self._broker: Any = None
        self._started = threading.Event()
        self._start_error: BaseException | None = None

    @property
    def url(self) -> str:
        """The `mqtt://host:port` URL clients use to reach this broker."""
        host = "127.0.0.1" if self.host in ("0.0.0.0", "") else self.host  # noqa: S104
        return f"mqtt://{host}:{self.port}"

    @property
    def listening_on(self) -> list[str]:
        """The `host:port` addresses the broker's sockets are bound to (empty before `start()`)."""
        server = getattr(self._broker, "_servers", {}).get("default")
        addresses = []
        for sock in getattr(getattr(server, "instance", None), "sockets", None) or ():
            host, port = sock.getsockname()[:2]
            addresses.append(f"[{host}]:{port}" if ":" in host else f"{host}:{port}")
        return addresses

    def exposure(self) -> str | None:
        """A warning when clients on other hosts can reach this broker unchecked, else None."""
        if is_loopback(self.host):
            return None
        if self.passwd_file is None:
            return (f"the broker listens on {self.host}, reachable from other hosts, and has no users: "
                    "anyone on the network can publish and subscribe, and so drive the motors; give it "
                    "--passwd and --acl (docs/security.md), or listen on 127.0.0.1")
        if self.acl is None:
            return (f"the broker listens on {self.host}, reachable from other hosts, without an ACL: "
                    "every user may publish and subscribe to every topic (drive the motors); give it "
                    "--acl (docs/security.md)")
        return None

    @property
    def running(self) -> bool:
        """True between a successful `start()` and `stop()`."""
        return self._thread is not None and self._started.is_set() and self._start_error is None

    def start(self, timeout: float = 10.0) -> None:
        """Start listening; raise ConfigError for a taken port or a bad password file."""
        if self._thread is not None:
            return
        if self.passwd_file is not None:
            check_password_file(self.passwd_file)
        _check_port_free(self.host, self.port)
        self._started.clear()
        self._start_error = None
        self._thread = threading.Thread(target=self._run, name=f"amqtt-{self.port}", daemon=True)
        self._thread.start()
        if not self._started.wait(timeout):
            self.stop()
            raise ConfigError(f"the embedded broker did not start within {timeout:g} s")
        error = self._failure()
        if error is not None:
            self._join()
            raise ConfigError(f"the embedded broker could not start on {self.host}:{self.port}: {error}")
        log.info("broker_started", host=self.host, port=self.port,
                 auth="password file" if self.passwd_file else "anonymous", acl=self.acl is not None)

    def _failure(self) -> BaseException | None:
        """Why the broker thread could not start, if it could not."""
        return self._start_error

    def _run(self) -> None:
        loop = asyncio.new_event_loop()
        self._loop = loop
        asyncio.set_event_loop(loop)
        try:
            loop.run_until_complete(self._start_broker())
        except BaseException as exc:  # reported to start(), which raises ConfigError
            self._start_error = exc
            self._started.set()
            loop.close()
            return
        self._started.set()
        try:
            loop.run_forever()
        finally:
            loop.run_until_complete(loop.shutdown_asyncgens())
            loop.close()

    async def _start_broker(self) -> None:
        from umlbot.services.bus.amqtt_broker import UmlbotBroker  # heavy import, only when a broker runs

        config = broker_config(self.host, self.port, self.passwd_file, self.acl)
        with warnings.catch_warnings():
            # amqtt 0.12 calls `acl` deprecated yet its config accepts no other name for it
            warnings.filterwarnings("ignore", "The 'acl' option is deprecated", DeprecationWarning)
            self._broker = UmlbotBroker(config, self.limits)
            await self._broker.start()
        if self.port == 0:  # "any free port": the one the system gave, for url and the logs
            self.port = self._bound_port() or 0

    def _bound_port(self) -> int | None:
        server = getattr(self._broker, "_servers", {}).get("default")
        for sock in getattr(getattr(server, "instance", None), "sockets", None) or ():
            port = sock.getsockname()[1]
            if isinstance(port, int) and port:
                return port
        return None

    async def _shutdown(self) -> None:
        if self._broker is not None:
            await self._broker.shutdown()
        # cancel what amqtt leaves behind (client handlers) so the loop closes quietly
        tasks = [t for t in asyncio.all_tasks() if t is not asyncio.current_task()]
        for task in tasks:
            task.cancel()
        await asyncio.gather(*tasks, return_exceptions=True)

    def stop(self, timeout: float = 5.0) -> None:
        """Disconnect every client and stop listening; safe to call twice."""
        loop, thread = self._loop, self._thread
        if thread is None:
            return
        if loop is not None and self._started.is_set() and self._start_error is None and loop.is_running():
            future = asyncio.run_coroutine_threadsafe(self._shutdown(), loop)
            with contextlib.suppress(Exception):
                future.result(timeout)
            loop.call_soon_threadsafe(loop.stop)
        self._join(timeout)
        log.info("broker_stopped", host=self.host, port=self.port)

    def _join(self, timeout: float = 5.0) -> None:
        if self._thread is not None:
            self._thread.join(timeout)
        self._thread = None
        self._loop = None
        self._broker = None

    def __enter__(self) -> EmbeddedBroker:
        self.start()
        return self

    def __exit__(self, *exc_info: object) -> None:
        self.stop()
