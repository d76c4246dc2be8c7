"""The FastAPI application: ``create_app(settings)``."""

from __future__ import annotations

import asyncio
import contextlib
import gc
import logging
import os
from collections.abc import AsyncIterator
from pathlib import Path

import anyio.to_thread
from anyio import CapacityLimiter
from fastapi import FastAPI
from fastapi.responses import FileResponse
from fastapi.staticfiles import StaticFiles

import engine
from service import docs_pages, errors
from service.limits import BodyLimit
from service.memory import MemoryReleaser
from service.routes import health, sessions, stream
from service.settings import Settings
from service.shutdown import StreamRegistry
from service.store import MemoryStore, SessionStore

STATIC = Path(__file__).parent / "static"
log = logging.getLogger("efdm.service")


def make_store(settings: Settings) -> SessionStore:
    """The session store the settings ask for: in memory, or Redis with ``EFDM_REDIS_URL``."""
    if settings.redis_url:
        from service.redis_store import RedisStore

        return RedisStore(
            settings.redis_url,
            max_sessions=settings.max_sessions,
            ttl=settings.session_ttl_seconds,
            exact_cache=settings.redis_exact_cache,
        )
    return MemoryStore(max_sessions=settings.max_sessions, ttl=settings.session_ttl_seconds)


async def _sweep(store: SessionStore, every: float, memory: MemoryReleaser) -> None:
    while True:
        await asyncio.sleep(every)
        with contextlib.suppress(Exception):
            if await store.sweep():
                memory.freed()


def create_app(settings: Settings | None = None, store: SessionStore | None = None) -> FastAPI:
    """Build the service.

    Parameters
    ----------
    settings : Settings, optional
        Defaults to the environment (``EFDM_*`` variables).
    store : SessionStore, optional
        Defaults to :func:`make_store`.
    """
    settings = settings or Settings()

    @contextlib.asynccontextmanager
    async def lifespan(app: FastAPI) -> AsyncIterator[None]:
        app.state.cpu = CapacityLimiter(settings.workers or os.cpu_count() or 1)
        await anyio.to_thread.run_sync(engine.warm_up)  # compile before the first request
        gc.collect()
        gc.freeze()  # start-up objects out of the collector's way: no long gen-2 pauses
        every = min(60.0, settings.session_ttl_seconds / 4)
        sweeper = asyncio.create_task(_sweep(app.state.store, every, app.state.memory))
        trimmer = asyncio.create_task(app.state.memory.run())
        try:
            yield
        finally:
            # graceful shutdown (service/shutdown.py): streams uvicorn left open end with 1001
            await app.state.streams.close_all()
            sweeper.cancel()
            trimmer.cancel()
            await app.state.store.close()

    app = FastAPI(
        title="efdm-tracker",
        version=engine.__version__,
        summary="Real-time contour tracking with explicit physics-based deformable models",
        description=(
            "Sessions hold a deformable contour (Krinidis & Pitas). Send forces for the "
            "equilibrium contour, or frames (REST or WebSocket) to track an object's boundary. "
            "Coordinates are [x, y] pixels (x = column, y = row), as in OpenCV."
        ),
        lifespan=lifespan,
        docs_url=None,  # served from the package instead (service.docs_pages): no CDN
        redoc_url=None,
        swagger_ui_parameters={"validatorUrl": None},  # no badge fetched from swagger.io
    )
    app.state.settings = settings
    app.state.store = store or make_store(settings)
    app.state.memory = MemoryReleaser()
    app.state.streams = StreamRegistry()  # open WebSocket streams (graceful shutdown)
    app.state.cpu = CapacityLimiter(settings.workers or os.cpu_count() or 1)
    errors.install(app)
    app.add_middleware(
        BodyLimit,
        json_bytes=settings.max_json_bytes,
        frame_bytes=settings.max_frame_bytes,
        body_seconds=settings.body_timeout_seconds,
    )
    app.include_router(sessions.router)
    app.include_router(stream.router)
    app.include_router(health.router)
    docs_pages.install(app)

    if (STATIC / "index.html").is_file():
        app.mount("/static", StaticFiles(directory=STATIC), name="static")

        @app.get("/", include_in_schema=False)
        async def demo() -> FileResponse:
            return FileResponse(STATIC / "index.html")

    return app
