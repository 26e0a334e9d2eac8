"""Spectral comparison helpers: Welch PSD and the Goodness-of-Fit Criterion (GFC).

scipy.signal is imported inside the functions: importing it costs ~0.6 s,
which graph loading should not pay.
"""

from __future__ import annotations

import functools
import math

import numpy as np


def gfc(a: np.ndarray, b: np.ndarray) -> float:
    """Goodness-of-Fit Criterion |sum A B| / (sqrt(sum A^2) sqrt(sum B^2)) of two spectra.

    Source: Culbertson et al. 2012, "Refined methods for creating realistic haptic virtual textures from tool-mediated contact acceleration data".

    ``a`` and ``b`` are sampled at the same frequencies; magnitudes are
    taken (``abs``) first. Culbertson et al. 2012 apply it to amplitude spectra (|DFT|), so
    pass ``sqrt(psd)`` when comparing power spectral densities. 1 means the
    same shape up to a scale factor; their perceptual threshold was 0.90.
    Returns 0.0 if either spectrum is all zero.
    """
    a = np.abs(np.asarray(a, dtype=np.float64)).ravel()
    b = np.abs(np.asarray(b, dtype=np.float64)).ravel()
    if a.shape != b.shape:
        raise ValueError(f"spectra must have the same length, got {a.size} and {b.size}")
    den = np.sqrt(np.sum(a * a)) * np.sqrt(np.sum(b * b))
    if den == 0.0:
        return 0.0
    return float(abs(np.sum(a * b)) / den)


def welch_psd(x: np.ndarray, rate_hz: float, nperseg: int = 1024, whole: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """One-sided Welch PSD of a real signal (Hann window, 50 % overlap, mean removed).

    Returns (frequencies in Hz, PSD in units(x)^2 / Hz), the scaling of
    :func:`flowtex.dsp.arma.arma_psd` with ``onesided=True``.

    ``whole``: spread the segments evenly from the first sample to the last (overlap 50 % or a little more), so
    every sample enters the estimate. scipy.signal.welch steps by half a segment and leaves out the samples after
    the last whole step: up to half a segment, 27 % of a 350-sample piece in 256-sample segments. On a short piece
    of heavy-tailed vibration the burst left out can hold most of its power, and the PSD then misses it (the piece
    a model was fitted on is not the piece it is compared with). Where the steps tile the signal exactly, both agree.
    """
    import scipy.signal

    x = np.asarray(x, dtype=np.float64).ravel()
    nperseg = int(min(nperseg, x.size))
    if not whole or x.size == nperseg:
        return scipy.signal.welch(x, fs=rate_hz, window="hann", nperseg=nperseg, detrend="constant",
                                  scaling="density", return_onesided=True)
    starts = welch_segments(x.size, nperseg, whole=True)
    segs = x[starts[:, None] + np.arange(nperseg)]
    segs = segs - segs.mean(axis=1, keepdims=True)
    win = scipy.signal.get_window("hann", nperseg)
    psd = np.mean(np.abs(np.fft.rfft(segs * win, axis=1)) ** 2, axis=0) / (rate_hz * np.sum(win ** 2))
    psd[1:nperseg // 2 + (nperseg % 2)] *= 2.0   # one-sided: every bin but DC (and Nyquist for an even length) twice
    return np.fft.rfftfreq(nperseg, 1.0 / rate_hz), psd


def welch_segments(n: int, nperseg: int, whole: bool = False) -> np.ndarray:
    """Start samples of the segments :func:`welch_psd` averages for a signal of ``n`` samples (its segment length is
    ``min(nperseg, n)``)."""
    nperseg = int(min(nperseg, n))
    if not whole or n == nperseg:
        return np.arange(0, n - nperseg + 1, nperseg - nperseg // 2, dtype=np.int64)  # scipy's step: noverlap nperseg // 2
    count = 1 + math.ceil((n - nperseg) / (nperseg // 2))
    return np.round(np.linspace(0.0, n - nperseg, count)).astype(np.int64)


def welch_overlaps(n: int, nperseg: int, whole: bool = False) -> np.ndarray:
    """Correlation matrix (K x K) of :func:`welch_psd`'s K windowed segments' DFT coefficients at one frequency, for
    white Gaussian data: entry (i, j) is sum_t h_t h_{t + s_j - s_i} for the Hann window h scaled to sum h^2 = 1 and the
    segment starts s (:func:`welch_segments`), up to a phase that leaves its eigenvalues unchanged (Percival & Walden
    1993, *Spectral Analysis for Physical Applications*, section 6.17)."""
    import scipy.signal

    starts = welch_segments(n, nperseg, whole)
    m = int(min(nperseg, n))
    h = scipy.signal.get_window("hann", m)
    h = h / math.sqrt(float(np.sum(h * h)))
    corr = np.correlate(h, h, mode="full")[m - 1:]  # corr[lag] = sum_t h_t h_{t + lag}
    lag = np.abs(starts[:, None] - starts[None, :])
    return np.where(lag < m, corr[np.minimum(lag, m - 1)], 0.0)


def welch_dof(n: int, nperseg: int, whole: bool = False) -> float:
    """Equivalent degrees of freedom nu of :func:`welch_psd`'s estimate between DC and Nyquist (Gaussian data, spectrum
    smooth over a bin): the nu for which S chi2(nu) / nu has the estimate's variance, Percival & Walden (1993) eq. 292b
    with the segments actually used: 2 K^2 / sum_ij R_ij^2 (:func:`welch_overlaps`; 50 % overlap: 2K / 1.05 for many
    segments)."""
    r = welch_overlaps(n, nperseg, whole)
    return 2.0 * r.shape[0] ** 2 / float(np.sum(r * r))


LSD_FLOOR_DRAWS = 1 << 15
"""Draws of :func:`expected_lsd_db`'s sampled mean square: its relative standard error is 1.24 % for one segment
(0.62 % on the LSD) and less for more."""


@functools.lru_cache(maxsize=1024)
def expected_lsd_db(n: int, rate_hz: float, nperseg: int, whole: bool = True, min_freq_hz: float = 15.0) -> float:
    """The LSD (dB, :func:`lsd_db`'s band above ``min_freq_hz``) that the true spectrum itself scores against
    :func:`welch_psd` of ``n`` samples of Gaussian data: the estimate's own scatter, the floor under a fit table's LSD.

    At a frequency between DC and Nyquist the estimate is S (1/K) sum_k mu_k E_k, with mu the eigenvalues of
    :func:`welch_overlaps` and E independent unit exponentials; at the Nyquist bin of an even segment (a real DFT
    coefficient) E_k becomes a squared standard normal. The mean square of 10 log10 of that is taken over
    :data:`LSD_FLOOR_DRAWS` draws (seeded: the same number on every run), and the RMS over the band's bins is
    returned. (A chi-square with :func:`welch_dof` degrees of freedom gives the same for many segments but over-states
    it by 14 % for two segments that overlap by 80 %.) Ignores :func:`lsd_db`'s 40 dB range; heavy tails, a spectrum
    that changes within the piece and the model's own error all add to it.
    """
    m = int(min(nperseg, n))
    mu = np.clip(np.linalg.eigvalsh(welch_overlaps(n, nperseg, whole)), 0.0, None)
    mu = mu[mu > 1e-12 * mu.max()] / mu.sum()
    rng = np.random.default_rng(0)
    db = 10.0 / math.log(10.0)
    complex_bin = float(np.mean((db * np.log(rng.standard_exponential((LSD_FLOOR_DRAWS, mu.size)) @ mu)) ** 2))
    real_bin = float(np.mean((db * np.log(rng.standard_normal((LSD_FLOOR_DRAWS, mu.size)) ** 2 @ mu)) ** 2))
    freqs = np.fft.rfftfreq(m, 1.0 / rate_hz)
    band = freqs > min_freq_hz
    if not np.any(band):
        return 0.0
    mean_square = np.full(freqs.shape[0], complex_bin)
    if m % 2 == 0:
        mean_square[-1] = real_bin
    return float(math.sqrt(np.mean(mean_square[band])))


def psd_band_power(freqs_hz: np.ndarray, psd: np.ndarray, min_freq_hz: float, max_freq_hz: float = math.inf) -> float:
    """Power (units^2) of a one-sided PSD from ``min_freq_hz`` (included) to ``max_freq_hz`` (excluded; rectangle rule)."""
    band = (freqs_hz >= min_freq_hz) & (freqs_hz < max_freq_hz)
    return float(np.sum(psd[band]) * (freqs_hz[1] - freqs_hz[0]))


def octave_bands(min_freq_hz: float, max_freq_hz: float) -> list[tuple[float, float, float]]:
    """(centre, low, high) Hz of the octave bands (centres 1000 x 2^k Hz, edges centre / sqrt 2 and centre x sqrt 2).

    Clipped to [``min_freq_hz``, ``max_freq_hz``]; a band is kept when at least half of it (in octaves) lies inside.
    """
    out = []
    for k in range(-10, 6):
        centre = 1000.0 * 2.0 ** k
        lo, hi = centre / math.sqrt(2.0), centre * math.sqrt(2.0)
        a, b = max(lo, min_freq_hz), min(hi, max_freq_hz)
        if b > a and math.log2(b / a) >= 0.5:
            out.append((centre, a, b))
    return out


def psd_centroid(freqs_hz: np.ndarray, psd: np.ndarray, min_freq_hz: float = 0.0, max_freq_hz: float = math.inf) -> float:
    """Spectral centroid (Hz) of a PSD between ``min_freq_hz`` and ``max_freq_hz``; NaN when the band holds no power."""
    band = (freqs_hz >= min_freq_hz) & (freqs_hz <= max_freq_hz)
    total = np.sum(psd[band])
    return float(np.sum(freqs_hz[band] * psd[band]) / total) if total > 0 else float("nan")


def signal_centroid(x: np.ndarray, rate_hz: float) -> float:
    """Spectral centroid (Hz) of a whole signal ``x`` sampled at ``rate_hz``: sum X(f)^2 f / sum X(f)^2, X its DFT
    magnitude (Culbertson & Kuchenbecker 2017 eq. 4, the tap hardness predictor); NaN for a silent signal, like
    :func:`psd_centroid` (callers choose what silence means for them)."""
    x = np.asarray(x, dtype=np.float64)
    return psd_centroid(np.fft.rfftfreq(x.size, 1.0 / rate_hz), np.abs(np.fft.rfft(x)) ** 2)


def lsd_db(s_fit: np.ndarray, s_true: np.ndarray, freqs_hz: np.ndarray, min_freq_hz: float = 15.0,
           range_db: float | None = 40.0, max_freq_hz: float = math.inf, floor: float = 0.0,
           shape_only: bool = False) -> float:
    """Log-spectral distance in dB: RMS over a band of 10 log10(S_fit / S_true) -- the project's one LSD.

    Band: the frequencies ``freqs_hz`` with ``min_freq_hz`` < f <= ``max_freq_hz``
    (Hz, the units of ``freqs_hz``) where ``s_true`` is within ``range_db`` dB of
    its peak in that band (None: all of them), so deep notches and the DC region,
    where a 10 s record says little, do not dominate (the project's definition is the
    default: above 15 Hz, 40 dB range). ``floor`` (PSD units, >= 0) raises both
    spectra to at least that before the logs (silent bands of rendered signals;
    0: none). ``shape_only``: the RMS about the mean of 10 log10(S_fit / S_true) (its standard deviation), the
    distance left once the two levels are matched. Both PSDs are sampled at ``freqs_hz`` in the same units. Returns inf
    if ``s_fit`` is zero or non-finite anywhere in the band (with ``floor`` 0).
    Used for model fits (:mod:`flowtex.fit.arma`), resampling
    (:mod:`flowtex.fit.resample`), bench errors (:mod:`flowtex.dsp.errors`) and
    renders compared with recordings.
    """
    s_fit = np.asarray(s_fit, dtype=np.float64)
    s_true = np.asarray(s_true, dtype=np.float64)
    freqs_hz = np.asarray(freqs_hz, dtype=np.float64)
    if floor < 0.0 or not math.isfinite(floor):
        raise ValueError(f"lsd_db floor must be finite and >= 0, got {floor}")
    if floor > 0.0:
        s_fit = np.maximum(s_fit, floor)
        s_true = np.maximum(s_true, floor)
    band = (freqs_hz > min_freq_hz) & (freqs_hz <= max_freq_hz)
    if not np.any(band):
        raise ValueError(f"no frequency in ({min_freq_hz}, {max_freq_hz}] Hz to compare")
    mask = band
    if range_db is not None:
        peak = np.max(s_true[band])
        mask = band & (s_true >= peak * 10.0 ** (-range_db / 10.0))
    with np.errstate(divide="ignore", invalid="ignore"):
        d = 10.0 * np.log10(s_fit[mask] / s_true[mask])
    if not np.all(np.isfinite(d)):
        return float("inf")
    if shape_only:
        d = d - np.mean(d)
    return float(np.sqrt(np.mean(d * d)))


def gfc_data_model(x: np.ndarray, ar: np.ndarray, ma: np.ndarray, smooth: int = 50) -> float:
    """Culbertson et al. 2012's GFC between a signal and a model: smoothed |DFT| of the data against the model's |C/A|.

    The data's N-point |DFT| is smoothed with a ``smooth``-point Bartlett-Hann
    window (Culbertson et al. 2012 section 3.3) and compared, at the N // 2 + 1 non-negative DFT
    frequencies, with |C(e^jw) / A(e^jw)| (the scale does not matter to GFC).
    """
    import scipy.signal

    x = np.asarray(x, dtype=np.float64).ravel()
    n = x.size
    ad = np.abs(np.fft.rfft(x - np.mean(x))) / np.sqrt(n)
    w = scipy.signal.windows.barthann(smooth)
    ad = np.convolve(ad, w / np.sum(w), mode="same")
    from .poly import power_spectrum

    am = np.sqrt(power_spectrum(ar, ma, 2.0 * np.pi * np.arange(n // 2 + 1) / n))
    return gfc(ad, am)


def spectrogram_psd(x: np.ndarray, rate_hz: float, nperseg: int = 256,
                    max_columns: int = 2000) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(frequencies Hz, segment centres s, one-sided PSD (units of x)^2/Hz per segment) of ``x``, centres from 0 to
    the signal's end.

    The signal is extended by half a segment at both ends (mirrored), so the first segment is centred on the first
    sample and the last on the last: a plain spectrogram's segments stop up to a segment short of the end, and its
    picture left the end of a recording blank as if nothing had been recorded there. The hop is an eighth of a
    segment, longer when that would give more than ``max_columns`` segments.

    Each segment's mean is removed first: an accelerometer's offset (gravity, 9.81 m/s^2) is no vibration, and its
    0 Hz bin outshone a 0.05 m/s^2 vibration by 67 dB, below a 60 dB colour range. ``x`` of shape (n, k) (k axes)
    gives the sum of the axes' PSDs, the total power DFT321 keeps: the PSD of the magnitude |x| (a rectified signal)
    put a 100 Hz vibration at 0 and 200 Hz, its 100 Hz 56 dB down.
    """
    from scipy.signal import spectrogram

    x = np.asarray(x, dtype=np.float64)
    x = x.reshape(x.shape[0], -1) if x.ndim > 1 else x.reshape(-1, 1)
    n = x.shape[0]
    nperseg = max(1, min(nperseg, n))
    half = nperseg // 2
    mode = "reflect" if n > nperseg - half else "constant"
    padded = np.pad(x, ((half, nperseg - half), (0, 0)), mode=mode)
    hop = max(1, nperseg // 8, -(-n // max_columns))
    f, t, s = spectrogram(padded, fs=rate_hz, nperseg=nperseg, noverlap=max(0, nperseg - hop), detrend="constant",
                          axis=0)
    return f, t - half / rate_hz, s.sum(axis=1)
