"""``efdm track``: follow a contour through a video or an image sequence.

Writes one JSON record per frame (JSON Lines)::

    {"frame": 0, "nodes": [[x, y], ...], "iterations": 3, "converged": true,
     "confidence": 0.9731, "status": "tracking", "elapsed_ms": 1.204}

Exit codes: 0 success; 1 an input or output could not be read or written
(missing file, unreadable video, empty folder, undecodable image, overlay
video that cannot be opened); 2 invalid arguments or data (not exactly one
``--init-*`` option, malformed box, polygon or circle, ``--nodes`` < 3, empty mask,
initial contour outside the first frame, frame size changing mid-stream,
tracker options the tracker rejects).
"""

from __future__ import annotations

import argparse
import io
import json
import os
import sys
import time
from pathlib import Path
from typing import Any, Protocol, TextIO

import numpy as np
from numpy.typing import NDArray

from efdm_cli._common import EXIT_INVALID, EXIT_IO, CliError

__all__ = ["add_parser", "initial_contour", "parse_box", "parse_circle", "parse_polygon", "run"]

Nodes = NDArray[np.float64]
_INIT_OPTIONS = ("--init-mask", "--init-box", "--init-polygon", "--init-circle")


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


def _numbers(text: str, what: str) -> list[float]:
    try:
        values = [float(v) for v in text.split(",")]
    except ValueError:
        raise CliError(
            f"{what}: {text!r} is not a comma-separated list of numbers", EXIT_INVALID
        ) from None
    if not all(np.isfinite(values)):
        raise CliError(f"{what}: {text!r} has a non-finite number", EXIT_INVALID)
    return values


def parse_polygon(text: str) -> Nodes:
    """``"x,y x,y ..."`` (at least 3 points, enclosing a non-zero area) as an (M, 2) array."""
    what = "--init-polygon"
    points = [_numbers(token, what) for token in text.replace(";", " ").split()]
    if any(len(p) != 2 for p in points):
        raise CliError(f'{what}: expected points "x,y x,y ..."; got {text!r}', EXIT_INVALID)
    if len(points) < 3:
        raise CliError(f"{what}: need at least 3 points; got {len(points)}", EXIT_INVALID)
    poly = np.array(points, dtype=np.float64)
    x, y = poly[:, 0], poly[:, 1]
    if abs(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1))) < 1e-9:
        raise CliError(f"{what}: the polygon encloses no area", EXIT_INVALID)
    return poly


def parse_circle(text: str) -> tuple[float, float, float]:
    """``"cx,cy,r"`` with r > 0."""
    values = _numbers(text, "--init-circle")
    if len(values) != 3 or not values[2] > 0:
        raise CliError(f"--init-circle: expected cx,cy,r with r > 0; got {text!r}", EXIT_INVALID)
    return values[0], values[1], values[2]


def parse_box(text: str) -> tuple[float, float, float, float]:
    """``"x0,y0,x1,y1"`` (pixel edges) with x1 > x0 and y1 > y0."""
    values = _numbers(text, "--init-box")
    if len(values) != 4 or not (values[2] > values[0] and values[3] > values[1]):
        raise CliError(
            f"--init-box: expected x0,y0,x1,y1 with x1 > x0 and y1 > y0; got {text!r}",
            EXIT_INVALID,
        )
    return values[0], values[1], values[2], values[3]


def _box_polygon(box: tuple[float, float, float, float]) -> Nodes:
    """The box's outline through its edge pixels' centres (pixel edges to centres)."""
    x0, y0, x1, y1 = box
    left, top, right, bottom = x0, y0, max(x1 - 1.0, x0), max(y1 - 1.0, y0)
    return np.array([[left, top], [right, top], [right, bottom], [left, bottom]])


def _warn_dropped_pieces(mask: NDArray[np.bool_], what: str) -> None:
    """Say on stderr which separate pieces of the object the track leaves out."""
    import cv2

    count, _, stats, _ = cv2.connectedComponentsWithStats(mask.astype(np.uint8), connectivity=8)
    areas = sorted((int(a) for a in stats[1:count, cv2.CC_STAT_AREA]), reverse=True)
    if len(areas) > 1:
        dropped = ", ".join(f"{a} px" for a in areas[1:6]) + (", ..." if len(areas) > 6 else "")
        print(
            f"efdm track: warning: {what} has {len(areas)} separate pieces; only the largest "
            f"({areas[0]} px) is tracked, dropped: {dropped}",
            file=sys.stderr,
        )


def _read_mask(path: str, label: int | None) -> NDArray[np.bool_]:
    """The object's pixels in a binary mask or label image (:mod:`efdm_cli._masks`)."""
    import cv2

    from efdm_cli._io import read_image
    from efdm_cli._masks import MaskError, object_mask

    image = read_image(path, cv2.IMREAD_UNCHANGED)
    if image.dtype != np.uint8:
        raise CliError(f"mask {path} must be 8-bit (got {image.dtype})", EXIT_INVALID)
    with open(path, "rb") as f:
        head = f.read(16)
    try:
        return object_mask(head, image, f"mask {path}", label)
    except MaskError as exc:
        raise CliError(str(exc), EXIT_INVALID) from None


def initial_contour(
    args: argparse.Namespace, size: tuple[int, int], first: NDArray[np.uint8] | None = None
) -> Nodes:
    """The ``--nodes`` initial nodes from exactly one ``--init-*`` option.

    A box (``--init-box``, unless ``--no-snap``) or a polygon or circle with
    ``--snap`` is snapped onto the object inside it in the ``first`` frame
    (:func:`engine.tracking.snap.snap`).

    Parameters
    ----------
    args : argparse.Namespace
        Parsed ``efdm track`` arguments.
    size : tuple of int
        ``(width, height)`` of the first frame.
    first : numpy.ndarray, optional
        The first frame (needed to snap).

    Raises
    ------
    CliError
        Invalid options, an unreadable or empty mask, or a contour entirely
        outside the frame.
    """
    from engine.geometry import circle_nodes, contour_to_mask, mask_to_contour, resample

    given = [o for o in _INIT_OPTIONS if getattr(args, o[2:].replace("-", "_")) is not None]
    if len(given) != 1:
        got = "none" if not given else " and ".join(given)
        raise CliError(f"give exactly one of {', '.join(_INIT_OPTIONS)} (got {got})", EXIT_INVALID)
    if args.nodes < 3:
        raise CliError(f"--nodes must be at least 3; got {args.nodes}", EXIT_INVALID)
    if getattr(args, "label", None) is not None and args.init_mask is None:
        raise CliError("--label chooses an object of --init-mask: give --init-mask", EXIT_INVALID)
    width, height = size
    snapping = getattr(args, "snap", None)
    box = getattr(args, "init_box", None)
    if snapping is None:
        snapping = box is not None  # boxes snap by default, outlines only when asked
    if args.init_circle is not None:
        cx, cy, r = parse_circle(args.init_circle)
        nodes = circle_nodes([cx, cy], r, args.nodes)
    elif box is not None:
        nodes = resample(_box_polygon(parse_box(box)), args.nodes, closed=True)
    elif args.init_polygon is not None:
        nodes = resample(parse_polygon(args.init_polygon), args.nodes, closed=True)
    else:
        snapping = False
        mask = _read_mask(args.init_mask, getattr(args, "label", None))
        if mask.shape != (height, width):
            raise CliError(
                f"mask {args.init_mask} is {mask.shape[1]} x {mask.shape[0]}, "
                f"the frames are {width} x {height}",
                EXIT_INVALID,
            )
        try:
            nodes = mask_to_contour(mask, args.nodes)
        except ValueError as exc:
            raise CliError(f"mask {args.init_mask}: {exc}", EXIT_INVALID) from None
        _warn_dropped_pieces(mask, f"mask {args.init_mask}")
    x, y = nodes[:, 0], nodes[:, 1]
    inside = (x >= -0.5) & (x <= width - 0.5) & (y >= -0.5) & (y <= height - 0.5)
    if not inside.any() and not contour_to_mask(nodes, (height, width)).any():
        raise CliError(f"initial contour lies outside the frame ({width} x {height})", EXIT_INVALID)
    if snapping and first is not None:
        from engine.tracking.snap import snap

        outline = parse_box(box) if box is not None else nodes
        try:
            nodes = mask_to_contour(snap(first, outline), args.nodes)
        except ValueError as exc:
            raise CliError(f"snap: {exc}", EXIT_INVALID) from None
    return nodes


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


def _record(index: int, result: StepResult, elapsed_ms: float) -> str:
    nodes = np.asarray(result.nodes, dtype=np.float64)
    return json.dumps(
        {
            "frame": index,
            "nodes": np.round(nodes, 3).tolist(),
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


def _silence(stream: TextIO) -> None:
    """Point ``stream``'s file descriptor at /dev/null, so that flushing it at exit is quiet."""
    try:
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, stream.fileno())
        os.close(devnull)
    except (OSError, ValueError, io.UnsupportedOperation):
        pass


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
    from engine.tracking.tracker import Tracker

    options = parse_options(args.option)
    if args.stiffness is not None:
        options["stiffness"] = args.stiffness
    source = open_frames(args.input)
    frames = source.frames()
    sink = out
    overlay: OverlayWriter | None = None
    progress: Progress | None = None
    try:
        first = next(frames, None)
        if first is None:
            raise CliError(f"cannot read any frame from {args.input}", EXIT_IO)
        height, width = first[1].shape[:2]
        size = (width, height)
        nodes = initial_contour(args, size, first[1])
        try:
            tracker = Tracker(nodes, closed=True, **options)
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
        item: tuple[str, NDArray[np.uint8]] | None = first
        while item is not None:
            name, frame = item
            check_size(name, index, frame, size)
            start = time.perf_counter()
            try:
                result = tracker.step(frame)
            except ValueError as exc:
                raise CliError(f"frame {index} ({name}): {exc}", EXIT_INVALID) from None
            elapsed_ms = 1e3 * (time.perf_counter() - start)
            try:
                sink.write(_record(index, result, elapsed_ms) + "\n")
                sink.flush()
            except BrokenPipeError:
                if sink is not out:
                    raise CliError(f"cannot write {args.out}: broken pipe", EXIT_IO) from None
                _silence(out)  # the reader (e.g. `head`) has had enough: stop quietly
                return
            except OSError as exc:
                target = args.out or "stdout"
                raise CliError(f"cannot write {target}: {exc.strerror}", EXIT_IO) from None
            if overlay is not None:
                overlay.write(frame, np.asarray(result.nodes), index, float(result.confidence))
            if masks is not None:
                masks.write(name, index, np.asarray(result.nodes), (height, width))
            confidences.append(float(result.confidence))
            statuses.append(str(result.status))
            index += 1
            progress.update(index)
            item = next(frames, None)
        progress.close()
        if progress.shown:
            print(summary(confidences, statuses, time.perf_counter() - started), file=sys.stderr)
    finally:
        frames.close()
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
            "confidence, elapsed_ms."
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
        "--label",
        type=int,
        metavar="K",
        help="with --init-mask: the object of label K (needed when the mask has several)",
    )
    init.add_argument(
        "--init-box",
        metavar="X0,Y0,X1,Y1",
        help="a box around the object in pixel edges (the box of a mask spanning columns "
        "x0..x1-1, rows y0..y1-1); snapped onto the object inside it unless --no-snap",
    )
    init.add_argument("--init-polygon", metavar='"X,Y X,Y ..."', help="polygon, >= 3 points")
    init.add_argument("--init-circle", metavar="CX,CY,R", help="circle, centre and radius")
    init.add_argument(
        "--snap",
        action=argparse.BooleanOptionalAction,
        default=None,
        help="snap the outline onto the object inside it on the first frame (GrabCut, under "
        "a second at 854x480): the default for --init-box; --snap for a loose polygon or "
        "circle; --no-snap keeps the box as given",
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
        help="contour nodes, >= 3 (default: 128)",
    )
    t.add_argument(
        "--stiffness", "-a", type=float, metavar="A", help="a = k/m > 0 (default: the tracker's)"
    )
    t.add_argument(
        "--option", "-O", action="append", default=[], metavar="KEY=VALUE",
        help="another tracker option, e.g. search_radius=16 (repeatable); VALUE is JSON, else text",
    )  # fmt: skip
    t.add_argument("--out", "-o", metavar="JSONL", help="write the records here, not stdout")
    t.add_argument("--overlay", metavar="VIDEO", help="also write a video with the contour drawn")
    t.add_argument("--quiet", "-q", action="store_true", help="no progress line on stderr")
    t.set_defaults(handler=run)
