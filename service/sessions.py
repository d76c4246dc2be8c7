"""A tracking session: the contour, its physics and its tracker (no web code).

All methods are synchronous and CPU-bound; the routes run them in worker
threads.  Coordinates are ``[x, y]`` pixels.
"""

from __future__ import annotations

import secrets
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from engine import Tracker, deform
from engine.geometry import contour_to_mask, mask_to_contour
from engine.physics import MODAL_METHODS
from engine.tracking import pack_image, unpack_image
from engine.tracking.snap import snap
from service.domain_errors import BadImageError, InvalidInputError, PreconditionFailedError
from service.objects import KEPT_FRAME_QUALITY, SessionObjects, first_contour, outline_nodes
from service.schemas import LIMIT, SessionCreate
from service.units import TIMES

NEAR_LIMIT = 1e6
"""Pixels within the coordinate limit where a frame's step is undoable: far more
than a tracker moves a contour in one frame."""
MODAL_MAX_NODES = 1024
"""Node limit of the O(N^3) modal methods (about 0.3 s per request at 1024)."""


def _size(value: Any) -> tuple[int, int] | None:
    """A stored ``[width, height]`` (None: no frame yet, or a record from before it was kept)."""
    if value is None:
        return None
    width, height = value
    return int(width), int(height)


def expiry(touched: float, ttl: float) -> str:
    """When a session last touched at ``touched`` expires, ISO 8601 UTC (``...Z``)."""
    return time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime(touched + ttl))


def new_id() -> str:
    """An unguessable session id (128 random bits, URL-safe)."""
    return secrets.token_urlsafe(16)


@dataclass
class Session:
    """One client's deformable contour and tracker.

    ``rest`` is the shape forces act on (the initial contour, then each tracked
    contour); ``nodes`` the latest result (of forces or of a frame).
    """

    id: str
    owner: str | None
    closed: bool
    stiffness: float
    method: str
    tracking: dict[str, Any]
    rest: NDArray[np.float64]
    nodes: NDArray[np.float64]
    frame_index: int = -1
    version: int = 1
    touched: float = field(default_factory=time.time)
    tracker: Tracker | None = None
    frame_size: tuple[int, int] | None = None  # (width, height) of the last frame tracked
    ttl: float | None = None  # idle seconds to expiry, when shorter than the server's
    # the outline to snap onto the object: a box or a polygon (None: done).  It is snapped on
    # the first frame from colour alone, and again on the next with what moved between them
    snap_outline: list[Any] | None = None
    snap_frame: NDArray[np.uint8] | None = None  # that first frame, until the next one comes
    objects: SessionObjects | None = None  # a session of several objects

    def lifetime(self, server_ttl: float) -> float:
        """Idle seconds before this session expires: its own TTL, at most the server's."""
        return server_ttl if self.ttl is None else min(self.ttl, server_ttl)

    @classmethod
    def create(cls, spec: SessionCreate, owner: str | None, max_nodes: int) -> Session:
        """Validate the request's contour and options.

        Raises
        ------
        InvalidInputError
            Too few or too many nodes, or tracker options it cannot take.
        """
        if spec.objects is not None:
            objects = SessionObjects.create(spec.objects, dict(spec.tracking), max_nodes)
            nodes = first_contour(objects.describe()[0])
            return cls(
                id=new_id(),
                owner=owner,
                closed=True,
                stiffness=spec.stiffness,
                method=spec.method,
                tracking=dict(spec.tracking),
                rest=nodes.copy(),
                nodes=nodes.copy(),
                ttl=spec.ttl_seconds,
                objects=objects,
            )
        nodes = outline_nodes(spec.circle, spec.box, spec.nodes, max_nodes)
        need = 3 if spec.closed else 2
        if spec.method in MODAL_METHODS:  # O(N^3) references: bounded CPU per request
            max_nodes = min(max_nodes, MODAL_MAX_NODES)
        if not need <= len(nodes) <= max_nodes:
            raise InvalidInputError(f"nodes: need {need} to {max_nodes} nodes; got {len(nodes)}")
        try:
            tracker = Tracker(nodes, **spec.tracking) if spec.closed else None
        except (TypeError, ValueError) as exc:
            raise InvalidInputError(f"tracking: {exc}") from None
        if spec.closed and tracker is not None:
            nodes = tracker.nodes  # evenly spaced by arc length
        return cls(
            id=new_id(),
            owner=owner,
            closed=spec.closed,
            stiffness=spec.stiffness,
            method=spec.method,
            tracking=dict(spec.tracking),
            rest=nodes.copy(),
            nodes=nodes.copy(),
            tracker=tracker,
            ttl=spec.ttl_seconds,
            snap_outline=None
            if not spec.snaps
            else list(spec.box)
            if spec.box is not None
            else nodes.tolist(),
        )

    def expect_version(self, wanted: str) -> None:
        """Check the version a client's change expects against the session's.

        Raises
        ------
        PreconditionFailedError
            The session is at another version than ``wanted``.
        """
        if wanted != str(self.version):
            raise PreconditionFailedError(f"session is at version {self.version}, not {wanted}")

    def apply_forces(self, forces: list[tuple[float, float]]) -> NDArray[np.float64]:
        """Equilibrium of the rest shape under ``forces``; returns the displacements.

        The tracker restarts from the deformed contour (the next frame
        re-initialises its colour model there).

        Raises
        ------
        InvalidInputError
            Not one force per node, or forces the model cannot take.
        """
        if self.objects is not None:
            raise InvalidInputError("forces act on a session of one contour, not of 'objects'")
        F = np.asarray(forces, dtype=np.float64)
        if F.shape != self.rest.shape:
            raise InvalidInputError(
                f"forces: need {len(self.rest)} forces, one per node; got {len(F)}"
            )
        try:
            U = deform(F, self.stiffness, closed=self.closed, method=self.method)
        except ValueError as exc:
            raise InvalidInputError(f"forces: {exc}") from None
        nodes = self.rest + U
        if not np.isfinite(nodes).all():
            raise InvalidInputError("forces: the deformed contour overflows float64")
        # every result is checked against the response's own bounds before it is kept
        reach = max(float(np.abs(nodes).max()), float(np.abs(U).max()))
        if reach > LIMIT:
            raise InvalidInputError(
                f"forces: they move the contour to {reach:.10g} px, beyond the limit of "
                f"+-{LIMIT:g} px; the session is unchanged"
            )
        if self.tracker is not None:
            try:
                self.tracker.reset(nodes)  # validates before anything changes
            except ValueError as exc:
                raise InvalidInputError(f"forces: {exc}") from None
        if self.snap_frame is not None:  # snapped already: the client's contour stands
            self.snap_outline = self.snap_frame = None
        self.nodes = nodes
        self.version += 1
        return U

    def track(self, frame: NDArray[np.uint8]) -> dict[str, Any]:
        """One tracker step on a decoded frame; returns the frame result fields.

        Raises
        ------
        InvalidInputError
            The session is an open chain (only closed contours are tracked), or its
            contour lies outside its first frame.
        BadImageError
            The tracker cannot use the frame.
        """
        if self.objects is not None:
            return self._track_objects(frame)
        if self.tracker is None:
            raise InvalidInputError("frames need a closed contour (an object boundary)")
        start = time.perf_counter()
        if self.frame_index < 0 and self.snap_outline is None:
            height, width = frame.shape[:2]
            if not contour_to_mask(self.nodes, (height, width)).any():  # as a snap refuses it
                raise InvalidInputError(
                    f"the contour lies outside the first frame ({width}{TIMES}{height}); "
                    "the session is unchanged"
                )
        if self.snap_outline is not None and self.snap_frame is None:
            self._snap(frame)
        elif self.snap_outline is not None:
            self._snap_again(frame)
        # frames were tracked, and the tracker waits for a first one: forces moved the contour
        restarted = self.frame_index >= 0 and not self.tracker.started
        # near the coordinate limit a step could carry the contour past it: keep a way back
        undo = self.tracker.to_state() if np.abs(self.nodes).max() > LIMIT - NEAR_LIMIT else None
        try:
            result = self.tracker.step(frame)
        except ValueError as exc:
            raise BadImageError(str(exc)) from None
        if undo is not None and np.abs(result.nodes).max() > LIMIT:
            self.tracker = Tracker.from_state(undo)
            raise InvalidInputError(
                f"the tracked contour would lie beyond +-{LIMIT:g} px; the session is unchanged"
            )
        size = (int(frame.shape[1]), int(frame.shape[0]))
        reset = None
        if self.frame_size is not None and size != self.frame_size:
            (w0, h0), (w, h) = self.frame_size, size
            reset = (
                f"frame size changed from {w0}{TIMES}{h0} to {w}{TIMES}{h}: "
                "tracking restarted from the current contour"
            )
        elif restarted:
            reset = "the contour was moved by forces: tracking restarted from it on this frame"
        self.frame_size = size
        self.frame_index += 1
        self.nodes = result.nodes
        self.rest = result.nodes.copy()
        self.version += 1
        return {
            "frame_index": self.frame_index,
            "nodes": self.nodes.tolist(),
            "iterations": result.iterations,
            "converged": result.converged,
            "confidence": result.confidence,
            "status": result.status,
            "reset": reset,
            "version": self.version,
            "elapsed_ms": (time.perf_counter() - start) * 1e3,
        }

    def _track_objects(self, frame: NDArray[np.uint8]) -> dict[str, Any]:
        """One step of every object; the frame result with ``objects``."""
        if self.objects is None:
            raise InvalidInputError("this session tracks one contour")
        start = time.perf_counter()
        try:
            found = self.objects.step(frame)
        except ValueError as exc:
            raise BadImageError(str(exc)) from None
        self.frame_size = (int(frame.shape[1]), int(frame.shape[0]))
        self.frame_index += 1
        self.version += 1
        first = found[0] if found else None
        self.nodes = self.nodes if first is None else first_contour(first)
        self.rest = self.nodes.copy()
        order = ("lost", "uncertain", "tracking")
        return {
            "frame_index": self.frame_index,
            "nodes": self.nodes.tolist(),
            "iterations": 0,
            "converged": True,
            "confidence": min((o["confidence"] for o in found), default=0.0),
            "status": min((o["status"] for o in found), key=order.index, default="lost"),
            "reset": None,
            "version": self.version,
            "elapsed_ms": (time.perf_counter() - start) * 1e3,
            "objects": found,
        }

    def change_objects(self, change: Callable[[SessionObjects], Any]) -> Any:
        """Apply an add, correction or removal of objects; a new version.

        Raises InvalidInputError for a session of one contour.
        """
        if self.objects is None:
            raise InvalidInputError(
                "this session tracks one contour; create it with 'objects' to track several"
            )
        result = change(self.objects)
        self.version += 1
        return result

    def _snap(self, frame: NDArray[np.uint8]) -> None:
        """Replace the contour by the object inside the outline on this (first) frame.

        The frame is kept: the next one snaps it again with what moved
        (:meth:`_snap_again`).  Raises InvalidInputError (and changes nothing) when
        the outline lies outside the frame.
        """
        if self.tracker is None or self.snap_outline is None:
            return
        try:
            mask = snap(frame, self.snap_outline)
            # a contour the tracker refuses (a snap onto a one-pixel line encloses no area)
            # is refused here, before anything changed
            self.tracker.reset(mask_to_contour(mask, len(self.nodes)))
        except ValueError as exc:
            raise InvalidInputError(f"snap: {exc}") from None
        self.rest, self.nodes = self.tracker.nodes, self.tracker.nodes
        self.snap_frame = frame.copy()

    def _snap_again(self, frame: NDArray[np.uint8]) -> None:
        """Snap the outline on the first frame again, with what moved between it and this
        one (:func:`engine.tracking.snap.snap`'s ``next_frame``), and start the tracker
        there anew: from this frame on, the track is the one ``efdm track --init-box``
        gives.  A frame of another size has nothing to add.
        """
        first, outline = self.snap_frame, self.snap_outline
        self.snap_frame = self.snap_outline = None
        if self.tracker is None or first is None or outline is None:
            return
        if first.shape[:2] != frame.shape[:2]:
            return
        try:
            mask = snap(first, outline, next_frame=frame)
            self.tracker.reset(mask_to_contour(mask, len(self.tracker.nodes)))
        except ValueError:
            # the frame cannot be read with the first, or the mask gives no contour the
            # tracker takes (refused before it changed anything): the colour snap stands
            return
        self.tracker.step(first)

    def to_record(self, *, compact: bool = False) -> dict[str, Any]:
        """The whole session as JSON-able data (for a shared store).

        ``compact``: the tracker's compact, lossy state (tens of kB instead of
        hundreds, :meth:`engine.Tracker.to_state`) and a first frame kept for the
        second snap as JPEG; everything else stays exact.
        """
        return {
            "id": self.id,
            "owner": self.owner,
            "closed": self.closed,
            "stiffness": self.stiffness,
            "method": self.method,
            "tracking": self.tracking,
            "rest": self.rest.tolist(),
            "nodes": self.nodes.tolist(),
            "frame_index": self.frame_index,
            "version": self.version,
            "touched": self.touched,
            "frame_size": None if self.frame_size is None else list(self.frame_size),
            "ttl": self.ttl,
            "tracker": None if self.tracker is None else self.tracker.to_state(compact=compact),
            "snap": self.snap_outline,
            "snap_frame": None
            if self.snap_frame is None
            else pack_image(self.snap_frame, quality=KEPT_FRAME_QUALITY if compact else None),
            "objects": None if self.objects is None else self.objects.to_state(compact=compact),
        }

    @classmethod
    def from_record(cls, record: dict[str, Any]) -> Session:
        """Inverse of :meth:`to_record`; ValueError when the record is malformed."""
        try:
            state = record["tracker"]
            return cls(
                id=str(record["id"]),
                owner=None if record["owner"] is None else str(record["owner"]),
                closed=bool(record["closed"]),
                stiffness=float(record["stiffness"]),
                method=str(record["method"]),
                tracking=dict(record["tracking"]),
                rest=np.asarray(record["rest"], dtype=np.float64),
                nodes=np.asarray(record["nodes"], dtype=np.float64),
                frame_index=int(record["frame_index"]),
                version=int(record["version"]),
                touched=float(record["touched"]),
                tracker=None if state is None else Tracker.from_state(state),
                frame_size=_size(record.get("frame_size")),
                ttl=None if record.get("ttl") is None else float(record["ttl"]),
                snap_outline=None if record.get("snap") is None else list(record["snap"]),
                snap_frame=None
                if record.get("snap_frame") is None
                else unpack_image(str(record["snap_frame"]), colour=True),
                objects=None
                if record.get("objects") is None
                else SessionObjects.from_state(record["objects"]),
            )
        except (KeyError, TypeError, ValueError) as exc:
            raise ValueError(f"malformed session record: {exc}") from None

    def describe(self, ttl: float) -> dict[str, Any]:
        """The API's view of the session (``objects`` only for a session of several)."""
        view = {
            "id": self.id,
            "nodes": self.nodes.tolist(),
            "closed": self.closed,
            "stiffness": self.stiffness,
            "method": self.method,
            "tracking": self.tracking,
            "frame_index": self.frame_index,
            "version": self.version,
            "expires_at": expiry(self.touched, self.lifetime(ttl)),
        }
        if self.objects is not None:
            view["objects"] = self.objects.describe()
        return view
