"""The first (compiling) run of a graph says so on stderr instead of being silent (issue 9 item 4)."""

from __future__ import annotations

import io
import time

from flowtex.graph.notice import compile_notice


class _Tty(io.StringIO):
    def isatty(self) -> bool:
        return True


def test_slow_compile_is_announced_once_without_a_terminal():
    out = io.StringIO()
    with compile_notice("graph 'g' (2 nodes: gain, delay)", "/cache", delay=0.05, stream=out):
        time.sleep(0.5)
    assert out.getvalue() == "flowtex: compiling graph 'g' (2 nodes: gain, delay) with numba (first run only: cached in /cache)\n"


def test_terminal_gets_a_spinner_and_the_total_time():
    out = _Tty()
    with compile_notice("graph 'g'", "/cache", delay=0.05, stream=out):
        time.sleep(0.7)
    text = out.getvalue()
    assert text.startswith("\rflowtex: compiling graph 'g' with numba (first run only: cached in /cache) ")
    assert any(f" {c} " in text for c in "|/-\\")
    assert "\rflowtex: compiled graph 'g' in " in text and text.endswith(" s (cached in /cache)\x1b[K\n")


def test_cache_hit_prints_nothing():
    for out in (io.StringIO(), _Tty()):
        with compile_notice("graph 'g'", "/cache", delay=5.0, stream=out):
            pass
        assert out.getvalue() == ""
