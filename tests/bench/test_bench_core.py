"""flowtex bench building blocks: knob parsing, error metrics, Pareto front (no graph compilation: fast)."""

from __future__ import annotations

import numpy as np
import pytest

from flowtex.bench.sweep import parse_knob
from flowtex.dsp.errors import pareto_front, signal_error
from flowtex.errors import FlowtexError


def test_parse_knob():
    assert parse_knob("synth.every=1,2,4") == ("synth.every", [1, 2, 4])
    assert parse_knob("friction.mode=hatt,continuous") == ("friction.mode", ["hatt", "continuous"])
    assert parse_knob("lookup.order=[6, 4];[4, 2]") == ("lookup.order", [[6, 4], [4, 2]])
    with pytest.raises(FlowtexError):
        parse_knob("synth=1,2")


def test_pareto_front_by_brute_force():
    rng = np.random.default_rng(0)
    cost, err = rng.uniform(size=40), rng.uniform(size=40)
    front = pareto_front(cost, err)
    for i in range(40):
        dominated = any(cost[j] <= cost[i] and err[j] <= err[i] and (cost[j] < cost[i] or err[j] < err[i]) for j in range(40))
        assert front[i] == (not dominated)


def test_errors_against_analytic_values():
    t = np.arange(4096)
    x = np.sin(0.3 * t)
    assert signal_error("rms", x, x + 0.5, 1000.0) == pytest.approx(0.5, rel=1e-12)  # constant offset
    # a gain of 2 raises the PSD by 4 everywhere: LSD = 10 log10(4) dB exactly; GFC is scale-free (0 error)
    noise = np.random.default_rng(1).normal(size=4096)
    assert signal_error("lsd", noise, 2.0 * noise, 1000.0) == pytest.approx(10 * np.log10(4.0), rel=1e-12)
    assert signal_error("gfc", noise, 2.0 * noise, 1000.0) == pytest.approx(0.0, abs=1e-12)


def test_sweep_every_knob_end_to_end(tmp_path, capsys):
    import csv

    from flowtex.cli import main

    graph = tmp_path / "g.yaml"
    graph.write_text("flowtex: 1\nname: tiny\nrate: 1000\ninputs:\n  x: {unit: N}\nnodes:\n  g: {type: gain, params: {k: 2.0}}\n"
                     "edges:\n  - x -> g.x\noutputs:\n  y: g.y\n")
    x = np.sin(0.05 * np.arange(1000))
    np.savez(tmp_path / "in.npz", x=x, extra=np.zeros(1000))  # a signal the graph does not read is left out, as in 'flowtex run'
    assert main(["bench", str(graph), "--input", str(tmp_path / "in.npz"), "--knob", "g.every=1,2", "--repeats", "2",
                 "-o", str(tmp_path / "t.csv")]) == 0
    rows = list(csv.reader(open(tmp_path / "t.csv")))
    assert rows[0] == ["g.every", "ns/tick (local, dispatch tier)", "y rms", "pareto"]
    assert rows[1][0] == "1" and float(rows[1][2]) == 0.0  # the reference itself
    # every=2: the gain runs on even ticks and holds its output on odd ones (a force: RMS metric)
    held = 2.0 * x[np.arange(1000) // 2 * 2]
    assert float(rows[2][2]) == pytest.approx(np.sqrt(np.mean((held - 2.0 * x) ** 2)), rel=1e-3)  # CSV keeps 4 digits
    assert "Pareto front" in capsys.readouterr().out


def test_a_recording_flowtex_run_refuses_is_refused_by_bench_too(tmp_path, capsys):
    """bench checks its recording as 'flowtex run' does (tests/test_cli_run.py): before, a 2 kHz recording ran through a
    1 kHz graph, and a speed stated in m/s through an input in mm/s, timed and scored as if they fitted."""
    from flowtex.cli import main
    from flowtex.io.recordings import save_recording

    graph = tmp_path / "g.yaml"
    graph.write_text("flowtex: 1\nname: tiny\nrate: 1000\ninputs:\n  x: {unit: N}\nnodes:\n  g: {type: gain, params: {k: 2.0}}\n"
                     "edges:\n  - x -> g.x\noutputs:\n  y: g.y\n")
    x = np.sin(0.05 * np.arange(1000))
    src = tmp_path / "in.npz"
    argv = ["bench", str(graph), "--input", str(src), "--knob", "g.every=1,2", "--repeats", "1"]
    for rate, units, message in ((2000.0, None, f"{src}: recorded at 2000 Hz but graph 'tiny' runs at 1000 Hz"),
                                 (1000.0, {"x": "kN"}, f"{src}: signal 'x' is in 'kN' (the file's units) but graph 'tiny' "
                                                       "input 'x' takes N; flowtex converts no unit: multiply it by 1000")):
        save_recording(src, {"x": x}, rate=rate, units=units)
        assert main(argv) == 1
        err = capsys.readouterr().err
        assert message in err, err
    save_recording(src, {"x": x}, rate=1000.0, units={"x": "N"})
    assert main(argv) == 0, capsys.readouterr().err
