"""flowtex bench --plot: the Pareto figure is readable (tests/figure_layout.py) with long knob values on close points."""

from __future__ import annotations

import pytest

from flowtex.bench.sweep import Config
from tests.figure_layout import layout_problems


def test_pareto_figure_numbers_its_points_and_names_them_in_a_key():
    """Knob values written beside close points ran into each other and off the right edge, at 7 pt."""
    pytest.importorskip("matplotlib")
    from flowtex.bench.report import pareto_figure
    from flowtex.io.figures import agg_pyplot

    plt = agg_pyplot("matplotlib")
    configs = [Config({"lookup.order": order, "lookup.every": every}, ns, {"vibration": err}, pareto=front)
               for order, every, ns, err, front in [([19, 17], 1, 1141.0, 0.0, True), ([19, 17], 4, 839.0, 1.04, True),
                                                    ([4, 2], 1, 527.0, 11.37, True), ([4, 2], 4, 500.0, 11.38, True),
                                                    ([10, 8], 1, 900.0, 2.5, False)]]
    fig = pareto_figure(configs, "vibration", "lsd", plt)
    try:
        assert layout_problems(fig) == []
        ax = fig.axes[0]
        assert [t.get_text() for t in ax.texts] == ["1", "2", "3", "4"]  # from the fastest
        key = [t.get_text() for t in fig.legends[0].get_texts()]
        assert key[2:] == ["1: lookup.order=[4, 2], lookup.every=4", "2: lookup.order=[4, 2], lookup.every=1",
                           "3: lookup.order=[19, 17], lookup.every=4", "4: lookup.order=[19, 17], lookup.every=1"]
        assert ax.get_xlabel() == "ns/tick (local)" and ax.get_ylabel() == "vibration error (LSD, dB)"
    finally:
        plt.close(fig)
