"""The streaming dft321 and resample kernels allocate nothing per tick (numba NRT allocation counts).

Run in a subprocess: numba counts allocations only when NUMBA_NRT_STATS=1 is
set before it is imported. A call from Python boxes its array arguments (a
fixed number of allocations per call); a 10-tick and a 3000-tick call must
therefore count the same.
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]

SCRIPT = """
import numpy as np
from numba.core.runtime import rtsys
import flowtex.dsp.dft321_stream as D
import flowtex.dsp.resample_stream as R

def count(kernel, p, s, si, x, y):
    a = rtsys.get_allocation_stats().alloc
    kernel(p, s, si, x, y)
    return rtsys.get_allocation_stats().alloc - a

x = np.random.default_rng(0).standard_normal((3000, 3))
for method in ("fft", "dft"):
    p = D.stream_params(64, 16, "hann", True, method)
    nf, ni = D.stream_state_sizes(64)
    s, si, y = np.zeros(nf), np.zeros(ni, np.int64), np.zeros((3000, 1))
    D.dft321_stream_block(p, s, si, x[:10], y[:10])
    print(count(D.dft321_stream_block, p, s, si, x[:10], y[:10]), count(D.dft321_stream_block, p, s, si, x, y))
for up, down in ((4, 1), (1, 4)):
    h = R.polyphase_filter(up, down, 60.0)
    p = R.stream_params(h, up, down)
    nf, ni = R.stream_state_sizes(h, up, down, 3)
    s, si, y = np.zeros(nf), np.zeros(ni, np.int64), np.zeros((3000, 3))
    R.resample_block(p, s, si, x[:10], y[:10])
    print(count(R.resample_block, p, s, si, x[:10], y[:10]), count(R.resample_block, p, s, si, x, y))
"""


def test_kernels_allocate_nothing_per_tick() -> None:
    env = {**os.environ, "NUMBA_NRT_STATS": "1", "PYTHONPATH": str(REPO)}
    out = subprocess.run([sys.executable, "-c", SCRIPT], env=env, capture_output=True, text=True, check=True).stdout
    rows = [tuple(map(int, line.split())) for line in out.split("\n") if line.strip()]
    assert len(rows) == 4
    for short, long in rows:
        assert short == long, rows
