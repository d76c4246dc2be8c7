"""One attempt at a frame: cue maps, refinement and cut around a prediction.

:class:`engine.tracking.Tracker` makes one attempt a frame around the motion's
prediction and, when that one ends unconfident, a second around the remembered shape
found elsewhere (:mod:`engine.tracking.reacquisition`); the better-scoring one is the
frame's.  An attempt is steps 2-5 of the tracker's frame (its module docstring): the cue
maps of the prediction's surroundings (with the motion contrast and the pixels other
objects cover), the prediction aligned to them and resting on the remembered outline
where the image shows no colour step (:mod:`engine.tracking.shape_memory`), the chain's
refinement (paper eq. 13-16, :func:`engine.tracking.refine`), the joint cut of the band
around it, and the evidence about the result with its confidence and search score.

Coordinates are ``[x, y]`` pixels (x = column, y = row), as in OpenCV.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from engine.tracking.alignment import aligned
from engine.tracking.background import MEASURE, Background
from engine.tracking.confidence import Evidence, calibrated, evidence, search_score
from engine.tracking.covering import cover_maps, covered_share
from engine.tracking.holding import hold_factors, side_contrast
from engine.tracking.motion_contrast import motion_ratio, with_motion
from engine.tracking.refinement import Refinement, refine
from engine.tracking.shape_memory import marks_at, rest_on
from engine.tracking.shared import Crowd
from engine.tracking.stages import BoundaryCues, Prediction
from engine.tracking.validity import valid_contour

if TYPE_CHECKING:
    from engine.tracking.tracker import Tracker

__all__ = ["BEHIND_FROM", "Attempt", "track_around"]

BEHIND_FROM = 0.02
"""An object this much hidden by other tracked objects in front is behind them for the
frame: no joint cut (whose smoothness would pull the unseen part in, as a curve shortens
where nothing holds it), and it learns nothing (the pixels inside its contour are partly
theirs).  Their rims touching it hide less than this."""


@dataclass(frozen=True, slots=True)
class Attempt:
    """One way of tracking the frame: the refinement, the final contour, the evidence
    about it, its confidence (reported) and its score (the search's decisions)."""

    refinement: Refinement
    nodes: NDArray[np.float64]
    evidence: Evidence
    confidence: float
    score: float


def track_around(
    tracker: Tracker,
    image: NDArray[np.uint8],
    grey: NDArray[np.uint8],
    prediction: Prediction,
    cues: BoundaryCues,
    hold: NDArray[np.float64],
    crowd: Crowd,
    outline: NDArray[np.float64] | None = None,
    marks: NDArray[np.float64] | None = None,
    *,
    textured: bool,
) -> Attempt:
    """Cue maps, refinement and cut around ``prediction``; the confidence of the result.

    Parameters
    ----------
    tracker : Tracker
        The tracker, on its previous frame: its options, previous grey frame and contour,
        appearance and segmentation stages, and memory (the usual look) are read, and
        none of them changed.
    image, grey : numpy.ndarray
        The frame (in the first frame's light) and its grey version, on the working grid.
    prediction : Prediction
        Where the motion (or the search) puts the contour, ``[x, y]`` pixels.
    cues : BoundaryCues
        The cue stage to make the maps with (the tracker's, or a copy from before the
        frame when the search retries it).
    hold : numpy.ndarray
        (N,) how much each node rests on the predicted shape (:mod:`engine.tracking.holding`).
    crowd : Crowd
        The pixels other objects in front cover, and the background's motion measured
        for the whole frame (:mod:`engine.tracking.shared`).
    outline, marks : numpy.ndarray, optional
        The remembered outline and its hold marks: the nodes held on the first frame
        that show no colour step now are put back on it where they lie outside it
        (:mod:`engine.tracking.shape_memory`), held as ``marks`` say where they are
        given, else as ``hold`` says.
    textured : bool
        The frame is grey and ``image`` its texture (:mod:`engine.tracking.texture`),
        which the confidence reads with its grey model
        (:data:`engine.tracking.confidence.GREY_COEFFICIENTS`).
    """
    options, previous, memory = tracker.options, tracker._previous, tracker._memory
    maps = cues.maps(image, grey, prediction, tracker.appearance)
    if maps.in_front:
        # partly behind something: the flow next to it is the front object's
        prediction = dataclasses.replace(prediction, nodes=prediction.rigid)
    guide = maps
    if options.motion_contrast and previous is not None:
        shape = maps.probability.shape
        args = (maps.origin, shape, tracker._nodes, prediction.matrix)
        shared = crowd.shared
        background: Background = MEASURE if shared is None else shared.background
        ratio = motion_ratio(previous, grey, *args, background=background)
        if ratio is not None:
            probability = with_motion(maps.probability, ratio)
            guide = dataclasses.replace(maps, probability=probability, observed=maps.seen)
            maps = dataclasses.replace(maps, motion=ratio)
    guide, maps = cover_maps(guide, crowd.covered), cover_maps(maps, crowd.covered)
    if options.align_prediction:
        prediction = aligned(prediction, guide)
    if outline is not None:
        contrast = side_contrast(maps.probability, maps.origin, prediction.nodes)
        held = hold if marks is None else marks_at(prediction.nodes, outline, marks)
        still = held * hold_factors(contrast, options.hold_below)
        prediction = dataclasses.replace(
            prediction, nodes=rest_on(prediction.nodes, outline, still)
        )
    refinement = refine(
        guide,
        grey.shape,
        prediction.nodes,
        options=options,
        previous_nodes=tracker._nodes,
        hold=hold,
    )
    nodes = refinement.nodes
    # behind another object, the cut's smoothness would pull the unseen part in
    behind = covered_share(crowd.covered, prediction.nodes) >= BEHIND_FROM
    cut = None
    if not behind:
        cut = tracker.segmentation.segment(image, maps, prediction.nodes, nodes, outline=outline)
    if cut is not None and valid_contour(cut, grey.shape, tracker._nodes):
        nodes = cut
    found = evidence(maps, nodes, refinement.converged, memory.outline, memory.recent)
    usual_in, usual_out = memory.usual_with(found.inside, found.outside)
    found = dataclasses.replace(
        found, usual_inside=usual_in, usual_outside=usual_out, grey=textured
    )
    return Attempt(refinement, nodes, found, calibrated(found), search_score(found))
