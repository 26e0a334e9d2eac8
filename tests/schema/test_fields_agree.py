"""Every declared value's JSON Schema accepts exactly what the loaders' checker (flowtex.schema.core.fits) accepts,
for every field of the graph, scene, device map and data-file declarations: editors and loaders read one declaration.

Left out, and why: a text ``pattern`` (editors check it; loaders parse the text themselves and say more), and
records with an old spelling (either spelling is accepted; the loaders refuse both at once with their own line)."""

from __future__ import annotations

import jsonschema
from hypothesis import given, settings
from hypothesis import strategies as st

from flowtex.schema import datafiles, devmap, graph, scene
from flowtex.schema.core import Field, Record, fits
from flowtex.schema.jsonschema import field_schema


def _fields(root: Record) -> list[tuple[str, Field]]:
    found: list[tuple[str, Field]] = []
    todo: list[tuple[str, Field]] = [(k, f) for k, f in root.keys.items()]
    while todo:
        name, f = todo.pop()
        found.append((name, f))
        subs = [*(f.of or ()), *([f.items] if f.items else []), *([f.values] if f.values else [])]
        if f.record is not None:
            subs += list(f.record.keys.values())
        todo += [(f"{name}.*", s) for s in subs]
    return found


def _checkable(f: Field) -> bool:
    if f.pattern or (f.record is not None and f.record.legacy):
        return False
    subs = [*(f.of or ()), *([f.items] if f.items else []), *([f.values] if f.values else [])]
    if f.record is not None:
        subs += list(f.record.keys.values())
    return all(_checkable(s) for s in subs)


ROOTS = (graph.GRAPH, scene.SCENE, devmap.MAP, datafiles.MODEL_SET, datafiles.PATTERN, datafiles.TAP_LIBRARY, datafiles.FRICTION)
FIELDS = [(n, f) for root in ROOTS for n, f in _fields(root) if _checkable(f)]
VALIDATORS = {id(f): jsonschema.Draft202012Validator(field_schema(f)) for _, f in FIELDS}

keys = st.sampled_from(["a", "b", "x_1", "2a", "rate", "speed", "limit", "max_ms", "output", "clip", "mu", "models", "type"])
scalars = st.one_of(st.none(), st.booleans(), st.integers(-3, 70000), st.floats(-1e6, 1e6, allow_nan=False),
                    st.sampled_from([0, 1, 0.5, 1.0, -1, 5000, 4999.5, "", "x", "texture", "flowtex-friction", "mm/s"]))
values = st.recursive(scalars, lambda inner: st.one_of(st.lists(inner, max_size=4), st.dictionaries(keys, inner, max_size=4)),
                      max_leaves=10)


def test_there_are_fields_to_compare():
    assert len(FIELDS) > 40


@settings(max_examples=600, deadline=None)
@given(field=st.sampled_from(FIELDS), value=values)
def test_field_schema_and_checker_agree(field, value):
    name, f = field
    assert VALIDATORS[id(f)].is_valid(value) == fits(value, f), (name, value)
