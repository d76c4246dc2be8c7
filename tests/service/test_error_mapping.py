"""The one mapping of domain errors to HTTP statuses, codes and headers.

:data:`service.errors.HTTP_ERRORS` serves the REST handlers and the stream's
error messages alike.
"""

from __future__ import annotations

import inspect

import pytest
from fastapi import FastAPI
from fastapi.testclient import TestClient

from service import domain_errors as d
from service.errors import HTTP_ERRORS, ApiError, as_api_error, install
from service.routes.stream import error_message

CASES: list[tuple[d.ServiceError, int, str, dict[str, str]]] = [
    (d.InvalidInputError("nodes: too few"), 422, "invalid", {}),
    (d.BadImageError("empty image"), 400, "bad_image", {}),
    (d.ImageTooLargeError("too many pixels"), 413, "too_large", {}),
    (d.UnsupportedImageTypeError("'text/plain'"), 415, "unsupported_media_type", {}),
    (d.SessionNotFoundError(), 404, "not_found", {}),
    (d.ObjectNotFoundError("no object 'k'"), 404, "object_not_found", {}),
    (d.PreconditionFailedError("at version 2, not 1"), 412, "version_mismatch", {}),
    (d.VersionConflictError(), 409, "conflict", {}),
    (d.StreamReplacedError(), 409, "stream_replaced", {}),
    (d.TooManySessionsError(5), 429, "too_many_sessions", {"Retry-After": "10"}),
    (d.StoreUnavailableError(), 503, "unavailable", {"Retry-After": "1"}),
]
IDS = [type(exc).__name__ for exc, *_ in CASES]


@pytest.mark.parametrize(("exc", "status", "code", "headers"), CASES, ids=IDS)
def test_each_domain_error_has_its_status_code_and_headers(
    exc: d.ServiceError, status: int, code: str, headers: dict[str, str]
) -> None:
    error = as_api_error(exc)
    assert (error.status, error.code, error.message) == (status, code, exc.message)
    assert error.headers == headers


def test_every_domain_error_is_mapped() -> None:
    kinds = {
        cls
        for _, cls in inspect.getmembers(d, inspect.isclass)
        if issubclass(cls, d.ServiceError) and cls is not d.ServiceError
    }
    assert kinds == set(HTTP_ERRORS) - {d.ServiceError}
    assert kinds == {type(exc) for exc, *_ in CASES}


def test_retry_after_follows_the_error() -> None:
    assert as_api_error(d.TooManySessionsError(3, retry_after=30)).headers == {"Retry-After": "30"}


def test_a_subclass_takes_its_bases_mapping() -> None:
    class NoSuchFrameError(d.SessionNotFoundError):
        pass

    class OtherError(d.ServiceError):
        pass

    assert as_api_error(NoSuchFrameError()).status == 404
    assert (as_api_error(OtherError("?")).status, as_api_error(OtherError("?")).code) == (
        400,
        "bad_request",
    )


def test_http_errors_pass_through() -> None:
    error = ApiError(401, "unauthorized", "missing API key", **{"WWW-Authenticate": "Bearer"})
    assert as_api_error(error) is error


@pytest.fixture(scope="module")
def raising() -> TestClient:
    """An app with the service's handlers and a route raising CASES[i]."""
    app = FastAPI()
    install(app)

    @app.get("/raise/{i}")
    async def fail(i: int) -> None:
        raise CASES[i][0]

    return TestClient(app)


@pytest.mark.parametrize("i", range(len(CASES)), ids=IDS)
def test_the_handler_answers_the_mapped_json_error(raising: TestClient, i: int) -> None:
    exc, status, code, headers = CASES[i]
    response = raising.get(f"/raise/{i}")
    assert response.status_code == status
    assert response.json() == {"error": {"status": status, "code": code, "message": exc.message}}
    for name, value in headers.items():
        assert response.headers[name] == value


@pytest.mark.parametrize(("exc", "status", "code", "headers"), CASES, ids=IDS)
def test_stream_error_messages_use_the_same_mapping(
    exc: d.ServiceError, status: int, code: str, headers: dict[str, str]
) -> None:
    assert error_message(exc) == {
        "type": "error",
        "error": {"status": status, "code": code, "message": exc.message},
    }
