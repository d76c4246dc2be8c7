"""The Python client against a real server: REST, WebSocket, asyncio, errors."""

from __future__ import annotations

import contextlib
import json
from collections.abc import AsyncIterator, Iterator
from datetime import UTC, datetime

import cv2
import numpy as np
import pytest

from service.client import (
    ApiError,
    AsyncClient,
    Client,
    ForcesResult,
    FrameResult,
    ImageEncoder,
    Session,
    _common,
)
from service.settings import Settings
from tests.service.conftest import LiveServer, _serve, disc_frame

CIRCLE = ((160.0, 120.0), 40.0, 32)
PATH = [(160.0, 120.0), (164.0, 121.0), (168.0, 123.0), (171.0, 126.0)]


def frames() -> list[bytes]:
    return [disc_frame(x, y) for x, y in PATH]


def centroid(nodes: np.ndarray) -> np.ndarray:
    return np.asarray(nodes.mean(axis=0))


@pytest.fixture
def anyio_backend() -> str:
    return "asyncio"


@pytest.fixture
def api(live_server: LiveServer) -> Iterator[Client]:
    with Client(live_server.url, timeout=30) as client:
        yield client


@pytest.fixture
def keyed_server() -> Iterator[LiveServer]:
    """A server that requires one of two API keys."""
    yield from _serve(Settings(api_keys=("k1", "k2"), max_sessions=10))


@pytest.fixture
def one_session_server() -> Iterator[LiveServer]:
    """A server that holds at most one session (leaks show up as 429)."""
    yield from _serve(Settings(max_sessions=1))


# --- sessions and forces -------------------------------------------------------------


def test_create_get_delete(api: Client) -> None:
    session = api.create_session(circle=CIRCLE, stiffness=20.0, method="efdm")
    assert isinstance(session, Session)
    assert session.nodes.shape == (32, 2)
    assert session.nodes.dtype == np.float64
    assert not session.nodes.flags.writeable
    assert np.allclose(centroid(session.nodes), [160, 120])
    assert (session.closed, session.stiffness, session.method) == (True, 20.0, "efdm")
    assert (session.frame_index, session.version) == (-1, 1)
    assert session.expires_at.tzinfo is not None
    assert session.expires_at > datetime.now(UTC)

    again = api.get_session(session.id)
    assert again.id == session.id
    assert np.array_equal(again.nodes, session.nodes)
    assert api.get_session(session).version == 1  # a Session works as well as its id

    api.delete_session(session)
    with pytest.raises(ApiError) as caught:
        api.get_session(session.id)
    assert (caught.value.status, caught.value.code) == (404, "not_found")


def test_create_from_nodes_open_chain(api: Client) -> None:
    nodes = np.array([[10.0, 10.0], [20.0, 10.0], [30.0, 12.0]])
    session = api.create_session(nodes, closed=False, tracking={})
    assert not session.closed
    assert np.array_equal(session.nodes, nodes)
    with pytest.raises(ValueError, match="exactly one"):
        api.create_session(nodes, circle=CIRCLE)
    with pytest.raises(ValueError, match=r"\(N, 2\)"):
        api.create_session([1.0, 2.0, 3.0])


def test_forces(api: Client) -> None:
    session = api.create_session(circle=((100.0, 100.0), 30.0, 16))
    outward = (session.nodes - [100.0, 100.0]) / 30.0 * 5.0
    result = api.apply_forces(session.id, outward)
    assert isinstance(result, ForcesResult)
    assert result.version == 2
    assert result.displacements.shape == (16, 2)
    assert np.allclose(result.nodes, session.nodes + result.displacements)
    radii = np.linalg.norm(result.nodes - [100.0, 100.0], axis=1)
    assert np.all(radii > 30.0)  # the ring grew
    assert np.array_equal(api.get_session(session).nodes, result.nodes)


# --- tracking --------------------------------------------------------------------------


def test_rest_tracking_follows_the_disc(api: Client) -> None:
    results = list(api.track(frames(), circle=CIRCLE))
    assert [r.frame_index for r in results] == [0, 1, 2, 3]
    for (x, y), result in zip(PATH, results, strict=True):
        assert isinstance(result, FrameResult)
        assert result.dropped == 0
        assert np.linalg.norm(centroid(result.nodes) - [x, y]) < 2


def test_track_deletes_its_session(one_session_server: LiveServer) -> None:
    with Client(one_session_server.url) as client:
        for _ in range(2):  # the second run needs the first's session gone
            assert len(list(client.track(frames()[:1], circle=CIRCLE))) == 1
        client.delete_session(client.create_session(circle=CIRCLE))
        with contextlib.closing(client.track(frames(), circle=CIRCLE)) as early:
            next(early)  # stopped early: closing the iterator deletes too
        client.create_session(circle=CIRCLE)
        with pytest.raises(ApiError) as caught:
            client.create_session(circle=CIRCLE)
        assert caught.value.status == 429
        assert caught.value.retry_after == 10


def test_array_frames_are_encoded(api: Client) -> None:
    first, image = (
        np.asarray(cv2.imdecode(np.frombuffer(disc_frame(x, y), np.uint8), cv2.IMREAD_COLOR))
        for x, y in PATH[:2]
    )
    session = api.create_session(circle=CIRCLE)
    assert api.track_frame(session, first).frame_index == 0  # learns the disc's colour
    moved = api.track_frame(session, image)
    assert np.linalg.norm(centroid(moved.nodes) - PATH[1]) < 2
    grey = cv2.cvtColor(image, cv2.COLOR_BGR2GRAY)
    assert api.track_frame(session, grey).frame_index == 2
    with Client(api.base_url, encoder=ImageEncoder("png")) as png:
        assert png.track_frame(session, image).frame_index == 3
    with pytest.raises(TypeError, match="uint8"):
        api.track_frame(session, image.astype(np.float32))
    with pytest.raises(ValueError, match="quality"):
        ImageEncoder(quality=0)


def test_stream_matches_rest_exactly(api: Client) -> None:
    data = frames()
    rest = api.create_session(circle=CIRCLE)
    ws = api.create_session(circle=CIRCLE)
    by_rest = [api.track_frame(rest, frame) for frame in data]
    by_ws = list(api.stream(ws, data))
    assert [r.frame_index for r in by_ws] == [0, 1, 2, 3]
    assert all(r.dropped == 0 for r in by_ws)
    for a, b in zip(by_rest, by_ws, strict=True):
        assert np.array_equal(a.nodes, b.nodes)
        assert (a.iterations, a.converged, a.version) == (b.iterations, b.converged, b.version)
    assert np.array_equal(api.get_session(ws).nodes, by_rest[-1].nodes)


def test_stream_realtime_accounts_for_every_frame(api: Client) -> None:
    session = api.create_session(circle=CIRCLE)
    data = frames() * 2
    results = list(api.stream(session, data, max_in_flight=8))
    assert sum(1 + r.dropped for r in results) == len(data)
    assert results[-1].frame_index == len(results) - 1
    with pytest.raises(ValueError, match="max_in_flight"):
        list(api.stream(session, data, max_in_flight=0))


def test_stream_every_mode_pipelines_without_dropping(api: Client) -> None:
    """A file, not a camera: every frame tracked, in order, however many are in flight."""
    data = frames() * 3
    reference = list(api.track(data, circle=CIRCLE))  # REST: one at a time
    session = api.create_session(circle=CIRCLE)
    results = list(api.stream(session, data, max_in_flight=16, mode="every"))
    assert [r.frame_index for r in results] == list(range(len(data)))
    assert all(r.dropped == 0 for r in results)
    for a, b in zip(reference, results, strict=True):
        assert np.array_equal(a.nodes, b.nodes)
    with pytest.raises(ValueError, match="mode must be one of latest, every"):
        list(api.stream(session, data, mode="fastest"))


# --- asyncio ---------------------------------------------------------------------------


async def _aframes() -> AsyncIterator[bytes]:
    for frame in frames():
        yield frame


@pytest.mark.anyio
async def test_async_client_matches_sync(live_server: LiveServer) -> None:
    data = frames()
    with Client(live_server.url) as sync:
        reference = list(sync.track(data, circle=CIRCLE))
    async with AsyncClient(live_server.url) as api:
        session = await api.create_session(circle=CIRCLE)
        assert (await api.get_session(session.id)).version == 1
        by_rest = [await api.track_frame(session, frame) for frame in data]
        streamed = await api.create_session(circle=CIRCLE)
        by_ws = [r async for r in api.stream(streamed, _aframes())]
        tracked = [r async for r in api.track(data, circle=CIRCLE)]
        for results in (by_rest, by_ws, tracked):
            assert len(results) == len(reference)
            for a, b in zip(reference, results, strict=True):
                assert np.array_equal(a.nodes, b.nodes)
        forces = await api.apply_forces(session, np.zeros((32, 2)))
        assert np.array_equal(forces.nodes, by_rest[-1].nodes)
        await api.delete_session(session)
        with pytest.raises(ApiError) as caught:
            await api.get_session(session)
        assert caught.value.status == 404


@pytest.mark.anyio
async def test_async_stream_realtime_and_errors(live_server: LiveServer) -> None:
    async with AsyncClient(live_server.url) as api:
        session = await api.create_session(circle=CIRCLE)
        data = frames() * 2
        results = [r async for r in api.stream(session, data, max_in_flight=8)]
        assert sum(1 + r.dropped for r in results) == len(data)
        every = [r async for r in api.stream(session, data, max_in_flight=8, mode="every")]
        assert len(every) == len(data)
        assert all(r.dropped == 0 for r in every)
        with pytest.raises(ApiError) as caught:
            async for _ in api.stream("no-such-session", frames()[:1]):
                pass
        assert (caught.value.status, caught.value.code) == (404, "not_found")
        with pytest.raises(ApiError) as caught:
            async for _ in api.stream(session, [b"not an image"]):
                pass
        assert (caught.value.status, caught.value.code) == (400, "bad_image")
        with pytest.raises(ApiError) as caught:
            await api.apply_forces(session, np.zeros((3, 2)))
        assert caught.value.status == 422


# --- errors ----------------------------------------------------------------------------


def test_unknown_session_is_404(api: Client) -> None:
    for call in (
        lambda: api.get_session("nope"),
        lambda: api.delete_session("nope"),
        lambda: api.apply_forces("nope", np.zeros((3, 2))),
        lambda: api.track_frame("nope", disc_frame(160, 120)),
        lambda: list(api.stream("nope", frames()[:1])),
    ):
        with pytest.raises(ApiError) as caught:
            call()
        assert (caught.value.status, caught.value.code) == (404, "not_found")


def test_wrong_number_of_forces_is_422(api: Client) -> None:
    session = api.create_session(circle=CIRCLE)
    with pytest.raises(ApiError) as caught:
        api.apply_forces(session, np.zeros((5, 2)))
    assert (caught.value.status, caught.value.code) == (422, "invalid")
    assert "32 forces" in caught.value.message


def test_bad_frame_on_stream_raises(api: Client) -> None:
    session = api.create_session(circle=CIRCLE)
    with pytest.raises(ApiError) as caught:
        list(api.stream(session, [disc_frame(160, 120), b"not an image"]))
    assert (caught.value.status, caught.value.code) == (400, "bad_image")
    assert api.get_session(session).frame_index == 0  # the good frame counted, not the bad


def test_urls_and_error_bodies_without_a_server() -> None:
    assert _common.stream_url("https://h.example/efdm/", "a/b") == (
        "wss://h.example/efdm/v1/sessions/a%2Fb/stream"
    )
    assert _common.stream_url("http://127.0.0.1:8000", "s") == (
        "ws://127.0.0.1:8000/v1/sessions/s/stream"
    )
    proxy = _common.error_from_body(502, b"<html>Bad Gateway</html>", "Bad Gateway", "5")
    assert (proxy.status, proxy.code, proxy.retry_after) == (502, "http_error", 5.0)
    assert "Bad Gateway" in proxy.message
    body = {"error": {"status": 422, "code": "invalid", "message": "m", "details": [{"loc": []}]}}
    invalid = _common.error_from_body(422, json.dumps(body).encode())
    assert (invalid.code, invalid.message, invalid.details) == ("invalid", "m", ({"loc": []},))
    assert str(invalid) == "422 invalid: m"


def test_if_match(api: Client) -> None:
    session = api.create_session(circle=CIRCLE)
    zero = np.zeros((32, 2))
    assert api.apply_forces(session, zero, if_match=session.version).version == 2
    assert api.apply_forces(session, zero, if_match='"2"').version == 3
    for call in (
        lambda: api.apply_forces(session, zero, if_match=1),
        lambda: api.track_frame(session, disc_frame(160, 120), if_match=2),
    ):
        with pytest.raises(ApiError) as caught:
            call()
        assert (caught.value.status, caught.value.code) == (412, "version_mismatch")
    assert api.track_frame(session, disc_frame(160, 120), if_match=3).version == 4


def test_api_keys(keyed_server: LiveServer) -> None:
    url = keyed_server.url
    for key in (None, "wrong"):
        with Client(url, api_key=key) as anonymous:
            with pytest.raises(ApiError) as caught:
                anonymous.create_session(circle=CIRCLE)
            assert (caught.value.status, caught.value.code) == (401, "unauthorized")
            with pytest.raises(ApiError) as caught:
                list(anonymous.stream("any", frames()[:1]))
            assert caught.value.status == 401
    with Client(url, api_key="k1") as first, Client(url, api_key="k2") as second:
        session = first.create_session(circle=CIRCLE)
        assert [r.frame_index for r in first.stream(session, frames()[:2])] == [0, 1]
        for call in (
            lambda: second.get_session(session),
            lambda: second.track_frame(session, disc_frame(160, 120)),
            lambda: list(second.stream(session, frames()[:1])),
        ):
            with pytest.raises(ApiError) as caught:
                call()
            assert caught.value.status == 404
        first.delete_session(session)
