"""Penn Haptic Texture Toolkit (HaTT) model files: read them, and write files of the same shape.

The format is described in ``docs/hatt-format.md`` (and how flowtex reads it in
``docs/model-sets.md``): one ``<modelSet>`` root with scalar children
(``material``, ``SampleRate``, ``mu``, ``numMod``, ``numTri``, ``maxSpeed``,
``maxForce``, ``numARCoeff``, ``numMACoeff``, units and picture paths),
``<speedList>``/``<forceList>`` arrays of ``<value>`` elements, ``numTri``
``<tri>`` arrays of three **1-based** model numbers, and ``numMod``
``<model>`` elements (``modNum``, ``ARcoeff``, ``ARlsf``, ``MAcoeff``,
``MAlsf``, ``var``, ``gain``, ``speedMod``, ``forceMod``).

``<mu>`` is the one optional scalar: every published HaTT file has it, but a
set fitted without friction data has no coefficient, so :func:`write_hatt_xml`
then leaves the element out and :func:`read_hatt_xml` reads a missing (or
empty) ``<mu>`` as ``mu = None`` -- never as 0, which would render a
frictionless surface instead of asking for a coefficient.

Reading is one ``xml.etree`` parse and one pass over the elements (all 100
published files load in well under a second). Every problem is reported as a
:class:`~flowtex.errors.DataError` naming the file, the element and, inside a
``<model>``, its ``modNum``.

flowtex ships no HaTT file: :func:`write_hatt_xml` writes files of exactly
this shape for tests and examples.
"""

from __future__ import annotations

import math
import re
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np

from ..dsp.lsf import lsf_to_poly_new
from ..errors import DataError
from ..limits import excerpt
from ..models.texture import HATT_RULE, RenderRule, TextureModelSet
from .xmldoc import parse_xml

HATT_NAMES = {
    "speeds": "<speedList>",
    "forces": "<forceList>",
    "triangles": "<tri>",
    "ar_lsf": "<ARlsf>",
    "ma_lsf": "<MAlsf>",
    "variance": "<var>",
    "gain": "<gain>",
    "ar_coeff": "<ARcoeff>",
    "ma_coeff": "<MAcoeff>",
    "max_speed": "<maxSpeed>",
    "max_force": "<maxForce>",
    "sample_rate": "<SampleRate>",
    "mu": "<mu>",
    "model": "<model> modNum",
}
"""Element names used in validation messages for HaTT files."""

_XML_CHAR = re.compile("[\t\n\r\x20-\ud7ff\ue000-\ufffd\U00010000-\U0010ffff]")
"""A character XML 1.0 can hold. A material named with a control character (a file name's, or a JSON set's
``"\\u0001"``) made a file no XML reader reads back, flowtex's included; a lone surrogate (a file name's bytes that are
not UTF-8) made the write an internal error."""

MAX_COUNT = 10**9
"""Largest count (``numMod``, ``numTri``, an order) read; a file within flowtex.limits.MAX_TEXT_BYTES holds far fewer."""

_REQUIRED_SCALARS = ("material", "SampleRate", "numMod", "numTri", "maxSpeed", "maxForce", "numARCoeff", "numMACoeff")
_MODEL_ARRAYS = ("ARcoeff", "ARlsf", "MAcoeff", "MAlsf")
_MODEL_SCALARS = ("var", "gain")
_EXPECTED_UNITS = {"SpeedUnits": "mm/s", "ForceUnits": "N", "AccelUnits": "m/s^2"}


def _values(elem: ET.Element, where: str) -> list[float]:
    """Numbers of an array element: its ``<value>`` children (or, failing that, whitespace-separated text)."""
    items = [v.text for v in elem if v.tag == "value"]
    if not items and elem.text and elem.text.strip():
        items = elem.text.split()
    try:
        return [float(t) for t in items]
    except (TypeError, ValueError):
        bad = next((t for t in items if not _is_number(t)), None)
        raise DataError(f"{where}: {bad!r} is not a number") from None


def _whole(text: str | None, where: str, low: int, high: int) -> int:
    """The whole number ``low..high`` that ``text`` states (``40``, ``40.0``), or DataError naming ``where``.

    One rule for the counts and model numbers of the file (numMod, numTri, the orders, modNum): ``1.7`` is not model 1,
    and ``nan`` or ``inf`` is no count at all.
    """
    stripped = (text or "").strip()
    try:
        value = float(stripped)
    except ValueError:
        raise DataError(f"{where} is {excerpt(stripped)}, not a number") from None
    if not (math.isfinite(value) and value == int(value) and low <= value <= high):
        raise DataError(f"{where} is {excerpt(stripped)}; expected a whole number from {low} to {high}")
    return int(value)


def _children(elem: ET.Element, repeated: tuple[str, ...], where: str) -> dict[str, ET.Element]:
    """``elem``'s children by tag, refusing a tag other than ``repeated`` that appears twice.

    With two ``<SampleRate>`` (or two ``<var>`` in one ``<model>``) the last one used to win without a word; no
    published file repeats an element, so a second one is a damaged or hand-edited file.
    """
    out: dict[str, ET.Element] = {}
    for child in elem:
        if child.tag in out and child.tag not in repeated:
            raise DataError(f"{where}: <{child.tag}> appears twice; a HaTT file has one (delete one)")
        out[child.tag] = child
    return out


def _is_number(text: str | None) -> bool:
    try:
        float(text)  # type: ignore[arg-type]
        return True
    except (TypeError, ValueError):
        return False


def read_hatt_xml(path: str | Path) -> TextureModelSet:
    """Read one HaTT ``Models_<name>.xml`` file into a validated :class:`TextureModelSet`.

    Triangles become 0-based. ``numARCoeff``/``numMACoeff`` are the orders
    p and q (``ARlsf`` holds p values, ``ARcoeff`` p+1 with the leading 1); a
    file that counts the leading 1 in ``numARCoeff`` is accepted too when its
    arrays agree with that reading. Models are ordered by ``modNum``.
    ``metadata`` keeps the texture index and the units. Raises
    :class:`DataError` naming the file and element for anything missing,
    malformed or inconsistent.
    """
    path = Path(path)
    name = str(path)
    root = parse_xml(path, "model file")  # bounded: size, depth, no DTD or entities
    if root.tag != "modelSet":
        raise DataError(f"{name}: root element is <{root.tag}>, expected <modelSet> (is this a HaTT model file?)")

    single = _children(root, ("model", "tri"), f"{name}: <modelSet>")
    tris = [child for child in root if child.tag == "tri"]
    models = [child for child in root if child.tag == "model"]
    speed_el, force_el = single.pop("speedList", None), single.pop("forceList", None)
    scalars = {tag: (child.text or "").strip() for tag, child in single.items() if tag not in ("model", "tri")}

    missing = [k for k in _REQUIRED_SCALARS if k not in scalars]
    if missing:
        raise DataError(f"{name}: missing element(s) {', '.join('<' + k + '>' for k in missing)} under <modelSet>")
    for key, want in _EXPECTED_UNITS.items():
        got = scalars.get(key)
        if got is not None and got != want:
            raise DataError(f"{name}: <{key}> is {got!r}; flowtex reads HaTT files in {want} only (convert the file)")

    def number(key: str) -> float:
        try:
            value = float(scalars[key])
        except ValueError:
            raise DataError(f"{name}: <{key}> is {scalars[key]!r}, not a number") from None
        if not math.isfinite(value):
            raise DataError(f"{name}: <{key}> is {scalars[key]!r}; it must be finite")
        return value

    def integer(key: str) -> int:
        return _whole(scalars[key], f"{name}: <{key}>", 0, MAX_COUNT)

    num_mod = integer("numMod")
    num_tri = integer("numTri")
    n_ar = integer("numARCoeff")
    n_ma = integer("numMACoeff")
    if speed_el is None or force_el is None:
        raise DataError(f"{name}: missing element {'<speedList>' if speed_el is None else '<forceList>'} under <modelSet>")
    speeds = _values(speed_el, f"{name}: <speedList>")
    forces = _values(force_el, f"{name}: <forceList>")
    for tag, vals in (("speedList", speeds), ("forceList", forces)):
        if len(vals) != num_mod:
            raise DataError(f"{name}: <{tag}> has {len(vals)} values but <numMod> is {num_mod}")
    if len(tris) != num_tri:
        raise DataError(f"{name}: found {len(tris)} <tri> elements but <numTri> is {num_tri}")
    if len(models) != num_mod:
        raise DataError(f"{name}: found {len(models)} <model> elements but <numMod> is {num_mod}")

    triangles = np.empty((num_tri, 3), dtype=np.int64)
    for t, el in enumerate(tris):
        vals = _values(el, f"{name}: <tri> {t + 1}")
        if len(vals) != 3:
            raise DataError(f"{name}: <tri> {t + 1} has {len(vals)} values; a triangle names 3 models")
        for v in vals:
            if not (math.isfinite(v) and v == int(v) and 1 <= v <= num_mod):  # nan and inf first: int() raises on them
                raise DataError(f"{name}: <tri> {t + 1} names model {v:g}, but models are numbered 1..{num_mod} (1-based)")
        triangles[t] = [int(v) - 1 for v in vals]

    per_model: list[dict[str, list[float] | float] | None] = [None] * num_mod
    for k, el in enumerate(models):
        fields = _children(el, (), f"{name}: <model> element {k + 1}")
        mod_el = fields.get("modNum")
        if mod_el is None:
            raise DataError(f"{name}: <model> element {k + 1} has no <modNum>")
        mod_num = _whole(mod_el.text, f"{name}: <model> element {k + 1}: <modNum> (numbered 1..{num_mod} by <numMod>)",
                         1, num_mod)
        where = f"{name}: <model> modNum {mod_num}"
        if per_model[mod_num - 1] is not None:
            raise DataError(f"{where}: two <model> elements have this modNum")
        for tag, listed, list_tag in (("speedMod", speeds, "speedList"), ("forceMod", forces, "forceList")):
            own = _values(fields[tag], f"{where} <{tag}>") if tag in fields else [listed[mod_num - 1]]
            if own != [listed[mod_num - 1]]:  # the renderer reads the list; a model fitted elsewhere is a damaged file
                raise DataError(f"{where}: <{tag}> is {excerpt(fields[tag].text)} but entry {mod_num} of <{list_tag}> is "
                                f"{listed[mod_num - 1]!r}; the two must agree (which one is the model's? fix the file)")
        entry: dict[str, list[float] | float] = {}
        for tag in _MODEL_ARRAYS:
            if tag not in fields:
                raise DataError(f"{where}: missing <{tag}>")
            entry[tag] = _values(fields[tag], f"{where} <{tag}>")
        for tag in _MODEL_SCALARS:
            if tag not in fields:
                raise DataError(f"{where}: missing <{tag}>")
            text = (fields[tag].text or "").strip()
            try:
                entry[tag] = float(text)
            except ValueError:
                raise DataError(f"{where}: <{tag}> is {text!r}, not a number") from None
        per_model[mod_num - 1] = entry

    p, q = _orders(name, per_model, n_ar, n_ma)
    ar_lsf = np.empty((num_mod, p))
    ma_lsf = np.empty((num_mod, q))
    ar_coeff = np.empty((num_mod, p + 1))
    ma_coeff = np.empty((num_mod, q + 1))
    variance = np.empty(num_mod)
    gain = np.empty(num_mod)
    for m, entry in enumerate(per_model):
        assert entry is not None
        where = f"{name}: <model> modNum {m + 1}"
        for tag, arr, want in (("ARlsf", ar_lsf, p), ("MAlsf", ma_lsf, q), ("ARcoeff", ar_coeff, p + 1), ("MAcoeff", ma_coeff, q + 1)):
            vals = entry[tag]
            assert isinstance(vals, list)
            if len(vals) != want:
                raise DataError(f"{where}: <{tag}> has {len(vals)} values, expected {want} "
                                f"(<numARCoeff> {n_ar}, <numMACoeff> {n_ma})")
            arr[m] = vals
        for tag, arr in (("ARcoeff", ar_coeff), ("MAcoeff", ma_coeff)):
            if arr[m, 0] != 1.0:
                raise DataError(f"{where}: <{tag}> starts with {arr[m, 0]!r}; HaTT polynomials start with 1")
        variance[m] = entry["var"]
        gain[m] = entry["gain"]

    ms = TextureModelSet(
        material=scalars["material"], sample_rate=number("SampleRate"), speeds=np.array(speeds), forces=np.array(forces),
        triangles=triangles, ar_lsf=ar_lsf, ma_lsf=ma_lsf, variance=variance, gain=gain,
        max_speed=number("maxSpeed"), max_force=number("maxForce"), mu=number("mu") if scalars.get("mu") else None,
        ar_coeff=ar_coeff, ma_coeff=ma_coeff, source=path,
        metadata={"format": "hatt-xml", "texture": root.get("texture"),
                  "units": {"speed": scalars.get("SpeedUnits", "mm/s"), "force": scalars.get("ForceUnits", "N"),
                            "accel": scalars.get("AccelUnits", "m/s^2")}},
    )
    return ms.validate(HATT_NAMES)


def _orders(name: str, models: list, n_ar: int, n_ma: int) -> tuple[int, int]:
    """AR and MA orders from <numARCoeff>/<numMACoeff>, which name the orders (or, in some files, the coefficient counts)."""
    first = models[0]
    if first is None:
        raise DataError(f"{name}: no <model> with modNum 1")
    orders = []
    for count, lsf_tag, tag in ((n_ar, "ARlsf", "numARCoeff"), (n_ma, "MAlsf", "numMACoeff")):
        got = len(first[lsf_tag])
        if got == count:
            orders.append(count)
        elif got == count - 1:
            orders.append(count - 1)
        else:
            raise DataError(f"{name}: <model> modNum 1 <{lsf_tag}> has {got} values but <{tag}> is {count}")
    return orders[0], orders[1]


def _fmt(x: float) -> str:
    return repr(float(x))


def rule_lost_in_xml(rule: RenderRule | None, path: str | Path) -> str | None:
    """The warning for writing a set whose file states ``rule`` to HaTT XML at ``path``, when that is not HaTT's rule.

    HaTT's format has no place for the rule (docs/model-sets.md), so the file read back renders with HaTT's rule: a
    fitted set (output-power interpolation) then renders quieter than its JSON between models of different
    resonance (docs/texture.md). None when nothing is lost.
    """
    if rule is None or rule == HATT_RULE:
        return None
    return (f"warning: {path}: HaTT XML cannot state this set's rendering rule (interpolation {rule.interpolation}, outside "
            f"{rule.outside}); read back it renders with HaTT's ({HATT_RULE.interpolation}, {HATT_RULE.outside}) unless "
            f"texture_lookup is given interpolation: {rule.interpolation} and outside: {rule.outside}; flowtex's JSON format keeps it")


MAX_TEXTURE_INDEX = 2**31 - 1
"""Largest ``<modelSet texture=...>`` written (HaTT numbers its textures 1 to 100; 0: unknown)."""


def texture_index(ms: TextureModelSet) -> int:
    """The texture index to write as ``<modelSet texture=...>``: the set's ``metadata['texture']`` (an integer, or the
    integer text a HaTT XML holds), 0 when absent; DataError naming the set's file when it is anything else (a JSON
    set's free-form metadata may hold any value), checked before the work that ends in writing the XML."""
    value = ms.metadata.get("texture") if isinstance(ms.metadata, dict) else None
    if value is None or value == "":
        return 0
    if isinstance(value, str) and value.strip().isdigit() and len(value.strip()) <= 10:
        value = int(value.strip())
    if isinstance(value, bool) or not isinstance(value, int) or not 0 <= value <= MAX_TEXTURE_INDEX:
        raise DataError(f"{ms.source or ms.material}: metadata 'texture' is {excerpt(value)}; the HaTT texture index written "
                        f"as <modelSet texture=...> must be a whole number from 0 to {MAX_TEXTURE_INDEX}: fix or remove it")
    return value


def write_hatt_xml(ms: TextureModelSet, path: str | Path, texture: int = 0, digits: int | None = None) -> Path:
    """Write ``ms`` as a HaTT model file (the elements of docs/hatt-format.md, its header in an order of its own); returns
    the path.

    Triangles are written 1-based; ``numARCoeff``/``numMACoeff`` hold the
    orders p and q; ``<mu>`` is left out when ``ms.mu`` is None. Coefficients are ``ms.ar_coeff``/``ms.ma_coeff`` when
    present, else computed from the LSFs with the float64 reference
    conversion. ``digits=None`` writes every float with ``repr`` (exact
    round trip); an integer writes that many significant digits, like a file
    produced by other software.
    """
    path = Path(path)
    fmt = _fmt if digits is None else (lambda x: f"{float(x):.{digits}g}")
    ar_coeff = ms.ar_coeff if ms.ar_coeff is not None else np.array([lsf_to_poly_new(r) for r in ms.ar_lsf])
    ma_coeff = ms.ma_coeff if ms.ma_coeff is not None else np.array([lsf_to_poly_new(r) for r in ms.ma_lsf])

    def arr(tag: str, values: np.ndarray, indent: str = "  ") -> str:
        inner = "".join(f"{indent}  <value>{fmt(v)}</value>\n" for v in values)
        return f'{indent}<{tag} type="array">\n{inner}{indent}</{tag}>\n'

    def esc(text: str) -> str:  # markup escaped; what XML 1.0 cannot hold at all written as its Python escape
        text = "".join(ch if _XML_CHAR.match(ch) else ch.encode("unicode_escape").decode("ascii") for ch in text)
        return text.replace("&", "&amp;").replace("<", "&lt;").replace(">", "&gt;")

    out = ['<?xml version="1.0" encoding="utf-8"?>\n', f'<modelSet texture="{int(texture)}">\n']
    pic = esc(ms.material.replace(" ", "_"))
    out.append(f"  <material>{esc(ms.material)}</material>\n")
    out.append(f"  <htmlPicture>images/{pic}.jpg</htmlPicture>\n  <htmlLinuxPicture>images/{pic}.jpg</htmlLinuxPicture>\n")
    out.append(f"  <renderPicture>images/{pic}_square.bmp</renderPicture>\n")
    out.append(f"  <DTpicture>images/{pic}_DT.bmp</DTpicture>\n  <LinuxDTpicture>images/{pic}_DT.bmp</LinuxDTpicture>\n")
    out.append("  <AccelUnits>m/s^2</AccelUnits>\n  <SpeedUnits>mm/s</SpeedUnits>\n  <ForceUnits>N</ForceUnits>\n")
    out.append(f"  <SampleRate>{ms.sample_rate:g}</SampleRate>\n")
    if ms.mu is not None:  # no friction fitted: no <mu> (the reader gives mu = None), never a made-up 0
        out.append(f"  <mu>{fmt(ms.mu)}</mu>\n")
    out.append(f"  <numMod>{ms.num_models}</numMod>\n  <numTri>{len(ms.triangles)}</numTri>\n")
    out.append(f"  <maxSpeed>{fmt(ms.max_speed)}</maxSpeed>\n  <maxForce>{fmt(ms.max_force)}</maxForce>\n")
    out.append(f"  <numARCoeff>{ms.ar_order}</numARCoeff>\n  <numMACoeff>{ms.ma_order}</numMACoeff>\n")
    out.append(arr("speedList", ms.speeds))
    out.append(arr("forceList", ms.forces))
    for t in np.asarray(ms.triangles):
        inner = "".join(f"    <value>{int(v) + 1}</value>\n" for v in t)
        out.append(f'  <tri type="array">\n{inner}  </tri>\n')
    for m in range(ms.num_models):
        out.append("  <model>\n")
        out.append(f"    <modNum>{m + 1}</modNum>\n")
        out.append(arr("ARcoeff", ar_coeff[m], "    "))
        out.append(arr("ARlsf", ms.ar_lsf[m], "    "))
        out.append(arr("MAcoeff", ma_coeff[m], "    "))
        out.append(arr("MAlsf", ms.ma_lsf[m], "    "))
        out.append(f"    <var>{fmt(ms.variance[m])}</var>\n    <gain>{fmt(ms.gain[m])}</gain>\n")
        out.append(f"    <speedMod>{fmt(ms.speeds[m])}</speedMod>\n    <forceMod>{fmt(ms.forces[m])}</forceMod>\n")
        out.append("  </model>\n")
    out.append("</modelSet>\n")
    from .atomic import write_text_atomic

    return write_text_atomic(path, "".join(out))
