"""``"box"`` and ``"snap"`` at ``POST /v1/sessions``: a rough outline snaps on the first frame."""

from __future__ import annotations

from typing import Any

import cv2
import numpy as np
import pytest
from fastapi.testclient import TestClient

from engine.geometry import contour_to_mask, mask_iou
from tests.service.conftest import LiveServer, disc_frame

JPEG = {"content-type": "image/jpeg"}
CENTRE, RADIUS = (160.0, 120.0), 40  # disc_frame's disc
BOX = [118, 78, 203, 163]  # around it, a few pixels loose


def truth() -> np.ndarray:
    mask = np.zeros((240, 320), np.uint8)
    cv2.circle(mask, (160, 120), RADIUS, 255, -1)
    return mask


def unchanged_part(session: dict[str, Any]) -> dict[str, Any]:
    """The session without its expiry (any request keeps a session alive)."""
    return {k: v for k, v in session.items() if k != "expires_at"}


def iou(nodes: list[list[float]]) -> float:
    return mask_iou(contour_to_mask(np.asarray(nodes), (240, 320)), truth())


def test_a_box_snaps_onto_the_object_on_the_first_frame(client: TestClient) -> None:
    created = client.post("/v1/sessions", json={"box": BOX})
    assert created.status_code == 201, created.text
    body = created.json()
    assert len(body["nodes"]) == 64
    assert iou(body["nodes"]) < 0.85  # the box itself, until a frame is seen
    sid = body["id"]
    first = client.post(f"/v1/sessions/{sid}/frames", content=disc_frame(*CENTRE), headers=JPEG)
    assert first.status_code == 200, first.text
    assert iou(first.json()["nodes"]) > 0.9
    moved = client.post(
        f"/v1/sessions/{sid}/frames", content=disc_frame(165.0, 122.0), headers=JPEG
    )
    assert moved.json()["frame_index"] == 1  # and it tracks on from there


@pytest.mark.parametrize("snap", [False, None])
def test_snap_false_keeps_the_box_and_nodes_do_not_snap_by_default(
    client: TestClient, snap: bool | None
) -> None:
    spec: dict[str, object] = (
        {"box": BOX, "snap": False}
        if snap is False
        else {"circle": {"center": [160, 120], "radius": 55}}
    )
    sid = client.post("/v1/sessions", json=spec).json()["id"]
    first = client.post(f"/v1/sessions/{sid}/frames", content=disc_frame(*CENTRE), headers=JPEG)
    assert iou(first.json()["nodes"]) < 0.85


def test_a_loose_circle_snaps_when_asked(client: TestClient) -> None:
    spec = {"circle": {"center": [160, 120], "radius": 55, "count": 48}, "snap": True}
    sid = client.post("/v1/sessions", json=spec).json()["id"]
    first = client.post(f"/v1/sessions/{sid}/frames", content=disc_frame(*CENTRE), headers=JPEG)
    nodes = first.json()["nodes"]
    assert len(nodes) == 48
    assert iou(nodes) > 0.9


@pytest.mark.parametrize(
    ("spec", "message"),
    [
        ({"box": [10, 10, 5, 20]}, "x1 > x0"),
        ({"box": [10, 10, 20, 10]}, "y1 > y0"),
        ({"box": [10, 10, 20]}, ""),
        ({"box": [0, 0, "a", 1]}, ""),
        ({"box": BOX, "circle": {"center": [1, 1], "radius": 2}}, "exactly one"),
        ({"box": BOX, "closed": False}, "closed"),
    ],
)
def test_bad_boxes_are_a_422_and_store_nothing(
    client: TestClient, spec: dict[str, object], message: str
) -> None:
    before = client.get("/v1/sessions").json()["sessions"]
    response = client.post("/v1/sessions", json=spec)
    assert response.status_code == 422
    assert message in response.text
    assert client.get("/v1/sessions").json()["sessions"] == before


def test_a_box_outside_the_first_frame_is_a_422_that_changes_nothing(client: TestClient) -> None:
    sid = client.post("/v1/sessions", json={"box": [1000, 1000, 1100, 1100]}).json()["id"]
    before = unchanged_part(client.get(f"/v1/sessions/{sid}").json())
    refused = client.post(f"/v1/sessions/{sid}/frames", content=disc_frame(*CENTRE), headers=JPEG)
    assert refused.status_code == 422
    assert "outside the frame" in refused.text
    assert unchanged_part(client.get(f"/v1/sessions/{sid}").json()) == before


def test_a_box_that_snaps_onto_a_line_is_a_422_that_changes_nothing(client: TestClient) -> None:
    """A snap whose object encloses no area (a one-pixel line) is refused, not a 500."""
    image = np.full((120, 160, 3), 40, np.uint8)
    cv2.line(image, (20, 60), (140, 60), (0, 0, 255), 1)
    line = cv2.imencode(".png", image)[1].tobytes()
    sid = client.post("/v1/sessions", json={"box": [20, 59, 141, 62]}).json()["id"]
    before = unchanged_part(client.get(f"/v1/sessions/{sid}").json())
    for _ in range(2):  # and again: the session was left as it was
        refused = client.post(
            f"/v1/sessions/{sid}/frames", content=line, headers={"content-type": "image/png"}
        )
        assert refused.status_code == 422, refused.text
        assert "snap" in refused.json()["error"]["message"]
    assert unchanged_part(client.get(f"/v1/sessions/{sid}").json()) == before


def test_the_python_client_starts_from_a_box(live_server: LiveServer) -> None:
    from service.client import Client

    frame = cv2.imdecode(np.frombuffer(disc_frame(*CENTRE), np.uint8), cv2.IMREAD_COLOR)
    with Client(live_server.url) as api:
        session = api.create_session(box=BOX)
        result = api.track_frame(session, np.asarray(frame, np.uint8))
        with pytest.raises(ValueError, match="exactly one"):
            api.create_session(box=BOX, nodes=[[0, 0], [1, 0], [1, 1]])
    assert iou(result.nodes.tolist()) > 0.9


def test_a_pending_snap_survives_the_shared_store_record() -> None:
    from service.schemas import SessionCreate
    from service.sessions import Session

    session = Session.create(SessionCreate(box=(118.0, 78.0, 203.0, 163.0)), None, max_nodes=4096)
    restored = Session.from_record(session.to_record(compact=True))
    assert restored.snap_outline == [118.0, 78.0, 203.0, 163.0]
    frame = cv2.imdecode(np.frombuffer(disc_frame(*CENTRE), np.uint8), cv2.IMREAD_COLOR)
    assert iou(restored.track(np.asarray(frame, np.uint8))["nodes"]) > 0.9
    kept = Session.from_record(restored.to_record())  # the first frame waits for the next
    assert kept.snap_outline == restored.snap_outline
    assert kept.snap_frame is not None
    np.testing.assert_array_equal(kept.snap_frame, frame)
    after = cv2.imdecode(np.frombuffer(disc_frame(165.0, 122.0), np.uint8), cv2.IMREAD_COLOR)
    kept.track(np.asarray(after, np.uint8))
    done = Session.from_record(kept.to_record())
    assert done.snap_outline is None
    assert done.snap_frame is None


def decoded(data: bytes) -> np.ndarray:
    return np.asarray(cv2.imdecode(np.frombuffer(data, np.uint8), cv2.IMREAD_UNCHANGED), np.uint8)


def test_the_second_frame_snaps_the_box_again_with_what_moved(client: TestClient) -> None:
    """Frame 0 answers the snap from colour alone; from frame 1 on the session tracks what
    a tracker started from the snap with the next frame tracks (``efdm track --init-box``),
    through the shared store's record too."""
    from engine import Tracker
    from engine.geometry import mask_to_contour
    from engine.tracking.snap import snap
    from service.schemas import SessionCreate
    from service.sessions import Session
    from tests.engine.scenes import decoy_scene, shifted

    first, second, truth, _ = decoy_scene()
    third = second.copy()
    frames = [cv2.imencode(".png", f)[1].tobytes() for f in (first, second, third)]
    ys, xs = np.nonzero(truth)
    box = [int(xs.min()), int(ys.min()), int(xs.max()) + 1, int(ys.max()) + 1]
    png = {"content-type": "image/png"}
    sid = client.post("/v1/sessions", json={"box": box}).json()["id"]
    answers = [
        client.post(f"/v1/sessions/{sid}/frames", content=f, headers=png).json()["nodes"]
        for f in frames
    ]
    alone = Tracker(mask_to_contour(snap(first, box), 64))
    np.testing.assert_allclose(answers[0], alone.step(first).nodes)
    library = Tracker(mask_to_contour(snap(first, box, next_frame=second), 64))
    library.step(first)
    for answer, frame in zip(answers[1:], (second, third), strict=True):
        np.testing.assert_allclose(answer, library.step(frame).nodes)
    there = shifted(truth, 6.0, 3.0)  # the disc on the second frame
    assert mask_iou(contour_to_mask(np.asarray(answers[1]), truth.shape), there) > 0.9
    stored = Session.create(SessionCreate(box=tuple(map(float, box))), None, max_nodes=4096)
    stored.track(decoded(frames[0]))
    again = Session.from_record(stored.to_record())
    np.testing.assert_allclose(again.track(decoded(frames[1]))["nodes"], answers[1])


def test_forces_after_the_first_frame_are_not_undone_by_the_second_snap() -> None:
    from service.schemas import SessionCreate
    from service.sessions import Session

    session = Session.create(SessionCreate(box=(118.0, 78.0, 203.0, 163.0)), None, max_nodes=4096)
    session.track(decoded(disc_frame(*CENTRE)))
    assert session.snap_frame is not None
    forces = np.zeros((len(session.rest), 2))
    forces[:, 0] = 30.0  # the whole contour 30 px to the right
    session.apply_forces([tuple(f) for f in forces])
    assert session.snap_outline is None
    assert session.snap_frame is None
    moved = session.nodes.copy()
    result = session.track(decoded(disc_frame(*CENTRE)))  # the same frame: nothing to follow
    assert np.abs(np.asarray(result["nodes"]).mean(axis=0) - moved.mean(axis=0)).max() < 15


def test_the_compact_record_keeps_the_first_frame_small_and_still_snaps_again() -> None:
    """The shared store's record keeps the first frame as JPEG: a tenth of the PNG, and the
    second snap from it lands where the exact one does."""
    import json

    from service.schemas import SessionCreate
    from service.sessions import Session
    from tests.engine.scenes import decoy_scene

    first, second, truth, _ = decoy_scene()
    ys, xs = np.nonzero(truth)
    box = (float(xs.min()), float(ys.min()), float(xs.max()) + 1, float(ys.max()) + 1)
    session = Session.create(SessionCreate(box=box), None, max_nodes=4096)
    session.track(first)
    exact, compact = session.to_record(), session.to_record(compact=True)
    assert len(compact["snap_frame"]) * 3 < len(exact["snap_frame"])
    assert len(json.dumps(compact)) < len(json.dumps(exact))
    ways = [Session.from_record(record) for record in (exact, compact)]
    answers = [np.asarray(way.track(second)["nodes"]) for way in ways]
    shape = truth.shape
    there = [contour_to_mask(a, shape) for a in answers]
    assert mask_iou(there[0], there[1]) > 0.95
