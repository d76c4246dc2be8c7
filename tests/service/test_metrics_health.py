"""Liveness, readiness and Prometheus metrics that move as the service works.

The metrics live in one process-wide registry, so tests compare before and after.
"""

from __future__ import annotations

import json
from collections.abc import Iterator
from typing import Any

import pytest
from fastapi.testclient import TestClient
from prometheus_client.parser import text_string_to_metric_families

from service.app import create_app
from service.settings import Settings
from service.store import MemoryStore
from tests.service.conftest import disc_frame

CIRCLE: dict[str, Any] = {"circle": {"center": [160, 120], "radius": 40}}
Labels = dict[str, str]


class Metrics:
    """One scrape of ``/metrics``, by sample name and labels."""

    def __init__(self, text: str) -> None:
        self.families = {f.name: f for f in text_string_to_metric_families(text)}
        self.samples: dict[tuple[str, frozenset[tuple[str, str]]], float] = {}
        for family in self.families.values():
            for sample in family.samples:
                key = (sample.name, frozenset(sample.labels.items()))
                self.samples[key] = sample.value

    def __call__(self, name: str, **labels: str) -> float:
        return self.samples.get((name, frozenset(labels.items())), 0.0)


def delta(before: Metrics, after: Metrics, name: str, **labels: str) -> float:
    return after(name, **labels) - before(name, **labels)


def scrape(client: TestClient) -> Metrics:
    response = client.get("/metrics")
    assert response.status_code == 200
    assert response.headers["content-type"].startswith("text/plain")
    return Metrics(response.text)


def create(client: TestClient, spec: dict[str, Any] | None = None) -> str:
    response = client.post("/v1/sessions", json=CIRCLE if spec is None else spec)
    assert response.status_code == 201, response.text
    sid: str = response.json()["id"]
    return sid


def post_frame(client: TestClient, sid: str, data: bytes) -> Any:
    return client.post(
        f"/v1/sessions/{sid}/frames", content=data, headers={"content-type": "image/jpeg"}
    )


# -- health -----------------------------------------------------------------------------------


def test_healthz(client: TestClient) -> None:
    response = client.get("/healthz")
    assert response.status_code == 200
    assert response.json() == {"status": "ok"}


def test_readyz(client: TestClient) -> None:
    response = client.get("/readyz")
    assert response.status_code == 200
    assert response.json() == {"status": "ready"}


class UnreachableStore(MemoryStore):
    async def ping(self) -> bool:
        return False


def test_readyz_reports_an_unreachable_store(settings: Settings) -> None:
    store = UnreachableStore(max_sessions=10, ttl=60)
    with TestClient(create_app(settings, store=store)) as client:
        response = client.get("/readyz")
        assert response.status_code == 503
        assert response.json() == {"status": "store unreachable"}
        assert client.get("/healthz").status_code == 200  # alive, just not ready


# -- metrics ----------------------------------------------------------------------------------


def test_metrics_are_exposed(client: TestClient) -> None:
    m = scrape(client)
    kinds = {name: f.type for name, f in m.families.items()}
    assert kinds["efdm_sessions_active"] == "gauge"
    assert kinds["efdm_frames_processed"] == "counter"
    assert kinds["efdm_frames_dropped"] == "counter"
    assert kinds["efdm_frame_seconds"] == "histogram"
    assert kinds["efdm_errors"] == "counter"
    assert kinds["efdm_forces"] == "counter"
    assert kinds["efdm_websockets_open"] == "gauge"


def test_sessions_active_follows_the_store(client: TestClient) -> None:
    assert scrape(client)("efdm_sessions_active") == 0
    ids = [create(client) for _ in range(3)]
    assert scrape(client)("efdm_sessions_active") == 3
    client.delete(f"/v1/sessions/{ids[0]}")
    assert scrape(client)("efdm_sessions_active") == 2


def test_rest_frames_are_counted_and_timed(client: TestClient) -> None:
    sid = create(client)
    before = scrape(client)
    for i in range(3):
        assert post_frame(client, sid, disc_frame(160 + i, 120)).status_code == 200
    after = scrape(client)
    rest = {"transport": "rest"}
    ws = {"transport": "websocket"}
    assert delta(before, after, "efdm_frames_processed_total", **rest) == 3
    assert delta(before, after, "efdm_frames_processed_total", **ws) == 0
    assert delta(before, after, "efdm_frame_seconds_count", **rest) == 3
    assert delta(before, after, "efdm_frame_seconds_sum", **rest) > 0
    buckets = [
        after("efdm_frame_seconds_bucket", transport="rest", le=le)
        for le in ("0.002", "0.005", "0.01", "0.02", "0.05", "0.1", "0.2", "0.5", "1.0", "2.0")
    ]
    assert buckets == sorted(buckets)
    assert after("efdm_frame_seconds_bucket", transport="rest", le="+Inf") == after(
        "efdm_frame_seconds_count", **rest
    )


def test_failed_frames_are_not_counted_as_processed(client: TestClient) -> None:
    sid = create(client)
    before = scrape(client)
    assert post_frame(client, sid, b"junk").status_code == 400
    after = scrape(client)
    assert delta(before, after, "efdm_frames_processed_total", transport="rest") == 0
    assert delta(before, after, "efdm_errors_total", kind="bad_image") == 1


def test_stream_frames_and_drops_are_counted(client: TestClient) -> None:
    sid = create(client)
    sent = 12
    frames = [disc_frame(160 + i % 3, 120) for i in range(3)]
    before = scrape(client)
    with client.websocket_connect(f"/v1/sessions/{sid}/stream") as ws:
        assert scrape(client)("efdm_websockets_open") == before("efdm_websockets_open") + 1
        for i in range(sent):
            ws.send_bytes(frames[i % 3])
        results = dropped = 0
        while results + dropped < sent:
            message = ws.receive_json()
            assert message["type"] == "frame"
            results += 1
            dropped += message["dropped"]
    after = scrape(client)
    ws_labels = {"transport": "websocket"}
    assert delta(before, after, "efdm_frames_processed_total", **ws_labels) == results
    assert delta(before, after, "efdm_frame_seconds_count", **ws_labels) == results
    assert delta(before, after, "efdm_frames_dropped_total") == dropped
    for _ in range(100):  # the handler's bookkeeping ends just after the close
        if scrape(client)("efdm_websockets_open") == before("efdm_websockets_open"):
            break
    assert scrape(client)("efdm_websockets_open") == before("efdm_websockets_open")


def test_forces_are_counted(client: TestClient) -> None:
    sid = create(client)
    before = scrape(client)
    client.post(f"/v1/sessions/{sid}/forces", json={"forces": [[1, 0]] * 64})
    with client.websocket_connect(f"/v1/sessions/{sid}/stream") as ws:
        ws.send_text(json.dumps({"forces": [[0, 1]] * 64}))
        assert ws.receive_json()["type"] == "forces"
    after = scrape(client)
    assert delta(before, after, "efdm_forces_total") == 2


def error_deltas(client: TestClient, act: Any) -> dict[str, float]:
    before = scrape(client)
    act()
    after = scrape(client)
    kinds = {
        dict(labels)["kind"]
        for name, labels in after.samples
        if name == "efdm_errors_total" and labels
    }
    deltas = {
        k: after("efdm_errors_total", kind=k) - before("efdm_errors_total", kind=k) for k in kinds
    }
    return {k: v for k, v in deltas.items() if v}


@pytest.mark.parametrize(
    ("kind", "act"),
    [
        ("not_found", lambda c, sid: c.get("/v1/sessions/nope")),
        ("invalid", lambda c, sid: c.post("/v1/sessions", json={})),
        ("invalid", lambda c, sid: c.post(f"/v1/sessions/{sid}/forces", json={"forces": []})),
        ("too_large", lambda c, sid: c.post("/v1/sessions", content=b" " * (3 * 1024 * 1024))),
        ("bad_image", lambda c, sid: post_frame(c, sid, b"\xff\xd8\xff junk")),
        (
            "unsupported_media_type",
            lambda c, sid: c.post(
                f"/v1/sessions/{sid}/frames", content=b"x", headers={"content-type": "text/plain"}
            ),
        ),
        (
            "version_mismatch",
            lambda c, sid: c.post(
                f"/v1/sessions/{sid}/forces",
                json={"forces": [[0, 0]] * 64},
                headers={"if-match": '"42"'},
            ),
        ),
        ("method_not_allowed", lambda c, sid: c.put(f"/v1/sessions/{sid}")),
    ],
)
def test_errors_are_counted_by_kind(client: TestClient, kind: str, act: Any) -> None:
    sid = create(client)
    assert error_deltas(client, lambda: act(client, sid)) == {kind: 1}


def test_session_cap_and_stream_errors_are_counted() -> None:
    with TestClient(create_app(Settings(max_sessions=1))) as client:
        sid = create(client)
        assert error_deltas(client, lambda: client.post("/v1/sessions", json=CIRCLE)) == {
            "too_many_sessions": 1
        }

        def stream_errors() -> None:
            with client.websocket_connect(f"/v1/sessions/{sid}/stream") as ws:
                ws.send_bytes(b"junk")
                ws.receive_json()
                ws.send_text("{bad")
                ws.receive_json()

        assert error_deltas(client, stream_errors) == {"bad_image": 1, "bad_request": 1}


class TestWithApiKeys:
    @pytest.fixture
    def settings(self) -> Settings:
        return Settings(api_keys=("k",))

    @pytest.fixture
    def client(self, settings: Settings) -> Iterator[TestClient]:
        with TestClient(create_app(settings)) as c:
            yield c

    def test_unauthorized_calls_are_counted(self, client: TestClient) -> None:
        deltas = error_deltas(client, lambda: client.get("/v1/sessions/x"))
        assert deltas == {"unauthorized": 1}

    def test_metrics_and_health_need_no_key(self, client: TestClient) -> None:
        assert client.get("/metrics").status_code == 200
        assert client.get("/healthz").status_code == 200
        assert client.get("/readyz").status_code == 200


def test_metrics_can_need_their_own_key() -> None:
    settings = Settings(metrics_key="scrape-me", api_keys=("client",))
    with TestClient(create_app(settings)) as client:
        assert client.get("/metrics").status_code == 401
        client_key = {"authorization": "Bearer client"}
        assert client.get("/metrics", headers=client_key).status_code == 401
        scraper = client.get("/metrics", headers={"authorization": "Bearer scrape-me"})
        assert scraper.status_code == 200
        assert "efdm_" in scraper.text
        assert client.get("/healthz").status_code == 200  # the probes stay open
