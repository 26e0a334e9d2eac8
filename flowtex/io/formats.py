"""The one format registry: which file formats flowtex reads and writes, found by suffix or by content.

Binary and tabular formats are known by their suffix (:data:`FORMATS`: kind, suffixes, reader, writer); flowtex's
own text files by their content (:func:`file_kind`: a JSON document by its ``format`` key, HaTT XML by its ``<``, a
YAML file by its keys). Output checks, ``run``, replay, ``validate``, ``resample`` and the fitters ask here, so a
format is added or renamed in one place. Readers and writers are named as ``module:function`` and imported only
when used.
"""

from __future__ import annotations

import importlib
import json
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from ..errors import DataError

RECORDING = "recording"
AUDIO = "audio"
CAN_LOG = "CAN session log"
GRAPH = "graph"
SCENE = "scene"
DEVICE_MAP = "device map"
MODEL_SET = "texture model set"
PATTERN = "pattern"
TAP_LIBRARY = "tap library"
FRICTION = "friction estimate"
COMPLIANCE = "compliance estimate"
DBC = "DBC"

TEXT_ENCODING = "utf-8-sig"
"""How flowtex reads its text files (CSV recordings and grid indexes, JSON documents, DBC files): UTF-8, with a
leading byte-order mark skipped. Windows editors and Excel's "CSV UTF-8" write one; read as plain UTF-8 it became
part of the first column's name (a signal ``\ufeffspeed`` that no graph input matches) or made a JSON file invalid."""


@dataclass(frozen=True)
class Format:
    """A file format known by its suffix: the kind of data it holds and the functions that read and write it."""

    name: str
    kind: str
    suffixes: tuple[str, ...]
    reader: str | None = None
    writer: str | None = None
    doc: str = ""

    def read(self) -> Callable[..., Any]:
        return _load(self.reader, self.name, "read")

    def write(self) -> Callable[..., Any]:
        return _load(self.writer, self.name, "written")


FORMATS: tuple[Format, ...] = (
    Format("npz", RECORDING, (".npz",), "flowtex.io.recordings:load_recording", "flowtex.io.recordings:save_recording",
           "NumPy archive: one array per signal, time first, plus 'rate'"),
    Format("csv", RECORDING, (".csv",), "flowtex.io.recordings:load_recording", "flowtex.io.recordings:save_recording",
           "one column per scalar, name[i] for vector components"),
    Format("hdf5", RECORDING, (".h5", ".hdf5"), "flowtex.io.recordings:load_recording", "flowtex.io.recordings:save_recording",
           "one dataset per signal (needs h5py)"),
    Format("wav", AUDIO, (".wav",), "flowtex.io.recordings:load_recording", "flowtex.io.recordings:save_recording",
           "channels ch0, ch1, ... at the audio rate"),
    Format("blf", CAN_LOG, (".blf",), "flowtex.io.canlog:read_session", "flowtex.io.canlog:SessionWriter", "Vector BLF CAN log"),
    Format("log", CAN_LOG, (".log",), "flowtex.io.canlog:read_session", "flowtex.io.canlog:SessionWriter", "candump/python-can text log"),
    Format("asc", CAN_LOG, (".asc",), "flowtex.io.canlog:read_session", "flowtex.io.canlog:SessionWriter", "Vector ASC CAN log"),
    Format("dbc", DBC, (".dbc",), "flowtex.io.dbc:load_dbc", None, "CAN database"),
)

JSON_FORMATS = {"flowtex-texture-models": MODEL_SET, "flowtex-pattern": PATTERN, "flowtex-tap-library": TAP_LIBRARY,
                "flowtex-friction": FRICTION, "flowtex-compliance": COMPLIANCE}
"""The ``format`` key of each flowtex JSON document -> its kind."""


OBJECT_FORMATS: dict[str, tuple[str, str]] = {
    "flowtex.models.texture:TextureModelSet": (MODEL_SET, "flowtex.io.modelset:load_model_set"),
    "flowtex.models.patterns:Pattern": (PATTERN, "flowtex.io.patternfile:read_pattern"),
    "flowtex.models.taps:TapLibrary": (TAP_LIBRARY, "flowtex.io.taplib:read_tap_library"),
}
"""A loaded object's type (``module:class``) -> the kind of file it is read from and the reader that reads it.

A node parameter declared ``Param("path", objects=(T,))`` takes a ``T``; given a file instead, it is read here by
T's reader before the node is built (flowtex.node_params.load_files, called where a graph is resolved and by
``Node.processor``), so nodes receive objects and never open files."""


def object_reader(types: tuple[type, ...]) -> Callable[[Path], Any] | None:
    """The reader of the first of ``types`` that :data:`OBJECT_FORMATS` knows (it raises DataError naming the file), or None."""
    for cls in types:
        entry = OBJECT_FORMATS.get(f"{cls.__module__}:{cls.__qualname__}")
        if entry is not None:
            return _load(entry[1], entry[0], "read")
    return None


def _load(target: str | None, name: str, verb: str) -> Callable[..., Any]:
    if target is None:
        raise DataError(f"{name} files cannot be {verb} by flowtex")
    module, _, attr = target.partition(":")
    return getattr(importlib.import_module(module), attr)


def suffixes(*kinds: str) -> tuple[str, ...]:
    """Every suffix (lower case, with the dot) of the formats of ``kinds``, in registry order."""
    return tuple(s for f in FORMATS if f.kind in kinds for s in f.suffixes)


def format_of(path: str | Path) -> Format | None:
    """The format of ``path`` by its suffix (case-insensitive), or None."""
    suffix = Path(path).suffix.lower()
    return next((f for f in FORMATS if suffix in f.suffixes), None)


def kind_of(path: str | Path) -> str | None:
    """The kind of data ``path`` holds by its suffix (RECORDING, AUDIO, CAN_LOG, DBC), or None."""
    f = format_of(path)
    return f.kind if f is not None else None


def listing(items: tuple[str, ...]) -> str:
    """``.npz, .csv, .h5 or .wav``: suffixes for a message."""
    return items[0] if len(items) == 1 else ", ".join(items[:-1]) + " or " + items[-1]


def json_kind(doc: Any) -> str | None:
    """The kind of a parsed JSON document by its ``format`` key; None if it names no flowtex format (or is no name)."""
    fmt = doc.get("format") if isinstance(doc, dict) else None
    return JSON_FORMATS.get(fmt) if isinstance(fmt, str) else None  # a list or an object is no format name


def file_kind(path: str | Path) -> str:
    """The kind of flowtex file at ``path``: from its suffix for binary formats, else from its content.

    A JSON document by its ``format`` key, HaTT XML by a leading ``<``, a YAML file by its keys (``flowtex_map``: a
    device map, ``surfaces``: a scene, anything else: a graph). Raises :class:`DataError` for unreadable text or a
    JSON document that names no flowtex format.
    """
    path = Path(path)
    kind = kind_of(path)
    if kind in (RECORDING, DBC, CAN_LOG):
        return kind
    suffix = path.suffix.lower()
    from ..limits import MAX_YAML_BYTES, check_file_size, excerpt

    if suffix in (".yaml", ".yml") and (not path.exists() or path.stat().st_size > MAX_YAML_BYTES):
        return GRAPH  # the graph loader says what is missing or too large, as validate always did
    raw = _read_text(path).lstrip("\ufeff")
    text = raw.lstrip(" \t\r\n")
    if suffix == ".xml" or text.startswith("<"):
        return MODEL_SET
    if suffix == ".json" or text.startswith("{"):
        try:
            doc = json.loads(raw)  # not the stripped text: the line numbers are the file's
        except json.JSONDecodeError as exc:  # where, as every flowtex JSON reader says it (flowtex.io.jsondoc)
            raise DataError(f"{path}:{exc.lineno}:{exc.colno}: not valid JSON ({exc.msg}); flowtex's JSON files are "
                            f"objects with a 'format' key: {', '.join(JSON_FORMATS)}") from None
        except (ValueError, RecursionError) as exc:  # nested too deep for the parser, or a number too long to convert
            why = "nested too deep" if isinstance(exc, RecursionError) else str(exc).split(";")[0]
            raise DataError(f"{path}: not valid JSON ({why}); flowtex's JSON files are objects with a "
                            f"'format' key: {', '.join(JSON_FORMATS)}") from None
        found = json_kind(doc)
        if found is None:
            formats = ", ".join(JSON_FORMATS)
            if not isinstance(doc, dict):
                what = {list: "an array", str: "a string", bool: "a boolean", type(None): "null"}.get(type(doc), "a number")
                raise DataError(f"{path}: holds {what}, not a JSON object with a 'format' key ({formats})")
            if "format" not in doc:
                raise DataError(f"{path}: no 'format' key: not a file flowtex reads ({formats}); the JSON that "
                                "compare --json and fit texture --holdout-json write is a report, not an input")
            raise DataError(f"{path}: key 'format' is {excerpt(doc['format'])}, not a flowtex file format ({formats})")
        return found
    from ..yamlsource import load_yaml

    check_file_size(path, "YAML file", MAX_YAML_BYTES)  # the YAML parser is slow: bounded before it starts
    data = load_yaml(raw, str(path))  # the whole text: its line numbers are the file's
    if isinstance(data, dict) and "flowtex_map" in data:
        return DEVICE_MAP
    if isinstance(data, dict) and "surfaces" in data:
        return SCENE
    return GRAPH


def _read_text(path: Path) -> str:
    from ..limits import check_file_size

    try:
        check_file_size(path, "flowtex file")
        return path.read_text(encoding=TEXT_ENCODING)
    except FileNotFoundError:
        raise DataError(f"{path}: file not found") from None
    except IsADirectoryError:
        raise DataError(f"{path}: is a folder; give a file") from None
    except UnicodeDecodeError as exc:  # binary data, or text in another encoding (Latin-1, UTF-16)
        raise DataError(f"{path}: not UTF-8 text (byte {exc.start}); flowtex's text files are UTF-8: save it as UTF-8, "
                        f"or give a recording ({', '.join(suffixes(RECORDING))})") from None
    except OSError as exc:
        raise DataError(f"{path}: cannot read ({exc.strerror or exc})") from None
