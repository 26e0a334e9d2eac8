"""The LSD floor (flowtex.dsp.spectral.expected_lsd_db): what the true spectrum scores against a short piece's Welch
estimate, checked against simulation of the whole chain (Gaussian data with a known spectrum, welch_psd, lsd_db).

Tolerance: the simulation's mean square of the LSD has a standard error computed from its own spread, and the
floor's sampled mean square at most 1.24 % (LSD_FLOOR_DRAWS, one segment); the two are compared within 4 combined standard errors
(on the LSD itself, half the relative error of its square).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
import scipy.signal

from flowtex.dsp.arma import arma_psd
from flowtex.dsp.spectral import expected_lsd_db, lsd_db, welch_dof, welch_psd

RATE = 1000.0
NPERSEG = 256
REPS = 300
AR2 = np.array([1.0, -1.2, 0.5])  # a broad resonance near 150 Hz: about 14 dB of range, inside lsd_db's 40 dB


def _simulated(n: int, coloured: bool, seed: int) -> tuple[float, float]:
    """(RMS over realisations of the LSD of the true PSD against welch_psd(whole=True) of n samples, its standard error)."""
    rng = np.random.default_rng(seed)
    squares = []
    for _ in range(REPS):
        e = rng.standard_normal(n + 500)
        x = scipy.signal.lfilter([1.0], AR2, e)[500:] if coloured else e[500:]
        freqs, s = welch_psd(x, RATE, NPERSEG, whole=True)
        true = arma_psd(AR2 if coloured else np.array([1.0]), np.array([1.0]), 1.0, 1.0, freqs, RATE)
        squares.append(lsd_db(true, s, freqs) ** 2)
    sq = np.asarray(squares)
    mean = float(sq.mean())
    return math.sqrt(mean), float(sq.std(ddof=1)) / math.sqrt(REPS) / (2.0 * math.sqrt(mean))


@pytest.mark.parametrize(("n", "coloured"), [(256, False), (300, True), (450, False), (1750, True)])
def test_floor_is_what_the_true_spectrum_scores(n, coloured):
    floor = expected_lsd_db(n, RATE, NPERSEG)
    simulated, se = _simulated(n, coloured, seed=n)
    tol = 4.0 * math.hypot(se, 0.0062 * floor)  # draws: at most 1.24 % on the square, 0.62 % on the LSD
    assert abs(floor - simulated) <= tol, (n, coloured, floor, simulated, tol)


def test_floor_falls_with_length_and_one_segment_is_a_chi_square_with_two_degrees():
    floors = [expected_lsd_db(n, RATE, NPERSEG) for n in (256, 300, 450, 1000, 5000)]
    assert all(np.diff(floors) < 0)
    assert welch_dof(256, NPERSEG, whole=True) == pytest.approx(2.0)
    # one segment: 10 log10 of a unit exponential, whose log has variance pi^2 / 6 and mean -Euler's gamma
    db = 10.0 / math.log(10.0)
    # (the Nyquist bin, 1 of the 125 above 15 Hz, is a squared normal: variance pi^2 / 2, mean -gamma - ln 2)
    gamma = 0.5772156649015329
    exact = db * math.sqrt((124 * (math.pi ** 2 / 6 + gamma ** 2) + (math.pi ** 2 / 2 + (gamma + math.log(2)) ** 2)) / 125)
    assert floors[0] == pytest.approx(exact, rel=0.025)  # 4 standard errors of the draws (0.62 % on the LSD)
    # many half-overlapping segments: Percival & Walden's 2K / 1.05
    k = 1 + (25600 - 256) // 128
    assert welch_dof(25600, NPERSEG, whole=True) == pytest.approx(2 * k / (1 + 2 * (1 - 1 / k) * (1 / 6) ** 2), rel=1e-3)
