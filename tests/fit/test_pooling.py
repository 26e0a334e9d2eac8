"""Pooling neighbouring pieces (flowtex.fit.pooling) and its place in fit texture: groups, the trend factor, the option.

Expected values are computed independently: the groups by scipy's KD-tree on
the same scaled log coordinates, the trend factor from an exact power law.
The effect on whole surfaces is checked in tests/fit/test_resonant_surfaces.py.
"""

from __future__ import annotations

import json

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial import cKDTree

from flowtex.cli import main
from flowtex.datasets.resonant import textured_exploration
from flowtex.fit.pooling import neighbour_groups, pooled_data, trend_factors
from flowtex.fit.texture import POOL_PIECES, TextureOptions, fit_texture
from flowtex.io.recordings import save_recording

RATE = 1000.0


def _scaled(speeds, forces):
    x = np.log(np.column_stack([speeds, forces]))
    with np.errstate(divide="ignore", invalid="ignore"):
        return x / x.std(axis=0)


points = st.lists(st.tuples(st.floats(5.0, 500.0), st.floats(0.1, 6.0)), min_size=2, max_size=30, unique=True)


@settings(max_examples=60, deadline=None)
@given(points, st.integers(1, 12))
def test_groups_are_the_nearest_pieces_itself_first(pts, k):
    s, f = (np.array(v) for v in zip(*pts, strict=True))
    if np.any(np.log(np.column_stack([s, f])).std(axis=0) < 1e-6):
        return                                  # an axis that does not vary: covered by the next test
    x = _scaled(s, f)
    groups = neighbour_groups(s, f, k)
    want = min(k, len(s))
    for i, g in enumerate(groups):
        assert g[0] == i and len(set(g.tolist())) == want
        # every piece left out is at least as far as the farthest piece taken (ties may go either way)
        d = np.sqrt(np.sum((x - x[i]) ** 2, axis=1))
        out = np.setdiff1d(np.arange(len(s)), g)
        if out.size:
            assert d[out].min() >= d[g].max() - 1e-9
        # and the distances taken are the KD-tree's k smallest
        ref, _ = cKDTree(x).query(x[i], k=want)
        np.testing.assert_allclose(np.sort(d[g]), np.sort(np.atleast_1d(ref)), atol=1e-9)


def test_pieces_all_at_one_point_pool_with_as_many_others():
    groups = neighbour_groups([100.0] * 4, [1.0] * 4, 3)
    assert all(g[0] == i and len(set(g.tolist())) == 3 for i, g in enumerate(groups))


def test_an_axis_that_does_not_vary_is_left_out():
    speeds = [100.0, 110.0, 200.0, 400.0]
    groups = neighbour_groups(speeds, [1.0] * 4, 2)
    assert [g.tolist() for g in groups] == [[0, 1], [1, 0], [2, 1], [3, 2]]
    assert [g.tolist() for g in neighbour_groups(speeds, [1.0] * 4, 1)] == [[0], [1], [2], [3]]


def test_pooled_data_joins_the_group_in_recording_order():
    data = [np.full(3, float(k)) for k in range(4)]
    np.testing.assert_array_equal(pooled_data(data, np.array([2, 0])), [0, 0, 0, 2, 2, 2])


def test_trend_factor_moves_a_groups_mean_power_to_its_own_point():
    """Pieces on an exact power law P = 3 s^2 F: the group's length-weighted mean power times the factor is the
    piece's own power, at the edges of the range as in the middle (where the plain mean would be off by dBs)."""
    rng = np.random.default_rng(3)
    s = rng.uniform(130.0, 320.0, 20)
    f = rng.uniform(0.3, 4.3, 20)
    n = rng.integers(300, 1500, 20)
    p = 3.0 * s ** 2 * f
    groups = neighbour_groups(s, f, 5)
    k = trend_factors(s, f, p, n, groups)
    pooled = np.array([np.sum(n[g] * p[g]) / np.sum(n[g]) for g in groups])
    np.testing.assert_allclose(k * pooled, p, rtol=1e-9)
    assert np.max(np.abs(10 * np.log10(pooled / p))) > 1.0       # without it the edge pieces would be off


def test_trend_factor_is_one_for_a_flat_surface():
    s, f = np.array([100.0, 150.0, 200.0, 300.0]), np.array([1.0, 2.0, 0.5, 3.0])
    k = trend_factors(s, f, np.full(4, 2.0), np.array([300, 400, 500, 600]), neighbour_groups(s, f, 3))
    np.testing.assert_allclose(k, 1.0, rtol=1e-12)


@pytest.fixture(scope="module")
def seed1():
    return textured_exploration(20.0, RATE, seed=1)


def test_pooled_models_scatter_less_around_the_truth(seed1):
    """At the fitted models' own (speed, force), their powers against the true surface's: each piece alone carries
    its second's loudness (2 dB standard deviation per second in the generator); pooled, the scatter shrinks."""
    from flowtex.dsp.arma import arma_output_variance
    from flowtex.fit.quality import models_at

    a = seed1.arrays

    def scatter(pool: int) -> float:
        fit = fit_texture(a["accel"], a["speed"], a["normal_force"], RATE, TextureOptions(order=(4, 2), pool_pieces=pool))
        s = np.array([pc.speed for pc in fit.pieces])
        f = np.array([pc.force for pc in fit.pieces])
        truth = np.array([arma_output_variance(*m) for m in models_at(seed1.truth["surface"], s, f)])
        return float(np.std(10 * np.log10(np.array([pc.fit.output_variance for pc in fit.pieces]) / truth)))

    alone, pooled = scatter(1), scatter(POOL_PIECES)
    assert pooled < 0.6 * alone, (alone, pooled)


def test_cli_pool_option_is_recorded(tmp_path, seed1, capsys):
    rec = tmp_path / "rec.npz"
    save_recording(rec, seed1.arrays, RATE)
    common = ["fit", "texture", str(rec), "--speed", "speed", "--order", "4,2"]
    assert main([*common, "-o", str(tmp_path / "default.json")]) == 0
    assert f"the {POOL_PIECES - 1} nearest, --pool {POOL_PIECES})" in capsys.readouterr().out     # stated in the output
    assert main([*common, "--pool", "1", "-o", str(tmp_path / "alone.json")]) == 0
    assert "--pool" not in capsys.readouterr().out
    default = json.loads((tmp_path / "default.json").read_text())
    alone = json.loads((tmp_path / "alone.json").read_text())
    assert default["metadata"]["pool_pieces"] == POOL_PIECES and alone["metadata"]["pool_pieces"] == 1
    assert default["models"] != alone["models"]
    for bad in ("0", "21"):                     # 1..20: each model's data, and so the fit's time, stay bounded
        assert main([*common, "--pool", bad, "-o", str(tmp_path / "bad.json")]) != 0
        assert "--pool" in capsys.readouterr().err
        assert not (tmp_path / "bad.json").exists()
