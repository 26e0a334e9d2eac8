"""Text CAN logs (.log candump format, .asc) read line by line, so that every error names the file and its line.

python-can's text readers iterate over a file object and raise bare Python errors (``invalid literal for int()
with base 16: 'ZZ'``) that say neither where nor what to fix; they also accept some lines silently that they
misread (an odd number of data hex digits in a .log line becomes a last byte the line does not hold). Here the
reader is handed :class:`NumberedLines`, which reads the file in bytes, counts its lines, refuses a line that is
not UTF-8 text (a binary file given a text log's suffix) and, for the candump format, checks each line's fields
before python-can parses it. Any other error python-can raises is reported at the line it was reading.
"""

from __future__ import annotations

import io
import re
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import BinaryIO

import can
from can.io.canutils import CAN_ERR_BUSERROR, CAN_ERR_FLAG

from .. import limits
from ..errors import DataError
from ..limits import check_frames, excerpt

MAX_LINE_BYTES = 64 * 1024
"""Longer lines are refused (a CAN FD line of an .asc log is a few hundred bytes): memory stays bounded on a binary file."""

CANDUMP_EXAMPLE = "(1700000000.000100) can0 100#0A1B2C3D R"
"""One line of the candump -L format with python-can's direction, quoted by every .log error."""

_HEX = re.compile(r"[0-9A-Fa-f]+\Z")
_CONTROL = re.compile(r"[\x00-\x08\x0b\x0c\x0e-\x1f\x7f]")
"""Control characters no text log holds (tab, CR and LF are allowed)."""


class NumberedLines:
    """The lines of a text log as ``str``, for python-can's text readers; :attr:`number` is the line last read (1-based).

    ``whole_only``: a last line without a newline (a log cut off while written) ends the iteration unread and sets
    :attr:`cut`, else it is read like the others. ``check(line) -> (problem, column) | None`` refuses a line.
    """

    def __init__(self, fh: BinaryIO, path: Path, whole_only: bool,
                 check: Callable[[str], tuple[str, int] | None] | None = None):
        self._fh, self.path, self._whole_only, self._check = fh, path, whole_only, check
        self.number = 0
        self.cut = False

    def __iter__(self) -> Iterator[str]:
        return self

    def __next__(self) -> str:
        raw = self._fh.readline(MAX_LINE_BYTES + 1)
        if not raw:
            raise StopIteration
        if len(raw) > MAX_LINE_BYTES:
            raise self.error(f"a line longer than {MAX_LINE_BYTES // 1024} KiB: is this a CAN log?", line=self.number + 1)
        if not raw.endswith(b"\n") and self._whole_only:
            self.cut = True
            raise StopIteration
        self.number += 1
        if self.number > limits.MAX_CANLOG_LINES:
            raise self.error(f"more than {limits.MAX_CANLOG_LINES:,} lines; flowtex reads text CAN logs of up to that many "
                             "(flowtex.limits.MAX_CANLOG_LINES): replay a shorter session")
        try:
            text = raw.decode("utf-8-sig" if self.number == 1 else "utf-8")  # a byte-order mark (Windows editors) is no text
        except UnicodeDecodeError as exc:
            raise self._not_text(raw[exc.start], exc.start) from None
        control = _CONTROL.search(text)
        if control is not None:
            raise self._not_text(ord(control.group()), control.start())
        if self._check is not None:
            problem = self._check(text)
            if problem is not None:
                raise self.error(problem[0], column=problem[1])
        return text

    def _not_text(self, byte: int, index: int) -> DataError:
        return self.error(f"byte {byte:#04x} is not text: is this a binary file named {self.path.suffix}? (text CAN logs "
                          "are candump -L .log or Vector .asc; a BLF log ends in .blf)", column=index + 1)

    def close(self) -> None:
        """python-can's ``stop()`` closes its file; the file handle belongs to the caller, which closes it."""

    def read(self, size: int = -1) -> str:
        """Not called: python-can's text readers iterate. python-can before 4.6 takes an object for an open file only
        when it has ``read`` and ``write`` (else it opens it as a path)."""
        raise io.UnsupportedOperation("a text CAN log is read line by line")

    def write(self, text: str) -> int:
        """Not called (see :meth:`read`): the log is only read."""
        raise io.UnsupportedOperation("a text CAN log is read, not written, here")

    def error(self, message: str, column: int = 0, line: int | None = None) -> DataError:
        """A DataError ``FILE:LINE[:COLUMN]: message`` at the line being read."""
        where = f"{self.path}:{self.number if line is None else line}" + (f":{column}" if column else "")
        return DataError(f"{where}: {message}")


def candump_problem(line: str) -> tuple[str, int] | None:
    """What is wrong with one line of a candump -L .log (python-can's trailing R/T allowed) and its column, or None.

    Checks what python-can's CanutilsLogReader parses: ``(TIMESTAMP) CHANNEL ID#DATA [R|T]`` with a finite
    timestamp, a hexadecimal ID (3 digits: standard, at most 0x7FF; up to 8: extended), and DATA as two hex digits a
    byte (at most 8 bytes; 64 in a CAN FD ``ID##F...`` frame) or ``R[DLC]`` for a remote frame. An 8-digit ID with
    CAN_ERR_FLAG (20000000) is an error frame, as python-can writes one received (``20000080#`` and up to 8 bytes).
    """
    fields = line.split()
    if not fields:
        return None
    form = f"(candump -L format, e.g. '{CANDUMP_EXAMPLE}')"
    columns = [m.start() + 1 for m in re.finditer(r"\S+", line)]
    if len(fields) < 3:
        return f"{len(fields)} field(s) where '(TIMESTAMP) CHANNEL ID#DATA' is expected: is the line cut? {form}", 1
    if len(fields) > 4:
        return f"{len(fields)} fields where '(TIMESTAMP) CHANNEL ID#DATA [R|T]' is expected {form}", columns[4]
    if len(fields) == 4 and fields[3].upper() not in ("R", "T"):
        return f"direction {excerpt(fields[3])} must be R (received) or T (sent) {form}", columns[3]
    stamp = fields[0]
    try:
        ok = stamp.startswith("(") and stamp.endswith(")") and abs(float(stamp[1:-1])) < float("inf")
    except ValueError:
        ok = False
    if not ok:
        return f"timestamp {excerpt(stamp)} is not '(SECONDS)' {form}", columns[0]
    frame, col = fields[2], columns[2]
    if "#" not in frame:
        return f"frame {excerpt(frame)} has no '#' between the CAN ID and the data {form}", col
    can_id, data = frame.split("#", 1)
    if not _HEX.match(can_id) or len(can_id) > 8:
        return f"CAN ID {excerpt(can_id)} is not 1 to 8 hexadecimal digits {form}", col
    if len(can_id) <= 3 and int(can_id, 16) > 0x7FF:
        return f"standard CAN ID {can_id} is above 7FF (write an extended ID with 8 digits, e.g. {int(can_id, 16):08X})", col
    if int(can_id, 16) >> 29 == CAN_ERR_FLAG >> 29 and len(can_id) == 8:  # the error flag, no other flag bit
        return _error_frame_problem(int(can_id, 16), data, form, col)
    if int(can_id, 16) > 0x1FFFFFFF:
        return f"extended CAN ID {can_id} is above 1FFFFFFF (a CAN ID has at most 29 bits)", col
    col += len(can_id) + 1
    limit = 8
    if data.startswith("#"):  # CAN FD: one hex digit of flags, then the data
        if len(data) < 2 or not _HEX.match(data[1]):
            return f"CAN FD frame {excerpt(frame)} needs one hex digit of flags after '##' {form}", col
        if not data[1].isdigit():
            return (f"CAN FD flags {data[1]!r} after '##': python-can reads flags 0 to 9 only (1 bit rate switch, 2 error "
                    "state, 4 FD frame)"), col + 1
        data, col, limit = data[2:], col + 2, 64
    elif data[:1] in ("R", "r"):
        if data[1:] and not (data[1:].isdigit() and int(data[1:]) <= 8):
            return f"remote frame length {excerpt(data[1:])} is not a DLC from 0 to 8 {form}", col + 1
        return None
    if data and not _HEX.match(data):
        bad = next(i for i, c in enumerate(data) if c not in "0123456789abcdefABCDEF")
        return f"data {excerpt(data)} is not hexadecimal (character {data[bad]!r}) {form}", col + bad
    if len(data) % 2:
        return f"data {excerpt(data)} has an odd number of hex digits ({len(data)}): two a byte {form}", col
    if len(data) // 2 > limit:
        return f"{len(data) // 2} data bytes; a {'CAN FD' if limit == 64 else 'classic CAN'} frame holds at most {limit}", col
    return None


def _error_frame_problem(can_id: int, data: str, form: str, col: int) -> tuple[str, int] | None:
    """The problem of a candump error frame ``2xxxxxxx#DATA`` (``can_id`` holds CAN_ERR_FLAG), or None: python-can reads
    it as an error frame only with the bus-error class bit (its own writer's ``20000080#``), else as a data frame."""
    if not can_id & CAN_ERR_BUSERROR:
        return (f"error frame {can_id:08X} (CAN_ERR_FLAG 20000000 with class {can_id & 0x1FFFFFFF:X}): python-can reads an "
                f"error frame only with the bus-error class bit 80 and would take this one for a data frame of ID "
                f"{can_id & 0x1FFFFFFF:#x}; delete the line or set that bit (e.g. {can_id | CAN_ERR_BUSERROR:08X})"), col
    col += 9
    if data and not _HEX.match(data):
        return f"error frame data {excerpt(data)} is not hexadecimal {form}", col
    if len(data) % 2 or len(data) > 16:
        return f"error frame data {excerpt(data)} is not 0 to 8 bytes of two hex digits each {form}", col
    return None


_ASC_FRAME = re.compile(r"\s*\d+\.\d+\s+\d+\s+(\S+)(?:\s+(Rx|Tx)(?:\s+(.*))?)?\s*\Z", re.IGNORECASE)
_ASC_TIME = re.compile(r"\d+\.\d+\Z")
"""The only timestamp python-can's ASCReader reads: it skips a frame line with any other (nan, 1e400, -0.5, 4)."""
"""An .asc line that starts like a classic CAN frame: TIME CHANNEL ID [Rx|Tx [d DLC BYTES... | r [DLC]]]."""
_ASC_BASE = re.compile(r"\s*base\s+(hex|dec)\b", re.IGNORECASE)


class AscCheck:
    """``check(line)`` for :class:`NumberedLines` on an .asc log: the problem of a classic CAN frame line python-can
    would skip without a word (cut after its ID or direction) or misread (fewer data bytes than its DLC), or None.
    Other lines (header, comments, events, CAN FD) are left to python-can, which skips what it does not know."""

    def __init__(self) -> None:
        self.base = 16
        self.in_header = True
        """Set False by :class:`AscLines` where python-can's header ends: a ``base`` line after it is ignored, as there."""

    def __call__(self, line: str) -> tuple[str, int] | None:
        base = _ASC_BASE.match(line)
        if base is not None:
            if self.in_header:
                self.base = 16 if base.group(1).lower() == "hex" else 10
            return None
        m = _ASC_FRAME.match(line)
        if m is None:
            tokens = line.split()
            if len(tokens) >= 4 and tokens[3].lower() in ("rx", "tx") and not _ASC_TIME.match(tokens[0]):
                return (f"timestamp {excerpt(tokens[0])} is not a number of seconds (DIGITS.DIGITS, e.g. 12.345000; python-can "
                        "would skip the frame)", line.index(tokens[0]) + 1)
            if len(tokens) >= 2 and tokens[1].upper() == "CANFD" and _ASC_TIME.match(tokens[0]):
                return self._canfd(tokens)
            return None
        if m.group(1).lower().startswith("errorframe") or m.group(1).upper() == "CANFD":
            return None
        digits = self.digits
        problem = self._id_problem(m.group(1))
        if problem is not None:
            return problem, m.start(1) + 1
        if m.group(2) is None:
            return (f"the frame line ends after {excerpt(m.group(1))}: is the line cut? (an .asc frame is "
                    "'TIME CHANNEL ID Rx|Tx d DLC BYTES...')", m.start(1) + 1)
        rest = (m.group(3) or "").split()
        if not rest:
            return "the frame line ends after its direction: is the line cut? (expected 'd DLC BYTES...')", m.end(2) + 1
        if rest[0].lower() != "d":
            return None  # a remote frame (r [DLC]): nothing to misread
        if len(rest) < 2 or not rest[1] or any(c not in digits for c in rest[1]):
            return f"DLC {excerpt(rest[1] if len(rest) > 1 else '')} is not a number (expected 'd DLC BYTES...')", m.start(3) + 1
        want = min(8, can.util.dlc2len(min(int(rest[1], self.base), 15)))
        have = rest[2:2 + want]
        if len(have) < want:
            return f"DLC {rest[1]} announces {want} data bytes but the line holds {len(have)}: is the line cut?", m.start(3) + 1
        for b in have:
            if any(c not in digits for c in b):
                return f"data byte {excerpt(b)} is not a number in base {self.base}", m.start(3) + 1
        return None


    @property
    def digits(self) -> str:
        """The characters of a number in the log's base (``base hex`` or ``base dec``)."""
        return "0123456789abcdefABCDEF"[: 10 if self.base == 10 else 22]

    def _id_problem(self, text: str) -> str | None:
        """What is wrong with a CAN ID of an .asc line (in the log's base; an extended one ends in x), or None."""
        ident = text[:-1] if text[-1:] in "xX" else text
        if not ident or any(c not in self.digits for c in ident):
            return f"CAN ID {excerpt(text)} is not a number in base {self.base} (an extended ID ends in x)"
        extended = ident != text
        top = 0x1FFFFFFF if extended else 0x7FF
        if int(ident, self.base) > top:
            why = "a CAN ID has at most 29 bits" if extended else "an extended ID ends in x"
            return f"{'extended' if extended else 'standard'} CAN ID {ident} is above {top:{'X' if self.base == 16 else 'd'}} ({why})"
        return None

    def _canfd(self, tokens: list[str]) -> tuple[str, int] | None:
        """The problem of a CAN FD line ``TIME CANFD CH Rx|Tx ID [NAME] BRS ESI DLC LENGTH BYTES...`` that python-can
        would misread (fewer bytes than its LENGTH, which it takes as the frame's length) or fail on, or None."""
        form = "(expected 'TIME CANFD CH Rx|Tx ID BRS ESI DLC LENGTH BYTES...')"
        rest = tokens[2:]
        if len(rest) < 7:
            return f"the CAN FD line ends after {len(tokens)} fields: is the line cut? {form}", 1
        problem = self._id_problem(rest[2])
        if problem is not None:
            return problem, 1
        fields = rest[3:7] if rest[3].isdigit() else rest[4:8]
        if len(fields) < 4 or not fields[3].isdigit():
            return f"CAN FD data length {excerpt(fields[3] if len(fields) > 3 else '')} is not a number of bytes {form}", 1
        length = int(fields[3])
        data = rest[(7 if rest[3].isdigit() else 8):][:length]
        if length > 64:
            return f"CAN FD data length {length} is more than the 64 bytes a CAN FD frame holds", 1
        if len(data) < length:
            return f"CAN FD data length {length} announces {length} bytes but the line holds {len(data)}: is the line cut?", 1
        bad = next((b for b in data if not b or any(c not in self.digits for c in b)), None)
        if bad is not None:
            return f"data byte {excerpt(bad)} is not a number in base {self.base}", 1
        return None


_ASC_HEADER = re.compile(r"date\s+\w+\s+.+|base\s+(hex|dec)|//", re.IGNORECASE)
_ASC_HEADER_END = re.compile(r"(no)?\s*internal\s+events\s+logged", re.IGNORECASE)
"""The header lines python-can's ASCReader reads (``_extract_header``: matched at the start of the stripped line), and
the line that ends its header."""


class AscLines(NumberedLines):
    """:class:`NumberedLines` of an .asc log for python-can's ASCReader, which reads header lines (date, base, comments)
    until ``internal events logged`` and takes whatever line comes first instead as the header's end, unread: a log
    without that line lost its first frame. Here such a header gets the line python-can expects (``no internal events
    logged``, which is what it says) before its first other line, so that line is read as any other is. Where the header
    ends the line check stops taking ``base`` lines, as python-can does."""

    def __init__(self, fh: BinaryIO, path: Path, whole_only: bool):
        self._asc = AscCheck()
        super().__init__(fh, path, whole_only, self._asc)
        self._held: str | None = None

    def __next__(self) -> str:
        if self._held is not None:
            text, self._held = self._held, None
            return text
        text = super().__next__()
        if self._asc.in_header and not _ASC_HEADER.match(text.strip()):
            self._asc.in_header = False
            if not _ASC_HEADER_END.match(text.strip()):
                self._held = text
                return "no internal events logged\n"
        return text


class TextLogFrames:
    """The frames of a .log or .asc session, read one line at a time as they are iterated (memory bounded whatever the
    log's length); :attr:`line` is the line of the frame last yielded and, once every frame is read, :attr:`cut` says
    whether the last line had no newline (``whole_only``: that line is then not read).

    Raises DataError ``FILE:LINE: ...`` for a line that is not text, a .log line that is malformed, any error
    python-can raises while reading a line, and a frame past :data:`~flowtex.limits.MAX_CANLOG_FRAMES`.
    """

    def __init__(self, path: Path, whole_only: bool):
        self.path, self._whole_only = path, whole_only
        self.line = 0
        self.cut = False

    def __iter__(self) -> Iterator[can.Message]:
        path = self.path
        asc = path.suffix.lower() == ".asc"
        try:
            fh = open(path, "rb")
        except OSError as exc:
            raise DataError(f"{path}: cannot read CAN log: {exc.strerror or exc}") from None
        with fh:
            source = AscLines(fh, path, self._whole_only) if asc else NumberedLines(fh, path, self._whole_only, candump_problem)
            reader = can.ASCReader(source) if asc else can.CanutilsLogReader(source)
            count = 0
            try:
                for msg in reader:
                    count += 1
                    if count > limits.MAX_CANLOG_FRAMES:
                        check_frames(f"{path}:{source.number}", count)
                    self.line = source.number
                    yield msg
            except DataError:
                raise
            except OSError as exc:
                raise DataError(f"{path}: cannot read CAN log: {exc.strerror or exc}") from None
            except Exception as exc:  # python-can raises ValueError, IndexError, ... on a line it cannot parse
                raise source.error(f"malformed {'ASC' if asc else 'CAN log'} line ({exc})") from None
            self.cut = source.cut
