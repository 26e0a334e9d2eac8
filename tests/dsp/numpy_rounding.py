"""Where numpy's complex loops round as flowtex.dsp.npmath does, so that bit-for-bit claims against numpy hold.

numpy picks its loops for the CPU it runs on. On x86-64 with AVX2 and FMA3 its complex multiply fuses one product of
each part into the other (checked by tests/dsp/test_npmath.py on this project's machines); elsewhere (arm64, an x86
without FMA3, another numpy) it may not, and flowtex's kernels then agree with numpy within one or two roundings
instead: the tests assert the bound everywhere and the bits where the claim was made.
"""

from __future__ import annotations

import platform

import numpy as np

try:
    from numpy._core._multiarray_umath import __cpu_features__ as _FEATURES  # numpy >= 2
except ImportError:  # numpy 1.x
    from numpy.core._multiarray_umath import __cpu_features__ as _FEATURES

NUMPY_ROUNDS_AS_NPMATH = (platform.machine().lower() in ("x86_64", "amd64") and bool(_FEATURES.get("FMA3"))
                          and bool(_FEATURES.get("AVX2")) and int(np.__version__.split(".")[0]) >= 2)
"""True where the bit-for-bit agreement with numpy is claimed (and asserted)."""
