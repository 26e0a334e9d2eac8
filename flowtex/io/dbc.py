"""DBC files: load a device description with cantools and look signals up by name.

The DBC grammar is cantools' business; this module only turns cantools'
exceptions into one-line :class:`~flowtex.errors.DataError` messages that name
the file, and resolves the ``Message.Signal`` names used in map files (with
"did you mean" suggestions for typos).
"""

from __future__ import annotations

import difflib
import math
import re
from pathlib import Path

import cantools
from cantools.database.can import Database, Message, Signal

from ..errors import DataError
from ..limits import MAX_DBC_BYTES, check_file_size
from .formats import TEXT_ENCODING


def load_dbc(path: str | Path) -> Database:
    """Load the DBC file at ``path`` (strict: overlapping signals are errors).

    Raises :class:`DataError` naming the file (and the line when cantools
    reports one) for a missing, unreadable or malformed file.
    """
    path = Path(path)
    check_file_size(path, "DBC file", MAX_DBC_BYTES)  # first: a FIFO or device is refused as such, not "not found"
    if not path.is_file():
        raise DataError(f"{path}: DBC file not found")
    try:
        text = path.read_text(encoding=TEXT_ENCODING, errors="replace")
    except OSError as exc:
        raise DataError(f"{path}: cannot read DBC file: {exc.strerror or exc}") from None
    check_id_numbers(text, path)
    try:
        db = cantools.database.load_string(text, database_format="dbc", strict=True)
    except Exception as exc:  # cantools raises ParseError, Error, ValueError... all mean "bad file"
        raise DataError(f"{path}: not a valid DBC file: {one_line(exc)}") from None
    if not db.messages:
        raise DataError(f"{path}: the DBC file defines no messages (BO_ lines)")
    check_unique_ids(db, path)
    check_scales(db, path)
    return db


_BO_LINE = re.compile(r"^[ \t]*BO_[ \t]+(-?\d+)[ \t]+(\w+)", re.MULTILINE)
EXTENDED_FLAG = 1 << 31
"""Bit 31 of a BO_ line's number marks an extended (29-bit) frame, as in every DBC writer."""
MAX_STANDARD_ID = 1 << 11
MAX_EXTENDED_ID = 1 << 29


def check_id_numbers(text: str, path: str | Path = "DBC") -> None:
    """Refuse a ``BO_`` number that is no CAN ID, read from the DBC text before cantools masks it.

    cantools keeps only the low 32 bits of the number (``BO_ 1099511627776`` = 2^40 becomes standard ID 0x000, the
    highest-priority ID on a bus), so the number is checked as written: below 2^32, and once bit 31 (the extended
    flag) is taken off, below 2^29 for an extended frame and below 2^11 for a standard one.
    """
    for match in _BO_LINE.finditer(text):
        number, name = int(match.group(1)), match.group(2)
        line = text.count("\n", 0, match.start()) + 1
        if number < 0 or number >= 1 << 32:
            raise DataError(f"{path}:{line}: message {name!r} has CAN ID {number}, which is no CAN ID (a BO_ number is below "
                            f"2^32: a standard ID below 2^11 = {MAX_STANDARD_ID}, or an extended ID below 2^29 with bit 31 set); "
                            "fix its BO_ line")
        if number & EXTENDED_FLAG:
            can_id = number & ~EXTENDED_FLAG
            if can_id >= MAX_EXTENDED_ID:
                raise DataError(f"{path}:{line}: message {name!r} has extended CAN ID {can_id:#x}, beyond 29 bits "
                                f"(extended IDs are below {MAX_EXTENDED_ID:#x}); fix its BO_ line")
        elif number >= MAX_STANDARD_ID:
            raise DataError(f"{path}:{line}: message {name!r} has standard CAN ID {number:#x}, beyond 11 bits (standard IDs are "
                            f"below {MAX_STANDARD_ID:#x}; an extended ID is written with bit 31 set: {number | EXTENDED_FLAG} for "
                            f"{number:#x} if it is below 2^29); fix its BO_ line")


def check_unique_ids(db: Database, path: str | Path = "DBC") -> None:
    """Refuse two messages with one CAN ID (same ID and frame format): a frame with that ID would be read as either."""
    seen: dict[tuple[int, bool], str] = {}
    for m in db.messages:
        key = (int(m.frame_id), bool(m.is_extended_frame))
        if key in seen:
            kind = "extended" if key[1] else "standard"
            raise DataError(f"{path}: messages {seen[key]!r} and {m.name!r} both use {kind} CAN ID {key[0]:#x}; "
                            "give each message its own ID in its BO_ line")
        seen[key] = m.name


def check_scales(db: Database, path: str | Path) -> None:
    """Refuse a signal whose scale (factor) is 0 or not finite, or whose offset is not finite: no value could be encoded."""
    for msg in db.messages:
        for sig in msg.signals:
            scale, offset = sig.scale, sig.offset
            if not (isinstance(scale, (int, float)) and math.isfinite(scale) and scale != 0):
                raise DataError(f"{path}: signal {msg.name}.{sig.name} has scale {scale!r}; a DBC scale (the factor in "
                                "'(factor,offset)' of its SG_ line) must be a nonzero finite number")
            if not (isinstance(offset, (int, float)) and math.isfinite(offset)):
                raise DataError(f"{path}: signal {msg.name}.{sig.name} has offset {offset!r}; the offset in its SG_ line "
                                "must be a finite number")


def one_line(exc: BaseException) -> str:
    """An exception's message on one line (whitespace collapsed, at most 300 characters; its type name if empty)."""
    text = " ".join(str(exc).split()) or type(exc).__name__
    return text if len(text) <= 300 else text[:297] + "..."


def find_signal(db: Database, name: str, dbc_path: str | Path = "DBC") -> tuple[Message, Signal]:
    """Resolve ``"Message.Signal"`` (or a bare signal name that is unique in the DBC).

    Raises :class:`DataError` with the closest known names when ``name`` does
    not exist, or with the candidates when a bare name is ambiguous.
    """
    msg_name, dot, sig_name = name.partition(".")
    if dot:
        try:
            msg = db.get_message_by_name(msg_name)
        except KeyError:
            hint = suggest(msg_name, [m.name for m in db.messages])
            raise DataError(f"{dbc_path}: no message {msg_name!r} for signal {name!r}{hint}") from None
        for sig in msg.signals:
            if sig.name == sig_name:
                return msg, sig
        hint = suggest(sig_name, [s.name for s in msg.signals], prefix=f"{msg.name}.")
        raise DataError(f"{dbc_path}: message {msg.name!r} has no signal {sig_name!r}{hint}")
    hits = [(m, s) for m in db.messages for s in m.signals if s.name == name]
    if len(hits) == 1:
        return hits[0]
    if hits:
        options = ", ".join(f"{m.name}.{s.name}" for m, s in hits)
        raise DataError(f"{dbc_path}: signal name {name!r} is used by several messages; write one of {options}")
    everything = [f"{m.name}.{s.name}" for m in db.messages for s in m.signals]
    bare = {s.name: f"{m.name}.{s.name}" for m in db.messages for s in m.signals}
    close = difflib.get_close_matches(name, list(bare) + everything, n=3, cutoff=0.6)
    hint = f" (did you mean {', '.join(repr(bare.get(c, c)) for c in close)}?)" if close else ""
    raise DataError(f"{dbc_path}: no signal {name!r}{hint}")


def suggest(name: str, known: list[str], prefix: str = "") -> str:
    """`` (did you mean 'x'?)`` for the closest names in ``known``, or ``""``."""
    close = difflib.get_close_matches(name, known, n=3, cutoff=0.6)
    if not close:
        return f"; known: {', '.join(prefix + k for k in known[:12])}" if known else ""
    return f" (did you mean {', '.join(repr(prefix + c) for c in close)}?)"
