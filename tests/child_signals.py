"""Start a child process with SIGINT as a terminal gives it, and read its signal state when a test fails.

A child inherits an ignored or blocked SIGINT from its parent (an ignored one survives ``exec``, and a Python started
with SIGINT ignored installs no KeyboardInterrupt handler). The tests that interrupt a ``flowtex`` child are about
what flowtex does with a Ctrl-C, so the child starts with SIGINT at its default and unblocked, whatever state the
pytest worker that starts it is in.
"""

from __future__ import annotations

import signal
from pathlib import Path


def sigint_as_a_terminal_gives_it() -> None:
    """``preexec_fn`` for :class:`subprocess.Popen` (POSIX): SIGINT back to its default action and unblocked."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)
    signal.pthread_sigmask(signal.SIG_UNBLOCK, {signal.SIGINT})


def signal_state(pid: int) -> str:
    """The Sig* lines of ``/proc/PID/status`` (pending, blocked, ignored, caught masks), for a failure message."""
    try:
        return " ".join(line.replace("\t", "") for line in Path(f"/proc/{pid}/status").read_text().splitlines()
                        if line.startswith("Sig"))
    except OSError as exc:
        return f"(no status: {exc})"
