"""Nodes take a loaded model set where they take its file: the same output bit for bit, nothing written to disk."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from flowtex.datasets.model_sets import cork_like_model_set
from flowtex.errors import GraphError
from flowtex.graph.builder import GraphBuilder
from flowtex.io.modelset import load_model_set, save_model_set
from flowtex.registry import load_registry


def texture(models, rate=1000.0) -> GraphBuilder:
    return (GraphBuilder("texture", rate=rate, seed=1)
            .input("speed", unit="mm/s").input("force", unit="N")
            .node("lookup", "texture_lookup", models=models).node("synth", "arma_synth")
            .edge("speed -> lookup.speed").edge("force -> lookup.force")
            .edge("lookup.ar -> synth.ar").edge("lookup.ma -> synth.ma")
            .edge("lookup.gain -> synth.gain").edge("lookup.variance -> synth.variance")
            .output("accel", "synth.y"))


def test_texture_lookup_takes_the_loaded_set_as_its_file(tmp_path):
    ms = cork_like_model_set()
    path = save_model_set(ms, tmp_path / "cork.json")
    t = np.arange(2000) / 1000.0
    inputs = {"speed": 200.0 + 150.0 * np.sin(2 * np.pi * 0.7 * t), "force": 2.0 + 1.5 * np.sin(2 * np.pi * 0.3 * t)}
    from_file = texture(str(path)).build(tier="dispatch").run(inputs, seed=5)["accel"]
    # The object as the file reads back, and the object as made: a JSON model set keeps every float exactly.
    for obj in (load_model_set(path), ms):
        from_object = texture(obj).build(tier="dispatch").run(inputs, seed=5)["accel"]
        assert np.array_equal(from_object, from_file)
    assert np.std(from_file) > 0.0


def test_texture_lookup_object_at_another_rate_is_refused_by_name():
    ms = dataclasses.replace(cork_like_model_set(), sample_rate=2000.0)
    with pytest.raises(GraphError, match=r"GraphBuilder.node\('lookup', 'texture_lookup', models=...\): .*the model set "
                                         r"'cork-like' given in memory is for 2000 Hz but the graph runs at 1000 Hz"):
        texture(ms).resolve()


def test_friction_takes_the_loaded_set():
    ms = dataclasses.replace(cork_like_model_set(), mu=0.37)
    coulomb = load_registry().get("coulomb_friction")
    v = np.column_stack([np.linspace(-50, 50, 400), np.linspace(20, -20, 400), np.zeros(400)])
    f = np.linspace(0.0, 3.0, 400)
    want = coulomb.processor(mu=0.37)(velocity=v, normal_force=f)["force"]
    got = coulomb.processor(models=ms)(velocity=v, normal_force=f)["force"]
    assert np.array_equal(got, want)
    assert np.any(want != 0.0)
