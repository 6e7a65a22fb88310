"""What the embedded broker holds at most: apart from `broker.py` so that the amqtt side
(`amqtt_broker.py`, imported only when a broker runs) reads it without importing its caller."""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class BrokerLimits:
    """What the embedded broker holds at most (docs/mqtt.md, "The embedded broker")."""

    #: a retained message larger than this is not retained (it is still delivered; logged).
    max_retained_bytes: int = 256 * 1024
    #: all retained messages together; a new one past it is not retained (logged).
    max_retained_total: int = 64 * 1024 * 1024
    #: messages queued for one disconnected persistent session; newer ones are dropped (logged).
    max_queued_messages: int = 1000
