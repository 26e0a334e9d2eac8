"""Signed figures in reports and summaries (power ratios, band errors): a value that rounds to zero reads +0.00."""

from __future__ import annotations

import math

from hypothesis import given
from hypothesis import strategies as st

from flowtex.limits import signed


def test_a_value_that_rounds_to_zero_has_no_minus_sign():
    assert signed(-0.001, 2) == "+0.00"  # ':+.2f' printed -0.00: a level "below" the recording by nothing
    assert signed(-0.0, 1) == "+0.0"
    assert signed(-0.006, 2) == "-0.01" and signed(0.004, 2) == "+0.00" and signed(3.14159, 1) == "+3.1"


@given(st.floats(allow_nan=False, allow_infinity=False, min_value=-1e12, max_value=1e12), st.integers(0, 4))
def test_the_digits_are_pythons_and_only_the_sign_of_zero_changes(value, digits):
    shown = signed(value, digits)
    plain = f"{value:+.{digits}f}"
    assert shown == plain or (shown == plain.replace("-", "+", 1) and float(plain) == 0.0)
    assert math.isclose(float(shown), value, abs_tol=10.0 ** -digits)
