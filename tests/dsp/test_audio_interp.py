"""Band-limited interpolation of tick-rate outputs to the audio rate (flowtex.dsp.audio_interp)."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy import signal

from flowtex.dsp.audio_interp import Interpolator, frames_before, interpolation_filter, low_frequency_delay


def _texture_like(n: int, rate: float = 1000.0, seed: int = 3) -> np.ndarray:
    """White noise through an 8th-order Butterworth low-pass at 0.4 x rate: power up to the band edge, like a texture."""
    rng = np.random.default_rng(seed)
    sos = signal.butter(8, 0.4 * rate, fs=rate, output="sos")
    return signal.sosfilt(sos, rng.standard_normal(n))


def _power_above(y: np.ndarray, rate: float, f0: float) -> float:
    f, p = signal.welch(y, rate, nperseg=4096)
    return float(p[f > f0].sum() / p.sum())


@pytest.mark.parametrize("up", [5, 8, 48])
def test_render_equals_scipy_upfirdn_clipped_and_scaled(up):
    x = 0.3 * _texture_like(400)
    x[50] = 5.0  # clipped to hi
    x[60] = np.nan  # a NaN output enters the filter as 0
    scale, lo, hi = 1.5, -0.5, 0.4
    it = Interpolator(up, 1, [scale], [lo], [hi])
    out = np.zeros((x.size * up, 1), dtype=np.float32)
    it.render(x.reshape(-1, 1), out)
    ref_in = np.where(np.isnan(x), 0.0, x)
    ref = np.clip(signal.upfirdn(up * it.h, ref_in, up)[:x.size * up], lo, hi) / scale
    # float64 sums in another order, then one float32 rounding: a few float32 ulps of full scale
    np.testing.assert_allclose(out[:, 0], ref, rtol=0, atol=4 * np.finfo(np.float32).eps)
    assert out.max() <= np.float32(hi / scale) and out.min() >= np.float32(lo / scale)


@pytest.mark.parametrize("ratio", [(8, 1), (441, 10)])
def test_nan_and_inf_enter_as_zero_and_are_counted_per_channel(ratio):
    """An inf used to enter the filter: its history then held inf for a filter length (samples at the clip, or NaN
    where inf - inf met, played as 0). Now NaN and inf both enter as 0, and each channel counts its ticks."""
    up, down = ratio
    x = 0.3 * np.stack([_texture_like(300, seed=4), _texture_like(300, seed=5)], axis=1)
    x[[20, 21, 150], 0] = [np.inf, np.nan, -np.inf]
    x[[40, 41, 42, 43, 299], 1] = [np.nan, np.inf, np.inf, -np.inf, np.nan]
    it = Interpolator(up, 2, [1.0, 1.0], [-0.5, -0.5], [0.5, 0.5], down=down)
    out = np.zeros((frames_before(300, up, down), 2), dtype=np.float32)
    half = frames_before(100, up, down)
    it.render(x[:100], out[:half])  # in two calls: the counts add up
    assert it.nonfinite.tolist() == [2, 4]
    it.render(x[100:], out[half:])
    assert it.nonfinite.tolist() == [3, 5]
    for q in range(2):
        ref_in = np.where(np.isfinite(x[:, q]), x[:, q], 0.0)
        ref = np.clip(signal.upfirdn(up * it.h, ref_in, up, down)[:out.shape[0]], -0.5, 0.5)
        np.testing.assert_allclose(out[:, q], ref, rtol=0, atol=4 * np.finfo(np.float32).eps)  # as in the test above
    it.reset()
    assert it.nonfinite.tolist() == [0, 0]


def test_44_1_khz_from_1_khz_is_scipy_upfirdn_by_441_over_10():
    """A rational ratio: every 10th sample of the 441x up-sampled signal; ticks give 44 or 45 frames."""
    x = _texture_like(200).reshape(-1, 1)
    it = Interpolator(441, 1, [1.0], [-10.0], [10.0], down=10)
    n = it.frames(200)
    assert n == frames_before(200, 441, 10) == 8820
    out = np.zeros((n, 1), dtype=np.float32)
    assert it.render(x[:77], out) == frames_before(77, 441, 10)  # in two pieces: the state carries the phase
    it.render(x[77:], out[frames_before(77, 441, 10):])
    ref = signal.upfirdn(441 * it.h, x[:, 0], 441, 10)[:n]
    np.testing.assert_allclose(out[:, 0], ref, rtol=0, atol=4 * np.finfo(np.float32).eps)


def test_blocks_of_any_size_give_the_same_samples():
    x = _texture_like(300).reshape(-1, 1)
    whole = np.zeros((300 * 8, 1), dtype=np.float32)
    Interpolator(8, 1, [1.0], [-10.0], [10.0]).render(x, whole)
    it = Interpolator(8, 1, [1.0], [-10.0], [10.0])
    parts = np.zeros_like(whole)
    for a, b in [(0, 1), (1, 2), (2, 50), (50, 51), (51, 300)]:
        it.render(x[a:b], parts[a * 8:b * 8])
    np.testing.assert_array_equal(parts, whole)


def test_images_stay_below_minus_40_db_where_hold_and_linear_do_not():
    x = _texture_like(16000)
    up, rate = 8, 8000.0
    out = np.zeros((x.size * up, 1), dtype=np.float32)
    Interpolator(up, 1, [1.0], [-100.0], [100.0]).render(x.reshape(-1, 1), out)
    assert _power_above(out[:, 0].astype(float), rate, 550.0) < 1e-4  # the requirement (0.55 x the 1 kHz rate)
    hold = np.repeat(x, up)
    linear = np.interp(np.arange(x.size * up) / up, np.arange(x.size), x)
    assert _power_above(hold, rate, 550.0) > 1e-3  # the images this filter removes
    assert _power_above(linear, rate, 550.0) > 1e-4


def test_minimum_phase_delay_is_a_fraction_of_the_linear_phase_delay():
    h = interpolation_filter(8)
    assert abs(h.sum() - 1.0) < 1e-12
    linear_delay = (h.size - 1) / 2 / 8000.0
    assert low_frequency_delay(h, 8000.0, 50.0) < linear_delay / 4
    w, resp = signal.freqz(h, worN=[100.0, 300.0, 500.0, 600.0], fs=8000.0)
    db = 20 * np.log10(np.abs(resp))
    assert np.all(np.abs(db[:2]) < 0.01)  # passband flat to 400 Hz (Kaiser ripple at 60 dB: 0.0087 dB)
    assert np.all(db[2:] < -59.0)  # images (from 500 Hz up) 60 dB down


@settings(max_examples=60)
@given(up=st.integers(1, 12), scale=st.floats(1e-3, 1e3), lo_share=st.floats(0.0, 1.0), hi_share=st.floats(0.0, 1.0),
       values=st.lists(st.floats(allow_nan=True, allow_infinity=True, width=64), min_size=1, max_size=40))
def test_no_sample_passes_full_scale_and_the_clip_only_by_float32_rounding(up, scale, lo_share, hi_share, values):
    """The safety rule for audio: whatever the graph outputs (huge, NaN, inf, a step into the filter's overshoot), no
    played sample is beyond full scale (|s| <= 1), even with a clip the map accepts at its limit (scale x (1 + 1e-12),
    io.audiomap's check), and none passes its clip by more than the float32 rounding of clip / scale (half a float32
    ulp; a sample has no coarser grid, unlike a CAN signal's LSB)."""
    lo, hi = -lo_share * scale * (1 + 1e-12), hi_share * scale * (1 + 1e-12)
    x = np.array(values + [hi * 10, lo * 10, hi, lo], dtype=np.float64).reshape(-1, 1)
    it = Interpolator(up, 1, [scale], [lo], [hi])
    out = np.zeros((x.shape[0] * up, 1), dtype=np.float32)
    it.render(x, out)
    assert np.all(np.abs(out) <= 1.0)
    s = out[:, 0].astype(np.float64)
    rounding = np.finfo(np.float32).eps / 2  # float32 round-to-nearest: relative error at most 2**-24
    assert np.all(s <= (hi / scale) * (1 + rounding)) and np.all(s >= (lo / scale) * (1 + rounding))
