"""The MQTT bus shared by every service and the orchestrator (SPEC §3).

`BusConnection` owns one paho client (reconnects, subscriptions, last will); `ComponentServer`
answers one component's feature calls; `BusClient` makes calls. Topics, envelopes and settings
are plain data. The embedded broker lives in `umlbot.services.bus.broker` (imported on demand).
"""

from umlbot.base.topics import Topics
from umlbot.services.bus.client import BusClient
from umlbot.services.bus.connection import BusConnection, Handler, Message, Will
from umlbot.services.bus.envelopes import (
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
    to_payload,
)
from umlbot.services.bus.server import MAX_REQUEST_BYTES, ComponentServer, Feature, FeatureError
from umlbot.services.bus.settings import (
    DEFAULT_BROKER_URL,
    BrokerSettings,
    make_client_id,
    redact_url,
    resolve_broker_url,
)

__all__ = [
    "DEFAULT_BROKER_URL",
    "ERROR_CODES",
    "MAX_REQUEST_BYTES",
    "BrokerSettings",
    "BusClient",
    "BusConnection",
    "CallRequest",
    "ComponentServer",
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
    "make_client_id",
    "redact_url",
    "resolve_broker_url",
    "to_payload",
]
