"""User-facing error types.

Every error a user can cause (bad YAML, bad parameter, bad recording, bad
model file) is raised as a :class:`FlowtexError` or one of its subclasses.
The command line prints these as one line each and exits non-zero; it never
shows a Python traceback for them.
"""

from __future__ import annotations

from dataclasses import dataclass


class FlowtexError(Exception):
    """An error caused by user input; its message is meant to be read as is."""


@dataclass(frozen=True)
class Location:
    """A position in a user file (1-based line and column, as editors show)."""

    path: str
    line: int = 0
    column: int = 0

    def __str__(self) -> str:
        if self.line <= 0:
            return self.path
        return f"{self.path}:{self.line}:{self.column}"


@dataclass(frozen=True)
class Diagnostic:
    """One problem found in a user file."""

    location: Location
    message: str

    def __str__(self) -> str:
        return f"{self.location}: {self.message}"


class GraphError(FlowtexError):
    """A graph file has one or more problems; each is a :class:`Diagnostic`."""

    def __init__(self, diagnostics: list[Diagnostic]):
        self.diagnostics = list(diagnostics)
        super().__init__("\n".join(str(d) for d in self.diagnostics))


class ParamError(FlowtexError):
    """A node parameter is invalid; raised by node code at build time.

    ``param`` names the offending parameter so that the graph compiler can
    point at its line in the YAML file.
    """

    def __init__(self, param: str | None, message: str):
        self.param = param
        super().__init__(message)


class DataError(FlowtexError):
    """A data file (recording, model set, tap library, ...) is malformed."""


class InputError(FlowtexError, ValueError):
    """Arrays or values given to the Python API (``Graph.run``, ``Node.processor``) are wrong: shape, kind, length.

    Also a ``ValueError``, as these problems were raised before they had a class of their own.
    """
