"""The monitor's terminal view (rich): availability, lanes, last calls, per-action statistics.

Every cell that shows something from the wire is a `Text`, never a markup string: rich would read
`[true]` (the arguments of `enabled(true)`) or `[bold]` as markup and drop or restyle them.
"""

from __future__ import annotations

import json
import math
import time
from typing import Any

from rich.console import Group, RenderableType
from rich.table import Table
from rich.text import Text

from umlbot.monitor.state import MonitorEvent, MonitorState, Stats

MAX_CELL = 40
#: rows of the statistics tables (the busiest first).
MAX_STATS_ROWS = 20


def _short(value: Any, style: str = "") -> Text:
    """A wire value as plain text (JSON unless it is a string), cut to `MAX_CELL` characters."""
    text = value if isinstance(value, str) else json.dumps(value, ensure_ascii=False, default=str)
    return Text(text if len(text) <= MAX_CELL else text[: MAX_CELL - 1] + "…", style=style)


def _ms(value: float) -> str:
    return "-" if math.isnan(value) else f"{value:.1f}"


def _age(since: float, now: float) -> str:
    seconds = max(0.0, now - since)
    return f"{seconds:.1f}s" if seconds < 120 else f"{seconds / 60:.0f}m"


def _name(robot: str, name: str, many_robots: bool) -> Text:
    return Text(f"{robot}/{name}" if many_robots else name)


def _stats_table(title: str, first: str, rows: list[tuple[Text, Stats]]) -> Table:
    busiest = sorted(rows, key=lambda row: (-row[1].count, row[0].plain))
    shown = busiest[:MAX_STATS_ROWS]
    more = len(busiest) - len(shown)
    table = Table(title=title, title_justify="left", expand=True,
                  caption=f"… and {more} more" if more else None, caption_justify="left")
    table.add_column(first)
    for column in ("count", "errors", "p50 ms", "p99 ms"):
        table.add_column(column, justify="right")
    for name, stats in shown:
        table.add_row(name, str(stats.count), str(stats.errors) if stats.errors else "",
                      _ms(stats.p50), _ms(stats.p99))
    return table


def _call_result(event: MonitorEvent) -> Text:
    if event.ok is None and event.error is None:
        return Text("sent", style="dim")
    if event.ok:
        return _short(event.value, "green") if event.value is not None else Text("ok", style="green")
    return _short(event.error or "error", "red")


def render(state: MonitorState, now: float | None = None, title: str = "umlbot monitor") -> RenderableType:
    """One frame of the live view of `state`."""
    now = time.time() if now is None else now
    robots = {r for r, _ in state.availability} | {r for r, _ in state.lanes} | set(state.orchestrator)
    many = len(robots) > 1
    orchestrator = ", ".join(f"{r}: {s}" for r, s in sorted(state.orchestrator.items())) or "not seen"
    header = Text.assemble(
        (title, "bold"), f"  robot: {', '.join(sorted(robots)) or '-'}  orchestrator: {orchestrator}  ",
        (f"{state.messages} messages, {state.pending_calls} calls pending"
         + (f", {state.malformed} malformed skipped" if state.malformed else "")
         + (f", {state.dropped_rows} rows dropped" if state.dropped_rows else ""), "dim"),
    )

    components = Table(title="Components", title_justify="left", expand=True)
    for column in ("component", "state", "impl", "driver", "for"):
        components.add_column(column)
    for (robot, name), avail in sorted(state.availability.items()):
        style = "green" if avail.state == "online" else "red"
        components.add_row(_name(robot, name, many), Text(avail.state, style=style), Text(avail.impl or ""),
                           Text(avail.driver or ""), _age(avail.since, now))

    lanes = Table(title="Lanes (last node executed)", title_justify="left", expand=True)
    for column in ("lane", "node", "kind", "detail", "ago"):
        lanes.add_column(column)
    for (robot, lane), current in sorted(state.lanes.items()):
        detail = _short(current.error or current.detail or "", "red" if current.error else "")
        lanes.add_row(_name(robot, lane, many), Text(current.node), Text(current.kind), detail,
                      _age(current.at, now))

    calls = Table(title="Last calls", title_justify="left", expand=True)
    for column in ("ago", "call", "args", "result", "latency ms"):
        calls.add_column(column, justify="right" if column == "latency ms" else "left")
    for event in reversed(state.recent_calls):
        calls.add_row(
            _age(event.time, now), _name(event.robot, f"{event.component}.{event.feature}", many),
            _short(event.args if event.args is not None else ""), _call_result(event),
            "-" if event.latency_ms is None else f"{event.latency_ms:.1f}",
        )

    actions = _stats_table(
        "Actions", "action",
        [(_name(r, f"{lane}: {s.label}", many), s) for (r, lane, _node), s in sorted(state.actions.items())],
    )
    features = _stats_table(
        "Calls per feature", "feature",
        [(_name(r, s.label, many), s) for (r, _c, _f), s in sorted(state.features.items())],
    )
    body: list[RenderableType] = [t for t in (components, lanes, calls, actions, features) if t.row_count]
    return Group(header, *(body or [Text("waiting for traffic…", style="dim")]))
