"""A Ctrl-C dropped inside a C callback is raised again, and an error it caused is reported as the interrupt.

numba hands LLVM's object code to Python through a ctypes callback; a KeyboardInterrupt raised there is dropped by
ctypes ("Exception ignored"). Before flowtex.interrupts, a cold ``flowtex live`` interrupted at that moment either
ran its whole session or ended with "internal error: RuntimeError: no compiled object yet" (exit 2). Here a ctypes
callback that raises KeyboardInterrupt stands for that moment, deterministically. The last two tests: any caller of
flowtex (a notebook, a script) gets the same for Ctrl-C during numba's compiles (flowtex.interrupts.guard_compiles).
"""

from __future__ import annotations

import argparse
import ctypes
import hashlib
import importlib
import json
import os
import signal
import sys
import time
from collections.abc import Callable

import pytest

from flowtex.interrupts import RESEND_AFTER_S, interrupt_was_lost, interrupts_kept, keeping_interrupts

cli_main = importlib.import_module("flowtex.cli.main")  # the module (flowtex.cli re-exports its main function)
CALLBACK = ctypes.CFUNCTYPE(None)


def _interrupted_in_callback() -> None:
    def body() -> None:
        raise KeyboardInterrupt

    CALLBACK(body)()  # ctypes drops the exception: this call returns normally


@pytest.fixture
def sigint_raises(monkeypatch):
    """SIGINT raises KeyboardInterrupt here (as Python's default handler does), counted; restored afterwards."""
    received: list[int] = []

    def handler(signum, frame):
        received.append(signum)
        raise KeyboardInterrupt

    old = signal.signal(signal.SIGINT, handler)
    yield received
    signal.signal(signal.SIGINT, old)


def test_an_interrupt_dropped_in_a_callback_is_raised_again(sigint_raises, capsys):
    deadline = time.monotonic() + 10.0  # the signal comes back after RESEND_AFTER_S; 10 s only bounds a failure
    with pytest.raises(KeyboardInterrupt), interrupts_kept(cli_main._signal_of):
        _interrupted_in_callback()
        assert interrupt_was_lost()
        while time.monotonic() < deadline:
            time.sleep(RESEND_AFTER_S / 5)
    assert sigint_raises == [signal.SIGINT]
    assert "Exception ignored" not in capsys.readouterr().err


def test_other_dropped_exceptions_are_still_reported(monkeypatch):
    def body() -> None:
        raise ValueError("a bug in a callback")

    reported: list[BaseException] = []
    def recorder(unraisable) -> None:
        reported.append(unraisable.exc_value)

    monkeypatch.setattr(sys, "unraisablehook", recorder)
    with interrupts_kept(cli_main._signal_of):
        CALLBACK(body)()
    assert not interrupt_was_lost()
    assert [str(e) for e in reported] == ["a bug in a callback"]
    assert sys.unraisablehook is recorder  # the hook from before the block is back


def test_an_error_caused_by_a_dropped_interrupt_exits_as_interrupted(monkeypatch, sigint_raises, capsys):
    def verb(args: argparse.Namespace) -> int:
        _interrupted_in_callback()
        raise RuntimeError("no compiled object yet")  # what numba raised next in a cold `flowtex live`

    parser = argparse.ArgumentParser()
    parser.set_defaults(func=verb)
    monkeypatch.setattr(cli_main, "build_parser", lambda command: parser)
    assert cli_main.main([]) == cli_main.EXIT_INTERRUPTED
    assert capsys.readouterr().err.strip().splitlines() == ["interrupted"]
    with pytest.raises(KeyboardInterrupt):  # the signal raised again arrives here, after main returned
        time.sleep(10.0)
    assert sigint_raises == [signal.SIGINT]


def test_a_dropped_sigterm_is_raised_again_as_sigterm(monkeypatch):
    # SIGTERM raises Terminated (a KeyboardInterrupt) inside the CLI: dropped in a callback, it must come back as
    # SIGTERM (exit 143), not as a Ctrl-C
    raised: list[int] = []
    monkeypatch.setattr("flowtex.interrupts._raise_again", raised.append)
    monkeypatch.setattr("flowtex.interrupts.RESEND_AFTER_S", 0.0)

    def body() -> None:
        raise cli_main.Terminated

    with interrupts_kept(cli_main._signal_of):
        CALLBACK(body)()
        deadline = time.monotonic() + 10.0
        while not raised and time.monotonic() < deadline:
            time.sleep(0.01)
    assert raised == [signal.SIGTERM] and interrupt_was_lost()


def _compile_calling(during_typing) -> None:
    """Compile (not from any cache) a new function whose typing calls ``during_typing``: code run inside a numba
    compile, as the object-code callback is."""
    from numba import njit
    from numba.extending import overload

    def poke() -> None:
        pass

    @overload(poke)
    def _poke():
        during_typing()
        return lambda: None

    @njit
    def uses_poke() -> None:
        poke()

    uses_poke()


def test_a_library_callers_interrupt_dropped_during_a_compile_is_raised_again(sigint_raises, capsys):
    import flowtex.dsp  # noqa: F401  (flowtex configures numba's cache, and keeps interrupts during compiles)

    assert not keeping_interrupts()
    seen: list[bool] = []
    deadline = time.monotonic() + 10.0
    with pytest.raises(KeyboardInterrupt):  # raised again: inside the compile (which it ends) or just after it
        _compile_calling(lambda: (seen.append(keeping_interrupts()), _interrupted_in_callback()))
        while time.monotonic() < deadline:
            time.sleep(RESEND_AFTER_S / 5)
    # every SIGINT raised again is Ctrl-C; under load the first may land in another of the compile's callbacks, be
    # dropped there too and be raised once more (module docstring of flowtex.interrupts), so there can be two
    assert seen == [True] and sigint_raises and set(sigint_raises) == {signal.SIGINT}
    assert not keeping_interrupts()  # left with the compile: no hook stays behind
    assert "Exception ignored" not in capsys.readouterr().err


def test_the_command_lines_keeper_is_not_replaced_during_a_compile():
    """Inside `flowtex`, a compile keeps the command line's keeper (which also raises SIGTERM again as SIGTERM)."""
    import flowtex.dsp  # noqa: F401

    seen: list[object] = []
    with interrupts_kept(cli_main._signal_of):
        outer = sys.unraisablehook
        _compile_calling(lambda: seen.append(sys.unraisablehook))
    assert seen == [outer]



def _ctrl_c(times: int = 1) -> Callable[[], None]:
    """Code for a compile's typing: presses Ctrl-C ``times`` (a real SIGINT to this process), then goes on working
    (Python's handler runs at the next bytecode: without deferral the KeyboardInterrupt is raised right here)."""

    def press() -> None:
        for _ in range(times):
            os.kill(os.getpid(), signal.SIGINT)
            sum(range(1000))
        reached.append(True)

    reached: list[bool] = []
    press.reached = reached  # type: ignore[attr-defined]
    return press


def test_a_library_callers_ctrl_c_during_a_compile_is_raised_when_the_compile_ends(sigint_raises, capfd):
    # a notebook goes on after Ctrl-C: a compile cut short would leave numba's half-built code behind ("no compiled
    # object yet" at every later compile that links it, until a restart), so the compile finishes first
    import flowtex.dsp  # noqa: F401

    press = _ctrl_c()
    with pytest.raises(KeyboardInterrupt):
        _compile_calling(press)
    assert press.reached == [True]  # the typing went on after the signal: the compile was not cut short
    assert sigint_raises == [signal.SIGINT]  # the caller's handler got it, once, at the compile's end
    assert signal.getsignal(signal.SIGINT) is not None and signal.getsignal(signal.SIGINT).__name__ == "handler"
    assert capfd.readouterr().err.count("Ctrl-C: stopping when this compile ends") == 1


def test_a_second_ctrl_c_during_a_compile_stops_it_at_once(sigint_raises):
    import flowtex.dsp  # noqa: F401

    press = _ctrl_c(times=2)
    with pytest.raises(KeyboardInterrupt):
        _compile_calling(press)
    assert press.reached == [] and sigint_raises == [signal.SIGINT]  # raised inside the typing, by the second one
    assert signal.getsignal(signal.SIGINT).__name__ == "handler"  # the caller's handler is back


def test_the_command_line_stops_a_compile_at_the_first_ctrl_c(sigint_raises):
    # flowtex exits on Ctrl-C, leaving nothing half-built behind: no deferral under its keeper
    import flowtex.dsp  # noqa: F401

    press = _ctrl_c()
    with pytest.raises(KeyboardInterrupt), interrupts_kept(cli_main._signal_of):
        _compile_calling(press)
    assert press.reached == [] and sigint_raises == [signal.SIGINT]


def test_ctrl_c_during_a_wrapper_compile_is_raised_once_its_entry_is_sealed(sigint_raises, tmp_path):
    # numba compiles flowtex's C-callable wrappers without compile events: kcache.sealed_compile defers instead
    from flowtex.graph.kcache import sealed_compile

    entry = tmp_path / "w.nbi"
    press = _ctrl_c()

    def compile_() -> str:
        press()
        entry.write_bytes(b"compiled")  # what numba would write
        return "cfunc"

    with pytest.raises(KeyboardInterrupt):
        sealed_compile(tmp_path / "w", lambda: [entry] if entry.exists() else [], compile_)
    assert press.reached == [True] and sigint_raises == [signal.SIGINT]
    assert json.loads((tmp_path / "w.seal").read_text()) == {"w.nbi": hashlib.sha256(b"compiled").hexdigest()}
