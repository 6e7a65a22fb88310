"""Recordings every robotics tool opens: rosbag2-compatible MCAP files and a live Foxglove view.

`Recorder` takes the robot's traffic (and, in the sim, the world) without making anything wait and
writes it from its own thread to its sinks: `McapBag` (one rosbag2 MCAP file) and, with
`--foxglove`, the live server. Needs the `record` extra (`pip install 'umlbot[record]'`); nothing
here is imported by the core. See docs/recording.md.
"""

from typing import TYPE_CHECKING

from umlbot.base.lazy import lazy_attributes

if TYPE_CHECKING:
    from umlbot.record.bag import McapBag, check_writable
    from umlbot.record.live import FoxgloveLive, check_port, live_sinks
    from umlbot.record.process import RecorderProcess
    from umlbot.record.recorder import Recorder, RecordStats, open_file_recorder
    from umlbot.record.sim import SimRecording

__all__ = ["FoxgloveLive", "McapBag", "RecordStats", "Recorder", "RecorderProcess", "SimRecording",
           "check_port", "check_writable", "live_sinks", "open_file_recorder"]

__getattr__ = lazy_attributes(__name__, {
    "FoxgloveLive": "umlbot.record.live",
    "live_sinks": "umlbot.record.live",
    "check_port": "umlbot.record.live",
    "McapBag": "umlbot.record.bag",
    "check_writable": "umlbot.record.bag",
    "RecordStats": "umlbot.record.recorder",
    "Recorder": "umlbot.record.recorder",
    "RecorderProcess": "umlbot.record.process",
    "open_file_recorder": "umlbot.record.recorder",
    "SimRecording": "umlbot.record.sim",
})
