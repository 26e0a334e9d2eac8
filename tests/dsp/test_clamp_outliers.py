"""flowtex.dsp.robust.clamp_outliers: isolated spikes are clipped, heavy-tailed vibration is not."""

from __future__ import annotations

import numpy as np
from scipy.signal import butter, sosfilt

from flowtex.dsp.robust import clamp_outliers, robust_scale


def _bursty(n: int, seed: int) -> np.ndarray:
    """A resonance driven by a Gaussian scale mixture: white noise times exp(0.8 z), z a unit 15 Hz low-pass noise."""
    rng = np.random.default_rng(seed)
    z = sosfilt(butter(2, 15.0, fs=1000.0, output="sos"), rng.standard_normal(n + 500))[500:]
    scale = np.exp(0.8 * z / np.std(z))
    return sosfilt(butter(2, [50.0, 70.0], btype="bandpass", fs=1000.0, output="sos"), scale * rng.standard_normal(n))


def test_heavy_tailed_bursts_are_not_clipped():
    x = _bursty(20000, 0)
    k4 = np.mean((x - x.mean()) ** 4) / np.var(x) ** 2
    assert k4 > 5.0                                                     # heavy-tailed, as real vibration is (4-12)
    out, bad = clamp_outliers(x)
    assert bad.size == 0 and np.array_equal(out, x)
    # the MAD alone would have: bursts go past 8 MAD-sigma of their 250-sample block
    past = sum(int(np.sum(np.abs(x[a:a + 250] - np.median(x[a:a + 250])) > 8 * robust_scale(x[a:a + 250])))
               for a in range(0, 20000, 250))
    assert past > 0


def test_isolated_spikes_are_clipped_even_in_heavy_tailed_vibration():
    x = _bursty(20000, 1)
    rms = float(np.std(x))
    where = np.arange(300, 20000, 997)[:20]
    spiky = x.copy()
    spiky[where] += 20.0 * rms * np.where(np.arange(where.size) % 2 == 0, 1.0, -1.0)
    out, bad = clamp_outliers(spiky)
    assert set(where) <= set(bad.tolist())
    assert len(bad) <= len(where) + 2                                   # at most a stray burst sample beside them
    # cut back to 8 scales of their block, whose RMS the spike itself raised by ~1.6 (so ~13 x the RMS, not 20)
    assert np.max(np.abs(out[where])) < 0.8 * 20.0 * rms
