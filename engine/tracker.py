"""``Tracker``: follow an object's boundary through video frames.

Per frame (``step``):

1. predict the object's motion: pyramidal Lucas-Kanade on the contour and on
   corners inside it, forward-backward checked, with a RANSAC similarity fit
   (:mod:`engine.motion`);
2. refine (:mod:`engine.refinement`): each node seeks the boundary along its
   normal (colour model and edges, :mod:`engine.image_forces`); the pulls are
   forces on the chain, whose equilibrium around the predicted shape,
   X = X0 + U with (I + K) U = F (paper eq. 13-16, :func:`engine.deform`),
   keeps the shape plausible through noise, clutter and occlusion;
3. resample by arc length and guard against crossing, collapse and NaN.

The options live in :mod:`engine.tracker_options` (re-exported here).

Coordinates are ``[x, y]`` pixels (x = column, y = row), as in OpenCV.
"""

from __future__ import annotations

import binascii
import contextlib
import dataclasses
import zlib
from collections.abc import Iterator
from dataclasses import dataclass
from typing import Any

import cv2
import numpy as np
from numpy.typing import ArrayLike, NDArray

from engine._state_codec import pack_histogram, pack_image, unpack_histogram, unpack_image
from engine.appearance import AppearanceModel
from engine.deform import deform
from engine.flow import node_flow
from engine.geometry import as_nodes, resample
from engine.image_forces import Maps, outward_normals
from engine.motion import Motion, estimate_motion
from engine.refinement import LocatedProbability, refine, roi_box, valid_contour
from engine.tracker_options import TrackerOptions

__all__ = ["TrackResult", "Tracker", "TrackerOptions"]

STATE_VERSION = 1
MIN_SIDE = 16  # frames smaller than this carry no trackable information
REDETECT_EVERY = 10
"""Corners are tracked on from frame to frame and found anew every this many frames."""


@dataclass(frozen=True, slots=True)
class TrackResult:
    """Result of one :meth:`Tracker.step`.

    Attributes
    ----------
    nodes : numpy.ndarray
        (N, 2) float64 contour, ``[x, y]`` pixels.
    iterations : int
        Refinement iterations run.
    converged : bool
        Whether the refinement settled before the iteration limit.
    confidence : float
        In [0, 1]; drops when the object is lost (little motion support and
        no boundary evidence).
    """

    nodes: NDArray[np.float64]
    iterations: int
    converged: bool
    confidence: float


@contextlib.contextmanager
def _repeatable_opencv() -> Iterator[None]:
    """OpenCV without its IPP fast paths, for this thread, while tracking.

    Some IPP kernels round differently with memory alignment and thread count,
    so the same frames could track a little differently from run to run (and
    between the library and the service).  Costs about 7 % of a frame's time;
    the setting is thread-local and restored afterwards.
    """
    previous = cv2.ipp.useIPP()
    cv2.ipp.setUseIPP(False)
    try:
        yield
    finally:
        cv2.ipp.setUseIPP(previous)


def _as_frame(frame: Any) -> tuple[NDArray[np.uint8], NDArray[np.uint8]]:
    """Validate a frame; return it as (BGR or grey image, grey image)."""
    if not isinstance(frame, np.ndarray):
        raise ValueError(f"frame must be a numpy array; got {type(frame).__name__}")
    if frame.dtype != np.uint8:
        raise ValueError(f"frame must be uint8 (as OpenCV decodes images); got {frame.dtype}")
    if frame.size == 0:
        raise ValueError(f"frame is empty: shape {frame.shape}")
    if frame.ndim == 3 and frame.shape[2] == 1:
        frame = frame[..., 0]
    if frame.ndim == 2:
        grey = np.ascontiguousarray(frame)
        return grey, grey
    if frame.ndim == 3 and frame.shape[2] in (3, 4):
        colour = np.ascontiguousarray(frame[..., :3])
        return colour, np.asarray(cv2.cvtColor(colour, cv2.COLOR_BGR2GRAY), dtype=np.uint8)
    raise ValueError(f"frame must be H x W grey or H x W x 3 BGR; got shape {frame.shape}")


def _as_features(value: Any) -> NDArray[np.float32]:
    """Corners from a tracker state: finite ``[x, y]`` pairs."""
    features = np.array(value, dtype=np.float32).reshape(-1, 2)
    if not np.isfinite(features).all():
        raise ValueError("features must be finite")
    return features


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
        **options: Any,
    ) -> None:
        if not closed:
            raise ValueError("the tracker follows object boundaries: closed contours only")
        if stiffness is not None:
            options["stiffness"] = stiffness
        try:
            self.options = TrackerOptions(**options)
        except TypeError as exc:
            raise ValueError(f"unknown tracker option: {exc}") from None
        self._nodes = self._initial(nodes)
        self._previous: NDArray[np.uint8] | None = None
        self._model: AppearanceModel | None = None
        # p(object) around the contour in the previous frame, 0-255, and its origin
        self._probability: LocatedProbability | None = None
        # corners on the object in the previous frame, to track on (None: find anew)
        self._features: NDArray[np.float32] | None = None
        self.frame_index = -1

    @staticmethod
    def _initial(nodes: ArrayLike) -> NDArray[np.float64]:
        arr = as_nodes(nodes)
        out = resample(arr, len(arr))
        if np.ptp(out, axis=0).max() <= 0:
            raise ValueError("the contour has zero length (all nodes coincide)")
        return out

    @property
    def nodes(self) -> NDArray[np.float64]:
        """The current contour, (N, 2) ``[x, y]`` (a copy)."""
        return self._nodes.copy()

    def reset(self, nodes: ArrayLike) -> None:
        """Place a new contour; the next frame is taken as the one it lies on."""
        self._nodes = self._initial(nodes)
        self._previous = None
        self._model = None
        self._probability = None
        self._features = None

    def step(self, frame: NDArray[np.uint8]) -> TrackResult:
        """Track into the next frame.

        The first frame (and the first after :meth:`reset`) only initialises
        the colour model from the given contour and returns it unchanged.

        Parameters
        ----------
        frame : numpy.ndarray
            H x W grey or H x W x 3 BGR uint8.

        Returns
        -------
        TrackResult

        Raises
        ------
        ValueError
            If the frame is not a non-empty uint8 image.
        """
        with _repeatable_opencv():
            return self._step(frame)

    def _step(self, frame: NDArray[np.uint8]) -> TrackResult:
        image, grey = _as_frame(frame)
        self.frame_index += 1
        opts = self.options
        if min(grey.shape) < MIN_SIDE:
            return self._result(0, False, 0.0)
        if self._previous is None or self._previous.shape != grey.shape or self._model is None:
            self._previous = grey
            self._model = AppearanceModel.fit(image, self._nodes, opts.band)
            self._probability = self._located_probability(image, self._nodes)
            self._features = None
            return self._result(0, True, 1.0 if self._visible(grey) else 0.0)
        features = self._features if self.frame_index % REDETECT_EVERY else None
        motion = estimate_motion(
            self._previous, grey, self._nodes, max_features=opts.max_features, features=features
        )
        self._features = motion.tracked
        predicted = motion.apply(self._nodes)  # a similarity cannot make it cross itself
        if not self._valid(predicted, grey.shape, check_crossing=False):
            predicted, motion = self._nodes, Motion.identity()
            self._features = None
        rigid = predicted
        if opts.flow_stiffness > 0:
            # non-rigid part: the object's own flow at each node, beyond the
            # similarity, smoothed as the equilibrium of the chain (eq. 16)
            inward = -outward_normals(self._nodes)
            flow = node_flow(self._previous, grey, self._nodes, inward)
            residual = (self._nodes + flow) - predicted
            # trust the flow only where it was read on object-like pixels, and
            # smooth it as a normalised equilibrium: deform(w r) / deform(w)
            w = self._object_weight(self._nodes + 3.0 * inward)
            num = deform(w[:, None] * residual, opts.flow_stiffness)
            den = deform(np.repeat(w[:, None], 2, axis=1), opts.flow_stiffness)
            bent = predicted + num / np.maximum(den, 1e-3)
            if self._valid(bent, grey.shape):
                predicted = bent
        # the silhouette moved rigidly with the object: where it used to be
        silhouette = (motion.matrix, rigid) if opts.occlusion else None
        refinement = refine(
            image,
            grey,
            predicted,
            model=self._model,
            options=opts,
            previous_nodes=self._nodes,
            previous_probability=self._probability,
            silhouette=silhouette,
        )
        refined = refinement.nodes
        confidence = float(np.clip(0.4 * motion.inlier_ratio + 0.6 * refinement.contrast, 0.0, 1.0))
        if not self._visible(grey):
            confidence = 0.0
        self._nodes = refined
        self._previous = grey
        self._probability = self._located_probability(image, refined, refinement.maps)
        if confidence >= 0.5 and opts.learning_rate > 0:
            self._model = self._model.updated(image, refined, opts.band, opts.learning_rate)
        return self._result(refinement.iterations, refinement.converged, confidence)

    def _located_probability(
        self, image: NDArray[np.uint8], nodes: NDArray[np.float64], maps: Maps | None = None
    ) -> LocatedProbability | None:
        """p(object) as 0-255 around ``nodes`` (with its origin), for the next frame.

        Reuses the refinement's ``maps`` (they cover the search band around the
        prediction, hence the refined contour) instead of computing them again.
        """
        if self._model is None:
            return None
        if maps is None:
            origin, box = roi_box(image.shape, nodes, self.options.search_radius)
            x0, y0, x1, y1 = box
            prob = self._model.probability(image[y0:y1, x0:x1])
            return origin, np.round(prob * 255.0).astype(np.uint8)
        # one pass: scale, round half to even (as np.round) and saturate
        return maps.origin, np.asarray(cv2.convertScaleAbs(maps.probability, alpha=255.0))

    def _object_weight(self, points: NDArray[np.float64]) -> NDArray[np.float64]:
        """p(object) in the previous frame at ``points`` (1 where unknown)."""
        if self._probability is None:
            return np.ones(len(points))
        (x0, y0), prob = self._probability
        ij = np.round(points - [x0, y0]).astype(int)
        h, w = prob.shape
        inside = (ij[:, 0] >= 0) & (ij[:, 0] < w) & (ij[:, 1] >= 0) & (ij[:, 1] < h)
        out = np.ones(len(points))
        out[inside] = prob[ij[inside, 1], ij[inside, 0]] / 255.0
        return out

    def _result(self, iterations: int, converged: bool, confidence: float) -> TrackResult:
        return TrackResult(self._nodes.copy(), iterations, converged, confidence)

    def _visible(self, grey: NDArray[np.uint8]) -> bool:
        h, w = grey.shape
        lo, hi = self._nodes.min(axis=0), self._nodes.max(axis=0)
        return bool(hi[0] >= 0 and hi[1] >= 0 and lo[0] < w and lo[1] < h)

    def _valid(
        self, nodes: NDArray[np.float64], shape: tuple[int, ...], *, check_crossing: bool = True
    ) -> bool:
        """:func:`engine.refinement.valid_contour` against the current contour."""
        return valid_contour(nodes, shape, self._nodes, check_crossing=check_crossing)

    # --- serialisation -------------------------------------------------------------

    def to_state(self, *, include_frame: bool = True) -> dict[str, Any]:
        """A JSON-able snapshot from which :meth:`from_state` resumes tracking.

        Parameters
        ----------
        include_frame : bool
            Keep the previous grey frame, the colour model, the object
            probability around the contour (PNG and compressed histograms,
            base64; tens of kB) and the corners being tracked, so tracking
            continues exactly as if uninterrupted; without them the next
            frame re-initialises.
        """
        state: dict[str, Any] = {
            "version": STATE_VERSION,
            "nodes": self._nodes.tolist(),
            "options": dataclasses.asdict(self.options),
            "frame_index": self.frame_index,
            "model": None,
            "previous": None,
            "probability": None,
            "features": None,
        }
        if self._model is not None and self._previous is not None and include_frame:
            state["model"] = {
                "object": pack_histogram(self._model.object_hist),
                "background": pack_histogram(self._model.background_hist),
            }
            state["previous"] = pack_image(self._previous)
            if self._probability is not None:
                origin, prob = self._probability
                state["probability"] = {"origin": list(origin), "png": pack_image(prob)}
            if self._features is not None:
                state["features"] = self._features.tolist()
        return state

    @classmethod
    def from_state(cls, state: dict[str, Any]) -> Tracker:
        """Rebuild a tracker from :meth:`to_state` output.

        Raises
        ------
        ValueError
            If the state is malformed or of another version.
        """
        if not isinstance(state, dict) or state.get("version") != STATE_VERSION:
            raise ValueError(f"tracker state must be a dict of version {STATE_VERSION}")
        try:
            tracker = cls(state["nodes"], **dict(state["options"]))
            tracker._nodes = as_nodes(state["nodes"])  # exactly, not resampled again
            tracker.frame_index = int(state["frame_index"])
            model, previous = state.get("model"), state.get("previous")
            if model is not None and previous is not None:
                obj = unpack_histogram(model["object"])
                bg = unpack_histogram(model["background"])
                if obj.shape != bg.shape:
                    raise ValueError("object and background histograms differ in size")
                tracker._previous = unpack_image(previous)
                tracker._model = AppearanceModel(obj, bg)
                located = state.get("probability")
                if located is not None:
                    x, y = (int(v) for v in located["origin"])
                    tracker._probability = ((x, y), unpack_image(located["png"]))
                features = state.get("features")
                if features is not None:
                    tracker._features = _as_features(features)
        except (KeyError, TypeError, ValueError, binascii.Error, zlib.error) as exc:
            raise ValueError(f"malformed tracker state: {exc}") from None
        return tracker
