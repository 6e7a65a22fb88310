"""Print every MQTT message under a topic filter as one JSON line, with the time it arrived.

tests/test_systemd_nspawn.py runs it with `nsenter --net` in the network namespace of the nspawn
container (whose broker listens on the container's own loopback):

    python tests/mqtt_recorder.py mqtt://user:password@127.0.0.1:1883 'umlbot/car/#'

Its first line is `{"subscribed": true}` once the broker acknowledged the subscription; then one
`{"t": …, "topic": …, "payload": …, "retain": …}` per message, `t` being `time.monotonic()` (the
clock the test reads too: the namespaces share it). A plain paho client that uses no umlbot code.
"""

from __future__ import annotations

import json
import sys
import threading
import time
import urllib.parse
import uuid
from typing import Any

import paho.mqtt.client as mqtt
from paho.mqtt.enums import CallbackAPIVersion

CONNECT_TIMEOUT_S = 10.0


def say(line: dict[str, Any]) -> None:
    sys.stdout.write(json.dumps(line) + "\n")
    sys.stdout.flush()


def main(url: str, topic: str) -> int:
    parsed = urllib.parse.urlsplit(url)
    client_id = f"umlbot-test-recorder-{uuid.uuid4().hex[:8]}"
    client = mqtt.Client(CallbackAPIVersion.VERSION2, client_id=client_id)
    if parsed.username:
        client.username_pw_set(urllib.parse.unquote(parsed.username),
                               urllib.parse.unquote(parsed.password or ""))
    subscribed = threading.Event()

    def on_connect(client: mqtt.Client, _data: object, _flags: object, reason: Any, _props: object) -> None:
        if reason.is_failure:
            say({"error": f"connection refused: {reason}"})
            return
        client.subscribe(topic, qos=1)

    def on_subscribe(_client: mqtt.Client, _data: object, _mid: int, reasons: Any, _props: object) -> None:
        if any(reason.is_failure for reason in reasons):
            say({"error": f"subscription to {topic} refused: {reasons}"})
            return
        if not subscribed.is_set():
            subscribed.set()
            say({"subscribed": True})

    def on_message(_client: mqtt.Client, _userdata: object, message: mqtt.MQTTMessage) -> None:
        text = message.payload.decode("utf-8", errors="replace")
        say({"t": time.monotonic(), "topic": message.topic, "payload": text, "retain": bool(message.retain)})

    client.on_connect = on_connect
    client.on_subscribe = on_subscribe
    client.on_message = on_message
    client.connect(parsed.hostname or "127.0.0.1", parsed.port or 1883, keepalive=10)
    client.loop_start()
    if not subscribed.wait(CONNECT_TIMEOUT_S):
        where = f"{parsed.hostname}:{parsed.port}"
        say({"error": f"not subscribed to {topic} at {where} in {CONNECT_TIMEOUT_S} s"})
        client.loop_stop()
        return 1
    sys.stdin.read()  # until the test closes our stdin (or kills us)
    client.disconnect()
    client.loop_stop()
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1], sys.argv[2]))
