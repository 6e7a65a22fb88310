"""Pacer: a message leaves at once after a quiet spell and for the first `burst` close together,
then at the steady spacing; never more than `per_second` in any second. Driven by given times."""

from __future__ import annotations

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from umlbot.base.pacing import Pacer


def run(pacer: Pacer, wanted: list[float]) -> list[float]:
    """When each message leaves, each wanted at its time (in order; one waits for the previous)."""
    sent: list[float] = []
    now = 0.0
    for at in wanted:
        now = max(now, at)
        now += pacer.wait(now)
        pacer.sent(now)
        sent.append(now)
    return sent


def most_in_a_second(times: list[float]) -> int:
    """The most of `times` in one half-open interval of one second."""
    best, start = 0, 0
    for end, t in enumerate(times):
        while t - times[start] >= 1.0 - 1e-9:  # (rounding of the sums)
            start += 1
        best = max(best, end - start + 1)
    return best


def test_the_first_after_a_quiet_spell_and_the_burst_leave_at_once_then_the_spacing() -> None:
    pacer = Pacer(50, burst=4)
    assert pacer.interval_s == pytest.approx(1 / 47)
    assert pacer.wait(100.0) == 0.0  # never sent: at once
    for now in (100.0, 100.003, 100.006, 100.009):  # four clusters 3 ms apart: each at once
        assert pacer.wait(now) == 0.0
        pacer.sent(now)
    # the fifth waits: at most one interval after the last one, not a whole burst's worth
    assert 0 < pacer.wait(100.012) <= pacer.interval_s
    assert pacer.wait(100.009) == pytest.approx(100.0 + 4 / 47 - 3 / 47 - 100.009)
    assert pacer.wait(200.0) == 0.0  # quiet again: at once


def test_burst_one_is_a_plain_minimum_spacing() -> None:
    pacer = Pacer.every(0.02)
    assert pacer.interval_s == pytest.approx(0.02) and pacer.burst == 1
    pacer.sent(10.0)
    assert pacer.wait(10.005) == pytest.approx(0.015)
    assert pacer.wait(10.02) == 0.0
    assert Pacer.every(0.0, burst=4).wait(1.0) == 0.0  # no bound
    assert Pacer.every(10.0, burst=4).burst == 1  # no room for a burst under one a second


def test_a_saturated_stream_keeps_the_bound_of_plain_spacing() -> None:
    """A tight loop (a message wanted every 0.1 ms for 5 s) sends no more in any second than the
    plain 20 ms spacing does: 50."""
    wanted = [i * 0.0001 for i in range(50_000)]
    plain = run(Pacer.every(0.02), wanted)
    paced = run(Pacer.every(0.02, burst=4), wanted)
    assert most_in_a_second(plain) == 50
    assert most_in_a_second(paced) <= 50
    assert len({round(t, 9) for t in paced}) >= 5 * 46  # it did keep sending at the steady rate


@settings(max_examples=300, deadline=None)
@given(per_second=st.integers(1, 200), burst=st.integers(1, 8),
       gaps=st.lists(st.floats(0.0, 0.05), min_size=1, max_size=400))
def test_never_more_than_per_second_in_any_second_and_never_a_long_wait(
        per_second: int, burst: int, gaps: list[float]) -> None:
    burst = min(burst, per_second)
    pacer = Pacer(per_second, burst)
    wanted, at = [], 0.0
    for gap in gaps:
        at += gap
        wanted.append(at)
    sent = run(pacer, wanted)
    assert most_in_a_second(sent) <= per_second
    for i, (t, want) in enumerate(zip(sent, wanted, strict=True)):
        # one that waited left at most one interval after the one before it
        assert t == want or (i > 0 and t - sent[i - 1] <= pacer.interval_s + 1e-9)
