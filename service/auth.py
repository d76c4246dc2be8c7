"""API keys: ``Authorization: Bearer <key>`` (WebSocket: ``?api_key=<key>``)."""

from __future__ import annotations

import hashlib
import hmac

from fastapi import Request, WebSocket

from service.errors import ApiError
from service.settings import Settings


def owner_of(key: str) -> str:
    """A session's owner tag: a hash of the key, never the key itself."""
    return hashlib.sha256(key.encode()).hexdigest()[:32]


def check_key(settings: Settings, key: str | None) -> str | None:
    """The owner for a presented key; None when keys are not required.

    Raises
    ------
    ApiError
        401 when keys are required and the key is missing or wrong.
    """
    if not settings.auth_enabled:
        return None
    if not key:
        raise ApiError(401, "unauthorized", "missing API key", **{"WWW-Authenticate": "Bearer"})
    if not any(hmac.compare_digest(key, k) for k in settings.api_keys):
        raise ApiError(401, "unauthorized", "wrong API key", **{"WWW-Authenticate": "Bearer"})
    return owner_of(key)


def bearer(header: str | None) -> str | None:
    """The key of an ``Authorization: Bearer <key>`` header."""
    if header and header[:7].lower() == "bearer ":
        return header[7:].strip() or None
    return None


async def request_owner(request: Request) -> str | None:
    """FastAPI dependency: authenticate an HTTP request."""
    settings: Settings = request.app.state.settings
    return check_key(settings, bearer(request.headers.get("authorization")))


def websocket_owner(websocket: WebSocket) -> str | None:
    """Authenticate a WebSocket: the Authorization header, or ``?api_key=`` (browsers)."""
    settings: Settings = websocket.app.state.settings
    key = bearer(websocket.headers.get("authorization")) or websocket.query_params.get("api_key")
    return check_key(settings, key)
