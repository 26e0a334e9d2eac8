"""Documented limits every reader checks before it allocates, :func:`excerpt` for quoting user values and
:func:`suggest` for naming what they may have meant.

A hostile or broken file costs the user one line of text, never the machine's
memory: each reader compares what a file *claims* (an npy header's shape, a
YAML alias tree's expanded size, a document's nesting depth, a file's size)
with these limits first, and refuses with a :class:`~flowtex.errors.FlowtexError`
that names the file and the limit. The limits are far above anything a real
flowtex file needs; ``docs/recordings.md`` ("Limits") lists them.

This module sits at the bottom of the layers (beside ``errors``) so that the
YAML loader, the graph checker and every reader in ``flowtex.io`` share it.
"""

from __future__ import annotations

import difflib
import math
import os
import reprlib
import stat
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from .errors import DataError, InputError

MAX_RECORDING_VALUES = 100_000_000
"""Numbers a recording may hold, all signals together (800 MB as float64; 9 hours of 3 axes at 1 kHz)."""
MAX_AUDIO_SECONDS = 10 * 3600
"""Length of an audio stream flowtex renders, rebuilds or checks (``run --output OUT.wav``, a replay's ``.wav`` and
``--expect-audio``): 10 hours at the stream's rate, longer than a CAN log may last (:data:`MAX_CANLOG_FRAMES`, 8 hours).
Streams are rendered and compared block by block, so this bounds time and disk (10 hours of 48 kHz stereo float32 is
14 GB), not memory."""
MAX_TEXT_BYTES = 64 * 1024 * 1024
"""Size of a JSON or XML file (model set, pattern, tap library), read by C parsers (64 MiB)."""
MAX_YAML_BYTES = 1024 * 1024
"""Size of a YAML file (graph, scene, device map): 1 MiB, 250 times the largest bundled one. The safe YAML
parser is pure Python (tens of KiB per second; docs/recordings.md, Limits), so this bounds the time too."""
MAX_DBC_BYTES = 4 * 1024 * 1024
"""Size of a DBC file (cantools parses tens of KiB per second, so this bounds the time too; docs/recordings.md, Limits)."""
MAX_CANLOG_BYTES = 16 * 1024 * 1024 * 1024
"""Size of a CAN session log (.blf, .log, .asc) and, for a BLF, of its containers once unpacked (16 GiB): a candump
line of a frame is about 40 bytes, an .asc line about 60, a BLF frame 48 bytes unpacked, so this is above
:data:`MAX_CANLOG_FRAMES` of them. Logs are streamed, never held: this bounds time (unpacking and reading), not memory."""
MAX_CANLOG_FRAMES = 120_000_000
"""Frames of a CAN session log: 8 hours of a 1 kHz session with 4 frames a tick. The replay streams the log and holds
the frames of two ticks (flowtex.runtime.replay), so this bounds time, not memory: a log at this limit reads in minutes
(docs/recordings.md, Limits), and a hostile header or file cannot make a reader run for days."""
MAX_CANLOG_LINES = 2 * MAX_CANLOG_FRAMES
"""Lines of a text CAN log (.log, .asc), frames or not: a file of blank or comment lines within :data:`MAX_CANLOG_BYTES`
would otherwise take hours; twice the frames a log may hold, so it costs at most what a log at the frame limit does."""
MAX_TICK_FRAMES = 100_000
"""Frames one tick of a replayed session may have received (between two actuator blocks): the replay holds a tick's
frames, so a log of received frames without a block is refused here rather than held whole. A 1 Mbit/s bus carries
at most about 20,000 frames a second, and the live loop reads a few a tick; 100,000 (about 25 MB held) is 5 seconds
of a saturated bus in one tick."""
MAX_BLF_CONTAINER_BYTES = 16 * 1024 * 1024
"""Size of one BLF container once unpacked, and of a frame object that spans containers (python-can and Vector write
128 KiB containers): a zlib bomb in one container is refused at this size, never unpacked whole."""
MAX_DEPTH = 100
"""Nesting of maps and lists in YAML and JSON, and of elements in XML (real flowtex files nest fewer than 10)."""
MAX_YAML_NODES = 1_000_000
"""Values in a YAML document with every alias (``*name``) expanded: an alias bomb is refused, not built."""
MAX_YAML_INT = 10**300
"""YAML integers at or beyond this magnitude are refused while loading (every flowtex number fits a float64)."""
MAX_SIGNAL_WIDTH = 16
"""A recording signal may have more components per sample than samples only up to this width (else it looks transposed)."""
TIME_GAP_TOLERANCE = 1.5
"""A ``time`` column step longer than this many median steps is a gap (a sample or more is missing)."""
MAX_RATE_HZ = 1_000_000.0
"""Largest rate flowtex takes, from an option or a graph's ``rate``: 1 MHz, above any haptic or audio recording
(filters designed at absurd rates fail)."""
MAX_EVERY = 1_000_000
"""Largest ``every:`` of a graph node (ticks between runs)."""
MAX_INT_PARAM = 2**31 - 1
"""Upper bound of an integer node parameter that declares none (kernels hold parameters as float64)."""
MAX_PORT_VALUES = 65_536
"""Values one port carries per tick (a graph input's shape, a node's declared or resolved input or output): a 256 x
256 field, far beyond any haptic signal, and 512 KiB per buffer row of 1,024 ticks."""
MAX_NODE_PORTS = 27
"""Inputs and outputs of one node type together. Each is an argument of the kernel call in the graph's generated code,
after p, s and si; CPython compiles a call with more than 30 positional arguments into a form (list_to_tuple) numba
cannot compile."""
MAX_BUFFER_VALUES = 1 << 27
"""Values of all port buffers of a graph together (block rows x values per tick): 1 GiB of float64."""
MAX_STATE_VALUES = 1 << 27
"""Values of all node parameters and states of a graph together (1 GiB of float64); built-in nodes stay far below
(a delay of its largest 1e7 samples is 10 million), a plugin's state sized by an unbounded parameter may not."""
MAX_SEED = 2**63 - 1
"""Largest noise seed (``--seed``, a live session's ``seed``): a non-negative integer (numpy's SeedSequence), kept within
a signed 64-bit word."""
MAX_SEEDS = 64
"""Renders ``compare --seeds`` averages at most: the mean power of 64 renders scatters by ~0.06 dB (one render by
~0.5 dB), below what any figure of the comparison resolves; more only costs time (a full render each)."""
MAX_CONFIGURATIONS = 256
"""Knob combinations one ``bench`` runs at most (the product of the ``--knob`` value counts): each is compiled, run
``--repeats`` times and timed, seconds each, so 256 is already most of an hour."""
EXCERPT_CHARS = 60
"""Longest quote of a user value in an error message."""

class _Repr(reprlib.Repr):
    """reprlib's bounded repr, applied to dict and list subclasses too (the YAML loader's LocDict, LocList)."""

    def repr1(self, x: Any, level: int) -> str:
        if isinstance(x, dict) and type(x) is not dict:
            return self.repr_dict(x, level)
        if isinstance(x, list) and type(x) is not list:
            return self.repr_list(x, level)
        return super().repr1(x, level)


_repr = _Repr()
_repr.maxlevel = 3
_repr.maxlist = _repr.maxtuple = _repr.maxdict = _repr.maxset = 6
_repr.maxstring = _repr.maxother = _repr.maxlong = EXCERPT_CHARS


def excerpt(value: Any, limit: int = EXCERPT_CHARS) -> str:
    """A repr of ``value`` of at most ``limit`` characters, built without expanding large or shared structures."""
    try:
        text = _repr.repr(value)
    except Exception:  # a user value whose repr fails is still quoted by its type
        text = f"<{type(value).__name__}>"
    text = " ".join(text.split())
    return text if len(text) <= limit else text[: limit - 3] + "..."


def short_number(value: float) -> str:
    """A number for a message: ``%g`` when a float can hold it, else a short excerpt of the integer."""
    try:
        return f"{float(value):g}"
    except OverflowError:
        return excerpt(value, 24)


def signed(value: float, digits: int) -> str:
    """``value`` with its sign and ``digits`` decimals, a value that rounds to zero as ``+0.00`` (``-0.001`` printed
    ``-0.00`` with ``:+.2f``: a level "below" the recording by nothing)."""
    return f"{round(float(value), digits) + 0.0:+.{digits}f}"


def port_values_problem(shape: tuple[int, ...] | list[int]) -> str | None:
    """Why a port of ``shape`` is refused (more than :data:`MAX_PORT_VALUES` values per tick), or None."""
    count = math.prod(int(s) for s in shape)
    if count <= MAX_PORT_VALUES:
        return None
    return (f"shape {list(shape)} carries {count:,} values per tick; a port carries at most {MAX_PORT_VALUES:,} "
            "(flowtex.limits.MAX_PORT_VALUES)")


_SPECIAL = ((stat.S_ISFIFO, "a FIFO (named pipe)"), (stat.S_ISCHR, "a character device"), (stat.S_ISBLK, "a block device"),
            (stat.S_ISSOCK, "a socket"))


def not_regular(path: Path | str, kind: str) -> str | None:
    """Why ``path`` cannot be read as a ``kind``: it exists and is neither a regular file nor a folder; else None.

    Opening a FIFO blocks until someone writes; a device such as ``/dev/zero`` reports size 0 and never ends, so the
    size checks cannot bound it. Checked with ``stat`` (which opens nothing) before any reader opens the file.
    """
    try:
        mode = os.stat(path).st_mode
    except (OSError, ValueError):
        return None
    for test, what in _SPECIAL:
        if test(mode):
            return f"the {kind} is {what}, not a regular file; flowtex reads {kind}s from regular files only (copy the data into a file first)"
    return None


def check_regular(path: Path | str, kind: str) -> None:
    """Raise :class:`DataError` naming ``path`` when :func:`not_regular` refuses it."""
    problem = not_regular(path, kind)
    if problem is not None:
        raise DataError(f"{path}: {problem}")


def check_file_size(path: Path, kind: str, limit: int = MAX_TEXT_BYTES) -> None:
    """Refuse the file at ``path`` when it is not a regular file (:func:`check_regular`) or is larger than ``limit``
    bytes (a missing file passes: its reader says so)."""
    check_regular(path, kind)
    try:
        size = path.stat().st_size
    except OSError:
        return
    if size > limit:
        raise DataError(f"{path}: {kind} is {size / 2**20:.1f} MiB; flowtex reads such files up to {limit / 2**20:g} MiB "
                        "(is this the right file?)")


def check_values(path: Path | str, count: int, what: str) -> None:
    """Refuse a recording that would hold ``count`` numbers, more than :data:`MAX_RECORDING_VALUES`."""
    if count > MAX_RECORDING_VALUES:
        raise DataError(f"{path}: {what} holds {count:,} numbers; flowtex reads recordings of up to "
                        f"{MAX_RECORDING_VALUES:,} numbers ({MAX_RECORDING_VALUES * 8 / 1e6:,.0f} MB): split or decimate it first")


def max_audio_frames(rate: float) -> int:
    """Frames of :data:`MAX_AUDIO_SECONDS` at ``rate`` Hz."""
    return int(MAX_AUDIO_SECONDS * float(rate))


def check_ticks(what: str, ticks: int, per_tick: int, fix: str) -> None:
    """Refuse running ``ticks`` ticks at once whose arrays hold ``per_tick`` values each tick, more than
    :data:`MAX_RECORDING_VALUES` together: an :class:`InputError` naming ``what`` (e.g. ``ticks``) before anything is
    allocated, with ``fix``."""
    if ticks * per_tick > MAX_RECORDING_VALUES:
        raise InputError(f"{what}={ticks:,} would fill {ticks * per_tick:,} values, more than a recording may hold "
                         f"({MAX_RECORDING_VALUES:,}); {fix}")


def check_frames(where: str, count: int, claimed: bool = False) -> None:
    """Refuse a CAN log of ``count`` frames, more than :data:`MAX_CANLOG_FRAMES`: ``where`` names the file (and line or
    frame); ``claimed``: the count is what the log's header says, checked before reading."""
    if count <= MAX_CANLOG_FRAMES:
        return
    what = f"its header counts {count:,} frames" if claimed else f"more than {MAX_CANLOG_FRAMES:,} frames"
    raise DataError(f"{where}: {what}; flowtex reads CAN logs of up to {MAX_CANLOG_FRAMES:,} frames "
                    "(flowtex.limits.MAX_CANLOG_FRAMES, 8 hours at 1 kHz): split the session or replay a shorter one")


def depth_of(value: Any, limit: int = MAX_DEPTH) -> int:
    """Nesting depth of dicts and lists in ``value`` (a scalar is 0), counted without recursion; stops past ``limit``."""
    deepest = 0
    stack: list[tuple[Any, int]] = [(value, 0)]
    while stack:
        item, depth = stack.pop()
        if isinstance(item, dict):
            children = item.values()
        elif isinstance(item, list):
            children = item
        else:
            continue
        depth += 1
        deepest = max(deepest, depth)
        if deepest > limit:
            return deepest
        stack.extend((child, depth) for child in children)
    return deepest


def too_deep(path: Path | str, kind: str) -> DataError:
    """The error for a document nested deeper than :data:`MAX_DEPTH`."""
    return DataError(f"{path}: {kind} nests lists or maps more than {MAX_DEPTH} levels deep; flowtex files nest a few levels "
                     "(is this the right file?)")


def close_names(word: str, candidates: Sequence[str], n: int = 3) -> list[str]:
    """The up to ``n`` names of ``candidates`` close enough to ``word`` to be what was meant, closest first."""
    return difflib.get_close_matches(word, list(candidates), n=n, cutoff=0.6)


def suggest(word: str, candidates: Sequence[str]) -> str:
    """A ``" (did you mean 'x'?)"`` hint, or ``""`` when nothing is close."""
    close = close_names(word, candidates)
    if not close:
        return ""
    return " (did you mean " + " or ".join(repr(c) for c in close) + "?)"
