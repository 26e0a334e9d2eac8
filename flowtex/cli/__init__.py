"""The ``flowtex`` command line: one module per command group, shared option builders (options.py), one error and
exit-code convention (main.py). Nothing below this package imports it; every verb calls library functions."""

from .main import build_parser, main

__all__ = ["build_parser", "main"]
