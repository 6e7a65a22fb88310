"""amqtt 0.12.1 made to behave as MQTT 3.1.1 says (and as Mosquitto does), for the embedded broker.

Imported only when a broker runs (amqtt is a heavy import). `UmlbotBroker` is amqtt's `Broker`
with these differences, each one a fault found against Mosquitto or the MQTT 3.1.1 text
(docs/security.md, "Faults and attacks tested"; tests/test_broker_conformance.py):

- keep-alive: a client silent for 1.5 x its keep-alive is disconnected and its will published
  (MQTT-3.1.2-24); amqtt waited for ever, so a frozen service was never announced offline;
- an MQTT 5 CONNECT is answered with CONNACK "unacceptable protocol version" (MQTT-3.1.2-2), so
  that the client falls back to 3.1.1; amqtt closed the connection without a word when the CONNECT
  had a will;
- strings: a topic, topic filter, client id or user name that is not well-formed UTF-8 or holds
  U+0000 closes the connection (MQTT-1.5.3-1, -2); amqtt turned the bytes into "b'...'" text and
  acknowledged the publish;
- client ids are bound to their user: a CONNECT with the client id of a session that another user
  holds is refused (CONNACK 5, not authorised) before it can touch that session; amqtt deleted
  or took over the session even before checking the password, so any user could knock any client
  off (its will published: "offline");
- persistent sessions (clean session 0): QoS 1 and 2 messages are queued while the client is away
  (also for clients without a user name: amqtt kept none for them), delivered as ordinary messages
  (not retained), and a QoS 1/2 message that was in flight when the connection dropped is sent
  again (DUP) on reconnect (MQTT-4.4.0-1); amqtt lost it;
- bounds: a retained message larger than `max_retained_bytes`, or past `max_retained_total`
  bytes of retained messages, is not retained (it is still delivered; a warning names the topic);
  an offline session queues at most `max_queued_messages` messages, then drops the newer ones
  (as Mosquitto's max_queued_messages, and logged once per outage);
- a retained message goes out only for the client's own subscriptions (amqtt sent every retained
  message matching any client's filter to each new client), and the subscription table is iterated
  over snapshots (amqtt lost broadcasts when a client subscribed during one).
"""

from __future__ import annotations

import asyncio
import contextlib
from collections.abc import Iterator
from typing import Any

from amqtt import codecs_amqtt
from amqtt.broker import Broker
from amqtt.errors import AMQTTError, MQTTError, NoDataError
from amqtt.events import BrokerEvents
from amqtt.mqtt import connect as connect_packet
from amqtt.mqtt import publish as publish_packet
from amqtt.mqtt import subscribe as subscribe_packet
from amqtt.mqtt import unsubscribe as unsubscribe_packet
from amqtt.mqtt.connack import UNACCEPTABLE_PROTOCOL_VERSION, ConnackPacket
from amqtt.mqtt.constants import QOS_0, QOS_1, QOS_2
from amqtt.mqtt.protocol.broker_handler import BrokerProtocolHandler
from amqtt.session import OUTGOING, Session
from amqtt.utils import format_client_message, gen_client_id
from transitions import MachineError

from umlbot.base.logs import get_logger
from umlbot.services.bus.broker_limits import BrokerLimits

log = get_logger("umlbot.services.bus.broker")

#: a client silent for this many times its keep-alive is disconnected (MQTT-3.1.2-24: 1.5).
KEEPALIVE_GRACE = 1.5


class ProtocolViolation(AMQTTError):  # type: ignore[misc]  # amqtt is untyped
    """A packet MQTT says the server must answer by closing the connection."""


class UnsupportedProtocolLevel(ProtocolViolation):
    """A CONNECT of another MQTT version than 3.1.1 (level 4): CONNACK 1, then close (MQTT-3.1.2-2).

    amqtt read the rest of an MQTT 5 CONNECT as 3.1.1 first and closed the connection without a
    CONNACK when that failed (as it does for one with a will): a client could not tell that it
    should fall back to 3.1.1.
    """


async def _strict_decode_string(reader: Any) -> str:
    """An MQTT UTF-8 string; ProtocolViolation for ill-formed UTF-8 or U+0000 (MQTT-1.5.3)."""
    length_bytes = await codecs_amqtt.read_or_raise(reader, 2)
    if len(length_bytes) < 2:
        raise codecs_amqtt.ZeroLengthReadError
    length = int.from_bytes(length_bytes, "big")
    if not length:
        return ""
    raw = await codecs_amqtt.read_or_raise(reader, length)
    try:
        text: str = raw.decode("utf-8")  # strict: refuses ill-formed UTF-8 and encoded surrogates
    except UnicodeDecodeError as exc:
        raise ProtocolViolation(f"a string is not well-formed UTF-8 ({exc.reason} at byte {exc.start})") \
            from None
    if "\0" in text:
        raise ProtocolViolation("a string holds the character U+0000")
    return text


def _patch_amqtt() -> None:
    """The process-wide parts: the packet decoders and the protocol handler. Idempotent."""
    for module in (connect_packet, publish_packet, subscribe_packet, unsubscribe_packet):
        module.decode_string = _strict_decode_string
    handler_cls: Any = BrokerProtocolHandler
    if getattr(handler_cls, "_umlbot_patched", False):
        return
    handler_cls._umlbot_patched = True
    payload_cls: Any = connect_packet.ConnectPayload
    read_payload = payload_cls.from_stream.__func__

    async def read_connect_payload(cls: Any, reader: Any, fixed_header: Any, variable_header: Any) -> Any:
        level = getattr(variable_header, "proto_level", 4)
        if level != 4:
            raise UnsupportedProtocolLevel(f"MQTT protocol level {level} (only 4, MQTT 3.1.1, is spoken)")
        return await read_payload(cls, reader, fixed_header, variable_header)

    payload_cls.from_stream = classmethod(read_connect_payload)

    def handle_read_timeout(self: Any) -> None:
        # the reader waited 1.5 x keep-alive (see UmlbotBroker) without a packet: cancelling the
        # reader ends the connection as a lost one, so the broker publishes the will
        session = self.session
        log.warning("broker_keepalive_expired", client_id=getattr(session, "client_id", None),
                    keepalive_s=getattr(session, "keep_alive", None))
        task = getattr(self, "_reader_task", None)
        if task is not None:
            task.cancel()

    original_flow = handler_cls._handle_message_flow

    async def handle_message_flow(self: Any, app_message: Any) -> None:
        try:
            await original_flow(self, app_message)
        except BaseException:
            # amqtt drops a QoS 1/2 message from the session when the connection ends before its
            # acknowledgement; a persistent session keeps it, to send it again on reconnect
            session = self.session
            unacknowledged = (app_message.puback_packet is None if app_message.qos == QOS_1
                              else app_message.pubcomp_packet is None)
            if (app_message.direction == OUTGOING and app_message.qos in (QOS_1, QOS_2)
                    and app_message.packet_id is not None and unacknowledged
                    and session is not None and not session.clean_session):
                session.inflight_out[app_message.packet_id] = app_message
            raise

    handler_cls.handle_read_timeout = handle_read_timeout
    handler_cls._handle_message_flow = handle_message_flow


class _Refused(Exception):
    """A connection answered and closed on purpose (no warning: the client knows what to do)."""


class _SnapshotSubscriptions(dict[str, list[Any]]):
    """amqtt's subscription table, iterated over snapshots.

    amqtt 0.12 loops over this table across an `await` per subscriber (`Broker._run_broadcast`);
    a client subscribing, unsubscribing or disconnecting meanwhile raised "dictionary changed size
    during iteration" and the message being broadcast was lost for the remaining subscribers.
    """

    def __iter__(self) -> Iterator[str]:
        return iter(list(super().keys()))

    def items(self) -> list[tuple[str, list[Any]]]:  # type: ignore[override]
        return [(key, list(value)) for key, value in super().items()]


class UmlbotBroker(Broker):  # type: ignore[misc]  # amqtt is untyped
    """amqtt's broker with the fixes listed in the module's docstring."""

    def __init__(self, config: dict[str, Any], limits: BrokerLimits | None = None) -> None:
        _patch_amqtt()
        super().__init__(config)
        self.limits = limits or BrokerLimits()
        self._subscriptions: dict[str, list[Any]] = _SnapshotSubscriptions(self._subscriptions)
        self._queue_full_warned: set[str] = set()

    # -- connecting: read the CONNECT, authenticate, and only then touch a stored session --------

    async def _client_connected(self, listener_name: str, reader: Any, writer: Any) -> None:
        """amqtt's, less its warning for an MQTT 5 client told to fall back (every such connect)."""
        try:
            await super()._client_connected(listener_name, reader, writer)
        except _Refused:
            server = self._servers.get(listener_name)
            if server is not None:
                server.release_connection()

    async def _initialize_client_session(
        self, reader: Any, writer: Any, remote_address: str, remote_port: int
    ) -> tuple[Any, Session]:
        """Read and check the CONNECT; the stored session is looked at after authentication."""
        where = format_client_message(address=remote_address, port=remote_port)
        try:
            handler, session = await BrokerProtocolHandler.init_from_connect(reader, writer,
                                                                             self.plugins_manager)
        except UnsupportedProtocolLevel as exc:  # an MQTT 5 client: it falls back to 3.1.1
            log.debug("broker_connect_refused", peer=where, reason=str(exc))
            with contextlib.suppress(Exception):
                await ConnackPacket.build(0, UNACCEPTABLE_PROTOCOL_VERSION).to_stream(writer)
            await writer.close()
            raise _Refused from exc
        except ProtocolViolation as exc:
            log.warning("broker_connect_refused", peer=where, reason=str(exc))
            await writer.close()
            raise MQTTError(str(exc)) from exc
        except MQTTError:
            self.logger.warning(f"Invalid connection from {where}")
            await writer.close()
            raise
        except (AMQTTError, NoDataError) as exc:
            self.logger.warning(f"[MQTT-3.1.0-1] {where}: Can't read first packet as CONNECT: {exc}")
            await writer.close()
            raise AMQTTError(exc) from exc
        if session.clean_session and not session.client_id:
            session.client_id = gen_client_id()
        return handler, session

    def _owner_conflict(self, session: Session) -> str | None:
        """Why this client may not use its client id: another user's session holds it."""
        stored = self._sessions.get(session.client_id)
        if stored is None or stored[0].username == session.username:
            return None
        return "the client id belongs to a session of another user"

    def _resume_or_start(self, session: Session) -> Session:
        """The session this connection continues (clean session 0) or a new one; as amqtt's
        `_initialize_client_session` did, but after authentication and the owner check."""
        if session.clean_session:
            return session
        stored = self._sessions.get(session.client_id)
        if stored is None:
            session.parent = 0
            return session
        existing: Session = stored[0]
        for name in ("will_flag", "will_message", "will_topic", "will_qos", "will_retain",
                     "keep_alive", "username", "password", "remote_address", "remote_port"):
            setattr(existing, name, getattr(session, name))
        existing.parent = 1
        return existing

    async def _handle_client_session(
        self, reader: Any, writer: Any, client_session: Session, handler: Any, server: Any, listener_name: str
    ) -> None:
        """amqtt's `_handle_client_session`, in a safe order: authenticate, check that the client
        id is this user's, and only then replace (clean session) or resume the stored session."""
        authenticated = await self._authenticate(client_session, self.listeners_config[listener_name])
        refusal = self._owner_conflict(client_session) if authenticated else "authentication failed"
        if refusal is not None:
            if authenticated:
                log.warning("broker_client_id_refused", client_id=client_session.client_id,
                            user=client_session.username, reason=refusal)
            client_session.parent = 0
            handler.attach(client_session, reader, writer)
            await handler.mqtt_connack_authorize(False)
            await writer.close()
            return
        client_session.is_anonymous = False  # MQTT keeps a session without a user name alike
        if client_session.clean_session:
            await self._delete_session(client_session.client_id)
            client_session.parent = 0
        client_session = self._resume_or_start(client_session)
        if client_session.keep_alive > 0:
            client_session.keep_alive = client_session.keep_alive * KEEPALIVE_GRACE
        self._queue_full_warned.discard(client_session.client_id)

        while True:
            try:
                client_session.transitions.connect()
                break
            except (MachineError, ValueError):
                if client_session.transitions.is_connected():
                    old = self._sessions[client_session.client_id]
                    await old[1].handle_connection_closed()
                    await old[1].stop()
                    break
                await asyncio.sleep(1)  # amqtt: "reconnecting too quickly"

        handler.attach(client_session, reader, writer)
        self._sessions[client_session.client_id] = (client_session, handler)
        await handler.mqtt_connack_authorize(True)
        client_id = client_session.client_id
        await self.plugins_manager.fire_event(BrokerEvents.CLIENT_CONNECTED, client_id=client_id,
                                              client_session=client_session)
        await handler.start()
        await self._publish_session_retained_messages(client_session)
        for topic in self._subscriptions:
            await self._publish_retained_messages_for_subscription((topic, QOS_0), client_session)
        await self._client_message_loop(client_session, handler)

    # -- retained messages and offline queues ------------------------------------------------------

    async def retain_message(
        self, source_session: Session | None, topic_name: str | None, data: bytes | bytearray | None,
        qos: int | None = None,
    ) -> None:
        if data and topic_name is not None:
            size = len(data)
            old = self._retained_messages.get(topic_name)
            total = sum(len(m.data) for m in self._retained_messages.values()) - (len(old.data) if old else 0)
            limit = None
            if size > self.limits.max_retained_bytes:
                limit = f"larger than {self.limits.max_retained_bytes} bytes"
            elif total + size > self.limits.max_retained_total:
                limit = f"the retained messages would exceed {self.limits.max_retained_total} bytes"
            if limit is not None:
                log.warning("broker_retained_refused", topic=topic_name, size=size, reason=limit,
                            client_id=getattr(source_session, "client_id", None),
                            kept="the previous retained message" if old else "nothing")
                return
        await super().retain_message(source_session, topic_name, data, qos)

    async def _retain_broadcast_message(
        self, broadcast: dict[str, Any], qos: int, target_session: Session
    ) -> None:
        """Queue a message for a disconnected persistent session, at most `max_queued_messages`."""
        queue = target_session.retained_messages
        if queue.qsize() >= self.limits.max_queued_messages:
            if target_session.client_id not in self._queue_full_warned:
                self._queue_full_warned.add(target_session.client_id)
                log.warning("broker_queue_full", client_id=target_session.client_id,
                            limit=self.limits.max_queued_messages, action="newer messages dropped")
            return
        await super()._retain_broadcast_message(broadcast, qos, target_session)

    async def _publish_session_retained_messages(self, session: Session) -> None:
        """Deliver what was queued while the session was away: ordinary messages, not retained."""
        handler = self._get_handler(session)
        tasks = []
        while handler is not None and not session.retained_messages.empty():
            queued = session.retained_messages.get_nowait()
            tasks.append(asyncio.ensure_future(handler.mqtt_publish(queued.topic, queued.data, queued.qos,
                                                                     retain=False)))
        if tasks:
            await asyncio.wait(tasks)
            for task in tasks:  # a client gone again meanwhile: its messages stay in flight
                with contextlib.suppress(BaseException):
                    task.result()

    async def _publish_retained_messages_for_subscription(
        self, subscription: tuple[str, int], session: Session
    ) -> None:
        """Retained messages only for a filter the session itself holds (see the module)."""
        holders = self._subscriptions.get(subscription[0], ())
        if any(holder.client_id == session.client_id for holder, _ in holders):
            await super()._publish_retained_messages_for_subscription(subscription, session)
