"""The Foxglove layout of docs/foxglove-layout.json, made with foxglove-sdk's layout classes.

A 3D view of the sim (the live scene, or the recorded track and pose), a plot of the sonar range
and the two motors' duty cycles, the trace as a log (live) and as raw messages, the calls as a
table. `python -m umlbot.record.layout [ROBOT]` prints it; a test checks the committed file.
"""

from __future__ import annotations

import json
import sys

from umlbot.base.rosmsg import require
from umlbot.record.messages import Topics, ros_name


def layout_json(robot: str = "car") -> str:
    """The layout for `robot`'s topics, as JSON text (sorted keys, 2-space indent)."""
    L = require("foxglove.layouts", "record", "The Foxglove layout")
    topics = Topics(robot)
    scene = f"/umlbot/{ros_name(robot)}/sim/scene"
    three_d = L.ThreeDeePanel(title="sim", config=L.ThreeDeeConfig(
        follow_mode="follow-none",
        topics={scene: L.BaseRendererSceneUpdateTopicSettings(visible=True),
                topics.track: {"visible": True}, topics.pose: {"visible": True}},
    ))
    plot = L.PlotPanel(title="sonar (m) and motor duty (%)", config=L.PlotConfig(paths=[
        L.PlotSeries(value=f"{topics.sonar}.range", label="sonar range (m)", enabled=True),
        L.PlotSeries(value=f"{topics.motors}.effort[0]", label="left duty (%)", enabled=True),
        L.PlotSeries(value=f"{topics.motors}.effort[1]", label="right duty (%)", enabled=True),
    ]))
    log_topic = f"/umlbot/{ros_name(robot)}/log"
    log = L.LogPanel(title="trace (live)", config=L.LogConfig(topic_to_render=log_topic))
    trace = L.TablePanel(title="trace", config=L.TableConfig(topic_path=topics.trace))
    calls = L.TablePanel(title="calls", config=L.TableConfig(topic_path=topics.calls))
    layout = L.Layout(content=L.SplitContainer(direction="row", items=[
        L.SplitItem(proportion=1, content=L.SplitContainer(direction="column", items=[
            L.SplitItem(proportion=2, content=three_d), L.SplitItem(proportion=1, content=plot)])),
        L.SplitItem(proportion=1, content=L.SplitContainer(direction="column", items=[
            L.SplitItem(proportion=1, content=log), L.SplitItem(proportion=1, content=trace),
            L.SplitItem(proportion=1, content=calls)])),
    ]))
    return json.dumps(json.loads(layout.to_json()), indent=2, sort_keys=True) + "\n"


if __name__ == "__main__":
    sys.stdout.write(layout_json(sys.argv[1] if len(sys.argv) > 1 else "car"))
