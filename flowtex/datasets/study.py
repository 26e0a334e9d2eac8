"""Synthetic stand-ins for the 15 surfaces of Culbertson & Kuchenbecker 2017's study, for tests, benchmarks and the docs example.

flowtex ships no HaTT file. These sets are built with
:func:`flowtex.datasets.model_sets.synthetic_model_set` (small orders, 3 x 3
grid) and scaled so that the planner's texture salience (mean vibration
power over speed 50-250 mm/s x force 0.5-2.5 N) equals the target below;
tap libraries are decaying sinusoids tuned to a target spectral centroid.

Values from Culbertson & Kuchenbecker 2017: powers of Whiteboard (0.25), Silk 1 (0.44), MDF
(1.19), Carpet 3 and ABS Plastic (~38), Brick 1 (200) (m/s^2)^2; mu of
Whiteboard (0.17), MDF (0.19), ABS (0.21), Silk 1 (0.28), Tarp (0.41), EPDM
Foam (1.39); Carpet 3's tap centroid 47.8 Hz. Every other number is
ILLUSTRATIVE (chosen on the side of the threshold that Culbertson & Kuchenbecker 2017's component-removal
results imply), not a measurement.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from ..io.atomic import write_text_atomic

SPEED_RANGE = (50.0, 250.0)
FORCE_RANGE = (0.5, 2.5)


@dataclass(frozen=True)
class StudySurface:
    key: str
    power: float
    """Target mean vibration power (m/s^2)^2 over SPEED_RANGE x FORCE_RANGE."""
    mu: float
    centroid_hz: float
    """Target tap spectral centroid (Hz)."""


STUDY_SURFACES = (
    StudySurface("ABS_Plastic", 38.0, 0.21, 260.0),
    StudySurface("Blanket", 3.0, 0.45, 90.0),
    StudySurface("Brick_1", 200.0, 0.42, 300.0),
    StudySurface("Carpet_3", 38.0, 0.40, 47.8),
    StudySurface("Cork", 0.6, 0.35, 150.0),
    StudySurface("EPDM_Foam", 4.0, 1.39, 80.0),
    StudySurface("MDF", 1.19, 0.19, 280.0),
    StudySurface("Nylon_Mesh", 60.0, 0.30, 180.0),
    StudySurface("Paper_Plate_2", 2.0, 0.33, 220.0),
    StudySurface("Polyethylene_Foam", 2.5, 0.38, 75.0),
    StudySurface("Sandpaper_100", 120.0, 0.45, 240.0),
    StudySurface("Silk_1", 0.44, 0.28, 120.0),
    StudySurface("Tarp", 0.8, 0.41, 160.0),
    StudySurface("Terra_Cotta", 25.0, 0.44, 290.0),
    StudySurface("Whiteboard", 0.25, 0.17, 320.0),
)


def study_model_set(surface: StudySurface, ar_order: int = 6, ma_order: int = 4):
    """A synthetic model set with the surface's mu, scaled to its target texture power."""
    from ..scene.salience import mean_texture_power
    from .model_sets import synthetic_model_set

    ms = synthetic_model_set([50.0, 150.0, 250.0], [0.5, 1.5, 2.5], ar_order, ma_order, mu=surface.mu, material=surface.key)
    ms.variance = ms.variance * (surface.power / mean_texture_power(ms, SPEED_RANGE, FORCE_RANGE))
    return ms


def study_tap_library(surface: StudySurface):
    """A synthetic tap library whose mean spectral centroid (50-100 mm/s) is the surface's target."""
    from scipy.optimize import brentq

    from ..models.taps import spectral_centroid
    from .taps import synthetic_tap_library

    def lib(freq: float):
        return synthetic_tap_library(freq_hz=freq, decay_s=0.02, stiffening=0.0, name=surface.key)

    freq = brentq(lambda f: spectral_centroid(lib(f)) - surface.centroid_hz, 5.0, 450.0, xtol=1e-6)
    return lib(freq)


def write_study_scene(folder: str | Path, keys: tuple[str, ...] | None = None, name: str = "study") -> Path:
    """Write model sets, tap libraries and ``scene.yaml`` for the chosen study surfaces (all 15 by default)."""
    from ..io.modelset import save_model_set
    from ..io.taplib import write_tap_library

    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    chosen = [s for s in STUDY_SURFACES if keys is None or s.key in keys]
    lines = ["flowtex: 1", f"name: {name}", "rate: 1000",
             f"trajectory: {{speed: [{SPEED_RANGE[0]:g}, {SPEED_RANGE[1]:g}], force: [{FORCE_RANGE[0]:g}, {FORCE_RANGE[1]:g}]}}",
             "surfaces:"]
    for s in chosen:
        save_model_set(study_model_set(s), folder / f"{s.key}.json")
        write_tap_library(folder / f"{s.key}_taps.json", study_tap_library(s))
        lines.append(f"  {s.key}: {{models: {s.key}.json, taps: {s.key}_taps.json}}")
    return write_text_atomic(folder / "scene.yaml", "\n".join(lines) + "\n")


__all__ = ["STUDY_SURFACES", "StudySurface", "study_model_set", "study_tap_library", "write_study_scene"]
