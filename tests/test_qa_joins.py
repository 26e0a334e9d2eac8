"""Joins between verbs that a user hits when chaining them (issues 17 and 18, found by running the CLI end to end)."""

from __future__ import annotations

import json
import os
import stat
import threading
from pathlib import Path

import pytest

from flowtex.errors import DataError, GraphError
from flowtex.graph.spec import parse_spec
from flowtex.io.atomic import check_output, write_json_atomic
from flowtex.io.recordings import load_recording

GRAPH = """flowtex: 1
name: g
rate: 1000
inputs:
  x: {}
nodes:
  k: {type: gain, params: {k: 2.0}}
edges:
  - x -> k.x
outputs: {y: k.y}
"""


def test_set_rate_sets_the_graph_rate(tmp_path: Path) -> None:
    # `--set rate=2000` is how a resampled model set is rendered (docs/fitting.md); it used to be refused.
    spec = parse_spec(GRAPH, tmp_path / "g.yaml", {"rate": 2000})
    assert spec.rate == 2000.0


@pytest.mark.parametrize("bad", [0, -5, float("nan"), "fast", True])
def test_set_rate_refuses_a_rate_that_is_not_positive(tmp_path: Path, bad: object) -> None:
    with pytest.raises(GraphError, match="rate must be a positive number of Hz"):
        parse_spec(GRAPH, tmp_path / "g.yaml", {"rate": bad})


def test_output_into_a_fifo_writes_into_it_and_keeps_it(tmp_path: Path) -> None:
    # `-o /dev/null` used to rename a temporary file over the device, turning /dev/null into a regular file (as root).
    # A FIFO is the same kind of target (exists, not a regular file) without touching the machine's /dev.
    fifo = tmp_path / "pipe.json"
    os.mkfifo(fifo)
    got: list[bytes] = []
    reader = threading.Thread(target=lambda: got.append(fifo.read_bytes()))
    reader.start()
    assert check_output(fifo) == fifo
    write_json_atomic(fifo, {"mu": 0.5})
    reader.join(timeout=10)
    assert stat.S_ISFIFO(os.stat(fifo).st_mode)
    assert json.loads(got[0]) == {"mu": 0.5}
    assert [p.name for p in tmp_path.iterdir()] == ["pipe.json"]   # no temporary file left behind


@pytest.mark.parametrize("content", [
    b"",                                     # numpy: EOFError -> "internal error"
    b"garbage\n",                            # numpy: "pickled data ... allow_pickle" advice
    b"\x93NUMPY\x01\x00" + b" " * 60,        # an .npy saved under an .npz name
])
def test_a_file_that_is_not_an_npz_is_refused_in_one_line(tmp_path: Path, content: bytes) -> None:
    path = tmp_path / "rec.npz"
    path.write_bytes(content)
    with pytest.raises(DataError, match=r"rec\.npz: .*npz") as info:
        load_recording(path)
    assert "pickle" not in str(info.value) and "\n" not in str(info.value)
