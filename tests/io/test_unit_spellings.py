"""Units compared by flowtex.io.recording_rules: the same unit spelled another way is the same unit."""

from __future__ import annotations

import pytest

from flowtex.errors import DataError
from flowtex.io.recording_rules import check_stated_unit, is_speed_unit


@pytest.mark.parametrize("stated", ["mm/sec", "mm/secs", "mm / second", "mm/seconds", "mm*sec^-1", "mm sec^-1"])
def test_the_second_spelled_out_is_the_second(stated):
    """DBC files often write the second out (cantools keeps a signal's unit as its text): a recording in mm/s played
    onto a signal in mm/sec was refused as another unit ("convert it to mm/sec")."""
    check_stated_unit({"speed": stated}, "speed", "mm/s", "rec.npz", "DBC signal Tool.Speed")
    check_stated_unit({"speed": "mm/s"}, "speed", stated, "rec.npz", "DBC signal Tool.Speed")
    assert is_speed_unit(stated)


def test_a_millisecond_stays_a_millisecond():
    with pytest.raises(DataError, match="is in 'msec'"):
        check_stated_unit({"t": "msec"}, "t", "s", "rec.npz", "input 't'")
    with pytest.raises(DataError, match="multiply it by 1000 and state its unit as mm/s"):
        check_stated_unit({"speed": "m/sec"}, "speed", "mm/s", "rec.npz", "input 'speed'")


@pytest.mark.parametrize("stated,wanted,factor", [
    ("mm", "m", "0.001"),        # the table's pair read backwards (m -> mm is 1000)
    ("N", "kN", "0.001"),
    ("m/s", "cm/s", "100"),      # through a unit both convert into (mm/s)
])
def test_the_factor_is_named_in_both_directions(stated, wanted, factor):
    """A refusal names the factor for any pair the unit table relates, as the device map's check does: a position in
    mm fed to an input in m was told only "convert it to m"."""
    with pytest.raises(DataError, match=rf"multiply it by {factor} and state its unit as {wanted}$"):
        check_stated_unit({"x": stated}, "x", wanted, "rec.npz", "input 'x'")
