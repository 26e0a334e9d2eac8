"""Regenerate the small synthetic example recordings in this folder.

    python graphs/data/make_examples.py

The recordings are synthetic (no third-party data): a 3-axis tool
acceleration made of gravity, slow hand motion and a texture-like vibration
whose strength follows the scanning speed.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from scipy import signal

from flowtex.io.recordings import save_recording

HERE = Path(__file__).parent
RATE = 1000.0


def accel_demo(seconds: float = 8.0, seed: int = 7) -> dict[str, np.ndarray]:
    rng = np.random.default_rng(seed)
    n = int(seconds * RATE)
    t = np.arange(n) / RATE
    gravity = np.array([0.0, 0.0, -9.81])
    hand = 0.8 * np.stack([np.sin(2 * np.pi * 0.7 * t), np.cos(2 * np.pi * 0.5 * t), 0.3 * np.sin(2 * np.pi * 1.1 * t)], axis=1)
    speed = 100.0 * (0.5 + 0.5 * np.sin(2 * np.pi * 0.25 * t) ** 2)  # mm/s, slowly varying
    # Texture-like vibration: AR(2) resonance at 180 Hz, amplitude proportional to speed.
    r, f0 = 0.97, 180.0
    a = [1.0, -2 * r * np.cos(2 * np.pi * f0 / RATE), r * r]
    vib = signal.lfilter([1.0], a, rng.standard_normal((n, 3)), axis=0) * (speed / 100.0)[:, None] * 0.2
    accel = gravity + hand + vib
    return {"accel": accel, "speed": speed}


def main() -> None:
    save_recording(HERE / "accel_demo.npz", accel_demo(), rate=RATE)
    save_recording(HERE / "accel_demo.csv", {k: v[:2000] for k, v in accel_demo().items()}, rate=RATE)


if __name__ == "__main__":
    main()
