"""Filter design at build time, with scipy.signal (never hand-written); Butterworth designs are remembered on disk
(:mod:`flowtex.dsp.design_memo`), so a warm run does not import scipy.signal."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from .design_memo import remembered


def butterworth_sos(kind: str, order: int, cutoff_hz: Sequence[float], rate_hz: float) -> np.ndarray:
    """Digital Butterworth as second-order sections (scipy ``butter``, bilinear transform).

    ``kind`` is lowpass/highpass (one cutoff) or bandpass/bandstop (two).
    Raises ``ValueError`` with a user-readable message on bad cutoffs.
    """
    nyquist = rate_hz / 2.0
    cut = [float(c) for c in cutoff_hz]
    band = kind in ("bandpass", "bandstop")
    if band and len(cut) != 2:
        raise ValueError(f"{kind} needs cutoff_hz: [low, high], got {len(cut)} value(s)")
    if not band and len(cut) != 1:
        raise ValueError(f"{kind} needs one cutoff_hz, got {len(cut)} values")
    for c in cut:
        if not 0.0 < c < nyquist:
            raise ValueError(f"cutoff {c:g} Hz must lie between 0 and the Nyquist frequency {nyquist:g} Hz")
    if band and not cut[0] < cut[1]:
        raise ValueError(f"band edges must increase, got [{cut[0]:g}, {cut[1]:g}]")
    wn = [float(c) for c in cut] if band else float(cut[0])

    def design() -> np.ndarray:
        from scipy import signal  # imported only when the design is not remembered: it is slow to import

        return signal.butter(order, wn, btype=kind, fs=rate_hz, output="sos")

    sections = order if band else (order + 1) // 2
    return remembered("butter", (int(order), wn, kind, float(rate_hz)), (sections, 6), design)


def zero_phase_highpass(x: np.ndarray, rate_hz: float, cutoff_hz: float, order: int = 4) -> np.ndarray:
    """``x`` (along its last axis) through an ``order``-th order Butterworth high-pass at ``cutoff_hz``, forward and
    backward (scipy ``sosfiltfilt``: zero phase, twice the order's attenuation); ``x`` as float when ``cutoff_hz`` <= 0.

    The preprocessing HaTT applies before fitting (10 Hz, 4th order) and the one comparisons apply to both signals.
    A signal not longer than scipy's default edge padding (15 samples at order 4) is padded by what it has: scipy
    refused it (an internal error of ``fit texture``, ``fit taps`` and ``compare`` on a recording of 2 to 15 samples,
    which each then refuse as too short, with their own reason); a longer one is filtered exactly as before.
    """
    if cutoff_hz <= 0:
        return np.asarray(x, float)
    from scipy.signal import sosfiltfilt

    sos = butterworth_sos("highpass", order, [cutoff_hz], rate_hz)
    n = np.shape(x)[-1]
    padlen = 3 * (2 * sos.shape[0] + 1 - min(int((sos[:, 2] == 0).sum()), int((sos[:, 5] == 0).sum())))  # scipy's default
    return sosfiltfilt(sos, x) if n > padlen else sosfiltfilt(sos, x, padlen=max(n - 1, 0))


def resampling_fir(up: int, down: int, atten_db: float, passband: float = 0.8) -> np.ndarray:
    """Linear-phase low-pass FIR for rational resampling by up/down (Kaiser window, scipy ``firwin``).

    The filter runs at the up-sampled rate ``up * rate_in``. Its transition
    band spans ``[passband, 1.0]`` times the lower of the two Nyquist
    frequencies, so everything that would alias (down-sampling) or every
    image (up-sampling) lies in the stopband, ``atten_db`` dB down. With a
    Kaiser window the passband ripple is the stopband's delta:
    20*log10(1 + 10**(-atten_db/20)) dB, 0.0087 dB at 60 dB. The length is
    odd (integer group delay (len-1)/2 at the up-sampled rate), the shortest
    from kaiserord's estimate upwards whose stopband meets ``atten_db``. DC gain is 1;
    multiply by ``up`` to keep the signal's amplitude when zeros are stuffed.
    """
    if up < 1 or down < 1:
        raise ValueError(f"resampling factors must be positive integers, got up={up}, down={down}")
    if not 0.0 < passband < 1.0:
        raise ValueError(f"passband must lie between 0 and 1 (fraction of the lower Nyquist frequency), got {passband:g}")
    if not 20.0 <= atten_db <= 200.0:
        raise ValueError(f"atten_db must lie between 20 and 200 dB, got {atten_db:g}")
    from scipy import signal

    m = max(up, down)
    width = (1.0 - passband) / m  # transition width, relative to the Nyquist frequency of the up-sampled rate
    cutoff = (1.0 + passband) / 2.0 / m
    numtaps, beta = signal.kaiserord(atten_db, width)
    numtaps |= 1
    # kaiserord's length formula is an estimate (short filters miss by ~1 dB): lengthen until the
    # stopband, checked on a dense grid, really is atten_db down.
    while True:
        h = signal.firwin(numtaps, cutoff, window=("kaiser", beta))
        nfft = 1 << max(13, int(np.ceil(np.log2(16 * numtaps))))  # a power of two: freqz takes its FFT path
        w, resp = signal.freqz(h, worN=nfft)
        stop = w >= np.pi / m
        if 20.0 * np.log10(np.max(np.abs(resp[stop])) + 1e-300) <= -atten_db:
            return h
        numtaps += 2 * max(1, numtaps // 256)
