"""SimClock: discrete sim time, exact sleeps, no time while a call is in flight or a lane computes."""

from __future__ import annotations

import asyncio
import threading
import time

import pytest

from umlbot.sim.clock import SimClock


def test_time_does_not_flow_with_the_wall_clock() -> None:
    clock = SimClock(50.0)
    time.sleep(0.05)
    assert clock.now() == 0.0  # nothing waited for sim time: nothing happened


def test_async_sleep_lasts_exactly_its_sim_time_paced_by_speed() -> None:
    clock = SimClock(10.0)

    async def main() -> tuple[float, float]:
        started = time.monotonic()
        await clock.asleep(0.3)
        return clock.now(), time.monotonic() - started

    now, wall = asyncio.run(main())
    assert now == 0.3
    assert wall >= 0.3 / 10.0 - 0.005  # speed paces the run: 0.3 sim s take 30 ms of wall time


def test_concurrent_sleeps_wake_in_deadline_order_at_their_deadlines() -> None:
    clock = SimClock(50.0)
    woke: list[tuple[str, float]] = []

    async def sleeper(name: str, seconds: float) -> None:
        await clock.asleep(seconds)
        woke.append((name, clock.now()))

    async def main() -> None:
        await asyncio.gather(sleeper("long", 0.4), sleeper("short", 0.2), sleeper("mid", 0.3))

    asyncio.run(main())
    assert woke == [("short", 0.2), ("mid", 0.3), ("long", 0.4)]


def test_time_stands_still_while_a_call_is_in_flight() -> None:
    clock = SimClock(50.0)

    async def main() -> tuple[float, float, bool]:
        sleeper = asyncio.create_task(clock.asleep(0.1))
        clock.call_started()
        await asyncio.sleep(0.05)  # 2.5 sim s of wall time at speed 50: the sleep stays pending
        during = clock.now()
        done_during = sleeper.done()
        clock.call_finished()
        await sleeper
        return during, clock.now(), done_during

    during, after, done_during = asyncio.run(main())
    assert during == 0.0 and not done_during
    assert after == 0.1


def test_a_lane_that_computes_takes_no_sim_time() -> None:
    # a lane that keeps the loop busy (ready to run) holds time, however long it takes on the wall
    clock = SimClock(100.0)
    seen: list[float] = []

    async def busy() -> None:
        for _ in range(100):
            await asyncio.sleep(0)  # ready again at once: the clock may not move meanwhile
            time.sleep(0.0005)  # noqa: ASYNC251 -- the lane computes: it holds the loop
        seen.append(clock.now())

    async def main() -> None:
        await asyncio.gather(busy(), clock.asleep(0.01))

    asyncio.run(main())
    assert seen == [0.0]
    assert clock.now() == 0.01


def test_a_charge_during_a_call_lets_the_other_lanes_sleep_end_on_time() -> None:
    # a sonar ping (charged in a service thread while its call is in flight) takes 0.1 s; a sleep
    # of another lane ends in the middle of it, at its own deadline, and the ping ends at 0.1
    clock = SimClock(20.0)
    events: list[tuple[str, float]] = []

    def ping() -> None:
        clock.charge(0.1)
        events.append(("ping", clock.now()))

    async def call_with_ping() -> None:
        clock.call_started()
        try:
            await asyncio.to_thread(ping)
        finally:
            clock.call_finished()

    async def other_lane() -> None:
        await clock.asleep(0.04)
        events.append(("sleep", clock.now()))

    async def main() -> None:
        await asyncio.gather(call_with_ping(), other_lane())

    asyncio.run(main())
    assert events == [("sleep", 0.04), ("ping", pytest.approx(0.1, abs=1e-12))]


def test_charge_without_an_orchestrator_moves_time_on_at_once() -> None:
    clock = SimClock(1.0)
    clock.charge(0.06)
    assert clock.now() == pytest.approx(0.06, abs=1e-12)


def test_thread_sleep_and_stop_event() -> None:
    clock = SimClock(10.0)
    assert clock.sleep(0.2) is False
    assert clock.now() == pytest.approx(0.2, abs=1e-12)
    stop = threading.Event()
    threading.Timer(0.05, stop.set).start()
    started = time.monotonic()
    assert clock.sleep(100.0, stop) is True
    assert time.monotonic() - started < 5.0


def test_a_cancelled_sleep_leaves_no_deadline_behind() -> None:
    clock = SimClock(100.0)

    async def main() -> float:
        task = asyncio.create_task(clock.asleep(50.0))
        await asyncio.sleep(0.02)
        task.cancel()
        with pytest.raises(asyncio.CancelledError):
            await task
        await clock.asleep(0.5)  # not held behind the cancelled deadline
        return clock.now()

    assert asyncio.run(main()) == 0.5


def test_halt_stops_time_and_release_ends_the_waits() -> None:
    clock = SimClock(100.0)

    async def main() -> tuple[float, bool, float]:
        await clock.asleep(0.1)
        clock.halt()
        sleeper = asyncio.create_task(clock.asleep(0.1))
        await asyncio.sleep(0.05)  # 5 sim s of wall time: a halted clock does not move
        pending = not sleeper.done()
        quiet = await asyncio.to_thread(clock.wait_quiet, 2.0)
        assert quiet  # nothing to do but wait
        clock.release()
        await sleeper
        return clock.now(), pending, clock.now()

    halted_at, pending, after = asyncio.run(main())
    assert halted_at == 0.1 and pending and after == 0.1


def test_time_ends_at_the_limit() -> None:
    clock = SimClock(100.0)
    clock.limit_s = 0.25

    async def main() -> bool:
        task = asyncio.create_task(clock.asleep(1.0))
        for _ in range(200):
            if clock.halted:
                break
            await asyncio.sleep(0.005)
        task.cancel()
        return clock.halted

    assert asyncio.run(main())
    assert clock.now() == 0.25
