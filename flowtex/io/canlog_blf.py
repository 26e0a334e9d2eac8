"""BLF CAN logs read with python-can's parser inside bounds on what the file claims.

python-can's BLFReader trusts every size in the file: it unpacks a zlib container whole (a 1 MB container of zeros
unpacks to 1 GiB), keeps the unparsed rest of every container while one frame object claims to span them (its memory
grows with the file, its time with the square of it), and loops for ever on a frame object whose size is 0 (the same
frame again and again). :class:`BoundedBLFReader` reads the containers itself, with the limits of
:mod:`flowtex.limits`, and hands each unpacked container to python-can's frame parser; every refusal names the file
and the byte offset of the object.
"""

from __future__ import annotations

import re
import zlib
from collections.abc import Iterator
from pathlib import Path

import can
from can.io.blf import (
    FILE_HEADER_STRUCT,
    LOG_CONTAINER,
    LOG_CONTAINER_STRUCT,
    NO_COMPRESSION,
    OBJ_HEADER_BASE_STRUCT,
    ZLIB_DEFLATE,
    BLFReader,
)

from .. import limits
from ..errors import DataError
from ..limits import MAX_BLF_CONTAINER_BYTES, MAX_CANLOG_BYTES, check_frames

MIN_FRAME_OBJECT = 48
"""Bytes of the smallest frame object (a classic CAN message: 16-byte base header, 16-byte v1 header, 16 bytes of
frame); a container of n bytes holds at most n // 48 frames."""


MAX_CONTAINER_OBJECT = MAX_BLF_CONTAINER_BYTES + MAX_BLF_CONTAINER_BYTES // 64 + 4096
"""Bytes a container object may claim: its data stored uncompressed, or zlib's worst case for incompressible data
(5 bytes a 16 KiB block and a few more), and its headers. A larger claim is refused before it is read."""


def read_blf(path: Path) -> Iterator[can.Message]:
    """Frames of the BLF at ``path`` in file order; DataError (naming the file) for a header, an object or a container
    that claims more than the limits allow, or more than :data:`~flowtex.limits.MAX_CANLOG_FRAMES` frames."""
    with open(path, "rb") as fh:
        head = fh.read(FILE_HEADER_STRUCT.size)
    if len(head) < FILE_HEADER_STRUCT.size or head[:4] != b"LOGG":
        raise DataError(f"{path}: not a BLF log (it does not start with a BLF file header, 'LOGG'; {len(head)} bytes read)")
    header = FILE_HEADER_STRUCT.unpack(head)
    header_size, claimed = int(header[1]), int(header[12])
    if not FILE_HEADER_STRUCT.size <= header_size <= MAX_BLF_CONTAINER_BYTES:
        raise DataError(f"{path}: its header claims to be {header_size:,} bytes long; a BLF header is "
                        f"{FILE_HEADER_STRUCT.size} to {MAX_BLF_CONTAINER_BYTES:,} bytes (a damaged or forged file?)")
    check_frames(str(path), claimed, claimed=True)
    reader = BoundedBLFReader(path)
    try:
        for count, msg in enumerate(reader, 1):
            if count > limits.MAX_CANLOG_FRAMES:
                check_frames(f"{path} (frame {count:,})", count)
            yield msg
    finally:
        reader.stop()


class BoundedBLFReader(BLFReader):
    """python-can's BLFReader with its container loop bounded: a container unpacks to at most
    :data:`~flowtex.limits.MAX_BLF_CONTAINER_BYTES`, all containers to at most :data:`~flowtex.limits.MAX_CANLOG_BYTES`,
    a frame object spanning containers to at most MAX_BLF_CONTAINER_BYTES, and a container yields at most as many
    frames as its bytes can hold. A file cut inside an object header ends the frames, as a cut inside a container
    does in python-can (the caller compares the header's size and count with what it read)."""

    def __init__(self, path: Path):
        super().__init__(path)
        self._path = path
        if not callable(getattr(self, "_parse_container", None)) or not isinstance(getattr(self, "_tail", None), bytes):
            self.stop()
            raise DataError(f"{path}: this python-can ({getattr(can, '__version__', 'unknown version')}) has no BLF frame "
                            "parser where flowtex's bounded BLF reader calls it (BLFReader._parse_container and _tail, "
                            "python-can 4.3 to 4.6); install one of those versions, or convert the log to .asc")

    def __iter__(self) -> Iterator[can.Message]:
        base = OBJ_HEADER_BASE_STRUCT.size
        unpacked = 0
        while True:
            at = self.file.tell()
            head = self.file.read(base)
            if len(head) < base:  # end of file, or cut inside an object header
                break
            signature, _, _, obj_size, obj_type = OBJ_HEADER_BASE_STRUCT.unpack(head)
            if signature != b"LOBJ":
                raise self._error(at, f"no BLF object here (it starts with {signature!r}, not b'LOBJ')")
            if obj_size < base:
                raise self._error(at, f"an object claims {obj_size} bytes, less than its {base}-byte header")
            if obj_type != LOG_CONTAINER:  # no frames in it (python-can skips it too): passed over, not read
                self.file.seek(obj_size - base + obj_size % 4, 1)
                continue
            if obj_size > MAX_CONTAINER_OBJECT:
                raise self._error(at, f"a container claims {obj_size:,} bytes; one of at most "
                                      f"{MAX_BLF_CONTAINER_BYTES / 2**20:g} MiB unpacked (flowtex.limits.MAX_BLF_CONTAINER_BYTES) "
                                      "is smaller even stored uncompressed: a damaged or forged size")
            body = self.file.read(obj_size - base)
            self.file.read(obj_size % 4)  # padding
            if len(body) < LOG_CONTAINER_STRUCT.size:
                break  # cut inside the container's header
            method, _ = LOG_CONTAINER_STRUCT.unpack_from(body)
            data = self._unpack(at, method, body[LOG_CONTAINER_STRUCT.size:])
            if data is None:
                continue
            unpacked += len(data)
            if unpacked > MAX_CANLOG_BYTES:
                raise self._error(at, f"its containers unpack to more than {MAX_CANLOG_BYTES / 2**20:g} MiB; flowtex reads "
                                      "CAN logs up to that size (flowtex.limits.MAX_CANLOG_BYTES)")
            most = (len(self._tail) + len(data)) // MIN_FRAME_OBJECT + 1
            for found, msg in enumerate(self._frames_of(at, data), 1):
                if found > most:
                    raise self._error(at, f"the container's {len(data):,} bytes yield more than {most - 1:,} frames of at "
                                          f"least {MIN_FRAME_OBJECT} bytes: a frame object whose size does not move past it")
                yield msg
            if len(self._tail) > MAX_BLF_CONTAINER_BYTES:
                raise self._error(at, f"a frame object spans more than {MAX_BLF_CONTAINER_BYTES / 2**20:g} MiB of containers "
                                      "(a frame object is at most a few hundred bytes: a damaged or forged size)")

    def _frames_of(self, at: int, data: bytes) -> Iterator[can.Message]:
        """python-can's frames of one unpacked container; what its parser raises is named at the container's byte."""
        smaller = _object_smaller_than_its_header(self._tail + data)
        if smaller is not None:
            raise self._error(at, f"an object in this container claims {smaller} bytes, less than its "
                                  f"{OBJ_HEADER_BASE_STRUCT.size}-byte header (a damaged or forged size)")
        try:
            yield from self._parse_container(data)
        except Exception as exc:  # BLFParseError, struct.error, ... on objects it cannot read
            raise self._error(at, f"malformed frame object in this container: {exc}") from None

    def _unpack(self, at: int, method: int, payload: bytes) -> bytes | None:
        """The container's data (None: a compression method python-can does not know, skipped as python-can does)."""
        if method == NO_COMPRESSION:
            data = payload
        elif method == ZLIB_DEFLATE:
            unzip = zlib.decompressobj()
            data = unzip.decompress(payload, MAX_BLF_CONTAINER_BYTES + 1)
        else:
            return None
        if len(data) > MAX_BLF_CONTAINER_BYTES:
            raise self._error(at, f"a container unpacks to more than {MAX_BLF_CONTAINER_BYTES / 2**20:g} MiB (BLF writers "
                                  "write containers of 128 KiB; flowtex.limits.MAX_BLF_CONTAINER_BYTES): a damaged or forged file")
        return data

    def _error(self, at: int, problem: str) -> DataError:
        return DataError(f"{self._path} (byte {at}): {problem}")


_SMALL_OBJECT = re.compile(rb"LOBJ.{4}[\x00-\x0f]\x00\x00\x00", re.DOTALL)
"""An object header whose size (bytes 8-11, little-endian) is below the 16 bytes of the header itself."""


def _object_smaller_than_its_header(buffer: bytes) -> int | None:
    """The size an object of ``buffer`` (python-can's unpacked container data) claims when it is below its header's,
    found at the object boundaries python-can's parser walks; None when there is none.

    python-can steps from an object to the one ``obj_size`` bytes on: an object of size 0 whose header version it does
    not know is skipped onto itself, for ever and without a frame to count. The byte pattern is looked for first (at C
    speed); only where it occurs are the objects walked as python-can walks them (a frame's data bytes may hold it).
    """
    if _SMALL_OBJECT.search(buffer) is None:
        return None
    base = OBJ_HEADER_BASE_STRUCT.size
    pos = 0
    while True:
        found = buffer.find(b"LOBJ", pos, pos + 8)  # python-can's search, past an object's padding
        if found < 0 or found + base > len(buffer):
            return None  # python-can stops here (or raises, which _frames_of names)
        obj_size = OBJ_HEADER_BASE_STRUCT.unpack_from(buffer, found)[3]
        if obj_size < base:
            return obj_size
        pos = found + obj_size
