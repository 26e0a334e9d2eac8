"""The outcome of a replay (:func:`~flowtex.runtime.replay.replay_session`) and the summary ``flowtex run`` prints."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path


@dataclass
class ReplayReport:
    """Outcome of :func:`replay_session`; ``str(report)`` is :meth:`summary`, what ``flowtex run --input SESSION`` prints.

    Every tick whose live actuator frames differ from the replayed ones is in
    ``mismatched_ticks`` and in exactly one of ``watchdog_ticks`` (a stale sensor),
    ``overrun_ticks`` (the overrun watchdog) or ``unexplained_ticks`` (neither).
    """

    ticks: int
    frames_in: int
    frames_out: int
    exit_block: bool
    """True when the log ends with the exit block of safe values (a clean live exit)."""
    mismatched_ticks: list[int] = field(default_factory=list)
    watchdog_ticks: list[int] = field(default_factory=list)
    """Mismatched ticks at which the replay's input watchdog finds a stale sensor: live sent the safe values."""
    overrun_ticks: list[int] = field(default_factory=list)
    """Mismatched ticks with every sensor fresh at which live sent exactly the safe values: the overrun watchdog
    (a tick that started more than ``overrun_limit_ms`` late, skipped deadlines included, and the ticks after it
    until every sensor had sent a fresh frame). The live run logged each such event; the log of frames cannot
    show the lateness, so the replay recognises them by the safe values."""
    unexplained_ticks: list[int] = field(default_factory=list)
    """Mismatched ticks no watchdog explains: live sent values other than the safe ones. A real difference: was the
    session run with another graph, parameters, ``--seed``, DBC or map?"""
    output_path: Path | None = None
    session_path: Path | None = None
    audio_lines: list[str] = field(default_factory=list)
    """With ``expect_audio``: one line per class of audio frames (:func:`~flowtex.runtime.audio_check.check_audio`)."""
    audio_unexplained: int = 0
    """Audio frames that differ from the live WAV and that the session's audio timeline does not explain."""
    truncated: str | None = None
    """Why the log does not hold the whole session (:class:`~flowtex.io.canlog.SessionFrames`), or None.
    A truncated log has no exit block: its last complete block is replayed as a tick."""
    expected_ticks: float | None = None
    """Ticks the whole session had, from the frames the BLF header counts (None: the log does not say)."""

    @property
    def identical(self) -> bool:
        return not self.mismatched_ticks

    def summary(self) -> str:
        """A few lines for the terminal: what was replayed, which ticks match, and why the others differ."""
        source = f" of {self.session_path}" if self.session_path is not None else ""
        ending = "ends with the exit block of safe values" if self.exit_block else "has no exit block (was the session killed?)"
        if self.truncated:
            ending = f"is TRUNCATED: {self.truncated}"
        lines = [f"replayed {self.ticks} ticks{source} ({self.frames_in} frames received, {self.frames_out} sent live; the log {ending})"]
        if self.truncated:
            said = (f"expected {_expected(self.expected_ticks)} ticks, found {self.ticks}" if self.expected_ticks is not None
                    else f"found {self.ticks} ticks; the log does not say how many the session had")
            lines.append(f"{said}: the rest of the session is not in the log, so nothing can be said about it")
        same = self.ticks - len(self.mismatched_ticks)
        lines.append(f"{_count(same)}: actuator frames equal to the live ones byte for byte"
                     + (" (all of them)" if self.identical and self.ticks and not self.truncated else ""))
        if self.watchdog_ticks:
            lines.append(f"{_count(len(self.watchdog_ticks))} ({_ranges(self.watchdog_ticks)}): live sent the safe values because a sensor "
                         "was stale (input watchdog, recomputed by the replay)")
        if self.overrun_ticks:
            lines.append(f"{_count(len(self.overrun_ticks))} ({_ranges(self.overrun_ticks)}): live sent the safe values with every sensor "
                         "fresh: the overrun watchdog (a tick started more than overrun_limit_ms late, or the ticks after it until "
                         "every sensor sent a fresh frame; the live run logged it)")
        if self.unexplained_ticks:
            lines.append(f"{_count(len(self.unexplained_ticks))} ({_ranges(self.unexplained_ticks)}): DIFFER from the live frames and no "
                         "watchdog explains it: was the session run with another graph, parameters, --seed, DBC or map?")
        lines.extend(self.audio_lines)
        if self.output_path is not None:
            lines.append(f"wrote {self.output_path}")
        return "\n".join(lines)

    __str__ = summary


def _expected(ticks: float) -> str:
    """``2000``, or ``about 1999`` when the frames per tick were not constant."""
    n = round(ticks)
    return f"{n}" if abs(ticks - n) < 1e-9 else f"about {n}"


def expected_ticks(expected_frames: int, ticks: int, received: int, block: int) -> float | None:
    """Ticks a whole session had, from the frame count of its log's header: each tick is its received frames
    and one block of ``block`` actuator frames, plus one exit block; received frames a tick as in the ``ticks`` found,
    which received ``received`` frames in all."""
    if not ticks:
        return None
    per_tick = block + received / ticks
    return max(float(ticks), (expected_frames - block) / per_tick)


def _count(n: int) -> str:
    return f"{n} tick" + ("" if n == 1 else "s")


def _ranges(ticks: list[int], n: int = 6) -> str:
    """``[3, 4, 5, 9]`` -> ``"3-5, 9"`` (the first ``n`` runs, then ``...``)."""
    runs: list[list[int]] = []
    for t in ticks:
        if runs and t == runs[-1][1] + 1:
            runs[-1][1] = t
        else:
            runs.append([t, t])
    text = ", ".join(f"{a}-{b}" if b > a else f"{a}" for a, b in runs[:n])
    return text + (", ..." if len(runs) > n else "")
