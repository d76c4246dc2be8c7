"""``FlowMotion``: the default :class:`~engine.tracking.stages.MotionModel`.

Two parts:

1. rigid: a similarity transform of the whole object, from pyramidal
   Lucas-Kanade on corners inside the contour and on its nodes,
   forward-backward checked, with a RANSAC fit (:mod:`engine.tracking.motion`);
   the corners kept are tracked on from frame to frame and found anew every
   :data:`REDETECT_EVERY` frames.  With ``figure_ground`` the background's
   motion is measured around the contour on the motion's halved crops and the
   points that moved with it are left out of the fit: the object is what moves
   otherwise than its surroundings (on the thirty training sequences, mean J
   0.671 to 0.685 over five node counts; a contour that took in a textured
   wall no longer stays on the wall);
2. non-rigid: the object's own dense optical flow at each node beyond the
   similarity (:mod:`engine.tracking.flow`), trusted where it was read on
   object-like pixels and smoothed by the chain as a normalised equilibrium,
   ``deform(w r) / deform(w)`` (paper eq. 16; docs/math.md, "Flow smoothing"),
   unless the object moves faster than dense flow can follow (:data:`FLOW_REACH`).

Coordinates are ``[x, y]`` pixels (x = column, y = row), as in OpenCV.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any, Self

import numpy as np
from numpy.typing import NDArray

from engine.geometry import outward_normals
from engine.physics import deform
from engine.tracking.background import MEASURE
from engine.tracking.flow import DEPTH, node_flow, read_flow
from engine.tracking.motion import FramePair, Motion, estimate_motion
from engine.tracking.shared import SharedMotion
from engine.tracking.stages import Grey, Move, ObjectWeight, Prediction, check_kind
from engine.tracking.validity import valid_contour

__all__ = ["FLOW_REACH", "REDETECT_EVERY", "FlowMotion"]

KIND = "flow-motion"
REDETECT_EVERY = 10
"""Corners are tracked on from frame to frame and found anew every this many
frames: new texture comes into view as the object turns, and tracked corners
slowly drift off theirs."""
FLOW_REACH = 20.0
"""Mean displacement of the nodes (pixels per frame, by the similarity) beyond which the
non-rigid part is left out.  DIS's ultrafast preset reads an object's own motion over a
still background up to about 20 px: at 24-28 px the flow at a tenth of the nodes already
falls back towards the background's zero, and at 40 px (a thrown ball, a car passing
close) most of the outline reads as nearly still, which bent a correctly moved contour
back into a tail.  Beyond it the similarity alone predicts the contour; the refinement
and the cut take up the deformation."""
MIN_WEIGHT = 1e-3
"""Floor of the smoothed weight ``deform(w)`` the flow is divided by: where no
node's flow was read on the object, the non-rigid part is (almost) zero."""


class FlowMotion:
    """Similarity motion plus the chain-smoothed non-rigid flow at the nodes.

    Parameters
    ----------
    max_features : int
        :attr:`TrackerOptions.max_features`: corners tracked inside the object.
    flow_stiffness : float
        :attr:`TrackerOptions.flow_stiffness`: ``a`` of the chain smoothing the
        per-node flow (0: similarity only).
    figure_ground : bool, default True
        :attr:`TrackerOptions.figure_ground`: leave out of the similarity the
        points that moved with the background.
    """

    def __init__(
        self, max_features: int, flow_stiffness: float, figure_ground: bool = True
    ) -> None:
        self.max_features = max_features
        self.flow_stiffness = flow_stiffness
        self.figure_ground = figure_ground
        # corners on the object in the previous frame, to track on (None: find anew)
        self._features: NDArray[np.float32] | None = None

    def reset(self) -> None:
        """Find corners anew on the next frame."""
        self._features = None

    def rescale(self, move: Move, factor: float) -> None:
        """The corners being tracked on another grid (:func:`engine.tracking.regrid.follow_size`):
        ``move`` maps old-grid ``[x, y]`` points onto it (``factor``: its pixels per old one)."""
        if self._features is not None:
            self._features = move(self._features.astype(np.float64)).astype(np.float32)

    def predict(
        self,
        previous: Grey,
        current: Grey,
        nodes: NDArray[np.float64],
        *,
        frame_index: int,
        object_weight: ObjectWeight,
        covered: NDArray[np.bool_] | None = None,
        shared: SharedMotion | None = None,
    ) -> Prediction:
        """The contour moved by the similarity, then bent by the smoothed flow (if not fast).

        A similarity that makes the contour implausible
        (:func:`~engine.tracking.validity.valid_contour`) is replaced by no
        motion, and a bent contour that is implausible by the similarity's.
        Given ``covered`` (H x W bool: pixels of ``previous`` that other objects
        in front hide), the similarity leaves those pixels out and the contour is
        not bent.  Given ``shared`` (a session of several objects, measured between
        these two frames), its background motion and dense flow are read instead of
        measured around the contour.
        """
        features = self._features if frame_index % REDETECT_EVERY else None
        frames = FramePair.around(previous, current, nodes)  # for the turn too
        motion = estimate_motion(
            previous,
            current,
            nodes,
            max_features=self.max_features,
            features=features,
            figure_ground=self.figure_ground,
            covered=covered,
            background=MEASURE if shared is None else shared.background,
            frames=frames,
        )
        self._features = motion.tracked
        predicted = motion.apply(nodes)  # a similarity cannot make it cross itself
        if not valid_contour(predicted, current.shape, nodes, check_crossing=False):
            predicted, motion = nodes, Motion.identity()
            self._features = None
        rigid = predicted
        fast = float(np.linalg.norm(predicted - nodes, axis=1).mean()) > FLOW_REACH
        # an object partly behind another is moved rigidly: the flow next to the front
        # object's edge is smoothed into the front object's motion
        if self.flow_stiffness > 0 and not fast and covered is None:
            inward = -outward_normals(nodes)
            if shared is None:
                flow = node_flow(previous, current, nodes, inward)
            else:
                flow = read_flow(shared.flow, nodes, inward)
            residual = (nodes + flow) - predicted
            w = object_weight(nodes + DEPTH * inward)
            num = deform(w[:, None] * residual, self.flow_stiffness)
            den = deform(np.repeat(w[:, None], 2, axis=1), self.flow_stiffness)
            bent = predicted + num / np.maximum(den, MIN_WEIGHT)
            if valid_contour(bent, current.shape, nodes):
                predicted = bent
        return Prediction(predicted, rigid, motion.matrix, motion.inlier_ratio, frames)

    def to_state(self) -> dict[str, Any]:
        """``{"kind", "features": [[x, y], ...] or None}``: the corners being tracked."""
        features = None if self._features is None else self._features.tolist()
        return {"kind": KIND, "features": features}

    def from_state(self, state: Mapping[str, Any]) -> Self:
        """This model's parameters holding ``state`` (of :meth:`to_state`)."""
        check_kind(state, KIND, "motion")
        restored = type(self)(self.max_features, self.flow_stiffness, self.figure_ground)
        features = state.get("features")
        if features is not None:
            values = np.array(features, dtype=np.float32).reshape(-1, 2)
            if not np.isfinite(values).all():
                raise ValueError("features must be finite")
            restored._features = values
        return restored
