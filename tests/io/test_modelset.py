"""Native JSON model sets: exact round trip, versioning, Delaunay when triangles are absent; load_model_set dispatch."""

from __future__ import annotations

import json

import numpy as np
import pytest
from scipy.spatial import Delaunay

from flowtex.datasets.model_sets import cork_like_model_set, hard_model_set, synthetic_model_set
from flowtex.errors import DataError
from flowtex.io.hatt import write_hatt_xml
from flowtex.io.modelset import load_model_set, save_model_set

ARRAYS = ("speeds", "forces", "ar_lsf", "ma_lsf", "variance", "gain", "ar_coeff", "ma_coeff", "triangles")


def test_round_trip_is_bit_exact(tmp_path):
    ms = cork_like_model_set()
    # awkward floats: subnormal, negative zero, values with 17 significant digits
    ms.gain[0] = 5e-324
    ms.variance[1] = 0.1 + 0.2
    ms.ar_coeff[2, 5] = -0.0
    ms.metadata = {"fit": {"window": 2048, "note": "ünïcode ok"}}
    path = save_model_set(ms, tmp_path / "cork like.json")
    back = load_model_set(path)
    for key in ARRAYS:
        a, b = getattr(ms, key), getattr(back, key)
        assert a.dtype == b.dtype and np.array_equal(a.view(np.int64) if a.dtype == np.float64 else a,
                                                     b.view(np.int64) if b.dtype == np.float64 else b), key
    assert (back.material, back.sample_rate, back.mu, back.max_speed, back.max_force) == \
        (ms.material, ms.sample_rate, ms.mu, ms.max_speed, ms.max_force)
    assert back.metadata == ms.metadata
    assert back.source == path


def test_optional_fields_absent(tmp_path):
    ms = synthetic_model_set([50.0, 150.0, 250.0], [0.5, 1.0, 1.7], ar_order=4, ma_order=3)
    path = save_model_set(ms, tmp_path / "s.json")
    doc = json.loads(path.read_text())
    for key in ("triangles", "mu", "max_speed", "max_force", "metadata"):
        del doc[key]
    for entry in doc["models"]:
        del entry["ar_coeff"], entry["ma_coeff"]
    path.write_text(json.dumps(doc))
    back = load_model_set(path)
    assert back.mu is None and back.ar_coeff is None and back.ma_coeff is None and back.metadata == {}
    assert back.max_speed == 250.0 and back.max_force == 1.7
    expect = Delaunay(np.column_stack([back.speeds, back.forces])).simplices
    assert np.array_equal(back.triangles, expect)


def test_unknown_version_refused(tmp_path):
    path = save_model_set(hard_model_set(), tmp_path / "h.json")
    doc = json.loads(path.read_text())
    doc["version"] = 2
    path.write_text(json.dumps(doc))
    with pytest.raises(DataError, match=r"h\.json: model-set format version 2 is not supported .* reads version 1"):
        load_model_set(path)


@pytest.mark.parametrize("edit, message", [
    (lambda d: d.__setitem__("format", "other"), "key 'format' is 'other'"),
    (lambda d: d.pop("sample_rate"), "missing key 'sample_rate'"),
    (lambda d: d["models"][3].pop("variance"), "models[3]: missing key 'variance'"),
    (lambda d: d["models"][2].__setitem__("ar_lsf", [0.1, 0.2]), "models[2]: 'ar_lsf' must be a list of 12 numbers"),
    (lambda d: d["models"][2]["ma_lsf"].reverse(), "models[2]: ma_lsf is not strictly increasing"),
    (lambda d: d["models"][0].__setitem__("colour", 1), "models[0]: unknown key(s) 'colour'"),
    (lambda d: d.__setitem__("triangles", [[0, 1]]), "key 'triangles' must be a list of [i, j, k] lists"),
    (lambda d: d.__setitem__("triangles", [[0, 1, 99]]), "triangles 1 names model 99, but the models are numbered 0..15"),
    (lambda d: d.__setitem__("mu", "high"), "key 'mu' is 'high'; expected a number or null"),
])
def test_malformed_native_files(tmp_path, edit, message):
    path = save_model_set(hard_model_set(), tmp_path / "bad set.json")
    doc = json.loads(path.read_text())
    edit(doc)
    path.write_text(json.dumps(doc))
    with pytest.raises(DataError) as err:
        load_model_set(path)
    assert str(path) in str(err.value) and message in str(err.value)


def test_nan_and_broken_json_refused(tmp_path):
    path = tmp_path / "n.json"
    path.write_text('{"format": "flowtex-texture-models", "version": 1, "material": "x", "sample_rate": NaN}')
    with pytest.raises(DataError, match="NaN is not allowed"):
        load_model_set(path)
    path.write_text('{"format": \n  "flowtex-texture-models",,}')
    with pytest.raises(DataError, match=r"n\.json:2:\d+: not valid JSON"):
        load_model_set(path)


def test_collinear_points_without_triangles_refused(tmp_path):
    ms = synthetic_model_set([50.0, 150.0, 250.0, 300.0], [1.0, 1.2, 1.4, 1.6], ar_order=4, ma_order=3, grid=False, corners=False)
    path = save_model_set(ms, tmp_path / "line.json")
    doc = json.loads(path.read_text())
    del doc["triangles"]
    for k, entry in enumerate(doc["models"]):  # put every model on one line
        entry["force"] = 1.0 + 0.001 * entry["speed"] if k else 1.05
    path.write_text(json.dumps(doc))
    with pytest.raises(DataError, match="lie on one line"):
        load_model_set(path)


def test_dispatch_on_content_not_extension(tmp_path):
    ms = hard_model_set()
    xml_path = write_hatt_xml(ms, tmp_path / "models.dat")
    json_path = save_model_set(ms, tmp_path / "models.xml")
    a, b = load_model_set(xml_path), load_model_set(json_path)
    assert a.metadata["format"] == "hatt-xml"
    assert np.array_equal(a.ar_lsf, b.ar_lsf) and np.array_equal(a.triangles, b.triangles)
    junk = tmp_path / "junk.bin"
    junk.write_bytes(b"\x00\x01garbage")
    with pytest.raises(DataError, match=r"junk\.bin: not a texture model file"):
        load_model_set(junk)
    with pytest.raises(DataError, match="no such model file"):
        load_model_set(tmp_path / "missing one.xml")
    with pytest.raises(DataError, match="is a folder"):
        load_model_set(tmp_path)


def test_friction_coefficient_is_exposed(tmp_path):
    path = write_hatt_xml(hard_model_set(), tmp_path / "Models_Friction Test.xml")
    assert load_model_set(path).mu == 0.5
