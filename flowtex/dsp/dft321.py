"""DFT321: reduce a 3-axis signal to one axis with the same spectral power (Romano & Kuchenbecker 2012 section 3.3.2).

At every frequency f of the DFT of the three axes A_x, A_y, A_z the reduced
signal has

    |A_s(f)| = sqrt(|A_x(f)|^2 + |A_y(f)|^2 + |A_z(f)|^2)
    angle(A_s(f)) = angle(A_x(f) + A_y(f) + A_z(f))

and the time signal is the inverse DFT of A_s. McMahan & Kuchenbecker smooth
the DFTs first; flowtex does not (neither offline nor in the streaming node),
so that:

- total power is exactly the sum of the axes' powers (Parseval), and
- when only one axis moves, the output IS that axis, sample for sample (the
  phase of A_x + 0 + 0 is A_x's own phase, with its sign: no sign flip).

Conventions at the edges: where A_x + A_y + A_z is exactly 0 (axes that cancel)
the phase is taken as 0. The DC bin and, for even n, the Nyquist bin of a real
signal are real; their phase is 0 or pi, so A_s is real there too and the
output is real with no power lost, for odd and even n alike.

The frame-wise (streaming) version lives in :mod:`flowtex.dsp.dft321_stream`.
"""

from __future__ import annotations

import numpy as np


def combine_spectra(spec: np.ndarray) -> np.ndarray:
    """Combine the one-sided spectra of three axes (shape (3, m), complex) into one (m,).

    Magnitude: root of the summed squared magnitudes; phase: that of the sum
    (0 where the sum is exactly zero). Units: those of the input spectra.
    """
    mag = np.sqrt(np.sum(spec.real ** 2 + spec.imag ** 2, axis=0))
    s = np.sum(spec, axis=0)
    abs_s = np.abs(s)
    unit = np.ones_like(s)
    nz = abs_s > 0.0
    unit[nz] = s[nz] / abs_s[nz]
    return mag * unit


def dft321(x: np.ndarray) -> np.ndarray:
    """Reduce a whole recording ``x`` of shape (n, 3) to one axis, shape (n,), same unit as ``x``.

    Offline and non-causal (zero delay): one DFT over the whole recording.
    ``sum(y**2) == sum(x**2)`` up to rounding (Parseval). Raises ValueError for a
    wrong shape or non-finite samples (a NaN would spread over every output
    sample through the DFT).
    """
    x = np.asarray(x, dtype=np.float64)
    if x.ndim != 2 or x.shape[1] != 3:
        raise ValueError(f"dft321 needs an array of shape (n, 3), got shape {x.shape}")
    n = x.shape[0]
    if n == 0:
        return np.zeros(0)
    if not np.all(np.isfinite(x)):
        bad = int(np.argmax(~np.all(np.isfinite(x), axis=1)))
        raise ValueError(f"dft321 input has a NaN or inf value (first at sample {bad}); clean the recording first")
    spec = np.fft.rfft(x, axis=0).T
    return np.fft.irfft(combine_spectra(spec), n=n)
