"""The one writer: every file flowtex writes goes through :func:`atomic_output`.

Rules (the same in every verb; documented in docs/cli.md, "Output files"):

- **Atomic.** The data go to a temporary file in the target folder, which is flushed, fsynced and renamed over the
  target. A failure, an exception or Ctrl-C leaves the old file intact and no partial file behind. A target that
  exists and is not a regular file (``-o /dev/null``, a FIFO) is written into, never renamed over.
- **Permissions** come from the umask, like any other program (``0666 & ~umask``); ``keep_mode=True`` (``--into``
  updates of an existing file) keeps the mode the file had.
- **Inputs are never overwritten.** :func:`check_output` refuses, before any work starts, an output that is the same
  file as any input of the command (``os.path.samefile``, so links and ``./x`` spellings are caught too).
- **Missing folders** are created (like ``mkdir -p``) by :func:`check_output`, before any work starts, when the
  nearest existing ancestor is a writable folder; otherwise the command stops at once naming the folder.
"""

from __future__ import annotations

import contextlib
import json
import os
import shutil
import stat
import tempfile
from collections.abc import Iterable, Iterator, Mapping
from pathlib import Path
from typing import Any

from ..errors import FlowtexError


class OutputError(FlowtexError):
    """An output path that cannot be written (same file as an input, folder not writable, ...)."""


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


def _same_file(a: Path, b: Path) -> bool:
    try:
        return os.path.samefile(a, b)
    except OSError:
        return False


def _same_name(a: Path, b: Path) -> bool:
    """The same file, or, for files not written yet, the same path once folders and links are resolved."""
    return _same_file(a, b) or os.path.realpath(a) == os.path.realpath(b)


def check_output(path: str | Path | None, *, inputs: Iterable[str | Path | None] = (), option: str = "-o",
                 create_folders: bool = True, suffixes: tuple[str, ...] = (),
                 others: Mapping[str, str | Path | None] | None = None) -> Path | None:
    """Check an output path before any work starts; return it (expanded), or None when ``path`` is None.

    Refuses (one line naming ``option`` and the file) an output that is the same file as one of ``inputs`` or as
    another output of the command (``others``: option -> path; files that do not exist yet compared by name), an
    existing folder given as a file, and a folder that does not exist and cannot be created or is not writable.
    Missing folders are created here, before the work, so no verb fails after its work is done. ``suffixes``
    (lower case, with the dot), when given, are the formats the verb can write.
    """
    if path is None:
        return None
    out = Path(path).expanduser()
    check_not_input(path, inputs, option)  # first: "that is an input" says more than the suffix would
    for other, item in (others or {}).items():  # one output written over another would be lost without a word
        if item is not None and _same_name(out, Path(item).expanduser()):
            raise OutputError(f"{option} {path}: {other} writes that file too; give each output its own file")
    if suffixes and out.suffix.lower() not in suffixes and not (len(suffixes) == 1 and _is_special(out)):
        # -o /dev/null (no suffix) is accepted where one format is written; where the suffix picks it, it is refused
        raise OutputError(f"{option} {path}: unknown output format {out.suffix!r}; use {', '.join(suffixes)}")
    if out.is_dir():
        raise OutputError(f"{option} {path}: is a folder; give a file name inside it")
    folder = out.parent if str(out.parent) else Path(".")
    if not folder.exists():
        if not create_folders:
            raise OutputError(f"{option} {path}: folder {folder} does not exist; create it first")
        try:
            folder.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise OutputError(f"{option} {path}: cannot create folder {folder} ({exc.strerror}); "
                              "create it or choose another output") from None
    if not folder.is_dir():
        raise OutputError(f"{option} {path}: {folder} is not a folder")
    if _is_special(out) and os.access(out, os.W_OK):
        return out
    if not os.access(folder, os.W_OK | os.X_OK):
        raise OutputError(f"{option} {path}: folder {folder} is not writable; choose another output folder")
    _probe(out, folder, f"{option} {path}")
    return out


def check_not_input(path: str | Path | None, inputs: Iterable[str | Path | None], option: str = "-o",
                    what: str = "an input of this command") -> None:
    """Refuse (one line naming ``option`` and the file) an output ``path`` that is the same file as one of ``inputs``;
    ``what`` says what the inputs are. :func:`check_output` calls it; a verb whose inputs are known only later (the
    files a graph's nodes read, once the graph is checked) calls it again then, still before any work."""
    if path is None:
        return
    out = Path(path).expanduser()
    for item in inputs:
        if item is not None and _same_file(out, Path(item).expanduser()):
            raise OutputError(f"{option} {path}: that is {what} ({item}); flowtex never overwrites an input: choose "
                              "another output file")


def _probe(out: Path, folder: Path, what: str) -> None:
    """Create (and remove) the temporary file :func:`atomic_output` will write, as the command will: asking
    (``os.access``, checked first for its plainer message) says yes to root in folders no file can be created in
    (``/sys/kernel``, a read-only mount)."""
    try:
        fd, name = _mkstemp(out, folder)
    except OSError as exc:
        raise OutputError(f"{what}: cannot create a file in folder {folder} ({exc.strerror or exc}); "
                          "choose another output folder") from None
    os.close(fd)
    with contextlib.suppress(OSError):
        os.unlink(name)


MAX_TEMP_STEM = 24
"""Characters of the target's name kept in a temporary name: the temporary file of a 255-character name must fit too."""


def _mkstemp(path: Path, folder: Path) -> tuple[int, str]:
    """A new temporary file beside ``path`` named ``.STEM.XXXXXXXX.part.SUFFIX``, at most ~50 characters long.

    The name keeps the target's suffix (up to 10 characters) so writers that append one (``numpy.savez``) write
    where expected, and a short piece of its name so a leftover (a session killed with SIGKILL) can be recognised.
    """
    suffix = path.suffix if len(path.suffix) <= 10 else ""
    return tempfile.mkstemp(dir=folder, prefix=f".{path.stem[:MAX_TEMP_STEM]}.", suffix=".part" + suffix)


def _is_special(path: Path) -> bool:
    """True for an existing target that is not a regular file (``/dev/null``, a FIFO, ``/dev/stdout``)."""
    try:
        return not stat.S_ISREG(os.stat(path).st_mode)
    except OSError:
        return False


def _copy_into(tmp: Path, path: Path) -> None:
    """Stream ``tmp`` into the special file ``path``: renaming over ``/dev/null`` would replace the device."""
    with open(tmp, "rb") as src, open(path, "wb") as dst:
        shutil.copyfileobj(src, dst)


@contextlib.contextmanager
def atomic_output(path: str | Path, *, keep_mode: bool = False) -> Iterator[Path]:
    """Yield a temporary path beside ``path`` (same suffix); on success it is fsynced and renamed to ``path``.

    On any exception, ``KeyboardInterrupt`` included, the temporary file is removed and ``path`` is untouched.
    The temporary name keeps ``path``'s suffix so writers that append one (``numpy.savez``) write where expected.
    """
    path = Path(path).expanduser()
    folder = path.parent if str(path.parent) else Path(".")
    mode = None
    if keep_mode and path.exists():
        mode = path.stat().st_mode & 0o7777
    special = _is_special(path)
    try:
        fd, tmp_name = _mkstemp(path, Path(tempfile.gettempdir()) if special else folder)
    except OSError as exc:
        raise OutputError(f"{path}: cannot write in {folder} ({exc.strerror}); choose another output folder") from None
    os.close(fd)
    tmp = Path(tmp_name)
    try:
        yield tmp
        os.chmod(tmp, mode if mode is not None else 0o666 & ~_umask())
        with open(tmp, "rb+") as fh:
            os.fsync(fh.fileno())
        if special:
            _copy_into(tmp, path)
            return
        os.replace(tmp, path)
        with contextlib.suppress(OSError):
            dir_fd = os.open(folder, os.O_RDONLY)
            try:
                os.fsync(dir_fd)
            finally:
                os.close(dir_fd)
    finally:
        tmp.unlink(missing_ok=True)


@contextlib.contextmanager
def kept_on_success(writer: Any) -> Iterator[Any]:
    """Around the writing of a streamed output (:class:`~flowtex.io.wav.WavWriter`,
    :class:`~flowtex.io.canlog.SessionWriter`, or None for no output): ``writer.close()`` (kept) when the block ends,
    ``writer.close(keep=False)`` (nothing partial left, an older file kept) when it raises, Ctrl-C included."""
    try:
        yield writer
    except BaseException:
        if writer is not None:
            writer.close(keep=False)
        raise
    if writer is not None:
        writer.close()


def write_bytes_atomic(path: str | Path, data: bytes, *, keep_mode: bool = False) -> Path:
    """Write ``data`` to ``path`` through :func:`atomic_output`; a write the system refuses (a full disk) is an
    :class:`OutputError` naming ``path``, with the older file left as it was."""
    try:
        with atomic_output(path, keep_mode=keep_mode) as tmp:
            tmp.write_bytes(data)
    except OSError as exc:
        raise refused_write(path, exc) from None
    return Path(path).expanduser()


def refused_write(path: str | Path, exc: OSError) -> OutputError:
    """The one-line error for a write into :func:`atomic_output`'s temporary file that the system refused (a full
    disk, a file size limit): it names ``path`` and says the older file is untouched (the temporary one is gone)."""
    return OutputError(f"{path}: cannot write it ({exc.strerror or exc}); an older file of that name is left as it was")


def write_text_atomic(path: str | Path, text: str, *, keep_mode: bool = False) -> Path:
    """Write ``text`` (UTF-8) to ``path`` through :func:`atomic_output`.

    A lone surrogate, which is what Python makes of a file name's bytes that are not UTF-8 (a report naming
    ``bad\\xffname.npz``), is written as its escape ``\\udcff``: UTF-8 cannot hold it, and the write was an internal
    error after the work was done."""
    return write_bytes_atomic(path, text.encode("utf-8", "backslashreplace"), keep_mode=keep_mode)


def write_json_atomic(path: str | Path, doc: dict[str, Any], *, keep_mode: bool = False) -> Path:
    """Write ``doc`` as indented JSON (no NaN/inf) to ``path`` through :func:`atomic_output`."""
    text = json.dumps(doc, indent=1, allow_nan=False) + "\n"
    return write_text_atomic(path, text, keep_mode=keep_mode)
