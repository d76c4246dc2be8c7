"""The session store contract, run against every store implementation.

Each store kind is a :class:`StoreKind` in :data:`STORES`; a new kind gets every check.
The Redis kind runs against a throwaway ``redis-server`` the tests start on a free
loopback port (keys under a random prefix, removed afterwards).
"""

from __future__ import annotations

import asyncio
import secrets
import time
from collections.abc import AsyncIterator
from dataclasses import dataclass, field

import pytest

from service.domain_errors import ServiceError, SessionNotFoundError, TooManySessionsError
from service.errors import as_api_error
from service.schemas import SessionCreate
from service.sessions import Session
from service.store import MemoryStore, SessionStore

pytestmark = pytest.mark.anyio


class StoreKind:
    """Makes stores of one implementation, and cleans up after them."""

    def make(self, max_sessions: int, ttl: float) -> SessionStore:
        raise NotImplementedError

    async def cleanup(self, store: SessionStore) -> None:
        await store.close()


class Memory(StoreKind):
    def make(self, max_sessions: int, ttl: float) -> SessionStore:
        return MemoryStore(max_sessions=max_sessions, ttl=ttl)


class Redis(StoreKind):
    url = ""  # set from the redis_server fixture

    def make(self, max_sessions: int, ttl: float) -> SessionStore:
        from service.redis_store import RedisStore

        prefix = f"efdm-test-{secrets.token_hex(8)}"
        return RedisStore(self.url, max_sessions=max_sessions, ttl=ttl, prefix=prefix)

    async def cleanup(self, store: SessionStore) -> None:
        from service.redis_store import RedisStore

        assert isinstance(store, RedisStore)
        async for key in store.redis.scan_iter(match=f"{store.prefix}:*"):
            await store.redis.delete(key)
        await store.close()


STORES = [
    pytest.param(Memory(), id="memory"),
    pytest.param(Redis(), id="redis"),
]


@pytest.fixture
def anyio_backend() -> str:
    return "asyncio"


@dataclass
class Stores:
    """Makes stores of one kind for a test; cleans them up after it."""

    kind: StoreKind
    made: list[SessionStore] = field(default_factory=list)

    def __call__(self, max_sessions: int = 10, ttl: float = 60.0) -> SessionStore:
        store = self.kind.make(max_sessions, ttl)
        self.made.append(store)
        return store


@pytest.fixture(params=STORES)
async def make_store(request: pytest.FixtureRequest) -> AsyncIterator[Stores]:
    if isinstance(request.param, Redis):
        request.param.url = request.getfixturevalue("redis_server").url
    stores = Stores(request.param)
    yield stores
    for store in stores.made:
        await stores.kind.cleanup(store)


def session(owner: str | None = None) -> Session:
    spec = SessionCreate(nodes=[(0.0, 0.0), (10.0, 0.0), (10.0, 10.0), (0.0, 10.0)])
    return Session.create(spec, owner, max_nodes=100)


async def status_of_lease(store: SessionStore, sid: str, owner: str | None) -> int:
    try:
        async with store.lease(sid, owner):
            return 200
    except ServiceError as exc:
        return as_api_error(exc).status


async def test_add_then_lease_gives_the_session(make_store: Stores) -> None:
    store = make_store()
    s = session()
    await store.add(s)
    assert await store.count() == 1
    async with store.lease(s.id, None) as leased:
        assert leased.id == s.id
        assert leased.nodes.tolist() == s.nodes.tolist()


async def test_changes_made_under_a_lease_are_kept(make_store: Stores) -> None:
    store = make_store()
    s = session()
    await store.add(s)
    async with store.lease(s.id, None) as leased:
        leased.apply_forces([(1.0, 0.0)] * 4)
        version = leased.version
    async with store.lease(s.id, None) as again:
        assert again.version == version == 2
        assert again.nodes[:, 0].tolist() == pytest.approx((s.rest[:, 0] + 1.0).tolist())


async def test_unknown_sessions_are_not_found(make_store: Stores) -> None:
    store = make_store()
    assert await status_of_lease(store, "nope", None) == 404
    with pytest.raises(SessionNotFoundError):
        await store.delete("nope", None)


async def test_owner_isolation(make_store: Stores) -> None:
    store = make_store()
    mine, anonymous = session("alice"), session(None)
    await store.add(mine)
    await store.add(anonymous)
    assert await status_of_lease(store, mine.id, "alice") == 200
    assert await status_of_lease(store, mine.id, "bob") == 404
    assert await status_of_lease(store, mine.id, None) == 404
    assert await status_of_lease(store, anonymous.id, "alice") == 404
    with pytest.raises(SessionNotFoundError):
        await store.delete(mine.id, "bob")
    assert await store.count() == 2
    assert await status_of_lease(store, mine.id, "alice") == 200


async def test_owned_lists_an_owners_live_sessions_in_pages(make_store: Stores) -> None:
    store = make_store(ttl=1.0)
    alice = [session("alice") for _ in range(5)]
    for s in [*alice, session("bob"), session(None)]:
        s.touched = time.time()  # made now, not when its tracker was built
        await store.add(s)
    ids = sorted(s.id for s in alice)
    listed = await store.owned("alice", "", 10)
    assert [s.id for s in listed] == ids
    assert all((s.frame_index, s.version) == (-1, 1) for s in listed)
    # pages: ids after the last one seen
    first = await store.owned("alice", "", 2)
    rest = await store.owned("alice", first[-1].id, 10)
    assert [s.id for s in first + rest] == ids
    assert [s.id for s in await store.owned("bob", "", 10)] != ids
    assert len(await store.owned(None, "", 10)) == 1  # anonymous ones are their own owner's
    # a change shows, a deleted or expired session does not
    async with store.lease(ids[0], "alice") as leased:
        leased.apply_forces([(1.0, 0.0)] * 4)
    await store.delete(ids[1], "alice")
    listed = await store.owned("alice", "", 10)
    assert [s.id for s in listed] == [ids[0], *ids[2:]]
    assert listed[0].version == 2
    await asyncio.sleep(0.5)
    async with store.lease(ids[2], "alice"):  # keeps this one alive
        pass
    await asyncio.sleep(0.7)
    assert [s.id for s in await store.owned("alice", "", 10)] == [ids[2]]


async def test_delete(make_store: Stores) -> None:
    store = make_store()
    s = session("alice")
    await store.add(s)
    await store.delete(s.id, "alice")
    assert await store.count() == 0
    assert await status_of_lease(store, s.id, "alice") == 404
    with pytest.raises(SessionNotFoundError):
        await store.delete(s.id, "alice")


async def test_capacity(make_store: Stores) -> None:
    store = make_store(max_sessions=2)
    first, second = session(), session()
    await store.add(first)
    await store.add(second)
    with pytest.raises(TooManySessionsError) as info:
        await store.add(session())
    assert info.value.limit == 2
    assert info.value.retry_after > 0
    assert await store.count() == 2
    await store.delete(first.id, None)
    await store.add(session())
    assert await store.count() == 2


async def test_expired_sessions_free_their_place_when_full(make_store: Stores) -> None:
    store = make_store(max_sessions=1, ttl=0.05)
    await store.add(session())
    await asyncio.sleep(0.15)
    await store.add(session())  # the expired one makes room
    assert await store.count() == 1


async def test_idle_sessions_expire(make_store: Stores) -> None:
    store = make_store(ttl=0.05)
    s = session()
    await store.add(s)
    await asyncio.sleep(0.15)
    assert await status_of_lease(store, s.id, None) == 404


async def test_sweep_drops_expired_sessions_and_counts_them(make_store: Stores) -> None:
    store = make_store(ttl=0.3)
    for _ in range(3):
        await store.add(session())
    assert await store.sweep() == 0
    assert await store.count() == 3
    await asyncio.sleep(0.5)
    assert await store.sweep() == 3
    assert await store.count() == 0
    fresh = session()
    await store.add(fresh)
    assert await store.sweep() == 0
    assert await status_of_lease(store, fresh.id, None) == 200


async def test_using_a_session_keeps_it_alive(make_store: Stores) -> None:
    store = make_store(ttl=0.5)
    s = session()
    await store.add(s)
    for _ in range(8):  # 0.8 s in all, longer than the ttl
        await asyncio.sleep(0.1)
        assert await status_of_lease(store, s.id, None) == 200
    assert await store.sweep() == 0


async def test_leases_of_one_session_are_exclusive(make_store: Stores) -> None:
    store = make_store()
    s = session()
    await store.add(s)
    events: list[str] = []

    async def use(name: str) -> None:
        async with store.lease(s.id, None) as leased:
            events.append(f"{name} in")
            before = leased.version
            await asyncio.sleep(0.02)
            leased.version = before + 1  # a read-modify-write that would race without the lease
            events.append(f"{name} out")

    await asyncio.gather(*(use(name) for name in "abcd"))
    assert len(events) == 8
    for i in range(0, 8, 2):  # each "in" is followed by its own "out"
        assert events[i].split()[0] == events[i + 1].split()[0]
        assert (events[i].split()[1], events[i + 1].split()[1]) == ("in", "out")
    async with store.lease(s.id, None) as leased:
        assert leased.version == 5


async def test_leases_of_different_sessions_overlap(make_store: Stores) -> None:
    store = make_store()
    one, two = session(), session()
    await store.add(one)
    await store.add(two)
    inside = 0
    most = 0

    async def use(sid: str) -> None:
        nonlocal inside, most
        async with store.lease(sid, None):
            inside += 1
            most = max(most, inside)
            await asyncio.sleep(0.05)
            inside -= 1

    await asyncio.gather(use(one.id), use(two.id))
    assert most == 2


async def test_a_waiter_finds_the_session_deleted_under_it(make_store: Stores) -> None:
    store = make_store()
    s = session()
    await store.add(s)
    entered = asyncio.Event()
    holder_saw: list[int] = []

    async def holder() -> None:
        try:
            async with store.lease(s.id, None):
                entered.set()
                await asyncio.sleep(0.1)
        except ServiceError as exc:  # a store may tell the holder its session is gone
            holder_saw.append(as_api_error(exc).status)

    task = asyncio.create_task(holder())
    await entered.wait()
    waiter = asyncio.create_task(status_of_lease(store, s.id, None))
    await asyncio.sleep(0.02)  # the waiter queues behind the holder
    await store.delete(s.id, None)
    assert await waiter == 404
    await task
    assert holder_saw in ([], [404])
    assert await store.count() == 0
    assert await status_of_lease(store, s.id, None) == 404


async def test_an_error_inside_a_lease_releases_it(make_store: Stores) -> None:
    store = make_store()
    s = session()
    await store.add(s)
    with pytest.raises(RuntimeError):
        async with store.lease(s.id, None):
            raise RuntimeError("boom")
    async with asyncio.timeout(5):
        assert await status_of_lease(store, s.id, None) == 200


async def test_ping_and_close(make_store: Stores) -> None:
    store = make_store()
    assert await store.ping() is True
    await store.add(session())
    await store.close()


# -- the in-memory store's own guarantees -----------------------------------------------------


@pytest.mark.anyio
async def test_memory_sweep_spares_a_session_in_use() -> None:
    """A lease longer than the idle time does not lose the session to the sweeper."""
    store = MemoryStore(max_sessions=10, ttl=0.05)
    s = session()
    await store.add(s)
    async with store.lease(s.id, None):
        await asyncio.sleep(0.15)
        assert await store.sweep() == 0
    assert await store.count() == 1
    await store.close()


async def test_a_session_with_its_own_shorter_ttl_expires_first(make_store: Stores) -> None:
    store = make_store(ttl=30.0)
    short = Session.create(
        SessionCreate(nodes=[(0.0, 0.0), (10.0, 0.0), (10.0, 10.0)], ttl_seconds=0.3), None, 100
    )
    long = session()
    for s in (short, long):
        s.touched = time.time()
        await store.add(s)
    assert {s.ttl for s in await store.owned(None, "", 10)} == {0.3, None}
    await asyncio.sleep(0.6)
    assert await status_of_lease(store, short.id, None) == 404
    assert await status_of_lease(store, long.id, None) == 200
