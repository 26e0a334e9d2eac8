"""WavWriter: a float32 WAV written block by block (live --record-audio) reads back as the same samples scipy's whole
write gives, holds no more than a block in memory, becomes RF64 past 4 GiB, and leaves no partial file. WavReader
(--expect-audio) reads 24-bit PCM, which scipy cannot map, block by block as scipy reads it whole."""

from __future__ import annotations

import struct

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.io import wavfile

from flowtex.errors import DataError
from flowtex.io import wav
from flowtex.io.atomic import OutputError
from flowtex.io.wav import WavReader, WavWriter, read_wav, write_wav
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


def _pcm24(path, samples, rate=8000, extensible=False, big_endian=False, junk=False, claim=None):
    """Write int ``samples`` (frames, channels) in [-2**23, 2**23) as a 24-bit PCM WAV (scipy writes none): RIFF or
    RIFX, a plain or extensible ``fmt`` chunk, a JUNK chunk before it if asked; ``claim``: the data size to state."""
    e = ">" if big_endian else "<"
    frames, channels = samples.shape
    b = samples.astype(e + "i4").view(np.uint8).reshape(-1, 4)
    raw = (b[:, 1:] if big_endian else b[:, :3]).tobytes()
    fmt = struct.pack(e + "HHIIHH", 0xFFFE if extensible else 1, channels, rate, rate * channels * 3, channels * 3, 24)
    if extensible:
        fmt += struct.pack(e + "HHII", 22, 24, 0, 1) + wav._SUBFORMAT_TAIL[big_endian]
    body = b"WAVE" + (b"JUNK" + struct.pack(e + "I", 3) + b"abc\x00" if junk else b"")
    body += b"fmt " + struct.pack(e + "I", len(fmt)) + fmt
    body += b"data" + struct.pack(e + "I", len(raw) if claim is None else claim) + raw + b"\x00" * (len(raw) & 1)
    path.write_bytes((b"RIFX" if big_endian else b"RIFF") + struct.pack(e + "I", len(body)) + body)


@settings(max_examples=20, deadline=None)
@given(n=st.integers(1, 301), channels=st.integers(1, 3), blocks=st.lists(st.integers(1, 320), min_size=1, max_size=4),
       extensible=st.booleans(), big_endian=st.booleans(), junk=st.booleans(), seed=st.integers(0, 2**32 - 1))
def test_24_bit_pcm_read_block_by_block_equals_what_scipy_reads(tmp_path_factory, n, channels, blocks, extensible, big_endian,
                                                                 junk, seed):
    """The old reader asked scipy to map it and refused the file ("mmap=True not compatible with 3-byte container size")."""
    path = tmp_path_factory.mktemp("w") / "s.wav"
    x = np.random.default_rng(seed).integers(-2**23, 2**23, (n, channels))
    x[0, 0], x[-1, -1] = -2**23, 2**23 - 1  # both ends of the range
    _pcm24(path, x, extensible=extensible, big_endian=big_endian, junk=junk)
    rate, ref = wavfile.read(path)  # scipy, whole: the independent reference
    r = WavReader(path)
    got, i = [], 0
    while r.position < r.frames:
        got.append(r.read(blocks[i % len(blocks)]))
        i += 1
    assert r.read(5).shape == (0, channels)
    r.close()
    assert (r.rate, r.channels, r.frames) == (rate, channels, n)
    assert np.array_equal(np.concatenate(got), ref.reshape(n, channels) / 2.0**31)


def test_24_bit_pcm_memory_is_one_block_and_a_damaged_file_is_one_line(tmp_path):
    """A 24 MB data chunk (8 M mono frames, a sparse file) read 4,096 frames at a time: the peak is that of a block, not
    the 64 MB the whole float64 array (the old code's read) takes."""
    _pcm24(tmp_path / "long.wav", np.zeros((2, 1), dtype=np.int64), claim=3 * 8_000_000)
    with open(tmp_path / "long.wav", "r+b") as fh:
        fh.truncate(44 + 3 * 8_000_000)
    r = WavReader(tmp_path / "long.wav")

    def read_all():
        while r.position < r.frames:
            r.read(4096)

    assert peak_bytes(read_all) < 8 * 4096 * 8 and r.position == 8_000_000
    r.close()
    _pcm24(tmp_path / "cut.wav", np.zeros((10, 2), dtype=np.int64), claim=6 * 11)
    with pytest.raises(DataError, match=f"^{tmp_path / 'cut.wav'}: its data chunk claims 66 bytes but the file holds 60 after"):
        WavReader(tmp_path / "cut.wav")
    _pcm24(tmp_path / "odd.wav", np.zeros((10, 2), dtype=np.int64), claim=59)
    with pytest.raises(DataError, match="odd.wav: its data chunk of 59 bytes is no whole number of 6-byte frames"):
        WavReader(tmp_path / "odd.wav")
    _pcm24(tmp_path / "empty.wav", np.zeros((0, 1), dtype=np.int64))
    with pytest.raises(DataError, match="empty.wav: the WAV file has no samples"):
        WavReader(tmp_path / "empty.wav")
