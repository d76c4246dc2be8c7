"""Several objects in one session: their outlines, what waits for a frame, their tracker.

A session created with ``"objects"`` follows each through the same frames
(:class:`engine.tracking.ObjectsTracker`).  An object given as a box (or an
outline with ``snap``) snaps onto the object on the next frame, and one given
as a mask must match that frame's size: both are checked on the frame, for
every object at once, before anything changes (a 422 leaves the session as it
was).  The snap reads colour alone on that frame; the frame after it snaps the
outline there again with what moved between the two
(:func:`engine.tracking.snap.snap`'s ``next_frame``), and the object starts anew
from that (:meth:`engine.tracking.ObjectsTracker.restart`), as ``efdm track``
starts it.  Coordinates are ``[x, y]`` pixels.
"""

from __future__ import annotations

import base64
import binascii
from collections.abc import Callable, Sequence
from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray

from engine.geometry import (
    MIN_PIECE_AREA,
    box_outline,
    circle_nodes,
    contour_to_mask,
    mask_to_contours,
    polygon_area,
)
from engine.tracking import ObjectsTracker, pack_image, unpack_image
from engine.tracking.snap import snap
from engine.tracking.tracker import MIN_AREA
from service.domain_errors import InvalidInputError, ObjectNotFoundError
from service.schemas import BOX_NODES, MAX_OBJECTS, Circle, ObjectSpec

__all__ = ["SessionObjects", "first_contour", "outline_nodes"]

MASK_NODES = 128
"""Nodes of an object given as a mask (of its largest piece; the others at the same
spacing, :func:`engine.geometry.mask_to_contours`)."""
MAX_PIECES = MAX_OBJECTS
"""Separate pieces of one object at most: each is a tracker of its own, as costly a frame
as an object (a mask of more answers 422; a snap keeps its largest)."""
PNG_MAGIC = b"\x89PNG"
KEPT_FRAME_QUALITY = 90
"""JPEG quality of the first frame kept for the second snap in a compact record (the shared
store's): 0.11-0.14 MB at 854 x 480 instead of the lossless PNG's 0.8-1.0 MB, for one
frame; the exact record keeps the PNG."""

Contours = list[NDArray[np.float64]]


def _mask(text: str) -> NDArray[np.uint8]:
    try:
        data = base64.b64decode(text, validate=True)
    except (binascii.Error, ValueError):
        raise InvalidInputError("mask: not base64") from None
    if data[:4] != PNG_MAGIC:
        raise InvalidInputError("mask: not a PNG (a mask must be lossless)")
    image = cv2.imdecode(np.frombuffer(data, np.uint8), cv2.IMREAD_GRAYSCALE)
    if image is None:
        raise InvalidInputError("mask: the PNG does not decode")
    return np.asarray(image, np.uint8)


def outline_nodes(
    circle: Circle | None, box: Sequence[float] | None, nodes: Any, max_nodes: int
) -> NDArray[np.float64]:
    """The contour of a circle, else a box (:data:`BOX_NODES` nodes), else a node list:
    the forms a session and an object are given in (the node count is the caller's to check).

    Raises InvalidInputError for a circle of more than ``max_nodes`` nodes.
    """
    if circle is not None:
        if circle.count > max_nodes:
            raise InvalidInputError(f"circle.count exceeds the limit of {max_nodes}")
        return circle_nodes(circle.center, circle.radius, circle.count)
    if box is not None:
        return box_outline(box, min(BOX_NODES, max_nodes))
    return np.asarray(nodes, dtype=np.float64)


def first_contour(shape: dict[str, Any]) -> NDArray[np.float64]:
    """The contour of an object as the API shows it (:func:`_shape`), or its first piece's."""
    return np.asarray(shape.get("nodes") or shape["contours"][0], dtype=np.float64)


def _snapped(mask: NDArray[np.uint8]) -> Contours:
    """A snap's contours: its :data:`MAX_PIECES` largest pieces of at least
    :data:`~engine.geometry.MIN_PIECE_AREA` pixels whose outlines enclose an area a tracker
    takes (:data:`engine.tracking.tracker.MIN_AREA`: a one-pixel line encloses none);
    ValueError when none is left."""
    pieces = mask_to_contours(mask, BOX_NODES, min_area=MIN_PIECE_AREA)
    kept = [c for c in pieces if abs(polygon_area(c)) >= MIN_AREA][:MAX_PIECES]
    if not kept:
        raise ValueError(
            f"no piece of what was found is one to track (at least {MIN_PIECE_AREA:g} px, "
            "enclosing an area: not a line)"
        )
    return kept


def outline(spec: ObjectSpec, max_nodes: int) -> tuple[Contours, dict[str, Any]]:
    """An object's contours and what waits for the next frame (``snap`` or ``size``)."""
    if spec.mask is None:
        contours = [outline_nodes(spec.circle, spec.box, spec.nodes, max_nodes)]
        if spec.nodes is not None and not 3 <= len(contours[0]) <= max_nodes:
            raise InvalidInputError(f"nodes: need 3 to {max_nodes}; got {len(contours[0])}")
    else:
        mask = _mask(str(spec.mask))
        try:
            contours = mask_to_contours(mask, MASK_NODES, min_area=MIN_PIECE_AREA)
        except ValueError as exc:
            raise InvalidInputError(f"mask: {exc}") from None
        if len(contours) > MAX_PIECES:
            raise InvalidInputError(
                f"mask: {len(contours)} separate pieces of at least {MIN_PIECE_AREA:g} px; "
                f"at most {MAX_PIECES}"
            )
        return contours, {"size": [int(mask.shape[1]), int(mask.shape[0])]}
    waiting: dict[str, Any] = {"check": True}
    if spec.snaps:
        waiting["snap"] = list(spec.box) if spec.box is not None else contours[0].tolist()
    return contours, waiting


class SessionObjects:
    """The objects of a session and their tracker.

    Parameters
    ----------
    tracker : ObjectsTracker
        One tracker per object, by id (text).
    waiting : dict
        Object id -> what its next frame must settle: ``"snap"`` (an outline
        to snap), ``"size"`` (a mask's width and height), ``"check"`` (the
        contour must overlap the frame), ``"again"`` (an outline snapped on
        ``first``, to snap there again with the next frame).
    first : numpy.ndarray, optional
        The frame outlines were last snapped on, while any waits to be snapped again.
    """

    def __init__(
        self,
        tracker: ObjectsTracker,
        waiting: dict[str, dict[str, Any]],
        first: NDArray[np.uint8] | None = None,
    ) -> None:
        self.tracker, self.waiting, self.first = tracker, waiting, first

    @classmethod
    def create(
        cls, specs: list[ObjectSpec], tracking: dict[str, Any], max_nodes: int
    ) -> SessionObjects:
        """The objects of a new session; InvalidInputError on a bad outline or option."""
        try:
            made = cls(ObjectsTracker(max_objects=MAX_OBJECTS, **tracking), {})
        except (TypeError, ValueError) as exc:
            raise InvalidInputError(f"tracking: {exc}") from None
        for spec in specs:
            made.add(spec, max_nodes)
        return made

    def _free_id(self) -> str:
        number = len(self.tracker.trackers) + 1
        while str(number) in self.tracker.trackers:
            number += 1
        return str(number)

    def add(self, spec: ObjectSpec, max_nodes: int) -> str:
        """Follow a new object from the next frame on; its id."""
        key = spec.id or self._free_id()
        if key in self.tracker.trackers:
            raise InvalidInputError(f"object {key!r} exists already")
        self._place(key, spec, max_nodes, self.tracker.add)
        return key

    def replace(self, key: str, spec: ObjectSpec, max_nodes: int) -> None:
        """A correction: the object starts anew from ``spec`` on the next frame."""
        if key not in self.tracker.trackers:
            raise ObjectNotFoundError(f"no object {key!r} in this session")
        if spec.id is not None and spec.id != key:
            raise InvalidInputError(f"the body names object {spec.id!r}, the URL {key!r}")
        self._place(key, spec, max_nodes, self.tracker.replace)

    def _place(
        self, key: str, spec: ObjectSpec, max_nodes: int, put: Callable[[str, Contours], None]
    ) -> None:
        """Give object ``key`` the outline of ``spec`` (``put``: add or replace)."""
        contours, waiting = outline(spec, max_nodes)
        try:
            put(key, contours)
        except ValueError as exc:
            raise InvalidInputError(f"object {key!r}: {exc}") from None
        self.waiting[key] = waiting

    def remove(self, key: str) -> None:
        """Stop following an object."""
        if key not in self.tracker.trackers:
            raise ObjectNotFoundError(f"no object {key!r} in this session")
        self.tracker.remove(key)
        self.waiting.pop(key, None)

    def _settle(self, frame: NDArray[np.uint8]) -> dict[str, Contours]:
        """The new contours of the objects waiting for this frame; checks all first."""
        height, width = frame.shape[:2]
        settled: dict[str, Contours] = {}
        for key, waiting in self.waiting.items():
            size = waiting.get("size")
            if size is not None and tuple(size) != (width, height):
                raise InvalidInputError(
                    f"object {key!r}: its mask is {size[0]}x{size[1]}, the frame {width}x{height}"
                )
            if "snap" in waiting:
                try:
                    settled[key] = _snapped(snap(frame, waiting["snap"]))
                except ValueError as exc:
                    raise InvalidInputError(f"object {key!r}: snap: {exc}") from None
            elif waiting.get("check"):
                contours = self.contours(key)
                if not any(contour_to_mask(c, (height, width)).any() for c in contours):
                    raise InvalidInputError(
                        f"object {key!r} lies outside the frame ({width}x{height})"
                    )
        return settled

    def contours(self, key: str) -> Contours:
        """An object's current contours."""
        return self.tracker.contours(key)

    def _snap_again(self, frame: NDArray[np.uint8]) -> None:
        """Snap again on :attr:`first`, with what moved between it and ``frame``, the
        outlines snapped there, and start those objects anew on it.  A frame of another
        size has nothing to add: their colour snaps stand."""
        first, self.first = self.first, None
        again = {k: w["again"] for k, w in self.waiting.items() if "again" in w}
        if first is None or first.shape[:2] != frame.shape[:2]:
            return
        for key, outline in again.items():
            try:
                contours = _snapped(snap(first, outline, next_frame=frame))
                self.tracker.restart(key, contours, first)
            except ValueError:
                continue  # nothing readable with the first frame: its colour snap stands

    def step(self, frame: NDArray[np.uint8]) -> list[dict[str, Any]]:
        """Track every object into ``frame`` (waiting ones settled first); their results."""
        settled = self._settle(frame)  # checks every object before anything changes
        self._snap_again(frame)
        for key, contours in settled.items():
            self.tracker.replace(key, contours)
        snapped = {k: w["snap"] for k, w in self.waiting.items() if "snap" in w}
        self.waiting = {key: {"again": outline} for key, outline in snapped.items()}
        self.first = frame.copy() if snapped else None
        results = self.tracker.step(frame)
        return [
            {
                "id": str(r.id),
                **_shape(r.contours),
                "confidence": float(r.confidence),
                "status": r.status,
                "behind": [str(key) for key in r.behind],
            }
            for r in results
        ]

    def describe(self) -> list[dict[str, Any]]:
        """Each object's id and contour(s)."""
        return [
            {"id": str(key), **_shape(self.contours(str(key)))} for key in self.tracker.trackers
        ]

    def to_state(self, *, compact: bool = False) -> dict[str, Any]:
        """JSON-able; :meth:`from_state` rebuilds it."""
        quality = KEPT_FRAME_QUALITY if compact else None
        first = None if self.first is None else pack_image(self.first, quality=quality)
        return {
            "tracker": self.tracker.to_state(compact=compact),
            "waiting": self.waiting,
            "first": first,
        }

    @classmethod
    def from_state(cls, state: dict[str, Any]) -> SessionObjects:
        """Inverse of :meth:`to_state`; ValueError if malformed."""
        waiting = state.get("waiting")
        if not isinstance(waiting, dict):
            raise ValueError("objects: 'waiting' must be a dict")
        first = state.get("first")
        return cls(
            ObjectsTracker.from_state(state["tracker"]),
            dict(waiting),
            None if first is None else unpack_image(str(first), colour=True),
        )


def _shape(contours: Contours) -> dict[str, Any]:
    points = [np.asarray(c, np.float64).tolist() for c in contours]
    return {"nodes": points[0]} if len(points) == 1 else {"contours": points}
