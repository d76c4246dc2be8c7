"""API keys: ``EFDM_API_KEYS`` set → every /v1 call needs ``Authorization: Bearer <key>``."""

from __future__ import annotations

from typing import Any

import pytest
from fastapi.testclient import TestClient

from service.auth import bearer, owner_of
from service.settings import Settings
from tests.service.conftest import disc_frame

CIRCLE: dict[str, Any] = {"circle": {"center": [160, 120], "radius": 40}}
A = {"authorization": "Bearer key-a"}
B = {"authorization": "Bearer key-b"}


@pytest.fixture
def settings() -> Settings:
    return Settings(api_keys=("key-a", "key-b"), max_sessions=50)


def create(client: TestClient, headers: dict[str, str]) -> str:
    response = client.post("/v1/sessions", json=CIRCLE, headers=headers)
    assert response.status_code == 201, response.text
    sid: str = response.json()["id"]
    return sid


def calls(sid: str) -> list[tuple[str, str, dict[str, Any]]]:
    """Every /v1 operation, as (method, url, httpx keyword arguments)."""
    return [
        ("POST", "/v1/sessions", {"json": CIRCLE}),
        ("GET", f"/v1/sessions/{sid}", {}),
        ("POST", f"/v1/sessions/{sid}/forces", {"json": {"forces": [[0, 0]] * 64}}),
        (
            "POST",
            f"/v1/sessions/{sid}/frames",
            {"content": disc_frame(160, 120), "headers": {"content-type": "image/jpeg"}},
        ),
        ("DELETE", f"/v1/sessions/{sid}", {}),
    ]


def request(
    client: TestClient, method: str, url: str, kwargs: dict[str, Any], auth: dict[str, str]
) -> Any:
    headers = {**kwargs.get("headers", {}), **auth}
    return client.request(method, url, **{**kwargs, "headers": headers})


def assert_unauthorized(response: Any) -> None:
    assert response.status_code == 401, response.text
    assert response.headers["www-authenticate"] == "Bearer"
    assert response.headers["content-type"].startswith("application/json")
    error = response.json()["error"]
    assert (error["status"], error["code"]) == (401, "unauthorized")
    assert "API key" in error["message"]


@pytest.mark.parametrize(
    "auth",
    [
        {},
        {"authorization": ""},
        {"authorization": "Bearer"},
        {"authorization": "Bearer "},
        {"authorization": "Bearer key-c"},
        {"authorization": "Bearer key-a2"},
        {"authorization": "Bearer key"},
        {"authorization": "Basic a2V5LWE6"},
        {"authorization": "key-a"},
        {"x-api-key": "key-a"},
    ],
    ids=repr,
)
def test_v1_calls_need_a_valid_key(client: TestClient, auth: dict[str, str]) -> None:
    sid = create(client, A)
    for method, url, kwargs in calls(sid):
        assert_unauthorized(request(client, method, url, kwargs, auth))
    assert client.get(f"/v1/sessions/{sid}", headers=A).json()["version"] == 1  # untouched


def test_the_api_key_query_parameter_is_only_for_websockets(client: TestClient) -> None:
    assert_unauthorized(client.post("/v1/sessions?api_key=key-a", json=CIRCLE))


def test_missing_and_wrong_keys_are_told_apart(client: TestClient) -> None:
    missing = client.get("/v1/sessions/x").json()["error"]["message"]
    wrong = client.get("/v1/sessions/x", headers={"authorization": "Bearer no"}).json()
    assert missing != wrong["error"]["message"]


def test_authentication_comes_before_lookup(client: TestClient) -> None:
    assert_unauthorized(client.get("/v1/sessions/no-such-session"))
    assert_unauthorized(client.post("/v1/sessions", content=b"{bad json"))
    as_json = {"content-type": "application/json"}
    for body in (b"{bad json", b"", b'{"circle": {"center": [1, 1], "radius": -1}}'):
        assert_unauthorized(client.post("/v1/sessions", content=body, headers=as_json))
    assert_unauthorized(client.post("/v1/sessions", content=b"{}", headers={"content-type": "a/b"}))


@pytest.mark.parametrize(
    "auth", [A, B, {"authorization": "bearer key-a"}, {"authorization": "BEARER  key-b "}]
)
def test_each_key_works(client: TestClient, auth: dict[str, str]) -> None:
    sid = create(client, auth)
    for method, url, kwargs in calls(sid):
        response = request(client, method, url, kwargs, auth)
        assert response.status_code < 300, (method, url, response.text)


@pytest.mark.parametrize("path", ["/healthz", "/readyz", "/metrics", "/", "/docs", "/openapi.json"])
def test_operations_and_docs_stay_open(client: TestClient, path: str) -> None:
    response = client.get(path)
    assert response.status_code == 200, response.text


def test_sessions_are_visible_only_to_the_creating_key(client: TestClient) -> None:
    sid = create(client, A)
    for method, url, kwargs in calls(sid)[1:]:
        response = request(client, method, url, kwargs, B)
        assert response.status_code == 404, (method, url)
        # indistinguishable from a session that does not exist
        unknown = request(client, method, url.replace(sid, "x" * len(sid)), kwargs, B)
        assert response.json() == unknown.json()
    session = client.get(f"/v1/sessions/{sid}", headers=A)
    assert session.status_code == 200
    assert session.json()["version"] == 1
    assert client.delete(f"/v1/sessions/{sid}", headers=A).status_code == 204


def test_the_owner_tag_is_not_the_key() -> None:
    assert owner_of("key-a") != owner_of("key-b")
    assert "key-a" not in owner_of("key-a")
    assert len(owner_of("key-a")) == 32


@pytest.mark.parametrize(
    ("header", "key"),
    [
        (None, None),
        ("", None),
        ("Bearer abc", "abc"),
        ("bearer abc", "abc"),
        ("Bearer   abc  ", "abc"),
        ("Bearer ", None),
        ("Basic abc", None),
        ("Bearerabc", None),
    ],
)
def test_bearer(header: str | None, key: str | None) -> None:
    assert bearer(header) == key


def test_keys_from_the_environment(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("EFDM_API_KEYS", " one, two ,,three ")
    configured = Settings()
    assert configured.api_keys == ("one", "two", "three")
    assert configured.auth_enabled
    monkeypatch.setenv("EFDM_API_KEYS", "")
    assert not Settings().auth_enabled


class TestWithoutKeys:
    @pytest.fixture
    def settings(self) -> Settings:
        return Settings(max_sessions=50)

    def test_no_key_needed_and_any_header_ignored(self, client: TestClient) -> None:
        sid = create(client, {})
        assert client.get(f"/v1/sessions/{sid}", headers=A).status_code == 200
        assert client.get(f"/v1/sessions/{sid}").status_code == 200


def test_a_listing_shows_only_the_callers_sessions(client: TestClient) -> None:
    mine = sorted(create(client, A) for _ in range(3))
    theirs = create(client, B)
    listed = client.get("/v1/sessions", headers=A)
    assert listed.status_code == 200
    assert [s["id"] for s in listed.json()["sessions"]] == mine
    assert [s["id"] for s in client.get("/v1/sessions", headers=B).json()["sessions"]] == [theirs]
    assert client.get("/v1/sessions").status_code == 401
    assert client.get("/v1/sessions", headers={"authorization": "Bearer nope"}).status_code == 401
