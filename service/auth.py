"""API keys: ``Authorization: Bearer <key>`` (WebSocket: ``?api_key=<key>``).

The routes take the owner through :data:`service.deps.OwnerDep` (HTTP) or
check the key themselves once accepted (WebSocket).
"""

from __future__ import annotations

import hashlib
import hmac

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
