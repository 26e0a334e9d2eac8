"""flowtex bench building blocks: knob parsing, error metrics, Pareto front (no graph compilation: fast)."""

from __future__ import annotations

import numpy as np
import pytest

from flowtex.bench.sweep import parse_knob
from flowtex.dsp.errors import pareto_front, signal_error
from flowtex.errors import FlowtexError


def test_parse_knob():
    assert parse_knob("synth.every=1,2,4") == ("synth.every", [1, 2, 4])
    assert parse_knob("friction.mode=hatt,continuous") == ("friction.mode", ["hatt", "continuous"])
    assert parse_knob("lookup.order=[6, 4];[4, 2]") == ("lookup.order", [[6, 4], [4, 2]])
    with pytest.raises(FlowtexError):
        parse_knob("synth=1,2")


def test_pareto_front_by_brute_force():
    rng = np.random.default_rng(0)
    cost, err = rng.uniform(size=40), rng.uniform(size=40)
    front = pareto_front(cost, err)
    for i in range(40):
        dominated = any(cost[j] <= cost[i] and err[j] <= err[i] and (cost[j] < cost[i] or err[j] < err[i]) for j in range(40))
        assert front[i] == (not dominated)


def test_errors_against_analytic_values():
    t = np.arange(4096)
    x = np.sin(0.3 * t)
    assert signal_error("rms", x, x + 0.5, 1000.0) == pytest.approx(0.5, rel=1e-12)  # constant offset
    # a gain of 2 raises the PSD by 4 everywhere: LSD = 10 log10(4) dB exactly; GFC is scale-free (0 error)
    noise = np.random.default_rng(1).normal(size=4096)
    assert signal_error("lsd", noise, 2.0 * noise, 1000.0) == pytest.approx(10 * np.log10(4.0), rel=1e-12)
    assert signal_error("gfc", noise, 2.0 * noise, 1000.0) == pytest.approx(0.0, abs=1e-12)
