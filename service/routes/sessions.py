"""``/v1/sessions``: create, read, delete; forces and frames; a session's objects."""

from __future__ import annotations

import time
from typing import Annotated, Any

import orjson
from fastapi import APIRouter, Header, Query, Request, Response, status
from starlette.exceptions import HTTPException as StarletteHTTPException

from service import metrics
from service.deps import CpuDep, OwnerDep, SettingsDep, StoreDep
from service.errors import ApiError
from service.schemas import (
    ErrorOut,
    ForcesIn,
    ForcesOut,
    FrameOut,
    ObjectId,
    ObjectOut,
    ObjectSpec,
    SessionCreate,
    SessionList,
    SessionOut,
)
from service.sessions import Session, expiry
from service.settings import Settings
from service.work import compute, track_encoded

router = APIRouter(prefix="/v1/sessions", tags=["sessions"])

CHEAP_METHODS = frozenset({"exact", "efdmt"})
"""Solvers fast enough to run on the event loop (O(N), at most 4096 nodes)."""

IfMatch = Annotated[
    str | None,
    Header(description="the session version this change expects; 412 when stale"),
]
ERRORS: dict[int | str, dict[str, Any]] = {
    code: {"model": ErrorOut} for code in (400, 401, 404, 412, 413, 415, 422, 429)
}


def check_version(session: Session, if_match: str | None) -> None:
    """412 when ``If-Match`` names another version than the session's (``*``: any)."""
    if if_match is None:
        return
    wanted = if_match.strip().strip('"').removeprefix("W/").strip('"')
    if wanted != "*":
        session.expect_version(wanted)


@router.post(
    "",
    status_code=status.HTTP_201_CREATED,
    response_model=SessionOut,
    response_model_exclude_unset=True,  # "objects" only for a session of several
    responses=ERRORS,
)
async def create_session(
    spec: SessionCreate,
    response: Response,
    owner: OwnerDep,
    settings: SettingsDep,
    store: StoreDep,
    cpu: CpuDep,
) -> dict[str, Any]:
    """Create a session from an initial contour (``nodes`` or ``circle``)."""
    session = await compute(cpu, lambda: Session.create(spec, owner, settings.max_nodes))
    await store.add(session)
    response.headers["Location"] = f"/v1/sessions/{session.id}"
    response.headers["ETag"] = f'"{session.version}"'
    return session.describe(settings.session_ttl_seconds)


PAGE_SIZE = 50
"""Sessions per page unless the caller asks for fewer or more (at most :data:`MAX_PAGE`)."""
MAX_PAGE = 500
"""Largest page: one listing's reply stays small and quick, even from a shared store."""


@router.get("", response_model=SessionList, responses=ERRORS)
async def list_sessions(
    request: Request,
    response: Response,
    owner: OwnerDep,
    settings: SettingsDep,
    store: StoreDep,
    limit: Annotated[int, Query(ge=1, le=MAX_PAGE, description="sessions per page")] = PAGE_SIZE,
    after: Annotated[
        str, Query(max_length=64, description="list the ids after this one (the previous 'next')")
    ] = "",
) -> dict[str, Any]:
    """The caller's sessions (those of its API key), in id order, a page at a time."""
    found = await store.owned(owner, after, limit + 1)
    page, more = found[:limit], len(found) > limit
    ttl = settings.session_ttl_seconds
    sessions = [
        {
            "id": s.id,
            "frame_index": s.frame_index,
            "version": s.version,
            "expires_at": expiry(s.touched, ttl if s.ttl is None else min(s.ttl, ttl)),
        }
        for s in page
    ]
    following = page[-1].id if more else None
    if following is not None:
        url = request.url.include_query_params(after=following, limit=limit)
        response.headers["Link"] = f'<{url.path}?{url.query}>; rel="next"'
    return {"sessions": sessions, "next": following}


@router.get(
    "/{session_id}", response_model=SessionOut, response_model_exclude_unset=True, responses=ERRORS
)
async def get_session(
    session_id: str, response: Response, owner: OwnerDep, settings: SettingsDep, store: StoreDep
) -> dict[str, Any]:
    """The session's contour and state."""
    async with store.lease(session_id, owner) as session:
        response.headers["ETag"] = f'"{session.version}"'
        return session.describe(settings.session_ttl_seconds)


@router.delete("/{session_id}", status_code=status.HTTP_204_NO_CONTENT, responses=ERRORS)
async def delete_session(
    session_id: str, owner: OwnerDep, store: StoreDep, request: Request
) -> Response:
    """Delete the session."""
    await store.delete(session_id, owner)
    request.app.state.memory.freed()  # its arrays go back to the system soon (service.memory)
    return Response(status_code=status.HTTP_204_NO_CONTENT)


@router.post("/{session_id}/forces", response_model=ForcesOut, responses=ERRORS)
async def apply_forces(
    session_id: str,
    payload: ForcesIn,
    owner: OwnerDep,
    store: StoreDep,
    cpu: CpuDep,
    if_match: IfMatch = None,
) -> Response:
    """Equilibrium of the rest shape under one force per node (paper eq. 15-16)."""
    async with store.lease(session_id, owner) as session:
        check_version(session, if_match)
        if session.method in CHEAP_METHODS:  # O(N): microseconds, no thread hop needed
            U = session.apply_forces(payload.forces)
        else:
            U = await compute(cpu, lambda: session.apply_forces(payload.forces))
        metrics.FORCES.inc()
        # arrays straight to JSON (orjson), without re-validating the response model
        content = orjson.dumps(
            {"nodes": session.nodes, "displacements": U, "version": session.version},
            option=orjson.OPT_SERIALIZE_NUMPY,
        )
        return Response(
            content, media_type="application/json", headers={"ETag": f'"{session.version}"'}
        )


FRAME_BODY = {
    "requestBody": {
        "required": True,
        "description": "one encoded image: raw bytes, or multipart/form-data field 'file'",
        "content": {
            "image/jpeg": {"schema": {"type": "string", "format": "binary"}},
            "image/png": {"schema": {"type": "string", "format": "binary"}},
            "image/webp": {"schema": {"type": "string", "format": "binary"}},
            "application/octet-stream": {"schema": {"type": "string", "format": "binary"}},
            "multipart/form-data": {
                "schema": {
                    "type": "object",
                    "properties": {"file": {"type": "string", "format": "binary"}},
                    "required": ["file"],
                }
            },
        },
    }
}


async def read_image(request: Request, settings: Settings) -> tuple[bytes, str | None]:
    """The uploaded image's bytes and declared type (raw body or multipart 'file')."""
    content_type = request.headers.get("content-type", "")
    if content_type.startswith("multipart/form-data"):
        try:
            async with request.form(
                max_files=1, max_fields=8, max_part_size=settings.max_frame_bytes + 1
            ) as form:  # closes the spooled upload afterwards
                upload = form.get("file")
                if upload is None or isinstance(upload, str):
                    raise ApiError(422, "invalid", "multipart body needs a file field 'file'")
                return await upload.read(), upload.content_type
        except ApiError:
            raise
        except StarletteHTTPException as exc:  # Starlette's own refusals of the framing
            if exc.status_code != 400:
                raise
            raise ApiError(400, "bad_request", f"malformed multipart body: {exc.detail}") from None
        except Exception as exc:  # malformed multipart framing
            raise ApiError(400, "bad_request", f"malformed multipart body: {exc}") from None
    return await request.body(), content_type or None


@router.post(
    "/{session_id}/frames",
    response_model=FrameOut,
    response_model_exclude_unset=True,  # "objects" only for a session of several
    responses=ERRORS,
    openapi_extra=FRAME_BODY,
)
async def track_frame(
    session_id: str,
    request: Request,
    response: Response,
    owner: OwnerDep,
    settings: SettingsDep,
    store: StoreDep,
    cpu: CpuDep,
    if_match: IfMatch = None,
) -> dict[str, Any]:
    """Track the session's contour into one encoded frame (JPEG, PNG or WebP)."""
    start = time.perf_counter()
    data, media_type = await read_image(request, settings)
    async with store.lease(session_id, owner) as session:
        check_version(session, if_match)
        result = await track_encoded(cpu, settings, session, data, media_type)
        response.headers["ETag"] = f'"{session.version}"'
    metrics.FRAMES.labels(transport="rest").inc()
    metrics.FRAME_SECONDS.labels(transport="rest").observe(time.perf_counter() - start)
    return result


@router.post(
    "/{session_id}/objects",
    status_code=status.HTTP_201_CREATED,
    response_model=ObjectOut,
    responses=ERRORS,
)
async def add_object(
    session_id: str,
    spec: ObjectSpec,
    response: Response,
    owner: OwnerDep,
    settings: SettingsDep,
    store: StoreDep,
    if_match: IfMatch = None,
) -> dict[str, Any]:
    """Add an object to a session of ``objects``; it is tracked from the next frame on."""
    async with store.lease(session_id, owner) as session:
        check_version(session, if_match)
        key = session.change_objects(lambda objects: objects.add(spec, settings.max_nodes))
        response.headers["ETag"] = f'"{session.version}"'
        response.headers["Location"] = f"/v1/sessions/{session_id}/objects/{key}"
        return {"id": key, **_shape_of(session, key)}


@router.put("/{session_id}/objects/{object_id}", response_model=ObjectOut, responses=ERRORS)
async def replace_object(
    session_id: str,
    object_id: ObjectId,
    spec: ObjectSpec,
    response: Response,
    owner: OwnerDep,
    settings: SettingsDep,
    store: StoreDep,
    if_match: IfMatch = None,
) -> dict[str, Any]:
    """Correct an object: it starts anew from this outline on the next frame."""
    async with store.lease(session_id, owner) as session:
        check_version(session, if_match)
        session.change_objects(lambda objects: objects.replace(object_id, spec, settings.max_nodes))
        response.headers["ETag"] = f'"{session.version}"'
        return {"id": object_id, **_shape_of(session, object_id)}


@router.delete(
    "/{session_id}/objects/{object_id}",
    status_code=status.HTTP_204_NO_CONTENT,
    responses=ERRORS,
)
async def remove_object(
    session_id: str,
    object_id: ObjectId,
    owner: OwnerDep,
    store: StoreDep,
    if_match: IfMatch = None,
) -> Response:
    """Stop tracking an object (from the next frame on)."""
    async with store.lease(session_id, owner) as session:
        check_version(session, if_match)
        session.change_objects(lambda objects: objects.remove(object_id))
        return Response(
            status_code=status.HTTP_204_NO_CONTENT, headers={"ETag": f'"{session.version}"'}
        )


def _shape_of(session: Session, key: str) -> dict[str, Any]:
    """An object's contour(s) as the API shows them."""
    described = {} if session.objects is None else {o["id"]: o for o in session.objects.describe()}
    found = dict(described.get(key, {}))
    found.pop("id", None)
    return found
