"""``TrackerOptions``: the tuning of :class:`engine.tracking.tracker.Tracker` and its bounds.

Coordinates are ``[x, y]`` pixels (x = column, y = row), as in OpenCV;
distances below are in pixels.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from engine.physics._validation import as_stiffness
from engine.tracking.appearance import COLOUR_BITS, MAX_COLOUR_BITS
from engine.tracking.motion import MAX_FEATURES
from engine.tracking.working import WORKING_SIDE

__all__ = ["TrackerOptions"]

_INTEGER_BOUNDS = {
    "search_radius": 256,
    "iterations": 100,
    "band": 256,
    "max_features": 1000,
    "colour_bits": MAX_COLOUR_BITS,
}
MIN_WORKING_SIDE = 64
"""Smallest working resolution (shorter side, pixels) besides 0: below it a frame holds
little more than the tracker's Lucas-Kanade pyramid and search windows."""
MAX_WORKING_SIDE = 16384
"""Largest working resolution: no camera's frame exceeds it."""
OBJECT_SIDE = 160
"""Default :attr:`TrackerOptions.object_side` (pixels)."""
MIN_OBJECT_SIDE = 16
"""Smallest ``object_side`` besides 0: an object this size is the smallest the tracker
follows well (the generated ``small`` object, 20-40 px across)."""
_ZERO_OR_BOUNDS = {
    "working_side": (MIN_WORKING_SIDE, MAX_WORKING_SIDE),
    "object_side": (MIN_OBJECT_SIDE, MAX_WORKING_SIDE),
}
"""Sizes that are 0 (off) or within these bounds."""
MAX_CUT_BAND = 64
"""Widest band of the joint segmentation: beyond this the cut is a whole-region
segmentation, slower and no longer anchored to the tracked shape."""
_NUMBER_BOUNDS: dict[str, float] = {
    "tolerance": math.inf,
    "region_weight": math.inf,
    "edge_weight": math.inf,
    "distance_penalty": math.inf,
    "flow_stiffness": 1e6,
    "learning_rate": 1.0,
    "reacquire_above": 1.0,
    "hold_below": 1.0,
    "far_background": 1.0,
}


@dataclass(frozen=True, slots=True)
class TrackerOptions:
    """Tuning of :class:`engine.tracking.Tracker` and its default stages.

    The defaults were chosen, before the training sequences arrived, on the
    five DAVIS-2016 sequences that are now the held-out validation set and on
    the synthetic conditions of :mod:`engine.testing.synthetic` (the reasons
    below); new choices are made by cross-validation on the thirty training
    sequences (``python -m bench.tracking --cv``).  Distances are pixels of
    the frame.

    Attributes
    ----------
    stiffness : float
        ``a = k/m`` of the chain that regularises the image forces (default
        40: the chain's Green's function decays by 1/e over about six nodes,
        so one node on clutter cannot kink the contour, yet a 128-node
        outline still bends round a limb).
    search_radius : int
        How far (1-256) each node looks for the boundary on the first
        iteration; later iterations look less far (default 12: what is left
        of a fast object's motion after the motion model's prediction).
    iterations : int
        Most refinement iterations per frame (1-100; default 10: enough for
        the radius to shrink step by step to 3 pixels).
    tolerance : float
        Converged when no node moved more than this in an iteration (default
        0.25 pixels: below the accuracy of the masks the tracker is judged on).
    region_weight, edge_weight, distance_penalty : float
        Cue weights of :func:`engine.tracking.boundary.find_boundary`: the
        colour-region split counts most (1.0), edges half as much (0.5: many
        edges are texture, not the boundary), and each search radius of
        displacement costs 0.15 (prefers the nearest of two equal boundaries).
    band : int
        Width (1-256) of the background ring of the colour model (default
        15: the surroundings the contour may move into between two frames).
    learning_rate : float
        Share in [0, 1] of each confident frame blended into the colour model
        (default 0.05: a lighting change is learnt within about 20 frames, a
        single bad frame moves the model by 5 %).
    max_features : int
        Corners tracked inside the object for the motion prediction (1-1000;
        default :data:`engine.tracking.motion.MAX_FEATURES`).
    flow_stiffness : float
        ``a`` of the chain that smooths the per-node optical flow added to
        the similarity prediction (0 disables the non-rigid prediction;
        default 20: softer than the refinement's chain (1/e over about four
        nodes), so that limbs may move on their own, stiff enough to average
        out a wrong flow vector).
    occlusion : bool
        Treat pixels that were the object's and now look like background,
        inside the rigidly moved silhouette, as covered by an occluder.
    cut_band : int
        Pixels (0-64) on each side of the refined contour that the joint
        band segmentation (:class:`engine.tracking.BandCut`) may relabel; 0
        turns it off (default 8: cross-validated on the thirty training
        sequences against 6 and 12; the most a boundary should move in one
        frame once the motion is compensated).
    reacquire_above : float
        When a frame does not end ``tracking``, the tracker searches a
        growing window for the object's remembered shape
        (:mod:`engine.tracking.reacquisition`) and moves there if the
        contour found reaches this search score
        (:func:`engine.tracking.confidence.search_score`; in [0, 1]; 1 turns the search
        off; default 0.55: cross-validated on the thirty training sequences
        against 0.445 and 0.65).
    hold_below : float
        Nodes whose two sides differ by less than this in p(object) on the
        first frame hold the shape where the image shows no step
        (:mod:`engine.tracking.holding`; in [0, 1], 0 turns it off; default
        0.4: cross-validated on the thirty training sequences against 0, 0.2
        and 0.6, chosen in all five folds).
    motion_contrast : bool
        Add to the colour evidence whether each pixel moved with the object
        or with the background (:mod:`engine.tracking.motion_contrast`;
        default True: cross-validated on the thirty training sequences, it
        raised J in every fold and cut the decay).
    figure_ground : bool
        Leave out of the object's motion the points inside the contour that
        moved with the background (:func:`engine.tracking.motion.estimate_motion`;
        default True: cross-validated on the thirty training sequences with
        each tracked from five node counts, chosen in all five folds, J 0.685
        against 0.671).
    shape_memory : bool
        Nodes held on the first frame that still show no colour step rest on
        the first frame's outline, carried with the object, where they would
        creep outside it (:mod:`engine.tracking.shape_memory`; default True:
        a stretch of boundary without contrast otherwise leaks further every
        frame; cross-validated on the thirty training sequences with each
        tracked from five node counts, chosen in all five folds, J 0.689
        against 0.685).
    lighting : bool
        Measure the change of light since the first frame, channel by
        channel, and undo what exceeds 5 % before the colours are read
        (:mod:`engine.tracking.lighting`; default True: without it a light
        dimming by a third over a few seconds loses the object; on the
        thirty training sequences, whose light hardly changes, it changes
        little: cross-validated, see ``bench/results/tracking_cv.md``).
    far_background : float
        Share in [0, 1] of the first frame's background colours drawn from
        the whole frame beyond two rings of the contour, the rest from the
        ring (:meth:`engine.tracking.appearance.Histograms.fit`): colours
        the ring does not show but the scene does are known as background
        when the object moves onto them.  Default 0.2, chosen in all five
        folds of the thirty training sequences over 0, 0.1 and 0.3 (J 0.707
        against 0.696 without, cross-validated).  It waited until the
        confidence model judged the contour's shape too
        (:func:`engine.tracking.confidence.shape_overlap`): without that, the
        model reported far fewer lost frames on sequences it was not fitted
        on (52 % of them against 88 %); see ``docs/tracking-log.md``.
    rigid_behind : bool
        When the occlusion rule finds the object partly behind something
        whose colours its surroundings lack
        (:func:`engine.tracking.occlusion.foreign`), the prediction is the
        similarity alone, not bent by the dense flow (default True: the flow
        next to a pole or a bar in front is the front object's, and drags the
        contour along with it; as for an object behind another tracked one).
        Cross-validated on the thirty training sequences over five node
        counts: chosen in all five folds, J 0.717 against 0.707; the synthetic
        ``occluder`` misses its goal on 4 seeds of 24 instead of 12.
    revealed_background : bool
        A piece the occlusion rule takes for covered whose colours are those of
        the object's surroundings is background the object's own motion
        uncovered (a gap opening between limbs, or between an arm and the
        body), not something in front: its colours count as they are instead
        of being made neutral (:func:`engine.tracking.occlusion.unoccluded`).
        Default True: neutral, the gap stayed the object's and the contour
        bridged it for as long as it lasted.  Cross-validated on the thirty
        training sequences over five node counts: chosen in all five folds, J
        0.729 against 0.717 (held out, four folds of five gain).  It cost lost
        detection on sequences the confidence model was not fitted on (see
        :data:`engine.tracking.confidence.TRACKING_FROM`).
    bridge_strips : bool
        The object's part beyond a thin strip that looks like background (a
        pole or a bar in front of it, up to 15 px wide) is taken back
        across the strip when its colours are plainly the object's and it lies
        inside the object's remembered outline (the cut's
        :func:`engine.tracking.beyond_band.bridge`; with ``shape_memory``).
        Default True: without it the contour kept the strip's near side and
        shrank with it as the strip swept across the object (the synthetic
        ``occluder`` with a static bar: 4 seeds of 24 at 0.61-0.66 IoU, of
        which 3 pass with it).  Cross-validated on the thirty training
        sequences over five node counts it ties: J 0.729 either way, off
        chosen in four folds of five by under 0.001 each (``docs/tracking-log.md``).
        Does nothing without ``shape_memory``, which keeps the outline.
    carve_gaps : bool
        Background seen through a gap that opened inside the object (two limbs
        that touched and part) is left out once it lies deeper than the cut's band
        and its colours are plainly the background's (the cut's
        :func:`engine.tracking.beyond_band.carve`).  Default True: without it the
        contour spanned the gap frame after frame, since the cut keeps everything
        deeper than its band.  Cross-validated on the thirty training sequences over
        five node counts: chosen in all five folds, J 0.735 against 0.729, every
        held-out fold up (0.853 / 0.697 / 0.687 / 0.652 / 0.784 against 0.849 /
        0.691 / 0.672 / 0.650 / 0.783).
    full_resolution_edges : bool
        A large object (its cut's band over 12,000 pixels), cut at half resolution to
        keep the frame's time, has its boundary placed to the pixel by a second cut at
        full resolution within 2 px inside the first's boundary and 1 px outside
        (:data:`engine.tracking.segmentation.FINE_INSIDE`, ``FINE_OUTSIDE``).  Default
        True: without it a large object's boundary is placed to 2 px.  Cross-validated
        on the thirty training sequences over five node counts: chosen in all five folds
        (``docs/tracking-log.md``).
    align_prediction : bool
        Before the refinement and the cut, the prediction is shifted (by up to 8 px
        each way) to where the frame's p(object) fits its silhouette best, when that
        is clearly better than where the motion put it
        (:func:`engine.tracking.alignment.align_to_appearance`).  Default True:
        without it a prediction the motion got wrong by more than the cut's band
        stayed off the object (a dog over a hurdle, a rider in motion blur).
        Cross-validated on the thirty training sequences over five node counts:
        chosen in all five folds, J 0.746 against 0.742 (``docs/tracking-log.md``).
    colour_bits : int
        Levels per BGR channel of the object and background colour histograms, as a
        power of two (1-5; :class:`engine.tracking.appearance.ColourHistogram`).
        Default 5, 32 levels: at 16 a colour 8 levels off the object's shared its
        bins half the time, so a background of nearly the object's colour read as
        object (:data:`engine.tracking.appearance.COLOUR_BITS`).  States written
        before it resume at 4.
    turn_outline : bool
        The remembered outline of ``shape_memory`` turns by the object's rotation
        measured from corners well inside it and the normal motion of its rim
        (:func:`engine.tracking.turn.measure_turn`), and the first frame's marks of
        the nodes held ride on the outline instead of on the contour's nodes.
        Default True: the motion model's similarity sees a nearly textureless object
        turn by a third of its turn, so the marks stayed behind and the contour took
        in the leading end of an object-coloured stretch of background (the
        synthetic ``no_contrast_stretch``: 9 seeds of 24 below 0.95, 5 with it).  The
        thirty training sequences over five node counts: J 0.7490 either way when it
        came; since strips up to 15 px are bridged, chosen in all five folds (0.749
        against 0.747, ``python -m bench.tracking --cv "turn_outline=true,false"``).  Does
        nothing without ``shape_memory``.  States written before it resume without.
    grey_texture : bool
        A grey frame (one channel, or three equal ones) is described to the colour
        models by its grey level, its edge energy and its local contrast
        (:func:`engine.tracking.texture.texture_image`) instead of its grey level
        alone.  Default True: the thirty training sequences turned grey score J 0.637 /
        decay +0.229 instead of 0.556 / +0.324 over five node counts, chosen in all five
        folds (``python -m bench.tracking --cv "grey_texture=false,true" --grey``), for
        about 8 ms more a grey frame.  Colour frames are unaffected.  States written
        before it resume without.
    working_side : int
        Frames whose shorter side exceeds this many pixels are tracked downscaled to
        it (:mod:`engine.tracking.working`); contours in and out stay in the frame's
        pixels.  Default 480, the DAVIS sequences' resolution, on which every pixel
        constant was chosen: a 720- or 1080-line camera is tracked as well as 480-line
        video and at about its cost (the thirty training sequences drawn at 720 lines:
        J 0.748 instead of 0.722, at 1080 lines 0.748 instead of 0.679, chosen in all
        five folds of ``python -m bench.tracking --cv "working_side=0,480" --resize
        2.25``).  0 tracks every frame at its own resolution; otherwise at least 64.
        States written before it resume with 0.
    object_side : int
        A track whose first contour encloses more than this many pixels squared
        (the square root of its area above it) is tracked on a grid smaller again by
        the ratio, so that the object is this size on it
        (:func:`engine.tracking.working.object_grid_side`); contours in and out stay in
        the frame's pixels.  The overlap is relative to the object's size: a large
        object's boundary placed to a coarser pixel costs it no more, and its frames
        cost what a smaller object's do.  Default 160 (pixels; 0: never): on the thirty
        training sequences over five node counts 0 / 140 / 160 / 180 / 200 gave J 0.749
        / 0.743 / 0.749 / 0.749 / 0.750 (``python -m bench.tracking --cv
        "object_side=0,140,160,180,200" --nodes 112,120,128,136,144``; 200 chosen in
        every fold, by at most 0.002), and 160, the smallest size that keeps J, takes a
        sixth off the validation five's median frame (four of their five objects start
        at about 205).  Decided on the track's first frame (and on
        :meth:`~engine.tracking.Tracker.reset`), and changed while the track is
        confident once the object's size has changed by a quarter, either way
        (:func:`engine.tracking.regrid.follow_size`).  Smaller sizes are faster and
        coarser: 80 takes about 0.73 of a frame's time, for J 0.735 / +0.123 on the
        thirty (56 / 64 / 72 / 96 / 112 / 128: 0.704 / 0.726 / 0.728 / 0.739 / 0.739 /
        0.741), and the generated objects (89-124 px) then fall under their goal in
        three conditions.  States written before it resume with 0.

    Raises
    ------
    ValueError
        If a field is of the wrong type or outside its bounds.
    """

    stiffness: float = 40.0
    search_radius: int = 12
    iterations: int = 10
    tolerance: float = 0.25
    region_weight: float = 1.0
    edge_weight: float = 0.5
    distance_penalty: float = 0.15
    band: int = 15
    learning_rate: float = 0.05
    max_features: int = MAX_FEATURES
    flow_stiffness: float = 20.0
    occlusion: bool = True
    cut_band: int = 8
    reacquire_above: float = 0.55
    hold_below: float = 0.4
    motion_contrast: bool = True
    figure_ground: bool = True
    shape_memory: bool = True
    lighting: bool = True
    far_background: float = 0.2
    rigid_behind: bool = True
    revealed_background: bool = True
    bridge_strips: bool = True
    carve_gaps: bool = True
    full_resolution_edges: bool = True
    align_prediction: bool = True
    colour_bits: int = COLOUR_BITS
    turn_outline: bool = True
    grey_texture: bool = True
    working_side: int = WORKING_SIDE
    object_side: int = OBJECT_SIDE

    @classmethod
    def from_mapping(cls, options: Mapping[str, Any]) -> TrackerOptions:
        """Options from a mapping of field names, with a clear error for unknown ones.

        Raises
        ------
        ValueError
            Naming an unknown option and listing the valid ones, or as
            :class:`TrackerOptions` for a bad value.
        """
        names = [f.name for f in dataclasses.fields(cls)]
        unknown = sorted(str(k) for k in options if k not in names)
        if unknown:
            raise ValueError(
                f"unknown tracker option {', '.join(map(repr, unknown))}; "
                f"the options are {', '.join(names)}"
            )
        return cls(**options)

    def __post_init__(self) -> None:
        as_stiffness(self.stiffness)
        for name, top in _INTEGER_BOUNDS.items():
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int) or not 1 <= value <= top:
                raise ValueError(f"{name} must be an integer in [1, {top}]; got {value!r}")
        for name, limit in _NUMBER_BOUNDS.items():
            value = getattr(self, name)
            ok = isinstance(value, int | float) and not isinstance(value, bool)
            if not ok or not math.isfinite(value) or not 0 <= value <= limit:
                raise ValueError(f"{name} must be a finite number in [0, {limit:g}]; got {value!r}")
        for name, (low, high) in _ZERO_OR_BOUNDS.items():
            value = getattr(self, name)
            if (
                isinstance(value, bool)
                or not isinstance(value, int)
                or not (value == 0 or low <= value <= high)
            ):
                raise ValueError(
                    f"{name} must be 0 or an integer in [{low}, {high}]; got {value!r}"
                )
        band = self.cut_band
        if isinstance(band, bool) or not isinstance(band, int) or not 0 <= band <= MAX_CUT_BAND:
            raise ValueError(f"cut_band must be an integer in [0, {MAX_CUT_BAND}]; got {band!r}")
        for name in (
            "occlusion",
            "motion_contrast",
            "figure_ground",
            "shape_memory",
            "lighting",
            "rigid_behind",
            "revealed_background",
            "bridge_strips",
            "carve_gaps",
            "full_resolution_edges",
            "align_prediction",
            "turn_outline",
            "grey_texture",
        ):
            if not isinstance(getattr(self, name), bool):
                raise ValueError(f"{name} must be true or false; got {getattr(self, name)!r}")
