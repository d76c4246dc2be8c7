"""The service answers on a real socket, and the README's first command is `efdm serve`."""

from __future__ import annotations

import httpx

from tests.service.conftest import LiveServer, disc_frame


def test_live_server_round_trip(live_server: LiveServer) -> None:
    with httpx.Client(base_url=live_server.url, timeout=10) as http:
        assert http.get("/healthz").json() == {"status": "ok"}
        created = http.post("/v1/sessions", json={"circle": {"center": [160, 120], "radius": 40}})
        assert created.status_code == 201
        sid = created.json()["id"]
        assert created.headers["location"] == f"/v1/sessions/{sid}"
        first = http.post(
            f"/v1/sessions/{sid}/frames",
            content=disc_frame(160, 120),
            headers={"content-type": "image/jpeg"},
        )
        assert first.status_code == 200
        moved = http.post(
            f"/v1/sessions/{sid}/frames",
            content=disc_frame(166, 122),
            headers={"content-type": "image/jpeg"},
        ).json()
        assert moved["frame_index"] == 1
        centre = [sum(c) / len(c) for c in zip(*moved["nodes"], strict=True)]
        assert abs(centre[0] - 166) < 2
        assert abs(centre[1] - 122) < 2
