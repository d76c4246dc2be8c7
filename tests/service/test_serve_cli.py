"""``efdm serve`` (the README's first command) starts a working service."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time

import httpx

from tests.service.conftest import free_port


def test_efdm_serve_starts_answers_and_stops() -> None:
    port = free_port()
    env = {**os.environ, "EFDM_MAX_SESSIONS": "7", "EFDM_LOG_LEVEL": "warning"}
    proc = subprocess.Popen(
        [sys.executable, "-m", "efdm_cli", "serve", "--port", str(port)],
        env=env,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
    )
    try:
        url = f"http://127.0.0.1:{port}"
        for _ in range(300):  # up to ~30 s for imports and the solver's warm-up
            try:
                if httpx.get(f"{url}/healthz", timeout=1).status_code == 200:
                    break
            except httpx.TransportError:
                time.sleep(0.1)
        else:
            raise AssertionError("efdm serve did not answer /healthz")
        assert httpx.get(f"{url}/readyz").json() == {"status": "ready"}
        page = httpx.get(f"{url}/")
        assert page.status_code == 200
        assert "text/html" in page.headers["content-type"]
        assert httpx.get(f"{url}/openapi.json").json()["info"]["title"] == "efdm-tracker"
        # the environment reached the settings: the session cap of 7 applies
        body = {"circle": {"center": [50, 50], "radius": 10, "count": 8}}
        codes = [httpx.post(f"{url}/v1/sessions", json=body).status_code for _ in range(8)]
        assert codes == [201] * 7 + [429]
    finally:
        proc.send_signal(signal.SIGINT)
        try:
            out, err = proc.communicate(timeout=15)
        except subprocess.TimeoutExpired:
            proc.kill()
            out, err = proc.communicate()
    assert proc.returncode == 0, err.decode()
    # one line on start says where to look and what is on
    assert out.decode().splitlines() == [
        f"efdm serve: http://127.0.0.1:{port}/ (demo page), /docs (API docs); "
        "API keys off; sessions in memory"
    ]


def test_the_banner_names_redis_without_its_password() -> None:
    from efdm_cli.serve import banner
    from service.settings import Settings

    line = banner(Settings(redis_url="redis://:hunter2@cache:6380/0", api_keys=("k",)))
    assert line.endswith("API keys on; sessions in Redis at cache:6380")
    assert "hunter2" not in line
