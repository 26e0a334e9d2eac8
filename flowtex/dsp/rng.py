"""Seeded Gaussian noise whose whole state lives in caller-owned arrays.

xoshiro256** (Blackman & Vigna) for uniform 64-bit integers, Marsaglia's
polar method for standard normals. Keeping the state in arrays (4 words in an
int64 array, one cached normal in a float64 array) lets a graph's arena hold
it: reset, chunked runs and live stepping all give the same sequence.
"""

from __future__ import annotations

import numpy as np
from numba import njit

STATE_INTS = 5
"""int64 words: 4 of xoshiro state + 1 flag 'a cached normal is waiting'."""
STATE_FLOATS = 1
"""float64 words: the cached second normal of the last polar-method pair."""


def seed_rng(istate: np.ndarray, fstate: np.ndarray, seed: np.random.SeedSequence) -> None:
    """Fill the xoshiro words from ``seed`` (never all zero) and clear the cache."""
    words = seed.generate_state(4, dtype=np.uint64)
    if not words.any():
        words[0] = 1
    istate[:4] = words.view(np.int64)
    istate[4] = 0
    fstate[0] = 0.0


@njit(inline="always")
def _rotl(x: np.uint64, k: int) -> np.uint64:
    return (x << np.uint64(k)) | (x >> np.uint64(64 - k))


@njit(cache=True)
def next_u64(si: np.ndarray) -> np.uint64:
    """Next 64-bit output of xoshiro256**, advancing ``si[0:4]``."""
    s0 = np.uint64(si[0])
    s1 = np.uint64(si[1])
    s2 = np.uint64(si[2])
    s3 = np.uint64(si[3])
    result = _rotl(s1 * np.uint64(5), 7) * np.uint64(9)
    t = s1 << np.uint64(17)
    s2 ^= s0
    s3 ^= s1
    s1 ^= s2
    s0 ^= s3
    s2 ^= t
    s3 = _rotl(s3, 45)
    si[0] = np.int64(s0)
    si[1] = np.int64(s1)
    si[2] = np.int64(s2)
    si[3] = np.int64(s3)
    return result


@njit(cache=True)
def next_uniform(si: np.ndarray) -> float:
    """Uniform double in [0, 1) with 53 random bits."""
    return float(next_u64(si) >> np.uint64(11)) * (1.0 / 9007199254740992.0)


@njit(cache=True)
def next_normal(si: np.ndarray, sf: np.ndarray) -> float:
    """Standard normal sample (polar method; the pair's second value is cached)."""
    if si[4] != 0:
        si[4] = 0
        return sf[0]
    # Accepts with probability pi/4; 200 rejections in a row only happen to a
    # generator that was never seeded (all-zero state, which xoshiro never leaves):
    # return 0 then rather than loop forever.
    for _ in range(200):
        u = 2.0 * next_uniform(si) - 1.0
        v = 2.0 * next_uniform(si) - 1.0
        r2 = u * u + v * v
        if 0.0 < r2 < 1.0:
            break
    else:
        return 0.0
    m = np.sqrt(-2.0 * np.log(r2) / r2)
    sf[0] = v * m
    si[4] = 1
    return u * m
