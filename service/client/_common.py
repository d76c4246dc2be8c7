"""What the sync and async clients share: result types, errors, encoding, parsing.

Nothing here does I/O; the clients send what these helpers build and parse
what the service answers.  Coordinates are ``[x, y]`` pixels.
"""

from __future__ import annotations

import json
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from datetime import datetime
from typing import Any, Literal, TypeAlias
from urllib.parse import quote

import cv2
import numpy as np
import websockets.exceptions
from numpy.typing import ArrayLike, NDArray

from service.image_types import sniff

Method: TypeAlias = Literal["exact", "efdm", "efdmt", "dmma", "dmmat"]
Frame: TypeAlias = bytes | bytearray | memoryview | NDArray[Any]
"""An encoded image (JPEG, PNG or WebP bytes), or a BGR / grey uint8 array.

Arrays are typed loosely, as OpenCV returns them; their dtype is checked
when they are encoded.
"""
Encoder: TypeAlias = Callable[[NDArray[np.uint8]], bytes]
"""Turns a BGR / grey uint8 array into an encoded image the service decodes."""
CircleSpec: TypeAlias = tuple[ArrayLike, float] | tuple[ArrayLike, float, int]
"""``(center [x, y], radius, count)``; ``count`` defaults to 64 on the server."""

USER_AGENT = "efdm-tracker-client/0.1"
MAX_MESSAGE = 64 * 1024 * 1024  # largest WebSocket message accepted from the server
WS_CLOSE_CODES = {401: "unauthorized", 404: "not_found", 413: "too_large", 429: "too_many"}
WS_OTHER_CLOSES = {
    1001: (503, "unavailable"),  # going away: server shutting down
    1009: (413, "too_large"),
    1011: (500, "internal"),
    1012: (503, "unavailable"),  # service restart
    1013: (503, "unavailable"),  # try again later
}


class ApiError(Exception):
    """An error answered by the service (or a WebSocket closed with an error code).

    Parameters
    ----------
    status : int
        HTTP status: 404 unknown session, 401 missing or wrong API key, 412
        stale ``if_match``, 422 invalid request, 429 too many sessions ...
    code : str
        The service's machine-readable code, e.g. ``"not_found"``.
    message : str
        Human-readable explanation.
    details : sequence of mapping, optional
        Per-field problems of a 422, as the service lists them.
    retry_after : float, optional
        Seconds to wait before retrying, when the service said so.
    """

    def __init__(
        self,
        status: int,
        code: str,
        message: str,
        *,
        details: Sequence[Mapping[str, Any]] = (),
        retry_after: float | None = None,
    ) -> None:
        super().__init__(f"{status} {code}: {message}")
        self.status = status
        self.code = code
        self.message = message
        self.details = tuple(details)
        self.retry_after = retry_after


@dataclass(frozen=True, eq=False)
class Session:
    """A tracking session as the service describes it.

    Arrays are read-only; ``eq=False``: sessions compare by identity.

    Attributes
    ----------
    id : str
        Session id, for the other calls.
    nodes : ndarray of float64, shape (N, 2)
        Current contour, ``[x, y]`` pixels.
    closed : bool
        Closed ring (trackable) or open chain.
    stiffness : float
        Spring stiffness a = k/m of the deformable model.
    method : str
        Solver of the model (``"exact"``, ``"efdm"`` ...).
    tracking : mapping
        Tracker options the session was created with.
    frame_index : int
        Index of the last tracked frame, -1 before any.
    version : int
        Incremented by every change; pass it as ``if_match``.
    expires_at : datetime
        When the idle session expires (UTC, timezone-aware).
    """

    id: str
    nodes: NDArray[np.float64]
    closed: bool
    stiffness: float
    method: str
    tracking: Mapping[str, Any]
    frame_index: int
    version: int
    expires_at: datetime


@dataclass(frozen=True, eq=False)
class FrameResult:
    """The contour tracked into one frame.

    Attributes
    ----------
    frame_index : int
        Index of this frame in the session (0, 1, ...).
    nodes : ndarray of float64, shape (N, 2)
        Tracked contour, ``[x, y]`` pixels (read-only).
    iterations : int
        Tracker iterations spent.
    converged : bool
        Whether the tracker converged.
    confidence : float
        In [0, 1]: the predicted overlap (IoU) of the contour with the object.
    status : str
        ``"tracking"``, ``"uncertain"`` or ``"lost"``.
    version : int
        Session version after this frame.
    elapsed_ms : float
        Server-side tracking time.
    dropped : int
        Frames the stream skipped since the previous result (realtime
        streaming only; always 0 over REST and with ``max_in_flight=1``).
    reset : str or None
        Why this frame restarted tracking (the frame size changed), or None.
    objects : tuple of dict
        A session of several objects: each one's ``{"id", "nodes"`` (or
        ``"contours"``, a list of them, for an object in pieces; read-only
        arrays)``, "confidence", "status", "behind"}`` (``"behind"``: the ids of the
        objects in front of it where they overlap); empty otherwise.
    """

    frame_index: int
    nodes: NDArray[np.float64]
    iterations: int
    converged: bool
    confidence: float
    version: int
    elapsed_ms: float
    dropped: int = 0
    status: str = "tracking"
    reset: str | None = None
    objects: tuple[dict[str, Any], ...] = ()


@dataclass(frozen=True, eq=False)
class ForcesResult:
    """Equilibrium of the rest shape under one force per node.

    Attributes
    ----------
    nodes : ndarray of float64, shape (N, 2)
        Deformed contour = rest + displacements (read-only).
    displacements : ndarray of float64, shape (N, 2)
        Displacement of every node (read-only).
    version : int
        Session version after the change.
    """

    nodes: NDArray[np.float64]
    displacements: NDArray[np.float64]
    version: int


@dataclass(frozen=True)
class ImageEncoder:
    """The default frame encoder: ``cv2.imencode`` of a BGR or grey uint8 array.

    Parameters
    ----------
    format : {"jpeg", "png", "webp"}
        Image format; PNG is lossless (and larger, slower to send).
    quality : int
        JPEG / WebP quality, 1 to 100 (ignored for PNG).
    """

    format: Literal["jpeg", "png", "webp"] = "jpeg"
    quality: int = 90

    def __post_init__(self) -> None:
        if self.format not in ("jpeg", "png", "webp"):
            raise ValueError(f"format must be 'jpeg', 'png' or 'webp'; got {self.format!r}")
        if not 1 <= self.quality <= 100:
            raise ValueError(f"quality must be in 1..100; got {self.quality}")

    def __call__(self, image: NDArray[np.uint8]) -> bytes:
        """Encode ``image``: uint8, shape (H, W), (H, W, 1) or BGR (H, W, 3)."""
        image = np.asarray(image)
        if image.dtype != np.uint8:
            raise TypeError(f"frames must be uint8 arrays; got {image.dtype}")
        if not (image.ndim == 2 or (image.ndim == 3 and image.shape[2] in (1, 3))):
            raise ValueError(f"frames must be (H, W) grey or (H, W, 3) BGR; got {image.shape}")
        if self.format == "jpeg":
            ext, params = ".jpg", [cv2.IMWRITE_JPEG_QUALITY, self.quality]
        elif self.format == "webp":
            ext, params = ".webp", [cv2.IMWRITE_WEBP_QUALITY, self.quality]
        else:
            ext, params = ".png", [cv2.IMWRITE_PNG_COMPRESSION, 1]
        ok, data = cv2.imencode(ext, np.ascontiguousarray(image), params)
        if not ok:
            raise ValueError(f"OpenCV could not encode the frame as {self.format}")
        return bytes(data.tobytes())


def session_id(session: str | Session) -> str:
    """The id of a session given as a :class:`Session` or an id."""
    sid = session.id if isinstance(session, Session) else session
    if not isinstance(sid, str) or not sid:
        raise ValueError(f"need a session or a non-empty session id; got {session!r}")
    return sid


def session_path(session: str | Session, suffix: str = "") -> str:
    """``/v1/sessions/{id}{suffix}``, the id percent-encoded."""
    return f"/v1/sessions/{quote(session_id(session), safe='')}{suffix}"


STREAM_MODES = ("latest", "every")


def stream_url(base_url: str, session: str | Session, mode: str = "latest") -> str:
    """The WebSocket URL of a session's stream, from the HTTP base URL.

    Raises
    ------
    ValueError
        ``mode`` is not ``"latest"`` or ``"every"``.
    """
    if mode not in STREAM_MODES:
        raise ValueError(f"mode must be one of {', '.join(STREAM_MODES)}; got {mode!r}")
    base = base_url.rstrip("/")
    if base.startswith(("http://", "https://")):
        base = "ws" + base.removeprefix("http")
    query = "" if mode == "latest" else f"?mode={mode}"
    return base + session_path(session, "/stream") + query


def headers(api_key: str | None) -> dict[str, str]:
    """Headers sent with every request (and the WebSocket handshake)."""
    out = {"User-Agent": USER_AGENT}
    if api_key:
        out["Authorization"] = f"Bearer {api_key}"
    return out


def if_match_header(if_match: int | str | None) -> dict[str, str]:
    """``If-Match`` for a session version (int, or an ETag string as given)."""
    if if_match is None:
        return {}
    return {"If-Match": f'"{if_match}"' if isinstance(if_match, int) else if_match}


def points(value: ArrayLike, name: str) -> NDArray[np.float64]:
    """``value`` as a finite (N, 2) float64 array; ValueError otherwise."""
    arr = np.array(value, dtype=np.float64)
    if arr.ndim != 2 or arr.shape[1] != 2:
        raise ValueError(f"{name} must have shape (N, 2), [[x, y], ...]; got {arr.shape}")
    if not np.isfinite(arr).all():
        raise ValueError(f"{name} must be finite")
    return arr


def session_body(
    nodes: ArrayLike | None,
    circle: CircleSpec | None,
    closed: bool,
    stiffness: float | None,
    method: Method | None,
    tracking: Mapping[str, Any] | None,
    *,
    box: ArrayLike | None = None,
    snap: bool | None = None,
    objects: Sequence[Mapping[str, Any]] | None = None,
) -> dict[str, Any]:
    """The JSON body of ``POST /v1/sessions`` (server defaults where None)."""
    if sum(v is not None for v in (nodes, circle, box, objects)) != 1:
        raise ValueError("give exactly one of nodes, circle, box or objects")
    body: dict[str, Any] = {"closed": closed}
    if objects is not None:
        body["objects"] = [dict(o) for o in objects]
    if snap is not None:
        body["snap"] = bool(snap)
    if box is not None:
        corners = np.asarray(box, dtype=np.float64)
        if corners.shape != (4,) or not np.isfinite(corners).all():
            raise ValueError("box must be four finite numbers [x0, y0, x1, y1]")
        body["box"] = corners.tolist()
    elif nodes is not None:
        body["nodes"] = points(nodes, "nodes").tolist()
    elif circle is not None:
        center = np.asarray(circle[0], dtype=np.float64).reshape(2).tolist()
        body["circle"] = {"center": center, "radius": float(circle[1])}
        if len(circle) == 3:
            body["circle"]["count"] = int(circle[2])
    if stiffness is not None:
        body["stiffness"] = float(stiffness)
    if method is not None:
        body["method"] = method
    if tracking is not None:
        body["tracking"] = dict(tracking)
    return body


def forces_body(forces: ArrayLike) -> dict[str, Any]:
    """The JSON body of ``POST /v1/sessions/{id}/forces``."""
    return {"forces": points(forces, "forces").tolist()}


def media_type(data: bytes) -> str:
    """The image type from its magic bytes (the server checks them again)."""
    return sniff(data) or "application/octet-stream"


def frame_bytes(frame: Frame, encoder: Encoder) -> bytes:
    """An encoded image: bytes as given, arrays through ``encoder``."""
    if isinstance(frame, np.ndarray):
        if frame.dtype != np.uint8:
            raise TypeError(f"frames must be uint8 arrays; got {frame.dtype}")
        return encoder(frame)
    if isinstance(frame, bytes | bytearray | memoryview):
        return bytes(frame)
    raise TypeError(f"a frame is encoded image bytes or a uint8 array; got {type(frame)}")


def _readonly(value: Any) -> NDArray[np.float64]:
    arr = np.array(value, dtype=np.float64).reshape(-1, 2)
    arr.flags.writeable = False
    return arr


def parse_session(data: Mapping[str, Any]) -> Session:
    """A :class:`Session` from the service's JSON."""
    return Session(
        id=str(data["id"]),
        nodes=_readonly(data["nodes"]),
        closed=bool(data["closed"]),
        stiffness=float(data["stiffness"]),
        method=str(data["method"]),
        tracking=dict(data["tracking"]),
        frame_index=int(data["frame_index"]),
        version=int(data["version"]),
        expires_at=datetime.fromisoformat(str(data["expires_at"])),
    )


def parse_frame(data: Mapping[str, Any]) -> FrameResult:
    """A :class:`FrameResult` from the service's JSON (REST or stream)."""
    return FrameResult(
        frame_index=int(data["frame_index"]),
        nodes=_readonly(data["nodes"]),
        iterations=int(data["iterations"]),
        converged=bool(data["converged"]),
        confidence=float(data["confidence"]),
        version=int(data["version"]),
        elapsed_ms=float(data["elapsed_ms"]),
        dropped=int(data.get("dropped", 0)),
        status=str(data.get("status", "tracking")),
        reset=None if data.get("reset") is None else str(data["reset"]),
        objects=tuple(_object(o) for o in data.get("objects") or ()),
    )


def _object(data: Mapping[str, Any]) -> dict[str, Any]:
    """One object of a frame result, its contours as read-only arrays."""
    found = dict(data)
    if found.get("nodes") is not None:
        found["nodes"] = _readonly(found["nodes"])
    if found.get("contours") is not None:
        found["contours"] = [_readonly(c) for c in found["contours"]]
    return found


def parse_forces(data: Mapping[str, Any]) -> ForcesResult:
    """A :class:`ForcesResult` from the service's JSON."""
    return ForcesResult(
        nodes=_readonly(data["nodes"]),
        displacements=_readonly(data["displacements"]),
        version=int(data["version"]),
    )


def error_from_body(
    status: int, body: bytes | bytearray, reason: str = "", retry_after: str | None = None
) -> ApiError:
    """An :class:`ApiError` from an error response's status and body.

    The body is the service's ``{"error": {"status", "code", "message"}}``;
    anything else (say, a proxy's HTML page) keeps the status, code
    ``"http_error"`` and the start of the text as the message.
    """
    try:
        payload = json.loads(body)
    except ValueError:
        payload = None
    error = payload.get("error") if isinstance(payload, dict) else None
    try:
        delay = float(retry_after) if retry_after is not None else None
    except ValueError:
        delay = None
    if isinstance(error, dict):
        details = error.get("details")
        if not isinstance(details, list):
            details = []
        return ApiError(
            status,
            str(error.get("code", "http_error")),
            str(error.get("message", reason)),
            details=[d for d in details if isinstance(d, dict)],
            retry_after=delay,
        )
    text = body[:200].decode("utf-8", "replace").strip()
    return ApiError(status, "http_error", text or reason or f"HTTP {status}", retry_after=delay)


def closed_error(exc: websockets.exceptions.ConnectionClosed) -> ApiError | None:
    """The error a WebSocket close frame reports; None when none was received.

    4xxx codes carry an HTTP status (4404 → 404, 4401 → 401); 1009 (message
    too large) maps to 413, 1011 to 500, going-away / restart codes to 503 and
    any other close before the expected result to 502 ``"closed"``.
    """
    close = exc.rcvd
    if close is None:
        return None
    reason = close.reason or f"WebSocket closed with code {close.code}"
    if 4000 <= close.code <= 4999:
        status = close.code - 4000
        return ApiError(status, WS_CLOSE_CODES.get(status, "closed"), reason)
    status, code = WS_OTHER_CLOSES.get(close.code, (502, "closed"))
    return ApiError(status, code, reason)


def parse_message(data: str | bytes) -> FrameResult | None:
    """A stream message: a frame result, None for other types; raises on errors.

    Raises
    ------
    ApiError
        For ``{"type": "error", "error": {...}}`` (say a frame that does not
        decode, 400 ``bad_image``).
    """
    message = json.loads(data)
    if not isinstance(message, dict):
        return None
    kind = message.get("type")
    if kind == "frame":
        return parse_frame(message)
    if kind == "error":
        error = message.get("error")
        status = error.get("status", 500) if isinstance(error, dict) else 500
        raise error_from_body(int(status), json.dumps(message).encode())
    return None  # "pong", "forces", or a type this client does not know


class InFlight:
    """Frames sent over a stream and not yet answered (nor reported dropped).

    Every frame the server receives is either answered or counted in the
    ``dropped`` of the next answer, so ``count`` returns to 0 once all the
    answers are in.
    """

    def __init__(self, limit: int) -> None:
        if limit < 1:
            raise ValueError(f"max_in_flight must be >= 1; got {limit}")
        self.limit = limit
        self.count = 0

    @property
    def room(self) -> bool:
        """Whether another frame may be sent before reading an answer."""
        return self.count < self.limit

    def sent(self) -> None:
        """Account for a frame sent."""
        self.count += 1

    def answered(self, result: FrameResult) -> None:
        """Account for a result: its frame and the frames dropped before it."""
        self.count = max(0, self.count - 1 - result.dropped)
