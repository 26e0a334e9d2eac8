"""fit_texture and compare_surface called from Python: wrong arrays are refused in one line before any fit math.

The CLI's readers check a recording's signals (flowtex.fit.inputs.signal); arrays handed over in Python were used
as given: signals of different lengths were compared over the shorter one without a word, a complex acceleration
lost its imaginary part, a (n, 2) array, a NaN or a rate given as text ended in numpy's or the builtins' errors.
"""

from __future__ import annotations

import numpy as np
import pytest

from flowtex.datasets.model_sets import cork_like_model_set
from flowtex.errors import DataError, InputError
from flowtex.fit.compare import compare_surface
from flowtex.fit.texture import fit_texture

N = 400
ACCEL = np.random.default_rng(0).normal(size=N)
SPEED = np.full(N, 100.0)
FORCE = np.full(N, 1.0)

CASES = [
    ((ACCEL[:-5], SPEED, FORCE, 1000.0), InputError,
     r"^recording: signals have different lengths \(accel 395, speed 400, force 400\); pass one sample per tick"),
    ((np.c_[ACCEL, ACCEL, ACCEL], SPEED, FORCE, 1000.0), InputError,
     r"signal 'accel' has shape \(400, 3\); pass a 1-D array.*dft321"),
    ((ACCEL + 1j, SPEED, FORCE, 1000.0), InputError, r"signal 'accel' holds complex"),
    ((ACCEL, np.r_[SPEED[:-1], np.nan], FORCE, 1000.0), DataError, r"signal 'speed': 1 NaN/inf sample\(s\) \(at sample 399\)"),
    ((ACCEL, SPEED, FORCE, "1000"), InputError, r"rate must be a positive number of Hz, got '1000'"),
    ((ACCEL, SPEED, FORCE, 0.0), InputError, r"rate must be a positive number of Hz, got 0"),
]


@pytest.mark.parametrize(("args", "error", "message"), CASES)
def test_fit_texture_refuses_wrong_arrays_naming_the_signal(args, error, message):
    with pytest.raises(error, match=message):
        fit_texture(*args)


@pytest.mark.parametrize(("args", "error", "message"), CASES)
def test_compare_surface_refuses_wrong_arrays_naming_the_signal(args, error, message):
    with pytest.raises(error, match=message):
        compare_surface(cork_like_model_set(), *args)


def test_compare_surface_names_a_path_given_for_the_surface():
    with pytest.raises(InputError, match=r"the surface must be a TextureModelSet \(flowtex.io.modelset.load_model_set"):
        compare_surface("cork.json", ACCEL, SPEED, FORCE, 1000.0)


@pytest.mark.parametrize(("kwargs", "message"), [
    ({"x": ACCEL + 1j, "order": (4, 2)}, r"fit_arma: signal 'x' holds complex"),
    ({"x": np.ma.array(ACCEL, mask=ACCEL > 2), "order": (4, 2)}, r"fit_arma: signal 'x' is a masked array"),
    ({"x": ACCEL, "order": (4,)}, r"ARMA order must be two non-negative integers \(p, q\), e.g. order=\(19, 17\); got \(4,\)"),
    ({"x": ACCEL, "order": (4.5, 2)}, r"ARMA order must be two non-negative integers .*got \(4.5, 2\)"),
    ({"x": ACCEL, "order": "4,2"}, r"ARMA order must be two non-negative integers"),
    ({"x": ACCEL, "max_order": "5"}, r"fit_arma: max_order must be an integer >= 0, got '5'"),
])
def test_fit_arma_refuses_what_it_would_change_or_misread(kwargs, message):
    from flowtex.fit import fit_arma

    with pytest.raises((InputError, DataError), match=message):
        fit_arma(**kwargs)


def test_an_arma_fit_s_spectrum_refuses_a_rate_that_is_no_positive_number():
    from flowtex.fit import fit_arma

    fit = fit_arma(ACCEL, order=(2, 0))
    for rate in (0, -1000.0, "1000", float("nan")):
        with pytest.raises(InputError, match=r"ArmaFit.psd: rate_hz must be a positive number of Hz"):
            fit.psd(np.linspace(0.0, 500.0, 5), rate)
        with pytest.raises(InputError, match=r"ArmaFit.lsd_db: rate_hz must be a positive number of Hz"):
            fit.lsd_db(ACCEL, rate)


def test_fit_friction_and_fit_taps_refuse_signals_of_different_lengths_and_complex_values():
    from flowtex.fit.friction import fit_friction
    from flowtex.fit.taps import fit_taps

    with pytest.raises(InputError, match=r"signals have different lengths \(normal 397, tangential 400\)"):
        fit_friction(FORCE[:-3], 0.3 * FORCE)
    with pytest.raises(InputError, match=r"signal 'tangential' holds complex"):
        fit_friction(FORCE, 0.3 * FORCE + 0j)
    position = np.zeros((N, 3))
    with pytest.raises(InputError, match=r"signals have different lengths \(accel 397, force 400, position 400\)"):
        fit_taps(ACCEL[:-3], FORCE, 1000.0, position=position)
    with pytest.raises(InputError, match=r"signal 'position' has shape \(400,\); pass an \(n, 3\) array"):
        fit_taps(ACCEL, FORCE, 1000.0, position=position[:, 0])
    with pytest.raises(DataError, match=r"signal 'accel': 1 NaN/inf sample\(s\)"):
        fit_taps(np.r_[ACCEL[:-1], np.nan], FORCE, 1000.0, position=position)


def test_compare_signals_fit_pattern_and_fit_grid_refuse_what_they_would_misread():
    from flowtex.fit.compare import compare_signals
    from flowtex.fit.pattern import fit_pattern
    from flowtex.fit.texture import fit_grid

    with pytest.raises(InputError, match=r"signals have different lengths \(recorded 400, renders\[0\] 395\)"):
        compare_signals(ACCEL, [ACCEL[:-5]], 1000.0)
    with pytest.raises(InputError, match=r"^renders must be a non-empty list of rendered signals"):
        compare_signals(ACCEL, ACCEL, 1000.0)
    with pytest.raises(DataError, match=r"signal 'recorded': 1 NaN/inf sample"):
        compare_signals(np.r_[ACCEL[:-1], np.nan], [ACCEL], 1000.0)
    position = np.c_[np.linspace(0.0, 40.0, N), np.zeros(N), np.zeros(N)]
    with pytest.raises(InputError, match=r"signals have different lengths \(accel 395, position 400\)"):
        fit_pattern(ACCEL[:-5], position, 1000.0)
    with pytest.raises(InputError, match=r"signal 'position' has shape \(400,\); pass an \(n, 3\) array"):
        fit_pattern(ACCEL, position[:, 0], 1000.0)
    with pytest.raises(InputError, match=r"signal 'accel' holds complex"):
        fit_grid([(ACCEL + 0j, 100.0, 1.0)], 1000.0)
    with pytest.raises(InputError, match=r"^grid: cells\[0\] must be \(accel, speed mm/s, force N\)"):
        fit_grid([(ACCEL, 100.0)], 1000.0)


@pytest.mark.parametrize("pairs", [[(300, 100)], [(-100, 100)], [(0.5, 100.5)], [(0, 401)], (0, 100), []])
def test_within_and_ranges_refuse_pairs_that_are_not_sample_ranges_of_the_recording(pairs):
    from flowtex.fit.compare import compare_signals

    message = r"(within|ranges)(\[0\] = .*: a range is \(start, stop\) sample indices, integers with 0 <= start < stop " \
              r"<= 400| must be a non-empty list of \(start, stop\) sample ranges)"
    with pytest.raises(InputError, match=message):
        fit_texture(ACCEL, SPEED, FORCE, 1000.0, within=pairs)
    with pytest.raises(InputError, match=message):
        compare_surface(cork_like_model_set(), ACCEL, SPEED, FORCE, 1000.0, ranges=pairs)
    with pytest.raises(InputError, match=message):
        compare_signals(ACCEL, [ACCEL], 1000.0, ranges=pairs)
