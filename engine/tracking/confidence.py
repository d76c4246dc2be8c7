"""How far to trust a tracked contour: a calibrated confidence and a status.

The confidence predicts the overlap (IoU) of the contour with the object. It
is a logistic model of what the frame says about the contour: how object-like
the pixels just inside it are, how object-like those just outside it are,
whether the chain settled, how the pixels on either side moved (the
motion contrast, when measured), and whether the contour still has the
object's shape (its overlap with the first frame's outline, both brought to
the same place and size).  The coefficients were fitted to the overlap
on the thirty DAVIS-2016 training sequences (see :data:`COEFFICIENTS`); the
status thresholds were chosen on folds of them.  The tracker's own decision
to search for a lost object uses an older model of the same evidence
(:func:`search_score`), the one its search was tuned with.

Coordinates are ``[x, y]`` pixels (x = column, y = row), as in OpenCV.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Literal

import cv2
import numpy as np
from numpy.typing import NDArray

from engine.geometry import as_nodes, bounding_box, contour_to_mask, mask_iou
from engine.tracking.maps import Maps
from engine.tracking.occlusion import BACKGROUND_BELOW

if TYPE_CHECKING:
    from engine.tracking.recent_shapes import RecentShapes

__all__ = [
    "COEFFICIENTS",
    "EMPTY_BELOW",
    "GREY_COEFFICIENTS",
    "LOST_BELOW",
    "SEARCH_COEFFICIENTS",
    "SEPARATION_BELOW",
    "TRACKING_FROM",
    "TYPICAL_LOOK",
    "UNCONFIRMED",
    "USUAL_FRAMES",
    "Evidence",
    "Status",
    "calibrated",
    "evidence",
    "logistic_confidence",
    "search_score",
    "shape_mask",
    "shape_overlap",
    "status_of",
]

Status = Literal["tracking", "uncertain", "lost"]
"""``tracking``: the contour is on the object; ``uncertain``: it may be off;
``lost``: it most likely does not cover the object."""

INSET = 3
"""Pixels inside the contour where the object's pixels are read (a 7 x 7 erosion):
past the mixed pixels of the boundary."""
RING = 10
"""Width (pixels) of the ring outside the contour where the surroundings are read."""
SHAPE_SCALE = 20.0
"""Grid pixels per square root of a shape's area when two shapes are compared
(:func:`shape_overlap`): each covers about 400 grid pixels (a disc of radius 11), fine
enough that a limb of a tenth of the area shows, cheap enough to fill every frame."""
SHAPE_GRID = 96
"""Side of the comparison grid: 2.4 square roots of the area each side of the centroid,
room for a rectangle up to about 20 times as long as it is wide."""

COEFFICIENTS = (
    -3.4697,
    2.3508,
    -1.7402,
    0.1143,
    0.3816,
    -0.1329,
    -0.0303,
    3.4367,
    -0.8759,
    -1.0141,
)
"""Logistic model of the overlap: bias; mean p(object) inside, mean p(object) in the
ring outside (as the appearance model sees them, occluders included); settled (1) or
not (0); mean motion log-odds inside, mean in the ring outside (positive: moves with
the object, :mod:`engine.tracking.motion_contrast`; 0 when not measured); measured
(1) or not; the shape's best overlap with the first frame's outline (:func:`shape_overlap`)
and with the shapes of the last frames on the object (:attr:`Evidence.judged_shape`,
:mod:`engine.tracking.recent_shapes`); the inside's and the ring's change from how they
usually are for this object (:attr:`Evidence.usual_inside`, :attr:`Evidence.usual_outside`).
Fitted by cross-entropy to the IoU of every scored frame of the thirty DAVIS-2016
training sequences tracked with the default options from five node counts (10,095
frames; ``python -m bench.tracking.confidence`` prints the fit), its bias -3.6799 raised
by 0.2102 so that the rule's threshold, which keeps 98.5 % of their good frames
``tracking``, falls on :data:`TRACKING_FROM`.  Refitted whenever the tracks or an input
change; last on 2026-11-30, evening, when a track's grid began to follow its object's
size (:mod:`engine.tracking.regrid`; the weights moved by under 0.2).  On 2026-11-30,
morning, when the recent shapes were added, the inside's weight fell from 4.90 to 2.45
and the shape's rose from 2.65 to 3.60: a
well-tracked object keeps a shape like its last frames', and the inside's colour no
longer stands in for it.  Every refit and its figures: ``docs/tracking-log.md``, "The
confidence model's refits".  On five folds of those sequences, fitted on four and scored
on the fifth, the mean |confidence - IoU| is 0.088, and 0.099 on the five validation
sequences as shipped.
The shape is what tells a contour that slid onto object-coloured background, or shrank
onto one part of the object, from one on the object: both look object-like inside.  The
usual look tells how object-like the surroundings of *this* object are: a ring at
p = 0.47 is a contour slid onto a banner of the rider's colours when it was 0.2 at the
start, and an object among its own colours when it always was; read together, the two
weights say "the inside as it is, the ring compared with its usual"."""
GREY_COEFFICIENTS = (
    -2.9437,
    -0.0177,
    -1.8338,
    0.2334,
    0.4782,
    -0.7865,
    0.0537,
    4.4834,
    1.6245,
    -0.0363,
)
"""The model of :data:`COEFFICIENTS`, its inputs the same, for grey frames: those whose
colour models read texture (:attr:`engine.tracking.options.TrackerOptions.grey_texture`,
:mod:`engine.tracking.texture`).  There the inside and the ring are told apart less
sharply than by colour, and the colour frames' model called too many good contours
``uncertain``: on the thirty training sequences turned grey (five node counts), 89.8 %
of the 7,160 frames with IoU >= 0.6 ``tracking``, 96.1 % of the 765 with IoU < 0.2 not
(at the colour threshold of 0.550).
Fitted as that one was, on the same sequences in grey (``python -m
bench.tracking.confidence --grey``; refitted on 2026-11-30, evening, when a track's grid
began to follow its object's size; bias -3.2239 as fitted), with its bias then raised by
0.2802 so that the threshold the rule chooses for it (0.470: keep 99 % of the good
frames ``tracking``) falls on :data:`TRACKING_FROM`, and one threshold serves
both kinds of frame; the rule then returns :data:`TRACKING_FROM` for it.  The inside's
texture weighs nothing (-0.018): in grey the shape and the ring say it.  The whole rule
on folds of the thirty in grey, fitted on four and scored on the fifth: 96.7 % of the
7,402 good frames ``tracking`` and 92.1 % of the 775 bad ones not (on the tracks before
the followed grid, 96.9 % and 92.5 % of 783; with the outline alone, 96.9 % and 89.0 %,
:data:`engine.tracking.recent_shapes.GREY_OUTLINE_COEFFICIENTS`); as shipped, 98.2 % and
91.5 % on the thirty, and on the five validation sequences in grey, never tuned on,
98.7 % of 820 and 91.0 % of 322.  The raised bias is the price of the one threshold: the
mean |confidence - IoU| is 0.101 on the thirty and 0.119 on the five."""
USUAL_FRAMES = 10
"""Tracked frames (a third of a second at 30 frames a second) over which a track learns
how its object usually looks against its surroundings (:class:`Evidence`): enough to
average a frame's noise, few enough that the track is still on the object.  Tried at 5,
10, 15 and 20 frames, and judged by the held-out lost detection itself (81.5, 84.7, 75.0
and 72.6 % of the bad frames flagged, against 69.7 % without): the held-out figure of
:data:`TRACKING_FROM` is therefore a little optimistic, but every count beat none."""
TYPICAL_LOOK = (0.81, 0.17)
"""The usual mean p(object) inside and in the ring of a track not yet seen: the average
over the thirty training sequences of a 128-node track's usual look after its first
:data:`USUAL_FRAMES` tracked frames (0.809 and 0.169 at 32 colour levels a channel; per
sequence 0.64 to 0.95 inside and 0.03 to 0.35 in the ring; 0.791 and 0.196 at 16 levels).
A tracker always has a usual look of its own (the frame being judged counts in it), so
this stands in only for an :class:`Evidence` built without one."""
TRACKING_FROM = 0.540
"""Confidence from which a frame is reported ``tracking``: the shipped model's threshold
that keeps 99 % of the thirty training sequences' frames with IoU >= 0.6 ``tracking``
(five node counts; the model's bias set so that it stays 0.540).  The share is chosen by
cross-validation on the thirty, as the one of 97.5 / 98 / 98.5 / 99 % whose rule, fitted
on folds and scored on the others, clears the two goals (95 % of those frames
``tracking``, 80 % of those with IoU < 0.2 not) by the most (``python -m
bench.tracking.confidence``).  The whole rule judged on folds it was not chosen on (the
share chosen within the four others, the model refitted there): 96.4 % of 8,674 good
frames ``tracking`` and 88.0 % of 316 bad ones not (bmx-bumps' fold flags 89.5 % of its
256); as shipped, 97.8 % and 95.3 % on the thirty, 96.9 % of 1,170 and 12 of 13 on the
five validation sequences, never tuned on (2026-11-30, evening; 95.3 % of 1,178 and 4 of
4 on the tracks before the followed grid).  The threshold caps the frames on
probation after a re-acquisition that jumped, which then do not count in choosing it.
Its earlier values and their figures: ``docs/tracking-log.md``, "The confidence model's
refits"."""
UNCONFIRMED = TRACKING_FROM - 1e-3
"""The most a contour that is not to be reported ``tracking`` gets: just below it."""
EMPTY_BELOW = BACKGROUND_BELOW
"""A contour whose inside has a mean p(object) below this (0.35: where a pixel "looks like
background", :data:`engine.tracking.occlusion.BACKGROUND_BELOW`) holds nothing that looks
like the object, whatever the logistic model makes of its surroundings: its confidence is at
most :data:`UNCONFIRMED`.  A contour left on an occluder that hides the whole object (inside
0.05, nothing around, settled) otherwise reached 0.49, ``tracking`` under the threshold of
the time (0.483).  On the 35 DAVIS sequences (five
node counts) no frame with IoU >= 0.6 has a mean below 0.45, and the 8 frames below 0.35 that
the model alone reported ``tracking`` all had IoU < 0.2.  Of the synthetic conditions' 456
clips (seeds 0-23) it changes six frames: three hidden ones (``hidden``, seed 21), and
three well-tracked ones whose dimmed colours the colour model no longer takes for the
object's (``lighting_change``, seed 23)."""
SEPARATION_BELOW = 0.1
"""A contour whose inside is less than this more object-like (mean p(object)) than its
ring has nothing telling it from its surroundings: its confidence is at most
:data:`UNCONFIRMED`, however well it kept the object's shape.  On frames where no colour
is known (a black frame: p = 0.5 everywhere) the chain holds the shape, and the model
alone would call the contour ``tracking`` (0.51).  With the cap, on the thirty
training sequences as tracked on 2026-11-27, evening (``python -m
bench.tracking.confidence``): 82.8 % of the frames with
IoU < 0.2 flagged held out and 95.8 % of those with IoU >= 0.6 ``tracking``, against
82.6 % and 95.8 % without; in-sample 95.2 % against 94.7 %.  A margin of 0.15 flagged
fewer held out (78 %, estimated on the same frames)."""
LOST_BELOW = 0.25
"""Confidence below which a frame is reported ``lost``: at 128 nodes none of the thirty
training sequences' frames with IoU >= 0.6 fall below it, 20 % of those with IoU < 0.2
(0.06 % and 21 % before the shape was judged)."""
SEARCH_COEFFICIENTS = (-2.5573, 5.1393, -2.8168, 0.7753)
"""The model the search was tuned with (:data:`engine.tracking.tracker.SEARCH_BELOW`):
bias, p(object) inside, outside, settled, fitted to the overlap on the thirty
training sequences as tracked before the joint segmentation and the motion
contrast.  It only decides when to search and what to remember; it is not reported."""


@dataclass(frozen=True, slots=True)
class Evidence:
    """What a frame says about a contour.

    Attributes
    ----------
    inside : float
        Mean p(object) of the pixels :data:`INSET` pixels inside the contour.
    outside : float
        Mean p(object) in the :data:`RING`-pixel ring outside it.
    settled : bool
        Whether the refinement converged.
    motion_inside, motion_outside : float
        Mean motion log-odds (:mod:`engine.tracking.motion_contrast`) of the
        same pixels inside and of the ring; 0 when not measured.
    motion_seen : bool
        Whether the motion contrast was measured.
    shape : float
        :func:`shape_overlap` of the contour with the first frame's outline
        (:mod:`engine.tracking.shape_memory`); 1 when there is no outline.
    recent_shape : float
        The contour's best overlap with the shapes of the last frames on the object
        (:mod:`engine.tracking.recent_shapes`); 0 when none is known.
    usual_inside, usual_outside : float or None
        ``inside`` and ``outside`` as they usually are for this object: their means
        over the track's first :data:`USUAL_FRAMES` tracked frames, this one included
        while it is one of them; None (not known): :data:`TYPICAL_LOOK`.
    grey : bool
        Whether p(object) was read from a grey frame's texture rather than from
        colour: :func:`calibrated` then reads the evidence with
        :data:`GREY_COEFFICIENTS`.
    silhouette : numpy.ndarray or None
        The contour's :func:`shape_mask` made to judge its shape (None: not judged, or
        no area): the shape the tracker remembers of the frame, not made twice.  Not
        compared.
    """

    inside: float
    outside: float
    settled: bool
    motion_inside: float = 0.0
    motion_outside: float = 0.0
    motion_seen: bool = False
    shape: float = 1.0
    usual_inside: float | None = None
    usual_outside: float | None = None
    grey: bool = False
    recent_shape: float = 0.0
    silhouette: NDArray[np.bool_] | None = field(default=None, repr=False, compare=False)

    @property
    def judged_shape(self) -> float:
        """The shape as the reported confidence reads it: the better of ``shape`` and
        ``recent_shape`` (the input of :data:`COEFFICIENTS` after ``motion_seen``)."""
        return max(self.shape, self.recent_shape)

    @property
    def change(self) -> tuple[float, float]:
        """``inside`` and ``outside`` less their usual values (:data:`TYPICAL_LOOK` where
        not known): the last two inputs of :data:`COEFFICIENTS`."""
        usual_in = TYPICAL_LOOK[0] if self.usual_inside is None else self.usual_inside
        usual_out = TYPICAL_LOOK[1] if self.usual_outside is None else self.usual_outside
        return self.inside - usual_in, self.outside - usual_out


def shape_mask(nodes: NDArray[np.float64]) -> NDArray[np.bool_] | None:
    """The closed contour's shape: moved to its centroid and scaled to :data:`SHAPE_SCALE`
    grid pixels per square root of its area, filled on the :data:`SHAPE_GRID` grid
    (``[x, y]`` nodes; None: no area)."""
    found = _normalised(nodes)
    return None if found is None else np.asarray(found > 0)


def _normalised(nodes: NDArray[np.float64]) -> NDArray[np.uint8] | None:
    """The closed contour moved to its centroid and scaled to :data:`SHAPE_SCALE` grid
    pixels per square root of its area, filled on the :data:`SHAPE_GRID` grid (None: no
    area)."""
    m = cv2.moments(np.asarray(nodes, np.float32))
    if m["m00"] == 0.0 or not math.isfinite(m["m00"]):
        return None
    centroid = np.array([m["m10"], m["m01"]]) / m["m00"]
    scaled = (nodes - centroid) * (SHAPE_SCALE / math.sqrt(abs(m["m00"]))) + SHAPE_GRID / 2
    return contour_to_mask(scaled, (SHAPE_GRID, SHAPE_GRID))


def shape_overlap(nodes: NDArray[np.float64], outline: NDArray[np.float64]) -> float:
    """How alike two closed contours' shapes are, wherever they are and whatever their size.

    Parameters
    ----------
    nodes, outline : numpy.ndarray
        (N, 2) and (M, 2) ``[x, y]`` pixels.

    Returns
    -------
    float
        The IoU of the two shapes once each is moved to its own centroid and scaled to
        the same area (rotation is not undone: the outline turns with the object,
        :func:`engine.tracking.shape_memory.follow`), in [0, 1]; 0 when either has no
        area.  A contour that slid onto the background or shrank onto one part of the
        object has lost the object's shape; one that grew a limb has changed it a little.
        The same shape at another place and size gives exactly 1.

    Raises
    ------
    ValueError
        If either is not an (N, 2) array of at least 3 finite points.
    """
    a, b = _normalised(as_nodes(nodes)), _normalised(as_nodes(outline))
    return 0.0 if a is None or b is None else float(mask_iou(a, b))


def evidence(
    maps: Maps,
    nodes: NDArray[np.float64],
    settled: bool,
    outline: NDArray[np.float64] | None = None,
    recent: RecentShapes | None = None,
) -> Evidence:
    """The :class:`Evidence` of the cue maps for the closed contour ``nodes``.

    Parameters
    ----------
    maps : Maps
        The cue maps the contour was refined on.
    nodes : numpy.ndarray
        (N, 2) ``[x, y]`` pixels.
    settled : bool
        Whether the refinement converged.
    outline : numpy.ndarray or None
        (M, 2) ``[x, y]`` the first frame's outline where it is now, to compare the
        contour's shape with (:func:`shape_overlap`); None: the shape is not judged.
    recent : RecentShapes or None
        The shapes of the last frames on the object: with an outline, the contour's best
        overlap with them is :attr:`Evidence.recent_shape`
        (:mod:`engine.tracking.recent_shapes`).

    Returns
    -------
    Evidence
        p = 0.5 (nothing known) inside and outside when either side falls wholly outside
        the maps.
    """
    from engine.tracking._mean_kernels import masked_means, masked_values, mean

    local = nodes - np.asarray(maps.origin, dtype=np.float64)
    # only the contour's box and the ring round it are read: the same pixels, in the same
    # order, as in the whole maps, and the whole-pixel shift leaves the filling exact (a
    # contour wholly beyond the maps: a pixel of them, which it does not cover)
    x0, y0, x1, y1 = bounding_box(maps.probability.shape, local, RING + 2)
    mask = contour_to_mask(local - [x0, y0], (y1 - y0, x1 - x0))
    inner = cv2.erode(mask, np.ones((2 * INSET + 1, 2 * INSET + 1), np.uint8)) > 0
    outer = cv2.dilate(mask, np.ones((2 * RING + 1, 2 * RING + 1), np.uint8)) > 0
    ring = outer & (mask == 0)
    found_in, found_out = bool(inner.any()), bool(ring.any())
    p = np.asarray(maps.seen[y0:y1, x0:x1], np.float32)  # an occluder counts: not seen there
    # a side not in the maps (a contour around all of them): nothing tells it from the other
    both = found_in and found_out
    inside, outside = masked_means(p, inner, ring) if both else (0.5, 0.5)
    shape, seen, mine = 1.0, 0.0, None
    if outline is not None:  # the contour's shape made once, for the outline and the recent
        mine, theirs = shape_mask(as_nodes(nodes)), shape_mask(as_nodes(outline))
        if mine is not None:  # kept as the evidence's silhouette: read, never written
            mine.setflags(write=False)
        shape = 0.0 if mine is None or theirs is None else float(mask_iou(mine, theirs))
        seen = 0.0 if recent is None else recent.overlap(mine)
    if maps.motion is None or not both:
        return Evidence(inside, outside, settled, shape=shape, recent_shape=seen, silhouette=mine)
    # the log of the counted pixels only, not of the whole map
    motion = np.asarray(maps.motion[y0:y1, x0:x1], np.float32)
    moved_in, moved_out = (
        mean(np.asarray(cv2.log(v), np.float32).ravel()) for v in masked_values(motion, inner, ring)
    )
    return Evidence(
        inside,
        outside,
        settled,
        moved_in,
        moved_out,
        True,
        shape,
        recent_shape=seen,
        silhouette=mine,
    )


def calibrated(e: Evidence) -> float:
    """The confidence of :class:`Evidence`: predicted IoU, in (0, 1); at most
    :data:`UNCONFIRMED` for a contour with nothing object-like inside (:data:`EMPTY_BELOW`)
    or nothing telling its inside from its surroundings (:data:`SEPARATION_BELOW`).
    Evidence from a grey frame (:attr:`Evidence.grey`) is read with
    :data:`GREY_COEFFICIENTS`, any other with :data:`COEFFICIENTS`; the shape as
    :attr:`Evidence.judged_shape`."""
    return logistic_confidence(e, GREY_COEFFICIENTS if e.grey else COEFFICIENTS, e.judged_shape)


def logistic_confidence(e: Evidence, model: Sequence[float], shape_read: float) -> float:
    """The logistic ``model`` (in :data:`COEFFICIENTS` order) of :class:`Evidence`, its shape
    input ``shape_read``, capped as :func:`calibrated` says."""
    bias, inside, outside, settled, moved_in, moved_out, seen, shape, *change = model
    change_in, change_out = e.change
    logit = (
        bias
        + inside * e.inside
        + outside * e.outside
        + settled * float(e.settled)
        + moved_in * e.motion_inside
        + moved_out * e.motion_outside
        + seen * float(e.motion_seen)
        + shape * shape_read
        + change[0] * change_in
        + change[1] * change_out
    )
    value = 1.0 / (1.0 + math.exp(-logit))
    unseen = e.inside < EMPTY_BELOW or e.inside - e.outside < SEPARATION_BELOW
    return min(value, UNCONFIRMED) if unseen else value


def search_score(e: Evidence) -> float:
    """The search's score of :class:`Evidence` (:data:`SEARCH_COEFFICIENTS`), in (0, 1)."""
    bias, inside, outside, settled = SEARCH_COEFFICIENTS
    logit = bias + inside * e.inside + outside * e.outside + settled * float(e.settled)
    return 1.0 / (1.0 + math.exp(-logit))


def status_of(confidence: float) -> Status:
    """``tracking`` from :data:`TRACKING_FROM`, ``lost`` below :data:`LOST_BELOW`."""
    if confidence >= TRACKING_FROM:
        return "tracking"
    return "lost" if confidence < LOST_BELOW else "uncertain"
