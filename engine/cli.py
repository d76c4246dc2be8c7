"""The ``efdm`` command line.

Exit codes: 0 success, 1 an input or output file could not be read or
written, 2 invalid arguments or data (the message says what is wrong).
"""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import Any, TextIO

import numpy as np
from numpy.typing import NDArray

from engine.deform import METHODS, deform

EXIT_OK, EXIT_IO, EXIT_INVALID = 0, 1, 2


class CliError(Exception):
    """A failure with its exit code and a message for stderr."""

    def __init__(self, message: str, code: int) -> None:
        super().__init__(message)
        self.code = code


def _read_json(source: str) -> Any:
    try:
        text = sys.stdin.read() if source == "-" else Path(source).read_text()
    except OSError as exc:
        raise CliError(f"cannot read {source}: {exc.strerror}", EXIT_IO) from None
    try:
        return json.loads(text)
    except json.JSONDecodeError as exc:
        raise CliError(f"{source} is not valid JSON: {exc}", EXIT_INVALID) from None


def _load_deform_input(source: str) -> tuple[NDArray[np.float64], NDArray[np.float64] | None]:
    """Forces and optional rest nodes from a .npy file or a JSON document."""
    if source.endswith(".npy"):
        try:
            return np.load(source, allow_pickle=False), None
        except OSError as exc:
            raise CliError(f"cannot read {source}: {exc}", EXIT_IO) from None
        except ValueError as exc:
            raise CliError(f"{source} is not a numeric .npy array: {exc}", EXIT_INVALID) from None
    doc = _read_json(source)
    if not isinstance(doc, dict) or "forces" not in doc:
        raise CliError('input JSON must be an object with "forces": [[fx, fy], ...]', EXIT_INVALID)
    try:
        forces = np.asarray(doc["forces"], dtype=np.float64)
        nodes = None if doc.get("nodes") is None else np.asarray(doc["nodes"], dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise CliError(f"forces and nodes must be numbers: {exc}", EXIT_INVALID) from None
    return forces, nodes


def _deform(args: argparse.Namespace, out: TextIO) -> None:
    forces, nodes = _load_deform_input(args.input)
    try:
        U = deform(forces, args.stiffness, closed=not args.open, method=args.method, tol=args.tol)
    except ValueError as exc:
        raise CliError(str(exc), EXIT_INVALID) from None
    result: dict[str, Any] = {"displacements": U.tolist()}
    if nodes is not None:
        if nodes.shape != U.shape:
            raise CliError(f"nodes must have the shape of forces {U.shape}", EXIT_INVALID)
        result["nodes"] = (nodes + U).tolist()
    if args.out is None:
        json.dump(result, out)
        out.write("\n")
        return
    try:
        if args.out.endswith(".npy"):
            np.save(args.out, U)
        else:
            Path(args.out).write_text(json.dumps(result) + "\n")
    except OSError as exc:
        raise CliError(f"cannot write {args.out}: {exc}", EXIT_IO) from None


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of ``efdm`` (one sub-command per job)."""
    parser = argparse.ArgumentParser(
        prog="efdm",
        description="Explicit physics-based deformable contours (Krinidis & Pitas).",
    )
    commands = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    d = commands.add_parser(
        "deform",
        help="equilibrium displacements of a contour under forces",
        description=(
            "Solve (I + K) U = F for the forces in INPUT: a JSON object "
            '{"forces": [[fx, fy], ...], "nodes": [[x, y], ...] (optional)} or a .npy '
            "array of shape (N, 2) or (B, N, 2); '-' reads JSON from stdin. Coordinates "
            'are [x, y] pixels. Prints {"displacements": ..., "nodes": X0 + U} as JSON.'
        ),
    )
    d.add_argument("input", help="JSON or .npy file, or - for JSON on stdin")
    d.add_argument("--stiffness", "-a", type=float, required=True, help="a = k/m > 0")
    d.add_argument("--open", action="store_true", help="open chain (default: closed ring)")
    d.add_argument("--method", choices=METHODS, default="exact", help="solver (default: exact)")
    d.add_argument("--tol", type=float, help="EFDMT error bound relative to max|F|")
    d.add_argument("--out", "-o", help="write JSON (or .npy displacements) here, not stdout")
    d.set_defaults(handler=_deform)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Run ``efdm``; returns the process exit code."""
    args = build_parser().parse_args(argv)
    try:
        args.handler(args, sys.stdout)
    except CliError as exc:
        print(f"efdm {args.command}: error: {exc}", file=sys.stderr)
        return exc.code
    return EXIT_OK


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(main())
