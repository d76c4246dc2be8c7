"""Tracking benchmark pictures: the J bar chart and the contact sheets.

Contact sheets are written for the clips where efdm scores lowest: the DAVIS sequences of
every set that ran together (``tracking_sheet_davis_<name>.jpg``, kept out of git by
``.gitignore``: the data's terms allow evaluation, not copies in the repository) and, apart,
the synthetic conditions (``tracking_sheet_synthetic_<name>.jpg``).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING

import cv2
import numpy as np
from numpy.typing import NDArray

from bench.common.data import Clip, Frame
from bench.tracking.goals import GOALS
from bench.tracking.run import ClipResult, mean_j
from bench.tracking.sets import ClipSpec, is_davis, resized
from bench.tracking.tables import worst_first
from bench.tracking.trackers import Nodes

if TYPE_CHECKING:
    from matplotlib.axes import Axes

REFERENCE_LINES = {
    "davis-train": ("tracker when the set arrived (README)", 0.547),
    "davis-val": ("rigid + snap (README, frames 1..T)", 0.581),
}
BAR_COLOURS = {"efdm": "tab:red", "static": "tab:grey", "skimage": "tab:blue"}
SHEET_COLOURS = {"static": (160, 160, 160), "skimage": (255, 140, 0), "efdm": (0, 0, 255)}
"""BGR colours of the contours on the contact sheets; drawn in this order, efdm on top."""
LABEL_COLOURS = {"static": (200, 200, 200), "skimage": (255, 170, 60), "efdm": (80, 80, 255)}
"""BGR colours of the J labels (lighter than the contours, for the dark label box)."""
COLOUR_NAMES = {"static": "grey", "skimage": "blue", "efdm": "red"}
GT_COLOUR = (0, 200, 0)
TILE_WIDTH = 400
COLUMNS = 3


# --------------------------------------------------------------------------- bar chart


def draw_bars(
    ax: Axes, results: Sequence[ClipResult], trackers: Sequence[str], with_mean: bool
) -> None:
    """Grouped bars: mean J per clip (and overall mean) for each tracker."""
    labels = [r.name for r in results] + (["mean"] if with_mean else [])
    width = 0.8 / max(len(trackers), 1)
    x = np.arange(len(labels))
    for k, tracker in enumerate(trackers):
        values = [r.runs[tracker].mean_j if tracker in r.runs else math.nan for r in results]
        if with_mean:
            values.append(mean_j(results, tracker))
        offset = (k - (len(trackers) - 1) / 2) * width
        colour = BAR_COLOURS.get(tracker, f"C{k}")
        ax.bar(x + offset, values, width, label=tracker, color=colour)
    ax.set_xticks(x, labels, rotation=30, ha="right", fontsize=8)
    ax.set(ylim=(0.0, 1.22), ylabel="mean J (IoU)")
    ax.set_yticks(np.linspace(0.0, 1.0, 6))
    ax.grid(True, axis="y", alpha=0.3)


def limited_note(results: Sequence[ClipResult]) -> str:
    """A title note naming trackers that tracked only part of some clips."""
    limited = sorted(
        {
            f"{t}: first {run.frames} frames"
            for r in results
            for t, run in r.runs.items()
            if run.frames < r.frames
        }
    )
    return f" ({'; '.join(limited)})" if limited else ""


def plot_scores(
    sets: Mapping[str, Sequence[ClipResult]], trackers: Sequence[str], path: Path
) -> None:
    """Mean J per clip of every set (one panel each, stacked), with the goal lines."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    panels = [(name, clips) for name, clips in sets.items() if clips]
    if not panels:
        return
    widest = max(len(clips) + 1 for _, clips in panels)
    fig, axes = plt.subplots(
        len(panels),
        1,
        figsize=(max(8.0, 2.5 + 0.38 * widest), 3.8 * len(panels)),
        layout="constrained",
        squeeze=False,
    )
    for ax, (name, clips) in zip(axes[:, 0], panels, strict=True):
        draw_bars(ax, clips, trackers, with_mean=is_davis(name))
        goal = GOALS[name]
        ax.axhline(goal, color="black", linestyle="--", linewidth=1, label=f"goal {goal:g}")
        if name in REFERENCE_LINES:
            label, value = REFERENCE_LINES[name]
            ax.axhline(value, color="tab:green", linestyle=":", linewidth=1.5, label=label)
        ax.set_title(f"{name}: mean J over frames 1..T-2{limited_note(clips)}", fontsize=10)
        ax.legend(fontsize=7, loc="upper center", ncol=5)
    fig.suptitle("Contour tracking: mean J per sequence (128 nodes)")
    fig.savefig(path, dpi=100)
    plt.close(fig)


# --------------------------------------------------------------------------- contact sheets


def sheet_indices(frames: int, count: int = 6) -> list[int]:
    """``count`` evenly spaced frame indices from 0 to ``frames - 1`` (no repeats)."""
    return sorted({int(v) for v in np.linspace(0, frames - 1, count).round()})


def draw_polyline(tile: Frame, points: Nodes, colour: tuple[int, int, int], thickness: int) -> None:
    """A closed polyline at sub-pixel precision (coordinates already in tile pixels)."""
    if len(points) >= 2 and np.isfinite(points).all():
        fixed = np.round(np.clip(points, -1e5, 1e5) * 16).astype(np.int32).reshape(-1, 1, 2)
        cv2.polylines(tile, [fixed], True, colour, thickness, cv2.LINE_AA, shift=4)


def put_lines(
    tile: Frame, lines: Sequence[tuple[str, tuple[int, int, int]]], origin: tuple[int, int]
) -> None:
    """Coloured text lines on a dark box, top-left corner at ``origin``."""
    font, scale, height = cv2.FONT_HERSHEY_SIMPLEX, 0.5, 18
    width = max(cv2.getTextSize(text, font, scale, 1)[0][0] for text, _ in lines)
    x, y = origin
    cv2.rectangle(tile, (x, y), (x + width + 8, y + height * len(lines) + 4), (24, 24, 24), -1)
    for row, (text, colour) in enumerate(lines):
        cv2.putText(
            tile, text, (x + 4, y + height * (row + 1) - 3), font, scale, colour, 1, cv2.LINE_AA
        )


def draw_tile(clip: Clip, result: ClipResult, index: int) -> Frame:
    """One frame, downscaled, with the ground truth and every tracker's contours."""
    height, width = clip.shape
    scale = TILE_WIDTH / width
    size = (TILE_WIDTH, round(height * scale))
    resized = cv2.resize(clip.frames[index], size, interpolation=cv2.INTER_AREA)
    tile = np.ascontiguousarray(resized, dtype=np.uint8)
    outlines, _ = cv2.findContours(
        (clip.masks[index] > 0).astype(np.uint8), cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE
    )
    for outline in outlines:
        draw_polyline(tile, outline.reshape(-1, 2).astype(np.float64) * scale, GT_COLOUR, 2)
    lines = [(f"frame {index}", (255, 255, 255))]
    for tracker, colour in SHEET_COLOURS.items():
        run = result.runs.get(tracker)
        if run is not None and index < len(run.nodes):
            others = run.others[index] if index < len(run.others) else ()
            for nodes in (run.nodes[index], *others):
                draw_polyline(tile, nodes * scale, colour, 2 if tracker == "efdm" else 1)
            lines.append((f"{tracker} J {run.iou[index]:.2f}", LABEL_COLOURS[tracker]))
    put_lines(tile, lines, (0, 0))
    return tile


def contact_sheet(clip: Clip, result: ClipResult, count: int = 6) -> Frame:
    """A grid of ``count`` evenly spaced frames with a header naming the colours."""
    tiles = [draw_tile(clip, result, i) for i in sheet_indices(len(clip.frames), count)]
    rows = math.ceil(len(tiles) / COLUMNS)
    blank = np.zeros_like(tiles[0])
    tiles += [blank] * (rows * COLUMNS - len(tiles))
    grid = np.vstack([np.hstack(tiles[r * COLUMNS : (r + 1) * COLUMNS]) for r in range(rows)])
    header = np.full((28, grid.shape[1], 3), 32, dtype=np.uint8)
    trackers = [t for t in SHEET_COLOURS if t in result.runs]
    legend = ", ".join(f"{t} {COLOUR_NAMES[t]}" for t in trackers)
    title = f"{clip.source} {clip.name}: ground truth green, {legend}"
    put_lines(header, [(title, (255, 255, 255))], (2, 1))
    return np.vstack([header, grid])


def write_sheet(image: NDArray[np.uint8], path: Path) -> None:
    """Save a contact sheet as JPEG (quality 88)."""
    if not cv2.imwrite(str(path), image, [cv2.IMWRITE_JPEG_QUALITY, 88]):
        raise OSError(f"cannot write {path}")


def save_sheet(clip: Clip, result: ClipResult, out: Path) -> str:
    """Write ``tracking_sheet_<davis|synthetic>_<name>.jpg`` into ``out``; the file name."""
    kind = "davis" if is_davis(clip.source) else "synthetic"
    file_name = f"tracking_sheet_{kind}_{clip.name}.jpg"
    out.mkdir(parents=True, exist_ok=True)
    write_sheet(contact_sheet(clip, result), out / file_name)
    return file_name


def write_sheets(
    sets: Mapping[str, Sequence[ClipResult]],
    davis: int,
    synthetic: int,
    out: Path,
    stride: int = 1,
) -> list[str]:
    """Sheets of the ``davis`` DAVIS clips (all sets together) and the ``synthetic`` synthetic
    conditions where efdm scores lowest (the first ones when efdm did not run), worst first;
    the clips are loaded again (the results keep the contours, not the frames), the DAVIS
    ones with one frame in ``stride`` as they were tracked."""
    davis_clips = [c for name, clips in sets.items() if is_davis(name) for c in clips]
    chosen = [
        *worst_first(davis_clips)[:davis],
        *worst_first(sets.get("synthetic", []))[:synthetic],
    ]
    return [save_sheet(resized(_reloaded(c, stride).load(), c.shape), c, out) for c in chosen]


def _reloaded(clip: ClipResult, stride: int) -> ClipSpec:
    """The clip a result was tracked on: its ``frames`` one in ``stride`` of the first
    ``frames * stride`` (DAVIS; a synthetic clip is drawn as it was)."""
    if not is_davis(clip.source) or stride == 1:
        return ClipSpec(clip.source, clip.name, clip.frames)
    return ClipSpec(clip.source, clip.name, clip.frames * stride, stride=stride)
