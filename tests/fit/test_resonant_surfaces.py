"""Recordings that behave like real ones (flowtex.datasets.resonant), measured; then fit -> compare on them (issue 23).

Part 1 measures every property the generator promises on the generated data
itself (not on its parameters): speed and force ranges, contact throughout,
resonance frequency and bandwidth that move, per-second kurtosis, loudness
that wanders beyond speed and force, the span of piece powers.

Part 2 is issue 23's check: fit -> compare in-sample and under two-fold
cross-validation over interleaved one-second blocks. In-sample: power within
+-1 dB of the recording and LSD within 0.5 dB of the true surface's own
render. Held out: mean power over the folds within +-1 dB, and the pooled
out-of-fold LSD within 1 dB of the in-sample LSD; each fold's own LSD is read
against the true surface's on the same seconds (the last two tests say why).
20-s recordings at order (4, 2) (the true order)
keep this file fast; benchmarks/bench_compare.py --surfaces runs the table over
more seeds.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.stats import kurtosis

from flowtex.datasets.model_sets import lsf_to_poly_reference
from flowtex.datasets.resonant import FORCE_RANGE, SPEED_RANGE, textured_exploration
from flowtex.dsp.arma import arma_psd
from flowtex.dsp.filter_design import zero_phase_highpass
from flowtex.dsp.spectral import psd_centroid, welch_psd
from flowtex.fit.compare import compare_surface
from flowtex.fit.crossval import evaluate_splits, fold_splits, holdout_doc
from flowtex.fit.texture import TextureOptions, fit_texture

RATE = 1000.0
SECONDS = 20
ORDER = TextureOptions(order=(4, 2))
SEEDS = (0, 1)


@pytest.fixture(scope="module")
def recordings():
    return [textured_exploration(float(SECONDS), RATE, seed=s) for s in SEEDS]


def _seconds(x: np.ndarray) -> list[np.ndarray]:
    return [x[int(k * RATE):int((k + 1) * RATE)] for k in range(SECONDS)]


# --- part 1: the generated data behaves like real recordings ----------------

def test_speed_and_force_stay_in_the_real_recordings_ranges(recordings):
    for rec in recordings:
        s, f = rec.arrays["speed"], rec.arrays["normal_force"]
        assert s.shape == f.shape == (SECONDS * int(RATE),)
        assert SPEED_RANGE[0] <= s.min() and s.max() <= SPEED_RANGE[1]        # 130-320 mm/s, by construction
        assert FORCE_RANGE[0] <= f.min() and f.max() <= FORCE_RANGE[1]        # 0.3-4.3 N: in contact throughout
        # a hand that never settles: it visits most of both ranges in 20 s (the drift is a 0.3 Hz low-pass)
        assert s.max() / s.min() > 1.8 and f.max() / f.min() > 5.0
        assert np.max(np.abs(np.diff(s))) < 2.0                               # no jumps: < 2 mm/s per ms


def _peak_and_width(ms, speed: float, force: float) -> tuple[float, float]:
    """(peak frequency, half-power width) in Hz of the model at the grid point (speed, force), from its PSD."""
    m = int(np.flatnonzero((ms.speeds == speed) & (ms.forces == force))[0])
    f = np.linspace(1.0, 200.0, 20000)
    psd = arma_psd(lsf_to_poly_reference(ms.ar_lsf[m]), lsf_to_poly_reference(ms.ma_lsf[m]), 1.0, 1.0, f, RATE)
    k = int(np.argmax(psd))
    above = np.flatnonzero(psd >= psd[k] / 2)
    edges = np.split(above, np.flatnonzero(np.diff(above) > 1) + 1)
    band = next(e for e in edges if k in e)
    return float(f[k]), float(f[band[-1]] - f[band[0]])


def test_resonance_frequency_and_bandwidth_move_with_speed_and_force(recordings):
    ms = recordings[0].truth["surface"]
    f_slow, _ = _peak_and_width(ms, 130.0, 1.1)
    f_fast, _ = _peak_and_width(ms, 350.0, 1.1)
    _, w_light = _peak_and_width(ms, 220.0, 0.3)
    _, w_hard = _peak_and_width(ms, 220.0, 4.3)
    assert f_fast / f_slow > 1.5           # a faster stroke over the same texture: a higher resonance
    assert w_hard / w_light > 1.5          # pressing harder damps it: a wider resonance
    for rec in recordings:
        # and so the recording's spectral centroid moves: by 27 Hz in a real stone recording (50 -> 77 Hz)
        x = zero_phase_highpass(rec.arrays["accel"], RATE, 10.0)
        cent = np.array([psd_centroid(*welch_psd(s, RATE, 250), 12.0) for s in _seconds(x)])
        speed = np.array([np.mean(s) for s in _seconds(rec.arrays["speed"])])
        assert cent.max() - cent.min() > 25.0
        assert np.corrcoef(cent, speed)[0, 1] > 0.8                      # it moves with the speed, not at random


def test_vibration_is_heavy_tailed(recordings):
    """Per-second kurtosis (so that loudness changes between seconds do not count): real recordings' 4-12."""
    for rec in recordings:
        x = zero_phase_highpass(rec.arrays["accel"], RATE, 10.0)
        k = np.median([kurtosis(s, fisher=False) for s in _seconds(x)])
        assert 4.0 <= k <= 12.0


def test_loudness_wanders_beyond_speed_and_force(recordings):
    """Each second against the true surface's own render of it (same excitation, no wandering factors).

    Real recordings: 1.5-5.7 dB standard deviation between seconds at the same speed and force (issue 23).
    """
    for rec in recordings:
        x = zero_phase_highpass(rec.arrays["accel"], RATE, 10.0)
        clean = zero_phase_highpass(rec.truth["clean"], RATE, 10.0)
        excess = [10 * np.log10(np.mean(a ** 2) / np.mean(b ** 2)) for a, b in zip(_seconds(x), _seconds(clean), strict=True)]
        assert 1.5 <= np.std(excess) <= 5.7
        # the truth is exposed so that a fit can be judged: its render has the recording's power overall
        assert np.sum(rec.arrays["accel"] ** 2) == pytest.approx(np.sum(clean ** 2), rel=0.05)   # 1 % sensor noise, 10 Hz


def test_piece_powers_span_15_to_30_db(in_sample):
    """The fitted pieces' powers span 15-30 dB, as real surfaces' per-piece models do (issue 23)."""
    for fit, _got, _truth in in_sample:
        powers = [10 * np.log10(np.var(fit.signal[p.start:p.stop])) for p in fit.pieces]
        assert 15.0 <= max(powers) - min(powers) <= 30.0


# --- part 2: fit -> compare, in-sample and held out -------------------------

@pytest.fixture(scope="module")
def in_sample(recordings):
    out = []
    for rec in recordings:
        a = rec.arrays
        fit = fit_texture(a["accel"], a["speed"], a["normal_force"], RATE, ORDER)
        got = compare_surface(fit.model_set, a["accel"], a["speed"], a["normal_force"], RATE)
        truth = compare_surface(rec.truth["surface"], a["accel"], a["speed"], a["normal_force"], RATE)
        out.append((fit, got, truth))
    return out


@pytest.fixture(scope="module")
def two_fold(recordings):
    docs = []
    for rec in recordings:
        a = rec.arrays
        cv = evaluate_splits(a["accel"], a["speed"], a["normal_force"], RATE, fold_splits(a["accel"].shape[0], RATE, 2), ORDER)
        docs.append(holdout_doc("blocks", "folds", 2, cv.comparisons, cv.pooled))
    return docs


def test_in_sample_power(in_sample):
    """Measured (2026-11-26, seeds 0 and 1, 5 pooled pieces): +0.29 / -0.27 dB (piece by piece +0.04 / +0.27)."""
    for _fit, got, _truth in in_sample:
        assert abs(got.power_ratio_db) <= 1.0


def test_in_sample_lsd(in_sample):
    """Issue 23: in-sample LSD within 0.5 dB of the true surface's own render.

    Measured (2026-11-26, seeds 0 and 1, models fitted on 5 pooled pieces, flowtex.fit.pooling): 1.27 / 1.26 dB
    against the truth's 1.73 / 0.93. Fitted piece by piece (``pool_pieces=1``) seed 1 scored 1.43, +0.50: each
    model carried its own 0.35-s piece's loudness (docs/fitting.md, "Pooling neighbouring pieces").
    """
    for _fit, got, truth in in_sample:
        assert got.lsd_db <= truth.lsd_db + 0.5


def test_two_fold_results_are_one_per_fold(two_fold):
    for doc in two_fold:
        assert doc["split"] == "blocks" and doc["folds"] == 2 and len(doc["results"]) == 2
        assert doc["mean"]["power_ratio_db"] == pytest.approx(np.mean([r["power_ratio_db"] for r in doc["results"]]))


def test_two_fold_held_out_power(two_fold):
    """Measured (2026-11-26, seeds 0 and 1, power interpolation): mean +0.27 / +0.37 dB (folds +1.36 / -0.82 and
    +1.71 / -0.96); with HaTT's variance interpolation seed 1 was +1.02 dB."""
    for doc in two_fold:
        assert abs(doc["mean"]["power_ratio_db"]) <= 1.0


def test_two_fold_held_out_lsd_near_in_sample(two_fold, in_sample):
    """Issue 23: held-out LSD within 1 dB of in-sample, on the pooled out-of-fold comparison (every held-out second
    compared once, rendered by the fold's surface that did not see it: flowtex.fit.crossval, 'Pooled').

    Measured (2026-11-26, seeds 0 and 1): pooled 1.50 / 2.34 dB against in-sample 1.25 / 1.43.
    """
    for doc, (_fit, got, _truth) in zip(two_fold, in_sample, strict=True):
        assert doc["pooled"]["lsd_db"] <= got.lsd_db + 1.0
        assert abs(doc["pooled"]["power_ratio_db"]) <= 1.0
        assert doc["pooled"]["seconds"] == pytest.approx(sum(r["seconds"] for r in doc["results"]))


@pytest.fixture(scope="module")
def truth_on_folds(recordings):
    """The true surface's LSD on each fold's held-out blocks: what the data of a fold sets, whatever the surface."""
    out = []
    for rec in recordings:
        a = rec.arrays
        splits = fold_splits(a["accel"].shape[0], RATE, 2)
        out.append([compare_surface(rec.truth["surface"], a["accel"], a["speed"], a["normal_force"], RATE, ranges=test).lsd_db
                    for _train, test in splits])
    return out


def test_two_fold_fold_lsds_near_the_truths_on_the_same_blocks(two_fold, truth_on_folds):
    """Each fold's own LSD, read against the true surface's on the same held-out seconds (as the in-sample LSD is
    read against the truth's on the whole recording): the mean over the folds within 1 dB of the truth's mean.

    Measured (2026-11-26, seeds 0 and 1, 5 pooled pieces): 2.36 / 2.37 dB against the truth's 2.02 / 1.61; piece
    by piece seed 1 was 3.12 against 1.61. Over seeds 0-7 this holds on 7 (docs/fitting.md, "Held-out figures").
    """
    for doc, truth in zip(two_fold, truth_on_folds, strict=True):
        assert doc["mean"]["lsd_db"] <= float(np.mean(truth)) + 1.0


def test_mean_of_fold_lsds_against_the_whole_recording_is_not_a_property_of_the_surface():
    """Why the folds' own LSDs are not read against the in-sample LSD: the true surface itself fails that reading.

    Seed 6 (docs/fitting.md, "Held-out figures"): the truth scores 1.60 dB on the whole recording and 2.80 / 3.29 on
    the two folds' held-out seconds (each fold's seconds wander in loudness by their own 2 dB per second, and Welch
    PSDs of half the data are noisier), 1.45 dB above; no fit can be held to less than the surface it estimates.
    """
    rec = textured_exploration(float(SECONDS), RATE, seed=6)
    a = rec.arrays
    sig = (a["accel"], a["speed"], a["normal_force"])
    whole = compare_surface(rec.truth["surface"], *sig, RATE).lsd_db
    folds = [compare_surface(rec.truth["surface"], *sig, RATE, ranges=test).lsd_db
             for _train, test in fold_splits(a["accel"].shape[0], RATE, 2)]
    assert float(np.mean(folds)) > whole + 1.0
