"""Densified model sets (flowtex.models.densify): the same render at their own rate, and resampled sets that follow
their originals between the models (issue 23: "rendered along a path, a resampled set agrees with its original
within LSD 0.5 dB"), by default (--densify auto, flowtex.fit.resample_densify).

Exactness is checked against the original set's own lookup (flowtex.fit.quality.models_at: texture_lookup's
kernel and rule) at random points, PSDs by arma_psd: the models are exact, so the tolerances are rounding only.
"""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest

from flowtex.cli import main
from flowtex.datasets.model_sets import synthetic_model_set
from flowtex.dsp.arma import arma_psd
from flowtex.fit.quality import lissajous_path, models_at, path_lsd_db
from flowtex.fit.resample import resample_model_set
from flowtex.fit.resample_densify import CHECK_PATHS, PATH_MARGIN_DB, resample_densified
from flowtex.io.modelset import load_model_set, save_model_set
from flowtex.models.densify import densify_set, measured_edges, split_edges
from flowtex.models.texture import INTERPOLATION_CHOICES, RenderRule


def _set(rule: str):
    ms = synthetic_model_set(np.array([40.0, 120.0, 250.0]), np.array([0.4, 1.5, 3.0]), ar_order=8, ma_order=6)
    return dataclasses.replace(ms, rule=RenderRule(rule, "fade"))


@pytest.mark.parametrize("rule", INTERPOLATION_CHOICES)
def test_densified_set_renders_the_same_models_everywhere(rule):
    ms = _set(rule)
    dense = densify_set(ms, 2)
    measured = int(np.count_nonzero(ms.variance > 0))
    assert dense.num_models > ms.num_models + 3 * measured                   # two levels of midpoints were added
    np.testing.assert_array_equal(dense.ar_lsf[:ms.num_models], ms.ar_lsf)    # the original models keep their index
    np.testing.assert_array_equal(dense.variance[:ms.num_models], ms.variance)
    assert dense.metadata["densify"] == {"levels": 2, "models_before": ms.num_models,
                                         "models_added": dense.num_models - ms.num_models}
    rng = np.random.default_rng(1)
    # inside the hull, the corner triangles (silent models) included, and beyond the maxima (HaTT's saturation)
    speeds = rng.uniform(0.0, 1.1 * ms.max_speed, 200)
    forces = rng.uniform(0.0, 1.1 * ms.max_force, 200)
    f = np.linspace(1.0, 499.0, 400)
    for (a1, c1, g1, v1), (a2, c2, g2, v2) in zip(models_at(ms, speeds, forces), models_at(dense, speeds, forces), strict=True):
        s1, s2 = arma_psd(a1, c1, g1, v1, f, 1000.0), arma_psd(a2, c2, g2, v2, f, 1000.0)
        np.testing.assert_allclose(s2, s1, rtol=1e-7, atol=1e-12 * max(np.max(s1), 1e-300))


def test_silent_models_stay_silent_and_levels_are_bounded():
    ms = _set("variance")
    dense = densify_set(ms, 1)
    silent = np.flatnonzero(ms.variance == 0)
    assert np.all(dense.variance[silent] == 0)
    # every added model lies between two measured ones: none at speed 0 or force 0
    added = np.arange(ms.num_models, dense.num_models)
    assert np.all(dense.speeds[added] > 0) and np.all(dense.forces[added] > 0) and np.all(dense.variance[added] > 0)
    assert densify_set(ms, 0) is ms
    with pytest.raises(ValueError, match="0 to 3"):
        densify_set(ms, 4)


def _conforming(ms) -> bool:
    """True if no model lies strictly inside an edge of a triangle (no hanging node) and the triangles cover the hull once."""
    pts = np.column_stack([ms.speeds / ms.max_speed, ms.forces / ms.max_force])
    for t in ms.triangles:
        for a, b in ((t[0], t[1]), (t[1], t[2]), (t[2], t[0])):
            d = pts[b] - pts[a]
            rel = pts - pts[a]
            u = rel @ d / (d @ d)
            off = np.abs(rel[:, 0] * d[1] - rel[:, 1] * d[0])
            if np.any((u > 1e-9) & (u < 1 - 1e-9) & (off < 1e-12)):
                return False
    tri = pts[ms.triangles]
    u, v = tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]
    areas = 0.5 * np.abs(u[:, 0] * v[:, 1] - u[:, 1] * v[:, 0])
    return bool(np.all(areas > 0)) and areas.sum() == pytest.approx(float(_hull_area(pts)), rel=1e-12)


def _hull_area(pts):
    from scipy.spatial import ConvexHull

    return ConvexHull(pts).volume


@pytest.mark.parametrize("rule", INTERPOLATION_CHOICES)
def test_partly_split_set_renders_the_same_and_stays_conforming(rule):
    """split_edges on a random subset of edges (what --densify auto does): same models everywhere, no hanging node."""
    ms = _set(rule)
    rng = np.random.default_rng(7)
    dense = ms
    for _ in range(2):
        edges = sorted(measured_edges(dense))
        pick = {edges[i] for i in rng.choice(len(edges), size=3, replace=False)}
        finer = split_edges(dense, pick)
        assert finer.num_models > dense.num_models and set(pick) <= measured_edges(dense)
        np.testing.assert_array_equal(finer.ar_lsf[:dense.num_models], dense.ar_lsf)  # appended, nothing moved
        dense = finer
    assert dense.num_models < densify_set(ms, 2).num_models                   # only part of the set was refined
    assert _conforming(ms) and _conforming(dense)
    rng = np.random.default_rng(2)
    speeds, forces = rng.uniform(0.0, 1.1 * ms.max_speed, 200), rng.uniform(0.0, 1.1 * ms.max_force, 200)
    f = np.linspace(1.0, 499.0, 400)
    for (a1, c1, g1, v1), (a2, c2, g2, v2) in zip(models_at(ms, speeds, forces), models_at(dense, speeds, forces), strict=True):
        s1, s2 = arma_psd(a1, c1, g1, v1, f, 1000.0), arma_psd(a2, c2, g2, v2, f, 1000.0)
        np.testing.assert_allclose(s2, s1, rtol=1e-7, atol=1e-12 * max(np.max(s1), 1e-300))


def _coarse():
    """4 measured 19/17 models at the corners of (60..240 mm/s) x (0.5..2.5 N), 5 silent corners: the blends span far."""
    return synthetic_model_set(np.array([60.0, 240.0]), np.array([0.5, 2.5]), ar_order=19, ma_order=17)


def _worst_path(src, out):
    """Worst path LSD over the check paths and two paths of this test's own (expected spectra, no render noise)."""
    walks = [lissajous_path(src, cycles=c, phase=ph) for c, ph in CHECK_PATHS + (((5.0, 7.0), 0.0), ((2.2, 9.5), 1.7))]
    return max(path_lsd_db(src, out, *w) for w in walks)


def test_default_resample_follows_its_original_along_paths(tmp_path, capsys):
    """The old default (nothing added) misses the 0.5 dB path target on this set at 500 Hz; the default now meets it."""
    ms = _coarse()
    assert _worst_path(ms, resample_model_set(ms, 500.0)) > 0.5              # --densify 0, the old default
    src = save_model_set(ms, tmp_path / "coarse.json")
    out = tmp_path / "coarse_500.json"
    assert main(["models", "resample", str(src), "--rate", "500", "-o", str(out)]) == 0
    assert "densified" in capsys.readouterr().out
    res = load_model_set(out)
    info = json.loads(out.read_text())["metadata"]["densify"]
    assert info["mode"] == "auto" and info["models_added"] == res.num_models - ms.num_models > 0
    assert _worst_path(ms, res) <= 0.5
    assert info["path_lsd_db"] <= PATH_MARGIN_DB < info["path_lsd_db_before"]


def test_fit_texture_render_rate_densifies_as_models_resample_does(tmp_path, capsys):
    """``fit texture --render-rate`` writes its set through the same default: before, it resampled without adding models
    and this set missed the path target (asserted in the test above)."""
    from types import SimpleNamespace

    from flowtex.fit.texture_job import write_outputs

    ms = _coarse()
    out = tmp_path / "fitted_500.json"
    write_outputs(SimpleNamespace(model_set=ms), out, None, 500.0)   # what fit texture does with its fitted set
    assert f"densified {out}" in capsys.readouterr().out
    res = load_model_set(out)
    assert res.sample_rate == 500.0 and res.metadata["densify"]["mode"] == "auto" and res.num_models > ms.num_models
    assert _worst_path(ms, res) <= 0.5


def test_auto_counts_progress_over_every_pass():
    calls = []
    dense, _ = resample_densified(_coarse(), 500.0, progress=lambda done, total: calls.append((done, total)))
    assert dense.metadata["densify"]["levels"] >= 1                          # more than one pass was made
    assert [d for d, _ in calls] == list(range(1, len(calls) + 1))           # one count, never restarting
    assert all(d <= t for d, t in calls)


def test_auto_adds_nothing_to_a_set_that_already_agrees():
    ms = synthetic_model_set(np.array([60.0, 150.0, 240.0]), np.array([0.5, 1.5, 2.5]), ar_order=12, ma_order=10)
    dense, out = resample_densified(ms, 500.0)
    cache: dict = {}
    plain = resample_model_set(ms, 500.0, cache=cache)
    assert dense.num_models == ms.num_models and out.metadata["densify"]["models_added"] == 0
    assert out.metadata["densify"]["path_lsd_db"] <= PATH_MARGIN_DB
    np.testing.assert_array_equal(out.ar_lsf, plain.ar_lsf)                  # the same fits as without densifying
    np.testing.assert_array_equal(out.variance, plain.variance)
    # a cache given to resample_densified serves its fits (none made again) and changes nothing
    calls = []
    _, again = resample_densified(ms, 500.0, progress=lambda d, t: calls.append(d), cache=cache)
    assert calls == [] and again.metadata["densify"] == out.metadata["densify"]
    np.testing.assert_array_equal(again.ar_lsf, out.ar_lsf)
    np.testing.assert_array_equal(again.variance, out.variance)


def test_fit_cache_reuses_fits_without_changing_them():
    ms = _coarse()
    calls = []
    cache: dict = {}
    first = resample_model_set(ms, 500.0, progress=lambda d, t: calls.append(d), cache=cache)
    fits = len(calls)
    again = resample_model_set(ms, 500.0, progress=lambda d, t: calls.append(d), cache=cache)
    assert len(calls) == fits                                                # nothing fitted twice
    dense = split_edges(ms, {sorted(measured_edges(ms))[0]})
    grown = resample_model_set(dense, 500.0, progress=lambda d, t: calls.append(d), cache=cache)
    assert len(calls) == fits + 1                                            # only the added model
    for out in (again, grown):
        np.testing.assert_array_equal(out.ar_lsf[:ms.num_models], first.ar_lsf)
        np.testing.assert_array_equal(out.variance[:ms.num_models], first.variance)


def test_densified_hatt_set_follows_its_original_when_resampled(hatt_files):
    """HaTT "Carpet 3" to 500 Hz: the worst of HaTT's sets resampled as it is; by default it meets the path target.

    One level of densifying alone is not promised to meet it: its figure sits at the target and depends on fits that
    differ in their last bits from one CPU to another (docs/fitting.md, "Across machines"). It at least halves the plain
    resample's miss; ``auto`` adds levels until the target is met."""
    path = next(p for p in hatt_files if p.name == "Models_Carpet 3.xml")
    src = load_model_set(path)
    walk = lissajous_path(src)
    cache: dict = {}  # the three resamples share their models' fits (the same fits: test_fit_cache_reuses_fits...)
    plain = path_lsd_db(src, resample_model_set(src, 500.0, cache=cache), *walk)
    assert plain > 0.5
    assert path_lsd_db(src, resample_model_set(densify_set(src, 1), 500.0, cache=cache), *walk) < plain / 2
    dense, out = resample_densified(src, 500.0, cache=cache)
    assert dense.num_models > src.num_models and _worst_path(src, out) <= 0.5


def test_cli_models_resample_densify(tmp_path, capsys):
    src = save_model_set(_set("power"), tmp_path / "set.json")
    out = tmp_path / "out.json"
    assert main(["models", "resample", str(src), "--rate", "2000", "--densify", "1", "-o", str(out)]) == 0
    assert "densified" in capsys.readouterr().out
    doc = load_model_set(out)
    assert doc.num_models > _set("power").num_models and doc.sample_rate == 2000.0
    assert json.loads(out.read_text())["metadata"]["densify"]["levels"] == 1
    assert doc.rule == RenderRule("power", "fade")                           # the rule carries over
    assert main(["models", "resample", str(src), "--rate", "2000", "--densify", "5", "-o", str(out)]) in (1, 2)
    assert "--densify" in capsys.readouterr().err
    assert main(["models", "resample", str(src), "--rate", "2000", "--densify", "0", "-o", str(out)]) == 0
    assert load_model_set(out).num_models == _set("power").num_models and "densify" not in json.loads(out.read_text())["metadata"]


def test_a_set_silent_along_the_check_paths_is_resampled_and_written(tmp_path, capsys):
    """Two silent spectra were an infinite path LSD: auto densified to its last level, then the set's metadata could not
    be written as JSON (``metadata is not plain JSON ... inf``), naming a temporary file."""
    ms = _set("variance")
    silent = dataclasses.replace(ms, variance=np.zeros_like(ms.variance), source=None)
    assert path_lsd_db(silent, silent, *lissajous_path(silent)) == 0.0
    src = save_model_set(silent, tmp_path / "silent.json")
    assert main(["models", "resample", str(src), "--rate", "2000", "-o", str(tmp_path / "out.json")]) == 0, capsys.readouterr().err
    out = load_model_set(tmp_path / "out.json")
    assert out.sample_rate == 2000.0 and not np.any(out.variance) and out.num_models == silent.num_models
    assert json.loads((tmp_path / "out.json").read_text())["metadata"]["densify"]["path_lsd_db"] == 0.0
