"""SimClock: exact sleeps, time that stands still while a call is in flight, charged robot time."""

from __future__ import annotations

import asyncio
import threading
import time

import pytest

from umlbot.sim.clock import HOLD_WALL_S, SimClock


def test_time_runs_at_speed_between_calls() -> None:
    clock = SimClock(20.0)
    time.sleep(0.05)
    assert 0.9 <= clock.now() <= 1.0 + 20 * 0.05  # >= 1 sim s for 50 ms wall, allowing slow wake-ups


def test_time_stands_still_while_a_call_is_in_flight() -> None:
    clock = SimClock(50.0)
    clock.call_started()
    frozen = clock.now()
    time.sleep(0.05)
    assert clock.now() == pytest.approx(frozen, abs=1e-9)
    clock.call_finished()
    time.sleep(0.02)
    assert clock.now() > frozen + 0.5


def test_async_sleep_lasts_exactly_its_sim_time_and_holds_until_the_next_call() -> None:
    clock = SimClock(10.0)

    async def main() -> tuple[float, float]:
        start = clock.now()
        await clock.asleep(0.3)
        woke = clock.now()  # held at the deadline for HOLD_WALL_S
        clock.call_started()  # the sleeper's next command goes out at the deadline
        at_call = clock.now()
        clock.call_finished()
        return woke - start, at_call - start

    slept, at_call = asyncio.run(main())
    # `start` is read a few microseconds of wall time before the sleep registers its deadline
    assert slept == pytest.approx(0.3, abs=2e-3)
    assert at_call == pytest.approx(slept, abs=1e-9)


def test_hold_ends_after_its_wall_time_without_a_call() -> None:
    clock = SimClock(10.0)
    asyncio.run(clock.asleep(0.1))
    held = clock.now()
    time.sleep(HOLD_WALL_S + 0.02)
    assert clock.now() > held


def test_concurrent_sleeps_wake_in_deadline_order() -> None:
    clock = SimClock(20.0)
    woke: list[tuple[str, float]] = []

    async def sleeper(name: str, seconds: float) -> None:
        start = clock.now()
        await clock.asleep(seconds)
        woke.append((name, clock.now() - start))
        clock.call_started()  # end the hold, as the engine's next call would
        clock.call_finished()

    async def main() -> None:
        await asyncio.gather(sleeper("long", 0.4), sleeper("short", 0.2))

    asyncio.run(main())
    assert [name for name, _ in woke] == ["short", "long"]
    assert woke[0][1] == pytest.approx(0.2, abs=2e-3)
    assert woke[1][1] == pytest.approx(0.4, abs=2e-3)


def test_charge_moves_time_on() -> None:
    clock = SimClock(1.0)
    clock.call_started()
    before = clock.now()
    clock.charge(0.06)
    assert clock.now() == pytest.approx(before + 0.06, abs=1e-9)
    clock.call_finished()


def test_thread_sleep_and_stop_event() -> None:
    clock = SimClock(10.0)
    assert clock.sleep(0.2) is False
    stop = threading.Event()
    threading.Timer(0.05, stop.set).start()
    started = time.monotonic()
    assert clock.sleep(100.0, stop) is True
    assert time.monotonic() - started < 5.0


def test_a_cancelled_sleep_leaves_no_deadline_behind() -> None:
    clock = SimClock(10.0)

    async def main() -> None:
        task = asyncio.create_task(clock.asleep(50.0))
        await asyncio.sleep(0.02)
        task.cancel()
        with pytest.raises(asyncio.CancelledError):
            await task

    asyncio.run(main())
    before = clock.now()
    time.sleep(0.05)
    assert clock.now() > before + 0.3  # not clamped at the cancelled deadline
