"""Regenerate the data of the scene example (graphs/scene_two_surfaces.yaml) in this folder.

    python graphs/data/make_scene_examples.py

Writes (all synthetic; flowtex ships no HaTT file), from the committed
``synthetic_texture.json`` and ``exploration.npz`` (make_texture_examples.py):

* ``rough_texture.json`` -- the example cork-like model set with every
  excitation variance multiplied by ``ROUGH_POWER_FACTOR``: the same spectra,
  16 times the vibration power (mean 3.2 (m/s^2)^2 over 50-250 mm/s and
  0.5-2.5 N, above the planner's texture threshold of 1; the original set's
  0.20 is below it);
* ``scene_strokes.npz`` -- the exploration (position mm, normal_force N, normal)
  plus ``surface``, the index of the touched surface in the scene's file order,
  switching mid-stroke at ``SWITCH_TIMES_S`` (in contact every time), and
  ``penetration`` (mm), the tool's depth below the plane z = 0, for scenes
  that render a base-surface stiffness. Every value lies on the example
  device's grid (graphs/devices/example.dbc), so a live session on the
  simulated device decodes exactly these numbers.

Deterministic: rerunning reproduces the committed bytes.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from flowtex.io.modelset import load_model_set, save_model_set

HERE = Path(__file__).parent
RATE = 1000.0
ROUGH_POWER_FACTOR = 16.0
SWITCH_TIMES_S = (6.0, 8.5, 11.2)
"""Surface 0 until 6.0 s (a 180 mm/s stroke at 1.5 N), then 1, 0, 1 (circles at 1-2 N; the lightening strokes)."""


def rough_model_set():
    ms = load_model_set(HERE / "synthetic_texture.json")
    ms.variance = ms.variance * ROUGH_POWER_FACTOR
    ms.material = "synthetic rough surface (the cork-like example with 16x the vibration power; not HaTT data)"
    ms.metadata = dict(ms.metadata, variance=f"synthetic_texture.json's x {ROUGH_POWER_FACTOR:g} (graphs/data/make_scene_examples.py)")
    return ms.validate()


def scene_strokes() -> dict[str, np.ndarray]:
    with np.load(HERE / "exploration.npz") as d:
        rec = {k: d[k] for k in ("position", "normal_force", "normal")}
    t = np.arange(rec["normal_force"].shape[0]) / RATE
    surface = (np.searchsorted(np.asarray(SWITCH_TIMES_S), t, side="right") % 2).astype(np.float64)
    penetration = np.round(np.maximum(-rec["position"][:, 2], 0.0) / 0.001) * 0.001  # the device's 1 um grid
    return {**rec, "surface": surface, "penetration": penetration}


def main(out_dir: Path = HERE) -> None:
    out_dir = Path(out_dir)
    save_model_set(rough_model_set(), out_dir / "rough_texture.json")
    np.savez_compressed(out_dir / "scene_strokes.npz", **scene_strokes(), rate=np.float64(RATE))


if __name__ == "__main__":
    main()
