"""Texture model sets: ARMA vibration models placed over a (speed, force) triangulation.

A :class:`TextureModelSet` is what a HaTT XML file (``flowtex.io.hatt``) or a
native model-set file (``flowtex.io.modelset``) holds once read: ``M`` ARMA
models, each fitted at one (speed, force) operating point, and a Delaunay
triangulation of those points. The ``texture_lookup`` node interpolates the
models' line spectral frequencies (LSFs), excitation variance and MA gain
inside the triangle that contains the current (speed, force).

Conventions (HaTT's):

* speeds in mm/s, forces in N, the vibration they describe in m/s^2;
* ``ar_lsf[m]`` are the ``p`` LSFs (radians, strictly increasing in (0, pi))
  of A(z) = 1 + a1 z^-1 + ... + ap z^-p; ``ma_lsf[m]`` the ``q`` LSFs of
  C(z) = 1 + c1 z^-1 + ... + cq z^-q;
* ``variance[m]`` is the variance of the white Gaussian excitation and
  ``gain[m]`` the MA gain g: y_n = -sum a_i y_{n-i} + g (e_n + sum c_j e_{n-j});
* ``triangles`` are 0-based model indices (HaTT files store them 1-based).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import DataError

FIELD_NAMES = {
    "speeds": "speeds",
    "forces": "forces",
    "triangles": "triangles",
    "ar_lsf": "ar_lsf",
    "ma_lsf": "ma_lsf",
    "variance": "variance",
    "gain": "gain",
    "ar_coeff": "ar_coeff",
    "ma_coeff": "ma_coeff",
    "max_speed": "max_speed",
    "max_force": "max_force",
    "sample_rate": "sample_rate",
    "mu": "mu",
    "model": "model",
    "index_base": "1",
}
"""Default names used in validation messages; file readers pass their own element names.

``model`` labels one model (``"{}"`` in it is replaced by the model number); ``index_base``
is the number of the first model (and of model indices in triangles) in messages.
"""


INTERPOLATION_CHOICES = ("variance", "power", "log_power")
"""How loudness is blended between models (flowtex.models.rendering): HaTT's excitation variance, output power, log power."""
OUTSIDE_CHOICES = ("fade", "hold", "trend")
"""What a set renders beyond its measured models (flowtex.models.outside): HaTT's fade, hold, trend."""


@dataclass(frozen=True)
class RenderRule:
    """How a model set renders between and beyond its models (flowtex.models.rendering); the defaults are HaTT's."""

    interpolation: str = "variance"
    """How loudness is blended between models: one of :data:`INTERPOLATION_CHOICES`."""
    outside: str = "fade"
    """What the set renders beyond its measured models: one of :data:`OUTSIDE_CHOICES`."""

    def __post_init__(self) -> None:
        if self.interpolation not in INTERPOLATION_CHOICES:
            raise ValueError(f"interpolation must be one of {', '.join(INTERPOLATION_CHOICES)}, got {self.interpolation!r}")
        if self.outside not in OUTSIDE_CHOICES:
            raise ValueError(f"outside must be one of {', '.join(OUTSIDE_CHOICES)}, got {self.outside!r}")


HATT_RULE = RenderRule()
"""HaTT's renderer: LSFs and excitation variance blended linearly, silent corners, saturation at the maximum."""


@dataclass
class TextureModelSet:
    """One surface's texture models (see the module docstring for conventions and units).

    ``ar_order`` (p) and ``ma_order`` (q) follow from the LSF arrays' widths.
    ``ar_coeff`` / ``ma_coeff`` are the polynomials as stored in the file they
    were read from (leading 1), kept for reference and checks only: lookup
    always works from the LSFs, never from raw coefficients.
    """

    material: str
    """Surface name."""
    sample_rate: float
    """Rate in Hz at which the models are meant to run (HaTT: 1000 or 10000)."""
    speeds: np.ndarray
    """(M,) speed of each model in mm/s."""
    forces: np.ndarray
    """(M,) normal force of each model in N."""
    triangles: np.ndarray
    """(T, 3) int64, 0-based model indices of each Delaunay triangle."""
    ar_lsf: np.ndarray
    """(M, p) AR line spectral frequencies in radians."""
    ma_lsf: np.ndarray
    """(M, q) MA line spectral frequencies in radians."""
    variance: np.ndarray
    """(M,) excitation variance ((m/s^2)^2 per unit gain^2); 0 makes the model silent."""
    gain: np.ndarray
    """(M,) MA gain g."""
    max_speed: float
    """Lookup saturation speed in mm/s."""
    max_force: float
    """Lookup saturation force in N."""
    mu: float | None = None
    """Kinetic friction coefficient, or None when the file has none."""
    ar_coeff: np.ndarray | None = None
    """(M, p+1) A(z) as read (leading 1), or None."""
    ma_coeff: np.ndarray | None = None
    """(M, q+1) C(z) as read (leading 1), or None."""
    source: Path | None = None
    """File the set was read from (None when built in memory)."""
    metadata: dict[str, Any] = field(default_factory=dict)
    """Free-form JSON-compatible facts (units, texture index, fitting settings, ...)."""
    rule: RenderRule | None = None
    """How the set renders (flowtex.models.rendering), as its file states it; None: the file states none (HaTT's rule)."""

    @property
    def num_models(self) -> int:
        """M, the number of models."""
        return int(np.asarray(self.speeds).shape[0])

    @property
    def ar_order(self) -> int:
        """p, the AR order (number of AR LSFs)."""
        return int(np.asarray(self.ar_lsf).shape[1])

    @property
    def ma_order(self) -> int:
        """q, the MA order (number of MA LSFs)."""
        return int(np.asarray(self.ma_lsf).shape[1])

    def points(self) -> np.ndarray:
        """(M, 2) array of (speed mm/s, force N) per model."""
        return np.column_stack([self.speeds, self.forces])

    def validate(self, names: Mapping[str, str] | None = None) -> TextureModelSet:
        """Check every array's shape and value; raise :class:`DataError` naming the file and element.

        ``names`` maps field names (``ar_lsf``, ``speeds``, ``model``, ...) to
        the element names of the file format being read, so that a HaTT file's
        problem is reported as ``<model> 3 <ARlsf>`` rather than ``ar_lsf[2]``.
        Arrays are converted in place to contiguous float64 (int64 for
        triangles). Returns ``self``.
        """
        n = dict(FIELD_NAMES)
        n.update(names or {})
        where = str(self.source) if self.source is not None else f"model set {self.material!r}"

        def fail(msg: str) -> None:
            raise DataError(f"{where}: {msg}")

        base = int(n.get("index_base", "1"))  # HaTT numbers models from 1, JSON lists from 0

        def model_name(m: int) -> str:
            label = n["model"]
            return label.format(m + base) if "{}" in label else f"{label} {m + base}"

        for key in ("sample_rate", "max_speed", "max_force"):
            value = getattr(self, key)
            if isinstance(value, (np.integer, np.floating)):
                value = float(value)
                setattr(self, key, value)
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value) or value <= 0:
                fail(f"{n[key]} must be a finite number > 0, got {value!r}")
        if self.mu is not None:
            self.mu = float(self.mu)
        if self.mu is not None and (not math.isfinite(self.mu) or self.mu < 0):
            fail(f"{n['mu']} must be a finite number >= 0, got {self.mu!r}")

        vec = {}
        for key in ("speeds", "forces", "variance", "gain"):
            arr = np.ascontiguousarray(getattr(self, key), dtype=np.float64)
            if arr.ndim != 1:
                fail(f"{n[key]} must be a list of numbers, got shape {arr.shape}")
            vec[key] = arr
        m_count = vec["speeds"].shape[0]
        if m_count < 3:
            fail(f"a model set needs at least 3 models to form a triangle, {n['speeds']} has {m_count}")
        for key, arr in vec.items():
            if arr.shape[0] != m_count:
                fail(f"{n[key]} has {arr.shape[0]} values but there are {m_count} models (from {n['speeds']})")
            bad = np.flatnonzero(~np.isfinite(arr))
            if bad.size:
                fail(f"{model_name(int(bad[0]))}: {n[key]} is {float(arr[bad[0]])!r}; it must be a finite number")
            setattr(self, key, arr)
        for key, unit in (("speeds", "mm/s"), ("forces", "N")):  # magnitudes: the lookup never asks below 0, yet a
            below = np.flatnonzero(vec[key] < 0)  # model there was blended into every query near 0, silently
            if below.size:
                fail(f"{model_name(int(below[0]))}: {n[key]} is {float(vec[key][below[0]])!r} {unit}; a model's "
                     "speed and force are magnitudes (>= 0): fix the file")
        neg = np.flatnonzero(vec["variance"] < 0)
        if neg.size:
            fail(f"{model_name(int(neg[0]))}: {n['variance']} is {float(vec['variance'][neg[0]])!r}; a variance must be >= 0")
        _, first, counts = np.unique(np.column_stack([vec["speeds"], vec["forces"]]), axis=0, return_index=True, return_counts=True)
        if np.any(counts > 1):
            point = np.column_stack([vec["speeds"], vec["forces"]])[first[np.argmax(counts > 1)]]
            twins = np.flatnonzero((vec["speeds"] == point[0]) & (vec["forces"] == point[1]))
            fail(f"{model_name(int(twins[0]))} and {model_name(int(twins[1]))} sit at the same point "
                 f"({float(point[0]):g} mm/s, {float(point[1]):g} N); a model set needs one model per (speed, force): "
                 "remove or merge the duplicate")

        for key in ("ar_lsf", "ma_lsf"):
            arr = np.ascontiguousarray(getattr(self, key), dtype=np.float64)
            if arr.ndim != 2 or arr.shape[0] != m_count:
                fail(f"{n[key]}: expected {m_count} models x order values, got shape {arr.shape}")
            self._check_lsf(arr, key, n, fail, model_name)
            setattr(self, key, arr)
        if self.ar_order < 1:
            fail(f"{n['ar_lsf']}: the AR order must be at least 1")

        for key, order in (("ar_coeff", self.ar_order), ("ma_coeff", self.ma_order)):
            arr = getattr(self, key)
            if arr is None:
                continue
            arr = np.ascontiguousarray(arr, dtype=np.float64)
            if arr.shape != (m_count, order + 1):
                fail(f"{n[key]}: expected {order + 1} values per model (order {order} plus the leading 1), got shape {arr.shape}")
            bad = np.argwhere(~np.isfinite(arr))
            if bad.size:
                fail(f"{model_name(int(bad[0, 0]))}: {n[key]} value {int(bad[0, 1]) + 1} is not a finite number")
            setattr(self, key, arr)

        from ..dsp.interp import UnusableModel, model_output_powers

        try:  # what texture_lookup computes from every model when it builds; validate and load say it first
            with np.errstate(over="ignore", invalid="ignore"):
                powers = model_output_powers(self.ar_lsf, self.ma_lsf, vec["variance"], vec["gain"])
                gain_squared = vec["gain"] ** 2
        except UnusableModel as exc:
            fail(f"{model_name(exc.model)}: its LSFs give no stable filter in float64 (neighbouring LSFs, or one and 0 or "
                 "pi, nearly coincide: a pole on the unit circle), so it cannot render; refit the model or remove it")
        loud = np.flatnonzero(~(np.isfinite(powers) & np.isfinite(gain_squared)))  # gain^2 is blended between models
        if loud.size:  # gain 1e300: rendered, resampled and compared in powers beyond float64
            m = int(loud[0])
            fail(f"{model_name(m)} ({vec['speeds'][m]:g} mm/s, {vec['forces'][m]:g} N): gain {vec['gain'][m]:g} and variance "
                 f"{vec['variance'][m]:g}: gain^2 or the vibration power gain^2 x variance is beyond the largest float64 "
                 "number; fix the model's gain or variance" + (f" ({loud.size} models affected)" if loud.size > 1 else ""))

        tri = np.asarray(self.triangles)
        if tri.ndim != 2 or tri.shape[1] != 3 or tri.shape[0] < 1:
            fail(f"{n['triangles']}: expected at least one triangle of 3 model numbers, got shape {tri.shape}")
        if not np.issubdtype(tri.dtype, np.integer):
            if not np.all(np.isfinite(tri)) or np.any(tri != np.round(tri)):
                fail(f"{n['triangles']}: model numbers must be integers")
        tri = np.ascontiguousarray(tri, dtype=np.int64)
        for t, row in enumerate(tri):
            for v in row:
                if not 0 <= v < m_count:
                    fail(f"{n['triangles']} {t + 1} names model {int(v) + base}, but the models are numbered "
                         f"{base}..{m_count - 1 + base}")
            if len({int(v) for v in row}) < 3:
                fail(f"{n['triangles']} {t + 1} repeats a model: {[int(v) + base for v in row]}")
        pts = np.column_stack([vec["speeds"], vec["forces"]])
        a, b, c = pts[tri[:, 0]], pts[tri[:, 1]], pts[tri[:, 2]]
        area2 = (b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (b[:, 1] - a[:, 1]) * (c[:, 0] - a[:, 0])
        scale = max(float(np.ptp(pts[:, 0])), 1e-300) * max(float(np.ptp(pts[:, 1])), 1e-300)
        flat = np.flatnonzero(np.abs(area2) <= 1e-12 * scale)
        if flat.size:
            t = int(flat[0])
            fail(f"{n['triangles']} {t + 1} is degenerate: models {[int(v) + base for v in tri[t]]} lie on one line "
                 f"(points {[tuple(map(float, pts[v])) for v in tri[t]]})")
        self.triangles = tri
        return self

    @staticmethod
    def _check_lsf(arr: np.ndarray, key: str, n: Mapping[str, str], fail: Any, model_name: Any) -> None:
        bad = np.argwhere(~np.isfinite(arr))
        if bad.size:
            m, k = int(bad[0, 0]), int(bad[0, 1])
            fail(f"{model_name(m)}: {n[key]} value {k + 1} is {float(arr[m, k])!r}; LSFs must be finite")
        out = np.argwhere((arr <= 0.0) | (arr >= math.pi))
        if out.size:
            m, k = int(out[0, 0]), int(out[0, 1])
            fail(f"{model_name(m)}: {n[key]} value {k + 1} is {float(arr[m, k])!r}; LSFs must lie strictly between 0 and pi")
        if arr.shape[1] > 1:
            dec = np.argwhere(np.diff(arr, axis=1) <= 0.0)
            if dec.size:
                m, k = int(dec[0, 0]), int(dec[0, 1])
                fail(f"{model_name(m)}: {n[key]} is not strictly increasing: value {k + 2} ({float(arr[m, k + 1])!r}) "
                     f"<= value {k + 1} ({float(arr[m, k])!r}); the model is unstable or the file is corrupt")
