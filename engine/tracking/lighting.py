"""``Lighting``: undo a gradual change of light, so that the colours learnt earlier still apply.

When a cloud passes, a lamp dims or a camera's exposure or white balance drifts,
every colour of the scene is scaled, channel by channel.  The colour models
(:mod:`engine.tracking.appearance`, :mod:`engine.tracking.local_colour`) learn
online, but only from confident frames and a few per cent at a time: a change of
a third over a few seconds leaves them behind, the object stops looking like
itself, and the track is lost.

Per frame and channel, the change of light is measured as a robust mean ratio of
a pixel's level now to its level in the previous frame (the mean over the points
near the median, re-centred on itself: a step below a grey level is still measured
in full, :func:`engine.tracking._lighting_kernel.ratio_step`), twice:

- over the whole frame, at the same pixels (an 8-pixel grid): many pixels, but a
  camera's pan pairs different points of the scene;
- over the object's interior carried by its measured motion (the prediction's
  similarity): the same points of the scene, but an object turning or flexing
  changes what is seen there.

A change of light scales both alike; motion disturbs each in its own way.  The
step taken is the smaller of the two where they agree in sign and none where
they disagree (the "minmod" of the two), so that motion alone hardly moves the
estimate.  The steps add up, as log gains, to the light now against the light
on the first frame.  Only what exceeds :data:`ABSORBED` is undone (a per-channel
lookup table on the frame): the colour models' bins and their online learning
absorb a small drift, and leaving the frame untouched then keeps the tracker
exactly as it is without this stage on video whose light does not change.
Levels from :data:`BRIGHT` up may be clipped light, which did not scale: a
darkening spreads them over what is left up to 255, so white stays white.

Coordinates are ``[x, y]`` pixels (x = column, y = row), as in OpenCV.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray

from engine.geometry import bounding_box, contour_to_mask
from engine.tracking._state_codec import pack_raw, unpack_raw
from engine.tracking.stages import Move

__all__ = ["ABSORBED", "Lighting"]

ABSORBED = 0.05
"""Log gain (about 5 %) the colour models absorb without help: 6 grey levels at mid-grey,
a third of a bin of the global model's 16 levels when it was chosen (four fifths of one
of its 32 levels since), and 5 % learning per confident frame follows such a drift.  Only
the change of light beyond it is undone (``lighting_change`` still passes on every seed of
24 at 32 levels)."""
GRID = 8
"""Pixels between the whole frame's sample points: 6,400 points at 854 x 480, a tenth of
a millisecond (a 4-pixel grid, four times the points and the time, tracked the thirty
training sequences no better)."""
OBJECT_POINTS = 1024
"""About this many points of the object's interior are compared: the median of a
thousand ratios is steady to a fraction of a per cent."""
INSET = 3
"""Object points stay this many pixels inside its contour: the contour's own
error and the mixed pixels of the boundary are not the object's colour."""
DARK, BRIGHT = 12, 243
"""Levels at or below 12 (noise and black clipping) or at or above 243 (saturation)
do not scale with the light; points with any such channel are left out."""
MOVED = 0.1
"""A point whose ratio is more than 10 % from the median (then from the mean) on any
channel changed for another reason than the light (motion, occlusion) and is left out of
the mean."""
MIN_POINTS = 50
"""Fewer agreeing points than this measure nothing: the step is taken as zero."""
MAX_LOG_GAIN = 8.0
"""A state's log gains beyond e^8 (about 3000) are not a light the levels could show."""


def _levels(image: NDArray[np.uint8]) -> NDArray[np.uint8]:
    """The image as H x W x C (grey: C = 1), a view."""
    return image[..., None] if image.ndim == 2 else image


class Lighting:
    """The change of light since the track's first frame, per channel, and its undoing.

    Attributes
    ----------
    log_gains : numpy.ndarray
        (C,) float64, C = 3 (BGR) or 1 (grey): natural log of the factor that
        brings each channel back to the first frame's light (0: unchanged).
    """

    def __init__(self) -> None:
        self.log_gains = np.zeros(3)
        self._sample: NDArray[np.uint8] | None = None
        self._points: NDArray[np.int64] | None = None
        self._colours: NDArray[np.uint8] | None = None

    def start(self, image: NDArray[np.uint8], nodes: NDArray[np.float64]) -> None:
        """The first frame of a track (``nodes``: its contour): the reference light."""
        self.log_gains = np.zeros(_levels(image).shape[2])
        self._sample = _grid_sample(image)
        self.learn(image, nodes)

    def resume(self, image: NDArray[np.uint8], nodes: NDArray[np.float64]) -> None:
        """Go on from this frame (``nodes``: the contour on it) after frames of another
        kind (:mod:`engine.tracking.looks`): the gains are kept, the frame and the object's
        colours taken here are what the next frame is compared with."""
        self._sample = _grid_sample(image)
        self.learn(image, nodes)

    @staticmethod
    def whole(
        previous: NDArray[np.uint8] | None, image: NDArray[np.uint8]
    ) -> tuple[NDArray[np.uint8], NDArray[np.float64] | None]:
        """The frame on the grid, and the whole frame's change of light since ``previous``
        (the previous frame on the grid; None: not measurable), as :meth:`compensate`
        measures it: what several objects' trackers of one frame share."""
        sample = _grid_sample(image)
        if previous is None or previous.shape != sample.shape:
            return sample, None
        return sample, _step(previous, sample)

    def compensate(
        self,
        image: NDArray[np.uint8],
        matrix: NDArray[np.float64],
        whole: tuple[NDArray[np.uint8], NDArray[np.float64] | None] | None = None,
    ) -> NDArray[np.uint8]:
        """Measure the light's change since the previous frame; ``image`` in the first one's light.

        Parameters
        ----------
        image : numpy.ndarray
            The new frame, H x W x 3 BGR or H x W grey uint8, as it was taken.
        matrix : numpy.ndarray
            2 x 3 similarity mapping the previous frame's ``[x, y]`` to this
            one's: the object's motion (:class:`~engine.tracking.stages.Prediction`).
        whole : tuple, optional
            :meth:`whole` of this tracker's previous frame and ``image``, measured
            once for several trackers (else measured here).

        Returns
        -------
        numpy.ndarray
            ``image`` itself while the change is within :data:`ABSORBED`; else a
            new image with each channel scaled back (clipped to 0-255).
        """
        known = self._sample is not None
        self._sample, frame_step = self.whole(self._sample, image) if whole is None else whole
        if known and frame_step is not None and len(frame_step) == len(self.log_gains):
            inner = self._object_step(_levels(image), matrix)
            if inner is not None:
                self.log_gains -= _minmod(frame_step, inner)
        return self.apply(image)

    def apply(self, image: NDArray[np.uint8]) -> NDArray[np.uint8]:
        """``image`` scaled back by the gains beyond :data:`ABSORBED` (itself if none)."""
        excess = np.sign(self.log_gains) * np.maximum(abs(self.log_gains) - ABSORBED, 0.0)
        if not excess.any() or _levels(image).shape[2] != len(excess):
            return image
        factor = np.exp(excess)
        levels = np.arange(256, dtype=np.float64)[:, None]
        table = levels * factor
        # a darkening keeps white white: levels from BRIGHT up may be clipped light,
        # which did not scale, so they are spread over what is left up to 255
        top = BRIGHT * factor + (levels - BRIGHT) * (255 - BRIGHT * factor) / (255 - BRIGHT)
        table = np.where((levels > BRIGHT) & (factor < 1), top, table)
        lut = np.clip(np.round(table), 0, 255).astype(np.uint8)
        return np.asarray(cv2.LUT(image, lut.reshape(256, 1, -1)), dtype=np.uint8)

    def rescale(self, move: Move) -> None:
        """The object's interior points on another grid (``move`` maps old-grid ``[x, y]``
        points onto it; :func:`engine.tracking.regrid.follow_size`).  The frame's sample,
        of the old grid's size, measures no change on the next frame and is then renewed."""
        if self._points is not None:
            self._points = np.rint(move(self._points.astype(np.float64))).astype(np.int64)

    def learn(self, image: NDArray[np.uint8], nodes: NDArray[np.float64]) -> None:
        """Remember the colours of the object's interior (``nodes``: its contour on ``image``,
        the frame as taken), to be compared with the next frame."""
        from engine.tracking._lighting_kernel import interior

        self._points = self._colours = None
        levels = _levels(image)
        x0, y0, x1, y1 = bounding_box(levels.shape, nodes, 0, 1, keep_inside=False)
        if x1 - x0 < 1 or y1 - y0 < 1:
            return
        # a grid of about OBJECT_POINTS over the box; its points INSET inside the contour
        stride = max(1, math.isqrt((x1 - x0) * (y1 - y0) // OBJECT_POINTS))
        shape = ((y1 - y0 - 1) // stride + 1, (x1 - x0 - 1) // stride + 1)
        inside = contour_to_mask((nodes - [x0, y0]) / stride, shape)
        reach = -(-INSET // stride)  # ceil: at least INSET pixels
        # the grid points whose neighbourhood is all inside (erosion leaves the border alone)
        core = cv2.erode(inside, np.ones((2 * reach + 1, 2 * reach + 1), np.uint8))
        frame = np.ascontiguousarray(levels)
        points, colours = interior(np.asarray(core, np.uint8), 0, (x0, y0), stride, frame)
        if len(points) >= MIN_POINTS:
            self._points, self._colours = points, colours

    def _object_step(
        self, levels: NDArray[np.uint8], matrix: NDArray[np.float64]
    ) -> NDArray[np.float64] | None:
        """The ratio over the remembered interior points carried by ``matrix``."""
        from engine.tracking._lighting_kernel import carried

        if self._points is None or self._colours is None:
            return None
        if self._colours.shape[1] != levels.shape[2]:
            return None
        image = np.ascontiguousarray(levels)
        before, after = carried(self._points, self._colours, np.ascontiguousarray(matrix), image)
        return _step(before, after)

    def to_state(self, *, compact: bool = False) -> dict[str, Any]:
        """JSON-able state; ``compact``: the gains only (the next frame then measures no step)."""
        state: dict[str, Any] = {"log_gains": self.log_gains.tolist()}
        if compact:
            return state
        sample, points, colours = self._sample, self._points, self._colours
        state["sample"] = None
        if sample is not None:
            state["sample"] = {"shape": list(sample.shape), "data": pack_raw(sample)}
        state["points"] = state["colours"] = None
        if points is not None and colours is not None:
            state["points"] = pack_raw(points.astype("<i4"))
            state["colours"] = pack_raw(colours)
        return state

    @classmethod
    def from_state(cls, state: Mapping[str, Any]) -> Lighting:
        """Inverse of :meth:`to_state`; ValueError if malformed."""
        out = cls()
        gains = np.asarray(state["log_gains"], dtype=np.float64)
        if gains.shape not in ((1,), (3,)) or not (abs(gains) <= MAX_LOG_GAIN).all():
            raise ValueError(f"lighting: log_gains must be 1 or 3 numbers in ±{MAX_LOG_GAIN}")
        out.log_gains = gains
        channels = len(gains)
        sample = state.get("sample")
        if sample is not None:
            k, c = (int(v) for v in sample["shape"])
            # the last frame's channels, which a stream switching between grey and colour
            # frames of one size can make differ from the gains' (``whole`` then measures
            # no change)
            if c not in (1, 3) or not 0 < k <= 1 << 20:
                raise ValueError("lighting: bad sample shape")
            out._sample = unpack_raw(sample["data"], np.uint8, k * c).reshape(k, c)
        points, colours = state.get("points"), state.get("colours")
        if points is not None and colours is not None:
            xy = unpack_raw(points, np.dtype("<i4"), None).reshape(-1, 2).astype(np.int64)
            out._points = xy
            # one or three channels, as the frame they were taken from (see the sample)
            values = unpack_raw(colours, np.uint8, None)
            depth = len(values) // len(xy) if len(xy) else channels
            if depth not in (1, 3) or len(values) != len(xy) * depth:
                raise ValueError("lighting: colours do not match the points")
            out._colours = values.reshape(-1, depth)
        return out


def _grid_sample(image: NDArray[np.uint8]) -> NDArray[np.uint8]:
    """(K, C) colours of the frame at every :data:`GRID`-th pixel."""
    from engine.tracking._lighting_kernel import grid_sample

    sample: NDArray[np.uint8] = grid_sample(np.ascontiguousarray(_levels(image)), GRID)
    return sample


def _step(before: NDArray[np.uint8], after: NDArray[np.uint8]) -> NDArray[np.float64] | None:
    """Per channel log ratio of the light from ``before`` to ``after`` ((K, C) colours of the same
    points), None when fewer than :data:`MIN_POINTS` points changed only by the light."""
    from engine.tracking._lighting_kernel import LOG, SCALE, ratio_step

    moved = round(MOVED * SCALE)
    before, after = np.ascontiguousarray(before), np.ascontiguousarray(after)
    kept, step = ratio_step(before, after, LOG, DARK, BRIGHT, moved)
    return step if kept >= MIN_POINTS else None


def _minmod(a: NDArray[np.float64], b: NDArray[np.float64]) -> NDArray[np.float64]:
    """Per channel, the smaller of two estimates where they agree in sign, else 0."""
    out: NDArray[np.float64] = np.where(a * b > 0, np.sign(a) * np.minimum(abs(a), abs(b)), 0.0)
    return out
