"""Fitting pipelines: recordings -> surfaces (texture model sets, friction, taps, patterns, compliance).

This layer sits above ``flowtex.dsp`` (the math) and ``flowtex.models`` / ``flowtex.io``
(the data objects and file formats); it never reaches into graphs or the live runtime.
"""

from .arma import ArmaFit, fit_arma, fit_arma_auto, select_shared_order

__all__ = ["ArmaFit", "fit_arma", "fit_arma_auto", "select_shared_order"]
