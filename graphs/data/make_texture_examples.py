"""Regenerate the synthetic data of the texture-rendering examples in this folder.

    python graphs/data/make_texture_examples.py

Writes (all synthetic; flowtex ships no HaTT file):

* ``synthetic_texture.json`` -- a texture model set in flowtex's native format
  (docs/model-sets.md) shaped like HaTT's cork surface: 45 ARMA(19, 17)
  models over (0..380 mm/s) x (0..4 N), silent at zero speed and zero force,
  vibration RMS growing with speed and force, friction coefficient mu = 0.3
  (:func:`example_model_set`);
* ``synthetic_taps.json`` -- a tap library (docs/tap-library.md): decaying
  150 Hz sinusoids at incoming speeds 20, 50, 100 and 200 mm/s
  (``flowtex.datasets.taps.synthetic_tap_library``);
* ``speed_force.npz`` -- the same exploration as a speed-sensor rig records
  it: tangential ``speed`` (mm/s) and ``normal_force`` (N) only, with their
  units, for graphs/speed_force_texture.yaml (:func:`speed_force`);
* ``exploration.npz`` -- a 16 s free exploration of a flat surface (the plane
  z = 0, normal +z) at 1000 Hz, with the graph inputs of the texture examples:
  ``position`` (n, 3) mm, ``normal_force`` (n,) N, ``normal`` (n, 3) unit
  surface normal, and ``rate`` = 1000. See :func:`exploration` for its phases.

Every file is deterministic (no random numbers at all), so rerunning the
script reproduces the committed bytes.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
from scipy.signal import lfilter

from flowtex.datasets.model_sets import cork_like_model_set
from flowtex.datasets.taps import synthetic_tap_library
from flowtex.io.modelset import save_model_set
from flowtex.io.taplib import write_tap_library
from flowtex.models.texture import TextureModelSet

HERE = Path(__file__).parent
RATE = 1000.0
"""Hz, the examples' tick rate."""
SURFACE_STIFFNESS_N_PER_MM = 2.0
"""The tool presses into the surface by normal_force / stiffness (a stiff table, 0.5 mm per N)."""
POSITION_STEP_MM = 0.001
FORCE_STEP_N = 0.001
"""Resolution of the example device (graphs/devices/example.dbc): recorded values lie on its grid."""
ORIGIN_MM = np.array([12.0, -30.0, 0.0])
"""Where the exploration starts on the surface (mm)."""


RMS_AT_MAX_M_S2 = 2.0
"""Vibration RMS (m/s^2) of the example surface's model at (max speed, max force)."""


def example_model_set() -> TextureModelSet:
    """The example surface: ``cork_like_model_set`` with excitation variances rescaled to a plausible vibration level.

    A real surface vibrates more the faster and harder it is stroked (001,
    003). The cork-like set's resonances move with speed and force, which
    changes each model's power gain, so its raw variances do not make the
    level grow with speed. Here every measured model's variance is set so
    that its stationary output RMS, sqrt(var) g sqrt(sum h^2) with h the
    impulse response of C(z)/A(z), equals
    ``RMS_AT_MAX_M_S2 * (speed / max_speed) * (0.4 + 0.6 * force / max_force)``;
    the silent corner models keep variance 0.
    """
    ms = cork_like_model_set()
    ms.material = "synthetic cork-like surface (flowtex example, not HaTT data)"
    impulse = np.zeros(4000)
    impulse[0] = 1.0
    for m in range(ms.num_models):
        if ms.variance[m] == 0.0:
            continue
        h = lfilter(ms.ma_coeff[m], ms.ar_coeff[m], impulse)
        power = ms.gain[m] ** 2 * float(h @ h)
        target = RMS_AT_MAX_M_S2 * (ms.speeds[m] / ms.max_speed) * (0.4 + 0.6 * ms.forces[m] / ms.max_force)
        ms.variance[m] = target ** 2 / power
    ms.metadata = dict(ms.metadata, variance=f"rescaled by graphs/data/make_texture_examples.py (RMS {RMS_AT_MAX_M_S2} m/s^2 at max)")
    return ms.validate()


class _Vertical:
    """Builds the penetration d(t) into the surface (mm; negative = height above it), phase by phase."""

    def __init__(self, height_mm: float):
        self.d: list[float] = []
        self.value = -height_mm

    @property
    def t(self) -> float:
        return len(self.d) / RATE

    def _append(self, values: np.ndarray) -> None:
        self.d.extend(float(v) for v in values)
        if len(values):
            self.value = float(values[-1])

    def hold_until(self, t_end: float) -> None:
        """Keep the current height or penetration until ``t_end`` (s)."""
        self._append(np.full(max(0, round(t_end * RATE) - len(self.d)), self.value))

    def tap(self, approach_mm_s: float, force_n: float, settle_s: float = 0.06) -> None:
        """Fall at ``approach_mm_s`` onto the surface, then settle at ``force_n``.

        The penetration after impact is p (1 - exp(-t / tau)) with
        tau = p / approach speed, so the velocity is continuous at the impact
        and the force settles within a few tau.
        """
        height = -self.value
        assert height > 0
        fall = np.arange(1, int(math.floor(height / approach_mm_s * RATE)) + 1) / RATE
        self._append(-height + approach_mm_s * fall)
        start = self.value  # <= 0, just above the surface
        p = force_n / SURFACE_STIFFNESS_N_PER_MM
        tau = p / approach_mm_s
        t = np.arange(1, round(settle_s * RATE) + 1) / RATE
        # continue the fall until the surface, then the exponential settle
        t_hit = -start / approach_mm_s
        self._append(np.where(t < t_hit, start + approach_mm_s * t, p * (1.0 - np.exp(-(t - t_hit) / tau))))

    def force_to(self, force_n: float, duration_s: float) -> None:
        """Change the normal force smoothly (raised cosine) to ``force_n`` over ``duration_s`` (s)."""
        p0, p1 = self.value, force_n / SURFACE_STIFFNESS_N_PER_MM
        u = np.arange(1, round(duration_s * RATE) + 1) / round(duration_s * RATE)
        self._append(p0 + (p1 - p0) * 0.5 * (1.0 - np.cos(np.pi * u)))

    def lift(self, speed_mm_s: float, height_mm: float) -> None:
        """Rise at ``speed_mm_s`` until ``height_mm`` above the surface."""
        n = int(math.ceil((self.value + height_mm) / speed_mm_s * RATE))
        self._append(np.maximum(self.value - speed_mm_s * np.arange(1, n + 1) / RATE, -height_mm))


def _vertical_plan() -> np.ndarray:
    v = _Vertical(5.0)
    v.hold_until(1.0)
    v.tap(40.0, 1.0)                 # slow tap, then rest on the surface without moving
    v.hold_until(1.8)
    v.lift(50.0, 5.0)
    v.hold_until(2.2)
    v.tap(120.0, 2.0)                # faster tap, then strokes with changing force
    v.hold_until(2.6)
    v.force_to(0.6, 0.7)
    v.force_to(3.8, 1.2)
    v.force_to(1.5, 1.4)
    v.hold_until(7.5)                # 7.0..7.5: resting in contact
    v.force_to(1.0, 0.3)             # circles at about 1 N
    v.force_to(2.0, 0.8)
    v.force_to(1.0, 0.8)
    v.hold_until(9.5)
    v.lift(80.0, 5.0)                # lift off while still moving: texture must stop
    v.hold_until(10.6)
    v.tap(200.0, 1.5)                # fast oblique tap while sliding on
    v.force_to(0.2, 1.9)             # lighter and lighter
    v.hold_until(12.6)
    v.lift(40.0, 3.0)
    for start, speed, force in [(13.0, 60.0, 0.8), (13.5, 90.0, 1.2), (14.0, 150.0, 3.0), (14.6, 25.0, 0.5)]:
        v.hold_until(start)          # quick taps in place
        v.tap(speed, force, settle_s=0.05)
        v.hold_until(start + 0.18)
        v.lift(60.0, 3.0)
    v.hold_until(16.0)
    return np.asarray(v.d[:round(16.0 * RATE)])


# Tangential motion: speed (mm/s) and heading (rad) keyframes, linear in between.
# A heading jump by pi where the speed passes through 0 is a stroke reversal.
_SPEED_KEYS = [
    (0.0, 0.0), (2.6, 0.0), (3.1, 100.0), (3.6, 100.0), (3.9, 0.0), (4.3, 250.0), (4.6, 250.0), (5.0, 0.0),
    (5.4, 180.0), (6.5, 180.0), (7.0, 0.0), (7.5, 0.0), (7.8, 150.0), (9.5, 150.0), (9.8, 120.0), (10.6, 120.0),
    (11.0, 80.0), (11.6, 0.0), (12.0, 220.0), (12.4, 120.0), (12.8, 0.0), (16.0, 0.0),
]
_HEADING_KEYS = [
    (0.0, 0.0), (3.9, 0.0), (3.9001, math.pi), (5.0, math.pi), (5.0001, 0.0), (5.4, 0.0), (6.5, math.pi / 2), (7.5, math.pi / 2),
    (9.8, math.pi / 2 + 7.5 * 2.3), (10.6, math.pi / 2 + 7.5 * 2.3), (11.6, 0.3), (11.6001, 0.3 + math.pi), (16.0, 0.3 + math.pi),
]


def tangential_speed(n: int) -> np.ndarray:
    """The exploration's tangential speed (mm/s) at each of ``n`` samples: the speed keyframes, linear in between."""
    ks, vs = zip(*_SPEED_KEYS, strict=True)
    return np.interp(np.arange(n) / RATE, ks, vs)


def speed_force(seconds: float = 16.0) -> dict[str, np.ndarray]:
    """The exploration as a speed-sensor rig records it: ``speed`` (mm/s, tangential) and ``normal_force`` (N) only.

    The same motion as :func:`exploration` (its force, its keyframed speed, rounded to 0.01 mm/s), with no
    position: the input of graphs/speed_force_texture.yaml.
    """
    rec = exploration(seconds)
    speed = np.round(tangential_speed(rec["normal_force"].shape[0]) / 0.01) * 0.01
    return {"speed": speed, "normal_force": rec["normal_force"]}


def exploration(seconds: float = 16.0) -> dict[str, np.ndarray]:
    """A synthetic free exploration of the plane z = 0 (normal +z), sampled at 1000 Hz.

    Phases (s): 0-1 hovering 5 mm above the surface; 1.0 a slow tap (40 mm/s,
    settles at 1 N) and resting in contact; 2.2 a faster tap (120 mm/s, 2 N),
    then straight strokes with two reversals at up to 250 mm/s while the force
    goes 2 -> 0.6 -> 3.8 -> 1.5 N; 7.0-7.5 resting in contact; circles of
    radius 20 mm at 150 mm/s and 1-2 N; 9.5 lift-off while moving on at
    120 mm/s (out of contact); 10.6 a 200 mm/s tap while sliding at 120 mm/s,
    then strokes (one reversal) with the force falling to 0.2 N; 12.6 lift;
    four quick taps in place at 60, 90, 150 and 25 mm/s; hovering to the end.

    The normal force is the penetration times a surface stiffness of
    2 N/mm; position and force are rounded to the example device's
    resolution (1 um, 1 mN).
    """
    n = round(seconds * RATE)
    t = np.arange(n) / RATE
    d = _vertical_plan()[:n]
    kh, hs = zip(*_HEADING_KEYS, strict=True)
    speed = tangential_speed(n)
    heading = np.interp(t, kh, hs)
    step = np.stack([np.cos(heading), np.sin(heading)], axis=1) * (speed / RATE)[:, None]
    xy = np.cumsum(step, axis=0) - step[0]
    position = np.column_stack([xy, -d]) + ORIGIN_MM
    position = np.round(position / POSITION_STEP_MM) * POSITION_STEP_MM
    force = np.round(SURFACE_STIFFNESS_N_PER_MM * np.maximum(d, 0.0) / FORCE_STEP_N) * FORCE_STEP_N
    normal = np.tile([0.0, 0.0, 1.0], (n, 1))
    return {"position": position, "normal_force": force, "normal": normal}


def main(out_dir: Path = HERE) -> None:
    """Write the four files into ``out_dir`` (default: this folder)."""
    out_dir = Path(out_dir)
    save_model_set(example_model_set(), out_dir / "synthetic_texture.json")
    write_tap_library(out_dir / "synthetic_taps.json", synthetic_tap_library(name="synthetic taps"),
                      notes="synthetic decaying sinusoids (flowtex.datasets.taps.synthetic_tap_library), not measured data")
    rec = exploration()
    # compressed npz: same layout as flowtex.io.recordings.save_recording writes, a quarter of the size
    np.savez_compressed(out_dir / "exploration.npz", **rec, rate=np.float64(RATE))
    np.savez_compressed(out_dir / "speed_force.npz", **speed_force(), rate=np.float64(RATE),
                        units=np.array('{"speed": "mm/s", "normal_force": "N"}'))


if __name__ == "__main__":
    main()
