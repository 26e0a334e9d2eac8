"""Writing a fitted set as HaTT XML says that the file cannot keep the set's rendering rule (docs/model-sets.md).

Read back, such an XML file renders with HaTT's rule (variance, fade), which is quieter than the fitted set's own
(power, trend) between models of different resonance (issue 23): the user who exports it is told, in one line, and
how to render it as fitted. A HaTT set written back as XML loses nothing and says nothing.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from flowtex.cli import main
from flowtex.datasets.model_sets import synthetic_model_set
from flowtex.io.hatt import write_hatt_xml
from flowtex.io.modelset import load_model_set, save_model_set
from flowtex.models.rendering import FITTED_RULE, HATT_RULE

LOST = "HaTT XML cannot state this set's rendering rule (interpolation power, outside trend)"
BAND = "HaTT XML cannot state that these models were resampled from"


def _sets(tmp_path: Path) -> tuple[Path, Path]:
    ms = synthetic_model_set(np.array([60.0]), np.array([0.5]), ar_order=4, ma_order=2)  # one measured model: the warnings are the point
    hatt = write_hatt_xml(ms, tmp_path / "hatt.xml")
    ms.rule = FITTED_RULE
    return save_model_set(ms, tmp_path / "fitted.json"), hatt


def test_models_resample_to_xml_warns_only_when_the_rule_is_lost(tmp_path, capsys):
    fitted, hatt = _sets(tmp_path)
    assert main(["models", "resample", str(fitted), "--rate", "2000", "-o", str(tmp_path / "f2k.xml")]) == 0
    err = capsys.readouterr().err.strip().splitlines()
    assert [line for line in err if LOST in line] == [line for line in err if "f2k.xml" in line][:1], err
    assert [line for line in err if BAND in line] == [line for line in err if "f2k.xml" in line][1:] and len(err) == 2, err
    assert "interpolation: power and outside: trend" in err[0]
    assert load_model_set(tmp_path / "f2k.xml").rule in (None, HATT_RULE)  # what the warning says: the rule is gone
    assert main(["models", "resample", str(fitted), "--rate", "2000", "-o", str(tmp_path / "f2k.json")]) == 0
    assert capsys.readouterr().err == ""
    assert load_model_set(tmp_path / "f2k.json").rule == FITTED_RULE
    assert main(["models", "resample", str(hatt), "--rate", "500", "-o", str(tmp_path / "h500.xml")]) == 0
    err = capsys.readouterr().err.strip().splitlines()  # a HaTT set loses no rule in XML, only the resampling record
    assert len(err) == 1 and BAND in err[0] and "up to 250 Hz, above the 200 Hz" in err[0], err


def test_xml_of_a_set_resampled_up_warns_that_compare_grades_it_to_the_nyquist_frequency(tmp_path, capsys):
    """A set resampled up knows its spectrum only up to 0.8 x the old Nyquist; its JSON records that and `flowtex
    compare` grades it there, its XML cannot, and compare read it back over the whole band (LSD 2.24 dB against 1.74
    on one fitted surface, docs/fitting.md): the export says so, and what the warning says is what compare does."""
    from flowtex.fit.resampled_band import resampled_band_hz

    _fitted, hatt = _sets(tmp_path)
    assert main(["models", "resample", str(hatt), "--rate", "2000", "-o", str(tmp_path / "h2k.xml")]) == 0
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and BAND in err[0] and "1000 Hz" in err[0] and "up to 1000 Hz, above the 400 Hz" in err[0], err
    assert resampled_band_hz(load_model_set(tmp_path / "h2k.xml")) == np.inf
    assert main(["models", "resample", str(hatt), "--rate", "2000", "-o", str(tmp_path / "h2k.json")]) == 0
    assert capsys.readouterr().err == ""
    assert resampled_band_hz(load_model_set(tmp_path / "h2k.json")) == 400.0


def test_fit_texture_xml_warns_that_the_xml_renders_with_hatts_rule(tmp_path, capsys):
    from flowtex.datasets.realistic import human_exploration

    rec = human_exploration(8.0, 1000.0, seed=0)
    rec.save(tmp_path / "rec.npz")
    assert main(["fit", "texture", str(tmp_path / "rec.npz"), "--speed", "speed", "--order", "4,2",
                 "-o", str(tmp_path / "s.json"), "--xml"]) == 0
    err = capsys.readouterr().err.strip().splitlines()
    assert len([line for line in err if LOST in line and "s.xml" in line]) == 1, err
    assert load_model_set(tmp_path / "s.json").rule == FITTED_RULE
