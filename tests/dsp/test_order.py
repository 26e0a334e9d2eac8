"""Texture model order reduction: Levinson step-down against Yule-Walker, power kept, the node's order param."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import scipy.linalg
import scipy.signal

from flowtex.datasets.model_sets import poly_from_roots, synthetic_model_set
from flowtex.dsp.arma import arma_output_variance
from flowtex.dsp.lsf import lsf_to_poly_new
from flowtex.dsp.order import step_down, truncate_models
from flowtex.errors import ParamError
from flowtex.io.modelset import load_model_set, save_model_set
from flowtex.node_api import BuildContext
from flowtex.nodes.texture import TextureLookup


def test_step_down_is_the_yule_walker_predictor():
    # The order-m step-down of A equals the Yule-Walker AR(m) fit to the autocorrelation of 1/A (Levinson);
    # autocorrelation from a 6000-sample impulse response (poles <= 0.95: truncation < 1e-130).
    a = poly_from_roots(np.array([0.95, 0.8, 0.7]), np.array([0.4, 1.3, 2.4]))
    imp = np.zeros(6000)
    imp[0] = 1.0
    h = scipy.signal.lfilter([1.0], a, imp)
    r = np.array([np.dot(h[: h.size - k], h[k:]) for k in range(7)])
    for m in (1, 2, 4):
        yw = scipy.linalg.solve_toeplitz(r[:m], -r[1:m + 1])
        np.testing.assert_allclose(step_down(a, m), np.r_[1.0, yw], rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(step_down(a, 6), a)  # same order: unchanged


def test_truncated_models_keep_power_and_are_valid():
    ms = synthetic_model_set([50.0, 250.0], [0.5, 2.5], 8, 6)
    ar, ma, var = truncate_models(ms.ar_lsf, ms.ma_lsf, ms.variance, ms.gain, 4, 2)
    assert ar.shape == (ms.num_models, 4) and ma.shape == (ms.num_models, 2)
    for m in range(ms.num_models):
        assert np.all(np.diff(np.r_[0.0, ar[m], np.pi]) > 0) and np.all(np.diff(np.r_[0.0, ma[m], np.pi]) > 0)
        full = arma_output_variance(lsf_to_poly_new(ms.ar_lsf[m]), lsf_to_poly_new(ms.ma_lsf[m]), ms.gain[m], ms.variance[m])
        red = arma_output_variance(lsf_to_poly_new(ar[m]), lsf_to_poly_new(ma[m]), ms.gain[m], var[m])
        assert red == pytest.approx(full, rel=1e-9, abs=1e-300)  # rounding of the two lattice step-downs


def test_lookup_order_param(tmp_path: Path):
    path = save_model_set(synthetic_model_set([50.0, 250.0], [0.5, 2.5], 8, 6), tmp_path / "m.json")
    params = {"models": load_model_set(path), "low_speed": 0.05, "low_speed_value": 0.0001, "speed_margin": 0.01, "low_force": 0.05,
              "low_force_value": 0.0001, "force_margin": 0.01, "order": [4, 2]}
    node = TextureLookup("lookup", params, BuildContext(rate=1000.0, base_dir=tmp_path))
    out = node.resolve({})
    assert out["ar"].shape == (5,) and out["ma"].shape == (3,)
    with pytest.raises(ParamError, match="1 <= p <= 8"):
        TextureLookup("lookup", {**params, "order": [9, 2]}, BuildContext(rate=1000.0, base_dir=tmp_path))
