"""Layout checks of a matplotlib figure, measured on the figure drawn by Agg: what a reader putting it in a paper sees.

``layout_problems(fig)`` lists (one line each) titles that cover an axes, axes whose labels run into another's,
texts of a panel that run into each other, legends over data or over another panel, text outside the figure, and
text smaller than :data:`MIN_FONT_PT`.
"""

from __future__ import annotations

from typing import Any

MIN_FONT_PT = 8.0
"""The smallest text readable in print at the figure's own size: journals ask for 8 pt at least (IEEE: 8-10 pt)."""

SLACK_PX = 1.0
"""Boxes that touch by less than a pixel do not overlap (rounding of the renderer's extents)."""


def _overlap(a: Any, b: Any) -> bool:
    return min(a.x1, b.x1) - max(a.x0, b.x0) > SLACK_PX and min(a.y1, b.y1) - max(a.y0, b.y0) > SLACK_PX


def _name(ax: Any) -> str:
    label = ax.get_ylabel().replace("\n", " ") or ax.get_title() or ax.get_label() or "?"
    return f"axes {label!r}"


def layout_problems(fig: Any) -> list[str]:
    """What is wrong with the layout of ``fig`` (after drawing it, which runs its layout engine), or []."""
    from matplotlib.text import Text

    fig.canvas.draw()
    r = fig.canvas.get_renderer()
    axes = [ax for ax in fig.axes if ax.get_visible() and ax.axison]
    frames = {ax: ax.get_window_extent(r) for ax in axes}
    tight = {ax: ax.get_tightbbox(r) for ax in axes}
    problems = []
    sup = getattr(fig, "_suptitle", None)  # Figure.get_suptitle() is matplotlib >= 3.8; the plot extra allows 3.7
    if sup is not None and sup.get_text():
        box = sup.get_window_extent(r)
        problems += [f"the title {sup.get_text()!r} overlaps {_name(ax)}" for ax in axes if _overlap(box, tight[ax])]
    for ax in axes:
        for title in (ax.title, ax._left_title, ax._right_title):
            if title.get_text():
                box = title.get_window_extent(r)
                problems += [f"the title {title.get_text()!r} of {_name(ax)} overlaps {_name(o)}" for o in axes
                             if _overlap(box, frames[o])]
    for i, a in enumerate(axes):  # each panel's tick labels, axis labels and title stay clear of the others
        for b in axes[i + 1:]:
            if _overlap(tight[a], tight[b]) and not (_overlap(frames[a], frames[b])):
                problems.append(f"{_name(a)} and {_name(b)} overlap (labels or titles)")
    for ax in axes:  # annotations and texts of one panel do not run into each other
        texts = [(t.get_text(), t.get_window_extent(r)) for t in ax.texts if t.get_visible() and t.get_text()]
        for i, (a, box) in enumerate(texts):
            problems += [f"the texts {a!r} and {b!r} of {_name(ax)} overlap" for b, other in texts[i + 1:] if _overlap(box, other)]
    legends = [(ax.get_legend(), ax) for ax in fig.axes if ax.get_legend() is not None] + [(leg, None) for leg in fig.legends]
    for leg, owner in legends:
        box = leg.get_window_extent(r)
        for ax in fig.axes:
            if ax is not owner and ax in frames and _overlap(box, frames[ax]):
                problems.append(f"a legend of {_name(owner) if owner else 'the figure'} covers {_name(ax)}")
            for line in ax.get_lines():
                if line.get_visible() and line.get_path().transformed(line.get_transform()).intersects_bbox(box, filled=False):
                    problems.append(f"a legend covers the line {line.get_label()!r} of {_name(ax)}")
            for coll in ax.collections:
                offsets = coll.get_offsets()
                if len(offsets) and coll.get_offset_transform() is not None:
                    pts = coll.get_offset_transform().transform(offsets)
                    inside = ((pts[:, 0] > box.x0) & (pts[:, 0] < box.x1) & (pts[:, 1] > box.y0) & (pts[:, 1] < box.y1))
                    if inside.any():
                        problems.append(f"a legend covers {int(inside.sum())} point(s) of {_name(ax)}")
            for patch in ax.patches:
                if _overlap(box, patch.get_window_extent(r)):
                    problems.append(f"a legend covers a bar of {_name(ax)}")
    page = fig.bbox
    boxes = [(f"{_name(ax)} (with its labels)", tight[ax]) for ax in axes]
    boxes += [(f"the text {t.get_text()!r}", t.get_window_extent(r)) for t in fig.texts if t.get_text()]
    boxes += [("a legend", leg.get_window_extent(r)) for leg, _ in legends]
    boxes += [(f"the text {t.get_text()!r} of {_name(ax)}", t.get_window_extent(r)) for ax in axes for t in ax.texts if t.get_text()]
    for what, box in boxes:
        if box.x0 < page.x0 - SLACK_PX or box.y0 < page.y0 - SLACK_PX or box.x1 > page.x1 + SLACK_PX or box.y1 > page.y1 + SLACK_PX:
            problems.append(f"{what} runs off the figure")
    for t in fig.findobj(Text):
        if t.get_visible() and t.get_text().strip() and t.get_fontsize() < MIN_FONT_PT:
            problems.append(f"the text {t.get_text()!r} is {t.get_fontsize():g} pt, below {MIN_FONT_PT:g} pt")
    return sorted(set(problems))
