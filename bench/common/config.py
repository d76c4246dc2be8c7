"""What a run measures (the ``Config`` base) and the command line every family shares."""

from __future__ import annotations

import argparse
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

from bench.common import RESULTS


@dataclass(frozen=True, slots=True)
class Config:
    """What to run, and how hard: each family subclasses it with its own fields.

    Every family has two configurations, ``FULL`` (what ``bench/results/`` holds)
    and ``QUICK`` (``--quick``: tiny counts for smoke tests).

    Attributes
    ----------
    name : str
        ``"full"`` or ``"quick"``.
    """

    name: str


def parse_args(
    doc: str | None,
    argv: Sequence[str] | None,
    arguments: Callable[[argparse.ArgumentParser], None] | None = None,
) -> argparse.Namespace:
    """``--quick`` and ``--out DIR`` (default ``bench/results/``), plus a family's own options.

    Parameters
    ----------
    doc : str or None
        The family's docstring; its first line describes the command.
    argv : sequence of str or None
        The arguments (None: ``sys.argv[1:]``).
    arguments : callable, optional
        Adds the family's own options to the parser.
    """
    parser = argparse.ArgumentParser(description=doc.splitlines()[0] if doc else None)
    parser.add_argument("--quick", action="store_true", help="reduced run for smoke tests")
    parser.add_argument("--out", type=Path, default=RESULTS, help="output directory")
    if arguments is not None:
        arguments(parser)
    return parser.parse_args(argv)
