"""API keys appear in no log line (service.redaction, efdm serve)."""

from __future__ import annotations

import io
import logging
import os
import signal
import subprocess
import sys
import time

import httpx
import pytest

from service.redaction import REDACTED, RedactSecrets, redact
from tests.service.conftest import free_port

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
    port = free_port()
    env = {**os.environ, "EFDM_LOG_LEVEL": "info", "EFDM_API_KEYS": KEY}
    proc = subprocess.Popen(
        [sys.executable, "-m", "efdm_cli", "serve", "--port", str(port)],
        env=env,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
    )
    try:
        url = f"http://127.0.0.1:{port}"
        for _ in range(300):
            try:
                if httpx.get(f"{url}/healthz", timeout=1).status_code == 200:
                    break
            except httpx.TransportError:
                time.sleep(0.1)
        else:
            raise AssertionError("efdm serve did not answer /healthz")
        assert httpx.get(f"{url}/v1/sessions", params={"api_key": KEY}).status_code == 401
        auth = {"authorization": f"Bearer {KEY}"}
        assert httpx.get(f"{url}/v1/sessions?limit=1", headers=auth).status_code == 200
        assert httpx.get(f"{url}/v1/sessions/nope?api_key={KEY}", headers=auth).status_code == 404
    finally:
        proc.send_signal(signal.SIGINT)
        try:
            out, err = proc.communicate(timeout=15)
        except subprocess.TimeoutExpired:
            proc.kill()
            out, err = proc.communicate()
    logs = (out + err).decode()
    assert "/v1/sessions/nope" in logs  # the access log is on ...
    assert KEY not in logs  # ... and says nothing of the key
    assert f"api_key={REDACTED}" in logs
