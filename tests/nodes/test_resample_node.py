"""The resample node inside graphs: up and down by integer factors, tones, latency, chunks, live, errors.

References: scipy.signal.upfirdn with the node's own filter (same numbers to
round-off), analytic tones (least-squares amplitude), the filter's group delay.
"""

from __future__ import annotations

import numpy as np
import pytest
import scipy.signal

import flowtex
from flowtex.dsp.resample_stream import polyphase_filter
from flowtex.errors import GraphError
from flowtex.graph.describe import describe_graph

DOWN = """\
flowtex: 1
name: down
rate: 1000
inputs:
  x: {shape: [2], unit: m/s^2}
nodes:
  rs: {type: resample, params: {to_hz: 250}}
  slow: {type: gain, every: 4, params: {k: 1.0}}
edges:
  - x -> rs.x
  - rs.y -> slow.x
outputs:
  y: rs.y
  z: slow.y
"""

UP = """\
flowtex: 1
name: up
rate: 1000
inputs:
  x: {unit: N}
nodes:
  slow: {type: gain, every: 4, params: {k: 1.0}}
  rs: {type: resample, params: {to_hz: 1000}}
edges:
  - x -> slow.x
  - slow.y -> rs.x
outputs:
  y: rs.y
"""


def test_down_by_4_matches_upfirdn_and_holds_between_outputs(write_graph) -> None:
    g = flowtex.load_graph(write_graph(DOWN))
    x = np.random.default_rng(0).standard_normal((1000, 2))
    out = g.run({"x": x})
    h = polyphase_filter(1, 4, 80.0)
    ref = scipy.signal.upfirdn(h, x, 1, 4, axis=0)[:250]
    # Same sums in another order: round-off only (1e-12 on unit-variance noise).
    np.testing.assert_allclose(out["y"][::4], ref, rtol=0, atol=1e-12)
    np.testing.assert_array_equal(out["y"], np.repeat(out["y"][::4], 4, axis=0))
    np.testing.assert_array_equal(out["z"], out["y"])  # the 250 Hz consumer reads each new sample
    lat = (h.size - 1) // 2
    assert g.resolved.nodes["rs"].node.latency_samples() == lat and lat % 4 == 0
    assert f"latency {lat} samples ({lat:g} ms)" in describe_graph(g)


def test_up_by_4_matches_upfirdn(write_graph) -> None:
    g = flowtex.load_graph(write_graph(UP))
    x = np.random.default_rng(1).standard_normal(800)
    y = g.run({"x": x})["y"]
    h = polyphase_filter(4, 1, 80.0)
    np.testing.assert_allclose(y, scipy.signal.upfirdn(4 * h, x[::4], 4, 1)[:800], rtol=0, atol=1e-12)


def tone_amp(y: np.ndarray, rate: float, f: float) -> float:
    t = np.arange(y.size) / rate
    a = np.stack([np.cos(2 * np.pi * f * t), np.sin(2 * np.pi * f * t)], axis=1)
    coef, *_ = np.linalg.lstsq(a, y, rcond=None)
    return float(np.hypot(*coef))


@pytest.mark.parametrize("atten", [60.0, 90.0])
def test_down_keeps_a_passband_tone_and_removes_an_aliasing_one(write_graph, atten) -> None:
    g = flowtex.load_graph(write_graph(DOWN), {"rs.atten_db": atten})
    t = np.arange(6000) / 1000.0
    pass_tone, alias_tone = np.cos(2 * np.pi * 90.0 * t), np.cos(2 * np.pi * 160.0 * t)  # 160 Hz aliases to 90 Hz at 250 Hz
    skip = 300 // 4  # past the filter's start-up
    y_pass = g.run({"x": np.stack([pass_tone, pass_tone], axis=1)})["y"][::4, 0][skip:]
    y_alias = g.run({"x": np.stack([alias_tone, alias_tone], axis=1)})["y"][::4, 0][skip:]
    assert abs(20 * np.log10(tone_amp(y_pass, 250.0, 90.0))) <= 0.1  # 90 Hz = 0.72 x Nyquist: in the passband
    assert 20 * np.log10(tone_amp(y_alias, 250.0, 90.0)) <= -atten + 0.1  # the design checks its stopband on a grid


def test_chunked_and_live_equal_one_pass(write_graph) -> None:
    g = flowtex.load_graph(write_graph(UP))
    x = np.random.default_rng(2).standard_normal(300)
    whole = g.run({"x": x})["y"]
    g.reset()
    parts = [g.process({"x": x[a:b]})["y"] for a, b in [(0, 3), (3, 101), (101, 300)]]
    np.testing.assert_array_equal(np.concatenate(parts), whole)
    g.reset()
    np.testing.assert_array_equal([g.step({"x": v})["y"] for v in x[:120]], whole[:120])


BAD = """\
flowtex: 1
name: bad
rate: 1000
inputs:
  x: {{unit: N}}
nodes:
  slow: {{type: gain, every: {every}, params: {{k: 1.0}}}}
  rs: {{type: resample{extra}, params: {{{params}}}}}
edges:
  - x -> slow.x
  - slow.y -> rs.x
outputs:
  y: rs.y
"""


@pytest.mark.parametrize("every,params,extra,match", [
    (1, "to_hz: 300", "", "does not divide the graph's base rate"),
    (2, "to_hz: 333.3333333333333", "", "not an integer ratio"),
    (2, "to_hz: 500", "", "already arrives at 500 Hz"),
    (1, "to_hz: 250, from_hz: 500", "", "input 'x' arrives at 1000 Hz"),
    (1, "to_hz: 250", ", every: 4", "drop every:"),
])
def test_bad_rates_are_one_line_errors(write_graph, every, params, extra, match) -> None:
    with pytest.raises(GraphError, match=match) as info:
        flowtex.load_graph(write_graph(BAD.format(every=every, params=params, extra=extra)))
    assert len(str(info.value).splitlines()) == 1


@pytest.mark.parametrize(("to_hz", "words"), [
    (0.01, "is a factor of 100,000; a resample node changes the rate by at most 1000x up or down"),  # took 2 minutes
    (1e-300, "is more than 1,000,000 ticks of the graph's base rate"),  # numpy "Maximum allowed size exceeded"
])
def test_a_rate_change_beyond_the_filter_limit_is_refused_at_once(to_hz, words) -> None:
    # refused from the rates alone, before any filter is designed (at 0.01 Hz the design took 129 s)
    from flowtex.graph.builder import GraphBuilder

    with pytest.raises(GraphError, match=words):
        GraphBuilder("r").input("x").node("r", "resample", to_hz=to_hz).edge("x -> r.x").output("y", "r.y").resolve()
    GraphBuilder("r").input("x").node("r", "resample", to_hz=1.0).edge("x -> r.x").output("y", "r.y").resolve()  # 1000x: allowed
