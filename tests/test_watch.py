"""``flowtex watch``: an edited graph is rerun, each run reporting its outputs and what changed (issue 25)."""

from __future__ import annotations

import os
import queue
import re
import subprocess
import sys
import threading
from pathlib import Path

import numpy as np

from flowtex.runtime.watch import output_stats

REPO = Path(__file__).resolve().parents[1]
WAIT_S = 600.0  # the first run compiles the dispatch tier's wrappers when the cache is cold; a loaded 2-core machine

GRAPH = "flowtex: 1\nname: w\nrate: 1000\ninputs: {{x: {{}}}}\nnodes:\n  g: {{type: gain, params: {{k: {k}}}}}\n" \
        "edges: [x -> g.x]\noutputs: {{y: g.y}}\n"


def _lines_until(lines: queue.Queue, pattern: str, seen: list[str]) -> list[str]:
    """Read report lines until one matches ``pattern``, then the output lines that follow it (they start with two spaces)."""
    while True:
        line = lines.get(timeout=WAIT_S)
        assert line is not None, "watch ended early:\n" + "\n".join(seen)
        seen.append(line)
        if re.match(pattern, line):
            return [lines.get(timeout=WAIT_S)]  # one output: y


def _rms(text: str) -> float:
    return float(re.search(r"RMS ([0-9.e+-]+)", text).group(1))


def test_two_edits_give_two_reruns_with_the_right_outputs(tmp_path):
    x = np.sin(np.arange(1000) / 5.0)
    np.savez(tmp_path / "r.npz", x=x, rate=1000.0)
    graph = tmp_path / "g.yaml"
    graph.write_text(GRAPH.format(k=2.0))
    env = {**os.environ, "PYTHONPATH": str(REPO), "FLOWTEX_BACKGROUND": "0"}
    proc = subprocess.Popen([sys.executable, "-m", "flowtex", "watch", str(graph), "-i", str(tmp_path / "r.npz"),
                             "-o", str(tmp_path / "o.npz"), "--max-runs", "3", "--interval", "0.1"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env, cwd=tmp_path)
    lines: queue.Queue = queue.Queue()

    def pump() -> None:
        assert proc.stdout is not None
        for line in proc.stdout:
            lines.put(line.rstrip("\n"))
        lines.put(None)

    threading.Thread(target=pump, daemon=True).start()
    seen: list[str] = []
    try:
        out1 = _lines_until(lines, r"run 1 \(start\): ", seen)
        graph.write_text(GRAPH.format(k=3.5))
        out2 = _lines_until(lines, r"run 2 \(changed: g\.yaml\): ", seen)
        graph.write_text(GRAPH.format(k=-10.25))
        out3 = _lines_until(lines, r"run 3 \(changed: g\.yaml\): ", seen)
        assert proc.wait(timeout=WAIT_S) == 0  # --max-runs 3: ends by itself
    finally:
        proc.kill()
    rel = 5e-6  # the report prints 6 significant digits
    for line, k in ((out1[0], 2.0), (out2[0], 3.5), (out3[0], -10.25)):
        rms, peak, bad = output_stats(k * x)
        assert line.startswith("  y: RMS ") and abs(_rms(line) - rms) <= rel * rms and f"non-finite {bad}" in line
        assert f"peak {peak:.6g}" in line
    assert f"(was {np.sqrt(np.mean((2.0 * x) ** 2)):.6g})" in out2[0]  # what changed: the previous run's RMS
    with np.load(tmp_path / "o.npz") as data:
        np.testing.assert_array_equal(data["y"], -10.25 * x)  # the last run's output file


def test_output_stats_ignore_non_finite_values():
    rms, peak, bad = output_stats(np.array([[3.0, np.nan], [-4.0, np.inf]]))
    assert (rms, peak, bad) == (np.sqrt(12.5), 4.0, 2)


def test_plot_writes_a_png_and_max_runs_ends_the_watch(tmp_path, capsys):
    from flowtex.cli import main

    np.savez(tmp_path / "r.npz", x=np.sin(np.arange(200) / 5.0), rate=1000.0)
    (tmp_path / "g.yaml").write_text(GRAPH.format(k=2.0))
    png = tmp_path / "o.png"
    assert main(["watch", str(tmp_path / "g.yaml"), "-i", str(tmp_path / "r.npz"), "--plot", str(png), "--max-runs", "1"]) == 0
    out = capsys.readouterr().out.splitlines()
    assert out[0].startswith("run 1 (start): ") and out[1].startswith("  y: RMS ")
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_max_runs_exits_1_when_the_last_run_failed(tmp_path, capsys):
    """`watch --max-runs 1` in a script: a broken graph or recording used to exit 0 after printing its error."""
    from flowtex.cli import main

    np.savez(tmp_path / "r.npz", x=np.sin(np.arange(200) / 5.0), rate=1000.0)
    (tmp_path / "cut.npz").write_bytes(b"PK\x03\x04" + bytes(40))
    (tmp_path / "g.yaml").write_text(GRAPH.format(k=2.0))
    (tmp_path / "bad.yaml").write_text(GRAPH.format(k="two"))
    for graph, rec in (("g.yaml", "cut.npz"), ("bad.yaml", "r.npz")):
        assert main(["watch", str(tmp_path / graph), "-i", str(tmp_path / rec), "--max-runs", "1"]) == 1
        out = capsys.readouterr().out.splitlines()
        assert out[0].startswith("run 1 (start): failed after ") and out[1].startswith("  "), out
    assert main(["watch", str(tmp_path / "g.yaml"), "-i", str(tmp_path / "r.npz"), "--max-runs", "1"]) == 0


def test_each_output_is_reported_with_its_unit(tmp_path, capsys):
    """'vibration: RMS 0.523, peak 9.41' gave numbers without their unit; an output without one stays bare."""
    from flowtex.cli import main

    np.savez(tmp_path / "r.npz", x=np.ones(500), rate=np.float64(1000.0))
    graph = GRAPH.replace("inputs: {{x: {{}}}}", "inputs: {{x: {{unit: m/s^2}}}}").format(k=2.0)
    (tmp_path / "g.yaml").write_text(graph)
    assert main(["watch", str(tmp_path / "g.yaml"), "-i", str(tmp_path / "r.npz"), "--max-runs", "1"]) == 0
    out = [line for line in capsys.readouterr().out.splitlines() if "RMS" in line]
    assert out == ["  y [m/s^2]: RMS 2, peak 2, non-finite 0"]
