"""The one format registry (flowtex/io/formats.py): suffix -> kind, reader and writer, used by every verb."""

from __future__ import annotations

import numpy as np
import pytest

from flowtex.errors import DataError
from flowtex.io import formats
from flowtex.io.canlog import READ_SUFFIXES, WRITE_SUFFIXES
from flowtex.io.recordings import AUDIO_SUFFIXES, SUFFIXES
from flowtex.io.recordings import load_recording as load_direct


def test_each_suffix_belongs_to_one_format():
    seen = [s for f in formats.FORMATS for s in f.suffixes]
    assert len(seen) == len(set(seen)) and all(s == s.lower() and s.startswith(".") for s in seen)


def test_modules_take_their_suffixes_from_the_registry():
    assert SUFFIXES == (".npz", ".csv", ".h5", ".hdf5") and AUDIO_SUFFIXES == (".wav",)
    assert READ_SUFFIXES == WRITE_SUFFIXES == (".blf", ".log", ".asc")


@pytest.mark.parametrize("f", formats.FORMATS, ids=lambda f: f.name)
def test_readers_and_writers_resolve(f):
    assert callable(f.read())
    if f.writer is not None:
        assert callable(f.write())


@pytest.mark.parametrize("name, kind", [("a.NPZ", formats.RECORDING), ("a.hdf5", formats.RECORDING), ("a.wav", formats.AUDIO),
                                        ("a.Blf", formats.CAN_LOG), ("a.dbc", formats.DBC), ("a.txt", None), ("a", None)])
def test_kind_by_suffix(name, kind):
    assert formats.kind_of(name) == kind


@pytest.mark.parametrize("suffix", [".npz", ".csv", ".wav"])
def test_recording_round_trip_through_the_registry(tmp_path, suffix):
    fmt = formats.format_of(f"x{suffix}")
    path = tmp_path / f"x{suffix}"
    data = {"ch0": np.linspace(-0.5, 0.5, 64)} if suffix == ".wav" else {"a": np.arange(5.0), "b": np.ones((5, 3))}
    fmt.write()(path, data, 1000.0)
    back = fmt.read()(path)
    direct = load_direct(path)
    assert back.rate == direct.rate == 1000.0
    for name in data:
        np.testing.assert_array_equal(back.arrays[name], direct.arrays[name])
        if suffix != ".wav":  # WAV stores samples at 16 or 32 bits: compared to itself above, not to float64
            np.testing.assert_array_equal(back.arrays[name], data[name])


def test_unknown_recording_suffix_names_the_registry_formats(tmp_path):
    path = tmp_path / "x.txt"
    path.write_text("1\n")
    with pytest.raises(DataError, match=r"unknown recording format '\.txt'; use \.npz, \.csv, \.h5 or \.wav"):
        load_direct(path)


@pytest.mark.parametrize("doc, kind", [({"format": "flowtex-pattern"}, formats.PATTERN), ({"format": ["flowtex-pattern"]}, None),
                                       ({"format": {"a": 1}}, None), ([1], None), ({"format": "x"}, None)])
def test_json_kind_by_format_key(doc, kind):
    assert formats.json_kind(doc) == kind
