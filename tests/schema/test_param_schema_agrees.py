"""A node parameter's JSON Schema accepts exactly what its Param declaration accepts (Param.coerce), for every
parameter of every built-in node type: editors and validate cannot disagree."""

from __future__ import annotations

import jsonschema
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from flowtex.registry import load_registry
from flowtex.schema.jsonschema import param_schema

PARAMS = [(f"{t}.{n}", p) for t, cls in sorted(load_registry().types.items()) for n, p in cls.params.items()]
VALIDATORS = {name: jsonschema.Draft202012Validator(param_schema(p)) for name, p in PARAMS}

scalars = st.one_of(
    st.booleans(), st.none(),
    st.integers(min_value=-(2**40), max_value=2**40),  # beyond 2**53 floats and ints part ways in coerce; not a user's value
    st.floats(allow_nan=False, allow_infinity=False, min_value=-1e12, max_value=1e12),
    st.sampled_from([0, 1, -1, 0.5, 1.0, 2.0, 1e-9, 2**31 - 1, 2**31, 20.0, 1000.0]),
    st.text(max_size=8), st.sampled_from(["lowpass", "highpass", "bandpass", "hold", "fade", "trend", "linear", "x.json"]),
)
values = st.one_of(scalars, st.lists(scalars, max_size=5))


def _accepts(p, value) -> bool:
    try:
        p.coerce(value)
    except ValueError:
        return False
    return True


@settings(max_examples=800, deadline=None)
@given(param=st.sampled_from(PARAMS), value=values)
def test_schema_and_declaration_agree(param, value):
    """Both accept or both refuse ``value``."""
    name, p = param
    # whether '~user' has a home folder is the machine's to know, not a schema's (coerce refuses an unknown user)
    assume(not (p.kind == "path" and isinstance(value, str) and value.startswith("~")))
    assert VALIDATORS[name].is_valid(value) == _accepts(p, value), (name, value)


@pytest.mark.parametrize("name, p", PARAMS, ids=[n for n, _ in PARAMS])
def test_defaults_pass_and_wrong_kinds_fail(name, p):
    v = VALIDATORS[name]
    if not p.required and p.default is not None:
        default = list(p.default) if isinstance(p.default, tuple) else p.default
        assert v.is_valid(default) and _accepts(p, default)
    assert not v.is_valid({"a": 1}) and not _accepts(p, {"a": 1})


def test_a_path_under_an_unknown_users_home_is_a_parameter_error_not_a_crash():
    path_param = next(p for _, p in PARAMS if p.kind == "path")
    with pytest.raises(ValueError, match="no such user's home folder"):
        path_param.coerce("~no_such_user_flowtex/x.json")
