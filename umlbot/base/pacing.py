"""A bound on how often a stream of messages may leave, with a small burst allowed (GCRA).

`Pacer(per_second, burst)` lets a message leave at once while fewer than `burst` left "early"
(closer together than the steady rate), and never lets more than `per_second` leave in any second
(any half-open interval of one second, wherever it starts). With `burst` 1 it is a plain minimum
spacing of `1 / per_second` seconds: a message leaves when the last one left that long ago.

A larger `burst` serves a robot whose events come in short clusters (a few nodes, a reply, a few
more nodes a few milliseconds later): each cluster leaves as it comes instead of waiting out the
spacing after the first. The price is a slightly slower steady rate (`interval_s`, chosen so that
the per-second bound holds with the burst included: `1 / (per_second + 1 - burst)`); a message
that has to wait never waits longer than `interval_s` after the last one left.

This is the generic cell rate algorithm (virtual scheduling): `_tat` is when the next message
would leave at the steady rate; one may leave `burst - 1` intervals before it. Pure arithmetic on
the times it is given, so it can be driven by any clock (tests use a fake one).
"""

from __future__ import annotations


class Pacer:
    """At most `per_second` messages in any second, up to `burst` of them back to back."""

    def __init__(self, per_second: float, burst: int = 1) -> None:
        if burst < 1 or not per_second + 1 - burst > 0:
            raise ValueError("burst must be >= 1 and at most per_second")
        self.per_second = per_second
        self.burst = burst
        #: the spacing of messages at the steady rate (what a sustained stream gets).
        self.interval_s = 1.0 / (per_second + 1 - burst)
        self._tolerance = (burst - 1) * self.interval_s
        self._tat = -float("inf")  # the theoretical time of the next message

    @classmethod
    def every(cls, window_s: float, burst: int = 1) -> Pacer:
        """One message per `window_s` on average: at most `1 / window_s` in any second (none
        with `window_s` 0: no bound). `burst` is lowered to what that bound leaves room for."""
        if window_s < 0 or burst < 1:
            raise ValueError("window_s must be >= 0 and burst >= 1")
        if window_s == 0:
            return cls(float("inf"), 1)
        per_second = 1.0 / window_s
        return cls(per_second, max(1, min(burst, int(per_second))))

    def wait(self, now: float) -> float:
        """Seconds from `now` until a message may leave (0.0: now)."""
        return max(0.0, self._tat - self._tolerance - now)

    def sent(self, now: float) -> None:
        """A message left at `now` (also one that left early on purpose, e.g. a full batch)."""
        self._tat = max(self._tat, now) + self.interval_s
