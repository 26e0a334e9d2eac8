"""More first-plugin mistakes, each named by ``plugin check`` (and at load) in one line at its file and line.

tests/plugin_cases/mistakes_more.py: a layout sized by a parameter its declaration lets be 0 (the probe built only at
the defaults), a kernel writing into its input, a resolve() missing a declared output (an internal KeyError at run),
a type named like a built-in one and a parameter named like a Node.processor keyword (both passed; the keyword, or an
input named like a processor call's ``ticks``, is a note), uses_seed without
seed_state (passed; the graph then failed with NotImplementedError), a negative fractional latency (printed as is) and
own_every() returning 0 (an internal IndentationError in the generated code, ZeroDivisionError at run), and a smoother
whose forward-Euler coefficient diverges at the largest cutoff its declaration allows (the probe built only at the
defaults and minimums, and a finite output growing as 2.1**t passed), a kernel drawing from numba's global np.random
(reported as lost state: "keep every value ... in s") and one reading its output's last row back at t = 0 (passed).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from flowtex.cli import main
from tests.plugin_files import chain_graph, plugin_project
from tests.test_plugin_check import _line, check_copy

CASE = Path(__file__).parent / "plugin_cases" / "mistakes_more.py"
GAIN = 'type_name = "gain"'
RATE = 'params = {"rate"'


@pytest.fixture(scope="module")
def report(tmp_path_factory):
    return check_copy(CASE, tmp_path_factory.mktemp("pcm"), "m.py")


def test_each_mistake_is_one_problem_at_its_line(report):
    code, lines, err, path = report
    assert code == 1
    assert err.startswith("m.py: 10 problem(s) in node type(s) ")
    problems = [line for line in lines if ": note: " not in line]
    want = {
        "in_place": f"m.py:{_line(path, 'def inplace_kernel')}: node 'in_place_pc': kernel writes into its input 'x'",
        "forgets": (f"m.py:{_line(path, 'def resolve')}: node 'forgets_output_pc': resolve() of graph node 'probe' "
                    "returned no spec for output(s) 'z'"),
        "gain": (f"m.py:{_line(path, GAIN)}: node type 'gain' is already defined by entry point "
                 "flowtex.nodes; a graph would refuse to load this plugin: rename it"),
        "seedless": (f"m.py:{_line(path, 'uses_seed = True')}: node 'seedless_pc': uses_seed = True but the node defines "
                     "no seed_state"),
        "latency": (f"m.py:{_line(path, 'def latency_samples')}: node 'half_latency_pc': latency_samples() of graph node "
                    "'probe' returned -2.5; return the delay from input to output as a whole number of ticks >= 0"),
        "every": (f"m.py:{_line(path, 'def own_every')}: node 'never_runs_pc': own_every() for graph node 'probe' returned "
                  "0; return None"),
        "euler": (f"m.py:{_line(path, 'def euler_kernel')}: node 'euler_smoother_pc': output 'y' grows without bound for "
                  "inputs uniform in [-1, 1] (built with x: scalar; cutoff_hz=500): |max| "),
        "jitter": (f"m.py:{_line(path, 'def jitter_kernel')}: node 'jitter_pc': output 'y': two runs from the same built "
                   "state over the same inputs differ from tick 0 (built with x: scalar); the kernel draws numbers kept "
                   "outside s and si (numba's np.random, a global)"),
        "previous": (f"m.py:{_line(path, 'def previous_kernel')}: node 'reads_output_pc': output 'y' depends on what its "
                     "buffer held before the call, from tick 0 (built with x: scalar); the kernel reads 'y' before writing it"),
    }
    zero = [line for line in problems if "node 'zero_taps_pc': kernel reads or writes outside its arrays (built with x: "
            "scalar; taps=0)" in line]
    assert len(zero) == 1, problems
    assert _line(path, "def zero_kernel") <= int(zero[0].split(":")[1]) < _line(path, "class ZeroTaps")  # the kernel
    for key, start in want.items():
        assert sum(line.startswith(start) for line in problems) == 1, (key, problems)
    assert len(problems) == len(want) + 1, problems


def test_a_parameter_named_like_a_processor_keyword_is_a_note(report):
    _, lines, _, path = report
    assert (f"m.py:{_line(path, RATE)}: node 'gain': note: parameter 'rate' is named like Node.processor()'s own "
            "keyword 'rate': a processor sets it only as params={'rate': ...}") in lines


def test_an_input_named_like_a_processor_call_keyword_is_a_note(report):
    _, lines, _, path = report
    line = _line(path, 'inputs = {"ticks"')
    assert (f"m.py:{line}: node 'ticks_input_pc': note: input 'ticks' is named like a processor call's own keyword "
            "'ticks': Node.processor() cannot feed it; rename it to use the node on arrays") in lines


GRAPH = chain_graph("d: {type: forgets_output_pc}")


def test_a_resolve_missing_an_output_is_the_plugins_error_at_load(tmp_path, capsys):
    # it was "internal error: KeyError: 'z'" at run, after validate said ok
    text = CASE.read_text().replace('type_name = "gain"', 'type_name = "not_gain_pc"').replace("uses_seed = True", "")
    plugin_project(tmp_path, {"m.py": text}, GRAPH, np.arange(5.0))
    for argv in (["validate", str(tmp_path / "g.yaml")],
                 ["run", str(tmp_path / "g.yaml"), "-i", str(tmp_path / "r.npz"), "-o", str(tmp_path / "o.npz")]):
        assert main(argv) == 1
        err = [ln for ln in capsys.readouterr().err.splitlines() if not ln.startswith("flowtex: ")]
        assert len(err) == 1 and "resolve() of graph node 'd' returned no spec for output(s) 'z'" in err[0], err
        assert err[0].startswith(f"{tmp_path / 'plugins' / 'm.py'}:{_line(CASE, 'def resolve')}: ") or \
            err[0].startswith(f"plugins/m.py:{_line(CASE, 'def resolve')}: "), err[0]
    assert not (tmp_path / "o.npz").exists()


def test_a_plugin_type_named_like_a_built_in_is_refused_at_its_type_name_line(tmp_path, capsys):
    plugin_project(tmp_path, {"m.py": CASE.read_text().replace("uses_seed = True", "")}, GRAPH)
    assert main(["validate", str(tmp_path / "g.yaml")]) == 1
    err = [ln for ln in capsys.readouterr().err.splitlines() if not ln.startswith("flowtex: ")]
    assert len(err) == 1 and err[0].endswith(f"m.py:{_line(CASE, GAIN)}: node type 'gain' is already "
                                             "defined by entry point flowtex.nodes; rename one of them (flowtex nodes "
                                             "lists the taken names)"), err


def test_own_every_returning_zero_is_the_plugins_error_at_load(tmp_path, capsys):
    text = CASE.read_text().replace('type_name = "gain"', 'type_name = "not_gain_pc"').replace("uses_seed = True", "")
    plugin_project(tmp_path, {"m.py": text}, GRAPH.replace("forgets_output_pc", "never_runs_pc"))
    for argv in (["validate", str(tmp_path / "g.yaml")], ["graph", str(tmp_path / "g.yaml")]):
        assert main(argv) == 1
        err = [ln for ln in capsys.readouterr().err.splitlines() if not ln.startswith("flowtex: ")]
        assert len(err) == 1 and err[0].endswith(f"m.py:{_line(CASE, 'def own_every')}: node 'never_runs_pc': own_every() "
                                                 "for graph node 'd' returned 0; return None (the graph's every: decides) or "
                                                 "a whole number of ticks from 1 to 1,000,000"), err


def test_two_classes_of_one_file_with_one_type_name_are_refused_by_plugin_check(tmp_path, capsys):
    text = CASE.read_text().replace('type_name = "never_runs_pc"', 'type_name = "half_latency_pc"')
    (tmp_path / "twice.py").write_text(text)
    assert main(["plugin", "check", str(tmp_path / "twice.py")]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert err[-1].endswith(f"twice.py:{_line_after(tmp_path / 'twice.py', 'class NeverRuns', 'type_name')}: node type "
                            "'half_latency_pc' is already defined by class HalfLatency of this file; give each class its own "
                            "type_name"), err


def _line_after(path: Path, anchor: str, needle: str) -> int:
    lines = path.read_text().splitlines()
    start = next(k for k, text in enumerate(lines) if anchor in text)
    return next(k for k, text in enumerate(lines[start:], start=start + 1) if needle in text)


def test_a_node_that_refuses_the_probes_made_up_shapes_is_a_note_not_a_problem(capsys):
    # dot refuses a scalar input (its ParamError): plugin check cannot build it at the scalar case, which is the
    # probe's limit, not the node's mistake -- while a resolve() breaking the contract (above) is a problem
    assert main(["plugin", "check", "dot"]) == 0
    out = capsys.readouterr()
    assert "note: input a must be a vector, got shape scalar" in out.out and out.err.strip().endswith("dot: ok (node type(s) dot; 1 note(s))")
