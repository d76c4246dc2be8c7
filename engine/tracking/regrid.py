"""A track's grid following its object's size: a large object is tracked coarser as it grows.

A track starts on the grid :func:`engine.tracking.working.object_grid_side` chooses for
its first contour: an object larger than
:attr:`~engine.tracking.options.TrackerOptions.object_side` is tracked on a grid on which
it is that size.  An object that grows on its way (one coming towards the camera) would
otherwise be tracked on its first grid at any size, every stage's cost growing with its
pixels: the validation sequence ``soapbox`` starts at 80 pixels and ends at 300, and
took 25 ms a frame at its end against 12 at its start.  :func:`follow_size` moves the
track to the grid its contour now asks for once that grid differs from the one it is on
by :data:`CHANGE` or more, either way (an object that shrank goes back to a finer one):

* the contour, the shape the search looks for and the remembered outline are mapped
  exactly (grid to frame to grid);
* the previous frame is resized onto the new grid, and each stage maps what it keeps
  of the frame before (``rescale``: the motion's corners, the cue maps' p(object)
  around the contour, the cut's window size, the light's interior points);
* what is learnt about the object's look (the colour models, the usual look, the
  recent shapes, which are compared at one size) does not depend on the grid and is
  kept as it is.

Only a confident track moves (its last result ``tracking``, not on probation after a
re-acquisition): the size of a contour that leaked into the background is not the
object's.  A tracker with a stage that has no ``rescale`` stays on its first grid.
Coordinates are ``[x, y]`` pixels (x = column, y = row), as in OpenCV.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any, Final

import cv2
import numpy as np
from numpy.typing import NDArray

from engine.tracking.confidence import TRACKING_FROM
from engine.tracking.stages import Move
from engine.tracking.working import WorkingScale, object_grid_side, working_scale

if TYPE_CHECKING:
    from engine.tracking.tracker import Tracker

__all__ = ["CHANGE", "follow_size", "grid_lines", "rescaled_map"]

CHANGE: Final = 1.25
"""The grid is changed when the one the contour asks for has a quarter more or fewer
lines than the one it is on: the object's size changed by a quarter since its grid was
chosen (its pixels by half again).  A few changes over a sequence as ``soapbox``'s, not
one every frame as its size wavers."""


def grid_lines(shape: tuple[int, int], side: int) -> int:
    """The lines of the grid of ``side`` (0: none) for frames of ``shape`` ``(height, width)``.

    Raises
    ------
    ValueError
        If ``shape`` is not two positive sides or ``side`` is negative.
    """
    if len(shape) != 2 or min(int(shape[0]), int(shape[1])) < 1:
        raise ValueError(f"shape must be (height, width) of positive sides; got {shape}")
    if side < 0:
        raise ValueError(f"side must be 0 (none) or positive; got {side}")
    shorter = min(int(shape[0]), int(shape[1]))
    return shorter if side == 0 else min(int(side), shorter)


def follow_size(tracker: Tracker) -> bool:
    """Move ``tracker`` to the grid its contour's size asks for, if it must; True if moved.

    Called before a frame of the size of the last one is tracked.  ``tracker``'s
    contour, memory, previous frame and stages are mapped onto the new grid
    (see the module's docstring); nothing happens when the object's grid is off
    (``object_side`` 0), the track is not confidently on the object, a stage cannot
    be rescaled, or the grid the contour asks for is within :data:`CHANGE` of the one
    it is on.
    """
    opts, shape, previous = tracker.options, tracker._frame_shape, tracker._previous
    if opts.object_side <= 0 or shape is None or previous is None:
        return False
    memory = tracker._memory
    if tracker._reported < TRACKING_FROM or memory.probation > 0:
        return False
    stages = (tracker.motion, tracker.cues, tracker.segmentation)
    rescales: list[Any] = [getattr(stage, "rescale", None) for stage in stages]
    if not all(callable(rescale) for rescale in rescales):
        return False
    nodes = tracker._in_frame(tracker._nodes)
    side = object_grid_side(shape, nodes, opts.working_side, opts.object_side)
    now, then = grid_lines(shape, side), grid_lines(shape, tracker._grid_side)
    if max(now, then) < CHANGE * min(now, then):
        return False
    old, new = tracker._scale, working_scale(shape, side)

    def move(points: NDArray[np.float64]) -> NDArray[np.float64]:
        frame = np.asarray(points, np.float64) if old is None else old.to_frame(points)
        return frame if new is None else new.to_working(frame)

    factor = now / then
    for rescale in rescales:
        rescale(move, factor)
    if opts.lighting:
        tracker._lighting.rescale(move)
    tracker._previous = _resized(previous, shape, new)
    tracker._nodes = move(tracker._nodes)
    memory.shape = move(memory.shape)
    if memory.outline is not None:
        memory.outline = move(memory.outline)
    tracker._scale, tracker._grid_side = new, side
    return True


def _resized(
    grey: NDArray[np.uint8], shape: tuple[int, int], scale: WorkingScale | None
) -> NDArray[np.uint8]:
    """The previous grey frame on the new grid (``scale``; None: the frames' own size)."""
    size = (shape[1], shape[0]) if scale is None else scale.size
    shrinking = size[0] < grey.shape[1]
    flags = cv2.INTER_AREA if shrinking else cv2.INTER_LINEAR
    return np.ascontiguousarray(cv2.resize(grey, size, interpolation=flags), dtype=np.uint8)


def rescaled_map(
    origin: tuple[int, int], values: NDArray[np.uint8], move: Move
) -> tuple[tuple[int, int], NDArray[np.uint8]]:
    """A map of a region of the old grid (``values`` at ``origin``, ``(x, y)`` of its
    top-left pixel) on the new one: its corners moved by ``move`` and the map resized
    (bilinear) to fit them, to within half a pixel.

    Raises
    ------
    ValueError
        If ``values`` is not a non-empty H x W uint8 map or ``origin`` not two
        non-negative integers.
    """
    if values.ndim != 2 or values.dtype != np.uint8 or values.size == 0:
        raise ValueError(f"values must be a non-empty H x W uint8 map; got {values.shape}")
    if len(origin) != 2 or not all(isinstance(v, int | np.integer) and v >= 0 for v in origin):
        raise ValueError(f"origin must be two non-negative integers (x, y); got {origin}")
    h, w = values.shape
    x0, y0 = origin
    corners = np.array([[x0 - 0.5, y0 - 0.5], [x0 + w - 0.5, y0 + h - 0.5]], np.float64)
    (a, b), (c, d) = np.rint(move(corners) + 0.5).astype(int)
    nx0, ny0 = max(int(a), 0), max(int(b), 0)
    nx1, ny1 = max(int(c), nx0 + 1), max(int(d), ny0 + 1)
    out = cv2.resize(values, (nx1 - nx0, ny1 - ny0), interpolation=cv2.INTER_LINEAR)
    return (nx0, ny0), np.ascontiguousarray(out, dtype=np.uint8)
