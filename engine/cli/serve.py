"""``efdm serve``: run the tracking service (FastAPI + uvicorn)."""

from __future__ import annotations

import argparse
from typing import Any


def add_parser(commands: Any) -> None:
    """Register ``serve`` on the sub-command parser."""
    p = commands.add_parser(
        "serve",
        help="run the HTTP/WebSocket tracking service",
        description=(
            "Serve the v1 API, the demo page (/) and /docs. Settings come from EFDM_* "
            "environment variables (see the README); --host and --port override them."
        ),
    )
    p.add_argument("--host", help="address to listen on (EFDM_HOST, default 127.0.0.1)")
    p.add_argument("--port", type=int, help="port (EFDM_PORT, default 8000)")
    p.set_defaults(handler=run)


def run(args: argparse.Namespace, out: Any) -> None:
    """Start uvicorn with the app (blocks until stopped)."""
    import uvicorn

    from service.app import create_app
    from service.settings import Settings

    overrides = {k: v for k, v in {"host": args.host, "port": args.port}.items() if v is not None}
    settings = Settings(**overrides)
    uvicorn.run(
        create_app(settings),
        host=settings.host,
        port=settings.port,
        log_level=settings.log_level,
        ws_ping_interval=20.0,
        ws_per_message_deflate=False,  # frames are JPEG: compressing them only costs CPU
        ws_max_size=max(settings.max_frame_bytes, settings.max_json_bytes) + 1024,
        ws_ping_timeout=20.0,
        timeout_graceful_shutdown=10,
    )
