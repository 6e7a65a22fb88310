"""The MQTT bus shared by every service and the orchestrator (SPEC §3).

`BusConnection` owns one paho client (reconnects, subscriptions, last will); `ComponentServer`
answers one component's feature calls; `BusClient` makes calls. Topics, envelopes and settings
are plain data. The embedded broker lives in `umlbot.services.bus.broker` (imported on demand).
"""

from typing import TYPE_CHECKING

from umlbot.base.lazy import lazy_attributes
from umlbot.base.topics import Topics
from umlbot.services.bus.connection import BusConnection, Handler, Message, Will
from umlbot.services.bus.envelopes import (
    ENVELOPE_KEYS,
    ERROR_CODES,
    CallRequest,
    ErrorBody,
    ErrorCode,
    ExitRequest,
    Heartbeat,
    OrchestratorStatus,
    Reply,
    Status,
    TraceEvent,
    dumps,
    json_default,
    parse_json,
    to_payload,
)
from umlbot.services.bus.server import (
    MAX_REQUEST_BYTES,
    STATUS_WAIT_S,
    ComponentServer,
    Feature,
    FeatureError,
    caller,
)
from umlbot.services.bus.settings import (
    DEFAULT_BROKER_URL,
    BrokerSettings,
    make_client_id,
    redact_url,
    resolve_broker_url,
)

if TYPE_CHECKING:
    from umlbot.services.bus.broker import BrokerLimits, EmbeddedBroker, check_user_name, password_line
    from umlbot.services.bus.client import BusClient, reply_value

__all__ = [
    "DEFAULT_BROKER_URL",
    "ENVELOPE_KEYS",
    "ERROR_CODES",
    "MAX_REQUEST_BYTES",
    "STATUS_WAIT_S",
    "BrokerLimits",
    "BrokerSettings",
    "BusClient",
    "BusConnection",
    "CallRequest",
    "ComponentServer",
    "EmbeddedBroker",
    "ErrorBody",
    "ErrorCode",
    "ExitRequest",
    "Feature",
    "FeatureError",
    "Handler",
    "Heartbeat",
    "Message",
    "OrchestratorStatus",
    "Reply",
    "Status",
    "Topics",
    "TraceEvent",
    "Will",
    "caller",
    "check_user_name",
    "dumps",
    "json_default",
    "make_client_id",
    "parse_json",
    "password_line",
    "redact_url",
    "reply_value",
    "resolve_broker_url",
    "to_payload",
]

#: heavy parts, imported on first use (umlbot.base.lazy.lazy_attributes); the client (with
#: concurrent.futures) is not used by a hardware service, which only serves
__getattr__ = lazy_attributes(__name__, {
    "BusClient": "umlbot.services.bus.client",
    "reply_value": "umlbot.services.bus.client",
    "BrokerLimits": "umlbot.services.bus.broker",
    "EmbeddedBroker": "umlbot.services.bus.broker",
    "check_user_name": "umlbot.services.bus.broker",
    "password_line": "umlbot.services.bus.broker",
})
