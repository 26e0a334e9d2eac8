"""Regenerate the data of graphs/pattern_compliance.yaml (all synthetic, deterministic seeds).

    PYTHONPATH=. python graphs/data/make_pattern_examples.py

Writes:

* ``synthetic_pattern.json`` -- a pattern file (docs/pattern-format.md) fitted with
  ``flowtex.fit.pattern.fit_pattern`` to a 2 s synthetic grating recording: features
  every 2 mm along x, 180 Hz resonances decaying in 6 ms, scanned at 60 mm/s, 5 % noise
  (``flowtex.datasets.patterns.patterned_recording``, seed 1);
* ``pattern_demo.npz`` -- 6 s at 1000 Hz (float32): ``position`` (n, 3) mm sweeping
  x = 3..90 mm and back at 60 mm/s, and a probe stroking a material with k_c = 0.5
  (k_g = 0.5 kg): ``normal_force`` (n,) N and ``acceleration`` (n,) m/s^2
  (``flowtex.datasets.patterns.stroking_recording``, seed 7), plus ``rate``.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from flowtex.datasets.patterns import patterned_recording, stroking_recording
from flowtex.fit.pattern import fit_pattern
from flowtex.io.patternfile import write_pattern

HERE = Path(__file__).resolve().parent
RATE = 1000.0


def main() -> None:
    rec = patterned_recording(seconds=2.0, seed=1)
    pat = fit_pattern(rec["accel"], rec["position"], RATE, orders=range(2, 7))
    pat.metadata["recording"] = "flowtex.datasets.patterns.patterned_recording(seconds=2.0, seed=1)"
    write_pattern(HERE / "synthetic_pattern.json", pat)
    n = int(6 * RATE)
    t = np.arange(n) / RATE
    period = 2 * 87.0 / 60.0  # there and back over 87 mm at 60 mm/s
    phase = (t % period) / period
    x = 3.0 + 87.0 * np.where(phase < 0.5, 2 * phase, 2 - 2 * phase)
    position = np.column_stack([x, np.full(n, 5.0), np.zeros(n)])
    stroke = stroking_recording(0.5, seconds=6.0, k_g=0.5, seed=7)
    np.savez(HERE / "pattern_demo.npz", position=position.astype(np.float32), normal_force=stroke["force"].astype(np.float32),
             acceleration=stroke["accel"].astype(np.float32), rate=np.float64(RATE))


if __name__ == "__main__":
    main()
