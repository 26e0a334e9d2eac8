"""WAV files in and out, through ``scipy.io.wavfile`` (scipy is already a dependency; see docs/live.md).

scipy reads and writes uncompressed PCM (8/16/24/32-bit integer) and IEEE float
WAV, which is every WAV the audio path makes or a recorder of raw samples
writes; compressed formats (FLAC, MP3, ADPCM) are out of scope, so the
``soundfile``/libsndfile dependency would buy nothing here. flowtex writes
float32 (the samples handed to PortAudio, bit for bit). Channels become
signals ``ch0``, ``ch1``, ... in full-scale units (integer PCM is divided by
its full scale: 32768 for 16 bit, 2**23 for 24 bit, 2**31 for 32 bit, 128 around 128 for 8 bit). The one thing
read here without scipy is 24-bit PCM block by block (:class:`WavReader`), since scipy cannot memory-map it: the
headers are walked within :data:`MAX_CHUNKS` chunks (:func:`read_header`) and the samples become the int32 values
scipy reads (:func:`pcm24_samples`).
"""

from __future__ import annotations

import struct
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import DataError
from ..limits import check_values

MAX_CHUNKS = 1000
"""RIFF chunks walked to find ``data`` (real WAVs have a handful)."""

CHANNEL_PREFIX = "ch"


def channel_names(n: int) -> list[str]:
    """Signal names of a WAV's channels: ch0, ch1, ..."""
    return [f"{CHANNEL_PREFIX}{i}" for i in range(n)]


def read_wav(path: str | Path) -> tuple[float, dict[str, np.ndarray]]:
    """(rate in Hz, {``chN``: float64 samples in full-scale units}) of a WAV file."""
    from scipy.io import wavfile

    path = Path(path)
    claimed = data_values(path)
    if claimed is not None:
        check_values(path, claimed, "its data chunk")
        if claimed == 0:
            raise DataError(f"{path}: the WAV file has no samples (its data chunk is empty)")
    try:
        rate, data = wavfile.read(path)
    except OSError as exc:
        raise DataError(f"{path}: cannot read: {exc.strerror or exc}") from None
    except Exception as exc:  # scipy reports a broken header with ValueError, EOFError or even UnboundLocalError
        raise DataError(f"{path}: not a WAV file scipy can read ({type(exc).__name__}: {exc}); write PCM or float WAV") from None
    x = full_scale(data)
    return float(rate), {n: x[:, i] for i, n in enumerate(channel_names(x.shape[1]))}


def full_scale(data: np.ndarray) -> np.ndarray:
    """WAV samples as scipy reads them -> (frames, channels) float64 in full-scale units (see the module docstring)."""
    if data.dtype.kind == "f":
        x = data.astype(np.float64)
    elif data.dtype == np.uint8:
        x = (data.astype(np.float64) - 128.0) / 128.0
    else:
        x = data.astype(np.float64) / float(2 ** (8 * data.dtype.itemsize - 1))
    return x.reshape(x.shape[0], -1) if x.ndim < 2 else x


class WavReader:
    """A WAV file read block by block (:meth:`read`), as :func:`read_wav` reads it whole: the same float64 samples in
    full-scale units, in memory of the block asked for whatever the file's length (``--expect-audio`` of a long
    session). The data chunk is memory-mapped (scipy's ``mmap=True``: pages of the file, not allocations, read as the
    blocks are converted); PCM in 3-byte containers (24-bit), which scipy cannot map, is read from the file block by
    block (:func:`pcm24_samples`, the int32 values scipy reads). Attributes: ``rate`` (Hz), ``channels``, ``frames``
    (in the file), ``position`` (frames read)."""

    def __init__(self, path: str | Path):
        self.path = Path(path)
        self._fh: Any = None
        self._pcm24: WavHeader | None = None
        """The headers of a 24-bit PCM file read from ``_fh``; None when scipy maps the data chunk into ``_data``."""
        self._data: Any = None
        head = read_header(self.path)
        if head is not None and head.values == 0:
            raise DataError(f"{self.path}: the WAV file has no samples (its data chunk is empty)")
        if (head is not None and head.tag == WAVE_FORMAT_PCM and 0 < head.channels and head.block_align == 3 * head.channels
                and head.bytes_per_second == head.rate * head.block_align):  # else scipy reads or refuses it
            self._open_pcm24(head)
            return
        rate, data = self._mapped()
        self._data = data.reshape(data.shape[0], -1)
        self.rate, self.channels, self.frames, self.position = float(rate), self._data.shape[1], self._data.shape[0], 0

    def _mapped(self) -> tuple[float, np.ndarray]:
        """(rate, the data chunk as scipy maps it); a container scipy cannot map (5 to 7 bytes; 3 in padded frames) is
        read whole within :data:`~flowtex.limits.MAX_RECORDING_VALUES` (:func:`read_wav`)."""
        from scipy.io import wavfile

        try:
            try:
                rate, data = wavfile.read(self.path, mmap=True)
            except ValueError as exc:
                if "mmap" not in str(exc):
                    raise
                rate, whole = read_wav(self.path)  # within MAX_RECORDING_VALUES, refused in one line past it
                data = np.stack(list(whole.values()), axis=1)
        except OSError as exc:
            raise DataError(f"{self.path}: cannot read: {exc.strerror or exc}") from None
        except DataError:
            raise
        except Exception as exc:  # as read_wav: a broken header is ValueError, EOFError or even UnboundLocalError
            raise DataError(f"{self.path}: not a WAV file scipy can read ({type(exc).__name__}: {exc}); write PCM or float "
                            "WAV") from None
        return float(rate), data

    def _open_pcm24(self, head: WavHeader) -> None:
        """Read 24-bit PCM from the file itself, a block at a time; the data chunk must be whole frames within the file."""
        if head.data_bytes % head.block_align:
            raise DataError(f"{self.path}: its data chunk of {head.data_bytes:,} bytes is no whole number of "
                            f"{head.block_align}-byte frames ({head.channels} channel(s) of 24 bits): the file is damaged; "
                            "record it again")
        try:
            held = self.path.stat().st_size - head.data_offset
            if head.data_bytes > held:
                raise DataError(f"{self.path}: its data chunk claims {head.data_bytes:,} bytes but the file holds "
                                f"{max(held, 0):,} after its headers: the file was cut short; record it again")
            self._fh = open(self.path, "rb")
        except OSError as exc:
            raise DataError(f"{self.path}: cannot read: {exc.strerror or exc}") from None
        self._pcm24 = head
        self.rate, self.channels, self.frames, self.position = float(head.rate), head.channels, \
            head.data_bytes // head.block_align, 0

    def read(self, n: int) -> np.ndarray:
        """The next ``n`` frames (fewer at the end of the file) as (frames, channels) float64 in full-scale units."""
        a = self.position
        self.position = min(self.frames, a + max(0, int(n)))
        head = self._pcm24
        if head is None:
            return full_scale(np.asarray(self._data[a:self.position]))
        want = (self.position - a) * head.block_align
        self._fh.seek(head.data_offset + a * head.block_align)
        raw = self._fh.read(want)
        if len(raw) < want:
            raise DataError(f"{self.path}: the file ended at frame {a + len(raw) // head.block_align:,} of {self.frames:,} "
                            "while it was read (was it cut or rewritten meanwhile?); read it again once it is complete")
        return full_scale(pcm24_samples(raw, head.channels, head.big_endian))

    def close(self) -> None:
        """Release the file (its memory map, or the file read block by block)."""
        if self._fh is not None:
            self._fh.close()
            self._fh = None
        if self._data is None:
            return
        mm = getattr(self._data, "_mmap", None)
        self._data = self._data[:0]
        if mm is not None:
            mm.close()


WAVE_FORMAT_PCM = 1
"""``fmt`` chunk format tag of integer PCM."""
WAVE_FORMAT_EXTENSIBLE = 0xFFFE
"""``fmt`` tag whose sample format is the first four bytes of a sub-format GUID ending in :data:`_SUBFORMAT_TAIL`."""
_SUBFORMAT_TAIL = {False: b"\x00\x00\x10\x00\x80\x00\x00\xaa\x00\x38\x9b\x71",
                   True: b"\x00\x00\x00\x10\x80\x00\x00\xaa\x00\x38\x9b\x71"}
"""The GUID's last 12 bytes (RFC 2361), as scipy matches them, keyed by big-endian (RIFX)."""


@dataclass(frozen=True)
class WavHeader:
    """What the headers of a WAV say, read up to its ``data`` chunk without its samples (:func:`read_header`)."""

    tag: int
    """Sample format: :data:`WAVE_FORMAT_PCM`, 3 for IEEE float (an extensible header's sub-format)."""
    channels: int
    rate: int
    """Frames per second (Hz)."""
    bits: int
    """Bits per sample (``wBitsPerSample``); each sample's container is ``block_align // channels`` bytes."""
    block_align: int
    """Bytes per frame, all channels."""
    bytes_per_second: int
    """``nAvgBytesPerSec``: ``rate * block_align`` in a valid PCM header."""
    data_offset: int
    """Where the samples start, in bytes from the start of the file."""
    data_bytes: int
    """The size the ``data`` chunk claims (RF64: its ``ds64`` chunk's), which may exceed what the file holds."""
    big_endian: bool
    """A ``RIFX`` file: sizes and samples big-endian."""

    @property
    def values(self) -> int:
        """Samples (all channels) the data chunk claims."""
        return self.data_bytes // max(1, self.bits // 8)


def read_header(path: Path) -> WavHeader | None:
    """The headers of the WAV at ``path`` (RIFF, RIFX or RF64), walked chunk by chunk (at most :data:`MAX_CHUNKS`) to
    its ``data`` chunk, reading a bounded number of bytes; None if the file is no such WAVE or its ``fmt`` chunk is
    short or does not precede ``data`` (scipy then reports what it finds)."""
    try:
        with open(path, "rb") as fh:
            head = fh.read(12)
            if head[:4] not in (b"RIFF", b"RIFX", b"RF64") or head[8:12] != b"WAVE":
                return None
            end = ">" if head[:4] == b"RIFX" else "<"
            fmt, ds64 = b"", None
            for _ in range(MAX_CHUNKS):
                chunk = fh.read(8)
                if len(chunk) < 8:
                    return None
                cid, size = chunk[:4], struct.unpack(end + "I", chunk[4:])[0]
                if cid == b"data":
                    if len(fmt) < 16:
                        return None
                    tag, channels, rate, per_second, align, bits = struct.unpack(end + "HHIIHH", fmt[:16])
                    if (tag == WAVE_FORMAT_EXTENSIBLE and len(fmt) >= 40 and struct.unpack(end + "H", fmt[16:18])[0] >= 22
                            and fmt[28:40] == _SUBFORMAT_TAIL[end == ">"]):
                        tag = struct.unpack(end + "I", fmt[24:28])[0]
                    if head[:4] == b"RF64" and size == RIFF_LIMIT and ds64 is not None:
                        size = ds64
                    return WavHeader(tag, channels, rate, bits, align, per_second, fh.tell(), size, end == ">")
                body = fh.read(min(size, 40)) if cid in (b"fmt ", b"ds64") else b""
                if cid == b"fmt ":
                    fmt = body
                elif cid == b"ds64" and len(body) >= 16:
                    ds64 = struct.unpack("<Q", body[8:16])[0]
                fh.seek(size - len(body) + (size & 1), 1)
    except OSError:
        return None
    return None


def data_values(path: Path) -> int | None:
    """Samples (all channels) the ``data`` chunk of the WAV at ``path`` claims, from its headers alone; None if unknown.

    Read before scipy allocates the data: a sparse file of a few KB may claim 600 million samples. Unknown (None) when
    the file is no plain RIFF/WAVE or its ``fmt`` chunk does not precede ``data`` (:func:`read_header`); scipy then
    reports what it finds.
    """
    head = read_header(path)
    return None if head is None else head.values


def pcm24_samples(raw: bytes, channels: int, big_endian: bool = False) -> np.ndarray:
    """Frames of 3-byte PCM samples -> (frames, channels) int32 with each sample in the upper three bytes, the values
    scipy reads (so :func:`full_scale` divides them by 2**31)."""
    b = np.frombuffer(raw, dtype=np.uint8).reshape(-1, 3)
    words = np.zeros((b.shape[0], 4), dtype=np.uint8)
    if big_endian:
        words[:, :3] = b
    else:
        words[:, 1:] = b
    return words.view(">i4" if big_endian else "<i4").reshape(-1, channels)


def _check_rate(path: Path, rate: float) -> None:
    """Refuse a rate a WAV header cannot hold (a whole positive number of Hz)."""
    if rate != int(rate) or rate <= 0:
        raise DataError(f"{path}: a WAV file needs a whole positive number of Hz, got {rate:g}; resample to e.g. 8000 first")


def write_wav(path: str | Path, samples: np.ndarray, rate: float) -> None:
    """Write ``samples`` (n, channels) or (n,) as a float32 WAV at ``rate`` Hz (a whole number)."""
    from scipy.io import wavfile

    path = Path(path)
    _check_rate(path, rate)
    from .atomic import atomic_output, refused_write

    path.parent.mkdir(parents=True, exist_ok=True)
    try:
        with atomic_output(path) as tmp:  # a failure or Ctrl-C leaves no partial file
            wavfile.write(tmp, int(rate), np.ascontiguousarray(samples, dtype=np.float32))
    except OSError as exc:  # a full disk: one line naming the file
        raise refused_write(path, exc) from None


def write_signals_wav(path: str | Path, arrays: Mapping[str, np.ndarray], rate: float | None) -> None:
    """Write scalar signals (one per channel, in order) as a float32 WAV; values are taken as full-scale units."""
    if rate is None:
        raise DataError(f"{path}: a WAV file needs a sample rate; the signals state none")
    cols = []
    for name, a in arrays.items():
        a = np.asarray(a)
        if a.ndim != 1:
            raise DataError(f"{path}: signal {name!r} has shape {a.shape[1:]}; a WAV channel holds one scalar signal")
        cols.append(a)
    if not cols:
        raise DataError(f"{path}: no signals to write")
    write_wav(path, np.stack(cols, axis=1), rate)


RIFF_LIMIT = 0xFFFFFFFF
"""Largest RIFF or data chunk size a plain WAV header holds (4 GiB); a longer :class:`WavWriter` file becomes RF64."""
_JUNK = b"JUNK" + struct.pack("<I", 28) + bytes(28)
"""Room for RF64's ``ds64`` chunk (its 64-bit sizes), written as a JUNK chunk that every reader skips."""


class WavWriter:
    """A float32 WAV written as its frames come, so that a long recording is never held in memory: the frames go to a
    temporary file beside ``path`` (:func:`~flowtex.io.atomic.atomic_output`), whose header :meth:`close` fills in
    before renaming it over ``path`` (an older file stays as it was until then). Past 4 GiB the header becomes RF64's,
    as scipy writes one. A write the system refuses (a full disk) does not raise from :meth:`write`, which runs in the
    live loop: it is noted in :attr:`error`, nothing more is written, and :meth:`close` raises it."""

    def __init__(self, path: str | Path, rate: float, channels: int):
        from .atomic import atomic_output

        self.path = Path(path)
        _check_rate(self.path, rate)
        self.rate, self.channels, self.frames = int(rate), int(channels), 0
        self.error: OSError | None = None
        self._commit = atomic_output(self.path)
        tmp = self._commit.__enter__()
        try:
            self._fh: Any = open(tmp, "wb")
            self._fh.write(self._header())
        except OSError as exc:
            self._commit.__exit__(type(exc), exc, None)
            self._refused(exc)

    def _header(self) -> bytes:
        """The file's header for the frames written so far (RF64 past :data:`RIFF_LIMIT`)."""
        data = self.frames * self.channels * 4
        fmt = b"fmt " + struct.pack("<IHHIIHH", 16, 3, self.channels, self.rate, self.rate * self.channels * 4,
                                    self.channels * 4, 32)  # 3: IEEE float
        riff = 4 + len(_JUNK) + len(fmt) + 8 + data
        if riff <= RIFF_LIMIT:
            return b"RIFF" + struct.pack("<I", riff) + b"WAVE" + _JUNK + fmt + b"data" + struct.pack("<I", data)
        ds64 = b"ds64" + struct.pack("<IQQQI", 28, riff, data, self.frames, 0)
        return b"RF64" + struct.pack("<I", RIFF_LIMIT) + b"WAVE" + ds64 + fmt + b"data" + struct.pack("<I", RIFF_LIMIT)

    def write(self, frames: np.ndarray) -> None:
        """Append ``frames`` (n, channels), as float32."""
        if self.error is not None or self._fh is None:
            return
        try:
            self._fh.write(np.ascontiguousarray(frames, dtype=np.float32).reshape(-1, self.channels).tobytes())
        except OSError as exc:
            self.error = exc
            return
        self.frames += len(frames)

    def close(self, keep: bool = True) -> None:
        """Fill in the header and rename the file into place (``keep=False``: discard it). Idempotent; a failed write,
        or one that fails now, raises :class:`~flowtex.io.atomic.OutputError` naming the file (an older one is kept)."""
        fh, self._fh = self._fh, None
        if fh is None:
            return
        try:
            if self.error is None and keep:
                fh.seek(0)
                fh.write(self._header())
            fh.close()
        except OSError as exc:
            self.error = self.error or exc
        if self.error is None and keep:
            try:
                self._commit.__exit__(None, None, None)
                return
            except OSError as exc:
                self.error = exc
        problem = self.error
        self._commit.__exit__(RuntimeError, RuntimeError("not kept"), None)  # removes the temporary file
        if problem is not None:
            self._refused(problem)

    def _refused(self, exc: OSError) -> None:
        from .atomic import refused_write

        raise refused_write(self.path, exc) from None
