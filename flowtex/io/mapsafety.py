"""Checks of a map's actuator messages as a whole: what the frames carry besides the bound signals, and who sends them.

Every actuator frame (safe and exit frames included) carries every signal of its message. Signals the map does not
bind are sent as physical 0 (:mod:`flowtex.io.codec`, rule 4), so that 0 must survive the DBC exactly as a bound
output's safe value must (:func:`flowtex.io.dbcrange.check_value`): a DBC ``Enable [1|1]`` would otherwise send
"enabled" in every frame meant to make the device safe. And the host must not transmit a message the DBC says the
device itself transmits (its ``BO_`` line's transmitter): two senders on one CAN ID.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

from cantools.database.can import Database

from .dbcrange import check_value, sendable_range

Report = Callable[[tuple[int, int] | None, str], None]


def check_unbound_signals(db: Database, outputs: Sequence, add: Report) -> None:
    """Refuse an actuator message whose unbound signal would not arrive as physical 0 (the value it is sent as).

    ``outputs``: the map's output bindings (``signals`` as ``(message, signal)``, ``loc``, ``name``).
    """
    bound = {k for b in outputs for k in b.signals}
    seen: set[str] = set()
    for b in outputs:
        for m in dict.fromkeys(m for m, _ in b.signals):
            if m in seen:
                continue
            seen.add(m)
            msg = db.get_message_by_name(m)
            for sig in msg.signals:
                if (m, sig.name) in bound:
                    continue
                got = check_value(msg, sig, 0.0)
                if got is None:
                    continue
                lo, hi = sendable_range(sig)
                unit = f" {sig.unit}" if sig.unit else ""
                add((b.loc.line, b.loc.column),
                    f"output {b.name!r} sends message {m!r}, whose signal {sig.name!r} no output binds: it is sent as 0, "
                    f"which would arrive as {got:g}{unit} in every frame (the safe and exit frames too), because the DBC "
                    f"range of {m}.{sig.name} is [{lo:g}, {hi:g}]{unit}; bind {m}.{sig.name} to a graph output with a safe "
                    "value inside that range, or fix the DBC")


def check_transmitters(db: Database, inputs: Sequence, outputs: Sequence, add: Report) -> None:
    """Refuse an output message transmitted (per the DBC) by a node that transmits the map's sensor messages.

    The sensor messages' transmitters are the device; the host sending one of the device's own messages puts two
    senders on one CAN ID. Messages whose DBC names no transmitter are not judged.
    """
    device = {s: m for b in inputs for m, _ in b.signals for s in db.get_message_by_name(m).senders}
    for b in outputs:
        for m in dict.fromkeys(m for m, _ in b.signals):
            msg = db.get_message_by_name(m)
            both = [s for s in msg.senders if s in device]
            if both:
                add((b.loc.line, b.loc.column),
                    f"output {b.name!r} writes message {m!r} (CAN ID {msg.frame_id:#x}), which the DBC says {both[0]} "
                    f"transmits, as it does {device[both[0]]!r} that this map reads: the host would send on the device's own "
                    f"ID; bind the output to a message the host transmits")
