"""Parse an XML file with bounds: size, element depth, and no DTD (so no entity can expand or fetch anything).

Used by the HaTT model reader. HaTT files are plain elements a few levels deep;
a ``<!DOCTYPE`` (the only place entities are declared) is refused before
parsing, a file larger than :data:`flowtex.limits.MAX_TEXT_BYTES` before reading,
and elements nested deeper than :data:`flowtex.limits.MAX_DEPTH` while parsing.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from pathlib import Path

from ..errors import DataError
from ..limits import MAX_DEPTH, check_file_size, excerpt, too_deep

_CHUNK = 1 << 16


def parse_xml(path: Path, kind: str) -> ET.Element:
    """The root element of the XML file ``path`` (a ``kind`` such as "model file"); raises :class:`DataError` naming the file."""
    try:
        if path.is_dir():
            raise DataError(f"{path}: is a folder, not a {kind}")
        check_file_size(path, f"the {kind}")
        data = path.read_bytes()
    except FileNotFoundError:
        raise DataError(f"{path}: no such {kind}") from None
    except OSError as exc:
        raise DataError(f"{path}: cannot read the {kind} ({exc.strerror or exc})") from None
    if b"<!DOCTYPE" in data or b"<!ENTITY" in data:
        raise DataError(f"{path}: the {kind} has a <!DOCTYPE> or <!ENTITY> declaration; flowtex reads plain XML only "
                        "(delete the declaration)")
    parser = ET.XMLPullParser(events=("start", "end"))
    depth = 0
    root = None
    try:
        for start in range(0, len(data), _CHUNK):
            parser.feed(data[start:start + _CHUNK])
            for event, elem in parser.read_events():
                depth += 1 if event == "start" else -1
                root = elem if root is None else root
                if depth > MAX_DEPTH:
                    raise too_deep(path, f"the {kind}")
        parser.close()
    except ET.ParseError as exc:
        raise DataError(f"{path}: not well-formed XML ({exc})") from None
    except (LookupError, ValueError) as exc:  # an unknown encoding= in the declaration, or a parser that gave up
        raise DataError(f"{path}: not readable XML ({excerpt(str(exc), 120)})") from None
    if root is None:
        raise DataError(f"{path}: the {kind} holds no XML element")
    return root
