"""``RecentShapes``: the shapes of the last frames on the object, for the confidence.

The confidence (:mod:`engine.tracking.confidence`) asks whether a contour still has
the object's shape: a contour that slid onto object-coloured background, or shrank
onto one part of the object, looks object-like inside but has lost it.  It used to
compare the contour with the first frame's outline alone
(:func:`~engine.tracking.confidence.shape_overlap`, the outline carried and turned
with the object).  An object whose shape changes for good, a dog stretched out as it
runs or a dancer with her arms up, then looks less and less like itself while it is
tracked well: on the validation sequences a running dog's well-tracked frames (IoU
0.7-0.8) overlapped the outline by 0.37-0.44 and were reported ``uncertain``.

So the shape is also compared with the contours of the last :data:`RECENT_FRAMES`
frames that were on the object, and the best overlap counts.  Which frames were on the
object is decided by the confidence model of the outline alone (:func:`remembered`), not
by the reported one, which reads these shapes: fed its own output, a contour reported
``tracking`` on the background would vouch for its next frames.  A gradual change
of shape matches the frames just before it; a contour that slid onto something else,
or shrank onto a part, matches neither them nor the outline; and one whose frames
stopped being judged on the object loses the support of its own recent shapes within
:data:`RECENT_FRAMES` frames.  Coordinates are ``[x, y]`` pixels (x = column, y =
row), as in OpenCV.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Final

import numpy as np
from numpy.typing import NDArray

from engine.tracking._state_codec import pack_raw, unpack_raw
from engine.tracking.confidence import (
    SHAPE_GRID,
    TRACKING_FROM,
    Evidence,
    logistic_confidence,
    shape_mask,
)

__all__ = [
    "GREY_OUTLINE_COEFFICIENTS",
    "OUTLINE_COEFFICIENTS",
    "RECENT_FRAMES",
    "RecentShapes",
    "remembered",
]

RECENT_FRAMES: Final = 20
"""Frames back whose shapes (where :func:`remembered`) a contour is compared with:
two thirds of a second at 30 frames a second.  Chosen on folds of the thirty DAVIS-2016
training sequences by the held-out lost detection, on their tracks at five node counts
(the confidence model refitted on four folds and scored on the fifth, a one-off script
on the rows of ``python -m bench.tracking.confidence``, the frames that model reported
``tracking`` remembered): 3, 5, 10, 20, 30 and 40 frames
flagged 71.5, 79.5, 87.9, 91.6, 92.3 and 87.9 % of the frames with IoU < 0.2, and kept
96.3-96.5 % of those with IoU >= 0.6 ``tracking`` (78.5 % and 95.6 % with the outline
alone).  Past a second the window holds shapes the object has left behind."""
OUTLINE_COEFFICIENTS = (
    -4.7263,
    4.9001,
    -0.7458,
    0.2034,
    0.3076,
    0.1327,
    0.127,
    2.6549,
    -3.3755,
    -2.6747,
)
"""The reported model as it was before the recent shapes (2026-11-29, night), its shape
input the overlap with the outline alone: it now only decides which frames' shapes are
remembered (:func:`remembered`).  The reported model reads those shapes, so a gate of its
own would feed its output back into its input, and refitting it would change the very
frames it is fitted on (tried: refitted twice, the held-out figures swung from 96 % of the
bad frames flagged to 64 %).  A fixed gate keeps the fit one pass."""
GREY_OUTLINE_COEFFICIENTS = (
    -3.5652,
    2.9643,
    -1.537,
    0.2402,
    0.3406,
    -0.4465,
    0.3478,
    3.8287,
    -1.5549,
    -0.4934,
)
""":data:`OUTLINE_COEFFICIENTS` for grey frames (the reported
:data:`~engine.tracking.confidence.GREY_COEFFICIENTS` as it was)."""
_BYTES = SHAPE_GRID * SHAPE_GRID // 8
"""Bytes of one shape packed to bits (the grid's side is a multiple of 8)."""


def remembered(e: Evidence) -> bool:
    """Whether a contour's shape is one to compare later contours with: its confidence by
    the models of the overlap with the outline alone (:data:`OUTLINE_COEFFICIENTS`,
    :data:`GREY_OUTLINE_COEFFICIENTS` for grey frames) is at least
    :data:`~engine.tracking.confidence.TRACKING_FROM`."""
    model = GREY_OUTLINE_COEFFICIENTS if e.grey else OUTLINE_COEFFICIENTS
    return logistic_confidence(e, model, e.shape) >= TRACKING_FROM


class RecentShapes:
    """The last :data:`RECENT_FRAMES` frames' shapes, None where a frame's was not remembered."""

    def __init__(self, shapes: Sequence[NDArray[np.bool_] | None] = ()) -> None:
        self._shapes: list[NDArray[np.bool_] | None] = []
        # the same shapes in a ring of grids the comparison reads in place (stacking them
        # anew for each comparison cost 0.018 ms a frame): slot k holds a kept shape
        # where kept[k]; the next frame's goes to slot ``_next``, over the oldest
        self._grids = np.zeros((RECENT_FRAMES, SHAPE_GRID, SHAPE_GRID), np.bool_)
        self._kept = np.zeros(RECENT_FRAMES, np.bool_)
        self._next = 0
        for shape in list(shapes)[-RECENT_FRAMES:]:
            self._append(shape)

    def _append(self, shape: NDArray[np.bool_] | None) -> None:
        """Keep ``shape`` (None: a frame not remembered) as the newest frame's."""
        if shape is not None and np.shape(shape) != (SHAPE_GRID, SHAPE_GRID):
            raise ValueError(
                f"a recent shape must be a {SHAPE_GRID} x {SHAPE_GRID} grid; got {np.shape(shape)}"
            )
        self._shapes.append(shape)
        del self._shapes[:-RECENT_FRAMES]
        slot, self._next = self._next, (self._next + 1) % RECENT_FRAMES
        self._kept[slot] = shape is not None
        if shape is not None:
            self._grids[slot] = shape

    def add(
        self,
        nodes: NDArray[np.float64],
        remember: bool,
        shape: NDArray[np.bool_] | None = None,
    ) -> None:
        """Count a frame: its contour ``nodes`` ((N, 2) ``[x, y]``), kept if ``remember``;
        ``shape``: its :func:`~engine.tracking.confidence.shape_mask` if made already."""
        if remember and shape is None:
            shape = shape_mask(nodes)
        self._append(shape if remember else None)

    def overlap(self, shape: NDArray[np.bool_] | None) -> float:
        """The best overlap of a contour's ``shape`` (its
        :func:`~engine.tracking.confidence.shape_mask`, None: no area) with the kept shapes,
        each moved to its own centroid and scaled to the same area; 0 when none is kept."""
        if shape is None or not self._kept.any():
            return 0.0
        from engine.tracking._shape_kernels import best_overlap

        # mask_iou with each kept grid; the largest does not depend on their order
        return float(best_overlap(self._grids, self._kept, np.ascontiguousarray(shape)))

    def to_state(self) -> list[str | None]:
        """JSON-able: per frame, the shape packed to bits (base64), or None."""
        return [None if s is None else pack_raw(np.packbits(s)) for s in self._shapes]

    @classmethod
    def from_state(cls, state: object) -> RecentShapes:
        """Inverse of :meth:`to_state`; ValueError if malformed."""
        if not isinstance(state, list) or len(state) > RECENT_FRAMES:
            raise ValueError(f"recent shapes must be a list of at most {RECENT_FRAMES} entries")
        shapes: list[NDArray[np.bool_] | None] = []
        for entry in state:
            if entry is None:
                shapes.append(None)
                continue
            if not isinstance(entry, str):
                raise ValueError("a recent shape must be packed text or null")
            try:
                packed = unpack_raw(entry, np.uint8, _BYTES)
            except ValueError as error:
                raise ValueError(f"a recent shape must be {SHAPE_GRID}² bits: {error}") from None
            bits = np.unpackbits(packed)
            shapes.append(bits.reshape(SHAPE_GRID, SHAPE_GRID).astype(np.bool_))
        return cls(shapes)
