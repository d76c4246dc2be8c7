"""What routes take from the app, as ``Annotated`` dependencies (FastAPI ``Depends``).

Every route, the WebSocket one included, declares what it needs as a
parameter typed with one of these aliases: :data:`SettingsDep`,
:data:`StoreDep`, :data:`CpuDep`, :data:`StreamsDep`, :data:`ApiKeyDep` and
:data:`OwnerDep`.  None of them reads the body; all run on the event loop
(``async def``: FastAPI would run plain functions in a thread).
"""

from __future__ import annotations

from collections.abc import Awaitable, Callable
from typing import Annotated, Any

from anyio import CapacityLimiter
from fastapi import Depends
from starlette.requests import HTTPConnection

from service.auth import bearer, check_key
from service.settings import Settings
from service.shutdown import StreamRegistry
from service.store import SessionStore

__all__ = [
    "ApiKeyDep",
    "CpuDep",
    "OwnerDep",
    "SettingsDep",
    "StoreDep",
    "StreamsDep",
    "api_key",
    "request_owner",
]


def app_state(name: str) -> Callable[[HTTPConnection], Awaitable[Any]]:
    """A dependency giving ``app.state.<name>`` (set by :func:`service.app.create_app`).

    Parameters
    ----------
    name : str
        The attribute; the ``Annotated`` alias using the dependency gives its type.
    """

    async def dependency(conn: HTTPConnection) -> Any:
        return getattr(conn.app.state, name)

    dependency.__name__ = dependency.__qualname__ = f"{name}_of"
    return dependency


SettingsDep = Annotated[Settings, Depends(app_state("settings"))]
"""The app's settings."""
StoreDep = Annotated[SessionStore, Depends(app_state("store"))]
"""The app's session store."""
CpuDep = Annotated[CapacityLimiter, Depends(app_state("cpu"))]
"""The limiter of CPU work in worker threads (one per core by default; :mod:`service.work`)."""
StreamsDep = Annotated[StreamRegistry, Depends(app_state("streams"))]
"""The registry of open WebSocket streams (graceful shutdown)."""


async def api_key(conn: HTTPConnection) -> str | None:
    """The API key presented, or None.

    ``Authorization: Bearer <key>``; on a WebSocket also ``?api_key=<key>``
    (browsers cannot set headers there).
    """
    key = bearer(conn.headers.get("authorization"))
    if key is None and conn.scope["type"] == "websocket":
        key = conn.query_params.get("api_key")
    return key


ApiKeyDep = Annotated[str | None, Depends(api_key)]
"""The key as presented, unchecked (a WebSocket checks it once accepted)."""


async def request_owner(settings: SettingsDep, key: ApiKeyDep) -> str | None:
    """Authenticate an HTTP request: the owner of its key (see :func:`check_key`)."""
    return check_key(settings, key)


OwnerDep = Annotated[str | None, Depends(request_owner)]
"""The authenticated owner of an HTTP request; 401 before the route runs otherwise."""
