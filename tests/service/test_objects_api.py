"""Sessions of several objects: ``"objects"`` at create, their results, and changes mid-stream."""

from __future__ import annotations

import base64
from typing import Any

import cv2
import numpy as np
import pytest
from fastapi.testclient import TestClient

from engine.geometry import contour_to_mask, mask_iou
from tests.service.conftest import LiveServer, disc_frame

JPEG = {"content-type": "image/jpeg"}
SIZE = (240, 320)  # disc_frame's frames: a disc of radius 40 at the given centre
BOX = [118, 78, 203, 163]  # around the disc at (160, 120)


def disc(centre: tuple[float, float]) -> np.ndarray:
    mask = np.zeros(SIZE, np.uint8)
    cv2.circle(mask, (round(centre[0]), round(centre[1])), 40, 255, -1)
    return mask


def unchanged_part(session: dict[str, Any]) -> dict[str, Any]:
    """The session without its expiry (any request keeps a session alive)."""
    return {k: v for k, v in session.items() if k != "expires_at"}


def iou(nodes: list[list[float]], centre: tuple[float, float]) -> float:
    return mask_iou(contour_to_mask(np.asarray(nodes), SIZE), disc(centre))


def specks(count: int) -> np.ndarray:
    """A mask of ``count`` separate 12 x 12 squares."""
    mask = np.zeros(SIZE, np.uint8)
    for k in range(count):
        y, x = divmod(k, 12)
        mask[5 + 20 * y : 17 + 20 * y, 5 + 20 * x : 17 + 20 * x] = 255
    return mask


def png(mask: np.ndarray) -> str:
    ok, data = cv2.imencode(".png", mask)
    assert ok
    return base64.b64encode(data.tobytes()).decode()


def frame(client: TestClient, sid: str, centre: tuple[float, float]) -> Any:
    return client.post(f"/v1/sessions/{sid}/frames", content=disc_frame(*centre), headers=JPEG)


def test_a_session_of_objects_snaps_tracks_and_answers_each(client: TestClient) -> None:
    spec = {
        "objects": [{"box": BOX}, {"id": "corner", "circle": {"center": [40, 40], "radius": 15}}]
    }
    created = client.post("/v1/sessions", json=spec)
    assert created.status_code == 201, created.text
    body = created.json()
    sid = body["id"]
    assert [o["id"] for o in body["objects"]] == ["1", "corner"]
    first = frame(client, sid, (160.0, 120.0))
    assert first.status_code == 200, first.text
    result = first.json()
    assert [o["id"] for o in result["objects"]] == ["1", "corner"]
    assert iou(result["objects"][0]["nodes"], (160, 120)) > 0.9  # the box snapped
    for o in result["objects"]:
        assert o["status"] in {"tracking", "uncertain", "lost"}
        assert 0.0 <= o["confidence"] <= 1.0
        assert o["behind"] == []  # apart: neither covers the other
    moved = frame(client, sid, (166.0, 122.0)).json()
    assert moved["frame_index"] == 1
    assert iou(moved["objects"][0]["nodes"], (166, 122)) > 0.85
    assert client.get(f"/v1/sessions/{sid}").json()["objects"][1]["id"] == "corner"


def test_objects_are_added_corrected_and_removed_mid_stream(client: TestClient) -> None:
    sid = client.post("/v1/sessions", json={"objects": [{"box": BOX}]}).json()["id"]
    frame(client, sid, (160.0, 120.0))
    added = client.post(
        f"/v1/sessions/{sid}/objects", json={"circle": {"center": [280, 200], "radius": 20}}
    )
    assert added.status_code == 201, added.text
    assert added.json()["id"] == "2"
    assert added.headers["location"].endswith(f"/v1/sessions/{sid}/objects/2")
    assert [o["id"] for o in frame(client, sid, (162.0, 120.0)).json()["objects"]] == ["1", "2"]
    correction = {"circle": {"center": [164, 120], "radius": 40, "count": 48}}
    put = client.put(f"/v1/sessions/{sid}/objects/1", json=correction)
    assert put.status_code == 200, put.text
    after = frame(client, sid, (164.0, 120.0)).json()["objects"][0]
    assert len(after["nodes"]) == 48  # the correction took effect on this frame
    assert iou(after["nodes"], (164, 120)) > 0.9
    assert client.delete(f"/v1/sessions/{sid}/objects/2").status_code == 204
    assert [o["id"] for o in frame(client, sid, (166.0, 120.0)).json()["objects"]] == ["1"]
    for method in ("put", "delete"):
        missing = client.request(method, f"/v1/sessions/{sid}/objects/9", json=correction)
        assert missing.status_code == 404
        assert missing.json()["error"]["code"] == "object_not_found"


def test_an_object_in_two_pieces_answers_its_contours(client: TestClient) -> None:
    mask = disc((160, 120))
    cv2.rectangle(mask, (260, 20), (299, 59), 255, -1)  # a second piece, 1,600 px
    sid = client.post("/v1/sessions", json={"objects": [{"mask": png(mask)}]}).json()["id"]
    result = frame(client, sid, (160.0, 120.0)).json()
    assert len(result["objects"][0]["contours"]) == 2
    at_most = client.post("/v1/sessions", json={"objects": [{"mask": png(specks(32))}]})
    assert at_most.status_code == 201, at_most.text


@pytest.mark.parametrize(
    ("spec", "message"),
    [
        ({"objects": [{"box": [10, 10, 5, 20]}]}, "x1 > x0"),
        (
            {"objects": [{"mask": base64.b64encode(b"\xff\xd8\xff not a png").decode()}]},
            "not a PNG",
        ),
        ({"objects": [{"mask": "%%%"}]}, "base64"),
        ({"objects": [{"mask": png(specks(33))}]}, "33 separate pieces of at least 100 px"),
        ({"objects": [{"circle": {"center": [1, 1], "radius": 2}}] * 33}, ""),
        ({"objects": [{"id": "a", "box": BOX}, {"id": "a", "box": BOX}]}, "differ"),
        ({"objects": []}, "at least one"),
        ({"objects": [{"box": BOX, "nodes": [[0, 0], [1, 0], [1, 1]]}]}, "exactly one"),
    ],
)
def test_bad_objects_are_a_422_and_store_nothing(
    client: TestClient, spec: dict[str, Any], message: str
) -> None:
    before = client.get("/v1/sessions").json()["sessions"]
    response = client.post("/v1/sessions", json=spec)
    assert response.status_code == 422, response.text
    assert message in response.text
    assert client.get("/v1/sessions").json()["sessions"] == before


@pytest.mark.parametrize(
    ("objects", "message"),
    [
        ([{"box": [1000, 1000, 1100, 1100]}], "outside the frame"),
        ([{"circle": {"center": [900, 900], "radius": 20}}], "outside the frame"),
        (
            [{"mask": png(np.full((100, 100), 255, np.uint8))}],
            "its mask is 100x100, the frame 320x240",
        ),
    ],
)
def test_what_the_first_frame_refutes_is_a_422_that_changes_nothing(
    client: TestClient, objects: list[dict[str, Any]], message: str
) -> None:
    sid = client.post("/v1/sessions", json={"objects": [{"box": BOX}, *objects]}).json()["id"]
    before = unchanged_part(client.get(f"/v1/sessions/{sid}").json())
    refused = frame(client, sid, (160.0, 120.0))
    assert refused.status_code == 422
    assert message in refused.text
    assert unchanged_part(client.get(f"/v1/sessions/{sid}").json()) == before


def test_an_object_snapped_onto_a_line_is_a_422_that_changes_nothing(client: TestClient) -> None:
    """A box whose snap finds only a one-pixel line (no area to track) refuses the frame
    before any object changed; not a 400 for the image, not half the objects placed."""
    decoded = cv2.imdecode(np.frombuffer(disc_frame(160.0, 120.0), np.uint8), cv2.IMREAD_COLOR)
    assert decoded is not None
    image = np.ascontiguousarray(decoded)
    cv2.line(image, (20, 20), (140, 20), (0, 0, 255), 1)
    body = cv2.imencode(".png", image)[1].tobytes()
    spec = {"objects": [{"box": BOX}, {"id": "line", "box": [20, 19, 141, 22]}]}
    sid = client.post("/v1/sessions", json=spec).json()["id"]
    before = unchanged_part(client.get(f"/v1/sessions/{sid}").json())
    refused = client.post(
        f"/v1/sessions/{sid}/frames", content=body, headers={"content-type": "image/png"}
    )
    assert refused.status_code == 422, refused.text
    assert "object 'line': snap" in refused.json()["error"]["message"]
    assert unchanged_part(client.get(f"/v1/sessions/{sid}").json()) == before


def test_single_contour_sessions_have_no_objects(client: TestClient) -> None:
    sid = client.post("/v1/sessions", json={"circle": {"center": [160, 120], "radius": 40}}).json()[
        "id"
    ]
    assert "objects" not in client.get(f"/v1/sessions/{sid}").json()
    assert "objects" not in frame(client, sid, (160.0, 120.0)).json()
    refused = client.post(f"/v1/sessions/{sid}/objects", json={"box": BOX})
    assert refused.status_code == 422
    assert "one contour" in refused.text
    several = client.post("/v1/sessions", json={"objects": [{"box": BOX}]}).json()["id"]
    forces = client.post(f"/v1/sessions/{several}/forces", json={"forces": [[0, 0]] * 64})
    assert forces.status_code == 422


def test_objects_over_the_websocket(client: TestClient) -> None:
    sid = client.post("/v1/sessions", json={"objects": [{"box": BOX}]}).json()["id"]
    with client.websocket_connect(f"/v1/sessions/{sid}/stream") as ws:
        ws.send_bytes(disc_frame(160.0, 120.0))
        message = ws.receive_json()
    assert message["type"] == "frame"
    assert iou(message["objects"][0]["nodes"], (160, 120)) > 0.9


def test_a_session_of_objects_survives_the_shared_store_record() -> None:
    from service.schemas import SessionCreate
    from service.sessions import Session

    spec = SessionCreate.model_validate(
        {"objects": [{"box": BOX}, {"id": "b", "circle": {"center": [40, 40], "radius": 15}}]}
    )
    session = Session.create(spec, None, max_nodes=4096)
    image = cv2.imdecode(np.frombuffer(disc_frame(160.0, 120.0), np.uint8), cv2.IMREAD_COLOR)
    restored = Session.from_record(session.to_record(compact=True))
    assert restored.objects is not None
    assert restored.objects.waiting["1"]["snap"] == BOX  # the snap still waits
    result = restored.track(np.asarray(image, np.uint8))
    assert iou(result["objects"][0]["nodes"], (160, 120)) > 0.9
    again = Session.from_record(restored.to_record())
    assert again.objects is not None  # the box is snapped again on the next frame
    assert again.objects.waiting == {"1": {"again": BOX}}
    assert again.objects.first is not None
    np.testing.assert_array_equal(again.objects.first, image)
    after = cv2.imdecode(np.frombuffer(disc_frame(165.0, 122.0), np.uint8), cv2.IMREAD_COLOR)
    again.track(np.asarray(after, np.uint8))
    done = Session.from_record(again.to_record())
    assert done.objects is not None
    assert done.objects.waiting == {}
    assert done.objects.first is None


def test_boxes_snap_again_on_the_second_frame_as_efdm_track_starts_them(
    client: TestClient,
) -> None:
    """From the second frame on, a session of objects tracks what an ObjectsTracker started
    from the snaps with the next frame tracks; a correction before it wins."""
    from engine.geometry import mask_to_contours
    from engine.tracking import ObjectsTracker
    from engine.tracking.snap import snap
    from tests.engine.scenes import decoy_scene

    first, second, truth, _ = decoy_scene()
    frames = [cv2.imencode(".png", f)[1].tobytes() for f in (first, second, second)]
    ys, xs = np.nonzero(truth)
    box = [int(xs.min()), int(ys.min()), int(xs.max()) + 1, int(ys.max()) + 1]
    other = [10, 120, 50, 160]  # a box on the background: snapped too, a contour all the same
    png = {"content-type": "image/png"}
    objects = [{"box": box}, {"id": "b", "box": other}, {"id": "c", "box": other}]
    sid = client.post("/v1/sessions", json={"objects": objects}).json()["id"]
    url = f"/v1/sessions/{sid}"
    answers = [client.post(f"{url}/frames", content=frames[0], headers=png).json()]
    fixed = [[12, 122], [48, 122], [48, 158], [12, 158]]
    put = client.put(f"{url}/objects/c", json={"nodes": fixed, "snap": False})
    assert put.status_code == 200, put.text
    answers += [client.post(f"{url}/frames", content=f, headers=png).json() for f in frames[1:]]

    def contours(mask: np.ndarray) -> list[np.ndarray]:
        return mask_to_contours(mask, 64, min_area=100.0)

    library = ObjectsTracker(
        {
            "1": contours(snap(first, box, next_frame=second)),
            "b": contours(snap(first, other, next_frame=second)),
        }
    )
    library.step(first)
    library.add("c", fixed)
    for answer, frame in zip(answers[1:], (second, second), strict=True):
        expected = library.step(frame)
        for got, want in zip(answer["objects"], expected, strict=True):
            assert got["id"] == str(want.id)
            shape = got["nodes"] if "nodes" in got else got["contours"]
            mine = [shape] if "nodes" in got else shape
            assert len(mine) == len(want.contours)
            for a, b in zip(mine, want.contours, strict=True):
                np.testing.assert_allclose(a, b)


def test_the_python_client_tracks_several_objects(live_server: LiveServer) -> None:
    from service.client import Client

    image = cv2.imdecode(np.frombuffer(disc_frame(160.0, 120.0), np.uint8), cv2.IMREAD_COLOR)
    with Client(live_server.url) as api:
        session = api.create_session(objects=[{"box": BOX}, {"id": "b", "box": [20, 20, 60, 60]}])
        result = api.track_frame(session, np.asarray(image, np.uint8))
    assert [o["id"] for o in result.objects] == ["1", "b"]
    assert iou(result.objects[0]["nodes"].tolist(), (160, 120)) > 0.9
    assert not result.objects[0]["nodes"].flags.writeable


def test_objects_are_changed_by_control_messages_mid_stream(client: TestClient) -> None:
    sid = client.post("/v1/sessions", json={"objects": [{"box": BOX}]}).json()["id"]
    with client.websocket_connect(f"/v1/sessions/{sid}/stream?mode=every") as ws:
        ws.send_bytes(disc_frame(160.0, 120.0))
        assert [o["id"] for o in ws.receive_json()["objects"]] == ["1"]
        ws.send_json({"add_object": {"id": "b", "circle": {"center": [280, 200], "radius": 20}}})
        added = ws.receive_json()
        assert (added["type"], added["id"], len(added["nodes"])) == ("object", "b", 64)
        ws.send_json(
            {
                "replace_object": {
                    "id": "1",
                    "circle": {"center": [162, 120], "radius": 40, "count": 40},
                }
            }
        )
        assert ws.receive_json()["id"] == "1"
        ws.send_bytes(disc_frame(162.0, 120.0))
        result = ws.receive_json()
        assert [o["id"] for o in result["objects"]] == ["1", "b"]
        assert len(result["objects"][0]["nodes"]) == 40  # the correction, on the next frame
        ws.send_json({"remove_object": "b"})
        assert ws.receive_json()["removed"] is True
        ws.send_json({"remove_object": "zz"})
        missing = ws.receive_json()
        assert (missing["type"], missing["error"]["code"]) == ("error", "object_not_found")
        ws.send_json({"replace_object": {"circle": {"center": [1, 1], "radius": 3}}})
        assert "give the object's 'id'" in ws.receive_json()["error"]["message"]
        ws.send_json({"add_object": {"box": [1, 1, 0, 0]}})  # the control is named, no stray ": "
        assert ws.receive_json()["error"]["message"].startswith("add_object: ")
        ws.send_json({"add_object": "x"})
        assert ws.receive_json()["error"]["message"].startswith("add_object: ")
        ws.send_bytes(disc_frame(164.0, 120.0))
        assert [o["id"] for o in ws.receive_json()["objects"]] == ["1"]
