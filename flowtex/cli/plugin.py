"""``flowtex plugin new`` and ``flowtex plugin check``: start a node type from one command, and check it."""

from __future__ import annotations

import argparse
from typing import Any

from .output import note, say


def register(sub: Any) -> None:
    p = sub.add_parser("plugin", help="write a plugin package for a new node type, or check a plugin's node types")
    verbs = p.add_subparsers(dest="plugin_command", required=True, metavar="ACTION", parser_class=type(p))
    q = verbs.add_parser("new", help="write an installable plugin package for node type NAME (node, test, golden file, README)")
    q.add_argument("name", metavar="NAME", help="node type name, e.g. smooth_gain (lowercase letters, digits, _)")
    q.add_argument("--output", "-o", required=True, metavar="DIR", help="new (or empty) folder for the package")
    q.set_defaults(func=cmd_plugin_new)
    q = verbs.add_parser("check", help="check every node type of a plugin file (or one installed node type): compile, "
                                       "allocation, state, unwritten outputs, bounds, finite outputs")
    q.add_argument("target", metavar="TARGET", help="a plugin .py file, or a node type name")
    q.set_defaults(func=cmd_plugin_check)


def cmd_plugin_new(args: argparse.Namespace) -> int:
    from ..scaffold import new_plugin

    files = new_plugin(args.name, args.output)
    say(f"{args.output}: plugin package for node type {args.name!r} ({len(files)} files); next: pip install -e {args.output} "
        f"&& (cd {args.output} && pytest)")
    return 0


def cmd_plugin_check(args: argparse.Namespace) -> int:
    from ..plugincheck import check_target

    report = check_target(args.target)
    for line in report.problems + report.notes:  # the report, on stdout; the verdict on stderr
        say(line)
    types = ", ".join(report.checked)
    if report.problems:
        note(f"{args.target}: {len(report.problems)} problem(s) in node type(s) {types}")
        return 1
    note(f"{args.target}: ok (node type(s) {types}; {len(report.notes)} note(s))")
    return 0
