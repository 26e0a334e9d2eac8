"""Declared layouts: offsets, sizes and the generated kernel offsets come from one declaration."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from flowtex.dsp import arma, rng
from flowtex.dsp.layout import Field, Layout


def test_fields_follow_each_other_in_order() -> None:
    lay = Layout("float", [Field("a", 2), Field("b", "n + 1"), Field("c", 1)], sizes=("n",))
    assert lay.bind(n=3) == {"a": slice(0, 2), "b": slice(2, 6), "c": slice(6, 7)}
    assert lay.size(n=3) == 7 and lay.zeros(n=3).dtype == np.float64
    assert lay.const("b") == 2
    with pytest.raises(ValueError, match="variable-length field 'b'"):
        lay.const("c")


def test_bind_answers_are_kept_per_sizes_and_the_callers_to_change() -> None:
    """bind() keeps its answer per sizes (node builds bind the same sizes again and again): a caller changing the dict
    it got changes no later answer, and other sizes, a missing size or a negative length are still checked."""
    lay = Layout("float", [Field("a", 2), Field("b", "m"), Field("c", "n - 2")], sizes=("n",), derived={"m": "2 * n"})
    first = lay.bind(n=3)
    first["a"] = slice(0, 0)
    assert lay.bind(n=3) == {"a": slice(0, 2), "b": slice(2, 8), "c": slice(8, 9)}
    assert lay.bind(n=4, other=9) == {"a": slice(0, 2), "b": slice(2, 10), "c": slice(10, 12)}
    with pytest.raises(ValueError, match="needs the sizes n"):
        lay.bind()
    with pytest.raises(ValueError, match="'c'"):
        lay.bind(n=1)


def test_bad_declarations_are_refused() -> None:
    with pytest.raises(ValueError, match="twice"):
        Layout("int", [Field("a"), Field("a")])
    with pytest.raises(ValueError, match="names 'm'"):
        Layout("float", [Field("a", "m")], sizes=("n",))
    with pytest.raises(ValueError, match="only"):
        Layout("float", [Field("a", "__import__('os')")], sizes=("n",))


@given(st.integers(0, 40), st.integers(0, 40))
def test_arma_kernel_offsets_equal_the_python_slices(p: int, q: int) -> None:
    """The numba offsets function generated from arma.STATE agrees with its Python bind for every order."""
    slots = arma.STATE.bind(p=p, q=q)
    generated = arma._offsets.py_func(p, q)
    assert generated[0] == max(p, q)
    assert list(generated[1:]) == [s.start for s in slots.values()]
    assert arma.state_size(p, q) == max(s.stop for s in slots.values())


def test_arma_int_state_follows_the_random_generator() -> None:
    """The synthesizer's flags sit after however many words the generator declares (they used to be literal 5..8)."""
    assert arma.ISTATE.const("active") == rng.STATE_INTS
    assert arma.ISTATE_INTS == rng.STATE_INTS + 4
    grown = Layout("int", [Field("rng", rng.STATE_INTS + 2)] + list(arma.ISTATE.fields[1:]))
    assert grown.const("which") == arma.SI_WHICH + 2
