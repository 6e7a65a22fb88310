"""When the studio's hub sends to its pages: a lone event at once, the first few flushes of a
robot's burst at once, and never more than `FLUSHES_PER_S` flushes in any second however fast
events come (the pages' frames are bounded as before the burst was allowed)."""

from __future__ import annotations

import asyncio
import threading
import time
from typing import Any

import pytest

from umlbot.studio import hub as hub_module
from umlbot.studio.hub import FLUSH_BURST, FLUSHES_PER_S, Hub, Page


class CountingPage(Page):
    """A page whose frames are only counted (nothing is sent)."""

    def __init__(self) -> None:
        async def send(text: str) -> None:
            return None

        super().__init__(send)
        self.frames: list[str] = []

    def put(self, text: str, events: bool = False) -> bool:
        if events:
            self.frames.append(text)
        return True


class FrozenClock:
    """A `time` stand-in whose monotonic clock only moves when told (the loop's own runs on)."""

    def __init__(self) -> None:
        self.now = 1000.0

    def monotonic(self) -> float:
        return self.now


def event(i: int) -> dict[str, Any]:
    return {"type": "trace", "time": 1000.0 + i, "robot": "car", "lane": "Main", "node": f"n{i}",
            "kind": "action", "duration_ms": 1.0, "level": "info", "detail": "x", "seq": i}


def test_a_lone_event_and_the_first_flushes_of_a_burst_go_at_once(monkeypatch: pytest.MonkeyPatch) -> None:
    """The mechanism, on a frozen clock: a push after a quiet spell is flushed at the loop's next
    turn, so are the next `FLUSH_BURST - 1`; the one after waits one interval (~10 ms)."""
    clock = FrozenClock()
    monkeypatch.setattr(hub_module, "time", clock)

    async def run() -> None:
        hub = Hub()
        task = asyncio.create_task(hub.run())
        await asyncio.sleep(0)
        page = CountingPage()
        hub.pages.add(page)
        clock.now += 1.0  # quiet since the hub's first flush (at its start)
        interval = hub.pacer.interval_s
        assert FLUSH_BURST == 4 and interval == pytest.approx(1 / (FLUSHES_PER_S + 1 - FLUSH_BURST))
        for i in range(FLUSH_BURST):  # trace messages 1 ms apart: each is on the page at once
            hub.push(event(i))
            await asyncio.sleep(0)
            await asyncio.sleep(0)
            assert len(page.frames) == i + 1
            clock.now += 0.001
        hub.push(event(9))
        await asyncio.sleep(0)
        await asyncio.sleep(0)
        assert len(page.frames) == FLUSH_BURST  # waits
        clock.now += interval
        await asyncio.sleep(interval + 0.01)  # the loop's timer runs on the real clock
        assert len(page.frames) == FLUSH_BURST + 1
        assert '"seq":9' in page.frames[-1]
        task.cancel()

    asyncio.run(run())


def test_a_flood_of_events_makes_at_most_100_flushes_in_any_second() -> None:
    """Events pushed from another thread (the bus's) every ~0.2 ms for 1.5 s: the pages get at
    most `FLUSHES_PER_S` frames in any second, each carrying many events."""
    flushed: list[float] = []
    pushed = 0

    async def run() -> CountingPage:
        nonlocal pushed
        hub = Hub()
        task = asyncio.create_task(hub.run())
        await asyncio.sleep(0)
        page = CountingPage()
        hub.pages.add(page)
        pacer_sent = hub.pacer.sent

        def sent(now: float) -> None:
            flushed.append(now)
            pacer_sent(now)

        hub.pacer.sent = sent  # type: ignore[method-assign]

        def flood() -> None:
            nonlocal pushed
            end = time.monotonic() + 1.5
            while time.monotonic() < end:
                hub.push(event(pushed))
                pushed += 1
                time.sleep(0.0002)

        pusher = threading.Thread(target=flood)
        pusher.start()
        await asyncio.to_thread(pusher.join)
        await asyncio.sleep(0.05)
        task.cancel()
        return page

    page = asyncio.run(run())
    most = 0
    for first, at in enumerate(flushed):  # any half-open second
        most = max(most, sum(1 for later in flushed[first:] if later - at < 1.0))
    assert most <= FLUSHES_PER_S
    assert len(page.frames) == len(flushed) < pushed / 3  # many events to a frame
    assert sum(frame.count('"type":"trace"') for frame in page.frames) == pushed  # none lost
