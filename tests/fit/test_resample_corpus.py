"""`models resample` on sets shaped like real ones (issue 23): HaTT's published sets, rough flat-to-Nyquist sets,
resonances at the old Nyquist's edge and copper-like narrow peaks, to 2 kHz and to 500 Hz.

Before: HaTT "Brick 1" to 2 kHz left 3 of 57 models over 0.5 dB (worst 1.31 dB) and nothing was written; a rough
set to 500 Hz left one model 42 dB off; a set shaped like flowtex's own fits of real-like recordings (real poles at
the old Nyquist) left every model 1-2 dB off at 2 kHz. Every model is checked here independently of the resampler's bookkeeping:
rebuilt from its stored LSFs (as texture_lookup renders it), PSDs by arma_psd, the LSD by lsd_db on a dense grid
plus every resonance frequency (narrow peaks are sampled at their top), band power by trapezoid up to 0.9 x the
lower Nyquist, power above the old Nyquist by a dense trapezoid. The limits are the issue's: the models are exact,
so there is no statistical allowance. HaTT's files are never in the repository: those cases skip without them.
"""

from __future__ import annotations

import numpy as np
import pytest

from flowtex.datasets.model_sets import edge_resonance_model_set, narrow_peak_model_set, nyquist_pole_model_set, rough_model_set
from flowtex.dsp.arma import arma_psd
from flowtex.dsp.lsf import is_valid_lsf, lsf_to_poly_new
from flowtex.dsp.spectral import lsd_db
from flowtex.fit.quality import lissajous_path, path_lsd_db
from flowtex.fit.resample import resample_model_set
from flowtex.io.modelset import load_model_set

# HaTT sets covered by the test (benchmarks/bench_model_resample.py --hatt runs all 100, docs/fitting.md): "Brick 1"
# is the case and needs the elliptic edge; "Wood" and "Sandpaper 100" keep their own order at both rates.
HATT_SETS = ("Brick 1", "Wood", "Sandpaper 100")


def _rendered(ms, m):
    return lsf_to_poly_new(ms.ar_lsf[m]), lsf_to_poly_new(ms.ma_lsf[m])


def _model_figures(src, res, m):
    """(LSD dB, band-power error, fraction of power above the old Nyquist) of model m of ``res`` against ``src``."""
    fs1, fs2 = src.sample_rate, res.sample_rate
    a1, c1 = _rendered(src, m)
    a2, c2 = _rendered(res, m)
    top = 0.45 * min(fs1, fs2)
    peaks = np.r_[np.abs(np.angle(np.roots(a1))) * fs1, np.abs(np.angle(np.roots(a2))) * fs2] / (2 * np.pi)
    f = np.unique(np.r_[np.linspace(0.0, top, 20001), peaks[peaks <= top]])
    s1 = arma_psd(a1, c1, src.gain[m], 1.0, f, fs1)  # unit variance: a silent model's shape is checked too
    s2 = arma_psd(a2, c2, res.gain[m], res.variance[m] / src.variance[m] if src.variance[m] > 0 else 1.0, f, fs2)
    if src.variance[m] == 0:  # the resampler keeps it silent; its shape matters once interpolated: level fitted out
        s2 = s2 * np.trapezoid(s1, f) / np.trapezoid(s2, f)
    band = float(np.trapezoid(s2, f) / np.trapezoid(s1, f) - 1.0)
    above = 0.0
    if fs2 > fs1:
        fa = np.linspace(0.0, fs2 / 2, 100001)
        sa = arma_psd(a2, c2, 1.0, 1.0, fa, fs2)
        above = float(np.trapezoid(sa[fa > fs1 / 2], fa[fa > fs1 / 2]) / np.trapezoid(sa, fa))
    return lsd_db(s2, s1, f, min_freq_hz=0.0), band, above


_CACHE: dict = {}


def _resampled(src, rate, key):
    """``src`` resampled to ``rate``, once per test session for each key (the set's tests share it)."""
    if (key, rate) not in _CACHE:
        _CACHE[(key, rate)] = resample_model_set(src, rate)
    return _CACHE[(key, rate)]


def _hatt(hatt_files, name):
    path = next((f for f in hatt_files if f.name == f"Models_{name}.xml"), None)
    if path is None:
        pytest.skip(f"Models_{name}.xml is not among the HaTT files here")
    return load_model_set(path)


def _check_set(src, rate, key):
    out = _resampled(src, rate, key)
    info = out.metadata["resample"]
    assert info["misses"] == [], info["misses"]
    assert out.num_models == src.num_models and np.array_equal(out.triangles, src.triangles)
    assert np.all(out.variance[src.variance == 0] == 0)  # silent models stay silent
    for m in range(src.num_models):
        assert is_valid_lsf(out.ar_lsf[m]) and is_valid_lsf(out.ma_lsf[m])
        lsd, band, above = _model_figures(src, out, m)
        assert lsd <= 0.5, (m, lsd)
        if src.variance[m] > 0:
            assert abs(band) <= 0.02, (m, band)
        assert above <= 0.02, (m, above)
    return out


@pytest.mark.parametrize("rate", [2000.0, 500.0])
@pytest.mark.parametrize("name", HATT_SETS)
def test_hatt_set_resamples_without_misses(hatt_files, name, rate):
    src = _hatt(hatt_files, name)
    out = _check_set(src, rate, name)
    if rate > src.sample_rate and name == "Brick 1":
        # flat up to the old Nyquist: its own 14/12 roots cannot also fall 30 dB there; the elliptic edge does
        assert out.metadata["resample"]["edge_lowpass"]


@pytest.mark.parametrize("rate", [2000.0, 500.0])
@pytest.mark.parametrize("make", [rough_model_set, edge_resonance_model_set, nyquist_pole_model_set],
                         ids=["rough", "edge-resonance", "nyquist-pole"])
def test_generated_hard_sets_resample_without_misses(make, rate):
    _check_set(make(), rate, make.__name__)


@pytest.mark.parametrize("rate", [2000.0, 500.0])
def test_copper_like_narrow_peaks_resample_without_misses(rate):
    _check_set(narrow_peak_model_set(count=12, ar_order=12, ma_order=12, max_pole_radius=0.9995), rate, "narrow")


@pytest.mark.parametrize("rate", [2000.0, 500.0])
@pytest.mark.parametrize("name", HATT_SETS)
def test_resampled_hatt_set_renders_like_the_original_along_a_path(hatt_files, name, rate):
    # expected spectra (no render noise) along a path across the triangulation: the models between the vertices are
    # LSF blends, which resampling need not preserve (docs/fitting.md); on HaTT's sets they stay within the 0.5 dB
    src = _hatt(hatt_files, name)
    assert path_lsd_db(src, _resampled(src, rate, name), *lissajous_path(src)) <= 0.5


def test_rough_set_to_500_hz_is_refitted_where_the_prediction_error_fit_fails():
    # the Whittle fit alone leaves this model 42 dB off (its spectrum rises to the new Nyquist); the log-spectral
    # refit brings it within the limit
    from flowtex.dsp.arma_resample import resample_arma

    src = rough_model_set()
    a, c = src.ar_coeff[9], src.ma_coeff[9]
    a2, c2, g2, v2 = resample_arma(a, c, 1.0, 1.0, 1000.0, 500.0)
    f = np.linspace(0.0, 225.0, 4001)
    assert lsd_db(arma_psd(a2, c2, g2, v2, f, 500.0), arma_psd(a, c, 1.0, 1.0, f, 1000.0), f, min_freq_hz=0.0) <= 0.5


def test_low_order_set_gets_more_order_when_downsampled():
    # an AR(2) set's band below 250 Hz is not an AR(2) at 500 Hz: 1.3 dB off at its own order; 2 more poles and zeros
    from flowtex.datasets.model_sets import synthetic_model_set

    out = _check_set(synthetic_model_set([60.0, 150.0], [0.5, 1.5], ar_order=2, ma_order=0), 500.0, "ar2")
    assert out.metadata["resample"]["extra_order"] > 0 and (out.ar_order, out.ma_order) == (4, 2)
