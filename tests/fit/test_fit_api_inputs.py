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
