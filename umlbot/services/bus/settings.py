"""Broker connection settings from a URL, and client ids that say who is talking.

`mqtt://user:pass@host:1883` or `mqtts://host:8883`; query parameters `ca`, `cert`, `key`,
`insecure=1` and `protocol` (`auto`, the default: MQTT 5, and 3.1.1 where the broker refuses 5;
`5` or `3.1.1` to insist on one). The password is a
`SecretStr` and every URL that is shown or logged goes through `redact_url`.
"""

from __future__ import annotations

import os
import re
import socket
from pathlib import Path
from typing import Final, Literal
from urllib.parse import parse_qs, quote, unquote, urlsplit

from pydantic import BaseModel, ConfigDict, Field, SecretStr

from umlbot.base.errors import ConfigError

DEFAULT_BROKER_URL: Final = "mqtt://127.0.0.1:1883"
BROKER_ENV: Final = "UMLBOT_BROKER"
_DEFAULT_PORTS: Final = {"mqtt": 1883, "mqtts": 8883}
_TRUE = {"1", "true", "yes", "on"}
_FALSE = {"0", "false", "no", "off", ""}


def resolve_broker_url(cli_value: str | None) -> str:
    """The broker URL to use: the command-line value, else `UMLBOT_BROKER`, else loopback:1883."""
    if cli_value:
        return cli_value
    return os.environ.get(BROKER_ENV) or DEFAULT_BROKER_URL


def redact_url(url: str) -> str:
    """The URL with its password replaced by `***` (safe for logs and error messages)."""
    try:
        parts = urlsplit(url)
    except ValueError:
        return "<unparsable broker URL>"
    if parts.password is None:
        return url
    netloc = parts.netloc.rsplit("@", 1)[1]
    user = parts.username or ""
    return parts._replace(netloc=f"{user}:***@{netloc}").geturl()


class BrokerSettings(BaseModel):
    """Where and how to connect to the MQTT broker; `repr` and `url` never show the password."""

    model_config = ConfigDict(frozen=True)

    scheme: Literal["mqtt", "mqtts"] = "mqtt"
    host: str = "127.0.0.1"
    port: int = Field(default=1883, ge=1, le=65535)
    username: str | None = None
    password: SecretStr | None = None
    ca_file: Path | None = None
    certfile: Path | None = None
    keyfile: Path | None = None
    insecure: bool = False
    #: "auto": MQTT 5, falling back to 3.1.1 on a broker that refuses 5 (amqtt)
    protocol: Literal["auto", "3.1.1", "5"] = "auto"
    keepalive_s: int = Field(default=30, ge=5, le=3600)

    @property
    def tls(self) -> bool:
        return self.scheme == "mqtts"

    @property
    def url(self) -> str:
        """The redacted URL: `mqtt://user:***@host:port`."""
        auth = ""
        if self.username is not None:
            auth = quote(self.username, safe="") + (":***" if self.password is not None else "") + "@"
        host = f"[{self.host}]" if ":" in self.host else self.host
        return f"{self.scheme}://{auth}{host}:{self.port}"

    def __str__(self) -> str:
        return self.url

    @classmethod
    def from_url(
        cls,
        url: str,
        ca_file: str | Path | None = None,
        certfile: str | Path | None = None,
        keyfile: str | Path | None = None,
        insecure: bool | None = None,
        protocol: str | None = None,
    ) -> BrokerSettings:
        """Parse a broker URL; keyword arguments (from the command line) win over query parameters."""
        shown = redact_url(url)
        try:
            parts = urlsplit(url.strip())
            port = parts.port
        except ValueError as exc:
            raise ConfigError(f"bad broker URL {shown}: {exc}") from exc
        scheme = parts.scheme.lower()
        if scheme not in _DEFAULT_PORTS:
            raise ConfigError(
                f"bad broker URL {shown}: the scheme must be mqtt:// or mqtts:// "
                "(e.g. mqtt://127.0.0.1:1883)"
            )
        if not parts.hostname:
            raise ConfigError(f"bad broker URL {shown}: no host (e.g. mqtt://127.0.0.1:1883)")
        if parts.path not in ("", "/"):
            raise ConfigError(f"bad broker URL {shown}: unexpected path {parts.path!r}")
        query = {k: v[-1] for k, v in parse_qs(parts.query, keep_blank_values=True).items()}
        known = {"ca", "cert", "key", "insecure", "protocol", "keepalive"}
        unknown = sorted(set(query) - known)
        if unknown:
            raise ConfigError(
                f"bad broker URL {shown}: unknown parameter(s) {', '.join(unknown)} "
                f"(known: {', '.join(sorted(known))})"
            )
        insecure_text = query.get("insecure", "0").lower()
        if insecure_text not in _TRUE | _FALSE:
            raise ConfigError(f"bad broker URL {shown}: insecure must be 0 or 1")
        protocol_text = protocol if protocol is not None else query.get("protocol", "auto")
        chosen_protocol = _protocol(protocol_text, shown)
        keepalive = query.get("keepalive", "30")
        if not keepalive.isdigit() or not 5 <= int(keepalive) <= 3600:
            raise ConfigError(f"bad broker URL {shown}: keepalive must be 5..3600 seconds")
        password = unquote(parts.password) if parts.password is not None else None
        settings = cls(
            scheme="mqtts" if scheme == "mqtts" else "mqtt",
            host=parts.hostname,
            port=port or _DEFAULT_PORTS[scheme],
            username=unquote(parts.username) if parts.username else None,
            password=SecretStr(password) if password is not None else None,
            ca_file=_path(ca_file if ca_file is not None else query.get("ca")),
            certfile=_path(certfile if certfile is not None else query.get("cert")),
            keyfile=_path(keyfile if keyfile is not None else query.get("key")),
            insecure=insecure if insecure is not None else insecure_text in _TRUE,
            protocol=chosen_protocol,
            keepalive_s=int(keepalive),
        )
        if (settings.certfile is None) != (settings.keyfile is None):
            raise ConfigError(f"broker {shown}: a client certificate needs both cert and key")
        if not settings.tls and (settings.ca_file or settings.certfile):
            raise ConfigError(f"broker {shown}: CA and client certificates need an mqtts:// URL")
        for name, path in (("CA file", settings.ca_file), ("certificate", settings.certfile),
                           ("key", settings.keyfile)):
            if path is not None and not path.is_file():
                raise ConfigError(f"broker {shown}: {name} {path} does not exist")
        return settings


def _path(value: str | Path | None) -> Path | None:
    return Path(value) if value else None


def _protocol(value: str, shown: str) -> Literal["auto", "3.1.1", "5"]:
    text = str(value).strip().lower()
    if text in ("auto", ""):
        return "auto"
    if text in ("3", "3.1.1", "311", "4", "v311"):
        return "3.1.1"
    if text in ("5", "5.0", "v5"):
        return "5"
    raise ConfigError(f"bad broker URL {shown}: protocol must be auto, 3.1.1 or 5")


_UNSAFE = re.compile(r"[^A-Za-z0-9_\-]")


def make_client_id(role: str, robot: str) -> str:
    """`umlbot-<role>-<robot>-<host>-<pid>-<32 hex digits>`: says what the client is, and cannot be
    guessed (128 random bits), so that no other client can take it (docs/security.md).

    umlbot never publishes it: statuses name an `instance` token, reply topics a token of their own.
    """
    host = _UNSAFE.sub("", socket.gethostname().split(".")[0])[:20] or "host"
    suffix = os.urandom(16).hex()
    role_part = _UNSAFE.sub("_", role)[:32] or "client"
    robot_part = _UNSAFE.sub("_", robot)[:32] or "any"
    return f"umlbot-{role_part}-{robot_part}-{host}-{os.getpid()}-{suffix}"
