"""API keys appear in no log line (service.redaction, efdm serve)."""

from __future__ import annotations

import io
import logging

import httpx
import pytest

from service.redaction import REDACTED, RedactSecrets, redact
from tests.service.conftest import efdm_serve

KEY = "s3cret-key-42"


@pytest.mark.parametrize(
    "text",
    [
        f'127.0.0.1:5 - "WebSocket /v1/sessions/x/stream?api_key={KEY}" [accepted]',
        f"GET /v1/sessions?limit=2&api_key={KEY}&after=x",
        f"Authorization: Bearer {KEY}",
        f"failed for key {KEY}",  # the configured key itself, anywhere
    ],
)
def test_redact_removes_the_key(text: str) -> None:
    out = redact(text, [KEY])
    assert KEY not in out
    assert REDACTED in out


def test_redact_keeps_the_rest() -> None:
    assert redact("GET /v1/sessions?limit=2&after=x", [KEY]) == "GET /v1/sessions?limit=2&after=x"
    assert redact(f"?api_key={KEY}&limit=2") == f"?api_key={REDACTED}&limit=2"


def test_the_filter_redacts_messages_arguments_and_tracebacks() -> None:
    stream = io.StringIO()
    handler = logging.StreamHandler(stream)
    handler.addFilter(RedactSecrets([KEY]))
    log = logging.getLogger("test.redaction")
    log.addHandler(handler)
    log.propagate = False
    try:
        log.warning('%s - "%s %s"', "127.0.0.1", "GET", f"/x?api_key={KEY}")
        log.warning("key %(key)s", {"key": KEY})
        try:
            raise ValueError(f"bad key {KEY}")
        except ValueError:
            log.exception("failed")
    finally:
        log.removeHandler(handler)
    text = stream.getvalue()
    assert KEY not in text
    assert text.count(REDACTED) == 3  # the access line, the mapping, the exception
    assert "ValueError" in text  # the traceback is still there


def test_efdm_serve_logs_no_key_at_info_level() -> None:
    """The access log printed ``?api_key=...`` in clear."""
    with efdm_serve(EFDM_LOG_LEVEL="info", EFDM_API_KEYS=KEY) as run:
        url = run.url
        assert httpx.get(f"{url}/v1/sessions", params={"api_key": KEY}).status_code == 401
        auth = {"authorization": f"Bearer {KEY}"}
        assert httpx.get(f"{url}/v1/sessions?limit=1", headers=auth).status_code == 200
        assert httpx.get(f"{url}/v1/sessions/nope?api_key={KEY}", headers=auth).status_code == 404
    logs = run.out + run.err
    assert "/v1/sessions/nope" in logs  # the access log is on ...
    assert KEY not in logs  # ... and says nothing of the key
    assert f"api_key={REDACTED}" in logs
