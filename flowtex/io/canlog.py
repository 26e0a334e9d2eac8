"""CAN session logs (.blf, .log, .asc, .csv, .trc via python-can): write and read, with clear errors.

The live runtime records every frame it read (``is_rx=True``) and wrote
(``is_rx=False``) in the order it handled them. Both Vector BLF and the
candump ``.log`` format (python-can's trailing ``R``/``T``) and ASCII ``.asc``
keep the direction, so :func:`read_session` gives it back unchanged.
"""

from __future__ import annotations

import math
import time
from collections.abc import Iterable, Iterator
from dataclasses import dataclass, replace
from pathlib import Path

import can
from can.io.blf import FILE_HEADER_SIZE, FILE_HEADER_STRUCT

from ..errors import DataError
from ..limits import MAX_CANLOG_BYTES, check_file_size
from .atomic import atomic_output
from .canlog_blf import read_blf
from .canlog_text import TextLogFrames
from .formats import CAN_LOG, suffixes

WRITE_SUFFIXES = READ_SUFFIXES = suffixes(CAN_LOG)
"""From the format registry (flowtex.io.formats)."""


def check_log_path(path: str | Path, for_writing: bool) -> Path:
    """``path`` as a Path if its suffix is a supported CAN log format, else DataError."""
    path = Path(path)
    suffixes = WRITE_SUFFIXES if for_writing else READ_SUFFIXES
    if path.suffix.lower() not in suffixes:
        raise DataError(f"{path}: CAN logs must end in {', '.join(suffixes)} (got {path.suffix or 'no suffix'!r})")
    if for_writing and not path.parent.exists():
        raise DataError(f"{path}: folder {path.parent} does not exist")
    return path


class RecordError(DataError):
    """A CAN log could not be written (disk full, file too large, device gone): one line naming the log."""


class SessionWriter:
    """Append frames to a CAN log; marks direction (``is_rx``) in every format.

    The frames go to a temporary file in the log's folder, renamed over ``path`` by :meth:`close`
    (:func:`~flowtex.io.atomic.atomic_output`): an existing log is replaced only by a complete one.
    A write the system refuses (a full disk) never raises from :meth:`write`, which runs in the live
    loop and at its exit: the writer notes it in :attr:`error`, writes nothing more, and :meth:`close`
    discards the temporary file and raises :class:`RecordError`.

    BLF files are written with zlib level 1 to keep the periodic compression
    of a 128 KiB container short (it runs inside the live loop's slack time).
    """

    def __init__(self, path: str | Path, option: str | None = None):
        self.path = check_log_path(path, for_writing=True)
        self._what = f"{option} {self.path}" if option else str(self.path)
        self.error: str | None = None
        """One line once a write failed (the log is then incomplete and will not be kept), else None."""
        suffix = self.path.suffix.lower()
        self._commit = atomic_output(self.path)
        tmp = self._commit.__enter__()  # a temporary file beside the log, renamed over it by close()
        try:
            if suffix == ".blf":
                self._writer = can.BLFWriter(tmp, compression_level=1)
            else:
                self._writer = can.Logger(tmp)
        except OSError as exc:
            self._commit.__exit__(type(exc), exc, exc.__traceback__)
            raise DataError(f"{self.path}: cannot write CAN log: {exc.strerror or exc}") from None
        self._blf = suffix == ".blf"
        self.frames = 0
        self._last_time = time.time()
        """The time of the last frame written, s (the wall time before the first)."""

    def write(self, msg: can.Message, is_rx: bool) -> None:
        """Log ``msg`` as received (``is_rx``) or sent by the runtime. ``msg`` may be reused afterwards."""
        if self.error is not None or self._writer is None:
            return
        msg.is_rx = is_rx
        if self._blf:
            msg.channel = None  # BLF stores small channel numbers; bus channel names (e.g. virtual's) do not fit
        if not isinstance(msg.timestamp, (int, float)) or not math.isfinite(msg.timestamp):
            # an interface's frame without a time (NaN, inf, None): written at the log's last time, as the replay reads
            # frames in order, never by their times. A .log wrote it as '(nan)', which no reader reads back (flowtex's
            # refuses the line, python-can's skips it); a .blf or .asc refused it and ended the session
            msg.timestamp = self._last_time
        try:
            self._writer.on_message_received(msg)
        except OSError as exc:
            self._failed(exc)
            return
        except (OverflowError, ValueError) as exc:  # python-can's .asc and .blf writers turn a frame's time into a date
            self._undated(msg.timestamp, exc)
            return
        self.frames += 1
        self._last_time = msg.timestamp

    def _undated(self, stamp: float | None, exc: Exception) -> None:
        what = f"frame time {stamp:g} s" if stamp is not None else "a frame time"
        self.error = (f"{self._what}: {what} cannot be written in a {self.path.suffix} log, which dates every frame "
                      f"({exc}); write a .log, which takes any time; it was not kept (an older file of that name is left "
                      "as it was)")

    def _failed(self, exc: OSError) -> None:
        self.error = (f"{self._what}: cannot write the CAN log: {exc.strerror or exc}; it was not kept (an older file of "
                      "that name is left as it was)")

    def write_tick(self, received: Iterable[can.Message], sent: Iterable[can.Message]) -> None:
        """Log one tick of the live loop: the frames it received, then those it sent (stamped with the present wall time, s)."""
        ts = time.time()
        for m in received:
            self.write(m, True)
        for m in sent:
            m.timestamp = ts
            self.write(m, False)

    def close(self, keep: bool = True) -> None:
        """Flush and close the log, then rename it into place (idempotent; the old file stays until then).

        ``keep=False`` (a session that never ran, or stopped by an exception) or a failed write (:attr:`error`)
        discards the temporary file instead; a failed write, or a flush that fails now, raises :class:`RecordError`."""
        if self._writer is None:
            return
        writer, self._writer = self._writer, None
        try:
            writer.stop()
        except OSError as exc:
            if self.error is None:
                self._failed(exc)
        except (OverflowError, ValueError) as exc:  # the header's dates (a BLF's first and last frame times)
            if self.error is None:
                self._undated(None, exc)
        if self.error is None and keep:
            try:
                self._commit.__exit__(None, None, None)
                return
            except OSError as exc:
                self._failed(exc)
        problem = RecordError(self.error) if self.error is not None else None
        exc = problem or RecordError(f"{self._what}: not kept")
        self._commit.__exit__(type(exc), exc, None)  # removes the temporary file
        if problem is not None:
            raise problem


def read_session(path: str | Path) -> Iterator[can.Message]:
    """Frames of a session log in file order (with their ``is_rx`` direction), read as they are iterated.

    Errors in a text log (.log, .asc) name the file and line (:mod:`flowtex.io.canlog_text`); a BLF is read within
    bounds on what it claims (:mod:`flowtex.io.canlog_blf`). Every log is refused beyond
    :data:`~flowtex.limits.MAX_CANLOG_BYTES` or :data:`~flowtex.limits.MAX_CANLOG_FRAMES`."""
    yield from SessionFrames(path, whole_only=False)


def _readable_log(path: str | Path) -> Path:
    """``path`` as a Path once it is a CAN log's suffix and an existing regular file of at most
    :data:`~flowtex.limits.MAX_CANLOG_BYTES`, else DataError."""
    path = check_log_path(path, for_writing=False)
    check_file_size(path, "CAN log", MAX_CANLOG_BYTES)
    if path.is_dir():
        raise DataError(f"{path}: is a folder, not a CAN log")
    if not path.is_file():
        raise DataError(f"{path}: CAN log not found")
    return path


@dataclass(frozen=True)
class LogCompleteness:
    """What a session log's own framing says about whether it holds the whole session."""

    found_frames: int
    expected_frames: int | None = None
    """Frames the BLF header counts (None: a text log, or a BLF whose header was never written)."""
    problem: str | None = None
    """None when the log is complete as far as its format can tell; else why it is not (one phrase)."""
    lines: tuple[int, ...] = ()
    """A text log's line of each frame (1-based), for errors about a frame; empty for a BLF and from
    :class:`SessionFrames` (which names the frame being read instead: :meth:`SessionFrames.place`)."""


class SessionFrames:
    """The frames of a session log in file order, read one at a time as they are iterated: memory stays bounded
    whatever the log's length (the readers hold one text line, or one BLF container of at most
    :data:`~flowtex.limits.MAX_BLF_CONTAINER_BYTES`). Iterating again reads the file again.

    While iterating, :meth:`place` names the frame last yielded (``s.log:17``, ``s.blf (frame 17)``); once every frame
    is read, :attr:`completeness` says whether the file was cut short (see :func:`read_session_checked`).
    ``whole_only``: a text log's last line without a newline (cut off) is not read (else it is read, and named if malformed).
    """

    def __init__(self, path: str | Path, whole_only: bool = True):
        self.path = _readable_log(path)
        self._whole_only = whole_only
        self.number = 0
        """1-based position in the log of the frame last yielded."""
        self.line = 0
        """Line of the frame last yielded in a text log (0 in a BLF)."""
        self.completeness: LogCompleteness | None = None
        """None until every frame was read."""

    def __iter__(self) -> Iterator[can.Message]:
        self.number, self.line, self.completeness = 0, 0, None
        if self.path.suffix.lower() != ".blf":
            text = TextLogFrames(self.path, self._whole_only)
            for msg in text:
                self.number += 1
                self.line = text.line
                yield msg
            self.completeness = LogCompleteness(self.number, None, "its last line is cut off" if text.cut else None)
            return
        try:
            for msg in read_blf(self.path):
                self.number += 1
                yield msg
        except DataError:
            raise
        except OSError as exc:
            raise DataError(f"{self.path}: cannot read CAN log: {exc.strerror or exc}") from None
        except Exception as exc:  # python-can raises various errors for a malformed container
            raise DataError(f"{self.path}: malformed CAN log: {exc}") from None
        self.completeness = _blf_completeness(self.path, self.number)

    def place(self) -> str:
        """Where the frame last yielded is, for errors: ``s.log:17`` (its line) or ``s.blf (frame 17)`` (its position)."""
        return f"{self.path}:{self.line}" if self.line else f"{self.path} (frame {self.number})"

    def check_start(self, frames: int = 1000) -> None:
        """Read the log's header and its first ``frames`` frames, and drop them: a file that is no log, a header
        claiming more than the limits or a malformed first line fails here, in one line, before a long compile."""
        for n, _ in enumerate(self, 1):
            if n >= frames:
                break


def open_session(path: str | Path) -> SessionFrames:
    """The session log at ``path``, checked at its start (:meth:`SessionFrames.check_start`: a bad log fails fast) and
    ready to be streamed once more, from its first frame, by the replay."""
    session = SessionFrames(path)
    session.check_start()
    return session


def read_session_checked(path: str | Path) -> tuple[list[can.Message], LogCompleteness]:
    """Every frame of a session log (:func:`read_session`), held in a list, and whether the file was cut short.

    python-can reads a truncated BLF silently up to the cut (zlib returns what it can), so the file's
    header is compared with what was read: the header's file size and frame count (written when the
    log is closed) against the file's size and the frames found. A header never written (size
    144 bytes, no frames, a longer file) means the writer was killed. A text log (.log, .asc) is cut
    when its last line has no newline: the frames of the lines before it are read.
    The replay streams the log instead (:class:`SessionFrames`); this holds every frame, for small logs and tests.
    """
    session = SessionFrames(path)
    frames: list[can.Message] = []
    lines: list[int] = []
    for msg in session:
        frames.append(msg)
        lines.append(session.line)
    assert session.completeness is not None  # set once the frames are all read
    return frames, replace(session.completeness, lines=tuple(lines) if session.line else ())


def _blf_completeness(path: Path, found: int) -> LogCompleteness:
    """A BLF's header (size and frame count, written when the log is closed) against its file and the ``found`` frames."""
    size = path.stat().st_size
    with open(path, "rb") as fh:
        header = FILE_HEADER_STRUCT.unpack(fh.read(FILE_HEADER_STRUCT.size))
    stated_size, count = int(header[10]), int(header[12])
    if stated_size == FILE_HEADER_SIZE and count == 0 and size > FILE_HEADER_SIZE:
        return LogCompleteness(found, None, "its header was never written (was the recording session killed?)")
    if size < stated_size or found < count:
        return LogCompleteness(found, count, f"{size} of the {stated_size} bytes and {found} of the {count} frames its "
                                             "header states are in the file")
    return LogCompleteness(found, count)
