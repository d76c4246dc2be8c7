"""``Tracker``: follow an object's boundary through video frames.

The tracker orchestrates four swappable stages (:mod:`engine.tracking.stages`)
and the physics.  Per frame (``step``):

1. a :class:`~engine.tracking.stages.MotionModel` predicts where the contour
   went (default :class:`~engine.tracking.prediction.FlowMotion`);
2. :class:`~engine.tracking.stages.BoundaryCues` make the cue maps from the
   frame and the :class:`~engine.tracking.stages.AppearanceModel` (defaults
   :class:`~engine.tracking.cues.RegionEdgeCues` and
   :class:`~engine.tracking.appearance.ColourHistogram`);
3. refine (:func:`engine.tracking.refine`): each node seeks the boundary
   along its normal on those maps; the pulls are forces on the chain, whose
   equilibrium around the predicted shape, X = X0 + U with (I + K) U = F
   (paper eq. 13-16, :func:`engine.deform`), keeps the shape plausible
   through noise, clutter and occlusion;
4. resample by arc length and guard against crossing, collapse and NaN;
5. a :class:`~engine.tracking.stages.Segmentation` relabels the pixels
   within a few pixels of the refined contour jointly (default
   :class:`~engine.tracking.segmentation.BandCut`: local colour models, the
   chain's contour as the shape prior, a minimum cut) and gives the final
   contour; a confident frame teaches the appearance model.

Frames larger than the option ``working_side`` (480 lines) are tracked downscaled to it,
and a large object (its first contour's area over ``object_side``², 160² px²) on a grid
smaller by as much as it is larger (:mod:`engine.tracking.working`), a grid that follows
the object as it grows or shrinks (:mod:`engine.tracking.regrid`); contours in and out
are in the frame's own pixels.  A
grey frame is described to the colour models by its grey level and two texture channels
(option ``grey_texture``, :mod:`engine.tracking.texture`); so is a tinted monochrome one
(sepia, a camera's cast: :func:`~engine.tracking.texture.is_tinted`) on a track's first
frame and on a track in grey.  A noisy colour frame is smoothed for the colour models
(:mod:`engine.tracking.noise`); the motion and the edges read its grey as it is.
Coordinates are ``[x, y]`` pixels (x = column, y = row), as in OpenCV.
"""

from __future__ import annotations

import copy
import dataclasses
import functools
from collections.abc import Mapping
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from engine.geometry import any_in_frame, as_nodes, polygon_area, resample
from engine.tracking._attempt import BEHIND_FROM, track_around
from engine.tracking._frames import as_frame as _as_frame
from engine.tracking._frames import as_image as _as_image
from engine.tracking._frames import check_prepared
from engine.tracking._frames import grey_of as _grey_of
from engine.tracking._frames import repeatable_opencv as _repeatable_opencv
from engine.tracking._tracker_state import restore, snapshot
from engine.tracking.appearance import ColourHistogram
from engine.tracking.confidence import UNCONFIRMED, Evidence, status_of
from engine.tracking.covering import covered_share
from engine.tracking.cues import RegionEdgeCues
from engine.tracking.flash import flashed
from engine.tracking.holding import carry, carry_by_shape, hold_factors, side_contrast
from engine.tracking.lighting import Lighting
from engine.tracking.looks import Look, change_look
from engine.tracking.maps import roi_box
from engine.tracking.memory import Memory
from engine.tracking.noise import denoised
from engine.tracking.options import TrackerOptions
from engine.tracking.prediction import FlowMotion
from engine.tracking.reacquisition import jumped, search_reach, search_shape
from engine.tracking.recent_shapes import remembered
from engine.tracking.regrid import follow_size
from engine.tracking.result import TrackResult
from engine.tracking.segmentation import BandCut
from engine.tracking.shape_memory import follow
from engine.tracking.shared import Crowd
from engine.tracking.stages import (
    AppearanceModel,
    BoundaryCues,
    MotionModel,
    Prediction,
    Segmentation,
)
from engine.tracking.texture import (
    TINT_KEPT,
    TINT_TOLERANCE,
    is_grey,
    is_tinted,
    texture_image,
)
from engine.tracking.turn import measure_turn, turned
from engine.tracking.validity import valid_contour
from engine.tracking.working import WorkingScale, object_grid_side, working_scale

__all__ = ["TrackResult", "Tracker", "TrackerOptions"]

MIN_SIDE = 16
"""Frames smaller than this (pixels) carry no trackable information."""
MAX_NODES = 4096
"""Most nodes a contour may have: more than one per boundary pixel of any object on the
480-line working grid (whose longest outline is about 3,000 pixels), and within what
the node-to-node searches (N x N distances) and OpenCV's sampling of the nodes as one
row of a map (under 32,767) can take."""
MIN_AREA = 1.0
"""Square pixels a contour must enclose: less (nodes on a line, a circle of radius 0.01)
has no inside to tell from its surroundings, and could only ever be reported on nothing."""
MOTION_SHARE = 0.4
"""Share of the motion's support in the learning signal; the rest is the
boundary evidence, which says more: a contour on the object's edges is right
even when the object's texture gives the motion little support."""
LEARN_ABOVE = 0.5
"""Only frames whose learning signal is at least this teach the appearance
model, so that a lost or occluded object does not teach it the background."""
REACQUIRE_MARGIN = 0.05
"""A re-acquired contour must beat the local track's search score by this much:
of two near-equal readings, the one that did not jump wins."""
PROBATION = 2
"""A re-acquired contour that jumped (:func:`engine.tracking.reacquisition.jumped`) is
reported ``uncertain`` on the frame it jumps on and the 2 after it: a jump is right only
if the object is then followed from there.  One that corrects the local contour in place
is reported as its confidence says; either way these frames do not become the remembered
shape."""
SEARCH_UNLESS_COVERED = 0.2
"""An object at least this much hidden by other tracked objects in front is not searched
for elsewhere: its low score is theirs, and it is known to be behind them."""
SEARCH_BELOW = 0.445
"""A frame whose contour's search score (:func:`engine.tracking.confidence.search_score`)
is below this starts a search, and one at or above it gives the shape to search for
(the threshold the search and the holding were cross-validated with; the reported
confidence and status have their own model and threshold,
:data:`engine.tracking.confidence.TRACKING_FROM`)."""

AFRESH_AFTER = 3
"""After this many frames in a row without a confident contour (the object hidden, or
lost and searched for), the first confident one starts the cue stage anew
(:meth:`~engine.tracking.stages.BoundaryCues.start`): what its occlusion rule remembers
under occluders by then is where the unconfident contour went, not the object, and a
lobe of background the contour drifted into while the object was hidden would otherwise
be held there as "covered" for a dozen frames (synthetic ``hidden``, seeds 8, 10 and 14,
scored as the benchmark does: 0.929-0.950 before, 0.985-0.988 after; nothing else of the
24 seeds of every condition changed, and the thirty training sequences scored J 0.6905
against 0.6908 over five node counts).  After one such frame instead of three: the same
on the synthetic conditions, 0.6887 on the thirty.

That first confident frame also searches for the remembered shape (the last confident
frame's contour), which replaces the local contour if it scores better by
:data:`REACQUIRE_MARGIN`: the local one may be a shrunken loop half on the object
(synthetic ``hidden`` seed 9: 0.600 before, 0.989 after; no other of the 456 generated
clips changed; on the thirty over five node counts one track of 150 changed, ``swing``
at 136 nodes, 0.690 -> 0.698).  Not after a re-acquisition in the same absence, whose
contour already is the remembered shape: searching again on probation's frames chained
jumps (``motorbike`` 0.747 -> 0.700), and after them a validation sequence's
(``breakdance`` at 128 nodes, 0.358 -> 0.217; :attr:`Memory.reacquired`)."""


class Tracker:
    """Follows an object's boundary, frame by frame.

    Parameters
    ----------
    nodes : array_like
        Initial contour on the first frame given to :meth:`step`, (N, 2)
        ``[x, y]`` pixels, N >= 3; resampled evenly by arc length.
    closed : bool, default True
        Only closed contours (object boundaries) are tracked.
    stiffness : float, optional
        ``a = k/m`` of the chain (default :attr:`TrackerOptions.stiffness`).
    motion : MotionModel, optional
        The motion stage (default :class:`~engine.tracking.FlowMotion` with
        the options' ``max_features`` and ``flow_stiffness``).
    appearance : AppearanceModel, optional
        The appearance stage (default :class:`~engine.tracking.ColourHistogram`
        with the options' ``band`` and ``learning_rate``).
    cues : BoundaryCues, optional
        The cue-map stage (default :class:`~engine.tracking.RegionEdgeCues`
        with the options' ``search_radius`` and ``occlusion``).
    segmentation : Segmentation, optional
        The joint segmentation stage (default :class:`~engine.tracking.BandCut`
        with the options' ``cut_band``).
    **options
        Other :class:`TrackerOptions` fields.

    Raises
    ------
    ValueError
        On a malformed contour (shape, non-finite, zero length) or option.
    """

    def __init__(
        self,
        nodes: ArrayLike,
        *,
        closed: bool = True,
        stiffness: float | None = None,
        motion: MotionModel | None = None,
        appearance: AppearanceModel | None = None,
        cues: BoundaryCues | None = None,
        segmentation: Segmentation | None = None,
        **options: Any,
    ) -> None:
        if not closed:
            raise ValueError("the tracker follows object boundaries: closed contours only")
        if stiffness is not None:
            options["stiffness"] = stiffness
        self.options = TrackerOptions.from_mapping(options)
        opts = self.options
        self.motion: MotionModel = motion or FlowMotion(
            opts.max_features, opts.flow_stiffness, opts.figure_ground
        )
        self.appearance: AppearanceModel = appearance or ColourHistogram(
            opts.band, opts.learning_rate, opts.far_background, opts.colour_bits
        )
        self.cues: BoundaryCues = cues or RegionEdgeCues(
            opts.search_radius, opts.occlusion, opts.rigid_behind, opts.revealed_background
        )
        self.segmentation: Segmentation = segmentation or BandCut(
            opts.cut_band, opts.bridge_strips, opts.carve_gaps, opts.full_resolution_edges
        )
        for name, stage, kind in (
            ("motion", self.motion, MotionModel),
            ("appearance", self.appearance, AppearanceModel),
            ("cues", self.cues, BoundaryCues),
            ("segmentation", self.segmentation, Segmentation),
        ):
            if not isinstance(stage, kind):
                raise ValueError(
                    f"{name} must implement {kind.__name__}; got {type(stage).__name__}"
                )
        self._nodes = self._initial(nodes)
        # the frames' size and their working grid (None: tracked as given); until a frame
        # comes, the contour is in the frame's pixels, afterwards on the grid
        self._frame_shape: tuple[int, int] | None = None
        self._scale: WorkingScale | None = None
        self._grid_side = self.options.working_side  # the grid's shorter side (0: none)
        # the previous grey frame (None: the next frame starts the track)
        self._previous: NDArray[np.uint8] | None = None
        self.frame_index = -1
        self._memory = Memory.fresh(self._nodes)
        self._lighting = Lighting()
        # the kind of frame (grey or not) the stages learnt from, and the other kind's look
        self._look_grey: bool | None = None
        self._aside: Look | None = None
        self._evidence: Evidence | None = None
        self._unconfirmed = False
        # frames in a row passed over as a flash (engine.tracking.flash), and the
        # confidence last reported (a flash reports the last contour with no more)
        self._passed = 0
        self._reported = 1.0

    @staticmethod
    def _initial(nodes: ArrayLike) -> NDArray[np.float64]:
        arr = as_nodes(nodes)
        if len(arr) > MAX_NODES:
            raise ValueError(f"a contour has at most {MAX_NODES} nodes; got {len(arr)}")
        out = resample(arr, len(arr))
        if np.ptp(out, axis=0).max() <= 0:
            raise ValueError("the contour has zero length (all nodes coincide)")
        if abs(polygon_area(out)) < MIN_AREA:
            raise ValueError(
                f"the contour encloses no area (under {MIN_AREA:g} square pixel: its nodes lie "
                "on a line or within a pixel)"
            )
        return out

    @property
    def nodes(self) -> NDArray[np.float64]:
        """The current contour, (N, 2) ``[x, y]`` pixels of the frames given (a copy)."""
        return self._in_frame(self._nodes)

    @property
    def previous_frame(self) -> NDArray[np.uint8] | None:
        """The grey frame the contour is on, on the working grid (downscaled when the
        frames' shorter side exceeds ``working_side``; None before the first frame): a
        read-only view, as the next frame is tracked against it."""
        if self._previous is None:
            return None
        view = self._previous.view()
        view.flags.writeable = False
        return view

    def _in_frame(self, nodes: NDArray[np.float64]) -> NDArray[np.float64]:
        """Working-grid ``[x, y]`` points in the frame's pixels (a copy)."""
        return nodes.copy() if self._scale is None else self._scale.to_frame(nodes)

    def _regrid(self, shape: tuple[int, int]) -> None:
        """A first frame, or one of another size: its working grid, the contour put on it,
        and the frame taken as the first of a track (as a frame of another size always
        was)."""
        nodes = self._in_frame(self._nodes)
        self._frame_shape = shape
        opts = self.options
        self._grid_side = object_grid_side(shape, nodes, opts.working_side, opts.object_side)
        self._scale = working_scale(shape, self._grid_side)
        self._nodes = nodes if self._scale is None else self._scale.to_working(nodes)
        self._previous = None

    @property
    def evidence(self) -> Evidence | None:
        """What the last frame said about its contour (None after a first frame, a flash
        passed over, or when there was nothing to track): the input of the confidence model.

        The last result's confidence is
        :func:`engine.tracking.confidence.calibrated` of it, except when the contour lies
        wholly outside the frame (0) and in the frames of probation after a re-acquisition
        that jumped (at most just below :data:`engine.tracking.confidence.TRACKING_FROM`).
        For analysis: the benchmark cross-validates the confidence model on it
        (``python -m bench.tracking.confidence``).  Not part of :meth:`to_state`.
        """
        return self._evidence

    @property
    def unconfirmed(self) -> bool:
        """Whether the last frame was on probation after a re-acquisition that jumped, the
        first frame of another kind (:mod:`engine.tracking.looks`) or a flash passed over
        (:mod:`engine.tracking.flash`): its confidence is then at most just below
        :data:`engine.tracking.confidence.TRACKING_FROM`, whatever :attr:`evidence` says.
        For analysis, as :attr:`evidence` (the confidence benchmark leaves these frames out
        of choosing the threshold).  Not part of :meth:`to_state`.
        """
        return self._unconfirmed

    @property
    def started(self) -> bool:
        """Whether a frame was seen: the next one is tracked (not taken as the first)."""
        return self._previous is not None

    def reset(self, nodes: ArrayLike) -> None:
        """Place a new contour (``[x, y]`` pixels of the next frame); the next frame is
        taken as the one it lies on."""
        self._nodes = self._initial(nodes)
        self._frame_shape = self._scale = None
        self._previous = None
        self.motion.reset()
        self._forget_search()

    def step(self, frame: NDArray[np.uint8]) -> TrackResult:
        """Track into the next frame.

        The first frame (and the first after :meth:`reset`) only initialises
        the appearance model from the given contour and returns it unchanged.

        Parameters
        ----------
        frame : numpy.ndarray
            H x W grey or H x W x 3 BGR uint8.  One whose shorter side exceeds the
            option ``working_side`` is tracked downscaled to it
            (:mod:`engine.tracking.working`).

        Returns
        -------
        TrackResult
            The contour in ``[x, y]`` pixels of ``frame``.

        Raises
        ------
        ValueError
            If the frame is not a non-empty uint8 image.
        """
        # the grey version is made on the grid the frame is tracked on: a frame brought
        # down to a smaller one would convert its every pixel for nothing
        return self._prepared(_as_image(frame), None, Crowd())

    def step_prepared(
        self,
        image: NDArray[np.uint8],
        grey: NDArray[np.uint8],
        crowd: Crowd | None = None,
    ) -> TrackResult:
        """:meth:`step` on a frame already checked and converted (shared by several trackers).

        ``image, grey`` as :func:`engine.tracking._frames.as_frame` returns them: the
        contiguous BGR (or grey) image and its grey version.  ``crowd``, from
        :class:`~engine.tracking.ObjectsTracker`: the pixels other objects in front of
        this one hide (:mod:`engine.tracking.covering`) and the background's motion
        and dense flow measured once over the whole frame (:mod:`engine.tracking.shared`;
        used when measured between this tracker's previous frame and ``grey``), the frame
        smoothed of its noise once for all (:class:`engine.tracking.noise.Smoothing`), and,
        on a frame tracked downscaled, brought down to the working grid once for all
        (:class:`engine.tracking.working.WorkingFrames`).

        Raises
        ------
        ValueError
            If they are not uint8, ``grey`` is not H x W, ``image`` is not that
            H x W (x 3), or the crowd's ``covered`` is not H x W bool.
        """
        crowd = crowd or Crowd()
        check_prepared(image, grey, crowd.covered)
        return self._prepared(image, grey, crowd)

    def _prepared(
        self, image: NDArray[np.uint8], grey: NDArray[np.uint8] | None, crowd: Crowd
    ) -> TrackResult:
        """:meth:`step_prepared` on a checked frame, whose grey version (None: not made
        yet) is made here only if the frame is tracked at its own size."""
        covered, shared = crowd.covered, crowd.shared
        if covered is not None and not covered.any():
            covered = None  # nothing in front: exactly as a tracker alone
        if image.shape[:2] != self._frame_shape:
            self._regrid((image.shape[0], image.shape[1]))
        else:  # an object that grew or shrank much: tracked on a grid of its new size
            follow_size(self)
        if grey is None and (self._scale is None or crowd.working is not None):
            grey = _grey_of(image)  # (outside the IPP-free context, as it always was)
        with _repeatable_opencv():
            scale, smoothing = self._scale, crowd.smoothing
            if scale is not None:  # on the working grid (the shared measures too, if theirs)
                if crowd.working is None:
                    image, grey = _as_frame(scale.image(image))
                    smoothing = None
                else:  # brought down (and smoothed) once for the trackers of the frame
                    assert grey is not None  # made above
                    image, grey, smoothing = crowd.working.at(scale, image, grey)
                covered = None if covered is None else scale.mask(covered)
            assert grey is not None  # made above, or on the working grid
            if shared is not None and not shared.applies_to(self._previous, grey):
                shared = None
            grey_frame = is_grey(image)
            starting = self._previous is None or self._previous.shape != grey.shape
            if not grey_frame and (starting or self._look_grey):
                # a tint is grey from a track's start, and to a grey look (not to a colour
                # look: a colour scene's frame may hold one channel's levels for a while)
                grey_frame = is_tinted(image, TINT_TOLERANCE if starting else TINT_KEPT)
            textured = self.options.grey_texture and grey_frame
            if textured:  # the colour models read texture, the confidence reads it so
                image = texture_image(grey)
                if shared is not None:  # the frame's light was measured on its grey
                    shared = dataclasses.replace(shared, light=None)
            else:  # the colours, not the sensor's noise (clean video: the frame itself)
                image = denoised(image, grey) if smoothing is None else smoothing.of(image, grey)
            return self._step(image, grey, Crowd(covered, shared), textured, grey_frame)

    def _step(
        self,
        image: NDArray[np.uint8],
        grey: NDArray[np.uint8],
        crowd: Crowd,
        textured: bool,
        grey_frame: bool,
    ) -> TrackResult:
        self.frame_index += 1
        self._evidence, self._unconfirmed = None, False
        if min(grey.shape) < MIN_SIDE:
            return self._result(0, False, 0.0)
        if self._previous is None or self._previous.shape != grey.shape:
            return self._start(image, grey, grey_frame)
        if flashed(grey, self._previous, self._passed):  # passed over: the last contour,
            self._passed += 1  # no more confident than it was, and not tracking
            self._unconfirmed = True
            visible = self._visible(self._nodes, grey)
            return self._result(0, False, min(self._reported, UNCONFIRMED) if visible else 0.0)
        self._passed = 0
        raw = image
        # the crowd's covered pixels: read by the motion on the previous frame and by
        # the cue maps on this one (the objects in front, where they were and are)
        prediction = self.motion.predict(
            self._previous,
            grey,
            self._nodes,
            frame_index=self.frame_index,
            object_weight=self.cues.object_weight,
            **crowd.motion_keywords(),
        )
        changed = self._look_grey is not None and grey_frame != self._look_grey
        if changed and not change_look(self, image, prediction.nodes, grey_frame):
            return self._predicted(grey, prediction)
        self._look_grey = grey_frame  # (a state written before the looks: from now on)
        if self.options.lighting:  # the frame in the first frame's light
            # (not the crowd's step of light from a frame of the other kind)
            light = None if crowd.shared is None or changed else crowd.shared.light
            whole = None if light is None else (light.sample, light.step)
            image = self._lighting.compensate(raw, prediction.matrix, whole)
        cues = copy.deepcopy(self.cues)  # before this frame, should a search retry it
        memory = self._memory
        hold = memory.hold
        if memory.outline is not None:
            motion = prediction.matrix
            if self.options.turn_outline and self._previous is not None:
                angle = measure_turn(
                    self._previous, grey, self._nodes, motion, frames=prediction.frames
                )
                if angle is not None:  # the outline turns as far as the object
                    motion = turned(motion, self._nodes, angle)
            memory.outline = follow(memory.outline, motion, prediction.nodes, hold)
        outline, marks = memory.outline, memory.marks
        attempt = track_around(
            self, image, grey, prediction, self.cues, hold, crowd, outline, marks, textured=textured
        )
        visible = self._visible(self._nodes, grey)  # where the object was: worth a search
        share = covered_share(crowd.covered, prediction.nodes)
        lost = attempt.score < SEARCH_BELOW
        # back after an absence, the local contour is where it drifted while there was
        # nothing to see: the remembered shape, searched for, competes with it once
        back = memory.misses >= AFRESH_AFTER and memory.probation == 0 and not memory.reacquired
        # every frame that does not end confident counts, in view or not: an object back
        # from beyond the frame's edge or from behind the others is back after an absence
        memory.misses += int(lost)
        if (lost or back) and visible and share < SEARCH_UNLESS_COVERED:
            retry = self._search(image, grey, prediction)
            if retry is not None:
                moved = carry_by_shape(hold, self._nodes, retry.nodes)
                other = track_around(
                    self, image, grey, retry, cues, moved, crowd, textured=textured
                )
                margin = attempt.score + REACQUIRE_MARGIN
                if other.score >= self.options.reacquire_above and other.score > margin:
                    if memory.outline is not None:  # the remembered outline goes along
                        shift = retry.nodes.mean(axis=0) - prediction.nodes.mean(axis=0)
                        memory.outline = memory.outline + shift
                    memory.jumped = jumped(attempt.nodes, other.nodes)
                    prediction, attempt, self.cues, hold = retry, other, cues, moved
                    self.motion.reset()
                    memory.probation = PROBATION + 1
                    memory.reacquired = True
        refinement, nodes, confidence = attempt.refinement, attempt.nodes, attempt.confidence
        self._evidence = attempt.evidence
        memory.hold = carry(hold, refinement.nodes, nodes)
        if memory.probation > 0:
            memory.probation -= 1
            if memory.jumped:  # on probation: just below tracking
                confidence = min(confidence, UNCONFIRMED)
                self._unconfirmed = True
        elif attempt.score >= SEARCH_BELOW:
            if memory.misses >= AFRESH_AFTER:  # back after an absence: occluders forgotten
                self.cues.start(image, nodes, self.appearance)
            memory.misses = 0
            memory.reacquired = False
            memory.shape = nodes
        support = MOTION_SHARE * prediction.support
        signal = support + (1 - MOTION_SHARE) * refinement.contrast
        if not self._visible(nodes, grey):  # the contour reported: none of it in view
            signal = confidence = 0.0
        else:  # how the object usually looks, from the track's first frames
            memory.learn_usual(attempt.evidence.inside, attempt.evidence.outside)
        self._nodes = nodes
        self._previous = grey
        if self.options.lighting:
            self._lighting.learn(raw, nodes)  # its colours as taken, to compare with the next
        if share < BEHIND_FROM:  # another object's colours are not this one's
            if signal >= LEARN_ABOVE:
                self.appearance.update(image, self._nodes)
            self.segmentation.learn(image, self._nodes)
        remember = not self._unconfirmed and remembered(attempt.evidence)
        shape = attempt.evidence.silhouette  # of these nodes, made to judge them
        return self._result(
            refinement.iterations, refinement.converged, confidence, remember, shape
        )

    def _search(
        self, image: NDArray[np.uint8], grey: NDArray[np.uint8], prediction: Prediction
    ) -> Prediction | None:
        """The remembered shape where the appearance says the object is (None: nowhere new)."""
        if self.options.reacquire_above >= 1.0:
            return None
        reach = search_reach(self._memory.misses)
        found = search_shape(image, prediction.nodes, self._memory.shape, self.appearance, reach)
        if found is None or not valid_contour(found, grey.shape, found, check_crossing=False):
            return None
        matrix = prediction.matrix.copy()
        matrix[:, 2] += found.mean(axis=0) - prediction.nodes.mean(axis=0)
        return Prediction(found, found, matrix, prediction.support)

    def _predicted(self, grey: NDArray[np.uint8], prediction: Prediction) -> TrackResult:
        """The predicted contour as the frame's result, just below ``tracking``: on the
        first frame of a kind (:func:`engine.tracking.looks.change_look`), whose look was
        learnt from it and cannot judge it."""
        memory = self._memory
        if memory.outline is not None:
            memory.outline = follow(
                memory.outline, prediction.matrix, prediction.nodes, memory.hold
            )
        self._nodes, self._previous = prediction.nodes, grey
        self._unconfirmed = True
        return self._result(0, True, UNCONFIRMED if self._visible(self._nodes, grey) else 0.0)

    def _start(
        self, image: NDArray[np.uint8], grey: NDArray[np.uint8], grey_frame: bool
    ) -> TrackResult:
        """The first frame of a track: every stage learns the object anew."""
        self._previous = grey
        self._look_grey, self._aside = grey_frame, None
        self._forget_search()
        self.motion.reset()
        self.appearance.fit(image, self._nodes)
        self.cues.start(image, self._nodes, self.appearance)
        self.segmentation.start(image, self._nodes)
        if self.options.lighting:
            self._lighting.start(image, self._nodes)
        _, (x0, y0, x1, y1) = roi_box(image.shape, self._nodes, self.options.search_radius)
        contrast = side_contrast(
            self.appearance.probability(image[y0:y1, x0:x1]), (x0, y0), self._nodes
        )
        self._memory.hold = hold_factors(contrast, self.options.hold_below)
        if self.options.shape_memory:
            self._memory.outline = self._nodes.copy()
            if self.options.turn_outline:  # the marks ride on the outline
                self._memory.marks = self._memory.hold.copy()
        return self._result(0, True, 1.0 if self._visible(self._nodes, grey) else 0.0, True)

    def _forget_search(self) -> None:
        """No frames missed; the current contour is the shape to look for."""
        self._memory = Memory.fresh(self._nodes)

    def _result(
        self,
        iterations: int,
        converged: bool,
        confidence: float,
        remember: bool = False,
        shape: NDArray[np.bool_] | None = None,
    ) -> TrackResult:
        """The frame's result; ``remember``: its contour's shape (``shape``, if made
        already) is one later contours are compared with
        (:mod:`engine.tracking.recent_shapes`)."""
        self._reported = confidence
        status = status_of(confidence)
        self._memory.recent.add(self._nodes, remember and confidence > 0.0, shape)
        return TrackResult(self._in_frame(self._nodes), iterations, converged, confidence, status)

    @staticmethod
    def _visible(nodes: NDArray[np.float64], grey: NDArray[np.uint8]) -> bool:
        """Whether a node of ``nodes`` lies in the frame: a contour with none in it (beside
        the frame, or around all of it) shows none of its boundary."""
        return any_in_frame(nodes, grey.shape)

    # --- serialisation -------------------------------------------------------------

    def to_state(self, *, include_frame: bool = True, compact: bool = False) -> dict[str, Any]:
        """A JSON-able snapshot from which :meth:`from_state` resumes tracking.

        Parameters
        ----------
        include_frame : bool
            Keep the previous grey frame (PNG, base64) and each stage's state
            (for the defaults: the colour histograms, p(object) around the
            contour and the corners being tracked; hundreds of kB at 480p),
            so tracking continues exactly as if uninterrupted; without them
            the next frame re-initialises.
        compact : bool
            With ``include_frame``: a snapshot of a few tens of kB instead,
            for stores written at every frame.  The previous frame is kept at
            half resolution around the contour and a quarter elsewhere (JPEG)
            and stages that offer a ``to_compact_state`` method (the default
            cues: p(object) as three levels) use it.  Lossy: the next frame
            is tracked slightly differently from an uninterrupted run (the
            frames after it from that frame's exact result); the contour and the
            options stay exact, the colour histograms are kept to three digits
            (float16), the shape the search remembers and the shape memory's
            outline to a hundredth of a pixel, and the lighting keeps its gains
            but not the colours it compares the next frame with (that frame
            measures no change of light).
        """
        return snapshot(self, include_frame=include_frame, compact=compact)

    @classmethod
    def from_state(
        cls,
        state: Mapping[str, Any],
        *,
        motion: MotionModel | None = None,
        appearance: AppearanceModel | None = None,
        cues: BoundaryCues | None = None,
        segmentation: Segmentation | None = None,
    ) -> Tracker:
        """Rebuild a tracker from :meth:`to_state` output.

        Parameters
        ----------
        state : dict
            A snapshot of version 3, 2 (before the segmentation stage) or 1
            (before the stages); the older ones continue exactly as the
            tracker that wrote them, without the segmentation stage and the
            search (``cut_band`` 0, ``reacquire_above`` 1) unless their
            options ask for them.
        motion, appearance, cues, segmentation : optional
            Stages built like those of the tracker that wrote ``state`` (the
            defaults when it used the defaults); they get the state's.

        Raises
        ------
        ValueError
            If the state is malformed, of an unknown version, or of stages
            other than those given.
        """
        make = functools.partial(
            cls, motion=motion, appearance=appearance, cues=cues, segmentation=segmentation
        )
        return restore(make, state)
