"""Least-squares power laws in speed and force: ln y = b0 + b_speed ln speed + b_force ln force.

Texture power grows roughly as a power of speed and force. Two places fit such a law: the ``trend`` outside rule
(exponents of the measured models' output powers, flowtex.models.outside) and the pooled fit's level correction
(the pieces' powers weighted by their lengths, flowtex.fit.pooling). Both come here.
"""

from __future__ import annotations

import numpy as np


def power_law_design(speeds: np.ndarray, forces: np.ndarray) -> np.ndarray:
    """(N, 3) design matrix [1, ln speed, ln force] (speeds in mm/s, forces in N, both > 0)."""
    return np.column_stack([np.ones(len(speeds)), np.log(np.asarray(speeds, float)), np.log(np.asarray(forces, float))])


def fit_power_law(design: np.ndarray, values: np.ndarray, weights: np.ndarray | None = None) -> np.ndarray:
    """Coefficients b of ln values ~ design @ b by least squares (rows weighted by ``weights`` when given, e.g. the
    samples behind each value); ``design`` as :func:`power_law_design` makes it, or a subset of its columns."""
    y = np.log(np.asarray(values, float))
    if weights is None:
        return np.linalg.lstsq(design, y, rcond=None)[0]
    root = np.sqrt(np.asarray(weights, float))
    return np.linalg.lstsq(design * root[:, None], y * root, rcond=None)[0]
