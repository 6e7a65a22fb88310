"""Signal occurrences on their way to accept-event nodes, with the buffering policy of umlbot.

fUML drops a signal that no accept-event node is waiting for at the moment it arrives. On a robot
that loses events to plain timing (the lane was busy one action before its accept), so umlbot
keeps the newest unconsumed occurrence of each signal name (a mailbox of one per name):

- an occurrence goes to every accept node waiting for its name at that moment;
- when none waits, it is held; a newer occurrence of the same name replaces it;
- an accept node that finds a held occurrence consumes it at once.

Everything here runs on the orchestrator's event loop thread.
"""

from __future__ import annotations

import asyncio

from services.orchestrator.expressions import Value
from umlbot.logs import get_logger

log = get_logger(__name__)


class SignalBoard:
    """Waiting accept nodes and held occurrences, by signal name."""

    def __init__(self) -> None:
        self._waiters: dict[str, list[asyncio.Future[Value]]] = {}
        self._held: dict[str, Value] = {}

    def deliver(self, name: str, payload: Value) -> int:
        """Hand an occurrence to the waiting accept nodes (or hold it); returns how many woke."""
        waiters = [f for f in self._waiters.pop(name, ()) if not f.done()]
        for future in waiters:
            future.set_result(payload)
        if not waiters:
            if name in self._held:
                log.debug("signal replaced an unconsumed one", signal=name)
            self._held[name] = payload
        return len(waiters)

    async def wait(self, name: str) -> Value:
        """The payload of the next occurrence of `name` (a held one first)."""
        if name in self._held:
            return self._held.pop(name)
        future: asyncio.Future[Value] = asyncio.get_running_loop().create_future()
        waiters = self._waiters.setdefault(name, [])
        waiters.append(future)
        try:
            return await future
        finally:
            if not future.done() or future.cancelled():
                waiters = self._waiters.get(name, [])
                if future in waiters:
                    waiters.remove(future)

    def waiting(self, name: str) -> int:
        """How many accept nodes wait for `name` right now."""
        return sum(1 for f in self._waiters.get(name, ()) if not f.done())

    def held(self, name: str) -> bool:
        """True when an unconsumed occurrence of `name` is held."""
        return name in self._held
