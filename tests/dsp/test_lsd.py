"""The one LSD (flowtex.dsp.spectral.lsd_db): band, range and floor parameters against hand-computed values."""

import math

import numpy as np
import pytest

from flowtex.dsp.spectral import lsd_db

F = np.linspace(0.0, 500.0, 501)


def test_constant_ratio_is_its_db():
    # S_fit = 2 S_true everywhere: every term is 10 log10 2 = 3.0103 dB, so the RMS is that exactly
    s = 1.0 + F
    assert lsd_db(2.0 * s, s, F) == pytest.approx(10.0 * math.log10(2.0), rel=1e-12)


def test_band_limits_select_frequencies():
    s = np.ones_like(F)
    fit = np.where(F > 300.0, 10.0, 1.0)  # 10 dB off above 300 Hz only
    assert lsd_db(fit, s, F, max_freq_hz=300.0) == 0.0
    # (300, 500]: 200 of the 485 frequencies in (15, 500] are 10 dB off -> sqrt(200 / 485) * 10
    assert lsd_db(fit, s, F) == pytest.approx(10.0 * math.sqrt(200 / 485), rel=1e-12)


def test_range_excludes_deep_notch_and_none_keeps_it():
    s = np.ones_like(F)
    s[200] = 1e-6  # a -60 dB notch
    fit = np.ones_like(F)
    assert lsd_db(fit, s, F) == 0.0  # outside the 40 dB range
    n = np.count_nonzero(F > 15.0)
    assert lsd_db(fit, s, F, range_db=None) == pytest.approx(math.sqrt(60.0 ** 2 / n), rel=1e-9)


def test_floor_makes_silence_finite():
    s = np.ones_like(F)
    fit = np.where(F > 250.0, 0.0, 1.0)
    assert lsd_db(fit, s, F) == math.inf
    n = np.count_nonzero(F > 15.0)
    k = np.count_nonzero(F > 250.0)
    assert lsd_db(fit, s, F, floor=1e-2) == pytest.approx(math.sqrt(k * 20.0 ** 2 / n), rel=1e-9)
    with pytest.raises(ValueError):
        lsd_db(fit, s, F, floor=-1.0)
    with pytest.raises(ValueError, match="no frequency"):
        lsd_db(s, s, F, min_freq_hz=600.0)
