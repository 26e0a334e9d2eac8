"""The output guard's peak allowance is a budget that refills over time (flowtex/runtime/safety.py, docs/live.md "Peak rule").

The bounds checked here are the documented ones, derived from the rule and not from the code: at most P consecutive
ticks beyond [lo, hi]; over any window of W ticks at most P (R + W) / (R + P) of them, so at most P / (P + R) of a long
run (P = peak_max_ticks, R = peak_recover_ticks, default 60 P). The reference model below is the rule written with
exact fractions of a tick, independent of the guard's integer units.
"""

from __future__ import annotations

import math
from fractions import Fraction

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from flowtex.runtime.safety import OutputGuard
from flowtex.schema.devmap import PEAK_RECOVER_RATIO

LO, HI, PEAK = -1.0, 1.0, 1.5


def step(g: OutputGuard, value: float, force_safe: bool = False) -> float:
    out = np.zeros(1)
    g.apply(np.array([value]), out, force_safe)
    return float(out[0])


def beyond(outs: list[float]) -> np.ndarray:
    """1 where the output left [LO, HI]."""
    return np.array([o > HI or o < LO for o in outs], dtype=np.int64)


def longest_run(flags: np.ndarray) -> int:
    best = run = 0
    for f in flags:
        run = run + 1 if f else 0
        best = max(best, run)
    return best


def worst_windows(flags: np.ndarray) -> np.ndarray:
    """For each window length W (index W), the most flagged ticks in any window of W consecutive ticks."""
    c = np.concatenate([[0], np.cumsum(flags)])
    n = flags.shape[0]
    return np.array([0] + [int((c[w:] - c[:n + 1 - w]).max()) for w in range(1, n + 1)])


def window_bound(p: int, r: int, w: int) -> float:
    return p * (r + w) / (r + p)


def test_alternating_attack_cannot_sit_at_the_peak_limit():
    """max_ms ticks at the peak limit, one tick inside, repeated: the old rule re-armed the whole allowance on the tick
    inside (20 of every 21 ticks at 1.5 A). Now the share of ticks beyond the clamp is bounded by P / (P + R) (+ the
    one full allowance at the start), with R = 60 P by default."""
    p, ticks = 20, 61_000
    g = OutputGuard(lo=LO, hi=HI, safe=0.0, peak_hi=PEAK, peak_max_ticks=p)
    outs = [step(g, PEAK if k % (p + 1) < p else 0.0) for k in range(ticks)]
    over = int(beyond(outs).sum())
    r = PEAK_RECOVER_RATIO * p
    assert over <= window_bound(p, r, ticks)  # 1019.7 ticks; the old rule gave 58096
    assert over / ticks < 1 / 61 + p / ticks
    # and the allowance does come back: every tick inside refills p / r = 1/60 of a tick, 2904 refilling ticks here
    assert over >= p + (ticks // (p + 1)) // PEAK_RECOVER_RATIO - 1
    assert longest_run(beyond(outs)) == p


def test_the_long_run_share_is_reached_by_the_worst_command():
    """A command at the peak limit whenever a whole peak tick is left, at 0 otherwise, spends the allowance as fast as
    it refills: its share of ticks beyond the clamp tends to P / (P + R) = 1/61 by default, the documented duty."""
    p, ticks = 20, 122_000
    g = OutputGuard(lo=LO, hi=HI, safe=0.0, peak_hi=PEAK, peak_max_ticks=p)
    outs = [step(g, PEAK if g.peak_ticks_left[0] >= 1 else 0.0) for _ in range(ticks)]
    over = int(beyond(outs).sum())
    assert over <= window_bound(p, PEAK_RECOVER_RATIO * p, ticks)
    assert over >= ticks / (PEAK_RECOVER_RATIO + 1) - 1  # 2000 of 122000: the bound is reached, not just respected


def test_one_tick_inside_no_longer_rearms_and_r_ticks_inside_refill_it():
    g = OutputGuard(lo=LO, hi=HI, safe=0.0, peak_hi=3.0, peak_max_ticks=3, peak_recover_ticks=12)
    assert [step(g, 2.5) for _ in range(5)] == [2.5, 2.5, 2.5, 1.0, 1.0]
    assert step(g, 0.5) == 0.5  # refills 3/12 of a tick: not yet one peak tick
    assert step(g, 2.0) == 1.0
    for _ in range(3):
        step(g, 0.0)  # 4 ticks inside in all: one peak tick
    assert [step(g, 2.0) for _ in range(2)] == [2.0, 1.0]
    for _ in range(11):
        step(g, 0.0)  # 11 ticks: 2.75 peak ticks
    assert [step(g, 2.0) for _ in range(3)] == [2.0, 2.0, 1.0]
    for _ in range(100):
        step(g, 0.0)  # capped at the full allowance
    assert g.peak_ticks_left.tolist() == [3]
    assert [step(g, -2.0) for _ in range(4)] == [-2.0, -2.0, -2.0, -1.0]


def test_nonfinite_and_forced_safe_ticks_refill_like_ticks_inside():
    """Their output is the safe value, inside the clamp: the actuator rests, so the allowance refills; a command held
    at the clamp (allowance spent) neither spends nor refills."""
    g = OutputGuard(lo=LO, hi=HI, safe=0.0, peak_hi=3.0, peak_max_ticks=2, peak_recover_ticks=2)
    assert [step(g, 2.0) for _ in range(3)] == [2.0, 2.0, 1.0]
    for _ in range(50):
        assert step(g, 5.0) == 1.0  # clamped: no refill however long
    assert step(g, math.nan) == 0.0
    assert step(g, 2.0, force_safe=True) == 0.0
    assert [step(g, 2.0) for _ in range(3)] == [2.0, 2.0, 1.0]
    g.reset()
    assert g.peak_ticks_left.tolist() == [2] and g.clamp_counts.tolist() == [0]


def test_default_recovery_and_properties():
    g = OutputGuard(lo=[-1.0, -1.0, -1.0], hi=1.0, safe=0.0, peak_hi=2.0, peak_max_ticks=np.array([0, 4, 6]),
                    peak_recover_ticks=np.array([5, 10, 9]))
    assert g.peak_max_ticks.tolist() == [0, 4, 6] and g.peak_recover_ticks.tolist() == [0, 10, 9]
    assert OutputGuard(lo=-1.0, hi=1.0, safe=0.0, peak_hi=2.0, peak_max_ticks=7).peak_recover_ticks.tolist() == [7 * PEAK_RECOVER_RATIO]
    assert [step(OutputGuard(lo=LO, hi=HI, safe=0.0, peak_hi=2.0, peak_max_ticks=0), 1.5) for _ in range(2)] == [1.0, 1.0]


class Reference:
    """The documented rule with an exact fractional budget in ticks."""

    def __init__(self, p: int, r: int) -> None:
        self.p, self.gain, self.budget = p, Fraction(p, r), Fraction(p)

    def step(self, v: float, force_safe: bool) -> float:
        if force_safe or not math.isfinite(v) or LO <= v <= HI:
            self.budget = min(Fraction(self.p), self.budget + self.gain)
            return 0.0 if force_safe or not math.isfinite(v) else v
        if self.budget >= 1:
            self.budget -= 1
            return min(max(v, -PEAK), PEAK)
        return min(max(v, LO), HI)


commands = st.lists(st.tuples(st.sampled_from([0.0, 0.5, -1.0, 1.0, 1.2, -1.4, 1.5, 3.0, -7.0, math.nan, math.inf]),
                              st.integers(0, 9).map(lambda k: k == 0)),  # a forced-safe tick (watchdog) one time in ten
                    min_size=1, max_size=300)


@settings(max_examples=150, deadline=None)
@given(p=st.integers(0, 6), r=st.integers(1, 30), seq=commands)
def test_any_command_sequence_keeps_the_documented_bounds(p, r, seq):
    g = OutputGuard(lo=LO, hi=HI, safe=0.0, peak_hi=PEAK, peak_max_ticks=p, peak_recover_ticks=r)
    ref = Reference(p, r)
    outs = []
    for v, forced in seq:
        o = step(g, v, forced)
        assert o == ref.step(v, forced)
        outs.append(o)
    flags = beyond(outs)
    assert longest_run(flags) <= p
    worst = worst_windows(flags)
    for w in range(1, len(outs) + 1):
        assert worst[w] <= window_bound(p, r, w) + 1e-9, (w, worst[w])
