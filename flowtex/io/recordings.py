"""Recordings on disk: ``.npz``, ``.csv`` and ``.h5`` (HDF5, when h5py is installed).

One array per signal, time on the first axis. A recording may state its
sample rate in Hz; a graph refuses a recording whose stated rate is not its own.

* ``.npz``: one array per signal; an optional 0-d entry ``rate`` states the
  rate, an optional 0-d string entry ``units`` the units (JSON ``{"name": "unit"}``).
* ``.csv``: a header row of column names; a vector signal ``position`` of
  shape (3,) is written as columns ``position[0]``, ``position[1]``,
  ``position[2]``; optional comment lines before it: ``# rate: 1000`` states
  the rate, ``# units: {"position": "mm"}`` (JSON) the units.
* ``.h5``: one dataset per signal at the file's root; an optional root
  attribute ``rate``; an optional attribute ``unit`` on each dataset.

Units are written by ``flowtex run`` (the graph's output units). Reading a file only fills ``Recording.units``;
what uses a signal refuses one stated in another unit than it takes
(:func:`flowtex.io.recording_rules.check_stated_unit`: a graph input, a fit's option), and nothing converts units.
"""

from __future__ import annotations

import csv
import json
import re
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import DataError
from ..limits import MAX_RECORDING_VALUES, check_regular, check_values, excerpt
from .formats import AUDIO, CAN_LOG, RECORDING, TEXT_ENCODING, format_of, listing, suffixes
from .jsondoc import DuplicateKey, unique_keys
from .npzread import read_npz_arrays
from .recording_rules import check_signals, numeric_signal

SUFFIXES = suffixes(RECORDING)
"""Recording suffixes, from the format registry (flowtex.io.formats)."""
AUDIO_SUFFIXES = suffixes(AUDIO)
"""Also read and written by load_recording/save_recording (channels ch0, ch1, ...; flowtex.io.wav), but not searched for by the fitters."""
_USE = listing((*(s for s in SUFFIXES if s != ".hdf5"), *AUDIO_SUFFIXES))
"""``.npz, .csv, .h5 or .wav`` for messages."""
_COLUMN = re.compile(r"^(?P<name>[^\[\]]+)(?:\[(?P<index>\d+)\])?$")


@dataclass
class Recording:
    """Signals of one recording (time first) and the rate the file states, if any."""

    arrays: dict[str, np.ndarray]
    rate: float | None = None
    path: Path | None = None
    units: dict[str, str] = field(default_factory=dict)
    """Unit of each signal, when the file states it ("" is dimensionless)."""

    @property
    def samples(self) -> int:
        return next(iter(self.arrays.values())).shape[0] if self.arrays else 0


def load_recording(path: str | Path) -> Recording:
    """Read a recording; raises :class:`DataError` naming the file and the problem."""
    path = Path(path)
    if not path.exists():
        raise DataError(f"{path}: recording not found")
    check_regular(path, "recording")
    fmt = format_of(path)
    name = fmt.name if fmt is not None and fmt.kind in (RECORDING, AUDIO) else None
    if name == "npz":
        rec = _load_npz(path)
    elif name == "csv":
        rec = _load_csv(path)
    elif name == "hdf5":
        rec = _load_h5(path)
    elif name == "wav":
        from .wav import read_wav

        rate, arrays = read_wav(path)
        rec = Recording(arrays, rate)
    elif fmt is not None and fmt.kind == CAN_LOG:  # the frames of a live session, not signals: replaying decodes them
        raise DataError(f"{path}: a CAN session log, not a recording ({_USE}); replay it into one: flowtex run GRAPH.yaml "
                        f"--input {path} --dbc DEVICE.dbc --map MAP.yaml --output OUT.npz (docs/live.md)")
    else:
        raise DataError(f"{path}: unknown recording format {path.suffix.lower()!r}; use {_USE}")
    check_signals(rec.arrays, path)
    rec.path = path
    return rec


UNITS_KEY = "units"


def _parse_units(text: str, path: Path) -> dict[str, str]:
    try:
        units = json.loads(text, object_pairs_hook=unique_keys)
    except DuplicateKey as exc:
        raise DataError(f"{path}: 'units': {exc}") from None
    except ValueError:
        raise DataError(f"{path}: 'units' must be JSON like {{\"y\": \"m/s^2\"}}, got {excerpt(text)}") from None
    except RecursionError:
        raise DataError(f"{path}: 'units' must be JSON like {{\"y\": \"m/s^2\"}}, got {excerpt(text)}") from None
    if not isinstance(units, dict) or not all(isinstance(k, str) and isinstance(v, str) for k, v in units.items()):
        raise DataError(f"{path}: 'units' must map signal names to unit strings, got {excerpt(text)}")
    return units


def _stated_rate(value: object, path: Path) -> float:
    try:
        rate = float(np.asarray(value))
    except (TypeError, ValueError):
        raise DataError(f"{path}: 'rate' must be a number of Hz, got {value!r}") from None
    if not np.isfinite(rate) or rate <= 0:
        raise DataError(f"{path}: 'rate' must be a positive number of Hz, got {rate!r}")
    return rate


def _load_npz(path: Path) -> Recording:
    arrays = {}
    rate = None
    units: dict[str, str] = {}
    for name, arr in read_npz_arrays(path).items():
        if name == "rate" and arr.ndim == 0:
            rate = _stated_rate(arr, path)
        elif name == UNITS_KEY and arr.ndim == 0 and arr.dtype.kind == "U":
            units = _parse_units(str(arr), path)
        elif arr.ndim == 0:
            raise DataError(f"{path}: entry {excerpt(name)} is a single number; signals need time on the first axis")
        else:
            arrays[name] = numeric_signal(arr, path, name)
    return Recording(arrays, rate, units=units)


MAX_CSV_LINE = 1 << 20
"""Longest CSV line read (characters); a longer one is not a recording row."""
_CSV_CHUNK = 1 << 20
"""Values parsed into Python floats before they are packed into a numpy block (bounds Python-object memory)."""


def _bounded_lines(fh, path: Path):
    """Lines of ``fh``, refusing one longer than MAX_CSV_LINE (a binary or one-line file would otherwise be read whole)."""
    while True:
        line = fh.readline(MAX_CSV_LINE + 1)
        if not line:
            return
        if len(line) > MAX_CSV_LINE:
            raise DataError(f"{path}: a line is longer than {MAX_CSV_LINE:,} characters; this is not a CSV recording")
        yield line


def _load_csv(path: Path) -> Recording:
    try:
        with path.open(newline="", encoding=TEXT_ENCODING) as fh:
            return _parse_csv(_bounded_lines(fh, path), path)
    except UnicodeDecodeError as exc:
        raise DataError(f"{path}: not UTF-8 text at byte {exc.start}; a CSV recording is text") from None
    except csv.Error as exc:
        raise DataError(f"{path}: not a readable CSV file ({excerpt(str(exc), 120)})") from None
    except OSError as exc:
        raise DataError(f"{path}: cannot read the recording ({exc.strerror or exc})") from None


def _parse_csv(lines, path: Path) -> Recording:
    rate = None
    units: dict[str, str] = {}
    stated: dict[str, int] = {}  # 'rate' / 'units' -> the line that states it
    comments = 0
    first = None
    for line in lines:
        if not line.startswith("#"):
            first = line
            break
        comments += 1
        m = re.match(r"#\s*(rate|units)\s*:\s*(.+?)\s*$", line)
        if m and m.group(1) in stated:
            raise DataError(f"{path}:{comments}: a second '# {m.group(1)}:' line (the first is line {stated[m.group(1)]}); "
                            "a recording states it once: delete one")
        if m:
            stated[m.group(1)] = comments
        if m and m.group(1) == "rate":
            rate = _stated_rate(m.group(2), path)
        elif m:
            units = _parse_units(m.group(2), path)
    if first is None:
        raise DataError(f"{path}: empty CSV; the first row must name the columns")
    header = next(csv.reader([first]))
    columns = _csv_columns(header, f"{path}:{comments + 1}")
    width = len(header)
    blocks: list[np.ndarray] = []
    rows: list[list[float]] = []
    count = 0
    for lineno, row in enumerate(csv.reader(lines), start=comments + 2):
        if not row:
            continue
        if len(row) != width:
            raise DataError(f"{path}:{lineno}: {len(row)} values but {width} columns in the header")
        try:
            rows.append([float(v) for v in row])
        except ValueError:
            raise DataError(f"{path}:{lineno}: non-numeric value in {excerpt(row)}") from None
        count += width
        if count > MAX_RECORDING_VALUES:
            check_values(path, count, "the CSV table (so far)")
        if len(rows) * width >= _CSV_CHUNK:
            blocks.append(np.array(rows, dtype=np.float64))
            rows = []
    blocks.append(np.array(rows, dtype=np.float64).reshape(len(rows), width))
    table = np.concatenate(blocks)
    arrays = {}
    for name, parts in columns.items():
        if -1 in parts:
            arrays[name] = table[:, parts[-1]].copy()
        else:
            arrays[name] = table[:, [parts[i] for i in range(max(parts) + 1)]].copy()
    return Recording(arrays, rate, units=units)


def _csv_columns(header: list[str], where: str) -> dict[str, dict[int, int]]:
    """Signal name -> {component index (-1 for a scalar): column}; refuses malformed, duplicate and incomplete columns.

    ``where`` is ``FILE:LINE`` of the header row (after any ``#`` comment lines)."""
    columns: dict[str, dict[int, int]] = {}
    for col, name in enumerate(header):
        m = _COLUMN.match(name.strip())
        if not m:
            raise DataError(f"{where}: column name {excerpt(name)} is not 'name' or 'name[i]'")
        index = int(m.group("index")) if m.group("index") is not None else -1
        parts = columns.setdefault(m.group("name"), {})
        if index in parts:
            raise DataError(f"{where}: column {excerpt(name.strip())} appears twice (columns {parts[index] + 1} and {col + 1}); "
                            "rename or delete one")
        if index > len(header):
            raise DataError(f"{where}: column {excerpt(name.strip())} has index {index} but the file has {len(header)} columns")
        parts[index] = col
    for name, parts in columns.items():
        if -1 in parts and len(parts) > 1:
            raise DataError(f"{where}: column {name!r} appears both as a scalar and as {name}[i]")
        if -1 not in parts:
            missing = [i for i in range(max(parts) + 1) if i not in parts]
            if missing:
                raise DataError(f"{where}: vector {name!r} lacks column(s) " + ", ".join(f"{name}[{i}]" for i in missing[:8]))
    return columns


def _h5py():
    try:
        import h5py
    except ImportError:
        raise DataError("reading .h5 recordings needs h5py: pip install 'flowtex[hdf5]'") from None
    return h5py


def _load_h5(path: Path) -> Recording:
    h5py = _h5py()
    try:
        with h5py.File(path, "r") as fh:
            rate = _stated_rate(fh.attrs["rate"], path) if "rate" in fh.attrs else None
            arrays = {}
            units = {}
            total = 0
            datasets = [(name, item) for name, item in fh.items() if isinstance(item, h5py.Dataset)]
            if not datasets:
                _refuse_grouped(fh, h5py, path)
            for name, item in datasets:  # every dataset's header first: nothing is read from a file that is too large
                if item.ndim == 0:
                    raise DataError(f"{path}: dataset {excerpt(name)} is a single number; signals need time on the first axis")
                if item.dtype.kind not in "biufc":
                    raise DataError(f"{path}: dataset {excerpt(name)} holds {str(item.dtype)[:40]} values, not numbers; "
                                    "store text (names, units) as attributes")
                check_values(path, total + int(item.size), f"dataset {excerpt(name)} (shape {item.shape})"
                             + (", with the datasets before it," if total else ""))
                total += int(item.size)
            for name, item in datasets:
                arrays[name] = numeric_signal(item[()], path, name)
                if "unit" in item.attrs:
                    unit = item.attrs["unit"]
                    units[name] = unit.decode(errors="replace") if isinstance(unit, bytes) else str(unit)
    except DataError:
        raise
    except (OSError, KeyError, RuntimeError, ValueError, TypeError) as exc:  # h5py reports damaged files in all of these
        raise DataError(f"{path}: not a readable HDF5 recording ({excerpt(str(exc), 120)})") from None
    return Recording(arrays, rate, units=units)


_GROUPED_SHOWN = 3
"""Datasets inside groups named when a file has none at its root."""
_GROUPED_VISITS = 10_000
"""Most objects the search for grouped datasets looks at, whatever the file claims to hold."""


def _refuse_grouped(fh: Any, h5py: Any, path: Path) -> None:
    """Refuse a file whose datasets all sit inside groups (``/trial1/accel``): flowtex reads one dataset per signal at
    the root, and said only that the file held no signals. Walks groups breadth-first and stops after a few datasets,
    so a file claiming millions of objects costs no more."""
    found: list[str] = []
    queue = [("", fh)]
    visited = 0
    while queue and len(found) < _GROUPED_SHOWN and visited < _GROUPED_VISITS:
        prefix, group = queue.pop(0)
        for name, item in group.items():
            visited += 1
            if visited > _GROUPED_VISITS:
                break
            if isinstance(item, h5py.Dataset):
                found.append(f"{prefix}{name}")
                if len(found) == _GROUPED_SHOWN:
                    break
            elif isinstance(item, h5py.Group):
                queue.append((f"{prefix}{name}/", item))
    if found:
        raise DataError(f"{path}: no dataset at the file's root; its signals are inside groups ({', '.join(map(excerpt, found))}"
                        f"{', ...' if len(found) == _GROUPED_SHOWN else ''}); flowtex reads one dataset per signal at the "
                        "root: copy them there (h5py: f[name] = f[group + '/' + name][()])")


NPZ_ENTRIES = ("rate", UNITS_KEY)
"""Names a .npz recording keeps for its rate and its units, so no signal may have them there."""


def check_writable(path: str | Path, names: Iterable[str]) -> None:
    """Refuse signal ``names`` that a recording at ``path`` cannot hold (a .npz file's own entries, :data:`NPZ_ENTRIES`).

    Called by :func:`save_recording` and, for ``flowtex run``, with the graph's output names before the run: an output
    named ``rate`` was an internal error once the run was done."""
    fmt = format_of(Path(path))
    if fmt is None or fmt.name != "npz":
        return
    for name in names:
        if name in NPZ_ENTRIES:
            raise DataError(f"{path}: a signal named {name!r} cannot be written to a .npz recording, whose {name!r} entry "
                            "holds the recording's own " + ("rate" if name == "rate" else "units") +
                            "; rename it (a graph output: under outputs:) or write a .csv or .h5 file")


def save_recording(path: str | Path, arrays: Mapping[str, np.ndarray], rate: float | None = None,
                   units: Mapping[str, str] | None = None) -> None:
    """Write signals (time first) in the format named by the file's suffix, with their ``units`` if given.

    Written through the one writer (:func:`flowtex.io.atomic.atomic_output`): a failure or Ctrl-C leaves the old
    file intact and no partial file; the mode comes from the umask.
    """
    from .atomic import atomic_output

    path = Path(path)
    fmt = format_of(path)
    name = fmt.name if fmt is not None and fmt.kind in (RECORDING, AUDIO) else None
    if name == "wav":
        from .wav import write_signals_wav

        write_signals_wav(path, arrays, rate)
        return
    if name is None:
        raise DataError(f"{path}: unknown output format {path.suffix.lower()!r}; use {_USE}")
    check_writable(path, arrays)
    arrays = {name: np.asarray(a, dtype=np.float64) for name, a in arrays.items()}
    try:  # what load_recording would refuse is not written: a graph output 'time' that does not increase, say
        check_signals(arrays, path)
    except DataError as exc:
        raise DataError(f"{path}: not written, since flowtex would not read it back: {str(exc).removeprefix(f'{path}: ')}"
                        " (a graph output: rename it under outputs:)") from None
    path.parent.mkdir(parents=True, exist_ok=True)
    units = {name: str(units[name]) for name in arrays if name in units} if units else {}
    with atomic_output(path) as tmp:
        if name == "npz":
            extra: dict[str, np.ndarray] = {"rate": np.float64(rate)} if rate is not None else {}
            if units and UNITS_KEY not in arrays:
                extra[UNITS_KEY] = np.array(json.dumps(units))
            with open(tmp, "wb") as fh:
                np.savez(fh, **arrays, **extra)
        elif name == "csv":
            _save_csv(tmp, arrays, rate, units)
        else:
            h5py = _h5py()
            with h5py.File(tmp, "w") as fh:
                for name, a in arrays.items():
                    ds = fh.create_dataset(name, data=a)
                    if name in units:
                        ds.attrs["unit"] = units[name]
                if rate is not None:
                    fh.attrs["rate"] = float(rate)


def _save_csv(path: Path, arrays: Mapping[str, np.ndarray], rate: float | None, units: Mapping[str, str]) -> None:
    header: list[str] = []
    columns: list[np.ndarray] = []
    for name, a in arrays.items():
        flat = a.reshape(a.shape[0], -1) if a.ndim > 1 else a[:, None]
        if a.ndim == 1:
            header.append(name)
        else:
            header += [f"{name}[{i}]" for i in range(flat.shape[1])]
        columns.append(flat)
    table = np.hstack(columns) if columns else np.zeros((0, 0))
    with path.open("w", newline="", encoding="utf-8") as fh:
        if rate is not None:
            fh.write(f"# rate: {rate:g}\n")
        if units:
            fh.write(f"# units: {json.dumps(dict(units))}\n")
        writer = csv.writer(fh)
        writer.writerow(header)
        for row in table:
            writer.writerow([repr(float(v)) for v in row])
