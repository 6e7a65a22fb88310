"""Tables of long-running processes that the wire can make grow: bounded, the busiest rows kept.

A monitor or a studio keys its rows by names that come over MQTT (robot, component, feature,
lane, node). A model has a few dozen of them, but a buggy or hostile client can send thousands
of distinct names, and a process that runs for days must not grow with them (issue 23 §3). A
`RecentDict` holds at most `limit` rows: setting or `touch`ing a row makes it the newest; past the
limit the row untouched for longest goes (and is counted in `dropped`), so the rows a running
model keeps updating stay while a flood of one-off names pushes out only itself.
"""

from __future__ import annotations

from collections import OrderedDict
from collections.abc import Callable
from typing import TypeVar

K = TypeVar("K")
V = TypeVar("V")

#: rows a table of the monitor or the studio keeps at most (a model has a few dozen).
MAX_ROWS = 1000


class RecentDict(OrderedDict[K, V]):
    """A dict of at most `limit` entries, the one touched longest ago dropped first."""

    def __init__(self, limit: int = MAX_ROWS) -> None:
        if limit < 1:
            raise ValueError(f"a table keeps at least 1 row, got {limit}")
        super().__init__()
        self.limit = limit
        #: rows dropped to stay within the limit
        self.dropped = 0

    def __setitem__(self, key: K, value: V) -> None:
        super().__setitem__(key, value)
        self.move_to_end(key)
        if len(self) > self.limit:
            self.popitem(last=False)
            self.dropped += 1

    def touch(self, key: K, make: Callable[[], V]) -> V:
        """The row of `key`, made the newest; a new row `make()` when there is none."""
        value = self.get(key)
        if value is None:
            value = self[key] = make()
        else:
            self.move_to_end(key)
        return value
