"""Model resampling: physical PSDs compared with the original model's, evaluated independently with arma_psd.

Requirements (issue 11): up to 0.9 x the lower Nyquist LSD <= 0.5 dB and band power within 2 %; nothing folded in
from above the new Nyquist when downsampling; at most 2 % of the power above the old Nyquist when upsampling.
The models are exact (no data), so the tolerances are the issue's, with no statistical allowance.
"""

from __future__ import annotations

import json

import numpy as np
import pytest

from flowtex.cli import main
from flowtex.dsp.arma import arma_output_variance, arma_psd
from flowtex.dsp.arma_resample import resample_arma
from flowtex.dsp.lsf import is_valid_lsf
from flowtex.dsp.spectral import lsd_db
from flowtex.io.hatt import write_hatt_xml
from flowtex.io.modelset import load_model_set, save_model_set
from flowtex.models.synthetic import hatt_like_model, synthetic_model_set


def _band(f, s):
    return float(np.trapezoid(s, f))


@pytest.mark.parametrize("fs2", [500.0, 400.0])
def test_downsampling_keeps_band_and_folds_nothing(fs2):
    # hatt_like_model(1) has 5 % of its power above 250 Hz and 38 % above 200 Hz: there is something to fold
    a, c = hatt_like_model(1)
    fs1 = 1000.0
    a2, c2, g2, v2 = resample_arma(a, c, 0.7, 2.0, fs1, fs2)
    assert np.max(np.abs(np.roots(a2))) < 1.0 and np.max(np.abs(np.roots(c2))) < 1.0
    f = np.linspace(0.0, 0.9 * fs2 / 2, 4001)
    s1 = arma_psd(a, c, 0.7, 2.0, f, fs1)
    s2 = arma_psd(a2, c2, g2, v2, f, fs2)
    assert lsd_db(s2, s1, f, min_freq_hz=0.0) <= 0.5
    assert abs(_band(f, s2) / _band(f, s1) - 1.0) <= 0.02
    # no fold-in: the new model's total power is the original's power below the new Nyquist (dense trapezoid of
    # the original's PSD), not its total power (which is larger by what lies in 250..500 Hz)
    fn = np.linspace(0.0, fs2 / 2, 200001)
    below = _band(fn, arma_psd(a, c, 0.7, 2.0, fn, fs1))
    total_new = arma_output_variance(a2, c2, g2, v2)
    assert abs(total_new / below - 1.0) <= 0.02
    assert below < 0.98 * arma_output_variance(a, c, 0.7, 2.0)  # the case does have power to fold


def test_upsampling_adds_little_above_old_nyquist():
    a, c = hatt_like_model(0)
    fs1, fs2 = 1000.0, 2000.0
    a2, c2, g2, v2 = resample_arma(a, c, 1.0, 1.0, fs1, fs2)
    fa = np.linspace(0.0, fs2 / 2, 400001)
    s2 = arma_psd(a2, c2, g2, v2, fa, fs2)
    above = _band(fa[fa > fs1 / 2], s2[fa > fs1 / 2]) / _band(fa, s2)
    assert above <= 0.02
    f = np.linspace(0.0, 0.9 * fs1 / 2, 4001)
    s1 = arma_psd(a, c, 1.0, 1.0, f, fs1)
    s2b = arma_psd(a2, c2, g2, v2, f, fs2)
    assert abs(_band(f, s2b) / _band(f, s1) - 1.0) <= 0.02
    assert lsd_db(s2b, s1, f, min_freq_hz=0.0) <= 0.5  # measured 0.11 dB for this model (others: see docs/fitting.md)


def test_same_rate_is_identity():
    a, c = hatt_like_model(3)
    a2, c2, g2, v2 = resample_arma(a, c, 0.5, 3.0, 1000.0, 1000.0)
    assert np.array_equal(a2, a) and np.array_equal(c2, c) and (g2, v2) == (0.5, 3.0)


def test_cli_resample_model_set(tmp_path, capsys):
    # HaTT XML input (exact floats), 2 measured + 4 silent models
    ms = load_model_set(write_hatt_xml(synthetic_model_set([60.0], [0.5, 1.5], ar_order=8, ma_order=6), tmp_path / "in.xml"))
    src = ms.source
    out = tmp_path / "out.json"
    assert main(["models", "resample", str(src), "--rate", "500", "-o", str(out)]) == 0
    assert "worst LSD" in capsys.readouterr().out
    res = load_model_set(out)
    assert res.sample_rate == 500.0 and res.num_models == ms.num_models
    np.testing.assert_array_equal(res.speeds, ms.speeds)
    np.testing.assert_array_equal(res.triangles, ms.triangles)
    assert np.all(res.variance[ms.variance == 0.0] == 0.0)  # silent models stay silent
    for m in range(res.num_models):
        assert is_valid_lsf(res.ar_lsf[m]) and is_valid_lsf(res.ma_lsf[m])
        if ms.variance[m] > 0:
            f = np.linspace(0.0, 0.9 * 250.0, 2001)
            s1 = arma_psd(ms.ar_coeff[m], ms.ma_coeff[m], ms.gain[m], ms.variance[m], f, 1000.0)
            s2 = arma_psd(res.ar_coeff[m], res.ma_coeff[m], res.gain[m], res.variance[m], f, 500.0)
            assert lsd_db(s2, s1, f, min_freq_hz=0.0) <= 0.5
    assert json.loads(out.read_text())["metadata"]["resample"]["from_hz"] == 1000.0


def test_cli_resample_errors(tmp_path, capsys):
    out = tmp_path / "out.json"
    assert main(["models", "resample", str(tmp_path / "missing.json"), "--rate", "500", "-o", str(out)]) == 1
    assert "no such model file" in capsys.readouterr().err
    src = save_model_set(synthetic_model_set([60.0], [0.5], ar_order=4, ma_order=2), tmp_path / "in.json")
    assert main(["models", "resample", str(src), "--rate", "-5", "-o", str(out)]) == 1
    assert "--rate must be a positive" in capsys.readouterr().err
    assert not out.exists()
