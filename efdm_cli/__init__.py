"""The ``efdm`` command line.

Sub-commands:

``efdm deform``
    Equilibrium displacements of a contour under forces
    (:mod:`efdm_cli.deform`).
``efdm track``
    Follow a contour through a video, a folder of images or a glob pattern;
    one JSON record per frame (:mod:`efdm_cli.track`).
``efdm eval``
    Score predicted masks against ground truth with the DAVIS measures J and F
    (:mod:`efdm_cli.evaluate`).
``efdm serve``
    The HTTP/WebSocket tracking service (:mod:`efdm_cli.serve`; imports the
    web stack only when run).

Exit codes (every sub-command): 0 success; 1 an input or output could not be
read or written (missing file, unreadable video, empty folder, undecodable
image, overlay that cannot be opened); 2 invalid arguments or data (the
message on stderr, ``efdm COMMAND: error: ...``, says what is wrong); 3 a
part of the program is not installed (``efdm serve`` needs the ``[service]``
extra: ``pip install 'efdm-tracker[service]'``).

The command line sits above both the engine and the service (the engine
never imports either); ``python -m efdm_cli`` runs it too.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence

from efdm_cli import deform as _deform
from efdm_cli import evaluate as _evaluate
from efdm_cli import serve as _serve
from efdm_cli import track as _track
from efdm_cli._common import (
    EXIT_INVALID,
    EXIT_IO,
    EXIT_MISSING,
    EXIT_OK,
    CliError,
    silence,
)

__all__ = [
    "EXIT_INVALID",
    "EXIT_IO",
    "EXIT_MISSING",
    "EXIT_OK",
    "CliError",
    "build_parser",
    "main",
]


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of ``efdm`` (one sub-command per job)."""
    parser = argparse.ArgumentParser(
        prog="efdm",
        description="Explicit physics-based deformable contours (Krinidis & Pitas).",
    )
    commands = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    _deform.add_parser(commands)
    _track.add_parser(commands)
    _evaluate.add_parser(commands)
    _serve.add_parser(commands)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Run ``efdm``; returns the process exit code."""
    args = build_parser().parse_args(argv)
    try:
        args.handler(args, sys.stdout)
    except CliError as exc:
        print(f"efdm {args.command}: error: {exc}", file=sys.stderr)
        return exc.code
    except BrokenPipeError:  # stdout's reader (e.g. `head`) has had enough: stop quietly
        silence(sys.stdout)
    return EXIT_OK
