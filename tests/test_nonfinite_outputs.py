"""flowtex run counts NaN and inf per output and warns, or refuses with --nonfinite-outputs error (issue 25)."""

from __future__ import annotations

import numpy as np
import pytest

from flowtex.cli import main
from flowtex.dsp.nonfinite import count_nonfinite

PLUGIN = '''
import numpy as np
from numba import njit

from flowtex.node_api import Node, NodeState, Param, Port


@njit(cache=True)
def ema_kernel(p, s, si, x, y):
    for t in range(x.shape[0]):
        s[0] = s[0] + p[0] * (x[t, 0] * x[t, 0] - s[0])
        y[t, 0] = s[0]


class EmaPower(Node):
    """Exponential moving power; alpha has no bounds (the mistake under test)."""

    type_name = "ema_power_nf"
    params = {"alpha": Param("float", default=0.01)}
    inputs = {"x": Port((), "*")}
    outputs = {"y": Port((), "")}
    kernel = ema_kernel

    def build(self, inputs, outputs):
        return NodeState(params=np.array([self.p["alpha"]]), state=np.zeros(1))
'''

GRAPH = """\
flowtex: 1
name: t
rate: 1000
inputs: {x: {}}
nodes:
  e: {type: ema_power_nf, params: {alpha: -5}}
edges: [x -> e.x]
outputs: {y: e.y, x: x}
"""


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
    folder = tmp_path_factory.mktemp("nonfinite")
    (folder / "plugins").mkdir()
    (folder / "plugins" / "ema_nf.py").write_text(PLUGIN)
    (folder / "g.yaml").write_text(GRAPH)
    x = np.sin(np.arange(2000) / 7.0)
    np.savez(folder / "r.npz", x=x, rate=1000.0)
    return folder, x


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
