"""The one fast-math setting of flowtex's numba kernels: fused multiply-add contraction, nothing else.

``{"contract"}`` lets LLVM fuse ``a * b + c`` into one FMA instruction where
the CPU has one: faster recursions, and each fused operation rounds once
instead of twice. No other fast-math flag is used (NaN and inf keep their
IEEE meaning, no reassociation), so on one machine results stay bit-identical
however a run is split into blocks.

Setting the environment variable ``FLOWTEX_CONTRACT=0`` before flowtex is
imported compiles the kernels without contraction (flowtex keys its numba
cache by this setting). benchmarks/bench_fastmath.py measures what
contraction buys; the decision is in docs/graph-format.md ("What is identical where").
"""

from __future__ import annotations

from ..config import CONTRACT_ENV, contract_enabled

__all__ = ["CONTRACT", "CONTRACT_ENV", "FASTMATH"]

CONTRACT = contract_enabled()
"""Whether kernels are compiled with FMA contraction (the default)."""

FASTMATH: set[str] = {"contract"} if CONTRACT else set()
"""The ``fastmath`` argument of every flowtex ``@njit`` that opts in."""
