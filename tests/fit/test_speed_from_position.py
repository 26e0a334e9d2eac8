"""fit's speed from position is the speed_estimator node's (method hatt) as a graph runs it, bit for bit."""

from __future__ import annotations

import numpy as np
import pytest

from flowtex.fit.texture_job import speed_from_position
from flowtex.graph.builder import GraphBuilder


@pytest.mark.parametrize("with_normal", [False, True])
def test_speed_from_position_is_the_graph_node(with_normal):
    rate, n = 1000.0, 4000
    rng = np.random.default_rng(1)
    pos = np.cumsum(rng.normal(size=(n, 3)) * [0.05, 0.05, 0.001], axis=0)
    pos[1000:1500] = pos[999]  # a stationary stretch: the gate holds the speed at 0
    normal = np.tile([0.1, 0.0, 1.0], (n, 1)) if with_normal else None
    b = GraphBuilder("speed", rate=rate).input("position", shape=3, unit="mm")
    if with_normal:
        b.input("normal", shape=3).edge("normal -> est.normal")
    b.node("est", "speed_estimator", method="hatt").edge("position -> est.position").output("speed", "est.speed")
    inputs = {"position": pos} | ({"normal": normal} if with_normal else {})
    want = b.build(tier="dispatch").run(inputs)["speed"].reshape(-1)
    got = speed_from_position(pos, normal, rate)
    assert np.array_equal(got, want)
    assert np.all(got[1100:1500] == 0.0) and np.mean(got) > 1.0
