"""``efdm serve``: run the tracking service (FastAPI + uvicorn)."""

from __future__ import annotations

import argparse
import signal
from types import FrameType
from typing import Any, NoReturn

from efdm_cli._common import EXIT_INVALID, EXIT_IO, EXIT_MISSING, CliError

GRACE_SECONDS = 10
"""On SIGTERM, seconds for the work in flight before uvicorn cancels what is left."""
DRAIN_SECONDS = 5.0
"""Of those, at most this long for WebSocket frames in flight (then 1001 regardless)."""


class _TerminatedError(Exception):
    """SIGTERM arrived outside uvicorn's own handler (before start, or re-raised at the end)."""


def _terminated(signum: int, frame: FrameType | None) -> NoReturn:
    raise _TerminatedError


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


def banner(settings: Any) -> str:
    """The one line ``efdm serve`` prints on start: where to look, and what is on."""
    from urllib.parse import urlsplit

    url = f"http://{settings.host}:{settings.port}"
    keys = "API keys on" if settings.auth_enabled else "API keys off"
    if settings.redis_url:
        where = urlsplit(settings.redis_url)  # host and port only: never a password
        store = f"sessions in Redis at {where.hostname}:{where.port or 6379}"
    else:
        store = "sessions in memory"
    return f"efdm serve: {url}/ (demo page), /docs (API docs); {keys}; {store}"


def run(args: argparse.Namespace, out: Any) -> None:
    """Start uvicorn with the app (blocks until stopped).

    SIGTERM or Ctrl-C stop it gracefully (:mod:`service.shutdown`): no new
    connections, requests in flight answered, WebSocket streams closed with
    ``1001`` after their frame in flight; then the process exits with 0.
    """
    try:
        import uvicorn
        from pydantic import ValidationError
        from uvicorn.config import STARTUP_FAILURE

        from service.app import create_app
        from service.connections import raise_open_file_limit, server_options
        from service.redaction import install as redact_logs
        from service.settings import Settings
        from service.shutdown import GracefulServer
    except ImportError as exc:
        raise CliError(
            f"the service is not installed ({exc}); install it with "
            "pip install 'efdm-tracker[service]'",
            EXIT_MISSING,
        ) from None

    overrides = {k: v for k, v in {"host": args.host, "port": args.port}.items() if v is not None}
    try:
        settings = Settings(**overrides)
    except ValidationError as exc:
        raise CliError(_invalid_settings(exc, set(overrides)), EXIT_INVALID) from None
    raise_open_file_limit()  # many clients, slow ones included, each hold a descriptor
    app = create_app(settings)
    config = uvicorn.Config(
        app,
        host=settings.host,
        port=settings.port,
        log_level=settings.log_level,
        access_log=settings.log_level in {"info", "debug"},
        ws_ping_interval=20.0,
        ws_per_message_deflate=False,  # frames are JPEG: compressing them only costs CPU
        ws_max_size=max(settings.max_frame_bytes, settings.max_json_bytes) + 1024,
        ws_ping_timeout=20.0,
        timeout_graceful_shutdown=GRACE_SECONDS,
        **server_options(settings),
    )
    # on the handlers uvicorn's Config has just set up
    redact_logs([*settings.api_keys, settings.metrics_key or ""])
    server = GracefulServer(
        config,
        app.state.streams,
        drain_seconds=DRAIN_SECONDS,
        on_started=lambda: print(banner(settings), file=out, flush=True),  # once it listens
    )
    previous = signal.signal(signal.SIGTERM, _terminated)
    stopped = False
    try:
        server.run()
    except (KeyboardInterrupt, _TerminatedError):
        stopped = True  # uvicorn re-raises the signal it stopped on: a requested stop succeeds
    except SystemExit as exc:  # uvicorn's own exit when it cannot start
        if server.started or exc.code != STARTUP_FAILURE:
            raise
    finally:
        signal.signal(signal.SIGTERM, previous)
    if not server.started and not stopped:
        raise CliError(
            f"could not serve on {settings.host}:{settings.port} (the address is in use or "
            "not this machine's, or the app failed to start: see the log above)",
            EXIT_IO,
        )


def _invalid_settings(exc: Any, given: set[str]) -> str:
    """A pydantic ``ValidationError`` of the settings as one line: each setting by the
    environment variable (or option) it came from, and what is wrong with it."""
    parts = []
    for error in exc.errors():
        name = str(error["loc"][0]) if error["loc"] else "settings"
        where = f"--{name}" if name in given else f"EFDM_{name.upper()}"
        parts.append(f"{where}: {error['msg']} (got {error.get('input')!r})")
    return "invalid settings: " + "; ".join(parts)
