"""flowtex.datasets generators and the resampling functions called from a notebook: a wrong argument is one line
naming it, checked before anything is allocated or rendered.

Before: a negative duration was numpy's 'negative dimensions', a zero one an empty recording with NaN warnings, a
duration of 1e9 s a MemoryError after trying to allocate terabytes, a seed of -1 numpy's 'expected non-negative
integer', a path for the surface an AttributeError, ``axes=2`` silently a 1-D recording, a rate of 0 for a tap
library scipy's 'up and down must be >= 1'.
"""

from __future__ import annotations

import numpy as np
import pytest

from flowtex import datasets
from flowtex.datasets import dragging, realistic, resonant
from flowtex.datasets.model_sets import cork_like_model_set
from flowtex.datasets.taps import synthetic_tap_library
from flowtex.errors import InputError
from flowtex.fit.resample import resample_model_set
from flowtex.models.taps import resample_tap_library

GENERATORS = [datasets.free_exploration, datasets.friction_session, realistic.human_exploration,
              resonant.textured_exploration, dragging.stiction_drag]


@pytest.mark.parametrize("generate", GENERATORS, ids=lambda f: f.__name__)
@pytest.mark.parametrize(("kwargs", "message"), [
    ({"duration_s": -1.0}, r"^duration_s must be a positive number of seconds, got -1.0$"),
    ({"duration_s": 0}, r"^duration_s must be a positive number of seconds, got 0$"),
    ({"duration_s": "5"}, r"^duration_s must be a positive number of seconds, got '5'$"),
    ({"duration_s": 1e9}, r"^duration_s x rate: samples=1,000,000,000,000 would fill .* more than a recording may hold"),
    ({"duration_s": 0.001}, r"^duration_s=0.001 s at 1000 Hz gives 1 sample\(s\); a recording needs at least 2$"),
    ({"duration_s": 2.0, "rate": "1000"}, r"^rate must be a positive number of Hz, got '1000'$"),
    ({"duration_s": 2.0, "seed": -1}, r"^seed must be an integer >= 0, got -1$"),
])
def test_a_generator_names_a_wrong_duration_rate_or_seed(generate, kwargs, message):
    with pytest.raises(InputError, match=message):
        generate(**kwargs)


def test_free_exploration_names_a_surface_given_as_a_path_or_at_another_rate_and_axes_neither_1_nor_3():
    with pytest.raises(InputError, match=r"^surface must be a TextureModelSet \(flowtex.io.modelset.load_model_set"):
        datasets.free_exploration(duration_s=2.0, surface="cork.json")
    with pytest.raises(InputError, match=r"^surface 'cork-like' is for 1000 Hz but rate is 2000 Hz; pass rate=1000 or "
                                         r"resample it \(flowtex.fit.resample.resample_model_set\)$"):
        datasets.free_exploration(duration_s=2.0, rate=2000.0, surface=cork_like_model_set())
    with pytest.raises(InputError, match=r"^axes must be 1 \(accel of shape \(n,\)\) or 3 .*got 2$"):
        datasets.free_exploration(duration_s=2.0, axes=2)


def test_resampling_names_a_path_for_the_model_set_and_a_rate_that_is_no_positive_number():
    with pytest.raises(InputError, match=r"^resample_model_set takes a TextureModelSet"):
        resample_model_set("cork.json", 2000.0)
    with pytest.raises(InputError, match=r"^resample_tap_library: sample_rate_hz must be a positive number of Hz, got 0$"):
        resample_tap_library(synthetic_tap_library(), 0)
    assert resample_tap_library(synthetic_tap_library(), np.int64(2000)).sample_rate_hz == 2000.0


@pytest.mark.parametrize("speeds", [(), (-5.0,), (np.nan,), 5.0, ("fast",)])
def test_tap_session_refuses_speeds_that_are_not_positive_incoming_speeds(speeds):
    with pytest.raises(InputError, match=r"^speeds must be a non-empty list of incoming speeds > 0 mm/s, got "):
        datasets.tap_session(speeds=speeds)
