"""Motion prediction between frames: pyramidal Lucas-Kanade, forward-backward
checked, and a robust similarity fit (OpenCV), at half resolution.

Both frames are cropped around the contour and halved (:class:`FramePair`);
the coarse pyramid levels and the forward-backward check run on the halves
(a quarter of the pixels), only the finest level at full resolution.

Coordinates are ``[x, y]`` pixels (x = column, y = row), as in OpenCV; a
pixel's centre has integer coordinates, at full and at half resolution.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import cv2
import numpy as np
from numpy.typing import NDArray

from engine.geometry import bounding_box, contour_to_mask, extent, fit_similarity
from engine.tracking.background import MEASURE, Background, background_motion, in_region
from engine.tracking.covering import covered_share, hidden_at

__all__ = ["MAX_FEATURES", "FramePair", "Motion", "estimate_motion"]

CONTEXT = 64
"""Pixels kept around the contour: more than any plausible motion between frames."""
MAX_FEATURES = 40
"""Corners sought inside the contour: enough for RANSAC to outvote a third of
them going astray, few enough that tracking them costs well under a millisecond."""
WINDOW = 9
"""Lucas-Kanade window side at half resolution: 18 frame pixels, enough texture
to lock on, small enough to stay on one part of an articulated object."""
LEVELS = 3
"""Pyramid levels above the half-resolution crop: with :data:`WINDOW` they follow
displacements of about 70 frame pixels."""
FINE_WINDOW = 15
"""Lucas-Kanade window side of the full-resolution refinement."""
FB_THRESHOLD = 1.0
"""Largest forward-backward error (frame pixels) of a point that is kept: a point
that does not come back to within a pixel of where it started was not tracked."""
RANSAC_THRESHOLD = 2.0
"""RANSAC inlier threshold (frame pixels): the similarity misses a non-rigid
object's own deformation by about this much between frames."""
MIN_POINTS = 3
"""Fewest points a similarity is fitted to: two determine it, a third can outvote
one that went astray."""
MIN_CROP = 4
"""Crops smaller than this (pixels) hold nothing to track."""
KEEP_TRACKED_SHARE = 4
"""Tracked corners are kept while at least a quarter of :data:`MAX_FEATURES` remain;
fewer, and corners are sought anew."""
NODE_STRIDE = 4
"""Every fourth node is tracked with the corners: the outline's own texture,
without tracking 128 nearly redundant points."""
CORNER_QUALITY = 0.01
"""``goodFeaturesToTrack`` quality level: corners down to 1 % of the strongest
one's response, so that weakly textured objects still get some."""
CORNER_SPACING = 3
"""Least distance (half-resolution pixels) between corners: no two in one window."""
CORNER_BLOCK = 3
"""Corner detector's neighbourhood (half-resolution pixels)."""
CORNER_REACH = 2
"""Corners are sought up to two half-resolution pixels outside the contour (a
5 x 5 dilation of its mask): the outline's corners belong to the object."""
LK_ITERATIONS = 10
"""Lucas-Kanade iterations per level; it converges in 3-5 on real frames."""
LK_EPSILON = 0.03
"""Lucas-Kanade stops when a step is smaller than this (pixels)."""
RUN_OFF = 2.0
"""A full-resolution refinement moving a point more than 2 pixels from its
half-resolution guess has lost the texture; the guess is kept."""
RANSAC_ITERATIONS = 500
"""RANSAC draws for the similarity: finds a fit with half the points inliers
with certainty far beyond 0.999."""
BACKGROUND_TOLERANCE = 1.0
"""A point that ends within 1 pixel (the forward-backward check's accuracy) of where the
background's motion takes it moved with the background."""
OBJECT_SHARE = 0.3
"""Points moving with the background are left out of the object's fit only when at least
this share of the tracked points (and :data:`MIN_POINTS`) move otherwise: fewer, and the
object moves with the background (a still object under a still camera, a passenger
carried along with it), so every point is the object's."""
MOSTLY_HIDDEN = 0.75
"""An object with more than 3/4 of its silhouette behind other tracked objects is not moved
by what little shows (a few points at its rim, some of them the front object's): it
stays where it was until more of it shows."""
MEDIAN_SUPPORT = 0.5
"""When RANSAC finds no similarity, the median shift is used, with half the
support the surviving points would give."""


@dataclass(frozen=True, slots=True)
class Motion:
    """A 2 x 3 similarity transform and how well the points supported it.

    Attributes
    ----------
    matrix : numpy.ndarray
        2 x 3 float64, maps ``[x, y, 1]`` of the previous frame to the current one.
    inlier_ratio : float
        Share of the tracked points that passed the forward-backward check
        and agreed with the fit, in [0, 1].
    points : int
        How many points were tracked.
    tracked : numpy.ndarray
        (K, 2) float32 ``[x, y]``: where the corners that agreed with the fit
        are in the current frame, to be tracked on from there.
    """

    matrix: NDArray[np.float64]
    inlier_ratio: float
    points: int
    tracked: NDArray[np.float32] = field(default_factory=lambda: np.zeros((0, 2), np.float32))

    def apply(self, nodes: NDArray[np.float64]) -> NDArray[np.float64]:
        """Transform ``[x, y]`` nodes."""
        result: NDArray[np.float64] = nodes @ self.matrix[:, :2].T + self.matrix[:, 2]
        return result

    @staticmethod
    def identity(points: int = 0) -> Motion:
        """No motion, no support."""
        return Motion(np.hstack([np.eye(2), np.zeros((2, 1))]), 0.0, points)


@dataclass(frozen=True, slots=True)
class FramePair:
    """Two grey frames cropped around a contour, at full and at half resolution.

    The half-resolution crops are ``cv2.INTER_AREA`` halvings: their pixel
    ``u`` averages crop pixels ``2u`` and ``2u + 1``, so crop point ``p`` is at
    ``p / 2 - 1/4`` there.

    Attributes
    ----------
    origin : tuple of int
        ``(x, y)`` of the crop's top-left pixel in the frame.
    previous, current : numpy.ndarray
        The crops, uint8, of equal shape (at least 1 x 1).
    half_previous, half_current : numpy.ndarray
        The crops halved (the crops themselves when under 2 pixels wide or high).
    """

    origin: tuple[int, int]
    previous: NDArray[np.uint8]
    current: NDArray[np.uint8]
    half_previous: NDArray[np.uint8]
    half_current: NDArray[np.uint8]

    @classmethod
    def around(
        cls,
        previous: NDArray[np.uint8],
        current: NDArray[np.uint8],
        nodes: NDArray[np.float64],
        *,
        margin: int = CONTEXT,
    ) -> FramePair:
        """Crop both grey frames to the nodes' box grown by ``margin``.

        Parameters
        ----------
        previous, current : numpy.ndarray
            Grey uint8 frames of equal size.
        nodes : numpy.ndarray
            (N, 2) ``[x, y]`` pixels, the contour in ``previous``.
        margin : int
            Context kept around the contour (pixels).
        """
        x0, y0, x1, y1 = bounding_box(previous.shape, nodes, margin, margin + 1)
        before = np.ascontiguousarray(previous[y0:y1, x0:x1])
        after = np.ascontiguousarray(current[y0:y1, x0:x1])
        return cls((x0, y0), before, after, _halve(before), _halve(after))

    @classmethod
    def given(
        cls,
        frames: object,
        previous: NDArray[np.uint8],
        current: NDArray[np.uint8],
        nodes: NDArray[np.float64],
    ) -> FramePair:
        """``frames`` when it is a :class:`FramePair` made already, :meth:`around` the
        ``[x, y]`` nodes when it is None: what a stage measuring between the two frames
        takes as its optional ``frames``.

        Raises
        ------
        ValueError
            If ``frames`` is neither a :class:`FramePair` nor None.
        """
        if frames is None:
            return cls.around(previous, current, nodes)
        if not isinstance(frames, FramePair):
            raise ValueError(f"frames must be a FramePair or None; got {type(frames).__name__}")
        return frames

    @classmethod
    def whole(cls, previous: NDArray[np.uint8], current: NDArray[np.uint8]) -> FramePair:
        """Both grey frames whole (the crop is the frame)."""
        return cls((0, 0), previous, current, _halve(previous), _halve(current))

    def to_half(self, points: NDArray[np.float64]) -> NDArray[np.float64]:
        """Frame ``[x, y]`` points to half-resolution crop coordinates."""
        result: NDArray[np.float64] = 0.5 * (points - np.asarray(self.origin)) - 0.25
        return result


def _halve(image: NDArray[np.uint8]) -> NDArray[np.uint8]:
    if min(image.shape) < 2:
        return image
    return np.asarray(cv2.resize(image, None, fx=0.5, fy=0.5, interpolation=cv2.INTER_AREA))


def _square(side: int) -> NDArray[np.uint8]:
    """A side x side structuring element of ones."""
    return np.ones((side, side), np.uint8)


def _corners(
    grey: NDArray[np.uint8], nodes: NDArray[np.float64], max_features: int
) -> NDArray[np.float32]:
    """Corners inside (and just around) the contour, ``grey`` and ``nodes`` at half resolution."""
    x0, y0, x1, y1 = bounding_box(grey.shape, nodes, 2 * CORNER_REACH, 2 * CORNER_REACH + 1)
    sub = np.ascontiguousarray(grey[y0:y1, x0:x1])
    local = nodes - [x0, y0]
    mask = np.asarray(
        cv2.dilate(contour_to_mask(local, sub.shape), _square(2 * CORNER_REACH + 1)), np.uint8
    )
    corners = cv2.goodFeaturesToTrack(
        sub,
        maxCorners=max_features,
        qualityLevel=CORNER_QUALITY,
        minDistance=CORNER_SPACING,
        mask=mask,
        blockSize=CORNER_BLOCK,
    )
    if corners is None:
        return np.zeros((0, 2), np.float32)
    return np.asarray(corners, np.float32).reshape(-1, 2) + np.array([x0, y0], np.float32)


def estimate_motion(
    previous: NDArray[np.uint8],
    current: NDArray[np.uint8],
    nodes: NDArray[np.float64],
    *,
    max_features: int = MAX_FEATURES,
    window: int = WINDOW,
    levels: int = LEVELS,
    fine_window: int = FINE_WINDOW,
    fb_threshold: float = FB_THRESHOLD,
    ransac_threshold: float = RANSAC_THRESHOLD,
    features: NDArray[np.float32] | None = None,
    figure_ground: bool = False,
    covered: NDArray[np.bool_] | None = None,
    background: Background = MEASURE,
    frames: FramePair | None = None,
) -> Motion:
    """Similarity motion of the object between two grey frames.

    Points: corners inside the contour (found anew, or ``features`` tracked
    from the frame before) and every fourth node.  Pyramidal
    Lucas-Kanade tracks them at half resolution, forward and back (points
    whose round trip misses by more than ``fb_threshold`` are dropped); one
    more Lucas-Kanade level at full resolution refines the survivors, and
    RANSAC fits the similarity.  With ``figure_ground``, the background's
    motion is measured around the contour on the halved crops
    (:func:`engine.tracking.background.background_motion`), and the points
    that moved with it are left out first when enough others did not
    (:data:`BACKGROUND_TOLERANCE`, :data:`OBJECT_SHARE`): a contour that took
    in some background (a textured wall the object passes) is still moved by
    the object, not held by the wall.

    Parameters
    ----------
    previous, current : numpy.ndarray
        Grey uint8 frames of equal size.
    nodes : numpy.ndarray
        The contour in ``previous``, (N, 2) ``[x, y]``.
    max_features : int
        Corners sought inside the contour (besides the nodes themselves).
    window, levels : int
        Lucas-Kanade window side and pyramid levels at half resolution (the
        defaults follow displacements of about 70 frame pixels).
    fine_window : int
        Lucas-Kanade window side of the full-resolution refinement.
    fb_threshold : float
        Largest forward-backward error (frame pixels) of a kept point.
    ransac_threshold : float
        RANSAC reprojection threshold (frame pixels).
    features : numpy.ndarray, optional
        (K, 2) ``[x, y]`` corners in ``previous`` to track instead of
        detecting new ones (the previous call's :attr:`Motion.tracked`);
        ignored when fewer than ``max_features // 4`` (at least 3).
    figure_ground : bool
        Leave out the points that moved with the background (see above).
    covered : numpy.ndarray, optional
        H x W bool: pixels of ``previous`` that other objects in front hide
        (:mod:`engine.tracking.covering`); points there are left out.
    background : numpy.ndarray, None or "measure"
        With ``figure_ground``: the background's frame similarity measured
        over the whole frame (:mod:`engine.tracking.shared`; None: it could
        not be), or :data:`~engine.tracking.background.MEASURE` it here.
    frames : FramePair, optional
        ``FramePair.around(previous, current, nodes)`` made already (for the
        turn too, :func:`engine.tracking.turn.measure_turn`), so as not to crop
        and halve twice.

    Returns
    -------
    Motion
        Identity with zero support when too few points survive.

    Raises
    ------
    ValueError
        If ``frames`` is neither a :class:`FramePair` nor None.
    """
    frames = FramePair.given(frames, previous, current, nodes)
    before, after = frames.half_previous, frames.half_current
    h, w = before.shape
    if min(frames.previous.shape) < MIN_CROP:
        return Motion.identity()
    half_nodes = frames.to_half(nodes)
    if features is not None and len(features) >= max(
        MIN_POINTS, max_features // KEEP_TRACKED_SHARE
    ):
        corners = frames.to_half(np.asarray(features, np.float64)).astype(np.float32)
    else:
        corners = _corners(before, half_nodes, max_features)
    pts = np.vstack([half_nodes[::NODE_STRIDE].astype(np.float32), corners])
    is_corner = np.arange(len(pts)) >= len(pts) - len(corners)
    inside = (pts[:, 0] >= 0) & (pts[:, 0] < w) & (pts[:, 1] >= 0) & (pts[:, 1] < h)
    hidden_share = covered_share(covered, nodes)  # of the object, behind other objects
    if covered is not None:
        inside &= ~hidden_at(covered, 2.0 * pts + 0.5 + np.asarray(frames.origin, np.float32))
    pts, is_corner = pts[inside], is_corner[inside]
    if len(pts) < MIN_POINTS or hidden_share > MOSTLY_HIDDEN:
        return Motion.identity(len(pts))
    criteria = (cv2.TERM_CRITERIA_EPS | cv2.TERM_CRITERIA_COUNT, LK_ITERATIONS, LK_EPSILON)

    def track(
        a: NDArray[np.uint8],
        b: NDArray[np.uint8],
        p: NDArray[np.float32],
        guess: NDArray[np.float32],
        side: int,
        top: int,
    ) -> tuple[NDArray[np.float32], NDArray[np.bool_]]:
        moved, status, _ = cv2.calcOpticalFlowPyrLK(
            a,
            b,
            p,
            guess.copy(),
            winSize=(side, side),
            maxLevel=top,
            criteria=criteria,
            flags=cv2.OPTFLOW_USE_INITIAL_FLOW,
        )
        return np.asarray(moved, np.float32).reshape(-1, 2), np.asarray(status).ravel() == 1

    fwd, ok_fwd = track(before, after, pts, pts, window, levels)
    back, ok_back = track(after, before, fwd, fwd, window, levels)
    # half-resolution pixels are two frame pixels wide
    good = ok_fwd & ok_back & (np.linalg.norm(back - pts, axis=1) < 0.5 * fb_threshold)
    if good.sum() < MIN_POINTS:
        return Motion.identity(len(pts))
    # the finest level, at full resolution (crop coordinates: p = 2u + 1/2)
    src = 2.0 * pts[good] + np.float32(0.5)
    guess = 2.0 * fwd[good] + np.float32(0.5)
    # on the points' surroundings only: the gradients are computed over the whole image
    low_x, low_y, high_x, high_y = extent(np.vstack([src, guess]))
    reach = fine_window // 2 + 2
    h_full, w_full = frames.previous.shape
    x0, y0 = max(math.floor(low_x) - reach, 0), max(math.floor(low_y) - reach, 0)
    x1, y1 = math.ceil(high_x) + reach + 1, math.ceil(high_y) + reach + 1
    x1, y1 = min(max(x1, x0 + 1), w_full), min(max(y1, y0 + 1), h_full)
    corner = np.array([x0, y0], np.float32)
    dst, ok_fine = track(
        np.ascontiguousarray(frames.previous[y0:y1, x0:x1]),
        np.ascontiguousarray(frames.current[y0:y1, x0:x1]),
        src - corner,
        guess - corner,
        fine_window,
        0,
    )
    dst += corner
    # a refinement that runs off (lost texture at full resolution) keeps the guess
    ok_fine &= np.linalg.norm(dst - guess, axis=1) < RUN_OFF
    dst = np.where(ok_fine[:, None], dst, guess)
    origin = np.asarray(frames.origin, dtype=np.float64)
    corner_good = is_corner[good]
    if not figure_ground or background is None:
        background = None
    elif isinstance(background, str):
        background = _background(frames, half_nodes)
    else:  # a frame similarity, in crop coordinates
        background = in_region(background, frames.origin)
    if background is not None:
        moving = _not_with(background, src, dst)
        if moving is not None:
            src, dst, corner_good = src[moving], dst[moving], corner_good[moving]
    matrix, inliers = fit_similarity(
        src, dst, threshold=ransac_threshold, iterations=RANSAC_ITERATIONS
    )
    if matrix is None or not np.isfinite(matrix).all():
        shift = np.median(dst - src, axis=0)
        matrix = np.array([[1.0, 0.0, shift[0]], [0.0, 1.0, shift[1]]])
        support = float(good.mean()) * MEDIAN_SUPPORT
        tracked = np.zeros((0, 2), np.float32)
    else:
        # the share of the object's points (those not moving with the background) that agree
        support = float(inliers.sum()) / (len(pts) - (int(good.sum()) - len(src)))
        agreed = inliers & corner_good
        tracked = (dst[agreed] + origin).astype(np.float32)
    fitted: NDArray[np.float64] = np.asarray(matrix, dtype=np.float64)
    if hidden_share > 0:  # a part cannot tell the whole's growth from its own shift
        fitted[:, :2] /= np.hypot(*fitted[:, 0])
    # back to frame coordinates: T(o) M T(-o)
    fitted[:, 2] += origin - fitted[:, :2] @ origin
    return Motion(fitted, support, len(pts), tracked)


def _background(frames: FramePair, half_nodes: NDArray[np.float64]) -> NDArray[np.float64] | None:
    """The background's similarity in crop coordinates, measured on the halved crops, or None.

    At half resolution it costs a quarter of a full-resolution fit (whose corner search and
    pyramids took 0.7 of its 0.9 ms on the validation sequences) and is still well within the
    :data:`BACKGROUND_TOLERANCE` it is compared with.
    """
    found = background_motion(frames.half_previous, frames.half_current, half_nodes)
    if found is None:
        return None
    # half-crop u to crop p = 2u + 1/2: p' = A p + (2t + 1/2 - A [1/2, 1/2])
    found[:, 2] = 2.0 * found[:, 2] + 0.5 - found[:, :2] @ np.array([0.5, 0.5])
    return found


def _not_with(
    background: NDArray[np.float64], src: NDArray[np.float32], dst: NDArray[np.float32]
) -> NDArray[np.bool_] | None:
    """Which tracked points (crop coordinates) did not move with the background, or None to
    keep them all (none moved with it, or too few moved otherwise)."""
    expected = src.astype(np.float64) @ background[:, :2].T + background[:, 2]
    moving = np.linalg.norm(dst - expected, axis=1) >= BACKGROUND_TOLERANCE
    if moving.all() or moving.sum() < max(MIN_POINTS, OBJECT_SHARE * len(src)):
        return None
    return np.asarray(moving)
