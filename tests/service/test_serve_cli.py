"""``efdm serve`` (the README's first command) starts a working service."""

from __future__ import annotations

import httpx

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
