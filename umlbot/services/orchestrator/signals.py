"""Signal occurrences on their way to accept-event nodes, with the buffering policy of umlbot.

fUML drops a signal that no accept-event node is waiting for at the moment it arrives. On a robot
that loses events to plain timing (the lane was busy one action before its accept), so umlbot
keeps the newest unconsumed occurrence of each signal name (a mailbox of one per name):

- an occurrence goes to every accept node waiting for its name at that moment;
- when none waits, it is held; a newer occurrence of the same name replaces it;
- an accept node that finds a held occurrence consumes it at once.

Signal names come from the wire (any topic `umlbot/<robot>/signal/<name>`), so the board built
for a model (`SignalBoard.for_model`) takes only the names its accept nodes wait for: at most one
held occurrence per accept node's signal, whatever other publishers send. Other names are
ignored: the model's own sends that nothing in it accepts silently, foreign names with one
warning line at most every `FOREIGN_LOG_INTERVAL_S` (never a line per message).

Everything here runs on the orchestrator's event loop thread.
"""

from __future__ import annotations

import asyncio
import time
from collections.abc import Callable, Iterable

from umlbot.base.logs import get_logger
from umlbot.compiler.compiled import AcceptNode, CompiledModel, SendNode
from umlbot.services.orchestrator.expressions import Value

log = get_logger(__name__)

#: at most one warning line per this many seconds about ignored foreign signal names
FOREIGN_LOG_INTERVAL_S = 60.0


class SignalBoard:
    """Waiting accept nodes and held occurrences, by signal name.

    `accepted`: the names taken (None: every name); `own`: names ignored without a log line (the
    model's sends that it does not accept itself).
    """

    def __init__(self, accepted: Iterable[str] | None = None, own: Iterable[str] = (),
                 clock: Callable[[], float] = time.monotonic) -> None:
        self.accepted: frozenset[str] | None = None if accepted is None else frozenset(accepted)
        self._own = frozenset(own)
        self._clock = clock
        self._waiters: dict[str, list[asyncio.Future[Value]]] = {}
        self._held: dict[str, Value] = {}
        #: occurrences ignored because no accept node of the model takes their name
        self.ignored = 0
        self._foreign_logged_at: float | None = None
        self._foreign_unlogged = 0

    @classmethod
    def for_model(cls, model: CompiledModel, clock: Callable[[], float] = time.monotonic) -> SignalBoard:
        """A board taking the signals the model's accept nodes wait for."""
        nodes = [node for lane in model.lanes.values() for node in lane.nodes.values()]
        accepted = {node.signal for node in nodes if isinstance(node, AcceptNode)}
        sent = {node.signal for node in nodes if isinstance(node, SendNode)}
        return cls(accepted, sent - accepted, clock)

    def accepts(self, name: str) -> bool:
        """True when occurrences of `name` are taken (safe from any thread: `accepted` is frozen)."""
        return self.accepted is None or name in self.accepted

    def deliver(self, name: str, payload: Value) -> int:
        """Hand an occurrence to the waiting accept nodes (or hold it); returns how many woke."""
        if not self.accepts(name):
            self._ignore(name)
            return 0
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

    def _ignore(self, name: str) -> None:
        self.ignored += 1
        if name in self._own:
            return
        self._foreign_unlogged += 1
        now = self._clock()
        if self._foreign_logged_at is not None and now - self._foreign_logged_at < FOREIGN_LOG_INTERVAL_S:
            return
        log.warning("ignoring signals that no accept node of the model waits for", signal=name,
                    ignored=self._foreign_unlogged, accepted=sorted(self.accepted or ()),
                    next_report_after_s=FOREIGN_LOG_INTERVAL_S)
        self._foreign_logged_at = now
        self._foreign_unlogged = 0
