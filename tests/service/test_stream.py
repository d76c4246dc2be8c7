"""``WS /v1/sessions/{id}/stream``: frames in, contours out, latest frame wins."""

from __future__ import annotations

import json
import threading
from typing import Any

import cv2
import httpx
import numpy as np
import pytest
from fastapi.testclient import TestClient
from starlette.testclient import WebSocketTestSession
from starlette.websockets import WebSocketDisconnect
from websockets.exceptions import ConnectionClosed
from websockets.sync.client import ClientConnection, connect

from engine import deform
from service.app import create_app
from service.settings import Settings
from tests.service.conftest import LiveServer, disc_frame

CIRCLE: dict[str, Any] = {"circle": {"center": [160, 120], "radius": 40}}


def create(http: TestClient | httpx.Client, spec: dict[str, Any] | None = None, **kw: Any) -> str:
    response = http.post("/v1/sessions", json=CIRCLE if spec is None else spec, **kw)
    assert response.status_code == 201, response.text
    sid: str = response.json()["id"]
    return sid


def receive(ws: WebSocketTestSession) -> dict[str, Any]:
    message: dict[str, Any] = ws.receive_json()
    return message


def big_frame(cx: float, cy: float) -> bytes:
    """A 2000 x 2000 JPEG (slow to decode and track): a disc on a noisy background."""
    rng = np.random.default_rng(int(cx * 10 + cy))
    texture = rng.integers(120, 230, (500, 500, 3), dtype=np.uint8)
    img = np.ascontiguousarray(cv2.resize(texture, (2000, 2000), interpolation=cv2.INTER_LINEAR))
    cv2.circle(img, (round(cx), round(cy)), 300, (40, 40, 170), -1, cv2.LINE_AA)
    ok, data = cv2.imencode(".jpg", img, [cv2.IMWRITE_JPEG_QUALITY, 90])
    assert ok
    return data.tobytes()


BIG_CIRCLE: dict[str, Any] = {"circle": {"center": [1000, 1000], "radius": 300, "count": 256}}


@pytest.fixture(scope="module")
def big_frames() -> list[bytes]:
    return [big_frame(1000 + i, 1000) for i in range(4)]


def closed_by(ws: WebSocketTestSession) -> WebSocketDisconnect:
    with pytest.raises(WebSocketDisconnect) as info:
        ws.receive_json()
    return info.value


def ws_connect(server: LiveServer, path: str) -> ClientConnection:
    return connect(
        server.ws_url + path,
        proxy=None,
        compression=None,
        max_size=2**24,
        open_timeout=30,
        close_timeout=5,
    )


def recv(ws: ClientConnection) -> dict[str, Any]:
    message: dict[str, Any] = json.loads(ws.recv(timeout=60))
    return message


# -- protocol ---------------------------------------------------------------------------------


@pytest.mark.parametrize("payload", [1, "hello", {"a": [1, 2]}, None, 2.5])
def test_ping_pong(client: TestClient, payload: Any) -> None:
    sid = create(client)
    with client.websocket_connect(f"/v1/sessions/{sid}/stream") as ws:
        ws.send_json({"ping": payload})
        assert receive(ws) == {"type": "pong", "pong": payload}


def test_frames_give_results(client: TestClient) -> None:
    sid = create(client)
    with client.websocket_connect(f"/v1/sessions/{sid}/stream") as ws:
        for i in range(3):
            ws.send_bytes(disc_frame(160 + 2 * i, 120))
            out = receive(ws)
            assert out["type"] == "frame"
            assert out["frame_index"] == i
            assert out["version"] == i + 2
            assert out["dropped"] == 0
            assert len(out["nodes"]) == 64
            assert 0 <= out["confidence"] <= 1
            assert out["status"] == "tracking"  # a textured disc, followed closely
    centre = np.asarray(out["nodes"]).mean(axis=0)
    assert np.hypot(centre[0] - 164, centre[1] - 120) < 2
    session = client.get(f"/v1/sessions/{sid}").json()
    assert session["frame_index"] == 2
    assert session["nodes"] == out["nodes"]


def test_forces_over_the_stream(client: TestClient) -> None:
    nodes = [[0.0, 0.0], [10.0, 0.0], [20.0, 5.0], [30.0, 0.0]]
    sid = create(client, {"nodes": nodes, "closed": False, "stiffness": 2, "method": "dmma"})
    forces = [[1.0, 2.0], [0.0, -1.0], [3.0, 0.5], [-2.0, 0.0]]
    with client.websocket_connect(f"/v1/sessions/{sid}/stream") as ws:
        ws.send_json({"forces": forces})
        out = receive(ws)
    assert out["type"] == "forces"
    assert out["version"] == 2
    U = deform(forces, 2.0, closed=False, method="dmma")
    assert np.array_equal(np.asarray(out["displacements"]), U)
    assert np.array_equal(np.asarray(out["nodes"]), np.asarray(nodes) + U)


def assert_error(message: dict[str, Any], status: int) -> None:
    assert message["type"] == "error"
    assert message["error"]["status"] == status
    assert message["error"]["message"]


@pytest.mark.parametrize("mode", ["latest", "every"])
def test_an_unexpected_error_closes_the_stream_with_1011(
    client: TestClient, monkeypatch: pytest.MonkeyPatch, mode: str
) -> None:
    """A defect of the server's is said with the close code clients read as a 500, not by
    dropping the connection."""
    import service.routes.stream as stream

    async def broken(*_: object) -> None:
        raise RuntimeError("a defect")

    monkeypatch.setattr(stream, "track_encoded", broken)
    sid = create(client)
    with client.websocket_connect(f"/v1/sessions/{sid}/stream?mode={mode}") as ws:
        ws.send_bytes(disc_frame(160, 120))
        closed = closed_by(ws)
    assert closed.code == 1011
    assert client.get(f"/v1/sessions/{sid}").json()["frame_index"] == -1  # nothing committed


def test_errors_do_not_close_the_stream(client: TestClient) -> None:
    sid = create(client)
    with client.websocket_connect(f"/v1/sessions/{sid}/stream") as ws:
        ws.send_bytes(b"junk bytes, not an image")
        junk = receive(ws)
        assert_error(junk, 400)
        assert junk["dropped"] == 0
        ws.send_bytes(b"")
        assert_error(receive(ws), 400)
        ws.send_text("{not json")
        assert_error(receive(ws), 400)
        for text in ("[1, 2]", '"ping"', '{"pong": 1}', "null"):
            ws.send_text(text)
            assert_error(receive(ws), 422)
        ws.send_json({"forces": [[1, 0]] * 3})  # 64 nodes
        assert_error(receive(ws), 422)
        ws.send_json({"forces": "push"})
        assert_error(receive(ws), 422)
        for raw in ('{"forces": [[NaN, 0]]}', '{"forces": [[1e999, 0]]}'):
            ws.send_text(raw)
            assert_error(receive(ws), 422)
        ws.send_json({"ping": "still there"})
        assert receive(ws) == {"type": "pong", "pong": "still there"}
        ws.send_bytes(disc_frame(160, 120))
        out = receive(ws)
        assert (out["type"], out["frame_index"]) == ("frame", 0)


def test_frames_on_an_open_contour_are_errors_not_closures(client: TestClient) -> None:
    sid = create(client, {"nodes": [[0, 0], [50, 0], [50, 50]], "closed": False})
    with client.websocket_connect(f"/v1/sessions/{sid}/stream") as ws:
        ws.send_bytes(disc_frame(160, 120))
        assert_error(receive(ws), 422)
        ws.send_json({"ping": 1})
        assert receive(ws)["type"] == "pong"


def test_deeply_nested_json_is_an_error_not_a_crash(client: TestClient) -> None:
    sid = create(client)
    with client.websocket_connect(f"/v1/sessions/{sid}/stream") as ws:
        ws.send_text("[" * 100_000)
        assert_error(receive(ws), 400)
        ws.send_json({"ping": 1})
        assert receive(ws)["type"] == "pong"


def test_unknown_session_closes_with_4404(client: TestClient) -> None:
    with client.websocket_connect("/v1/sessions/no-such-session/stream") as ws:
        closed = closed_by(ws)
    assert closed.code == 4404
    assert "no such session" in closed.reason


def test_a_session_deleted_while_streaming_closes_with_4404(client: TestClient) -> None:
    sid = create(client)
    with client.websocket_connect(f"/v1/sessions/{sid}/stream") as ws:
        ws.send_json({"ping": 1})
        receive(ws)
        assert client.delete(f"/v1/sessions/{sid}").status_code == 204
        ws.send_bytes(disc_frame(160, 120))
        closed = closed_by(ws)
    assert closed.code == 4404
    assert "no such session" in closed.reason


def test_an_oversized_frame_closes_with_1009() -> None:
    settings = Settings(max_frame_bytes=64 * 1024)
    with TestClient(create_app(settings)) as client:
        sid = create(client)
        with client.websocket_connect(f"/v1/sessions/{sid}/stream") as ws:
            ws.send_bytes(b"\xff\xd8\xff" + bytes(64 * 1024))
            closed = closed_by(ws)
    assert closed.code == 1009
    assert closed.reason == "frame is 65,539 bytes; the limit is 65,536 bytes"


def test_pending_control_messages_are_bounded(client: TestClient) -> None:
    """Every ping gets a pong or a 429 error: the queue of waiting messages stays short."""
    sid = create(client, BIG_CIRCLE)
    frame = big_frame(1000, 1000)
    with client.websocket_connect(f"/v1/sessions/{sid}/stream") as ws:
        ws.send_bytes(frame)
        for i in range(60):
            ws.send_json({"ping": i})
        pongs: list[int] = []
        refused = frames = 0
        while len(pongs) + refused < 60 or frames < 1:
            message = receive(ws)
            if message["type"] == "pong":
                pongs.append(message["pong"])
            elif message["type"] == "frame":
                frames += 1
            else:
                assert_error(message, 429)
                assert message["error"]["code"] == "too_many_messages"
                refused += 1
    assert pongs == sorted(pongs)  # in order
    assert frames == 1


# -- latest frame wins (a real server) --------------------------------------------------------


def flood(server: LiveServer, sid: str, frames: list[bytes], count: int) -> list[dict[str, Any]]:
    """Send ``count`` frames at once; collect results until every frame is accounted for."""
    results: list[dict[str, Any]] = []
    with ws_connect(server, f"/v1/sessions/{sid}/stream") as ws:
        for i in range(count):
            ws.send(frames[i % len(frames)])
        accounted = 0
        while accounted < count:
            message = recv(ws)
            assert message["type"] == "frame", message
            results.append(message)
            accounted += 1 + message["dropped"]
            assert accounted <= count
    return results


def test_latest_frame_wins(live_server: LiveServer, big_frames: list[bytes]) -> None:
    sent = 25
    with httpx.Client(base_url=live_server.url, timeout=30) as http:
        sid = create(http, BIG_CIRCLE)
        shortfalls = []
        for _ in range(3):
            before = http.get(f"/v1/sessions/{sid}").json()["frame_index"]
            results = flood(live_server, sid, big_frames, sent)
            assert len(results) + sum(r["dropped"] for r in results) == sent
            indices = [r["frame_index"] for r in results]
            assert indices == list(range(before + 1, before + 1 + len(results)))
            assert http.get(f"/v1/sessions/{sid}").json()["frame_index"] == indices[-1]
            shortfalls.append(sent - len(results))
            if shortfalls[-1] > 0:
                break
    assert max(shortfalls) > 0, "no frame was ever dropped"


def test_the_event_loop_stays_responsive_while_a_stream_is_busy(
    live_server: LiveServer, big_frames: list[bytes]
) -> None:
    """/healthz answers many times while one stream tracks frame after frame."""
    count = 40
    done = [0]
    failure: list[BaseException] = []
    started = threading.Event()

    def stream(sid: str) -> None:
        try:
            with ws_connect(live_server, f"/v1/sessions/{sid}/stream") as ws:
                for i in range(count):
                    ws.send(big_frames[i % len(big_frames)])
                    assert recv(ws)["type"] == "frame"
                    done[0] += 1
                    started.set()
        except BaseException as exc:  # reported by the main thread
            failure.append(exc)
            started.set()

    with httpx.Client(base_url=live_server.url, timeout=30) as http:
        sid = create(http, BIG_CIRCLE)
        worker = threading.Thread(target=stream, args=(sid,), daemon=True)
        worker.start()
        assert started.wait(60)
        first = done[0]
        for _ in range(30):
            assert http.get("/healthz").json() == {"status": "ok"}
        during = done[0] - first
        worker.join(120)
    assert not failure, failure
    assert done[0] == count
    # a loop blocked by tracking answers about one request per frame tracked
    assert during <= 5, f"{during} frames went by while /healthz answered 30 times"


# -- API keys ---------------------------------------------------------------------------------


class TestWithApiKeys:
    @pytest.fixture
    def settings(self) -> Settings:
        return Settings(api_keys=("key-a", "key-b"), max_sessions=50)

    @pytest.fixture
    def sid(self, client: TestClient) -> str:
        return create(client, headers={"authorization": "Bearer key-a"})

    def test_a_missing_key_closes_with_4401(self, client: TestClient, sid: str) -> None:
        with client.websocket_connect(f"/v1/sessions/{sid}/stream") as ws:
            closed = closed_by(ws)
        assert closed.code == 4401
        assert "API key" in closed.reason

    def test_a_wrong_key_closes_with_4401(self, client: TestClient, sid: str) -> None:
        with client.websocket_connect(f"/v1/sessions/{sid}/stream?api_key=nope") as ws:
            assert closed_by(ws).code == 4401

    @pytest.mark.parametrize(
        ("query", "headers"),
        [("?api_key=key-a", {}), ("", {"authorization": "Bearer key-a"})],
        ids=["query", "header"],
    )
    def test_the_key_opens_the_stream(
        self, client: TestClient, sid: str, query: str, headers: dict[str, str]
    ) -> None:
        with client.websocket_connect(f"/v1/sessions/{sid}/stream{query}", headers=headers) as ws:
            ws.send_json({"ping": 1})
            assert receive(ws) == {"type": "pong", "pong": 1}
            ws.send_bytes(disc_frame(160, 120))
            assert receive(ws)["frame_index"] == 0

    def test_another_keys_session_closes_with_4404(self, client: TestClient, sid: str) -> None:
        with client.websocket_connect(f"/v1/sessions/{sid}/stream?api_key=key-b") as ws:
            closed = closed_by(ws)
        assert closed.code == 4404

    def test_live_server_rejects_missing_keys(self, live_server: LiveServer) -> None:
        with httpx.Client(base_url=live_server.url, timeout=30) as http:
            sid = create(http, headers={"authorization": "Bearer key-b"})
        with (
            ws_connect(live_server, f"/v1/sessions/{sid}/stream") as ws,
            pytest.raises(ConnectionClosed) as info,
        ):
            ws.recv(timeout=30)
        assert info.value.rcvd is not None
        assert info.value.rcvd.code == 4401
        with ws_connect(live_server, f"/v1/sessions/{sid}/stream?api_key=key-b") as ws:
            ws.send(json.dumps({"ping": "x"}))
            assert recv(ws) == {"type": "pong", "pong": "x"}


def test_mode_every_tracks_every_frame_in_order_pings_in_between(client: TestClient) -> None:
    """300 frames sent as fast as possible: 300 results, in order, none dropped."""
    sid = create(client)
    frames = [disc_frame(160 + (i % 20), 120) for i in range(300)]
    with client.websocket_connect(f"/v1/sessions/{sid}/stream?mode=every") as ws:
        for i, frame in enumerate(frames):
            ws.send_bytes(frame)
            if i == 149:
                ws.send_text(json.dumps({"ping": "half-way"}))
        answers = [receive(ws) for _ in range(301)]
    kinds = [a["type"] for a in answers]
    assert kinds.count("frame") == 300
    assert kinds.index("pong") == 150  # after the 150 frames sent before it
    results = [a for a in answers if a["type"] == "frame"]
    assert [r["frame_index"] for r in results] == list(range(300))
    assert all(r["dropped"] == 0 for r in results)
    assert client.get(f"/v1/sessions/{sid}").json()["frame_index"] == 299


def test_an_unknown_mode_closes_with_4422(client: TestClient) -> None:
    sid = create(client)
    with client.websocket_connect(f"/v1/sessions/{sid}/stream?mode=fastest") as ws:
        closed = closed_by(ws)
    assert closed.code == 4422
    assert "mode must be one of latest, every" in closed.reason


def test_a_second_stream_takes_the_session_over(client: TestClient) -> None:
    """The older stream is closed with 4409 at its next frame, having changed nothing."""
    sid = create(client)
    with client.websocket_connect(f"/v1/sessions/{sid}/stream") as first:
        first.send_bytes(disc_frame(160, 120))
        assert receive(first)["frame_index"] == 0
        with client.websocket_connect(f"/v1/sessions/{sid}/stream") as second:
            second.send_bytes(disc_frame(162, 120))
            assert receive(second)["frame_index"] == 1
            first.send_bytes(disc_frame(164, 120))
            closed = closed_by(first)
            assert closed.code == 4409
            assert "another stream took the session over" in closed.reason
            assert client.get(f"/v1/sessions/{sid}").json()["frame_index"] == 1  # unchanged
            second.send_bytes(disc_frame(164, 120))
            assert receive(second)["frame_index"] == 2  # the newer stream goes on
