"""``efdm deform``: equilibrium displacements of a contour under forces."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any, TextIO

import numpy as np
from numpy.typing import NDArray

from efdm_cli._common import EXIT_INVALID, EXIT_IO, CliError
from engine.physics import METHODS, deform

__all__ = ["add_parser", "run"]


def _read_json(source: str) -> Any:
    try:
        text = sys.stdin.read() if source == "-" else Path(source).read_text()
    except OSError as exc:
        raise CliError(f"cannot read {source}: {exc.strerror}", EXIT_IO) from None
    except UnicodeDecodeError:
        raise CliError(f"{source} is not valid JSON: not UTF-8 text", EXIT_INVALID) from None
    try:
        return json.loads(text)
    except json.JSONDecodeError as exc:
        raise CliError(f"{source} is not valid JSON: {exc}", EXIT_INVALID) from None


def _load_input(source: str) -> tuple[NDArray[np.float64], NDArray[np.float64] | None]:
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


def run(args: argparse.Namespace, out: TextIO) -> None:
    """Solve for the forces in ``args.input``; write JSON to ``out`` or ``args.out``.

    Raises
    ------
    CliError
        With :data:`EXIT_IO` or :data:`EXIT_INVALID`.
    """
    forces, nodes = _load_input(args.input)
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


def add_parser(commands: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Register ``deform`` on the sub-command set of ``efdm``."""
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
    d.set_defaults(handler=run)
