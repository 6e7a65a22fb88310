"""`umlbot monitor`: watch a robot's traffic — availability, calls with latency, the trace.

`MonitorState` turns MQTT messages (or trace-file lines) into `MonitorEvent`s and statistics;
`LiveMonitor` feeds it from the broker; `replay` from a recorded trace; `render` draws it.
"""

from umlbot.monitor.live import LiveMonitor, topic_filter
from umlbot.monitor.replay import read_trace, replay
from umlbot.monitor.state import DEFAULT_CALL_TIMEOUT_S, MonitorEvent, MonitorState, Stats
from umlbot.monitor.view import render

__all__ = [
    "DEFAULT_CALL_TIMEOUT_S",
    "LiveMonitor",
    "MonitorEvent",
    "MonitorState",
    "Stats",
    "read_trace",
    "render",
    "replay",
    "topic_filter",
]
