"""Change a texture model set's sample rate: every model resampled on its own (flowtex.dsp.arma_resample).

A lookup exactly at a model's (speed, force) then gives the resampled model;
the triangulation, operating points, maxima and mu are kept.
"""

from __future__ import annotations

import dataclasses
import math
import sys
from collections.abc import Callable

import numpy as np

from ..dsp.arma import arma_psd
from ..dsp.arma_resample import resample_arma_lsf, upsampled_order
from ..dsp.lsf import lsf_to_poly_new, poly_to_lsf
from ..dsp.spectral import lsd_db
from ..errors import FlowtexError
from ..models.texture import TextureModelSet
from .arma import min_phase_for_lsf


def resample_quality(ar1, ma1, g1, v1, rate1, ar2, ma2, g2, v2, rate2) -> tuple[float, float]:
    """(LSD dB, relative band-power error) of model 2 against model 1 up to 0.9 x the lower Nyquist (physical PSDs)."""
    f = np.linspace(0.0, 0.45 * min(rate1, rate2), 4001)
    s1 = arma_psd(ar1, ma1, g1, v1, f, rate1)
    s2 = arma_psd(ar2, ma2, g2, v2, f, rate2)
    band = float(np.trapezoid(s2, f) / np.trapezoid(s1, f) - 1.0)
    return lsd_db(s2, s1, f, min_freq_hz=0.0), band


def resample_model_set(ms: TextureModelSet, rate_hz: float, progress: Callable[[int, int], None] | None = None,
                       keep_order: bool = False) -> TextureModelSet:
    """A copy of ``ms`` whose models run at ``rate_hz`` (Hz) with the same physical PSDs below min Nyquist.

    Upsampling by more than 2x raises every model's order alike
    (:func:`flowtex.dsp.arma_resample.upsampled_order`) unless ``keep_order``.
    ``metadata["resample"]`` records the source rate, the orders, the method
    and the worst LSD (dB) and band-power error of the models as rendered,
    i.e. rebuilt from the stored LSFs (see :func:`resample_quality`).
    ``progress(done, total)`` is called after each model.
    """
    if not (isinstance(rate_hz, (int, float)) and math.isfinite(rate_hz) and rate_hz > 0):
        raise FlowtexError(f"--rate must be a positive number of Hz, got {rate_hz!r}")
    rate_from = float(ms.sample_rate)
    m_count = ms.num_models
    p0, q0 = ms.ar_order, ms.ma_order
    p, q = upsampled_order(p0, q0, rate_from, float(rate_hz), keep_order)
    ar_lsf = np.empty((m_count, p))
    ma_lsf = np.empty((m_count, q))
    ar_coeff = np.empty((m_count, p + 1))
    ma_coeff = np.empty((m_count, q + 1))
    variance = np.empty(m_count)
    gain = np.empty(m_count)
    worst_lsd = 0.0
    worst_band = 0.0
    for m in range(m_count):
        a = lsf_to_poly_new(ms.ar_lsf[m])
        c = lsf_to_poly_new(ms.ma_lsf[m])
        v1 = float(ms.variance[m])
        # a silent model (variance 0) is resampled at unit variance and stays silent: its shape still matters once
        # texture_lookup interpolates it with its neighbours
        v_fit = v1 if v1 > 0.0 else 1.0
        a2, c2, lsf_a, lsf_c, g2, v2 = resample_arma_lsf(a, c, float(ms.gain[m]), v_fit, rate_from, float(rate_hz),
                                                         keep_order=keep_order)
        if lsf_a is None:  # downsampling: LSFs from the (well-conditioned) polynomials
            a2 = min_phase_for_lsf(a2)
            c2 = min_phase_for_lsf(c2)
            lsf_a = poly_to_lsf(a2) if p else ar_lsf[m]
            lsf_c = poly_to_lsf(c2) if q else ma_lsf[m]
        ar_lsf[m] = lsf_a
        ma_lsf[m] = lsf_c
        ar_coeff[m] = a2
        ma_coeff[m] = c2
        gain[m] = g2
        variance[m] = v2 if v1 > 0.0 else 0.0
        # quality of the model as texture_lookup renders it: rebuilt from the stored LSFs
        lsd, band = resample_quality(a, c, float(ms.gain[m]), v_fit, rate_from, lsf_to_poly_new(ar_lsf[m]),
                                     lsf_to_poly_new(ma_lsf[m]), g2, v2, float(rate_hz))
        worst_lsd = max(worst_lsd, lsd)
        worst_band = max(worst_band, abs(band))
        if progress is not None:
            progress(m + 1, m_count)
    metadata = dict(ms.metadata)
    if rate_hz < rate_from:
        method = "prediction-error fit of the PSD below the new Nyquist, same order"
    else:
        method = "log-spectral fit of the PSD below the old Nyquist, stopband ceiling above"
        if (p, q) != (p0, q0):
            method += "; fitted at 1/M of the rate, stretched z -> z^M and cascaded with an FIR anti-imaging lowpass"
    metadata["resample"] = {"from_hz": rate_from, "to_hz": float(rate_hz), "method": method,
                            "from_order": [p0, q0], "to_order": [p, q],
                            "worst_lsd_db": worst_lsd, "worst_band_power_error": worst_band}
    out = dataclasses.replace(ms, sample_rate=float(rate_hz), ar_lsf=ar_lsf, ma_lsf=ma_lsf, variance=variance, gain=gain,
                              ar_coeff=ar_coeff, ma_coeff=ma_coeff, source=None, metadata=metadata,
                              speeds=np.array(ms.speeds, dtype=np.float64), forces=np.array(ms.forces, dtype=np.float64),
                              triangles=np.array(ms.triangles, dtype=np.int64))
    return out.validate()


def tqdm_progress(total: int, desc: str) -> tuple[Callable[[int, int], None] | None, Callable[[], None]]:
    """(progress callback, close) showing a tqdm bar on a terminal; (None, no-op) otherwise."""
    if not sys.stderr.isatty():
        return None, lambda: None
    from tqdm import tqdm

    bar = tqdm(total=total, desc=desc, unit="model", leave=False)

    def update(done: int, _total: int) -> None:
        bar.n = done
        bar.refresh()

    return update, bar.close
