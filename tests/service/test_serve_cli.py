"""``efdm serve`` (the README's first command) starts a working service."""

from __future__ import annotations

import os
import socket
import subprocess
import sys

import httpx
import pytest

from tests.service.conftest import efdm_serve


def test_efdm_serve_starts_answers_and_stops() -> None:
    with efdm_serve(EFDM_MAX_SESSIONS="7", EFDM_LOG_LEVEL="warning") as run:
        url = run.url
        assert httpx.get(f"{url}/readyz").json() == {"status": "ready"}
        page = httpx.get(f"{url}/")
        assert page.status_code == 200
        assert "text/html" in page.headers["content-type"]
        assert httpx.get(f"{url}/openapi.json").json()["info"]["title"] == "efdm-tracker"
        # the environment reached the settings: the session cap of 7 applies
        body = {"circle": {"center": [50, 50], "radius": 10, "count": 8}}
        codes = [httpx.post(f"{url}/v1/sessions", json=body).status_code for _ in range(8)]
        assert codes == [201] * 7 + [429]
    assert run.returncode == 0, run.err
    # one line on start says where to look and what is on
    assert run.out.splitlines() == [
        f"efdm serve: {url}/ (demo page), /docs (API docs); API keys off; sessions in memory"
    ]


def test_the_banner_names_redis_without_its_password() -> None:
    from efdm_cli.serve import banner
    from service.settings import Settings

    line = banner(Settings(redis_url="redis://:hunter2@cache:6380/0", api_keys=("k",)))
    assert line.endswith("API keys on; sessions in Redis at cache:6380")
    assert "hunter2" not in line


def _serve(*args: str, **env: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "efdm_cli", "serve", *args],
        env={**os.environ, **env},
        capture_output=True,
        text=True,
        timeout=120,
        check=False,
    )


@pytest.mark.parametrize(
    ("args", "env", "named"),
    [
        ((), {"EFDM_PORT": "abc"}, "EFDM_PORT"),
        (("--port", "99999"), {}, "--port"),
        ((), {"EFDM_MAX_SESSIONS": "-1"}, "EFDM_MAX_SESSIONS"),
        ((), {"EFDM_LOG_LEVEL": "loud"}, "EFDM_LOG_LEVEL"),
    ],
    ids=["port not a number", "port out of range", "negative cap", "unknown log level"],
)
def test_bad_settings_are_a_clean_exit_2_naming_the_setting(
    args: tuple[str, ...], env: dict[str, str], named: str
) -> None:
    run = _serve(*args, **env)
    assert run.returncode == 2, run.stderr
    assert run.stderr.startswith("efdm serve: error: invalid settings: " + named)
    assert "Traceback" not in run.stderr
    assert run.stdout == ""


def test_a_port_in_use_is_a_clean_exit_1_and_no_banner() -> None:
    with socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen()
        run = _serve("--port", str(taken.getsockname()[1]))
    assert run.returncode == 1, run.stderr
    assert "efdm serve: error: could not serve on 127.0.0.1:" in run.stderr
    assert "Traceback" not in run.stderr
    assert run.stdout == ""  # the address is printed only once the server listens
