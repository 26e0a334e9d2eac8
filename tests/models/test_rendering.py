"""A model set's rendering rule: stated in the file, carried through resampling, resolved in one place for every caller."""

from __future__ import annotations

import json

import numpy as np
import pytest

from flowtex.cli import main
from flowtex.datasets.model_sets import hard_model_set, synthetic_model_set
from flowtex.dsp.arma import arma_output_variance
from flowtex.errors import DataError
from flowtex.fit.quality import models_at
from flowtex.graph.compiled import load_graph
from flowtex.io.hatt import write_hatt_xml
from flowtex.io.modelset import load_model_set, save_model_set
from flowtex.models.rendering import FITTED_RULE, HATT_RULE, RenderRule, resolve_rule
from flowtex.scene.salience import mean_texture_power
from tests.nodes.test_texture_lookup import graph_file


def small_set(rule=None):
    ms = synthetic_model_set([40.0, 120.0, 200.0], [0.5, 1.5, 2.5], 6, 4)
    ms.rule = rule
    return ms


def test_resolution_order_node_then_file_then_hatt():
    plain, fitted = small_set(), small_set(FITTED_RULE)
    assert resolve_rule(plain) == HATT_RULE == RenderRule("variance", "fade")
    assert resolve_rule(fitted) == FITTED_RULE
    assert resolve_rule(fitted, outside="fade") == RenderRule(FITTED_RULE.interpolation, "fade")
    assert resolve_rule(plain, interpolation="log_power") == RenderRule("log_power", "fade")
    with pytest.raises(ValueError, match="outside must be one of fade, hold, trend"):
        resolve_rule(plain, outside="louder")


def test_native_file_states_the_rule_and_reads_it_back(tmp_path):
    path = save_model_set(small_set(RenderRule("log_power", "hold")), tmp_path / "s.json")
    doc = json.loads(path.read_text())
    assert (doc["interpolation"], doc["outside"]) == ("log_power", "hold")
    assert load_model_set(path).rule == RenderRule("log_power", "hold")
    plain = save_model_set(small_set(), tmp_path / "plain.json")
    assert "interpolation" not in json.loads(plain.read_text()) and load_model_set(plain).rule is None
    xml = write_hatt_xml(small_set(FITTED_RULE), tmp_path / "Models_S.xml")     # HaTT's format states no rule
    assert load_model_set(xml).rule is None


def test_a_file_stating_half_a_rule_gets_hatts_other_half(tmp_path):
    path = save_model_set(small_set(), tmp_path / "s.json")
    doc = json.loads(path.read_text())
    doc["outside"] = "trend"
    path.write_text(json.dumps(doc))
    assert load_model_set(path).rule == RenderRule("variance", "trend")


@pytest.mark.parametrize("key, value, hint", [("outside", "trends", "did you mean 'trend'"),
                                              ("interpolation", "powr", "did you mean 'power'"),
                                              ("interpolation", 3, "expected one of variance, power, log_power")])
def test_bad_rule_in_a_file_is_named(tmp_path, key, value, hint):
    path = save_model_set(small_set(), tmp_path / "bad set.json")
    doc = json.loads(path.read_text())
    doc[key] = value
    path.write_text(json.dumps(doc))
    with pytest.raises(DataError) as err:
        load_model_set(path)
    msg = str(err.value)
    assert "bad set.json" in msg and f"key {key!r}" in msg and hint in msg


def test_models_resample_carries_the_rule_over(tmp_path, capsys):
    src = save_model_set(small_set(RenderRule("power", "trend")), tmp_path / "in.json")
    out = tmp_path / "out.json"
    assert main(["models", "resample", str(src), "--rate", "2000", "-o", str(out), "--allow-misses"]) == 0
    assert load_model_set(out).rule == RenderRule("power", "trend")
    plain = save_model_set(small_set(), tmp_path / "plain.json")
    assert main(["models", "resample", str(plain), "--rate", "2000", "-o", str(tmp_path / "p2.json"), "--allow-misses"]) == 0
    assert load_model_set(tmp_path / "p2.json").rule is None


def _lookup_graph(tmp_path, ms, **params):
    path = save_model_set(ms, tmp_path / "s.json")
    extra = "".join(f", {k}: {v}" for k, v in params.items())
    return load_graph(graph_file(tmp_path / f"g{len(params)}", str(path), outside=None, extra=extra))


def test_node_renders_the_files_rule_and_its_parameters_override(tmp_path):
    ms = hard_model_set(8, 6)
    ms.rule = RenderRule("power", "trend")
    speed = np.array([0.0, 30.0, 100.0, 180.0, 400.0, 150.0])
    force = np.array([1.0, 0.2, 1.0, 2.0, 3.0, 0.0])
    own = _lookup_graph(tmp_path, ms).run({"speed": speed, "force": force})
    over = _lookup_graph(tmp_path, ms, outside="fade", interpolation="variance").run({"speed": speed, "force": force})
    want_own = models_at(ms, speed, force)
    want_hatt = models_at(ms, speed, force, outside="fade", interpolation="variance")
    assert [r[3] for r in want_own] != [r[3] for r in want_hatt]                # the two rules differ here
    assert np.array_equal(own["variance"][:, 0] if own["variance"].ndim > 1 else own["variance"], [r[3] for r in want_own])
    assert np.array_equal(over["variance"] if over["variance"].ndim == 1 else over["variance"][:, 0], [r[3] for r in want_hatt])


def test_scene_salience_uses_the_sets_rule():
    ms = hard_model_set(8, 6)
    ms.rule = RenderRule("power", "trend")
    speeds, forces = np.linspace(5.0, 300.0, 9), np.linspace(0.1, 3.0, 9)
    want = []
    for s in speeds:
        for f in forces:
            a, c, g, v = models_at(ms, [s], [f])[0]
            want.append(arma_output_variance(a, c, g, v) if v > 0 else 0.0)
    got = mean_texture_power(ms, (5.0, 300.0), (0.1, 3.0))
    assert got == pytest.approx(np.mean(want), rel=1e-12)
    ms.rule = None
    hatt = mean_texture_power(ms, (5.0, 300.0), (0.1, 3.0))
    assert abs(got / hatt - 1) > 1e-3                                             # the rule matters to the figure


def test_planner_weighs_and_plans_with_the_sets_rule(tmp_path):
    # the planner's texture salience is the mean power under the set's own rule, and the planned graph's lookup
    # gets only the file, so it renders that same rule
    import yaml

    ms = hard_model_set(8, 6)
    ms.rule = RenderRule("power", "trend")
    models = save_model_set(ms, tmp_path / "fitted.json")
    (tmp_path / "scene.yaml").write_text(
        "flowtex: 1\nname: one\nrate: 1000\ntrajectory: {speed: [5, 300], force: [0.1, 3.0]}\n"
        f"surfaces:\n  s:\n    models: {models.name}\n    keep: [texture]\n    drop: [friction]\n")
    out, plan = tmp_path / "planned.yaml", tmp_path / "plan.json"
    assert main(["scene", "plan", str(tmp_path / "scene.yaml"), "-o", str(out), "--json", str(plan)]) == 0
    salience = json.loads(plan.read_text())["s"]["texture"]["salience"]
    assert salience == pytest.approx(mean_texture_power(ms, (5.0, 300.0), (0.1, 3.0)), rel=1e-12)
    nodes = yaml.safe_load(out.read_text())["nodes"]
    lookups = [n for n in nodes.values() if n["type"] == "texture_lookup"]
    assert len(lookups) == 1 and set(lookups[0]["params"]) == {"models"}
