"""Errors as JSON: ``{"error": {"status": 404, "code": "not_found", "message": ...}}``.

The one place where failures get their HTTP status, error code and headers:
:data:`HTTP_ERRORS` maps each domain error (:mod:`service.domain_errors`) to
its status and code, :func:`as_api_error` applies it, and the handlers of
:func:`install` (REST) and the stream route (WebSocket) both go through it.
"""

from __future__ import annotations

import logging
from collections.abc import Mapping, Sequence
from typing import Any

from fastapi import FastAPI, Request
from fastapi.exceptions import RequestValidationError
from fastapi.responses import JSONResponse
from starlette.exceptions import HTTPException as StarletteHTTPException
from starlette.routing import compile_path

from service import metrics
from service.domain_errors import (
    BadImageError,
    ImageTooLargeError,
    InvalidInputError,
    ObjectNotFoundError,
    PreconditionFailedError,
    ServiceError,
    SessionNotFoundError,
    StoreUnavailableError,
    StreamReplacedError,
    TooManySessionsError,
    UnsupportedImageTypeError,
    VersionConflictError,
)

log = logging.getLogger("efdm.service")


class ApiError(Exception):
    """An error a client caused (or may retry), with its HTTP status.

    Raised directly only for HTTP concerns (authentication, request framing);
    domain errors become one through :func:`as_api_error`.
    """

    def __init__(self, status: int, code: str, message: str, **headers: str) -> None:
        super().__init__(message)
        self.status = status
        self.code = code
        self.message = message
        self.headers = headers


HTTP_ERRORS: Mapping[type[ServiceError], tuple[int, str]] = {
    ServiceError: (400, "bad_request"),
    InvalidInputError: (422, "invalid"),
    BadImageError: (400, "bad_image"),
    ImageTooLargeError: (413, "too_large"),
    UnsupportedImageTypeError: (415, "unsupported_media_type"),
    SessionNotFoundError: (404, "not_found"),
    ObjectNotFoundError: (404, "object_not_found"),
    PreconditionFailedError: (412, "version_mismatch"),
    VersionConflictError: (409, "conflict"),
    StreamReplacedError: (409, "stream_replaced"),
    TooManySessionsError: (429, "too_many_sessions"),
    StoreUnavailableError: (503, "unavailable"),
}
"""HTTP status and error code of each domain error (a subclass takes its base's)."""


def as_api_error(exc: ApiError | ServiceError) -> ApiError:
    """The HTTP error a failure answers: status, code, message and headers.

    Parameters
    ----------
    exc : ApiError or ServiceError
        An HTTP error (returned as it is) or a domain error (mapped by
        :data:`HTTP_ERRORS`; its ``retry_after`` becomes ``Retry-After``).
    """
    if isinstance(exc, ApiError):
        return exc
    status, code = next(HTTP_ERRORS[k] for k in type(exc).__mro__ if k in HTTP_ERRORS)
    headers = {} if exc.retry_after is None else {"Retry-After": str(exc.retry_after)}
    return ApiError(status, code, exc.message, **headers)


def body(status: int, code: str, message: str, **extra: Any) -> dict[str, Any]:
    """The JSON body of an error response."""
    return {"error": {"status": status, "code": code, "message": message, **extra}}


def first_invalid(errors: Sequence[Mapping[str, Any]], context: str = "") -> str:
    """The first of pydantic's ``errors`` as one line: ``"where: what"``, where is
    ``context`` (e.g. the WebSocket control's name) and the field's path, whichever exist."""
    if not errors:
        return f"{context}: invalid" if context else "invalid"
    first = errors[0]
    path = [context] if context else []
    path += [str(p) for p in first.get("loc", ()) if p != "body"]
    where, what = ".".join(path), str(first.get("msg", "invalid"))
    return f"{where}: {what}" if where else what


def malformed_json(error: Mapping[str, Any]) -> str:
    """A person's reading of a JSON decode error: what is wrong and at which character."""
    loc = error.get("loc", ())
    at = loc[-1] if loc and isinstance(loc[-1], int) else None
    reason = (error.get("ctx") or {}).get("error") or error.get("msg") or "JSON decode error"
    where = "" if at is None else f" at character {at}"
    return f"the body is not valid JSON{where}: {reason}"


def allowed_methods(app: FastAPI, path: str) -> list[str]:
    """The HTTP methods the API offers on ``path`` (from its OpenAPI paths)."""
    methods: set[str] = set()
    for template, operations in app.openapi().get("paths", {}).items():
        if compile_path(template)[0].match(path):
            methods.update(m.upper() for m in operations)
    return sorted(methods)


UNPARSED_BODY = "There was an error parsing the body"
"""FastAPI's 400 detail for a JSON body its parser gave up on (nested too deep, not UTF-8)."""


def _is_json(media_type: str) -> bool:
    """``application/json`` or a ``+json`` type (``application/merge-patch+json``)."""
    return media_type == "application/json" or media_type.endswith("+json")


def install(app: FastAPI) -> None:
    """Register the handlers that turn every failure into a JSON error."""

    @app.exception_handler(ApiError)
    @app.exception_handler(ServiceError)
    async def api_error(_: Request, exc: ApiError | ServiceError) -> JSONResponse:
        error = as_api_error(exc)
        metrics.ERRORS.labels(kind=error.code).inc()
        return JSONResponse(
            body(error.status, error.code, error.message),
            status_code=error.status,
            headers=error.headers,
        )

    @app.exception_handler(RequestValidationError)
    async def invalid(request: Request, exc: RequestValidationError) -> JSONResponse:
        from service.auth import bearer, check_key

        settings = getattr(request.app.state, "settings", None)
        # a /v1 body is read before its key is checked: a request without a good key is 401
        if settings is not None and request.url.path.startswith("/v1/"):
            try:
                check_key(settings, bearer(request.headers.get("authorization")))
            except ApiError as refused:
                return await api_error(request, refused)
        errors = exc.errors()
        kind = request.headers.get("content-type", "").split(";")[0].strip().lower()
        in_body = any(tuple(e.get("loc", ()))[:1] == ("body",) for e in errors)
        if in_body and kind and not _is_json(kind):  # a JSON body sent as something else
            metrics.ERRORS.labels(kind="unsupported_media_type").inc()
            message = f"send the body as application/json; got {kind}"
            return JSONResponse(body(415, "unsupported_media_type", message), status_code=415)
        broken = [e for e in errors if e.get("type") == "json_invalid"]
        empty = any(e.get("type") == "missing" and e.get("loc") == ("body",) for e in errors)
        if broken or empty:  # not JSON at all: a malformed request (400), not an invalid value
            metrics.ERRORS.labels(kind="bad_json").inc()
            message = (
                malformed_json(broken[0]) if broken else "the body is empty: send a JSON object"
            )
            return JSONResponse(body(400, "bad_json", message), status_code=400)
        metrics.ERRORS.labels(kind="invalid").inc()
        details = [{"loc": list(e.get("loc", ())), "msg": str(e.get("msg", ""))} for e in errors]
        message = first_invalid(details) if details else "invalid request"
        return JSONResponse(body(422, "invalid", message, details=details), status_code=422)

    @app.exception_handler(StarletteHTTPException)
    async def http_error(request: Request, exc: StarletteHTTPException) -> JSONResponse:
        code = {404: "not_found", 405: "method_not_allowed", 408: "timeout", 413: "too_large"}.get(
            exc.status_code, "http_error"
        )
        if exc.status_code == 400 and exc.detail == UNPARSED_BODY:  # FastAPI's, for JSON
            code = "bad_json"  # nested too deep to parse, or not UTF-8
        metrics.ERRORS.labels(kind=code).inc()
        headers = dict(getattr(exc, "headers", None) or {})
        if exc.status_code == 405:  # every method of the path (RFC 9110), not one route's
            headers["Allow"] = ", ".join(allowed_methods(request.app, request.url.path))
        return JSONResponse(
            body(exc.status_code, code, str(exc.detail)),
            status_code=exc.status_code,
            headers=headers or None,
        )

    @app.exception_handler(Exception)
    async def unexpected(_: Request, exc: Exception) -> JSONResponse:  # pragma: no cover
        metrics.ERRORS.labels(kind="internal").inc()
        log.exception("unexpected error", exc_info=exc)
        return JSONResponse(body(500, "internal", "internal error"), status_code=500)
