"""The streaming dft321 and resample kernels allocate nothing per tick (numba NRT allocation counts).

A call from Python boxes its array arguments (a fixed number of allocations per
call); a 10-tick and a 3000-tick call must therefore count the same. Counted in
this process (the ``nrt_allocations`` fixture switches numba's statistics on).
"""

from __future__ import annotations

import numpy as np

import flowtex.dsp.dft321_stream as D
import flowtex.dsp.resample_stream as R


def test_kernels_allocate_nothing_per_tick(nrt_allocations) -> None:
    count = nrt_allocations
    x = np.random.default_rng(0).standard_normal((3000, 3))
    rows = []
    for method in ("fft", "dft"):
        p = D.stream_params(64, 16, "hann", True, method)
        nf, ni = D.stream_state_sizes(64)
        s, si, y = np.zeros(nf), np.zeros(ni, np.int64), np.zeros((3000, 1))
        D.dft321_stream_block(p, s, si, x[:10], y[:10])  # compiled (or loaded) before counting
        rows.append((count(D.dft321_stream_block, p, s, si, x[:10], y[:10]), count(D.dft321_stream_block, p, s, si, x, y)))
    for up, down in ((4, 1), (1, 4)):
        h = R.polyphase_filter(up, down, 60.0)
        p = R.stream_params(h, up, down)
        nf, ni = R.stream_state_sizes(h, up, down, 3)
        s, si, y = np.zeros(nf), np.zeros(ni, np.int64), np.zeros((3000, 3))
        R.resample_block(p, s, si, x[:10], y[:10])
        rows.append((count(R.resample_block, p, s, si, x[:10], y[:10]), count(R.resample_block, p, s, si, x, y)))
    assert len(rows) == 4
    for short, long in rows:
        assert short == long and short > 0, rows  # > 0: the counter is on (it counts the boxing)
