"""Switching the active surface mid-stroke: no burst, no stale friction, equal to the new surface alone after the fade."""

from __future__ import annotations

import re

import numpy as np
import pytest

from flowtex.cli import main
from flowtex.datasets.study import write_study_scene
from flowtex.dsp.switch import crossfade_block, switch_params
from flowtex.graph.compiled import load_graph
from flowtex.scene.build import plan_to_graph
from tests.conftest import REPO


def test_crossfade_is_a_convex_ramp_and_nan_holds():
    n = 12
    index = np.zeros((n, 1))
    index[3:] = 1.0
    index[8] = np.nan
    a = np.full((n, 2), 2.0)
    b = np.full((n, 2), -4.0)
    y = np.empty((n, 2))
    s = np.zeros(2)
    crossfade_block(switch_params(1, 4.0), s, index, a, b, y)
    w = np.r_[0, 0, 0, 0.25, 0.5, 0.75, 1, 1, 1, 1, 1, 1]  # 4-tick ramp starting on the switching tick; NaN keeps b
    np.testing.assert_allclose(y[:, 0], (1 - w) * 2.0 + w * -4.0, rtol=0, atol=1e-15)


def test_a_chain_of_switches_crossfades_exactly_the_two_surfaces_involved():
    # 4 surfaces chosen by a chain of 3 switches, as 'scene plan' writes it. Every change (up, down, adjacent or not)
    # must mix only the old and the new surface: y = (1 - lam) s_old + lam s_new, lam = 1/4, 2/4, 3/4, 1
    # (powers of two: exact in floating point). Surface values 1, 10, 100, 1000 make any third surface visible.
    fade = 4
    sequence = [0, 2, 1, 3, 0, 3, 2, 0, 1]
    seg = 8
    index = np.repeat(np.array(sequence, dtype=float), seg)[:, None]
    index[seg * 3 + 6] = np.nan  # NaN and a negative index keep the current surface
    index[seg * 5 + 6] = -1.0
    n = index.shape[0]
    sources = [np.full((n, 1), 10.0 ** i) for i in range(4)]
    y = sources[0]
    for i in range(1, 4):
        out = np.empty((n, 1))
        crossfade_block(switch_params(i, float(fade)), np.zeros(2), index, y, sources[i], out)
        y = out
    expected = np.empty(n)
    for m, k in enumerate(sequence):
        old = sequence[m - 1] if m else 0
        lam = np.minimum(1.0, np.arange(1, seg + 1) / fade) if k != old else np.ones(seg)
        expected[m * seg:(m + 1) * seg] = (1 - lam) * 10.0 ** old + lam * 10.0 ** k
    np.testing.assert_array_equal(y[:, 0], expected)


@pytest.fixture(scope="module")
def switching(tmp_path_factory):
    folder = tmp_path_factory.mktemp("switch")
    scene = write_study_scene(folder, ("Whiteboard", "EPDM_Foam"))
    scene.write_text(re.sub(r", taps: \w+\.json", "", scene.read_text()))  # texture and friction only: a smaller graph to compile
    rec = dict(np.load(REPO / "graphs/data/exploration.npz"))
    sl = slice(5500, 7500)  # a stroke in contact (1.5 N, ~180 mm/s around tick 6000)
    inputs = {k: rec[k][sl] for k in ("position", "normal_force", "normal")}
    surface = np.zeros(2000)  # surfaces in file order: 0 EPDM_Foam, 1 Whiteboard
    surface[:500] = 1.0  # Whiteboard -> EPDM Foam at tick 500, mid-stroke
    np.savez(folder / "rec.npz", surface=surface, **inputs)
    out = folder / "out.npz"
    assert main(["scene", "run", str(scene), "--input", str(folder / "rec.npz"), "-o", str(out)]) == 0
    # reference: the same planned graph (one compilation) with EPDM Foam active all along
    plan_to_graph(scene, folder / "graph.yaml")
    alone = load_graph(folder / "graph.yaml").run({**inputs, "surface": np.zeros(2000)})
    return dict(np.load(out)), alone, inputs


def test_after_the_fade_the_scene_equals_the_new_surface_alone(switching):
    out, alone, inputs = switching
    assert np.all(inputs["normal_force"][450:560] > 0.5)  # really mid-stroke
    fade = 10  # select.fade default 0.01 s at 1 kHz
    # the friction spring of EPDM Foam ran all along: its force right after the fade is the one of EPDM alone
    # (same nodes, same inputs, same noise seed by node name: equal to rounding)
    np.testing.assert_allclose(out["friction_force"][500 + fade:], alone["friction_force"][500 + fade:], rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(out["vibration"][500 + fade:], alone["vibration"][500 + fade:], rtol=1e-12, atol=1e-12)
    assert np.all(out["friction_force"][20:500] == 0.0)  # Whiteboard renders no friction (mu 0.17)
    assert np.abs(alone["friction_force"][500]).max() > 0.5  # EPDM's spring was already loaded at the switch: not stale


def test_no_burst_at_the_switch(switching):
    out, alone, _ = switching
    window = slice(490, 530)
    # the crossfade is convex: never above the larger of the two surfaces' own signals (Whiteboard's friction
    # and texture are 0), element by element
    for name in ("friction_force", "vibration"):
        assert np.all(np.abs(out[name][window]) <= np.abs(alone[name][window]) + 1e-12)
    step = np.abs(np.diff(out["friction_force"][window], axis=0)).max()
    jump = np.abs(alone["friction_force"][500]).max()
    assert step <= jump / 10 + 0.05  # 10-tick ramp: each tick moves at most a tenth of the jump (+ the force's own change)
