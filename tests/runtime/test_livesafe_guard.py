"""Clamp and peak-limit events per output: counted by the guard, in the status line, in --stats and warned about above 1 %.

Reference counts come from the graph run offline over the inputs cantools decodes from the frames the simulated
device sends (offline and live give identical outputs), compared with the map's clamp: independent of the guard.
"""

from __future__ import annotations

import io
import json
import textwrap

import cantools
import numpy as np
from test_live import DBC, MAP, setup  # noqa: F401  (fixture; rootdir-relative import as pytest does)

from flowtex.graph.compiled import load_graph
from flowtex.runtime.live import LiveConfig, run_live
from flowtex.runtime.safety import OutputGuard

TICKS = 300


def test_peak_limit_and_clamp_events_are_counted_apart():
    """Rules of flowtex/runtime/safety.py: within the 2-tick allowance a value beyond the peak limit is a peak-limit
    event; after it, a clamp event; NaN is neither."""
    g = OutputGuard(lo=[-1.0, -1.0], hi=[1.0, 1.0], safe=[0.0, 0.0], peak_hi=3.0, peak_max_ticks=2, peak_recover_ticks=2)
    out = np.zeros(2)
    for v in ([5.0, 0.5], [2.0, 1.5], [2.0, np.nan], [0.0, 1.5], [-4.0, 1.5]):
        g.apply(np.array(v), out, False)
    # channel 0: 5 -> 3 (peak-limited), 2 passes (tick 2 of the allowance), 2 -> 1 (clamped), 0 refills one peak tick
    # (2 ticks refill the allowance of 2), -4 -> -3 (peak-limited)
    # channel 1: 0.5 passes, 1.5 passes (peak tick 1), NaN -> safe (refills a tick), 1.5 passes, 1.5 passes, both peaks
    assert g.peak_counts.tolist() == [2, 0]
    assert g.clamp_counts.tolist() == [1, 0]
    assert g.nonfinite_counts.tolist() == [0, 1]


def _reference(setup, ticks: int) -> dict[str, np.ndarray]:  # noqa: F811
    """Graph outputs offline over the recording's first ``ticks`` samples as cantools decodes them from the DBC."""
    db = cantools.database.load_file(DBC)
    rec = np.load(setup / "rec.npz")
    pos, force = rec["position"][:ticks], rec["normal_force"][:ticks]
    tp, tf = db.get_message_by_name("ToolPosition"), db.get_message_by_name("ToolForce")
    P = np.array([[tp.decode(tp.encode({"PosX": x, "PosY": y, "PosZ": z, "PosCounter": 0}))[k] for k in ("PosX", "PosY", "PosZ")]
                  for x, y, z in pos], dtype=float)
    zero = {"SurfNormalX": 0, "SurfNormalY": 0, "SurfNormalZ": 0}
    F = np.array([tf.decode(tf.encode({"NormalForce": f, **zero}))["NormalForce"] for f in force], dtype=float)
    return load_graph(setup / "g.yaml").run({"position": P, "normal_force": F})


def test_clamps_per_output_in_status_stats_and_a_warning_above_one_percent(setup):  # noqa: F811
    ref = _reference(setup, TICKS)
    over_v = np.abs(ref["vibration"]) > 0.8
    over_f = np.abs(ref["force"]) > 0.5
    assert 0.01 * TICKS < over_v.sum() < TICKS and 0.01 * TICKS < over_f.sum()  # the data do exercise the clamps
    m = setup / "clamp.yaml"
    m.write_text(textwrap.dedent(MAP).replace("clamp: [-1, 1], safe: 0}", "clamp: [-0.8, 0.8], safe: 0}")
                 .replace("clamp: [-4, 4]", "clamp: [-0.5, 0.5]"))
    status = io.StringIO()
    r = run_live(load_graph(setup / "g.yaml"), LiveConfig(DBC, m, simulate=setup / "rec.npz", max_ticks=TICKS, status=status,
                                                          stats_path=setup / "stats.json"))
    assert r.error is None and r.watchdog_events == 0
    expected = {"vibration": int(over_v.sum()), "force": int(over_f.sum())}
    assert r.summary["clamped"] == expected
    assert r.summary["peak_limited"] == {"vibration": 0, "force": 0} and r.summary["nonfinite"] == {"vibration": 0, "force": 0}
    doc = json.loads((setup / "stats.json").read_text())
    assert doc["clamped"] == expected and doc["ticks"] == TICKS
    text = status.getvalue()
    assert f"| clamped vibration {expected['vibration']}, force {expected['force']}" in text  # the last status line
    assert f"guard     clamped vibration {expected['vibration']}, force {expected['force']}" in text  # the summary
    assert "peak-limited" not in text and "guard     nonfinite" not in text  # kinds that did not occur are not listed
    busiest = int(over_f.sum(axis=0).max())
    assert r.warnings == [
        f"output 'vibration' was clamped on {expected['vibration']} of {TICKS} ticks ({100 * expected['vibration'] / TICKS:.1f} %, "
        "over the 1 % warning level): the graph commands more than clamp [-0.8, 0.8] in clamp.yaml allows; "
        "check the graph's gains or the clamp",
        f"output 'force' was clamped on {busiest} of {TICKS} ticks ({100 * busiest / TICKS:.1f} %, over the 1 % warning level): "
        "the graph commands more than clamp [-0.5, 0.5] in clamp.yaml allows; check the graph's gains or the clamp"]


def test_clamped_on_exactly_one_percent_of_ticks_is_counted_but_not_warned_about(setup):  # noqa: F811
    """3 of 300 ticks (1 %, not more): a clamp LOW between the third and fourth smallest vibration values."""
    vib = np.sort(_reference(setup, TICKS)["vibration"])
    assert vib[2] < vib[3]
    lo = float(vib[2] + vib[3]) / 2
    m = setup / "one.yaml"
    m.write_text(textwrap.dedent(MAP).replace("clamp: [-1, 1], safe: 0}", f"clamp: [{lo!r}, 1], safe: 0.75}}"))
    r = run_live(load_graph(setup / "g.yaml"), LiveConfig(DBC, m, simulate=setup / "rec.npz", max_ticks=TICKS, status=None))
    assert r.summary["clamped"] == {"vibration": 3, "force": 0}
    assert r.warnings == []


def test_peak_limited_output_is_called_peak_limited_in_status_and_warning(setup):  # noqa: F811
    """One word for one thing: an output limited only by its peak allowance is 'peak-limited', never 'clamped'."""
    m = setup / "peak.yaml"
    m.write_text(textwrap.dedent(MAP).replace("clamp: [-4, 4]", "clamp: [-0.5, 0.5], peak: {limit: 0.5, max_ms: 1000000}"))
    status = io.StringIO()
    r = run_live(load_graph(setup / "g.yaml"), LiveConfig(DBC, m, simulate=setup / "rec.npz", max_ticks=TICKS, status=status))
    assert r.error is None
    peaked = r.summary["peak_limited"]["force"]
    assert peaked > 0.01 * TICKS and r.summary["clamped"]["force"] == 0
    text = status.getvalue()
    assert f"| peak-limited force {peaked}" in text and "clamped force" not in text
    assert f"guard     peak-limited vibration 0, force {peaked}" in text
    assert [w for w in r.warnings if "'force'" in w][0].startswith("output 'force' was peak-limited on ")
    assert not any("'force' was clamped" in w for w in r.warnings)
