"""A map binding with scale 1 converts no unit, so its DBC signal's unit must be the graph port's.

flowtex converts no unit (:func:`~flowtex.io.recording_rules.check_stated_unit` refuses a recording whose stated unit
differs from what it feeds); a map binding is the same seam. A DBC speed signal in m/s bound with ``scale: 1`` to a
graph input in mm/s renders 1000x too slow, and a graph output in N bound to an actuator signal in kN commands 1000x
the force the graph meant (the map's clamp is in graph units, so it does not catch it). :func:`check_binding_units`
refuses such a binding when the two units are one quantity on two scales (a factor of
:data:`~flowtex.io.recording_rules.UNIT_FACTORS`), naming the ``scale`` that converts, and warns when the units differ
otherwise (DBC unit texts are free-form: ``Amp`` for ``A`` is likely fine, ``deg`` for ``rad`` is not). A binding
with any other scale is the user's conversion and is not checked (:func:`keeps_unit`).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from typing import Any

from cantools.database.can import Database

from ..errors import Location
from .recording_rules import NO_UNIT, plain_unit, unit_factor

__all__ = ["check_binding_units", "keeps_unit"]

_UNIT_CHARS = 40
"""A DBC unit text is shown up to this many characters."""


def keeps_unit(binding: Any, component: int) -> bool:
    """Whether a binding component carries its DBC signal's unit into the graph unchanged: its map ``scale`` is 1.

    The scale is the map's unit conversion (DBC mm to graph m is ``scale: 0.001``); an ``offset`` moves the zero in
    the same unit (a sensor's tare), so a component with scale 1 and any offset must have its DBC signal's unit on
    the graph side. The device map's unit check and ``flowtex simulate-device``'s recording check both ask this.
    """
    return float(binding.scale[component]) == 1.0


def check_binding_units(db: Database, inputs: Sequence, outputs: Sequence, input_units: Mapping[str, str],
                        output_units: Mapping[str, str], add: Callable[[Location, str], None]) -> list[str]:
    """Compare each component that keeps its unit (map ``scale`` 1, any ``offset``) of the input and output bindings (``Binding``
    of :mod:`flowtex.io.canmap`) with its graph port's unit (``input_units``/``output_units``: port name -> unit).

    Units one factor apart are reported through ``add(location, message)`` at the binding's line with the scale
    that converts (inputs: graph = physical * scale + offset; outputs: physical = graph * scale + offset); other
    differing units are returned as warning lines. A unit that states nothing on either side passes.
    """
    warnings: list[str] = []
    for section, bindings, units in (("inputs", inputs, input_units), ("outputs", outputs, output_units)):
        for b in bindings:
            graph_unit = plain_unit(str(units.get(b.name, "")))
            for j, (m, s) in enumerate(b.signals):
                if not keeps_unit(b, j):
                    continue
                dbc_unit = plain_unit(str(db.get_message_by_name(m).get_signal_by_name(s).unit or ""))
                if dbc_unit in NO_UNIT or graph_unit in NO_UNIT or dbc_unit == graph_unit:
                    continue
                shown = dbc_unit[:_UNIT_CHARS]  # free text from the DBC; the command line escapes control characters
                what = f"{section}.{b.name}" + (f"[{j}]" if b.width > 1 else "")
                # inputs: graph = physical * scale, so scale converts DBC into graph units; outputs the other way
                factor = unit_factor(dbc_unit, graph_unit) if section == "inputs" else unit_factor(graph_unit, dbc_unit)
                flow = (f"DBC {shown} -> graph {graph_unit}" if section == "inputs"
                        else f"graph {graph_unit} -> DBC {shown}")
                if factor is not None:
                    add(b.loc, f"{what} binds {m}.{s} in {shown} to a graph {section[:-1]} in {graph_unit} with scale 1; "
                        f"flowtex converts no unit: set scale: {factor:g} for {what} ({flow})")
                else:
                    warnings.append(f"{b.loc}: {what} binds {m}.{s} in {shown} to a graph "
                                    f"{section[:-1]} in {graph_unit} with scale 1; flowtex knows no factor between the two: "
                                    f"if they differ, set the scale that converts ({flow}), else write the DBC unit as {graph_unit}")
    return warnings
