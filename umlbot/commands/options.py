"""Option types shared by the commands.

`Number` is the one click type of every float option: click's `FloatRange` lets `nan`, `inf` and
`1e400` through (NaN passes every comparison, and an infinite time-out removes the bound it sets),
so a bare `FloatRange` is not used anywhere. Seconds are also capped at `MAX_SECONDS`, far below
what the standard library's waits accept (`threading.TIMEOUT_MAX`, about 292 years) — a larger
value overflowed there with a traceback.
"""

from __future__ import annotations

import math
from typing import Any

import click

#: the longest time-out or duration an option accepts: 30 days.
MAX_SECONDS = 30 * 24 * 3600.0


class Number(click.FloatRange):
    """A finite float within [min, max] (bounds optional); NaN and ±infinity exit 2."""

    name = "number"

    def convert(self, value: Any, param: click.Parameter | None, ctx: click.Context | None) -> Any:
        try:
            number = float(value)
        except (TypeError, ValueError):
            self.fail(f"{value!r} is not a valid number.", param, ctx)
        if not math.isfinite(number):
            self.fail(f"{value!r} is not a finite number.", param, ctx)
        return super().convert(number, param, ctx)


def seconds(min: float = 0.0, min_open: bool = False) -> Number:
    """A number of seconds: finite, at least `min`, at most `MAX_SECONDS`."""
    return Number(min=min, max=MAX_SECONDS, min_open=min_open)
