"""Read the arrays of an ``.npz`` file with every size checked before anything is allocated.

``numpy.load`` trusts each member's npy header: a 64-byte member claiming
10**12 samples asks for 8 TB, and a compressed member of zeros claiming
500,000,000 x 3 samples (11.6 MB on disk) for 12 GB. Here each member's header
is read first and checked against

* the bytes the zip directory says the member holds (a header claiming more
  than that is a truncated or forged file), and
* :data:`flowtex.limits.MAX_RECORDING_VALUES`, all members together (which also
  bounds what a compressed member may decompress to);

then exactly the claimed bytes are read. Object, structured and unknown
dtypes are refused (no pickle is ever loaded); numbers, booleans and text
are returned with their dtype for the caller to judge.
"""

from __future__ import annotations

import math
import zipfile
import zlib
from pathlib import Path

import numpy as np

from ..errors import DataError
from ..limits import MAX_RECORDING_VALUES, check_values, excerpt

_HEADER_LIMIT = 10_000
"""Longest npy header read (bytes; numpy's own default guard)."""


def read_npz_arrays(path: Path) -> dict[str, np.ndarray]:
    """Every member of the ``.npz`` at ``path`` by name (without ``.npy``); raises :class:`DataError` naming the file and member."""
    try:
        zf = zipfile.ZipFile(path)
    except (zipfile.BadZipFile, OSError, ValueError, EOFError) as exc:
        raise DataError(f"{path}: not a readable .npz recording ({excerpt(str(exc), 120)})") from None
    arrays: dict[str, np.ndarray] = {}
    total = 0
    with zf:
        for info in zf.infolist():
            name = info.filename[:-4] if info.filename.endswith(".npy") else info.filename
            if name in arrays:
                raise DataError(f"{path}: entry {excerpt(name)} appears twice in the .npz; write the file again")
            try:
                arr, count = _member(zf, info, path, name, total)
            except (zipfile.BadZipFile, zlib.error, EOFError, OSError, NotImplementedError, RuntimeError) as exc:
                raise DataError(f"{path}: entry {excerpt(name)} cannot be read ({excerpt(str(exc), 120)}); "
                                "the file is damaged") from None
            total += count
            arrays[name] = arr
    return arrays


def _member(zf: zipfile.ZipFile, info: zipfile.ZipInfo, path: Path, name: str, total: int) -> tuple[np.ndarray, int]:
    where = f"{path}: entry {excerpt(name)}"
    if info.file_size > MAX_RECORDING_VALUES * 8 + _HEADER_LIMIT:
        raise DataError(f"{where} unpacks to {info.file_size:,} bytes; flowtex reads recordings of up to "
                        f"{MAX_RECORDING_VALUES:,} numbers: split or decimate it first")
    with zf.open(info) as fh:
        try:
            version = np.lib.format.read_magic(fh)
            if version == (1, 0):
                shape, fortran, dtype = np.lib.format.read_array_header_1_0(fh, max_header_size=_HEADER_LIMIT)
            elif version == (2, 0):
                shape, fortran, dtype = np.lib.format.read_array_header_2_0(fh, max_header_size=_HEADER_LIMIT)
            else:
                raise DataError(f"{where}: npy format version {version} is not read by flowtex; save it with numpy.savez")
        except ValueError as exc:
            raise DataError(f"{where} is not an npy array ({excerpt(str(exc), 120)})") from None
        if dtype.hasobject or dtype.names is not None or dtype.subdtype is not None or dtype.kind not in "biufcUS":
            raise DataError(f"{where} has dtype {str(dtype)[:40]}; a recording holds plain numbers")
        if any(not isinstance(d, int) or d < 0 for d in shape):
            raise DataError(f"{where}: its header claims shape {excerpt(shape)}; an array's dimensions are counts (>= 0): "
                            "the file is damaged")
        count = math.prod(shape)
        check_values(path, total + count, f"entry {excerpt(name)} (shape {excerpt(shape)})"
                     + (", with the entries before it," if total else ""))
        need = count * dtype.itemsize
        held = info.file_size - fh.tell()
        if need > held:
            raise DataError(f"{where}: its header claims shape {excerpt(shape)} ({need:,} bytes) but the entry holds "
                            f"{max(held, 0):,} bytes; the file is truncated or damaged")
        data = bytearray(need)  # writable, so the array needs no copy
        got = fh.readinto(data)
    if got < need:
        raise DataError(f"{where}: {got:,} of {need:,} bytes present; the file is truncated")
    arr = np.frombuffer(data, dtype=dtype)
    arr = arr.reshape(shape[::-1]).T if fortran else arr.reshape(shape)
    return arr, count
