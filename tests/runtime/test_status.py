"""flowtex live --show: chosen graph outputs/inputs on the status line (formatting, name checks, a short session)."""

from __future__ import annotations

import argparse
import io
import math
import re

import numpy as np
import pytest
from test_live import DBC, setup  # noqa: F401  (fixture; rootdir-relative import as pytest does)

from flowtex.cli.live import register
from flowtex.errors import FlowtexError
from flowtex.graph.compiled import load_graph
from flowtex.runtime.live import LiveConfig, run_live
from flowtex.runtime.status import format_values, resolve_shown


def test_format_values_scalars_vectors_units_and_non_finite():
    vib = np.array([0.123456])
    force = np.array([0.0123456, -4.5e-05, 0.0])
    assert format_values([("vibration", vib, "A")]) == "vibration 0.1235 A"
    assert format_values([("force", force, "N"), ("gain", np.array([2.0]), "")]) == "force [0.01235 -4.5e-05 0] N | gain 2"
    assert format_values([("x", np.array([np.nan, np.inf, -np.inf]), "mm")]) == "x [nan inf -inf] mm"
    assert format_values([]) == ""


def test_resolve_shown_reads_the_live_port_views(setup):  # noqa: F811
    g = load_graph(setup / "g.yaml").with_block_rows(1)
    shown = resolve_shown(g, ["vibration", "force[2]", "position"])
    assert [(label, unit) for label, _, unit in shown] == [("vibration", "A"), ("force[2]", "N"), ("position", "mm")]  # the gains state A and N
    g.input_view("position")[:] = [1.5, -2.0, 3.25]
    g.input_view("normal_force")[:] = 2.0
    g.step_block(1)
    # gain k=0.25 on the force; the 50 Hz lowpass's first output is its input times (1 - exp(-2 pi 50 / 1000)) (zero state)
    alpha = 1.0 - math.exp(-2 * math.pi * 50 / 1000)
    text = format_values(shown)
    assert text.startswith("vibration 0.5 A | force[2] ")
    assert text.endswith(" N | position [1.5 -2 3.25] mm")
    got = float(re.search(r"force\[2\] (\S+) N", text).group(1))
    assert got == pytest.approx(0.01 * 3.25 * alpha, rel=1e-3)  # printed with 4 significant digits


def test_resolve_shown_rejects_unknown_names_and_indices(setup):  # noqa: F811
    g = load_graph(setup / "g.yaml").with_block_rows(1)
    with pytest.raises(FlowtexError, match=r"no output or input 'vibraton' \(did you mean 'vibration'\?\)"):
        resolve_shown(g, ["vibraton"])
    with pytest.raises(FlowtexError, match=r"'force' has 3 component\(s\).*0\.\.2"):
        resolve_shown(g, ["force[3]"])


def test_live_session_shows_the_chosen_values_on_its_status_line(setup):  # noqa: F811
    parser = argparse.ArgumentParser()
    register(parser.add_subparsers())
    args = parser.parse_args(["live", "g.yaml", "--dbc", "d", "--map", "m", "--show", "vibration", "--show", "force[0]"])
    assert args.show == ["vibration", "force[0]"]

    out = io.StringIO()
    g = load_graph(setup / "g.yaml")
    r = run_live(g, LiveConfig(DBC, setup / "m.yaml", simulate=setup / "rec.npz", max_ticks=600, status=out, show=args.show))
    assert r.error is None
    last = [line for line in out.getvalue().replace("\r", "\n").splitlines() if line.startswith("tick ")][-1]
    vib = float(re.search(r"\| vibration (\S+) A \| force\[0\] \S+ N$", last).group(1))
    # the last tick (599) got sample 599 of the recording: 0.25 * (3 + sin(10 pi t)); NormalForce is sent in 0.001 N
    # steps (0.25 * 0.0005 N of error) and printed with 4 significant digits (5e-5 here)
    assert vib == pytest.approx(0.25 * (3 + math.sin(10 * math.pi * 0.599)), abs=2e-4)


class _GoneTerminal(io.StringIO):
    """A terminal that closes after its first write, as one does when its window or ssh session goes (EIO)."""

    def isatty(self) -> bool:
        return True

    def write(self, text: str) -> int:
        if self.getvalue():
            raise OSError(5, "Input/output error")
        return super().write(text)


def test_a_status_stream_that_fails_does_not_end_the_session(setup):  # noqa: F811
    # the display only informs: before, the session ended at the first refused write as "CAN bus error at tick 500:
    # [Errno 5] Input/output error" (a wrong label, and a session cut short by its display)
    out = _GoneTerminal()
    r = run_live(load_graph(setup / "g.yaml"), LiveConfig(DBC, setup / "m.yaml", simulate=setup / "rec.npz", max_ticks=1200,
                                                          status=out))
    assert r.error is None and r.ticks == 1200, r.error
    assert out.getvalue().startswith("\rtick       500 |")  # the one write that got through


@pytest.mark.parametrize("terminal", [True, False], ids=["terminal", "log"])
def test_a_flood_of_watchdog_events_prints_a_few_lines_and_counts_the_rest(setup, terminal):  # noqa: F811
    """A machine too loaded to keep time trips the overrun watchdog again and again: each status period prints its first
    EVENT_LINES events one by one and the others as one line, and every event is counted (the old display printed
    200 lines here, one per event)."""
    from flowtex.runtime.canio import load_io
    from flowtex.runtime.stats import TickStats
    from flowtex.runtime.status import StatusDisplay

    class Terminal(io.StringIO):
        def isatty(self) -> bool:
            return terminal

    g = load_graph(setup / "g.yaml")
    cio = load_io(g, DBC, setup / "m.yaml")
    wd = cio.new_watchdog(overrun_limit_ns=1_000_000, emit_log=False)
    out = Terminal()
    display = StatusDisplay(out, cio, wd, TickStats(100), 50)
    period = display.every  # 50 ticks on a terminal, 500 in a log
    ticks, late_every = 2000, 10
    for tick in range(ticks):
        for i in range(len(wd.timeouts)):
            wd.fresh(i, tick)  # every sensor fresh: only the late ticks trip it, and it recovers at the next tick
        wd.check(tick, 2_000_000 if tick % late_every == late_every - 1 else 0)  # ticks 9, 19, ...: shown at k = 10, 20, ...
        display.tick(tick + 1)
    display.finish(False)
    assert wd.events == ticks // late_every  # 200 events, each a new trip
    lines = [line.strip() for line in out.getvalue().replace("\r", "\n").split("\n")]
    one_by_one = [line for line in lines if line.startswith("watchdog: tick ")]
    held = [line for line in lines if line.startswith("watchdog: ") and " more event" in line]
    periods = ticks // period
    per_period = period // late_every  # events in one period
    assert len(one_by_one) == periods * StatusDisplay.EVENT_LINES and len(held) == periods
    counted = [int(re.match(r"watchdog: (\d+) more events in ticks (\d+)-(\d+)", line).group(1)) for line in held]
    assert counted == [per_period - StatusDisplay.EVENT_LINES] * periods and sum(counted) + len(one_by_one) == wd.events
    first_held = int(re.match(r"watchdog: \d+ more events in ticks (\d+)-", held[0]).group(1))
    assert first_held == (StatusDisplay.EVENT_LINES + 1) * late_every - 1  # the 4th event of the first period: tick 39
