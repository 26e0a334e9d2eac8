"""Fitting pipelines: recordings -> surfaces (texture model sets, friction, taps, patterns, compliance).

This layer sits above ``flowtex.dsp`` (the math) and ``flowtex.models`` / ``flowtex.io``
(the data objects and file formats); it renders models through the in-memory graph API
(``flowtex.graph.builder``, :mod:`flowtex.fit.texture_graph`), never through temporary files, and never
reaches into the live runtime.
"""

from .arma import ArmaFit, fit_arma, fit_arma_auto, select_shared_order

__all__ = ["ArmaFit", "fit_arma", "fit_arma_auto", "select_shared_order"]
