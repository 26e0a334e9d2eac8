"""The spectral helpers moved into flowtex/dsp (band power, centroid, zero-phase high-pass) against independent references."""

from __future__ import annotations

import numpy as np
from scipy import signal

from flowtex.dsp.filter_design import zero_phase_highpass
from flowtex.dsp.spectral import psd_band_power, psd_centroid, welch_psd


def test_band_power_of_a_tone_is_its_mean_square_and_its_centroid_its_frequency():
    rate, f0 = 1000.0, 125.0  # f0 on the Welch grid (1024-point segments: 0.977 Hz bins), so no leakage bias at the peak
    t = np.arange(20000) / rate
    x = 2.0 * np.sin(2 * np.pi * f0 * t)
    freqs, psd = welch_psd(x, rate, 1000)
    assert abs(psd_band_power(freqs, psd, 10.0) - 2.0) / 2.0 < 0.01  # mean square of amplitude 2: 2; Hann window leakage < 1 %
    assert abs(psd_centroid(freqs, psd, 10.0) - f0) < 0.5
    assert np.isnan(psd_centroid(freqs, np.zeros_like(psd)))


def test_zero_phase_highpass_is_scipys_butterworth_forward_and_back():
    rng = np.random.default_rng(1)
    x = rng.standard_normal(3000)
    sos = signal.butter(4, 10.0, "highpass", fs=1000.0, output="sos")
    np.testing.assert_allclose(zero_phase_highpass(x, 1000.0, 10.0), signal.sosfiltfilt(sos, x), rtol=0, atol=1e-12)
    assert np.array_equal(zero_phase_highpass(x, 1000.0, 0.0), x)
