"""The graph a texture model set renders through: ``texture_lookup`` + ``arma_synth`` along (speed, force).

The one description of it: fit renders a surface with it (:func:`flowtex.fit.compare.render_along`),
:mod:`flowtex.datasets` makes ground-truth recordings with it (plain and with a wandering loudness) and
benchmarks/bench_texture.py times it, so a fitted surface is judged by exactly the nodes that render it. It is
built in Python (:func:`texture_builder`, flowtex.graph.builder) with the loaded model set: nothing is written to
disk.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from ..graph.builder import GraphBuilder
    from ..models.texture import TextureModelSet

MODEL_OUTPUTS = ("ar", "ma", "gain", "variance")
"""``texture_lookup``'s outputs, which ``model_outputs=True`` makes graph outputs too (the per-tick model)."""


def texture_builder(models: TextureModelSet | str | Path, rate: float, lookup: Mapping[str, Any] | None = None,
                    every: int = 1, scaled: bool = False, model_outputs: bool = False) -> GraphBuilder:
    """Vibration (output ``accel``, m/s^2) of a model set along the inputs ``speed`` (mm/s) and ``force`` (N).

    ``models`` a loaded set or its file; ``rate`` in Hz; ``lookup`` more ``texture_lookup`` parameters, run every
    ``every`` ticks. ``scaled`` adds the input ``power_factor`` (>= 0) multiplying the excitation variance tick by
    tick (flowtex.datasets.resonant); ``model_outputs`` outputs the lookup's model too (:data:`MODEL_OUTPUTS`).
    Seed 1; node names ``lookup``, ``scale``, ``synth`` (the synthesis's noise is seeded by its name).
    """
    from ..graph.builder import GraphBuilder

    g = (GraphBuilder("dataset-scaled-texture" if scaled else "dataset-texture", rate=rate, seed=1)
         .input("speed", unit="mm/s").input("force", unit="N"))
    if scaled:
        g.input("power_factor")
    g.node("lookup", "texture_lookup", every=every, models=models, **dict(lookup or {}))
    if scaled:
        g.node("scale", "multiply")
    g.node("synth", "arma_synth")
    g.edge("speed -> lookup.speed").edge("force -> lookup.force")
    g.edge("lookup.ar -> synth.ar").edge("lookup.ma -> synth.ma").edge("lookup.gain -> synth.gain")
    if scaled:
        g.edge("lookup.variance -> scale.a").edge("power_factor -> scale.b").edge("scale.y -> synth.variance")
    else:
        g.edge("lookup.variance -> synth.variance")
    g.output("accel", "synth.y")
    for port in MODEL_OUTPUTS if model_outputs else ():
        g.output(port, f"lookup.{port}")
    return g

