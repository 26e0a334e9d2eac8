"""texture_lookup's rules beyond the measured models (outside: trend | hold | fade), against the known 15-dB surface.

References: the surface's exact power law (flowtex.datasets.realistic builds
every model's power as range_db x (2/3 u_s + 1/3 u_f)), its stored variances,
and HaTT's linear fade to the silent corner.
"""

from __future__ import annotations

import numpy as np
import pytest

from flowtex.datasets.model_sets import lsf_to_poly_reference
from flowtex.datasets.realistic import SPEED_SHARE, loud_surface
from flowtex.fit.quality import models_at
from flowtex.models.outside import TREND_CAP, model_powers, nearest_measured, power_trend
from tests.power_reference import lyapunov_power


@pytest.fixture(scope="module")
def surface():
    return loud_surface()


def test_surface_spans_15_db_and_model_powers_are_exact(surface):
    measured = surface.variance > 0
    p = model_powers(surface)
    ref = [lyapunov_power(lsf_to_poly_reference(surface.ar_lsf[m]), lsf_to_poly_reference(surface.ma_lsf[m]),
                          surface.gain[m], surface.variance[m]) for m in np.flatnonzero(measured)]
    assert np.allclose(p[measured], ref, rtol=1e-9)                   # FFT-grid power vs the Lyapunov solution
    assert 10 * np.log10(p[measured].max() / p[measured].min()) == pytest.approx(15.0, abs=1e-6)


def test_power_trend_recovers_the_surfaces_law(surface):
    ks, kf = power_trend(surface)
    s, f = surface.speeds[surface.variance > 0], surface.forces[surface.variance > 0]
    assert ks == pytest.approx(1.5 * SPEED_SHARE / np.log10(s.max() / s.min()), rel=1e-6)   # 15 dB x 2/3 over the speed decades
    assert kf == pytest.approx(1.5 * (1 - SPEED_SHARE) / np.log10(f.max() / f.min()), rel=1e-6)


def test_nearest_measured_maps_silent_corners_only(surface):
    src = nearest_measured(surface)
    measured = np.flatnonzero(surface.variance > 0)
    assert np.array_equal(src[measured], measured)
    assert np.all(surface.variance[src] > 0)


def _var(ms, speed, force, outside):
    return models_at(ms, np.array([speed]), np.array([force]), outside)[0][3]


def test_rules_below_above_and_inside(surface):
    ks, kf = power_trend(surface)
    smin, smax, f = 15.0, 320.0, 0.9                                   # grid edges; 0.9 N is a measured force
    v_low = surface.variance[(surface.speeds == smin) & (surface.forces == f)][0]
    v_high = surface.variance[(surface.speeds == smax) & (surface.forces == f)][0]
    assert _var(surface, 7.5, f, "fade") == pytest.approx(0.5 * v_low, rel=1e-9)         # HaTT: linear to the silent corner
    assert _var(surface, 7.5, f, "hold") == pytest.approx(v_low, rel=1e-9)
    assert _var(surface, 7.5, f, "trend") == pytest.approx(v_low * 0.5 ** ks, rel=1e-9)
    assert _var(surface, 0.0, f, "trend") == 0.0                                          # at rest: silent
    assert _var(surface, 640.0, f, "fade") == pytest.approx(v_high, rel=1e-4)            # clamped to 320 - 0.01 mm/s: held
    assert _var(surface, 640.0, f, "trend") == pytest.approx(v_high * 2.0 ** ks, rel=1e-4)
    assert _var(surface, 1e5, f, "trend") == pytest.approx(v_high * TREND_CAP ** ks, rel=1e-4)
    inside = _var(surface, 100.0, 1.2, "fade")
    assert _var(surface, 100.0, 1.2, "hold") == inside
    assert _var(surface, 100.0, 1.2, "trend") == inside
    assert kf > 0 and _var(surface, 100.0, 0.15, "trend") < _var(surface, 100.0, 0.3, "trend")
