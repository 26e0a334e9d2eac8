"""numpy's complex arithmetic in compiled kernels, rounded as numpy rounds it: a kernel that replaces numpy array code
keeps every result bit for bit.

Why: the fits iterate (Levenberg-Marquardt, IRLS, restarts that keep the best), so a difference in the last bit of a
spectrum can send a fit to another, equally good optimum (a resampled model set moved by up to 0.06 dB of path LSD
when only power_spectrum's rounding changed; docs/fitting.md). Replacing numpy by a kernel must therefore not change
the rounding.

What numpy 2 does on x86-64 with AVX2 and FMA3 (checked bit for bit by tests/dsp/test_npmath.py there; numpy picks
its loops per CPU, and where it does not fuse, as on a CPU without FMA, these stay within two roundings of numpy's
values, which the same tests check on every CPU):

- complex multiplication (a + jb)(c + jd) = fma(a, c, -(b d)) + j fma(a, d, b c): one fused multiply-add each;
- |a + jb| = L sqrt(fma(r, r, 1)) with L = max(|a|, |b|), r = min(|a|, |b|) / L (0 when L = 0), inf when either
  part is infinite, else nan when either is nan.

:func:`fma` is LLVM's ``llvm.fma`` intrinsic: one rounding on every CPU (an instruction where the CPU has one, a
correctly rounded library call where it does not).
"""

from __future__ import annotations

import math

from llvmlite import ir
from numba import njit, types
from numba.extending import intrinsic


@intrinsic
def fma(typingctx, x, y, z):  # noqa: ARG001  (numba's intrinsic signature)
    """x * y + z with one rounding (float64)."""
    sig = types.float64(types.float64, types.float64, types.float64)

    def codegen(context, builder, signature, args):  # noqa: ARG001
        d = ir.DoubleType()
        fn = builder.module.declare_intrinsic("llvm.fma", [d], ir.FunctionType(d, [d, d, d]))
        return builder.call(fn, args)

    return sig, codegen


@njit(cache=True, inline="always")
def cmul(ar: float, ai: float, br: float, bi: float) -> tuple[float, float]:
    """(ar + j ai)(br + j bi) as numpy multiplies complex128 arrays."""
    return fma(ar, br, -(ai * bi)), fma(ar, bi, ai * br)


@njit(cache=True, inline="always")
def cabs(re: float, im: float) -> float:
    """|re + j im| as numpy's ``abs`` of a complex128 array computes it."""
    re = abs(re)
    im = abs(im)
    if math.isinf(re) or math.isinf(im):
        return math.inf
    if math.isnan(re) or math.isnan(im):
        return math.nan
    larger = max(re, im)
    if larger == 0.0:
        return 0.0
    ratio = min(re, im) / larger
    return math.sqrt(fma(ratio, ratio, 1.0)) * larger
