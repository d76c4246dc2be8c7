"""service.memory: the heap is trimmed once sessions end, and only then."""

from __future__ import annotations

import asyncio
import sys
import time

import pytest
from fastapi.testclient import TestClient

from service.app import create_app
from service.memory import MemoryReleaser, malloc_trim
from service.settings import Settings
from tests.service.conftest import disc_frame

SOON = 0.01  # seconds before a trim in these tests


class Counter:
    def __init__(self) -> None:
        self.calls = 0

    def __call__(self) -> None:
        self.calls += 1


async def settle(task: asyncio.Task[None]) -> None:
    await asyncio.sleep(10 * SOON + 0.05)
    task.cancel()


def test_sessions_ending_in_a_burst_are_trimmed_for_once() -> None:
    counter = Counter()

    async def scenario() -> None:
        releaser = MemoryReleaser(counter, after=SOON)
        task = asyncio.create_task(releaser.run())
        for _ in range(50):
            releaser.freed()
        await settle(task)

    asyncio.run(scenario())
    assert counter.calls == 1


def test_nothing_is_trimmed_while_no_session_ends() -> None:
    counter = Counter()

    async def scenario() -> None:
        releaser = MemoryReleaser(counter, after=SOON)
        await settle(asyncio.create_task(releaser.run()))

    asyncio.run(scenario())
    assert counter.calls == 0


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="glibc's malloc_trim: Linux")
def test_on_linux_the_c_library_trims() -> None:
    trim = malloc_trim()
    assert trim is not None
    assert trim() in (0, 1)  # 1: memory was released, 0: there was none to release


def test_deleting_a_session_trims_the_servers_heap() -> None:
    counter = Counter()
    app = create_app(Settings())
    app.state.memory = MemoryReleaser(counter, after=SOON)
    with TestClient(app) as client:
        sid = client.post("/v1/sessions", json={"circle": {"center": [160, 120], "radius": 40}})
        session = sid.json()["id"]
        frame = client.post(
            f"/v1/sessions/{session}/frames",
            content=disc_frame(160, 120),
            headers={"content-type": "image/jpeg"},
        )
        assert frame.status_code == 200
        assert counter.calls == 0
        assert client.delete(f"/v1/sessions/{session}").status_code == 204
        deadline = time.monotonic() + 5.0  # the trim runs in the background, after SOON
        while counter.calls == 0 and time.monotonic() < deadline:
            time.sleep(0.01)
    assert counter.calls == 1
