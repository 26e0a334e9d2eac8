"""JSON data files checked against their declarations (flowtex/schema/datafiles.py): misspelt keys, the one rate
spelling (``sample_rate``) written and the old one (``sample_rate_hz``) still read, and a ``format`` that is no name."""

from __future__ import annotations

import json

import numpy as np
import pytest

from flowtex.cli import main
from flowtex.datasets import synthetic_tap_library
from flowtex.errors import DataError
from flowtex.io.patternfile import Pattern, read_pattern, write_pattern
from flowtex.io.taplib import read_tap_library, write_tap_library


def _pattern() -> Pattern:
    return Pattern(1000.0, np.array([1.0, 0.0, 0.0]), np.zeros(3), np.array([0.0, 2.0]), np.array([1.0, 0.5]),
                   [np.array([1.0, 0.5]), np.array([1.0])], [np.array([1.0, -0.5]), np.array([1.0])])


def test_pattern_with_a_misspelt_key_is_refused_with_a_suggestion(tmp_path):
    path = write_pattern(tmp_path / "p.json", _pattern())
    doc = json.loads(path.read_text())
    doc["featurs"] = doc.pop("features")
    path.write_text(json.dumps(doc))
    with pytest.raises(DataError, match=r"p.json: unknown key 'featurs' \(did you mean 'features'\?\)"):
        read_pattern(path)
    doc["features"] = doc.pop("featurs")
    doc["features"][0]["ampltude"] = 1.0
    path.write_text(json.dumps(doc))
    with pytest.raises(DataError, match=r"features\[0\]: unknown key 'ampltude' \(did you mean 'amplitude'\?\)"):
        read_pattern(path)


@pytest.mark.parametrize("write, read", [(lambda p: write_pattern(p, _pattern()), read_pattern),
                                         (lambda p: write_tap_library(p, synthetic_tap_library()), read_tap_library)])
def test_rate_is_written_as_sample_rate_and_the_old_spelling_is_still_read(tmp_path, write, read):
    path = tmp_path / "f.json"
    write(path)
    doc = json.loads(path.read_text())
    assert "sample_rate" in doc and "sample_rate_hz" not in doc
    new = read(path)
    doc["sample_rate_hz"] = doc.pop("sample_rate")
    path.write_text(json.dumps(doc))
    assert read(path).sample_rate_hz == new.sample_rate_hz
    doc["sample_rate"] = doc["sample_rate_hz"]
    path.write_text(json.dumps(doc))
    with pytest.raises(DataError, match="'sample_rate_hz' is the old spelling of 'sample_rate'"):
        read(path)


@pytest.mark.parametrize("fmt", [["flowtex-pattern"], {"a": 1}, 3, None])
def test_validate_a_json_file_whose_format_is_not_a_name(tmp_path, capsys, fmt):
    path = tmp_path / "x.json"
    path.write_text(json.dumps({"format": fmt, "version": 1}))
    assert main(["validate", str(path)]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(f"{path}: key 'format' is") and "not a flowtex file format" in err[0]
