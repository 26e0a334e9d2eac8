"""CSV recordings a newcomer writes by hand: vector columns, a time column, shape errors (issue 9 item 9)."""

from __future__ import annotations

import numpy as np
import pytest

from flowtex.cli import main

GRAPH = """
flowtex: 1
name: csv
rate: {rate}
inputs:
  acc: {{shape: [3], unit: m/s^2}}
nodes:
  g: {{type: gain, params: {{k: 2}}}}
edges: [acc -> g.x]
outputs: {{y: g.y}}
"""


def _error_line(capsys) -> str:
    """The error, without the one-line compile notice a cold numba cache prints before it."""
    return capsys.readouterr().err.strip().splitlines()[-1]


def _csv(path, header, rows):
    path.write_text(header + "\n" + "\n".join(", ".join(repr(float(v)) for v in row) for row in rows) + "\n")
    return path


@pytest.fixture
def rows():
    return np.random.default_rng(2).standard_normal((20, 3))


def test_xyz_columns_get_a_hint(write_graph, tmp_path, rows, capsys):
    graph = write_graph(GRAPH.format(rate=1000))
    src = _csv(tmp_path / "r.csv", "acc_x, acc_y, acc_z", rows)
    assert main(["run", str(graph), "-i", str(src)]) == 1
    assert _error_line(capsys) == (
        f"{src}: lacks graph input(s) acc (the file has: acc_x, acc_y, acc_z); input 'acc' has shape (3,): "
        "name its CSV columns acc[0], acc[1], acc[2] (not acc_x, acc_y, acc_z)")


def test_time_column_checks_the_rate(write_graph, tmp_path, rows, capsys):
    t = np.arange(20) / 1000.0  # spaced at 1 kHz
    src = _csv(tmp_path / "r.csv", "time,acc[0],acc[1],acc[2]", np.column_stack([t, rows]))
    slow = write_graph(GRAPH.format(rate=2000), "g2.yaml")
    assert main(["run", str(slow), "-i", str(src)]) == 1
    assert _error_line(capsys) == (
        f"{src}: column 'time' is spaced 0.001 s (1000 Hz) but graph 'csv' runs at 2000 Hz; resample the recording, "
        "set the graph's rate: 1000, or drop the time column if it is not in seconds")
    ok = write_graph(GRAPH.format(rate=1000), "g1.yaml")
    out = tmp_path / "o.npz"
    assert main(["run", str(ok), "-i", str(src), "-o", str(out)]) == 0
    capsys.readouterr()
    np.testing.assert_array_equal(np.load(out)["y"], 2 * rows)  # k = 2 is exact in binary


def test_shape_error_names_the_file(write_graph, tmp_path, capsys):
    graph = write_graph(GRAPH.format(rate=1000))
    src = tmp_path / "r.npz"
    np.savez(src, acc=np.zeros((10, 2)))
    assert main(["run", str(graph), "-i", str(src)]) == 1
    assert _error_line(capsys) == f"{src}: input 'acc': expected shape (n, 3) with time first, got (10, 2)"
