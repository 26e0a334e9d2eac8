"""Text files that read as something else: a byte-order mark, a key or element given twice, model numbers that are not
whole, a model that cannot render. Each was read silently wrong (or was an internal error) and is now read as meant
or refused in one line naming the file and what to fix. Every file is built here, small."""

from __future__ import annotations

import dataclasses
import json
import re
import zipfile

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from flowtex.cli import main
from flowtex.datasets.model_sets import synthetic_model_set
from flowtex.errors import DataError
from flowtex.io.atomic import write_text_atomic
from flowtex.io.dbc import load_dbc
from flowtex.io.hatt import HATT_NAMES, read_hatt_xml, write_hatt_xml
from flowtex.io.modelset import load_model_set, save_model_set
from flowtex.io.recordings import load_recording
from tests.conftest import REPO

BOM = "\ufeff"
SET = synthetic_model_set(np.array([50.0, 150.0]), np.array([1.0, 3.0]), ar_order=4, ma_order=3)
"""A small set (9 models with its silent corners), orders 4/3."""


def one_line(call, match: str) -> str:
    """Run ``call``: one DataError line containing ``match``."""
    with pytest.raises(DataError) as err:
        call()
    text = str(err.value)
    assert "\n" not in text and match in text, text
    return text


@pytest.mark.parametrize("text, rate", [
    ("speed,normal_force\r\n1,2\r\n1,2\r\n1,2\r\n", None),
    ("# rate: 1000\nspeed,normal_force\n1,2\n1,2\n1,2\n", 1000.0),
])
def test_a_csv_with_a_byte_order_mark_names_its_first_signal_as_written(tmp_path, text, rate):
    path = tmp_path / "excel.csv"
    path.write_bytes((BOM + text).encode("utf-8"))  # Excel's "CSV UTF-8"
    rec = load_recording(path)
    assert sorted(rec.arrays) == ["normal_force", "speed"] and rec.rate == rate


def test_json_and_dbc_files_with_a_byte_order_mark_read_as_without(tmp_path):
    plain = save_model_set(SET, tmp_path / "plain.json")
    marked = tmp_path / "marked.json"
    marked.write_bytes(BOM.encode() + plain.read_bytes())
    assert load_model_set(marked).speeds.tolist() == load_model_set(plain).speeds.tolist()
    dbc = tmp_path / "marked.dbc"
    dbc.write_bytes(BOM.encode() + (REPO / "graphs" / "devices" / "example.dbc").read_bytes())
    assert len(load_dbc(dbc).messages) == len(load_dbc(REPO / "graphs" / "devices" / "example.dbc").messages)


@settings(max_examples=15, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(key=st.sampled_from(["sample_rate", "mu", "max_speed", "material", "ar_order", "triangles", "models"]),
       nested=st.booleans())
def test_a_json_key_given_twice_is_refused_naming_it(tmp_path, key, nested):
    """Python's reader kept the last of two equal keys: a second "sample_rate" silently changed the set's rate."""
    doc = json.loads(save_model_set(SET, tmp_path / "s.json").read_text())
    if nested:  # a key of one model: its speed given twice
        key = "speed"
        text = json.dumps(doc).replace('"speed": ', '"speed": 1.0, "speed": ', 1)
    else:
        text = "{" + json.dumps(key) + ": " + json.dumps(doc[key]) + ", " + json.dumps(doc)[1:]
    path = tmp_path / "twice.json"
    path.write_text(text)
    one_line(lambda: load_model_set(path), f"{path}: key '{key}' is given twice in one object; keep one")


def test_a_json_version_true_is_not_version_1(tmp_path):
    doc = json.loads(save_model_set(SET, tmp_path / "s.json").read_text())
    doc["version"] = True
    path = tmp_path / "v.json"
    path.write_text(json.dumps(doc))
    one_line(lambda: load_model_set(path), "format version True is not supported")


def test_a_recording_that_states_its_rate_or_units_twice_is_refused(tmp_path):
    csv = tmp_path / "r.csv"
    csv.write_text("# rate: 1000\n# rate: 500\nspeed\n1\n2\n3\n")
    one_line(lambda: load_recording(csv), f"{csv}:2: a second '# rate:' line (the first is line 1)")
    npz = tmp_path / "r.npz"
    with zipfile.ZipFile(npz, "w") as z:
        for name, arr in {"speed": np.arange(3.0), "units": np.array('{"speed": "mm/s", "speed": "m/s"}')}.items():
            with z.open(name + ".npy", "w") as fh:
                np.lib.format.write_array(fh, arr)
    one_line(lambda: load_recording(npz), "'units': key 'speed' is given twice")


def test_a_csv_header_problem_names_the_header_line_after_comments(tmp_path):
    path = tmp_path / "r.csv"
    path.write_text("# rate: 1000\n# units: {}\nx,x\n1,2\n1,2\n")
    one_line(lambda: load_recording(path), f"{path}:3: column 'x' appears twice")


@pytest.fixture
def hatt(tmp_path):
    """The text of SET written as a HaTT file, and a function writing a changed text to a file."""
    text = write_hatt_xml(SET, tmp_path / "Models_Small.xml").read_text()

    def write(new: str):
        assert new != text
        path = tmp_path / "Models_Changed.xml"
        path.write_text(new)
        return path
    return text, write


@pytest.mark.parametrize("change, match", [
    (lambda t: t.replace("<SampleRate>", "<SampleRate>500</SampleRate><SampleRate>", 1), "<modelSet>: <SampleRate> appears twice"),
    (lambda t: t.replace("<mu>", "<mu>5</mu><mu>", 1), "<modelSet>: <mu> appears twice"),
    (lambda t: re.sub(r"(<forceList[^>]*>.*?</forceList>)", r"\1\1", t, count=1, flags=re.S), "<modelSet>: <forceList> appears twice"),
    (lambda t: t.replace("<var>", "<var>1e6</var><var>", 1), "<model> element 1: <var> appears twice"),
])
def test_a_hatt_element_given_twice_is_refused_not_the_last_one_read(hatt, change, match):
    text, write = hatt
    path = write(change(text))
    one_line(lambda: read_hatt_xml(path), f"{path}: {match}; a HaTT file has one")


@pytest.mark.parametrize("value", ["nan", "inf", "1.7", "-inf", "1e300"])
def test_a_model_number_that_is_not_whole_is_refused_in_one_line(hatt, value, capsys):
    """``<modNum>inf</modNum>`` was an internal error; ``1.7`` was read as model 1."""
    text, write = hatt
    path = write(text.replace("<modNum>1</modNum>", f"<modNum>{value}</modNum>", 1))
    one_line(lambda: read_hatt_xml(path), f"<modNum> (numbered 1..{SET.num_models} by <numMod>) is '{value}'; expected a whole number")
    counts = write(text.replace(f"<numMod>{SET.num_models}</numMod>", f"<numMod>{value}</numMod>", 1))
    one_line(lambda: read_hatt_xml(counts), f"<numMod> is '{value}'; expected a whole number from 0 to")
    corner = write(re.sub(r"(<tri[^>]*>\s*<value>)[^<]*", rf"\g<1>{value}", text, count=1))
    assert main(["validate", str(corner)]) == 1
    assert capsys.readouterr().err.strip().endswith(f"<tri> 1 names model {float(value):g}, but models are numbered "
                                                    f"1..{SET.num_models} (1-based)")


def test_a_model_whose_speed_disagrees_with_the_speed_list_is_refused(hatt):
    text, write = hatt
    first = re.search(r"<speedMod>([^<]*)</speedMod>", text)
    path = write(text[:first.start(1)] + "12345.0" + text[first.end(1):])
    one_line(lambda: read_hatt_xml(path), "<model> modNum 1: <speedMod> is '12345.0' but entry 1 of <speedList> is")


def near_pole_lsf(order: int) -> list[float]:
    """Increasing LSFs in pairs 1e-15 rad apart: valid on paper, a pole on the unit circle in float64."""
    return [0.3 + 0.4 * (k // 2) + (1e-15 if k % 2 else 0.0) for k in range(order)]


def test_a_model_that_cannot_render_is_refused_when_read_naming_it(tmp_path, capsys):
    """``validate`` said ok to a set whose graph then refused to build, naming the model 0-based in a 1-based file."""
    m = int(np.flatnonzero(SET.variance > 0)[1])
    doc = json.loads(save_model_set(SET, tmp_path / "s.json").read_text())
    doc["models"][m]["ar_lsf"] = near_pole_lsf(SET.ar_order)
    doc["models"][m].pop("ar_coeff", None)
    for model in doc["models"]:
        model.pop("ar_coeff", None)
        model.pop("ma_coeff", None)
    path = tmp_path / "poles.json"
    path.write_text(json.dumps(doc))
    assert main(["validate", str(path)]) == 1
    assert capsys.readouterr().err.strip() == (
        f"{path}: models[{m}]: its LSFs give no stable filter in float64 (neighbouring LSFs, or one and 0 or pi, nearly "
        "coincide: a pole on the unit circle), so it cannot render; refit the model or remove it")
    xml = write_hatt_xml(load_model_set(tmp_path / "s.json"), tmp_path / "Models_S.xml")
    ms = read_hatt_xml(xml)
    ms.ar_lsf[m] = near_pole_lsf(SET.ar_order)
    ms.ar_coeff = None
    one_line(lambda: ms.validate(HATT_NAMES), f"<model> modNum {m + 1}: its LSFs give no stable filter")


@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(material=st.text(min_size=1, max_size=12))
def test_any_material_name_is_written_as_hatt_xml_that_reads_back(tmp_path, material):
    """A control character (a recording's file name, a JSON set's "\\u0001") made an XML file no reader reads back,
    flowtex's included; a lone surrogate (a file name's bytes that are not UTF-8) made the write an internal error."""
    path = write_hatt_xml(dataclasses.replace(SET, material=material), tmp_path / "Models_Any.xml")
    back = read_hatt_xml(path).material
    assert back.strip() != "" or material.strip() == ""
    if all(ch == "\t" or " " <= ch <= "~" for ch in material):  # plain text comes back as written (XML trims the ends)
        assert back == material.strip()


def test_a_text_output_naming_a_file_whose_name_is_not_utf8_is_written(tmp_path):
    """Reports name their recordings; a name with bytes that are not UTF-8 failed the write after the work was done."""
    path = write_text_atomic(tmp_path / "report.md", "# surface along bad\udcffname.npz\n")
    assert path.read_bytes() == b"# surface along bad\\udcffname.npz\n"


@pytest.mark.parametrize("key, unit", [("speed", "mm/s"), ("force", "N")])
def test_a_model_below_zero_speed_or_force_is_refused(tmp_path, key, unit):
    """A model at -10 mm/s loaded, and every query near 0 blended it in (the lookup clamps queries to >= 0)."""
    doc = json.loads(save_model_set(SET, tmp_path / "s.json").read_text())
    doc["models"][0][key] = -10.0
    doc["triangles"] = None  # triangulated anew: the model is a vertex of the hull
    path = tmp_path / "below.json"
    path.write_text(json.dumps(doc))
    one_line(lambda: load_model_set(path), f"{path}: models[0]: models[].{key} is -10.0 {unit}; a model's speed and force "
                                           "are magnitudes (>= 0)")


def test_a_text_file_in_another_encoding_is_named_as_such_with_the_fix(tmp_path, capsys):
    """A HaTT file saved as Latin-1 was 'not a text file'."""
    path = tmp_path / "Models_Latin.xml"
    text = write_hatt_xml(dataclasses.replace(SET, material="Pl\u00e4stic"), tmp_path / "Models_Utf8.xml").read_text()
    path.write_bytes(text.encode("latin-1"))
    assert main(["validate", str(path)]) == 1
    at = text.encode("latin-1").index(b"\xe4")
    assert capsys.readouterr().err.strip() == (f"{path}: not UTF-8 text (byte {at}); flowtex's text files are UTF-8: save it as "
                                               "UTF-8, or give a recording (.npz, .csv, .h5, .hdf5)")
