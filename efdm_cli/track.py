"""``efdm track``: follow a contour through a video or an image sequence.

Writes one JSON record per frame (JSON Lines)::

    {"frame": 0, "nodes": [[x, y], ...], "iterations": 3, "converged": true,
     "confidence": 0.9731, "status": "tracking", "elapsed_ms": 1.204}

(``"contours": [[[x, y], ...], ...]`` instead of ``"nodes"`` for an object
that ``--init-mask`` gives in several pieces).

Exit codes: 0 success; 1 an input or output could not be read or written
(missing file, unreadable video, empty folder, undecodable image, overlay
video that cannot be opened); 2 invalid arguments or data (not exactly one
``--init-*`` option, malformed box, polygon or circle, ``--nodes`` outside 3-4096, empty mask,
initial contour outside the first frame, frame size changing mid-stream,
tracker options the tracker rejects).
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path
from typing import Any, Protocol, TextIO

import numpy as np
from numpy.typing import NDArray

from efdm_cli._common import EXIT_INVALID, EXIT_IO, CliError, silence
from efdm_cli._init import (
    MIN_PIECE_AREA,
    initial_contour,
    initial_objects,
    parse_box,
    parse_circle,
    parse_polygon,
)

__all__ = ["add_parser", "initial_contour", "parse_box", "parse_circle", "parse_polygon", "run"]

Nodes = NDArray[np.float64]


class StepResult(Protocol):
    """What :meth:`engine.tracking.tracker.Tracker.step` returns, as far as the CLI uses it."""

    @property
    def nodes(self) -> Nodes: ...
    @property
    def iterations(self) -> int: ...
    @property
    def converged(self) -> bool: ...
    @property
    def confidence(self) -> float: ...
    @property
    def status(self) -> str: ...


def parse_options(items: list[str]) -> dict[str, Any]:
    """``KEY=VALUE`` tracker options; VALUE is read as JSON, else kept as a string."""
    options: dict[str, Any] = {}
    for item in items:
        key, sep, value = item.partition("=")
        key = key.strip().replace("-", "_")
        if not sep or not key.isidentifier():
            raise CliError(f"--option: expected KEY=VALUE; got {item!r}", EXIT_INVALID)
        if key in ("closed", "stiffness"):
            raise CliError(f"--option: {key} cannot be set this way", EXIT_INVALID)
        try:
            options[key] = json.loads(value)
        except json.JSONDecodeError:
            options[key] = value
    return options


class _Crowd:
    """Several objects' results of one frame, as one :class:`StepResult` (worst status,
    lowest confidence) that also carries each object's."""

    ORDER = ("lost", "uncertain", "tracking")

    def __init__(self, objects: list[Any]) -> None:
        self.objects = objects
        self.nodes = objects[0].contours[0]
        self.contours = [c for o in objects for c in o.contours]
        self.iterations, self.converged = 0, True
        self.confidence = min(float(o.confidence) for o in objects)
        self.status = min((str(o.status) for o in objects), key=self.ORDER.index)


def _shape(contours: list[Nodes]) -> dict[str, Any]:
    """``{"nodes": ...}`` for one contour, ``{"contours": [...]}`` for several pieces."""
    rounded = [np.round(np.asarray(c, np.float64), 3).tolist() for c in contours]
    return {"nodes": rounded[0]} if len(rounded) == 1 else {"contours": rounded}


def _record(index: int, result: StepResult, elapsed_ms: float) -> str:
    if isinstance(result, _Crowd):
        objects = [
            {
                "id": o.id,
                **_shape(o.contours),
                "confidence": round(float(o.confidence), 4),
                "status": str(o.status),
                "behind": list(o.behind),
            }
            for o in result.objects
        ]
        return json.dumps({"frame": index, "objects": objects, "elapsed_ms": round(elapsed_ms, 3)})
    pieces = getattr(result, "contours", None)
    shape: dict[str, Any]
    if pieces is None:
        shape = {"nodes": np.round(np.asarray(result.nodes, np.float64), 3).tolist()}
    else:
        shape = {"contours": [np.round(np.asarray(p, np.float64), 3).tolist() for p in pieces]}
    return json.dumps(
        {
            "frame": index,
            **shape,
            "iterations": int(result.iterations),
            "converged": bool(result.converged),
            "confidence": round(float(result.confidence), 4),
            "status": str(result.status),
            "elapsed_ms": round(elapsed_ms, 3),
        }
    )


def summary(confidences: list[float], statuses: list[str], seconds: float) -> str:
    """The closing line of a run: frames, time per frame, confidence, frames lost."""
    count = len(confidences)
    worst = int(np.argmin(confidences))
    lost, unsure = statuses.count("lost"), statuses.count("uncertain")
    return (
        f"efdm track: {count} frames in {seconds:.1f} s ({1e3 * seconds / count:.1f} ms per "
        f"frame); confidence mean {np.mean(confidences):.2f}, worst {confidences[worst]:.2f} "
        f"(frame {worst}); {lost} reported lost, {unsure} uncertain"
    )


def run(args: argparse.Namespace, out: TextIO) -> None:
    """Track the contour through ``args.input``; JSON Lines to ``out`` or ``args.out``.

    Raises
    ------
    CliError
        With :data:`EXIT_IO` or :data:`EXIT_INVALID`.
    """
    from efdm_cli._io import ImageFrames, MaskWriter, OverlayWriter, check_size, open_frames
    from efdm_cli._progress import Progress
    from engine.physics.recursive import warm_up
    from engine.tracking.objects import ObjectsTracker
    from engine.tracking.pieces import PiecesTracker
    from engine.tracking.tracker import Tracker

    options = parse_options(args.option)
    if args.stiffness is not None:
        options["stiffness"] = args.stiffness
    if args.processes < 0:
        raise CliError(f"--processes must be 0 or more; got {args.processes}", EXIT_INVALID)
    source = open_frames(args.input)
    frames = source.frames()
    sink = out
    overlay: OverlayWriter | None = None
    progress: Progress | None = None
    crowd: ObjectsTracker | None = None
    try:
        first = next(frames, None)
        if first is None:
            raise CliError(f"cannot read any frame from {args.input}", EXIT_IO)
        height, width = first[1].shape[:2]
        size = (width, height)
        # the snap reads what moved between the first two frames: read one ahead
        second = next(frames, None)
        following = None if second is None or second[1].shape != first[1].shape else second[1]
        objects = initial_objects(args, size, first[1], following)
        contours = next(iter(objects.values()))
        tracker: Tracker | PiecesTracker | ObjectsTracker
        try:
            if len(objects) > 1:
                spread = {"workers": args.processes, "processes": True} if args.processes else {}
                tracker = crowd = ObjectsTracker(objects, **spread, **options)
            elif len(contours) > 1:
                tracker = PiecesTracker(contours, **options)
            else:
                tracker = Tracker(contours[0], closed=True, **options)
        except (TypeError, ValueError) as exc:
            raise CliError(f"tracker: {exc}", EXIT_INVALID) from None
        warm_up()  # so that elapsed_ms of frame 1 does not include compiling the solver
        if args.out is not None:
            try:
                sink = Path(args.out).open("w", encoding="utf-8")  # noqa: SIM115
            except OSError as exc:
                raise CliError(f"cannot write {args.out}: {exc.strerror}", EXIT_IO) from None
        if args.overlay is not None:
            overlay = OverlayWriter(args.overlay, source.fps, size)
        masks = None
        if args.masks_out is not None:
            masks = MaskWriter(args.masks_out, named=isinstance(source, ImageFrames))
        progress = Progress(source.total, sys.stderr, enabled=not args.quiet)
        index = 0
        confidences: list[float] = []
        statuses: list[str] = []
        started = time.perf_counter()
        ahead = [] if second is None else [second]
        item: tuple[str, NDArray[np.uint8]] | None = first
        while item is not None:
            name, frame = item
            check_size(name, index, frame, size)
            start = time.perf_counter()
            try:
                stepped = tracker.step(frame)
            except ValueError as exc:
                raise CliError(f"frame {index} ({name}): {exc}", EXIT_INVALID) from None
            result: StepResult = _Crowd(stepped) if isinstance(stepped, list) else stepped
            elapsed_ms = 1e3 * (time.perf_counter() - start)
            try:
                sink.write(_record(index, result, elapsed_ms) + "\n")
                sink.flush()
            except BrokenPipeError:
                if sink is not out:
                    raise CliError(f"cannot write {args.out}: broken pipe", EXIT_IO) from None
                silence(out)  # the reader (e.g. `head`) has had enough: stop quietly
                return
            except OSError as exc:
                target = args.out or "stdout"
                raise CliError(f"cannot write {target}: {exc.strerror}", EXIT_IO) from None
            drawn = getattr(result, "contours", None) or np.asarray(result.nodes)
            if overlay is not None:
                overlay.write(frame, drawn, index, float(result.confidence))
            if masks is not None and isinstance(result, _Crowd):
                masks.write_labels(name, index, result.objects, (height, width))
            elif masks is not None:
                masks.write(name, index, drawn, (height, width))
            confidences.append(float(result.confidence))
            statuses.append(str(result.status))
            index += 1
            progress.update(index)
            item = ahead.pop() if ahead else next(frames, None)
        progress.close()
        if progress.shown:
            print(summary(confidences, statuses, time.perf_counter() - started), file=sys.stderr)
    finally:
        frames.close()
        if crowd is not None:
            crowd.close()  # its worker processes, if any
        if progress is not None:
            progress.close()
        if overlay is not None:
            overlay.close()
        if sink is not out:
            sink.close()


def add_parser(commands: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Register ``track`` on the sub-command set of ``efdm``."""
    t = commands.add_parser(
        "track",
        help="track a contour through a video or image sequence",
        description=(
            "Track a closed contour through INPUT, a video file, a folder of images "
            "(jpg/jpeg/png/bmp/tif/tiff/webp, sorted by name) or a quoted glob pattern "
            "(sorted). Writes one JSON record per frame (JSON Lines): frame, nodes "
            "[[x, y], ...] in pixels (x = column, y = row), iterations, converged, "
            "confidence, status (tracking, uncertain or lost), elapsed_ms; with several "
            "objects, frame, objects [{id, nodes or contours, confidence, status, "
            "behind}, ...] and elapsed_ms."
        ),
        epilog=(
            "exit codes: 0 success, 1 an input or output could not be read or written, "
            "2 invalid arguments or data"
        ),
    )
    t.add_argument("input", help='video file, folder of images, or glob such as "frames/*.png"')
    init = t.add_argument_group("initial contour on the first frame (exactly one)")
    init.add_argument(
        "--init-mask",
        metavar="PNG",
        help="binary mask or label image (8-bit grey, or palette PNG as DAVIS-2017): "
        "the largest outer contour of the object's pixels",
    )
    init.add_argument(
        "--min-piece-area",
        type=float,
        metavar="PX",
        help="with --init-mask or a snapped outline: an object in several separate pieces "
        "is tracked piece by piece (JSON 'contours'), pieces under PX pixels left out (with "
        f"a warning for a mask; default {MIN_PIECE_AREA:g})",
    )
    init.add_argument(
        "--label",
        type=int,
        metavar="K",
        help="with --init-mask: only the object of label K (without it, a label image of "
        "several labels gives several objects, their ids the labels)",
    )
    init.add_argument(
        "--init-box",
        action="append",
        metavar="X0,Y0,X1,Y1",
        help="the object's bounding box in pixel edges (the box of a mask spanning columns "
        "x0..x1-1, rows y0..y1-1: the object reaches every side); snapped onto the object "
        "inside it unless --no-snap; repeat for several objects (ids 1, 2, ...)",
    )
    init.add_argument("--init-polygon", metavar='"X,Y X,Y ..."', help="polygon, >= 3 points")
    init.add_argument("--init-circle", metavar="CX,CY,R", help="circle, centre and radius")
    init.add_argument(
        "--snap",
        action=argparse.BooleanOptionalAction,
        default=None,
        help="snap the outline onto the object inside it on the first frame (GrabCut with "
        "what moved by the second frame, under a second at 854x480): the default for "
        "--init-box; --snap for a loose polygon or circle; --no-snap keeps the box as given",
    )
    t.add_argument(
        "--masks-out",
        metavar="DIR",
        help="also write each frame's mask (PNG, 0/255) to DIR, named like the input "
        "images (DAVIS layout; a video's frames as 00000.png, 00001.png, ...)",
    )
    t.add_argument(
        "--nodes",
        "-n",
        type=int,
        default=128,
        metavar="N",
        help="contour nodes, 3 to 4096 (default: 128)",
    )
    t.add_argument(
        "--stiffness", "-a", type=float, metavar="A", help="a = k/m > 0 (default: the tracker's)"
    )
    t.add_argument(
        "--option", "-O", action="append", default=[], metavar="KEY=VALUE",
        help="another tracker option, e.g. search_radius=16 (repeatable); VALUE is JSON, else text",
    )  # fmt: skip
    t.add_argument(
        "--processes", type=int, default=0, metavar="N",
        help="track several objects on N worker processes, the same results sooner on "
        "several cores (default: 0, in this process)",
    )  # fmt: skip
    t.add_argument("--out", "-o", metavar="JSONL", help="write the records here, not stdout")
    t.add_argument("--overlay", metavar="VIDEO", help="also write a video with the contour drawn")
    t.add_argument("--quiet", "-q", action="store_true", help="no progress line on stderr")
    t.set_defaults(handler=run)
