"""Command-line options that two modules parse, each defined once here.

``moments-ref report`` is parsed by the command line (:mod:`moments_ref.cli`) and,
for callers of ``moments_ref.report.main([...])``, by the report itself; both add
the arguments of :func:`add_report_arguments` and the command line hands the parsed
values to the report. Kept in this light module so that the command line builds its
parser without importing the report (and everything below it).
"""

from __future__ import annotations

import argparse
from pathlib import Path

__all__ = ["positive_int_arg", "folder_arg", "add_report_arguments"]


def positive_int_arg(text):
    """argparse type: an integer >= 1."""
    try:
        n = int(text)
    except ValueError:
        n = 0
    if n < 1:
        raise argparse.ArgumentTypeError(f"expected a positive integer, got {text!r}")
    return n


def folder_arg(text):
    """argparse type of ``--out``: a path, not the empty string (which would mean the current folder)."""
    if not text.strip():
        raise argparse.ArgumentTypeError(f"expected a folder, got {text!r} (write '.' for the current folder)")
    return Path(text)


def add_report_arguments(parser):
    """The arguments of ``moments-ref report`` on ``parser`` (returned)."""
    p = parser
    p.add_argument("--scene", action="append", metavar="NAME|FILE",
                   help="shipped scene name or scene file (repeatable; default: all shipped scenes)")
    p.add_argument("--full", action="store_true",
                   help="the scene's own map size, MSAA and camera resolution (default: reduced, printed at the start)")
    p.add_argument("--technique", action="append", metavar="NAME",
                   help="run this technique (repeatable) instead of each scene's outputs")
    p.add_argument("--all-techniques", action="store_true",
                   help="every technique that can run on each scene instead of its outputs")
    p.add_argument("--repeats", type=positive_int_arg, default=3, metavar="N",
                   help="timed repeats of each cost stage after a warm-up (default 3)")
    p.add_argument("--jobs", type=positive_int_arg, default=None, metavar="N",
                   help="worker processes running scenes side by side (default: the usable cores; 1: serial)")
    p.add_argument("--out", required=True, type=folder_arg, help="output folder")
    p.add_argument("--no-progress", action="store_true", help="no progress bars")
    return p
