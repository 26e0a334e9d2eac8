"""The texture index written as HaTT XML's <modelSet texture=...> comes from a set's metadata, which a JSON set holds
free-form and an XML holds as text: anything but a whole number is one line naming the file, never an internal error
after the work (``models resample -o OUT.xml``, ``fit friction --into SET.xml``)."""

from __future__ import annotations

import os

import numpy as np
import pytest

from flowtex.cli import main
from flowtex.datasets.model_sets import synthetic_model_set
from flowtex.io.hatt import MAX_TEXTURE_INDEX, write_hatt_xml
from flowtex.io.modelset import load_model_set, save_model_set
from flowtex.io.recordings import save_recording

BAD = ["abc", 3.5, [1], True, -3, 1e300, MAX_TEXTURE_INDEX + 1]  # (a JSON integer of 19+ digits is refused by the reader)


def _set(tmp_path, texture, name="s.json"):
    ms = synthetic_model_set([60.0], [0.5], ar_order=4, ma_order=2)
    ms.metadata = {"texture": texture}
    return save_model_set(ms, tmp_path / name)


def _one_line(capsys, argv) -> str:
    code = main([str(a) for a in argv])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 1 and len(err) == 1, err
    return err[0]


@pytest.mark.parametrize("texture", BAD)
def test_models_resample_to_xml_refuses_a_texture_that_is_not_an_index(tmp_path, capsys, texture):
    src = _set(tmp_path, texture)
    line = _one_line(capsys, ["models", "resample", src, "--rate", "2000", "-o", tmp_path / "out.xml"])
    assert line.startswith(f"{src}: metadata 'texture' is ") and f"from 0 to {MAX_TEXTURE_INDEX}" in line, line
    assert sorted(os.listdir(tmp_path)) == ["s.json"]


@pytest.mark.parametrize("texture", [7, "7", " 12 ", None])
def test_an_index_is_written_as_it_is(tmp_path, capsys, texture):
    src = _set(tmp_path, texture)
    assert main(["models", "resample", str(src), "--rate", "2000", "-o", str(tmp_path / "out.xml")]) == 0
    assert load_model_set(tmp_path / "out.xml").metadata["texture"] == ("0" if texture is None else str(texture).strip())


def test_fit_friction_into_an_xml_with_a_broken_texture_keeps_the_file(tmp_path, capsys):
    ms = synthetic_model_set([60.0], [0.5], ar_order=4, ma_order=2)
    surface = write_hatt_xml(ms, tmp_path / "s.xml", texture=3)
    surface.write_text(surface.read_text().replace('texture="3"', 'texture="3.5"'))
    before = surface.read_bytes()
    rng = np.random.default_rng(0)
    normal = rng.uniform(0.5, 2.0, 4000)
    save_recording(tmp_path / "r.npz", {"normal_force": normal, "friction": 0.4 * normal + rng.normal(0, 0.01, 4000)}, 1000.0)
    line = _one_line(capsys, ["fit", "friction", tmp_path / "r.npz", "--force", "normal_force", "--friction-force",
                              "friction", "-o", tmp_path / "mu.json", "--into", surface])
    assert line.startswith(f"{surface}: metadata 'texture' is '3.5'"), line
    assert surface.read_bytes() == before
    assert sorted(os.listdir(tmp_path)) == ["r.npz", "s.xml"]
