"""The live source of the monitor: one read-only bus connection subscribed to a robot's topics."""

from __future__ import annotations

import threading
import time
from collections.abc import Callable

from umlbot.base.errors import BrokerRefused
from umlbot.base.topics import check_name
from umlbot.monitor.state import MonitorEvent, MonitorState
from umlbot.services.bus import BrokerSettings, BusConnection, Message

EventSink = Callable[[MonitorEvent], None]


def topic_filter(robot: str | None) -> str:
    """Everything of one robot, or of every robot when `robot` is None (ConfigError for a bad id)."""
    return f"umlbot/{check_name('robot id', robot)}/#" if robot else "umlbot/+/#"


def topic_filters(robots: str | None) -> list[str]:
    """The filters of `--robot`: every robot for None, '' or '*'; else one per robot of a
    comma-separated list (`car1,car2`)."""
    if not robots or robots.strip() == "*":
        return [topic_filter(None)]
    names = [name.strip() for name in robots.split(",") if name.strip()]
    return [topic_filter(name) for name in dict.fromkeys(names)] or [topic_filter(None)]


class LiveMonitor:
    """Feeds `state` from the broker; `on_event` runs on the bus dispatcher thread.

    Readers of `state` (the terminal view) hold `lock` while they look. It never publishes, so a
    read-only MQTT user (`umlbot-monitor`) is enough.
    """

    def __init__(self, settings: BrokerSettings, robot: str | None, on_event: EventSink,
                 state: MonitorState | None = None) -> None:
        self.robot = robot
        self.state = state or MonitorState()
        self.lock = threading.Lock()
        self._on_event = on_event
        self._filters = topic_filters(robot)
        single = robot is not None and "," not in robot and "*" not in robot and robot.strip() != ""
        name = robot.strip() if robot is not None and single else "any"
        self._connection = BusConnection(settings, "monitor", robot=name)
        for topic in self._filters:
            self._connection.subscribe(topic, self._handle)

    @property
    def connected(self) -> bool:
        return self._connection.connected

    def broker_status(self, now: float | None = None) -> dict[str, object]:
        """The connection as the studio shows it: `connected`, else `problem` (why the last
        attempt failed), `attempts` (failed ones since the last connection) and `retry_in_s`."""
        connection = self._connection
        if connection.connected:
            return {"connected": True}
        status: dict[str, object] = {"connected": False, "problem": connection.connect_problem,
                                     "attempts": connection.connect_failures}
        at = connection.next_attempt_at
        if at is not None:
            status["retry_in_s"] = round(max(0.0, at - (time.time() if now is None else now)), 1)
        return status

    def start(self, timeout: float | None = 5.0) -> None:
        """Connect; raises NotConnected when the broker is not reached within `timeout` (None:
        connect in the background and keep trying), and BrokerRefused when the broker refuses the
        subscription to the robot's topics (its ACL; amqtt says so in its SUBACK, Mosquitto grants
        it and filters each message instead): a monitor that would show nothing says why."""
        self._connection.start(timeout)
        if timeout is None:
            return
        self._connection.wait_subscribed(timeout)
        for topic in self._filters:
            refused = self._connection.refused_subscriptions.get(topic)
            if refused is not None:
                raise BrokerRefused(f"the subscription to {topic} (may this user read the robot's "
                                    "topics? see docs/security.md)", refused)

    def tick(self, now: float | None = None) -> None:
        """Report calls that stayed unanswered (call it about once a second)."""
        with self.lock:
            events = self.state.expire(time.time() if now is None else now)
        for event in events:
            self._on_event(event)

    def close(self) -> None:
        """Disconnect; safe to call twice."""
        self._connection.close()

    def _handle(self, message: Message) -> None:
        with self.lock:
            events = self.state.observe(message.topic, message.payload, time.time())
        for event in events:
            self._on_event(event)
