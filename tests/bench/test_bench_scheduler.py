"""``flowtex bench --scheduler ADDR`` against a real dask.distributed scheduler started here.

The configurations must run on the cluster (the scheduler saw the tasks), the
timing column must say it was measured on the workers, and the error column
must equal a local run's: errors are deterministic (same graph, input and
seed), timings are not and are never compared.
"""

from __future__ import annotations

import csv

import numpy as np

from flowtex.cli import main

GRAPH = ("flowtex: 1\nname: tiny\nrate: 1000\ninputs:\n  x: {unit: N}\n"
         "nodes:\n  lp: {type: first_order_lowpass, params: {cutoff_hz: 50}}\n  g: {type: gain, params: {k: 2.0}}\n"
         "edges:\n  - x -> lp.x\n  - lp.y -> g.x\noutputs:\n  y: g.y\n")


def _rows(path):
    with open(path, newline="") as fh:
        return list(csv.reader(fh))


def test_bench_on_a_dask_scheduler_equals_a_local_run(tmp_path, capsys):
    from distributed import LocalCluster

    graph = tmp_path / "g.yaml"
    graph.write_text(GRAPH)
    np.savez(tmp_path / "in.npz", x=np.sin(0.05 * np.arange(1000)) + 0.3 * np.sin(0.9 * np.arange(1000)))
    sweep = [str(graph), "--input", str(tmp_path / "in.npz"), "--knob", "g.every=1,2,3", "--knob", "lp.cutoff_hz=50,20", "--repeats", "1"]
    assert main(["bench", *sweep, "-o", str(tmp_path / "local.csv")]) == 0
    capsys.readouterr()
    # one worker process with one thread: a real cluster; its scheduler runs in this process, so it can be inspected
    with LocalCluster(n_workers=1, threads_per_worker=1, processes=True, dashboard_address=None) as cluster:
        assert main(["bench", *sweep, "--scheduler", cluster.scheduler_address, "-o", str(tmp_path / "dask.csv")]) == 0
        prefix = cluster.scheduler.task_prefixes.get("run_config")
        computed = 0 if prefix is None else prefix.state_counts["memory"]  # tasks that reached 'memory' (a result)
    printed = capsys.readouterr().out
    assert computed == 6  # every configuration (3 x 2) was computed on the cluster
    local, remote = _rows(tmp_path / "local.csv"), _rows(tmp_path / "dask.csv")
    assert local[0] == ["g.every", "lp.cutoff_hz", "ns/tick (local, dispatch tier)", "y rms", "pareto"]
    assert remote[0] == ["g.every", "lp.cutoff_hz", "ns/tick (dask workers, dispatch tier)", "y rms", "pareto"]
    assert "ns/tick (dask workers, dispatch tier)" in printed
    assert len(remote) == len(local) == 7
    for a, b in zip(local[1:], remote[1:], strict=True):
        assert a[:2] == b[:2]  # same configuration, same order
        assert b[3] == a[3]  # the error, computed from outputs made on the worker, equals the local one
        assert float(b[2]) > 0  # a timing arrived (its value depends on the machine: never compared)
    errors = [float(r[3]) for r in local[1:]]
    assert errors[0] == 0.0 and min(errors[1:]) > 0  # the reference, then real differences (not all-zero columns)


def test_an_unaligned_input_array_runs_like_an_aligned_one(tmp_path):
    # Dask hands a worker arrays deserialized from its message frames, at any byte offset. The compiled run
    # addresses its input in 8-byte steps from the arena, so an unaligned one used to be read shifted by a
    # few bytes (garbage outputs on the workers: this test's first version found it). Now it is copied first.
    from flowtex.bench.sweep import build

    (tmp_path / "g.yaml").write_text(GRAPH)
    g = build(tmp_path / "g.yaml", {})
    x = np.sin(0.05 * np.arange(1000)) + 0.3 * np.sin(0.9 * np.arange(1000))
    expected = g.run({"x": x})["y"].copy()
    for offset in (1, 4, 7):
        unaligned = np.frombuffer(bytearray(8 * 1000 + 8), dtype=np.float64, count=1000, offset=offset)  # writeable
        unaligned[:] = x
        assert not unaligned.flags.aligned and np.array_equal(unaligned, x)
        np.testing.assert_array_equal(g.run({"x": unaligned})["y"], expected)
