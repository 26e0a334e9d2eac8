"""WavWriter: a float32 WAV written block by block (live --record-audio) reads back as the same samples scipy's whole
write gives, holds no more than a block in memory, becomes RF64 past 4 GiB, and leaves no partial file."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.io import wavfile

from flowtex.errors import DataError
from flowtex.io import wav
from flowtex.io.atomic import OutputError
from flowtex.io.wav import WavWriter, read_wav, write_wav
from tests.memory import peak_bytes


def _blocks(x, cuts):
    edges = [0, *sorted(cuts), len(x)]
    return [x[a:b] for a, b in zip(edges, edges[1:], strict=False)]


@settings(max_examples=25, deadline=None)
@given(n=st.integers(1, 300), channels=st.integers(1, 3), cuts=st.lists(st.integers(0, 300), max_size=5),
       seed=st.integers(0, 2**32 - 1))
def test_blocks_read_back_as_one_whole_write(tmp_path_factory, n, channels, cuts, seed):
    folder = tmp_path_factory.mktemp("w")
    x = np.random.default_rng(seed).uniform(-1, 1, (n, channels)).astype(np.float32)
    w = WavWriter(folder / "s.wav", 8000, channels)
    for block in _blocks(x, [c for c in cuts if c <= n]):
        w.write(block)
    w.close()
    write_wav(folder / "whole.wav", x, 8000)
    rate, data = wavfile.read(folder / "s.wav")
    assert rate == 8000 and data.dtype == np.float32 and np.array_equal(data.reshape(n, channels), x)
    assert read_wav(folder / "s.wav")[1].keys() == read_wav(folder / "whole.wav")[1].keys()
    for a, b in zip(read_wav(folder / "s.wav")[1].values(), read_wav(folder / "whole.wav")[1].values(), strict=True):
        assert np.array_equal(a, b)


def test_past_the_riff_limit_the_header_is_rf64(tmp_path, monkeypatch):
    """The RF64 header (4 GiB of samples stands as 4 KiB here) reads back with scipy, which writes the same form."""
    monkeypatch.setattr(wav, "RIFF_LIMIT", 4096)
    x = np.arange(4000, dtype=np.float32).reshape(-1, 2)
    w = WavWriter(tmp_path / "big.wav", 48000, 2)
    w.write(x)
    w.close()
    assert (tmp_path / "big.wav").read_bytes()[:4] == b"RF64"
    rate, data = wavfile.read(tmp_path / "big.wav")
    assert rate == 48000 and np.array_equal(data, x)


def test_memory_is_one_block_whatever_the_length(tmp_path):
    block = np.ones((8000, 2), dtype=np.float32)  # 64 KB

    def record(blocks):
        w = WavWriter(tmp_path / f"r{blocks}.wav", 8000, 2)
        for _ in range(blocks):
            w.write(block)
        w.close()

    assert peak_bytes(lambda: record(200)) < 4 * block.nbytes  # 12.8 MB written
    assert (tmp_path / "r200.wav").stat().st_size > 200 * block.nbytes


def test_a_refused_write_names_the_file_and_keeps_the_older_one(tmp_path):
    path = tmp_path / "s.wav"
    path.write_bytes(b"an older recording")
    w = WavWriter(path, 8000, 1)
    w.write(np.zeros(10))
    w.error = OSError(27, "File too large")  # as write() notes a refused write
    w.write(np.zeros(10))
    with pytest.raises(OutputError, match=f"^{path}: cannot write it \\(File too large\\); an older file"):
        w.close()
    assert path.read_bytes() == b"an older recording" and [p.name for p in tmp_path.iterdir()] == ["s.wav"]
    w.close()  # idempotent


def test_not_kept_leaves_nothing_and_a_bad_rate_is_refused(tmp_path):
    w = WavWriter(tmp_path / "s.wav", 8000, 1)
    w.write(np.zeros(10))
    w.close(keep=False)
    assert list(tmp_path.iterdir()) == []
    with pytest.raises(DataError, match="whole positive number of Hz"):
        WavWriter(tmp_path / "s.wav", 44100.5, 1)
    assert list(tmp_path.iterdir()) == []
