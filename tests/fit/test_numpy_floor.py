"""flowtex runs on the oldest numpy pyproject.toml allows (1.24): `models resample` called ``np.trapezoid``, added in
numpy 2.0, so on numpy 1.24-1.26 every resample (and ``fit texture --render-rate``) ended in an AttributeError.

The suite runs on a numpy 2 here; removing the name for the test stands in for numpy 1.x (which has ``np.trapz``)."""

from __future__ import annotations

import numpy as np

from flowtex.fit.resample import power_above, resample_quality


def test_resample_quality_needs_no_numpy_2_name(monkeypatch):
    monkeypatch.delattr(np, "trapezoid", raising=False)
    a = np.array([1.0, -0.5])
    c = np.array([1.0, 0.2])
    lsd, band = resample_quality(a, c, 1.0, 1.0, 1000.0, a, c, 1.0, 1.0, 1000.0)
    assert lsd == 0.0 and band == 0.0  # a model against itself
    # an AR(1) pole at 0.5 has power 1 / (1.25 - cos w): its integral is (8/3) atan(3 tan(w/2)), so the share above
    # 250 Hz (w > pi/2) is 1 - 2 atan(3) / pi. The 40001-point trapezoid cut at a grid point errs by at most about one
    # step's area at the cut, 0.8 x (pi / 40000) over the total 4 pi / 3: 1.5e-5
    share = power_above(a, np.array([1.0]), 1000.0, 250.0)
    assert abs(share - (1.0 - 2.0 * np.arctan(3.0) / np.pi)) < 1.5e-5
