"""Texture model-set files: flowtex's native JSON format, and ``load_model_set`` for any supported file.

The native format (``docs/model-sets.md`` is its full description) is one
JSON object::

    {"format": "flowtex-texture-models", "version": 1,
     "material": "cork", "sample_rate": 1000.0,
     "mu": 0.42,                       # optional (null or absent: no friction data)
     "max_speed": 380.0, "max_force": 4.0,   # optional: default to the largest model point
     "interpolation": "power", "outside": "trend",  # optional rendering rule; absent: HaTT's
     "ar_order": 19, "ma_order": 17,
     "triangles": [[0, 1, 2], ...],    # optional, 0-based; absent: Delaunay at load time
     "models": [{"speed": 12.5, "force": 0.8, "ar_lsf": [...], "ma_lsf": [...],
                 "variance": 1e-3, "gain": 1.1,
                 "ar_coeff": [...], "ma_coeff": [...]}, ...],   # coeffs optional
     "metadata": {...}}                # optional, free-form

JSON was chosen over ``.npz`` because Python writes every float64 with
``repr`` (the shortest string that reads back to the same bits) and reads it
back exactly, so files round-trip bit for bit while staying readable,
diffable and free of pickles; a 45-model set at orders 19/17 is about 90 kB.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import DataError
from ..limits import check_regular, excerpt
from ..models.rendering import HATT_RULE, RenderRule
from ..models.texture import TextureModelSet
from ..node_api import suggest
from ..schema.core import Collector, check_unknown, get
from ..schema.datafiles import MODEL, MODEL_SET, RATE_KEY
from .hatt import read_hatt_xml
from .jsondoc import read_json_document

FORMAT_NAME = "flowtex-texture-models"
FORMAT_VERSION = 1
SUPPORTED_VERSIONS = (1,)

NATIVE_NAMES = {  # only what differs from TextureModelSet's default names
    "speeds": "models[].speed",
    "forces": "models[].force",
    "model": "models[{}]",
    "index_base": "0",
}


TOP_KEYS = tuple(MODEL_SET.keys)
"""Keys a native model set may have at its top level (anything else is a typo, refused with a suggestion)."""
MAX_ORDER = int(MODEL_SET.keys["ar_order"].max)
"""Largest AR or MA order a model set may declare (fitted sets use tens)."""


def load_model_set(path: str | Path) -> TextureModelSet:
    """Read a texture model set from a HaTT ``.xml`` file or a native flowtex JSON file.

    The kind is decided by the file's first non-blank character (``<``:
    HaTT XML, ``{``: native JSON), so the extension does not matter. The
    result is validated. Raises :class:`DataError` naming the file (and the
    element or key) for a missing, unreadable or malformed file.
    """
    path = Path(path).expanduser()
    check_regular(path, "model file")
    try:
        with path.open("rb") as fh:
            head = fh.read(256).lstrip()
    except FileNotFoundError:
        raise DataError(f"{path}: no such model file") from None
    except IsADirectoryError:
        raise DataError(f"{path}: is a folder, not a model file") from None
    except OSError as exc:
        raise DataError(f"{path}: cannot read the model file ({exc.strerror or exc})") from None
    if head.startswith(b"\xef\xbb\xbf"):
        head = head[3:].lstrip()
    if head.startswith(b"<"):
        return read_hatt_xml(path)
    if head.startswith(b"{"):
        return read_native(path)
    raise DataError(f"{path}: not a texture model file (expected HaTT XML or flowtex JSON, "
                    f"which start with '<' or '{{')")


def save_model_set(ms: TextureModelSet, path: str | Path) -> Path:
    """Write ``ms`` in the native JSON format (bit-exact floats); returns the path.

    The set is validated first, so a file written here always loads.
    """
    ms.validate()
    path = Path(path).expanduser()
    models = []
    for m in range(ms.num_models):
        entry: dict[str, Any] = {
            "speed": float(ms.speeds[m]), "force": float(ms.forces[m]),
            "ar_lsf": [float(v) for v in ms.ar_lsf[m]], "ma_lsf": [float(v) for v in ms.ma_lsf[m]],
            "variance": float(ms.variance[m]), "gain": float(ms.gain[m]),
        }
        if ms.ar_coeff is not None:
            entry["ar_coeff"] = [float(v) for v in ms.ar_coeff[m]]
        if ms.ma_coeff is not None:
            entry["ma_coeff"] = [float(v) for v in ms.ma_coeff[m]]
        models.append(entry)
    doc: dict[str, Any] = {
        "format": FORMAT_NAME,
        "version": FORMAT_VERSION,
        "material": ms.material,
        RATE_KEY: float(ms.sample_rate),
        "mu": None if ms.mu is None else float(ms.mu),
        "max_speed": float(ms.max_speed),
        "max_force": float(ms.max_force),
        **({} if ms.rule is None else {"interpolation": ms.rule.interpolation, "outside": ms.rule.outside}),
        "ar_order": ms.ar_order,
        "ma_order": ms.ma_order,
        "triangles": [[int(v) for v in t] for t in ms.triangles],
        "models": models,
        "metadata": ms.metadata,
    }
    try:
        text = json.dumps(doc, indent=1, allow_nan=False)
    except (TypeError, ValueError) as exc:
        raise DataError(f"{path}: cannot write model set {ms.material!r}: metadata is not plain JSON ({exc})") from None
    from .atomic import write_text_atomic

    return write_text_atomic(path, text + "\n")


def read_native(path: str | Path) -> TextureModelSet:
    """Read a native flowtex JSON model set (see the module docstring); validated."""
    path = Path(path)
    name = str(path)
    doc = read_json_document(path, "model-set", FORMAT_NAME, SUPPORTED_VERSIONS)
    c = Collector(name)
    check_unknown(c, doc, MODEL_SET)
    c.raise_first_as_data_error()

    def need(key: str, kind: type | tuple[type, ...], where: dict = doc, label: str = "") -> Any:
        if key not in where:
            raise DataError(f"{name}: {label}missing key {key!r}")
        value = where[key]
        if isinstance(value, bool) or not isinstance(value, kind):
            raise DataError(f"{name}: {label}key {key!r} is {excerpt(value)}; expected {_kind_name(kind)}")
        return value

    material = need("material", str)
    spelling = get(doc, MODEL_SET, RATE_KEY)[1] or RATE_KEY
    sample_rate = float(need(spelling, (int, float)))
    models = need("models", list)
    if not models:
        raise DataError(f"{name}: key 'models' is empty")
    p = need("ar_order", int)
    q = need("ma_order", int)
    for key, order in (("ar_order", p), ("ma_order", q)):
        if not 0 <= order <= MAX_ORDER:
            raise DataError(f"{name}: key {key!r} is {excerpt(order)}; model orders run from 0 to {MAX_ORDER}")
    mu = doc.get("mu")
    if mu is not None and (isinstance(mu, bool) or not isinstance(mu, (int, float))):
        raise DataError(f"{name}: key 'mu' is {excerpt(mu)}; expected a number or null")
    count = len(models)
    speeds = np.empty(count)
    forces = np.empty(count)
    variance = np.empty(count)
    gain = np.empty(count)
    ar_lsf = np.empty((count, p))
    ma_lsf = np.empty((count, q))
    has_ar = all(isinstance(e, dict) and "ar_coeff" in e for e in models)
    has_ma = all(isinstance(e, dict) and "ma_coeff" in e for e in models)
    ar_coeff = np.empty((count, p + 1)) if has_ar else None
    ma_coeff = np.empty((count, q + 1)) if has_ma else None
    for m, entry in enumerate(models):
        label = f"models[{m}]: "
        if not isinstance(entry, dict):
            raise DataError(f"{name}: {label}expected an object")
        unknown = set(entry) - set(MODEL.keys)
        if unknown:
            raise DataError(f"{name}: {label}unknown key(s) {', '.join(sorted(map(excerpt, unknown)))}")
        speeds[m] = need("speed", (int, float), entry, label)
        forces[m] = need("force", (int, float), entry, label)
        variance[m] = need("variance", (int, float), entry, label)
        gain[m] = need("gain", (int, float), entry, label)
        for key, arr, width in (("ar_lsf", ar_lsf, p), ("ma_lsf", ma_lsf, q), ("ar_coeff", ar_coeff, p + 1), ("ma_coeff", ma_coeff, q + 1)):
            if arr is None:
                continue
            values = need(key, list, entry, label)
            if len(values) != width or not all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in values):
                raise DataError(f"{name}: {label}{key!r} must be a list of {width} numbers "
                                f"({'ar_order' if key.startswith('ar') else 'ma_order'} {p if key.startswith('ar') else q}"
                                f"{' plus the leading 1' if key.endswith('coeff') else ''}), got {len(values)} items")
            arr[m] = values
    points = np.column_stack([speeds, forces])
    tri_doc = doc.get("triangles")
    if tri_doc is None:
        triangles = delaunay_triangles(points, name)
    else:
        if not isinstance(tri_doc, list) or not all(
                isinstance(t, list) and len(t) == 3 and all(isinstance(v, int) and not isinstance(v, bool) for v in t) for t in tri_doc):
            raise DataError(f"{name}: key 'triangles' must be a list of [i, j, k] lists of 0-based model indices")
        triangles = np.array(tri_doc, dtype=np.int64).reshape(-1, 3)
    max_speed = float(need("max_speed", (int, float))) if "max_speed" in doc else float(speeds.max())
    max_force = float(need("max_force", (int, float))) if "max_force" in doc else float(forces.max())
    metadata = doc.get("metadata") or {}
    if not isinstance(metadata, dict):
        raise DataError(f"{name}: key 'metadata' must be an object")
    rule = _read_rule(doc, name)
    ms = TextureModelSet(material=material, sample_rate=sample_rate, speeds=speeds, forces=forces, triangles=triangles,
                         ar_lsf=ar_lsf, ma_lsf=ma_lsf, variance=variance, gain=gain,
                         max_speed=max_speed, max_force=max_force, mu=None if mu is None else float(mu),
                         ar_coeff=ar_coeff, ma_coeff=ma_coeff, source=path, metadata=metadata, rule=rule)
    return ms.validate(NATIVE_NAMES)


def _read_rule(doc: dict, name: str) -> RenderRule | None:
    """The rendering rule the file states (keys ``interpolation``, ``outside``; each optional, HaTT's when absent), or None."""
    if "interpolation" not in doc and "outside" not in doc:
        return None
    parts = {}
    for key in ("interpolation", "outside"):
        value = doc.get(key, getattr(HATT_RULE, key))
        choices = MODEL_SET.keys[key].choices
        if value not in choices:
            raise DataError(f"{name}: key {key!r} is {excerpt(value)}{suggest(str(value), choices)}; "
                            f"expected one of {', '.join(choices)} (or leave it out for HaTT's rule)")
        parts[key] = value
    return RenderRule(**parts)


def delaunay_triangles(points: np.ndarray, where: str = "model set") -> np.ndarray:
    """(T, 3) 0-based Delaunay triangles of (speed, force) points, via scipy.spatial.Delaunay.

    Raises :class:`DataError` when the points are too few or all on one line.
    """
    from scipy.spatial import Delaunay, QhullError

    points = np.asarray(points, dtype=np.float64)
    if points.shape[0] < 3 or not np.all(np.isfinite(points)):
        raise DataError(f"{where}: a triangulation needs at least 3 models with finite speed and force")
    try:
        tri = Delaunay(points)
    except QhullError:
        raise DataError(f"{where}: cannot triangulate the models' (speed, force) points: they lie on one line; "
                        "add models at other speeds or forces, or give 'triangles' explicitly") from None
    return tri.simplices.astype(np.int64)


def _kind_name(kind: type | tuple[type, ...]) -> str:
    kinds = kind if isinstance(kind, tuple) else (kind,)
    names = {int: "an integer", float: "a number", str: "a string", list: "a list", dict: "an object"}
    if set(kinds) == {int, float}:
        return "a number"
    return " or ".join(names.get(k, k.__name__) for k in kinds)
