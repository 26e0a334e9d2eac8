"""Reading HaTT model XML files (built here in HaTT's documented shape; no HaTT file is shipped)."""

from __future__ import annotations

import textwrap

import numpy as np
import pytest

from flowtex.datasets.model_sets import cork_like_model_set, hard_model_set, lsf_to_poly_reference
from flowtex.errors import DataError
from flowtex.io.hatt import read_hatt_xml, write_hatt_xml
from flowtex.io.modelset import load_model_set


def values(xs, indent="    "):
    return "".join(f"{indent}<value>{x}</value>\n" for x in xs)


def _num(text):
    try:
        return np.isfinite(float(text))
    except ValueError:
        return False


def handmade(tri_rows=((1, 2, 3), (2, 4, 3)), num_tri=None, ar_lsf=("0.5", "1.5"), num_mod=None, extra_model=True,
             drop="", units="mm/s", mod_nums=(1, 2, 3, 4), speeds=("0", "100", "0", "100")):
    """A 4-model, order-2/1 HaTT file written by hand (independent of write_hatt_xml)."""
    forces = ("0", "0", "2", "2")
    tris = "".join(f'  <tri type="array">\n{values(r)}  </tri>\n' for r in tri_rows)
    models = ""
    for k, m in enumerate(mod_nums):
        lsf = ar_lsf if k == 1 else ("0.6", "1.6")
        a = lsf_to_poly_reference(np.array([0.6, 1.6] if k != 1 or not all(_num(v) for v in lsf) or len(lsf) != 2 else [float(v) for v in lsf]))
        models += (f"  <model>\n    <modNum>{m}</modNum>\n"
                   f'    <ARcoeff type="array">\n{values(a, "      ")}    </ARcoeff>\n'
                   f'    <ARlsf type="array">\n{values(lsf, "      ")}    </ARlsf>\n'
                   f'    <MAcoeff type="array">\n{values([1.0, 0.2], "      ")}    </MAcoeff>\n'
                   f'    <MAlsf type="array">\n{values([1.7721542475852274], "      ")}    </MAlsf>\n'
                   f"    <var>{0.0 if k % 2 == 0 else 0.01}</var>\n    <gain>{1.0 + k}</gain>\n"
                   f"    <speedMod>{speeds[m - 1]}</speedMod>\n    <forceMod>{forces[m - 1]}</forceMod>\n  </model>\n")
    text = f"""<?xml version="1.0" encoding="utf-8"?>
<modelSet texture="7">
  <material>Hand Made</material>
  <htmlPicture>images/x.jpg</htmlPicture>
  <AccelUnits>m/s^2</AccelUnits>
  <SpeedUnits>{units}</SpeedUnits>
  <ForceUnits>N</ForceUnits>
  <SampleRate>1000</SampleRate>
  <mu>0.25</mu>
  <numMod>{num_mod if num_mod is not None else len(mod_nums)}</numMod>
  <numTri>{num_tri if num_tri is not None else len(tri_rows)}</numTri>
  <maxSpeed>100</maxSpeed>
  <maxForce>2</maxForce>
  <numARCoeff>2</numARCoeff>
  <numMACoeff>1</numMACoeff>
  <speedList type="array">
{values(speeds)}  </speedList>
  <forceList type="array">
{values(forces)}  </forceList>
{tris}{models}</modelSet>
"""
    if drop:
        lines = [ln for ln in text.splitlines(keepends=True) if f"<{drop}>" not in ln]
        text = "".join(lines)
    return text


def test_handmade_file_reads_with_zero_based_triangles(tmp_path):
    path = tmp_path / "Models_Hand Made.xml"
    path.write_text(handmade())
    ms = read_hatt_xml(path)
    assert ms.material == "Hand Made"
    assert ms.sample_rate == 1000.0 and ms.mu == 0.25 and ms.max_speed == 100.0 and ms.max_force == 2.0
    assert ms.ar_order == 2 and ms.ma_order == 1
    assert ms.triangles.tolist() == [[0, 1, 2], [1, 3, 2]]
    assert ms.speeds.tolist() == [0.0, 100.0, 0.0, 100.0]
    assert ms.forces.tolist() == [0.0, 0.0, 2.0, 2.0]
    assert ms.ar_lsf[1].tolist() == [0.5, 1.5]
    assert ms.ma_coeff[0].tolist() == [1.0, 0.2]
    assert ms.variance.tolist() == [0.0, 0.01, 0.0, 0.01]
    assert ms.gain.tolist() == [1.0, 2.0, 3.0, 4.0]
    assert ms.metadata["texture"] == "7"
    assert ms.source == path


def test_models_are_ordered_by_modnum(tmp_path):
    path = tmp_path / "m.xml"
    path.write_text(handmade(mod_nums=(2, 1, 3, 4)))  # the second <model> element (special LSFs) is modNum 1
    ms = read_hatt_xml(path)
    assert ms.ar_lsf[0].tolist() == [0.5, 1.5]
    assert ms.gain.tolist() == [2.0, 1.0, 3.0, 4.0]


@pytest.mark.parametrize("kwargs, message", [
    ({"tri_rows": ((1, 2, 5), (2, 4, 3))}, "<tri> 1 names model 5, but models are numbered 1..4 (1-based)"),
    ({"tri_rows": ((0, 2, 3),)}, "<tri> 1 names model 0"),
    ({"tri_rows": ((1, 2),)}, "<tri> 1 has 2 values; a triangle names 3 models"),
    ({"num_tri": 3}, "found 2 <tri> elements but <numTri> is 3"),
    ({"num_mod": 5}, "<speedList> has 4 values but <numMod> is 5"),
    ({"ar_lsf": ("1.5", "0.5")}, "<model> modNum 2: <ARlsf> is not strictly increasing"),
    ({"ar_lsf": ("0.5", "3.5")}, "<model> modNum 2: <ARlsf> value 2 is 3.5; LSFs must lie strictly between 0 and pi"),
    ({"ar_lsf": ("0.5", "abc")}, "<model> modNum 2 <ARlsf>: 'abc' is not a number"),
    ({"ar_lsf": ("0.5", "nan")}, "<model> modNum 2: <ARlsf> value 2 is nan"),
    ({"ar_lsf": ("0.5", "1.0", "1.5")}, "<model> modNum 2: <ARlsf> has 3 values, expected 2"),
    ({"drop": "SampleRate"}, "missing element(s) <SampleRate> under <modelSet>"),
    ({"drop": "var"}, "<model> modNum 1: missing <var>"),
    ({"mod_nums": (1, 1, 3, 4)}, "<model> modNum 1: two <model> elements have this modNum"),
    ({"units": "m/s"}, "<SpeedUnits> is 'm/s'; flowtex reads HaTT files in mm/s only"),
    ({"tri_rows": ((1, 2, 3), (1, 2, 1))}, "<tri> 2 repeats a model"),
    ({"speeds": ("0", "100", "0", "0")}, "<model> modNum 3 and <model> modNum 4 sit at the same point (0 mm/s, 2 N)"),
])
def test_malformed_files_name_file_and_element(tmp_path, kwargs, message):
    path = tmp_path / "Models_Bad File.xml"
    path.write_text(handmade(**kwargs))
    with pytest.raises(DataError) as err:
        read_hatt_xml(path)
    assert str(path) in str(err.value)
    assert message in str(err.value)


def test_not_xml_wrong_root_and_missing_file(tmp_path):
    bad = tmp_path / "a.xml"
    bad.write_text("<modelSet><material>x</material>")
    with pytest.raises(DataError, match=r"a\.xml: not well-formed XML"):
        read_hatt_xml(bad)
    bad.write_text("<other/>")
    with pytest.raises(DataError, match=r"root element is <other>, expected <modelSet>"):
        read_hatt_xml(bad)
    with pytest.raises(DataError, match="no such model file"):
        read_hatt_xml(tmp_path / "Models_Nope Nope.xml")


def test_write_then_read_round_trips_exactly(tmp_path):
    ms = cork_like_model_set()
    path = write_hatt_xml(ms, tmp_path / "Models_Cork Like.xml", texture=12)
    back = load_model_set(path)
    for key in ("speeds", "forces", "ar_lsf", "ma_lsf", "variance", "gain", "ar_coeff", "ma_coeff", "triangles"):
        assert np.array_equal(getattr(back, key), getattr(ms, key)), key
    assert back.mu == ms.mu and back.max_speed == ms.max_speed and back.metadata["texture"] == "12"
    text = path.read_text()
    # HaTT's shape: 1-based triangles, orders in numARCoeff/numMACoeff
    assert "<numARCoeff>19</numARCoeff>" in text and "<numMACoeff>17</numMACoeff>" in text
    assert text.count("<tri ") == 60 and text.count("<model>") == 45
    first_tri = text.split('<tri type="array">')[1].split("</tri>")[0]
    assert [int(v) for v in first_tri.replace("<value>", " ").replace("</value>", " ").split()] == [int(v) + 1 for v in ms.triangles[0]]


def test_limited_precision_file_matches_to_its_precision(tmp_path):
    ms = hard_model_set()
    path = write_hatt_xml(ms, tmp_path / "Models_Hard 8.xml", digits=12)
    back = read_hatt_xml(path)
    assert np.allclose(back.ar_lsf, ms.ar_lsf, rtol=1e-11, atol=0)
    assert np.allclose(back.ma_lsf, ms.ma_lsf, rtol=1e-11, atol=0)


def test_num_coeff_counting_the_leading_one_is_accepted(tmp_path):
    path = tmp_path / "m.xml"
    path.write_text(handmade().replace("<numARCoeff>2</numARCoeff>", "<numARCoeff>3</numARCoeff>")
                    .replace("<numMACoeff>1</numMACoeff>", "<numMACoeff>2</numMACoeff>"))
    ms = read_hatt_xml(path)
    assert (ms.ar_order, ms.ma_order) == (2, 1)


def test_values_as_plain_text_are_accepted(tmp_path):
    # Robustness: an array written as whitespace-separated text instead of <value> children.
    text = handmade()
    old = '<speedList type="array">\n' + values(("0", "100", "0", "100")) + "  </speedList>"
    assert old in text
    path = tmp_path / "m.xml"
    path.write_text(text.replace(old, "<speedList>0 100 0 100</speedList>"))
    assert read_hatt_xml(path).speeds.tolist() == [0.0, 100.0, 0.0, 100.0]


def test_hatt_shape_is_documented_shape(tmp_path):
    ms = hard_model_set()
    text = write_hatt_xml(ms, tmp_path / "x.xml").read_text()
    head = textwrap.dedent(text.split("<speedList")[0])
    for tag in ("material", "AccelUnits", "SpeedUnits", "ForceUnits", "SampleRate", "mu", "numMod", "numTri", "maxSpeed",
                "maxForce", "numARCoeff", "numMACoeff", "htmlPicture", "DTpicture"):
        assert f"<{tag}>" in head, tag
    model = text.split("<model>")[1]
    for tag in ("modNum", "ARcoeff", "ARlsf", "MAcoeff", "MAlsf", "var", "gain", "speedMod", "forceMod"):
        assert f"<{tag}" in model, tag
