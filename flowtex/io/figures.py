"""matplotlib for flowtex's plots: the optional ``plot`` extra loaded on the Agg backend, and PNGs written atomically.

One place for the three things every plot writer did on its own: import matplotlib (absent unless the ``plot``
extra is installed), select the file-only Agg backend, and write the figure through the one writer.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from ..errors import DataError
from .atomic import atomic_output


def agg_pyplot(missing: str | None) -> Any:
    """``matplotlib.pyplot`` on the Agg backend.

    When matplotlib is not installed: raise :class:`DataError` with the message ``missing`` (naming the ``plot``
    extra), or return None when ``missing`` is None (the caller goes on without plots).
    """
    try:
        import matplotlib
    except ImportError:
        if missing is None:
            return None
        raise DataError(missing) from None
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def figure_text(text: str) -> str:
    """``text`` from a file (its name, a signal's name or unit) as a figure can draw it: a lone surrogate, which is what
    Python makes of a file name's bytes that are not UTF-8 (``bad\\xffname.npz``) or of a JSON ``"\\udcff"``, is shown
    as its escape (``\\udcff``); matplotlib's font code refused the string, an internal error."""
    return text.encode("utf-8", "backslashreplace").decode("utf-8")


FONT_PT = 9
"""Smallest font size (points) of flowtex's figures: readable when a figure is printed at its own size."""


def save_png(fig: Any, path: str | Path, dpi: int = 100) -> None:
    """Lay out ``fig``, write it as a PNG to ``path`` through the one writer (no partial file), and close it.

    A figure made with ``layout="constrained"`` is laid out by its engine (titles, colorbars and legends outside the
    axes get their room); any other with ``tight_layout``. The engine runs here, once, and is then removed, so
    ``savefig`` draws the figure once: with an engine it draws it twice (a pass without output that runs the layout,
    then the drawing), and the pass without output computes every tick and text extent again (a quarter of
    ``fit texture --report``'s many-panel figure; the PNG is the same pixel for pixel, tests/io/test_figures.py)."""
    import matplotlib.pyplot as plt

    engine = fig.get_layout_engine()
    if engine is None:
        fig.tight_layout()
    else:
        engine.execute(fig)
        fig.set_layout_engine(None)
    with atomic_output(path) as tmp:
        fig.savefig(tmp, dpi=dpi, format="png")
    plt.close(fig)
