"""The one texture graph (flowtex.fit.texture_graph) that fit, datasets and the benchmark render through."""

from __future__ import annotations

import numpy as np

from flowtex.datasets.model_sets import cork_like_model_set
from flowtex.fit.texture_graph import MODEL_OUTPUTS, texture_builder
from flowtex.registry import load_registry


def _path(n: int) -> dict[str, np.ndarray]:
    t = np.arange(n) / 1000.0
    return {"speed": 200.0 + 150.0 * np.sin(2 * np.pi * 0.7 * t), "force": 2.0 + 1.5 * np.sin(2 * np.pi * 0.3 * t)}


def test_the_texture_graph_is_lookup_then_synthesis_and_its_variants_agree():
    ms = cork_like_model_set()
    inputs = _path(1500)
    plain = texture_builder(ms, 1000.0, model_outputs=True).build().run(inputs, seed=3)
    # The lookup's outputs are texture_lookup's own on the same path (the node alone, Node.processor).
    alone = load_registry().types["texture_lookup"].processor(models=ms)(**inputs)
    for port in MODEL_OUTPUTS:
        assert np.array_equal(plain[port].reshape(alone[port].shape), alone[port])
    # A variance factor of 1 is exact, so the scaled variant renders the plain one bit for bit; 0 silences it.
    ones, zeros = np.ones(1500), np.zeros(1500)
    scaled = texture_builder(ms, 1000.0, scaled=True).build()
    assert np.array_equal(scaled.run(inputs | {"power_factor": ones}, seed=3)["accel"], plain["accel"])
    assert not np.any(scaled.run(inputs | {"power_factor": zeros}, seed=3)["accel"])
    assert np.std(plain["accel"]) > 0.0
    # A slower lookup holds its model between runs.
    held = texture_builder(ms, 1000.0, every=4, model_outputs=True).build().run(inputs, seed=3)
    assert np.array_equal(held["gain"][1:4], np.repeat(held["gain"][:1], 3, axis=0))
    assert np.array_equal(held["gain"][::4], plain["gain"][::4])
