"""Recordings flowtex writes are recordings flowtex reads: a graph output named like a .npz file's own entry (``rate``,
``units``) was an internal error after the run or lost the file's units, and one named ``time`` that does not increase
was written into a file every verb then refused. Each is refused in one line, nothing is written, and ``run`` says it
before the run. Also: a resampling ratio that cannot be joined names the rates as given, and a graph's free-text name
is escaped in the DOT source ``flowtex graph --dot`` writes."""

from __future__ import annotations

import numpy as np
import pytest

from flowtex.cli import main
from flowtex.errors import DataError
from flowtex.io.recordings import load_recording, save_recording

GRAPH = """flowtex: 1
name: named
rate: 1000
inputs:
  speed: {{unit: mm/s}}
nodes:
  g: {{type: gain, params: {{k: 2.0}}}}
edges:
  - speed -> g.x
outputs:
  {name}: g.y
"""


@pytest.fixture
def rec(tmp_path):
    path = tmp_path / "in.npz"
    save_recording(path, {"speed": np.linspace(1.0, 2.0, 50)}, rate=1000.0)
    return path


@pytest.mark.parametrize("name", ["rate", "units"])
def test_an_output_named_like_an_npz_entry_is_refused_before_the_run(tmp_path, rec, capsys, monkeypatch, name):
    import flowtex.runtime.offline as offline

    monkeypatch.setattr(offline, "run_recording", lambda *a, **k: pytest.fail("the run started"))
    graph = tmp_path / "g.yaml"
    graph.write_text(GRAPH.format(name=name))
    out = tmp_path / "out.npz"
    assert main(["run", str(graph), "--input", str(rec), "-o", str(out)]) == 1
    err = capsys.readouterr().err.strip()
    assert err == (f"{out}: a signal named {name!r} cannot be written to a .npz recording, whose {name!r} entry holds "
                   f"the recording's own {name}; rename it (a graph output: under outputs:) or write a .csv or .h5 file")
    assert set(tmp_path.iterdir()) == {graph, rec}  # nothing written


@pytest.mark.parametrize("suffix", [".npz", ".csv"])
def test_a_time_signal_that_would_be_refused_when_read_is_not_written(tmp_path, suffix):
    out = tmp_path / f"out{suffix}"
    with pytest.raises(DataError) as err:
        save_recording(out, {"time": np.full(10, 2.0), "y": np.zeros(10)}, rate=1000.0)
    assert str(err.value).startswith(f"{out}: not written, since flowtex would not read it back: signal 'time' does not "
                                     "increase at sample 1")
    assert not out.exists()
    save_recording(out, {"rate": np.zeros(10)} if suffix == ".csv" else {"y": np.zeros(10)}, rate=1000.0)  # what a format holds
    assert load_recording(out).arrays.keys() == ({"rate"} if suffix == ".csv" else {"y"})


def test_rates_that_resample_cannot_join_are_named_as_given(tmp_path, rec, capsys):
    """--rate 999.9999 from 1000 Hz said 'cannot resample 1000 Hz -> 1000 Hz' (both rounded to 6 digits)."""
    assert main(["resample", str(rec), "--rate", "999.9999", "-o", str(tmp_path / "o.npz")]) == 1
    assert "cannot resample 1000 Hz -> 999.9999 Hz: the ratio is not p/q" in capsys.readouterr().err


def test_a_graph_name_cannot_write_dot_of_its_own(tmp_path, capsys):
    """flowtex graph --dot wrote the free-text graph name between quotes as it was: a quote in it ended the string."""
    graph = tmp_path / "g.yaml"
    graph.write_text(GRAPH.format(name="y").replace("name: named", 'name: "x\\" ]; a [label=\\"1\\nnext\\\\"'))
    assert main(["graph", str(graph), "--dot"]) == 0
    dot = capsys.readouterr().out
    assert dot.splitlines()[0] == 'digraph "x\\" ]; a [label=\\"1\\nnext\\\\" {'
