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


def test_whole_welch_is_scipys_where_the_steps_tile_the_signal():
    x = np.random.default_rng(2).standard_normal(256 + 7 * 128)  # 8 segments of 256 at steps of 128 end at the last sample
    f0, p0 = signal.welch(x, fs=1000.0, window="hann", nperseg=256)
    f1, p1 = welch_psd(x, 1000.0, 256, whole=True)
    np.testing.assert_allclose(f1, f0, rtol=0, atol=1e-12)
    np.testing.assert_allclose(p1, p0, rtol=1e-12, atol=0)


def test_whole_welch_uses_every_sample_of_a_short_piece():
    # 350 samples in 256-sample segments: scipy's Welch takes samples 0..255 only. A burst in the last 94 samples (as
    # heavy-tailed vibration has) must enter the piece's PSD; expected: the mean of scipy's periodograms of segments
    # at 0 and 94 (evenly spread from the first sample to the last).
    rng = np.random.default_rng(3)
    x = rng.standard_normal(350)
    x[256:] *= 10.0
    _, p_scipy = welch_psd(x, 1000.0, 256)
    _, p_head = signal.welch(x[:256], fs=1000.0, window="hann", nperseg=256)
    np.testing.assert_allclose(p_scipy, p_head, rtol=1e-12)  # the burst is left out of scipy's estimate
    _, p_whole = welch_psd(x, 1000.0, 256, whole=True)
    expected = np.mean([signal.periodogram(x[a:a + 256], fs=1000.0, window="hann")[1] for a in (0, 94)], axis=0)
    np.testing.assert_allclose(p_whole, expected, rtol=1e-10)
    # the burst (100x the power over 94 samples) now counts, if tapered by the Hann window's falling half: the second
    # segment weights it by sum(w^2) over its last 94 samples / sum(w^2) = 0.19, so that segment holds about
    # 0.81 + 0.19 * 100 = 20x the noise's power, and the mean of the two segments about 10x the burst-free estimate
    assert np.sum(p_whole) > 8 * np.sum(p_scipy)
