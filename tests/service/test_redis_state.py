"""Redis holds a compact tracker state; the replica that wrote it goes on exactly.

Each committed frame writes the session's record: the tracker's compact state
(:meth:`engine.Tracker.to_state` with ``compact=True``, tens of kB at 480p)
instead of its exact one (hundreds).  The replica that committed a version
keeps the session exactly in memory and goes on from it, so a client served
by one replica tracks exactly as with the in-memory store; another replica
resumes from the compact record, closely.
"""

from __future__ import annotations

import secrets
from collections.abc import AsyncIterator

import numpy as np
import pytest
from numpy.typing import NDArray

from engine.geometry import circle_nodes, contour_to_mask, mask_iou
from service.redis_store import RedisStore
from service.schemas import SessionCreate
from service.sessions import Session
from tests.engine.scenes import DiscScene
from tests.service.conftest import RedisServer

pytestmark = pytest.mark.anyio

SCENE = DiscScene(width=640, height=480, radius=70.0, seed=5)
LIMIT = 64 * 1024
"""The aim per committed frame for a 128-node contour at 480p (JSON bytes)."""


@pytest.fixture
def anyio_backend() -> str:
    return "asyncio"


def centre(i: int) -> tuple[float, float]:
    return (220.0 + 6.0 * i, 200.0 + 4.0 * i)


def video(count: int) -> list[NDArray[np.uint8]]:
    return [SCENE.frame(centre(i)) for i in range(count)]


def new_session() -> Session:
    nodes = [tuple(p) for p in circle_nodes(centre(0), 70.0, 128).tolist()]
    # the chain's own contour (no cut snapping it to whole pixels): a lossy resume shows
    spec = SessionCreate(nodes=nodes, tracking={"cut_band": 0})
    return Session.create(spec, None, max_nodes=4096)


async def twins(store: RedisStore, count: int) -> tuple[list[NDArray[np.uint8]], Session, Session]:
    """``count`` frames, a session tracked alone (the in-memory reference) and its twin,
    added to ``store``."""
    alone, stored = new_session(), new_session()
    await store.add(stored)
    return video(count), alone, stored


@pytest.fixture
async def replicas(redis_server: RedisServer) -> AsyncIterator[tuple[RedisStore, RedisStore]]:
    """Two stores on one Redis under one prefix: two replicas of the service."""
    prefix = f"efdm-test-{secrets.token_hex(8)}"
    one, two = (
        RedisStore(redis_server.url, max_sessions=10, ttl=60.0, prefix=prefix) for _ in range(2)
    )
    yield one, two
    async for key in one.redis.scan_iter(match=f"{prefix}:*"):
        await one.redis.delete(key)
    await one.close()
    await two.close()


async def test_one_replica_tracks_exactly_as_in_memory_and_stores_little(
    replicas: tuple[RedisStore, RedisStore],
) -> None:
    store, _ = replicas
    frames, alone, stored = await twins(store, 8)
    for frame in frames:
        expected = alone.track(frame)["nodes"]
        async with store.lease(stored.id, None) as session:
            got = session.track(frame)["nodes"]
        assert got == expected  # bit for bit: the exact copy, not the compact record
    record = await store.redis.hget(store._key(stored.id), "d")
    assert record is not None
    assert len(record) <= LIMIT


async def test_another_replica_resumes_from_the_compact_record_closely(
    replicas: tuple[RedisStore, RedisStore],
) -> None:
    one, two = replicas
    frames = video(12)
    alone = new_session()
    stored = new_session()
    await one.add(stored)
    for frame in frames[:6]:
        alone.track(frame)
        async with one.lease(stored.id, None) as session:
            session.track(frame)
    for i, frame in enumerate(frames[6:], start=6):
        expected = np.asarray(alone.track(frame)["nodes"])
        async with two.lease(stored.id, None) as session:
            got = np.asarray(session.track(frame)["nodes"])
        mine = contour_to_mask(got, SCENE.shape)
        assert mask_iou(mine, contour_to_mask(expected, SCENE.shape)) > 0.95
        assert mask_iou(mine, SCENE.mask(centre(i))) > 0.9


async def test_a_version_written_elsewhere_is_never_served_from_the_exact_copy(
    replicas: tuple[RedisStore, RedisStore],
) -> None:
    one, two = replicas
    frames = video(3)
    stored = new_session()
    await one.add(stored)
    async with one.lease(stored.id, None) as session:
        session.track(frames[0])
    async with two.lease(stored.id, None) as session:  # the other replica moves it on
        session.track(frames[1])
        moved_on = session.version
    async with one.lease(stored.id, None) as session:  # stale copy here: Redis's wins
        assert session.version == moved_on
        assert session.frame_index == 1


async def test_the_exact_copies_are_bounded(redis_server: RedisServer) -> None:
    prefix = f"efdm-test-{secrets.token_hex(8)}"
    store = RedisStore(redis_server.url, max_sessions=10, ttl=60.0, prefix=prefix, exact_cache=2)
    try:
        for _ in range(4):
            await store.add(new_session())
        assert len(store._exact) == 2
    finally:
        async for key in store.redis.scan_iter(match=f"{prefix}:*"):
            await store.redis.delete(key)
        await store.close()


async def test_a_stream_leaves_the_exact_copy_to_the_next_request(
    replicas: tuple[RedisStore, RedisStore],
) -> None:
    """Frames streamed, then sent one by one on the same replica: exact throughout."""
    store, _ = replicas
    frames, alone, stored = await twins(store, 8)
    async with store.stream(stored.id, None) as held:
        for frame in frames[:4]:
            expected = alone.track(frame)["nodes"]
            async with held.turn() as session:
                assert session.track(frame)["nodes"] == expected
    for frame in frames[4:]:
        expected = alone.track(frame)["nodes"]
        async with store.lease(stored.id, None) as session:
            assert session.track(frame)["nodes"] == expected  # not the compact record's


async def test_a_refused_request_keeps_the_exact_copy(
    replicas: tuple[RedisStore, RedisStore],
) -> None:
    """A request that fails changes nothing: neither the session nor how exactly it goes on."""
    store, _ = replicas
    frames, alone, stored = await twins(store, 6)
    for i, frame in enumerate(frames):
        expected = alone.track(frame)["nodes"]
        if i == 3:
            with pytest.raises(ValueError, match="refused"):
                async with store.lease(stored.id, None):
                    raise ValueError("refused")  # as a frame that cannot be decoded
        async with store.lease(stored.id, None) as session:
            assert session.track(frame)["nodes"] == expected


async def test_a_request_during_a_stream_on_its_replica_is_the_streams_next_state(
    replicas: tuple[RedisStore, RedisStore],
) -> None:
    """Forces sent by REST while a stream of the same replica is open: the stream's next
    frame goes on from them, as with the in-memory store, not a 409."""
    store, _ = replicas
    frames, alone, stored = await twins(store, 4)
    push = [(0.5, -0.25)] * 128
    async with store.stream(stored.id, None, commit_every=2) as held:
        alone.track(frames[0])
        async with held.turn() as session:
            session.track(frames[0])
        alone.apply_forces(push)
        async with store.lease(stored.id, None) as session:
            session.apply_forces(push)
        for frame in frames[1:]:
            expected = alone.track(frame)["nodes"]
            async with held.turn() as session:
                assert session.track(frame)["nodes"] == expected
    async with store.lease(stored.id, None) as session:
        assert session.version == alone.version
        assert session.nodes.tolist() == alone.nodes.tolist()
