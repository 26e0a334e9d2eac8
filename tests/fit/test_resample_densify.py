"""Densified model sets (flowtex.models.densify): the same render at their own rate, and resampled sets that follow
their originals between the models (issue 23: "rendered along a path, a resampled set agrees with its original
within LSD 0.5 dB").

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
from flowtex.io.modelset import load_model_set, save_model_set
from flowtex.models.densify import densify_set
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


def test_densified_hatt_set_follows_its_original_when_resampled(hatt_files):
    """HaTT "Carpet 3" to 500 Hz: path LSD 1.43 dB resampled as it is (the worst of HaTT's sets), 0.42 densified once."""
    path = next(p for p in hatt_files if p.name == "Models_Carpet 3.xml")
    src = load_model_set(path)
    walk = lissajous_path(src)
    assert path_lsd_db(src, resample_model_set(src, 500.0), *walk) > 0.5
    assert path_lsd_db(src, resample_model_set(densify_set(src, 1), 500.0), *walk) <= 0.5


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
