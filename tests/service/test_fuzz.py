"""Fuzzing: schemathesis against the app's own OpenAPI, and random bodies at every endpoint.

Whatever arrives, the answer is never a server error, and every error is the JSON error body.
"""

from __future__ import annotations

import json
from collections.abc import Iterator
from typing import Any

import pytest
import schemathesis
from fastapi.testclient import TestClient
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from pydantic import BaseModel

from service.app import create_app
from service.schemas import ErrorOut, ForcesOut, FrameOut, SessionOut
from service.settings import Settings

APP = create_app(Settings(max_sessions=100_000, session_ttl_seconds=600))
SCHEMA = schemathesis.openapi.from_asgi("/openapi.json", APP)
HELPER = TestClient(APP)
CIRCLE: dict[str, Any] = {"circle": {"center": [160, 120], "radius": 40}}

FUZZ = settings(
    max_examples=30,
    deadline=None,
    derandomize=True,  # the same examples on every run
    database=None,
    suppress_health_check=list(HealthCheck),
)

# the success body of each operation
BODIES: dict[tuple[str, str, int], type[BaseModel]] = {
    ("POST", "/v1/sessions", 201): SessionOut,
    ("GET", "/v1/sessions/{session_id}", 200): SessionOut,
    ("POST", "/v1/sessions/{session_id}/forces", 200): ForcesOut,
    ("POST", "/v1/sessions/{session_id}/frames", 200): FrameOut,
}


def new_session(closed: bool = True) -> str:
    spec = CIRCLE if closed else {"nodes": [[0, 0], [10, 0], [20, 5]], "closed": False}
    response = HELPER.post("/v1/sessions", json=spec)
    assert response.status_code == 201
    sid: str = response.json()["id"]
    return sid


def with_real_session(case: schemathesis.Case[Any]) -> None:
    """Point about half the generated session ids at a live session (the rest stay unknown)."""
    params = case.path_parameters or {}
    generated = str(params.get("session_id", ""))
    if "session_id" in params and len(generated) % 2 == 0:
        params["session_id"] = new_session(closed=len(generated) % 4 == 0)


def check_body(method: str, path: str, status: int, content_type: str, body: bytes) -> None:
    """Errors are ``{"error": {...}}``; successes match their response model."""
    assert status < 500, body[:500]
    if status >= 400:
        assert content_type.startswith("application/json"), (status, content_type)
        error = ErrorOut.model_validate_json(body)
        assert error.error.status == status
        assert error.error.message
        return
    model = BODIES.get((method, path, status))
    if model is not None:
        model.model_validate_json(body)
    if status == 204:
        assert body == b""


@SCHEMA.parametrize()
@FUZZ
def test_schema_no_server_errors(case: schemathesis.Case[Any]) -> None:
    with_real_session(case)
    response = case.call()
    content_type = (response.headers.get("content-type") or [""])[0]
    check_body(
        case.method.upper(),
        case.operation.path,
        response.status_code,
        content_type,
        response.content,
    )


@SCHEMA.parametrize()
@FUZZ
def test_schema_conformance(case: schemathesis.Case[Any]) -> None:
    """Every schemathesis check, except two that cannot judge this API.

    - ``positive_data_acceptance``: the schema cannot say that forces must number as many
      as the nodes, that a ring needs 3 nodes, or which ``tracking`` options exist, so
      "schema-valid" bodies are legitimately refused with 422;
    - ``response_schema_conformance``: schemathesis rewrites the OpenAPI 3.1 ``prefixItems``
      of ``[x, y]`` points into an invalid ``items`` array and cannot validate them
      (schemathesis issues #3842, #4099); :func:`test_schema_no_server_errors` validates
      the bodies with the app's own models instead.
    """
    with_real_session(case)
    case.call_and_validate(
        excluded_checks=[
            schemathesis.checks.positive_data_acceptance,
            schemathesis.checks.response_schema_conformance,
        ]
    )


# -- random bodies at every endpoint ----------------------------------------------------------


@pytest.fixture(scope="module")
def fuzz_client() -> Iterator[TestClient]:
    settings_ = Settings(max_sessions=100_000, max_json_bytes=64 * 1024, max_frame_bytes=64 * 1024)
    with TestClient(create_app(settings_), raise_server_exceptions=False) as client:
        yield client


ENDPOINTS = [
    ("POST", "/v1/sessions"),
    ("GET", "/v1/sessions/{sid}"),
    ("DELETE", "/v1/sessions/{sid}"),
    ("POST", "/v1/sessions/{sid}/forces"),
    ("POST", "/v1/sessions/{sid}/frames"),
    ("PUT", "/v1/sessions/{sid}"),
    ("PATCH", "/v1/sessions/{sid}/forces"),
    ("GET", "/healthz"),
    ("GET", "/readyz"),
    ("GET", "/metrics"),
    ("POST", "/v1/sessions/{sid}/stream"),
    ("POST", "/nowhere"),
]
CONTENT_TYPES = [
    None,
    "application/json",
    "application/json; charset=utf-8",
    "image/jpeg",
    "image/png",
    "image/webp",
    "application/octet-stream",
    "multipart/form-data; boundary=fuzz",
    "multipart/form-data",
    "application/x-www-form-urlencoded",
    "text/plain",
    "image/",
    ";;;",
]

numbers = st.one_of(
    st.floats(),
    st.integers(min_value=-(10**30), max_value=10**30),
    st.sampled_from([0, -1, 1e-320, 1e308, -1e308, 4096, 4097, 1e9, -1e9, 999_999_999.5]),
)
json_values = st.recursive(
    st.none() | st.booleans() | numbers | st.text(max_size=20),
    lambda inner: st.lists(inner, max_size=6) | st.dictionaries(st.text(max_size=10), inner),
    max_leaves=30,
)
points = st.lists(st.lists(numbers, min_size=1, max_size=3), max_size=70)
near_valid = st.fixed_dictionaries(
    {},
    optional={
        "nodes": points | json_values,
        "forces": points | json_values,
        "circle": st.fixed_dictionaries(
            {"center": st.lists(numbers, max_size=3), "radius": numbers},
            optional={"count": numbers | json_values},
        ),
        "closed": st.booleans() | json_values,
        "stiffness": numbers | json_values,
        "method": st.sampled_from(["exact", "efdm", "efdmt", "dmma", "dmmat", "x"]),
        "tracking": st.dictionaries(
            st.sampled_from(["stiffness", "iterations", "band", "occlusion", "learning_rate", "x"]),
            numbers | json_values,
        ),
        "ping": json_values,
    },
)
bodies = st.one_of(
    st.binary(max_size=2000),
    json_values.map(lambda v: json.dumps(v).encode()),
    near_valid.map(lambda v: json.dumps(v).encode()),
    st.sampled_from(
        [b"", b"{", b"[" * 5000, b"\xff\xd8\xff" + b"\0" * 64, b"\x89PNG\r\n\x1a\n", b"RIFF"]
    ),
)


def send(
    client: TestClient, method: str, path: str, body: bytes, content_type: str | None
) -> tuple[str, int, str, bytes]:
    url = path.format(sid=new_session_in(client))
    headers = {} if content_type is None else {"content-type": content_type}
    response = client.request(method, url, content=body, headers=headers)
    return url, response.status_code, response.headers.get("content-type", ""), response.content


def sessions_held(client: TestClient) -> int:
    """How many sessions the app's store holds (its /metrics gauge, read from the store)."""
    text = client.get("/metrics").text
    line = next(x for x in text.splitlines() if x.startswith("efdm_sessions_active "))
    return int(float(line.split()[1]))


def new_session_in(client: TestClient) -> str:
    response = client.post("/v1/sessions", json=CIRCLE)
    assert response.status_code == 201
    sid: str = response.json()["id"]
    return sid


@given(
    endpoint=st.sampled_from(ENDPOINTS),
    body=bodies,
    content_type=st.sampled_from(CONTENT_TYPES),
)
@settings(FUZZ, max_examples=150)
def test_random_bodies_everywhere(
    fuzz_client: TestClient, endpoint: tuple[str, str], body: bytes, content_type: str | None
) -> None:
    method, path = endpoint
    _, status, response_type, content = send(fuzz_client, method, path, body, content_type)
    check_body(method, path.replace("{sid}", "{session_id}"), status, response_type, content)


@given(spec=near_valid)
@settings(FUZZ, max_examples=150)
def test_near_valid_sessions_and_forces(fuzz_client: TestClient, spec: dict[str, Any]) -> None:
    body = json.dumps(spec).encode()  # NaN and Infinity go as the bare words
    headers = {"content-type": "application/json"}
    held = sessions_held(fuzz_client)
    created = fuzz_client.post("/v1/sessions", content=body, headers=headers)
    assert sessions_held(fuzz_client) == held + (
        created.status_code == 201
    )  # a failure stores none
    check_body(
        "POST",
        "/v1/sessions",
        created.status_code,
        created.headers["content-type"],
        created.content,
    )
    sid = created.json()["id"] if created.status_code == 201 else new_session_in(fuzz_client)
    before = fuzz_client.get(f"/v1/sessions/{sid}").json()
    path = "/v1/sessions/{session_id}/forces"
    forces = fuzz_client.post(f"/v1/sessions/{sid}/forces", content=body, headers=headers)
    check_body("POST", path, forces.status_code, forces.headers["content-type"], forces.content)
    # whatever the forces did, the session still reads back within the schema ...
    after = fuzz_client.get(f"/v1/sessions/{sid}")
    check_body(
        "GET",
        "/v1/sessions/{session_id}",
        after.status_code,
        after.headers["content-type"],
        after.content,
    )
    assert after.status_code == 200
    if forces.status_code != 200:  # ... and an error changed nothing
        assert {k: v for k, v in after.json().items() if k != "expires_at"} == {
            k: v for k, v in before.items() if k != "expires_at"
        }
