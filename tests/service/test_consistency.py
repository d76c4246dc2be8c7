"""REST, WebSocket and the library track the same frames to exactly the same contours."""

from __future__ import annotations

from typing import Any

import cv2
import numpy as np
import pytest
from fastapi.testclient import TestClient
from numpy.typing import NDArray

from engine import Tracker, deform
from engine.geometry import circle_nodes
from service.image_types import sniff
from tests.service.conftest import disc_frame

Step = tuple[str, Any]  # ("frame", jpeg bytes) or ("forces", [[fx, fy], ...])

CENTER, RADIUS, COUNT = (150.0, 110.0), 38.0, 48


def bgr(data: bytes) -> NDArray[np.uint8]:
    """Decode an encoded frame as the library's users would."""
    image = cv2.imdecode(np.frombuffer(data, np.uint8), cv2.IMREAD_COLOR)
    assert image is not None
    return np.asarray(image, dtype=np.uint8)


def script() -> list[Step]:
    """A disc that moves, a nudge by forces mid-way, then more motion."""
    path = [(150, 110), (153, 111), (157, 113), (160, 116), (162, 120), (160, 123)]
    steps: list[Step] = [("frame", disc_frame(x, y)) for x, y in path[:4]]
    angles = np.linspace(0, 2 * np.pi, COUNT, endpoint=False)
    steps.append(("forces", np.column_stack([2 * np.cos(angles), np.sin(angles)]).tolist()))
    steps += [("frame", disc_frame(x, y)) for x, y in path[4:]]
    steps.append(("frame", disc_frame(158, 124, r=36)))
    return steps


CASES = [
    pytest.param({}, "exact", 10.0, id="defaults"),
    pytest.param({"stiffness": 30, "iterations": 5}, "efdm", 4.0, id="options"),
    pytest.param({"search_radius": 20, "occlusion": False}, "dmma", 25.0, id="more-options"),
]


def spec(tracking: dict[str, Any], method: str, stiffness: float) -> dict[str, Any]:
    circle = {"center": list(CENTER), "radius": RADIUS, "count": COUNT}
    return {"circle": circle, "tracking": tracking, "method": method, "stiffness": stiffness}


def by_library(
    steps: list[Step], tracking: dict[str, Any], method: str, stiffness: float
) -> list[list[list[float]]]:
    tracker = Tracker(circle_nodes(CENTER, RADIUS, COUNT), **tracking)
    rest = tracker.nodes
    out = []
    for kind, payload in steps:
        if kind == "frame":
            nodes = tracker.step(bgr(payload)).nodes
            rest = nodes.copy()
        else:
            nodes = rest + deform(payload, stiffness, closed=True, method=method)
            tracker.reset(nodes)
        out.append(nodes.tolist())
    return out


def by_rest(client: TestClient, steps: list[Step], session: dict[str, Any]) -> list[Any]:
    sid = client.post("/v1/sessions", json=session).json()["id"]
    out = []
    for kind, payload in steps:
        if kind == "frame":
            response = client.post(
                f"/v1/sessions/{sid}/frames",
                content=payload,
                headers={"content-type": sniff(payload) or "application/octet-stream"},
            )
        else:
            response = client.post(f"/v1/sessions/{sid}/forces", json={"forces": payload})
        assert response.status_code == 200, response.text
        out.append(response.json()["nodes"])
    return out


def by_websocket(client: TestClient, steps: list[Step], session: dict[str, Any]) -> list[Any]:
    sid = client.post("/v1/sessions", json=session).json()["id"]
    out = []
    with client.websocket_connect(f"/v1/sessions/{sid}/stream") as ws:
        for kind, payload in steps:
            if kind == "frame":
                ws.send_bytes(payload)
            else:
                ws.send_json({"forces": payload})
            message = ws.receive_json()
            assert message["type"] == kind, message
            assert message.get("dropped", 0) == 0
            out.append(message["nodes"])
    return out


@pytest.mark.parametrize(("tracking", "method", "stiffness"), CASES)
def test_rest_websocket_and_library_agree_exactly(
    client: TestClient, tracking: dict[str, Any], method: str, stiffness: float
) -> None:
    steps = script()
    session = spec(tracking, method, stiffness)
    expected = by_library(steps, tracking, method, stiffness)
    assert by_rest(client, steps, session) == expected
    assert by_websocket(client, steps, session) == expected
    # and the tracking did something: the contour followed the disc
    final = np.asarray(expected[-1]).mean(axis=0)
    assert np.hypot(final[0] - 158, final[1] - 124) < 3


def test_tracking_is_repeatable(client: TestClient) -> None:
    steps = [s for s in script() if s[0] == "frame"]
    session = spec({}, "exact", 10.0)
    first = by_rest(client, steps, session)
    assert by_rest(client, steps, session) == first
    assert by_websocket(client, steps, session) == first


def test_other_image_encodings_of_the_same_pixels_agree(client: TestClient) -> None:
    """A lossless PNG of the decoded JPEG tracks exactly like the JPEG itself."""
    steps = [s for s in script() if s[0] == "frame"]
    png_steps: list[Step] = []
    for _, jpeg in steps:
        ok, png = cv2.imencode(".png", bgr(jpeg))
        assert ok
        png_steps.append(("frame", png.tobytes()))
    session = spec({}, "exact", 10.0)
    assert by_rest(client, png_steps, session) == by_rest(client, steps, session)
