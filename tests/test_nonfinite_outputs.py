"""flowtex run counts NaN and inf per output and warns, or refuses with --nonfinite-outputs error (issue 25)."""

from __future__ import annotations

import numpy as np
import pytest

from flowtex.cli import main
from flowtex.dsp.nonfinite import count_nonfinite
from tests.plugin_files import chain_graph, plugin_project, plugin_source

PLUGIN = plugin_source("ema_power_nf", "ema_kernel", """
for t in range(x.shape[0]):
    s[0] = s[0] + p[0] * (x[t, 0] * x[t, 0] - s[0])
    y[t, 0] = s[0]
""", doc="Exponential moving power; alpha has no bounds (the mistake under test).", cls="EmaPower",
    params='{"alpha": Param("float", default=0.01)}', outputs='{"y": Port((), "")}',
    build='NodeState(params=np.array([self.p["alpha"]]), state=np.zeros(1))')

GRAPH = chain_graph("e: {type: ema_power_nf, params: {alpha: -5}}", outputs="x: x")


def _expected(x: np.ndarray) -> str:
    """The same recursion in float64 numpy: where it overflows, and how many NaN and inf it leaves."""
    s, y = 0.0, np.empty_like(x)
    with np.errstate(over="ignore", invalid="ignore"):
        for t, v in enumerate(x):
            s = s + -5.0 * (v * v - s)
            y[t] = s
    nan, inf = int(np.isnan(y).sum()), int(np.isinf(y).sum())
    first = int(np.argmax(~np.isfinite(y)))
    assert nan + inf > 0  # the recursion does blow up within the recording
    return f"output 'y': {nan} NaN and {inf} inf value(s), the first at tick {first}"


@pytest.fixture(scope="module")
def project(tmp_path_factory):
    """The plugin, graph and recording, shared by the tests (they only read them; each writes into its own tmp_path):
    one plugin file compiles its kernel once."""
    x = np.sin(np.arange(2000) / 7.0)
    return plugin_project(tmp_path_factory.mktemp("nonfinite"), {"ema_nf.py": PLUGIN}, GRAPH, x), x


def test_run_warns_per_output(project, tmp_path, capsys):
    folder, x = project
    out = tmp_path / "o.npz"
    assert main(["run", str(folder / "g.yaml"), "-i", str(folder / "r.npz"), "-o", str(out)]) == 0
    warnings = [line for line in capsys.readouterr().err.splitlines() if line.startswith("warning:")]
    assert warnings == [f"warning: {_expected(x)} (--nonfinite-outputs error refuses instead)"]  # nothing about 'x'
    assert out.exists()


def test_run_refuses_with_the_error_policy(project, tmp_path, capsys):
    folder, x = project
    out = tmp_path / "o.npz"
    assert main(["run", str(folder / "g.yaml"), "-i", str(folder / "r.npz"), "-o", str(out),
                 "--nonfinite-outputs", "error"]) == 1
    err = [line for line in capsys.readouterr().err.splitlines() if not line.startswith("flowtex: ")]
    assert len(err) == 1 and _expected(x) in err[0] and "nothing written" in err[0]
    assert not out.exists()


def test_count_nonfinite_counts_every_component():
    a = np.zeros((5, 3))
    a[2, 1] = np.nan
    a[3, 0] = a[3, 2] = np.inf
    a[4, 1] = -np.inf
    found = count_nonfinite(a)
    assert (found.nan, found.inf, found.first_index) == (1, 3, 2)
    assert count_nonfinite(np.ones((4, 2))) is None
