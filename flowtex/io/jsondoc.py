"""Read a versioned flowtex JSON document (model set, tap library): the checks every such file starts with.

Every problem raises :class:`flowtex.errors.DataError` naming the file (and, for
broken JSON, line and column): unreadable file, invalid JSON, a NaN or Infinity
constant (not JSON, though Python's reader accepts it), a top level that is not an
object, a key given twice in one object, the wrong ``format``, an unsupported ``version``, a file larger than
:data:`flowtex.limits.MAX_TEXT_BYTES` or nested deeper than :data:`flowtex.limits.MAX_DEPTH`.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from ..errors import DataError
from ..limits import MAX_DEPTH, check_file_size, depth_of, excerpt, too_deep
from .formats import TEXT_ENCODING


class DuplicateKey(ValueError):
    """A JSON object names one key twice (raised by :func:`unique_keys`)."""


def unique_keys(pairs: list[tuple[str, Any]]) -> dict[str, Any]:
    """A JSON object's pairs as a dict, refusing a key given twice (``object_pairs_hook`` of ``json.loads``).

    Python's reader keeps the last of two equal keys, so ``"sample_rate": 1000, "sample_rate": 500`` read as 500 Hz
    without a word, where the YAML files' loader refuses the second key. Raises :class:`DuplicateKey` naming the key.
    """
    doc: dict[str, Any] = {}
    for key, value in pairs:
        if key in doc:
            raise DuplicateKey(f"key {excerpt(key)} is given twice in one object; keep one")
        doc[key] = value
    return doc


def read_json_document(path: Path, kind: str, format_name: str, versions: tuple[int, ...]) -> dict[str, Any]:
    """The top-level object of the JSON file ``path``, checked to be a ``kind`` of format ``format_name`` in one of ``versions``."""

    def no_constant(token: str) -> None:
        raise ValueError(f"{token} is not allowed in a {kind} (only finite numbers)")

    def finite_float(token: str) -> float:
        value = float(token)
        if value in (float("inf"), float("-inf")):
            raise ValueError(f"the number {token[:30]} is too large (beyond 1.8e308)")
        return value

    def bounded_int(token: str) -> int:
        if len(token.lstrip("-")) > 18:
            raise ValueError(f"the integer {token[:30]} is too large (flowtex files use integers below 1e18)")
        return int(token)

    check_file_size(path, f"the {kind} file")
    try:
        doc = json.loads(path.read_text(encoding=TEXT_ENCODING), parse_constant=no_constant,
                         parse_float=finite_float, parse_int=bounded_int, object_pairs_hook=unique_keys)
    except RecursionError:  # json's C scanner gives up near the interpreter's recursion limit, cleanly
        raise too_deep(path, f"the {kind} file") from None
    except FileNotFoundError:
        raise DataError(f"{path}: {kind} file not found (check the path; relative paths resolve against the graph file's folder)") from None
    except json.JSONDecodeError as exc:
        raise DataError(f"{path}:{exc.lineno}:{exc.colno}: not valid JSON ({exc.msg})") from None
    except ValueError as exc:  # the constants above, a key given twice, undecodable UTF-8
        raise DataError(f"{path}: {exc}") from None
    except OSError as exc:
        raise DataError(f"{path}: cannot read the {kind} file ({exc.strerror or exc})") from None
    if depth_of(doc) > MAX_DEPTH:
        raise too_deep(path, f"the {kind} file")
    if not isinstance(doc, dict):
        raise DataError(f"{path}: expected a JSON object with \"format\": \"{format_name}\" at the top level")
    if doc.get("format") != format_name:
        raise DataError(f"{path}: key 'format' is {excerpt(doc.get('format'))}, expected {format_name!r} (is this a {kind}?)")
    version = doc.get("version")
    if isinstance(version, bool) or version not in versions:  # true == 1 in Python, not in a file
        raise DataError(f"{path}: {kind} format version {excerpt(version)} is not supported by this flowtex "
                        f"(it reads version {', '.join(map(str, versions))}; key 'version'); upgrade flowtex or re-export the file")
    return doc
