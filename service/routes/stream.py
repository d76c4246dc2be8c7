"""``WS /v1/sessions/{id}/stream``: frames in, contours out, latest frame wins.

Protocol (JSON text messages from the server carry a ``type``):

- client binary message: one encoded frame (JPEG, PNG or WebP); answered by
  ``{"type": "frame", ...REST frame result..., "dropped": n}``;
- client text ``{"forces": [[fx, fy], ...]}``: answered by
  ``{"type": "forces", "nodes", "displacements", "version"}``;
- client text ``{"ping": x}``: answered by ``{"type": "pong", "pong": x}``;
- in a session of several objects, client text ``{"add_object": {...}}``
  (an object as ``POST …/objects`` takes it), ``{"replace_object": {"id":
  ..., ...}}`` (a correction, as ``PUT``) or ``{"remove_object": id}``:
  answered by ``{"type": "object", "id", "nodes" or "contours", "version"}``
  (``"removed": true`` and no contour for a removal); they take effect on
  the next frame;
- a message the server cannot use: ``{"type": "error", "error": {...}}``, and
  the stream goes on.

Two modes, chosen by the query parameter ``mode``:

- ``latest`` (the default, for a live camera): when frames arrive faster than
  they are tracked, only the newest waiting frame is kept; the others are
  counted in the next result's ``dropped``.  Memory per stream is bounded:
  one waiting frame and a few control messages.
- ``every`` (for a file, annotation): every frame is tracked, in order, none
  dropped; messages wait in a queue of :data:`EVERY_QUEUE`, and while it is
  full the server stops reading the socket (back-pressure: the client's sends
  block).  A ping is answered after the frames sent before it.

An unknown mode closes the stream with 4422.
Fatal problems close the socket with a code and a reason: 4000 + the
status a REST call would get (the mapping of :mod:`service.errors`), such
as 4401 missing or wrong API key, 4404 unknown or expired session, 4503
session store unreachable; 1009 message too large, 1011 unexpected server
error.  Error messages carry that status and code too.

One stream per session: a new stream on a session takes it over, on any
replica, and the older stream is closed with 4409 at its next frame or
forces message, having changed nothing (so a client whose replica died can
reconnect at once, and two tabs never interleave their frames).  Coordinates are
``[x, y]`` pixels.
"""

from __future__ import annotations

import asyncio
import contextlib
import json
import time
from collections import deque
from typing import Any

import anyio
from anyio import CapacityLimiter
from fastapi import APIRouter, WebSocket, WebSocketDisconnect
from pydantic import ValidationError

from service import metrics
from service.auth import check_key
from service.connections import ABORT
from service.deps import ApiKeyDep, CpuDep, SettingsDep, StoreDep, StreamsDep
from service.domain_errors import (
    InvalidInputError,
    ServiceError,
    SessionNotFoundError,
    StreamReplacedError,
)
from service.errors import ApiError, as_api_error, first_invalid, log
from service.schemas import ForcesIn, ObjectSpec
from service.settings import Settings
from service.shutdown import Stream
from service.store import StreamLease
from service.units import too_many_bytes
from service.work import compute, track_encoded

router = APIRouter(tags=["stream"])

MAX_PENDING_CONTROL = 16
EVERY_QUEUE = 4
"""Messages waiting in ``mode=every`` before the server stops reading: enough to keep
the tracker busy while the next frame arrives, few enough to bound memory (a few frames)."""
MODES = ("latest", "every")
UNEXPECTED = 1011
"""Close code of an unexpected server error (RFC 6455: the server met a condition that
kept it from fulfilling the request); clients read it as a 500."""
OBJECT_CONTROLS = frozenset({"add_object", "replace_object", "remove_object"})
CONTROLS = frozenset({"forces", "ping"}) | OBJECT_CONTROLS
"""The keys a control message may carry (one of them)."""


class Inbox:
    """``mode=latest``: the newest frame and a short control queue."""

    def __init__(self) -> None:
        self.frame: bytes | None = None
        self.dropped = 0
        self.control: deque[dict[str, Any]] = deque()
        self.ready = asyncio.Event()

    async def put_frame(self, data: bytes) -> None:
        if self.frame is not None:
            self.dropped += 1
            metrics.DROPPED.inc()
        self.frame = data
        self.ready.set()

    async def put_control(self, message: dict[str, Any]) -> bool:
        if len(self.control) >= MAX_PENDING_CONTROL:
            return False
        self.control.append(message)
        self.ready.set()
        return True


class Queue:
    """``mode=every``: frames and control messages in arrival order, a bounded queue."""

    def __init__(self) -> None:
        self.items: asyncio.Queue[tuple[str, Any]] = asyncio.Queue(EVERY_QUEUE)

    async def put_frame(self, data: bytes) -> None:
        await self.items.put(("frame", data))  # waits while full: the socket is not read

    async def put_control(self, message: dict[str, Any]) -> bool:
        await self.items.put(("control", message))
        return True


def error_message(exc: ApiError | ServiceError) -> dict[str, Any]:
    """An error as a stream message (status and code as a REST answer has them)."""
    error = as_api_error(exc)
    metrics.ERRORS.labels(kind=error.code).inc()
    return {
        "type": "error",
        "error": {"status": error.status, "code": error.code, "message": error.message},
    }


@router.websocket("/v1/sessions/{session_id}/stream")
async def stream(
    websocket: WebSocket,
    session_id: str,
    settings: SettingsDep,
    store: StoreDep,
    cpu: CpuDep,
    streams: StreamsDep,
    key: ApiKeyDep,
) -> None:
    """Track a stream of frames (see the module docstring for the protocol)."""
    await websocket.accept()
    mode = websocket.query_params.get("mode", "latest")
    try:
        if mode not in MODES:
            raise InvalidInputError(f"mode must be one of {', '.join(MODES)}; got {mode!r}")
        owner = check_key(settings, key)
        held = store.stream(session_id, owner, settings.stream_commit_every)
        lease = await held.__aenter__()
    except (ApiError, ServiceError) as exc:
        error = as_api_error(exc)
        metrics.ERRORS.labels(kind=error.code).inc()
        refused = _FatalError.of(error)
        await websocket.close(code=refused.code, reason=refused.reason[:120])
        return
    metrics.WEBSOCKETS.inc()
    registered = streams.register(websocket)
    inbox = Inbox() if mode == "latest" else Queue()
    try:
        async with anyio.create_task_group() as tasks:
            if isinstance(inbox, Inbox):
                tasks.start_soon(_work, websocket, lease, inbox, registered, cpu, settings)
            else:
                tasks.start_soon(_work_every, websocket, lease, inbox, registered, cpu, settings)
            await _receive(websocket, inbox, settings)
            tasks.cancel_scope.cancel()
    except* _FatalError as group:  # task groups raise exception groups
        fatal = group.exceptions[0]
        assert isinstance(fatal, _FatalError)
        await _close(websocket, fatal.code, fatal.reason)
    except* (WebSocketDisconnect, ClientGoneError):
        pass  # the client left while a result was on its way
    except* Exception as group:  # a defect of ours: said with 1011, not a dropped socket
        metrics.ERRORS.labels(kind="internal").inc()
        log.error("unexpected error in a stream", exc_info=group.exceptions[0])
        await _close(websocket, UNEXPECTED, "internal error")
    finally:
        metrics.WEBSOCKETS.dec()
        try:
            await held.__aexit__(None, None, None)  # writes through what is pending
        finally:
            streams.unregister(registered)  # after the write-through


class _FatalError(Exception):
    def __init__(self, code: int, reason: str) -> None:
        super().__init__(reason)
        self.code = code
        self.reason = reason

    @classmethod
    def of(cls, exc: ApiError | ServiceError) -> _FatalError:
        """Close code 4000 + the HTTP status a REST answer would have (4404, 4401 ...)."""
        error = as_api_error(exc)
        return cls(4000 + error.status, error.message)


class ClientGoneError(Exception):
    """The client disconnected while the server was sending."""


async def _send(websocket: WebSocket, message: dict[str, Any]) -> None:
    """Send, or give the client up if it has read nothing for the send timeout."""
    settings: Settings = websocket.app.state.settings
    try:
        await asyncio.wait_for(websocket.send_json(message), settings.ws_send_timeout_seconds)
    except TimeoutError as exc:  # not reading: the stream ends and its socket is reset
        metrics.ERRORS.labels(kind="stuck_client").inc()
        abort = websocket.scope.get(ABORT)
        if callable(abort):  # a graceful close would wait for the unread results forever
            abort()
        raise ClientGoneError from exc
    except (WebSocketDisconnect, RuntimeError, OSError) as exc:
        raise ClientGoneError from exc


async def _close(websocket: WebSocket, code: int, reason: str) -> None:
    with contextlib.suppress(RuntimeError, WebSocketDisconnect):
        await websocket.close(code=code, reason=reason[:120])


async def _receive(websocket: WebSocket, inbox: Inbox | Queue, settings: Settings) -> None:
    """Read messages until the client goes away, into the mode's inbox."""
    while True:
        message = await websocket.receive()
        if message["type"] == "websocket.disconnect":
            return
        data, text = message.get("bytes"), message.get("text")
        if data is not None:
            if len(data) > settings.max_frame_bytes:
                raise _FatalError(
                    1009, too_many_bytes("frame", len(data), settings.max_frame_bytes)
                )
            await inbox.put_frame(data)
        elif text is not None:
            if len(text.encode()) > settings.max_json_bytes:
                size = len(text.encode())
                raise _FatalError(1009, too_many_bytes("message", size, settings.max_json_bytes))
            try:
                parsed = json.loads(text)
            except (ValueError, RecursionError):  # not JSON, or nested beyond reason
                await _send(
                    websocket,
                    error_message(ApiError(400, "bad_request", "text messages must be JSON")),
                )
                continue
            if not isinstance(parsed, dict) or not (CONTROLS & parsed.keys()):
                await _send(
                    websocket,
                    error_message(
                        InvalidInputError(
                            'expected {"forces": [...]}, {"ping": ...}, {"add_object": {...}}, '
                            '{"replace_object": {...}} or {"remove_object": id}'
                        )
                    ),
                )
                continue
            if not await inbox.put_control(parsed):
                await _send(
                    websocket,
                    error_message(ApiError(429, "too_many_messages", "too many pending messages")),
                )


async def _work(
    websocket: WebSocket,
    lease: StreamLease,
    inbox: Inbox,
    registered: Stream,
    cpu: CapacityLimiter,
    settings: Settings,
) -> None:
    """Process waiting control messages in order, then the newest frame."""
    while True:
        await inbox.ready.wait()
        inbox.ready.clear()
        async with registered.in_flight():  # shutdown waits for this, then closes with 1001
            while inbox.control:
                control = inbox.control.popleft()
                await _send(websocket, await _control(lease, control, cpu, settings.max_nodes))
            if inbox.frame is not None:
                data, dropped = inbox.frame, inbox.dropped
                inbox.frame, inbox.dropped = None, 0
                await _send(websocket, await _frame(lease, data, dropped, cpu, settings))


async def _work_every(
    websocket: WebSocket,
    lease: StreamLease,
    inbox: Queue,
    registered: Stream,
    cpu: CapacityLimiter,
    settings: Settings,
) -> None:
    """Process every message in arrival order, frames included."""
    while True:
        kind, item = await inbox.items.get()
        async with registered.in_flight():
            if kind == "frame":
                await _send(websocket, await _frame(lease, item, 0, cpu, settings))
            else:
                await _send(websocket, await _control(lease, item, cpu, settings.max_nodes))


async def _object_control(
    lease: StreamLease, message: dict[str, Any], max_nodes: int
) -> dict[str, Any]:
    """Add, correct or remove one object of a session of several (mid-stream)."""
    try:
        if "remove_object" in message:
            key = message["remove_object"]
            if not isinstance(key, str):
                raise InvalidInputError("remove_object: give the object's id (text)")
            spec = None
        else:
            raw = message.get("add_object", message.get("replace_object"))
            spec = ObjectSpec.model_validate(raw)
            key = spec.id or ""
            if "replace_object" in message and not key:
                raise InvalidInputError("replace_object: give the object's 'id'")
    except ValidationError as exc:
        control = "add_object" if "add_object" in message else "replace_object"
        return error_message(InvalidInputError(first_invalid(exc.errors(), control)))
    except ServiceError as exc:
        return error_message(exc)
    try:
        async with lease.turn() as session:
            if spec is None:
                session.change_objects(lambda objects: objects.remove(key))
                return {"type": "object", "id": key, "removed": True, "version": session.version}
            if "add_object" in message:
                key = session.change_objects(lambda objects: objects.add(spec, max_nodes))
            else:
                session.change_objects(lambda objects: objects.replace(key, spec, max_nodes))
            described = [] if session.objects is None else session.objects.describe()
            shape = next(o for o in described if o["id"] == key)
            return {"type": "object", **shape, "version": session.version}
    except (SessionNotFoundError, StreamReplacedError) as exc:  # gone, or taken over: the end
        raise _FatalError.of(exc) from None
    except ServiceError as exc:
        return error_message(exc)


async def _control(
    lease: StreamLease, message: dict[str, Any], cpu: CapacityLimiter, max_nodes: int
) -> dict[str, Any]:
    if OBJECT_CONTROLS & message.keys():
        return await _object_control(lease, message, max_nodes)
    if "ping" in message:
        try:
            json.dumps(message["ping"], allow_nan=False)  # echo only what JSON can carry
        except ValueError:
            return error_message(InvalidInputError("ping: NaN and Infinity are not JSON"))
        return {"type": "pong", "pong": message["ping"]}
    try:
        payload = ForcesIn.model_validate({"forces": message.get("forces")})
    except ValidationError as exc:
        return error_message(InvalidInputError(first_invalid(exc.errors())))
    try:
        async with lease.turn() as session:
            U = await compute(cpu, lambda: session.apply_forces(payload.forces))
            metrics.FORCES.inc()
            return {
                "type": "forces",
                "nodes": session.nodes.tolist(),
                "displacements": U.tolist(),
                "version": session.version,
            }
    except (SessionNotFoundError, StreamReplacedError) as exc:  # gone, or taken over: the end
        raise _FatalError.of(exc) from None
    except ServiceError as exc:
        return error_message(exc)


async def _frame(
    lease: StreamLease, data: bytes, dropped: int, cpu: CapacityLimiter, settings: Settings
) -> dict[str, Any]:
    start = time.perf_counter()
    try:
        async with lease.turn() as session:
            result = await track_encoded(cpu, settings, session, data, None)
    except (SessionNotFoundError, StreamReplacedError) as exc:  # gone, or taken over: the end
        raise _FatalError.of(exc) from None
    except ServiceError as exc:
        return {**error_message(exc), "dropped": dropped}
    metrics.FRAMES.labels(transport="websocket").inc()
    metrics.FRAME_SECONDS.labels(transport="websocket").observe(time.perf_counter() - start)
    return {"type": "frame", **result, "dropped": dropped}
