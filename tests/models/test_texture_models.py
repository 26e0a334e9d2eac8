"""TextureModelSet validation and the synthetic ground-truth model sets."""

from __future__ import annotations

import math

import numpy as np
import pytest

from flowtex.datasets.model_sets import (
    cork_like_model_set,
    hard_model_set,
    lsf_to_poly_reference,
    poly_from_roots,
    poly_to_lsf_reference,
    synthetic_model_set,
)
from flowtex.errors import DataError


def small():
    return synthetic_model_set([50.0, 150.0], [0.5, 1.5], ar_order=6, ma_order=4)


def test_reference_conversions_invert_each_other_on_known_polynomials():
    rng = np.random.default_rng(0)
    for order in (1, 2, 5, 10, 19, 20):
        npair = order // 2
        a = poly_from_roots(rng.uniform(0.3, 0.95, npair), np.sort(rng.uniform(0.1, 3.0, npair)), [0.4] if order % 2 else [])
        lsf = poly_to_lsf_reference(a)
        assert lsf.shape == (order,)
        assert np.all(np.diff(lsf) > 0) and lsf[0] > 0 and lsf[-1] < math.pi
        assert np.allclose(lsf_to_poly_reference(lsf), a, rtol=0, atol=1e-11)


def test_reference_lsf_of_first_order_is_the_pole_angle():
    # A(z) = 1 + a z^-1: P, Q = (1 + a z^-1) -+ (a + z^-1) z^-1 ... the single LSF is arccos(-a) for |a| < 1
    a = 0.3
    assert poly_to_lsf_reference(np.array([1.0, a]))[0] == pytest.approx(math.acos(-a), abs=1e-12)


def test_poly_to_lsf_reference_refuses_non_minimum_phase():
    with pytest.raises(ValueError):
        poly_to_lsf_reference(np.real(np.poly([1.2, 0.5])))


def test_synthetic_models_are_stable_and_corners_silent():
    ms = synthetic_model_set([50.0, 100.0, 200.0], [0.5, 1.0, 2.0], ar_order=19, ma_order=17)
    assert ms.ar_order == 19 and ms.ma_order == 17
    assert ms.num_models == 9 + 3 + 3 + 1
    for a, c in zip(ms.ar_coeff, ms.ma_coeff, strict=True):
        assert np.abs(np.roots(a)).max() < 1.0
        assert np.abs(np.roots(c)).max() < 1.0
    zero = (ms.speeds == 0) | (ms.forces == 0)
    assert np.all(ms.variance[zero] == 0.0)
    assert np.all(ms.variance[~zero] > 0.0)
    # a corner copies its nearest measured model's LSFs
    k = int(np.flatnonzero((ms.speeds == 0) & (ms.forces == 1.0))[0])
    src = int(np.flatnonzero((ms.speeds == 50.0) & (ms.forces == 1.0))[0])
    assert np.array_equal(ms.ar_lsf[k], ms.ar_lsf[src])


def test_cork_like_has_hatt_cork_size():
    ms = cork_like_model_set()
    assert (ms.num_models, len(ms.triangles), ms.ar_order, ms.ma_order) == (45, 60, 19, 17)
    assert np.all(ms.variance[(ms.speeds == 0) | (ms.forces == 0)] == 0.0)


def test_hard_model_set_has_the_hard_features():
    ms = hard_model_set()
    radii = [np.abs(np.roots(a)).max() for a in ms.ar_coeff]
    assert min(radii) >= 0.995 and max(radii) < 1.0
    assert np.diff(ms.ma_lsf, axis=1).min() <= 2.0001e-4
    assert math.pi - ms.ma_lsf.max() < 5e-4
    assert np.any(ms.variance == 0.0)


@pytest.mark.parametrize("mutate, message", [
    (lambda ms: setattr(ms, "forces", ms.forces[:-1]), "forces has 8 values but there are 9 models"),
    (lambda ms: ms.ar_lsf.__setitem__((2, 3), ms.ar_lsf[2, 1]), "model 3: ar_lsf is not strictly increasing"),
    (lambda ms: ms.ma_lsf.__setitem__((0, 3), 3.2), "model 1: ma_lsf value 4 is 3.2; LSFs must lie strictly between 0 and pi"),
    (lambda ms: ms.ma_lsf.__setitem__((1, 0), -0.1), "model 2: ma_lsf value 1"),
    (lambda ms: ms.triangles.__setitem__((0, 1), 9), "triangles 1 names model 10, but the models are numbered 1..9"),
    (lambda ms: ms.triangles.__setitem__((1, 2), ms.triangles[1, 0]), "triangles 2 repeats a model"),
    (lambda ms: ms.variance.__setitem__(4, np.nan), "model 5: variance is nan"),
    (lambda ms: ms.variance.__setitem__(4, -1.0), "model 5: variance is -1.0; a variance must be >= 0"),
    (lambda ms: ms.ar_lsf.__setitem__((0, 0), np.nan), "model 1: ar_lsf value 1 is nan"),
    (lambda ms: setattr(ms, "max_speed", 0.0), "max_speed must be a finite number > 0"),
    (lambda ms: setattr(ms, "ar_coeff", ms.ar_coeff[:, :-1]), "ar_coeff: expected 7 values per model"),
])
def test_validation_names_element_and_model(mutate, message):
    ms = small()
    ms.source = None
    mutate(ms)
    with pytest.raises(DataError) as err:
        ms.validate()
    assert message in str(err.value)
    assert "model set 'synthetic'" in str(err.value)


def test_degenerate_triangle_refused():
    ms = small()
    # three models on the line force = 0.5 (speeds 0, 50, 150)
    on_line = np.flatnonzero(ms.forces == 0.5)[:3]
    assert len(on_line) == 3
    ms.triangles[0] = on_line
    with pytest.raises(DataError, match="triangles 1 is degenerate"):
        ms.validate()


def test_validation_names_the_source_file(tmp_path):
    ms = small()
    ms.source = tmp_path / "Models_x y.xml"
    ms.gain[0] = math.inf
    with pytest.raises(DataError, match=r"Models_x y\.xml: model 1: gain is inf"):
        ms.validate()
