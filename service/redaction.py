"""Secrets stay out of logs: API keys are redacted from every log line.

A WebSocket client passes its key as ``?api_key=...`` (browsers cannot set
headers there), and uvicorn's access log prints each request's path with its
query string.  :class:`RedactSecrets`, a :class:`logging.Filter` installed on
every handler by :func:`install`, rewrites each record before it is written:
``api_key=`` query values, ``Bearer`` tokens, and the configured keys
themselves wherever they appear (message, arguments, exception text).
"""

from __future__ import annotations

import logging
import re
from collections.abc import Iterable

__all__ = ["REDACTED", "RedactSecrets", "install", "redact"]

REDACTED = "[redacted]"
_PATTERNS = (
    # a query parameter named like a key: api_key, apikey, api-key, key, token, access_token
    re.compile(r"(?i)([?&](?:api[_-]?key|key|token|access_token)=)[^&\s\"']*"),
    re.compile(r"(?i)(bearer\s+)[^\s\"',]+"),
)
LOGGERS = ("", "uvicorn", "uvicorn.error", "uvicorn.access", "efdm", "efdm.service")
"""Loggers whose handlers get the filter: the root, uvicorn's and the service's."""


def redact(text: str, secrets: Iterable[str] = ()) -> str:
    """``text`` with key-like query values, Bearer tokens and ``secrets`` replaced."""
    for pattern in _PATTERNS:
        text = pattern.sub(lambda m: m.group(1) + REDACTED, text)
    for secret in secrets:
        if secret:
            text = text.replace(secret, REDACTED)
    return text


class RedactSecrets(logging.Filter):
    """Redacts every record it sees (it never drops one).

    Parameters
    ----------
    secrets : iterable of str
        Values to remove wherever they appear (the configured API keys).
    """

    def __init__(self, secrets: Iterable[str] = ()) -> None:
        super().__init__()
        # longest first: a key that contains another is removed whole
        self.secrets = tuple(sorted({s for s in secrets if s}, key=len, reverse=True))

    def filter(self, record: logging.LogRecord) -> bool:
        if isinstance(record.msg, str):
            record.msg = redact(record.msg, self.secrets)
        if isinstance(record.args, tuple):
            record.args = tuple(
                redact(a, self.secrets) if isinstance(a, str) else a for a in record.args
            )
        elif isinstance(record.args, dict):
            record.args = {
                k: redact(v, self.secrets) if isinstance(v, str) else v
                for k, v in record.args.items()
            }
        if record.exc_info and not record.exc_text:
            record.exc_text = logging.Formatter().formatException(record.exc_info)
        if record.exc_text:
            record.exc_text = redact(record.exc_text, self.secrets)
        return True


def install(secrets: Iterable[str] = ()) -> RedactSecrets:
    """Put one :class:`RedactSecrets` on every handler of :data:`LOGGERS`; returns it.

    Call after the server configured logging (uvicorn does so when its
    ``Config`` is made).  Handlers that already have one keep theirs.
    """
    redactor = RedactSecrets(secrets)
    for name in LOGGERS:
        for handler in logging.getLogger(name).handlers:
            if not any(isinstance(f, RedactSecrets) for f in handler.filters):
                handler.addFilter(redactor)
    return redactor
