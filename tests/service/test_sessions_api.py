"""``/v1/sessions`` over REST: create, read, delete, forces and frames."""

from __future__ import annotations

import re
import time
from datetime import UTC, datetime
from typing import Any

import cv2
import numpy as np
import pytest
from fastapi.testclient import TestClient
from numpy.typing import NDArray

from engine import Tracker, deform
from engine.geometry import circle_nodes
from service.settings import Settings
from tests.service.conftest import disc_frame

CIRCLE: dict[str, Any] = {"circle": {"center": [160, 120], "radius": 40}}
POLYGON: list[list[float]] = [
    [100.0, 80.0],
    [180.0, 70.0],
    [230.0, 120.0],
    [200.0, 170.0],
    [120.0, 160.0],
    [90.0, 120.0],
]
METHODS = ["exact", "efdm", "efdmt", "dmma", "dmmat"]


def create(client: TestClient, spec: dict[str, Any] | None = None) -> dict[str, Any]:
    response = client.post("/v1/sessions", json=CIRCLE if spec is None else spec)
    assert response.status_code == 201, response.text
    body: dict[str, Any] = response.json()
    return body


def bgr(data: bytes) -> NDArray[np.uint8]:
    """Decode an encoded frame as the library's users would."""
    image = cv2.imdecode(np.frombuffer(data, np.uint8), cv2.IMREAD_COLOR)
    assert image is not None
    return np.asarray(image, dtype=np.uint8)


def encoded(kind: str, cx: float = 160, cy: float = 120) -> bytes:
    """The disc frame as ``kind`` (jpeg, png or webp)."""
    jpeg = disc_frame(cx, cy)
    if kind == "jpeg":
        return jpeg
    ok, data = cv2.imencode(f".{kind}", bgr(jpeg))
    assert ok
    return data.tobytes()


def post_frame(
    client: TestClient, sid: str, data: bytes, media_type: str = "image/jpeg", **headers: str
) -> Any:
    return client.post(
        f"/v1/sessions/{sid}/frames", content=data, headers={"content-type": media_type, **headers}
    )


def error_of(response: Any, status: int) -> dict[str, Any]:
    assert response.status_code == status, response.text
    assert response.headers["content-type"].startswith("application/json")
    error: dict[str, Any] = response.json()["error"]
    assert error["status"] == status
    assert isinstance(error["code"], str)
    assert isinstance(error["message"], str)
    assert error["message"]
    return error


def as_array(value: Any) -> NDArray[np.float64]:
    return np.asarray(value, dtype=np.float64)


# -- create, read, delete ---------------------------------------------------------------------


def test_create_with_nodes(client: TestClient, settings: Settings) -> None:
    response = client.post(
        "/v1/sessions", json={"nodes": POLYGON, "stiffness": 25, "method": "efdm"}
    )
    assert response.status_code == 201
    body = response.json()
    assert response.headers["location"] == f"/v1/sessions/{body['id']}"
    assert response.headers["etag"] == '"1"'
    assert set(body) == {
        "id",
        "nodes",
        "closed",
        "stiffness",
        "method",
        "tracking",
        "frame_index",
        "version",
        "expires_at",
    }
    assert body["closed"] is True
    assert body["stiffness"] == 25
    assert body["method"] == "efdm"
    assert body["tracking"] == {}
    assert (body["frame_index"], body["version"]) == (-1, 1)
    nodes = as_array(body["nodes"])
    assert nodes.shape == (len(POLYGON), 2)
    # closed contours are resampled evenly by arc length, as the tracker does
    assert np.array_equal(nodes, Tracker(POLYGON).nodes)
    assert not np.array_equal(nodes, as_array(POLYGON))
    expires = datetime.strptime(body["expires_at"], "%Y-%m-%dT%H:%M:%SZ").replace(tzinfo=UTC)
    assert abs(expires.timestamp() - (time.time() + settings.session_ttl_seconds)) < 5


def test_create_open_chain_keeps_the_nodes(client: TestClient) -> None:
    body = create(client, {"nodes": POLYGON, "closed": False})
    assert body["closed"] is False
    assert body["nodes"] == POLYGON


def test_create_with_circle(client: TestClient) -> None:
    body = create(client, {"circle": {"center": [150, 110], "radius": 30, "count": 24}})
    nodes = as_array(body["nodes"])
    assert nodes.shape == (24, 2)
    assert np.allclose(np.hypot(nodes[:, 0] - 150, nodes[:, 1] - 110), 30)
    assert len(create(client)["nodes"]) == 64  # default count


def test_a_circle_reaching_beyond_the_coordinate_limit_is_a_422(client: TestClient) -> None:
    """Found by the schema fuzzer: the nodes would exceed the limit the responses promise."""
    response = client.post(
        "/v1/sessions", json={"circle": {"center": [0.0, 999999101.0], "radius": 900.0}}
    )
    assert response.status_code == 422
    assert "within" in response.text


@pytest.mark.parametrize(
    ("spec", "around"),
    [
        ({"circle": {"center": [160, 120], "radius": 1e6}}, True),
        ({"box": [-1e8, -1e8, 1e8, 1e8], "snap": False}, True),
        ({"nodes": [[0, 0], [1e7, 0], [1e7, 1e7]]}, False),  # a corner and a side in view
    ],
    ids=["radius 1e6", "box 1e8", "triangle 1e7"],
)
def test_a_contour_far_larger_than_the_frames_is_tracked_not_a_500(
    client: TestClient, spec: dict[str, Any], around: bool
) -> None:
    """Found by an audit: its colour windows once asked for more memory than there is, a 500
    on every frame of the session.  One around the whole frame shows none of its boundary:
    ``lost``."""
    sid = create(client, spec)["id"]
    for cx in (160, 163, 166):
        response = post_frame(client, sid, disc_frame(cx, 120))
        assert response.status_code == 200, response.text
        if around:
            assert response.json()["status"] == "lost"


@pytest.mark.parametrize(
    "spec",
    [
        {"nodes": [[100, 200], [300, 200], [500, 200]]},
        {"circle": {"center": [160, 120], "radius": 0.01}},
    ],
    ids=["on a line", "within a pixel"],
)
def test_a_contour_enclosing_no_area_is_a_422(client: TestClient, spec: dict[str, Any]) -> None:
    error = error_of(client.post("/v1/sessions", json=spec), 422)
    assert "no area" in error["message"]


def test_session_ids_are_unguessable(client: TestClient) -> None:
    ids = [create(client)["id"] for _ in range(20)]
    assert len(set(ids)) == len(ids)
    for sid in ids:
        assert len(sid) >= 16
        assert re.fullmatch(r"[A-Za-z0-9_-]+", sid)


def test_get_returns_the_session(client: TestClient) -> None:
    created = client.post("/v1/sessions", json={"nodes": POLYGON, "stiffness": 3})
    sid = created.json()["id"]
    response = client.get(created.headers["location"])
    assert response.status_code == 200
    assert response.headers["etag"] == '"1"'
    body = response.json()
    assert {k: v for k, v in body.items() if k != "expires_at"} == {
        k: v for k, v in created.json().items() if k != "expires_at"
    }
    assert body["id"] == sid


def test_list_sessions_a_page_at_a_time(client: TestClient) -> None:
    ids = sorted(create(client)["id"] for _ in range(5))
    client.post(f"/v1/sessions/{ids[0]}/frames", content=encoded("jpeg"))
    seen: list[dict[str, Any]] = []
    url: str | None = "/v1/sessions?limit=2"
    pages = 0
    while url is not None:
        response = client.get(url)
        assert response.status_code == 200
        body = response.json()
        seen += body["sessions"]
        pages += 1
        link = response.headers.get("link")
        assert (link is None) == (body["next"] is None)
        url = None if link is None else re.fullmatch(r'<(.+)>; rel="next"', link)[1]  # type: ignore[index]
    assert pages == 3
    assert [s["id"] for s in seen] == ids
    first = seen[0]
    assert (first["frame_index"], first["version"]) == (0, 2)
    # the listing reports the expiry the session itself does; reading the session touches
    # it (a sliding expiry) and listing does not, so read first, then list
    shown = client.get(f"/v1/sessions/{ids[0]}").json()["expires_at"]
    listed = client.get("/v1/sessions", params={"limit": 1}).json()["sessions"][0]
    assert (listed["id"], listed["expires_at"]) == (ids[0], shown)
    after = client.get("/v1/sessions", params={"after": ids[2]}).json()
    assert [s["id"] for s in after["sessions"]] == ids[3:]
    assert after["next"] is None


@pytest.mark.parametrize("query", ["limit=0", "limit=501", "limit=x", "after=" + "a" * 65])
def test_list_sessions_rejects_bad_paging(client: TestClient, query: str) -> None:
    error_of(client.get(f"/v1/sessions?{query}"), 422)


def test_delete(client: TestClient) -> None:
    sid = create(client)["id"]
    response = client.delete(f"/v1/sessions/{sid}")
    assert response.status_code == 204
    assert response.content == b""
    assert error_of(client.get(f"/v1/sessions/{sid}"), 404)["code"] == "not_found"
    error_of(client.delete(f"/v1/sessions/{sid}"), 404)
    error_of(client.post(f"/v1/sessions/{sid}/forces", json={"forces": [[0, 0]] * 64}), 404)
    error_of(post_frame(client, sid, disc_frame(160, 120)), 404)


def test_unknown_session_is_not_found(client: TestClient) -> None:
    error = error_of(client.get("/v1/sessions/AAAAAAAAAAAAAAAAAAAAAA"), 404)
    assert error["code"] == "not_found"


def test_unknown_route_is_a_json_404(client: TestClient) -> None:
    error_of(client.get("/v1/nothing/here"), 404)


def test_method_not_allowed_lists_the_allowed_methods(client: TestClient) -> None:
    """RFC 9110 15.5.6: a 405 carries Allow with every method the resource supports."""
    sid = create(client)["id"]
    response = client.put(f"/v1/sessions/{sid}", json={})
    error_of(response, 405)
    allowed = {m.strip() for m in response.headers["allow"].split(",")}
    assert {"GET", "DELETE"} <= allowed
    response = client.put("/v1/sessions", json={})
    error_of(response, 405)
    assert {"GET", "POST"} <= {m.strip() for m in response.headers["allow"].split(",")}


# -- forces -----------------------------------------------------------------------------------


@pytest.mark.parametrize("method", METHODS)
@pytest.mark.parametrize("closed", [True, False], ids=["closed", "open"])
def test_forces_match_the_engine(client: TestClient, method: str, closed: bool) -> None:
    body = create(client, {"nodes": POLYGON, "closed": closed, "stiffness": 7, "method": method})
    rest = as_array(body["nodes"])
    forces = np.random.default_rng(5).normal(0, 20, rest.shape)
    response = client.post(f"/v1/sessions/{body['id']}/forces", json={"forces": forces.tolist()})
    assert response.status_code == 200, response.text
    assert response.headers["etag"] == '"2"'
    out = response.json()
    assert out["version"] == 2
    U = deform(forces, 7, closed=closed, method=method)
    assert np.array_equal(as_array(out["displacements"]), U)
    assert np.array_equal(as_array(out["nodes"]), rest + U)
    after = client.get(f"/v1/sessions/{body['id']}").json()
    assert after["nodes"] == out["nodes"]
    assert after["version"] == 2


def test_forces_act_on_the_rest_shape_not_cumulatively(client: TestClient) -> None:
    body = create(client, {"nodes": POLYGON})
    rest = as_array(body["nodes"])
    url = f"/v1/sessions/{body['id']}/forces"
    push = [[5.0, 0.0]] * len(POLYGON)
    first = client.post(url, json={"forces": push}).json()
    second = client.post(url, json={"forces": push}).json()
    assert second["nodes"] == first["nodes"]
    assert np.array_equal(as_array(second["nodes"]), rest + deform(as_array(push), 10.0))
    assert second["version"] == 3


def test_the_frame_after_forces_says_tracking_restarted(client: TestClient) -> None:
    sid = create(client)["id"]
    for cx in (160, 162):
        assert post_frame(client, sid, disc_frame(cx, 120)).json()["reset"] is None
    push = [[2.0, 0.0]] * 64
    assert client.post(f"/v1/sessions/{sid}/forces", json={"forces": push}).status_code == 200
    after = post_frame(client, sid, disc_frame(164, 120)).json()
    assert after["reset"] == (
        "the contour was moved by forces: tracking restarted from it on this frame"
    )
    assert post_frame(client, sid, disc_frame(166, 120)).json()["reset"] is None


@pytest.mark.parametrize(
    "forces",
    [
        [[1e9, 1e9]] * 6,  # each node pushed to just past the limit
        [[-1e9, -1e9]] * 6,
    ],
)
def test_forces_past_the_coordinate_limit_are_refused_and_change_nothing(
    client: TestClient, forces: list[list[float]]
) -> None:
    """Once a 200 with nodes past the limit, then a 500 on every later GET."""
    session = create(client, {"nodes": POLYGON, "closed": False})
    sid = session["id"]
    before = client.get(f"/v1/sessions/{sid}").json()
    error = error_of(client.post(f"/v1/sessions/{sid}/forces", json={"forces": forces}), 422)
    assert "unchanged" in error["message"]
    after = client.get(f"/v1/sessions/{sid}")
    assert after.status_code == 200
    unchanged = {k: v for k, v in after.json().items() if k != "expires_at"}
    assert unchanged == {k: v for k, v in before.items() if k != "expires_at"}
    # the session goes on as before
    assert (
        client.post(f"/v1/sessions/{sid}/forces", json={"forces": [[1, 0]] * 6}).status_code == 200
    )


def test_a_frame_whose_result_would_pass_the_limit_changes_nothing(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """Near the limit a step is undone if its contour would leave the bounds."""
    from engine.tracking import TrackResult
    from service.domain_errors import InvalidInputError
    from service.schemas import LIMIT, SessionCreate
    from service.sessions import Session

    far = [[LIMIT - 100.0 + x, LIMIT - 100.0 + y] for x, y in ((0, 0), (40, 0), (40, 40), (0, 40))]
    session = Session.create(SessionCreate(nodes=far), None, 64)
    frame = np.zeros((48, 64, 3), np.uint8)
    tracker = session.tracker
    assert tracker is not None
    # the first frame, started directly: a session refuses a contour outside its first frame
    tracker.step(frame)
    session.frame_index, session.frame_size = 0, (64, 48)
    state, version = tracker.to_state(), session.version
    step = tracker.step

    def overshoot(image: NDArray[np.uint8]) -> TrackResult:
        result = step(image)
        return TrackResult(
            result.nodes + 200.0,
            result.iterations,
            result.converged,
            result.confidence,
            result.status,
        )

    monkeypatch.setattr(tracker, "step", overshoot)
    with pytest.raises(InvalidInputError, match="unchanged"):
        session.track(frame)
    assert session.version == version
    assert session.tracker is not None
    assert session.tracker.to_state() == state


def test_forces_on_the_shortest_open_chain(client: TestClient) -> None:
    body = create(client, {"nodes": [[0, 0], [10, 0]], "closed": False, "stiffness": 1})
    out = client.post(f"/v1/sessions/{body['id']}/forces", json={"forces": [[1, 0], [-1, 0]]})
    assert out.status_code == 200
    U = deform([[1.0, 0.0], [-1.0, 0.0]], 1.0, closed=False)
    assert np.array_equal(as_array(out.json()["displacements"]), U)
    assert out.json()["nodes"][0][0] > 0  # pulled together, less than freely


# -- frames -----------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("kind", "media_type"),
    [
        ("jpeg", "image/jpeg"),
        ("png", "image/png"),
        ("webp", "image/webp"),
        ("jpeg", "application/octet-stream"),
        ("png", "application/octet-stream"),
    ],
)
def test_frames_raw(client: TestClient, kind: str, media_type: str) -> None:
    sid = create(client)["id"]
    response = post_frame(client, sid, encoded(kind), media_type)
    assert response.status_code == 200, response.text
    assert response.headers["etag"] == '"2"'
    out = response.json()
    assert set(out) == {
        "frame_index",
        "nodes",
        "iterations",
        "converged",
        "confidence",
        "status",
        "reset",
        "version",
        "elapsed_ms",
    }
    assert out["status"] == "tracking"  # the first frame returns the contour as given
    assert out["reset"] is None
    assert (out["frame_index"], out["version"]) == (0, 2)
    assert len(out["nodes"]) == 64
    assert isinstance(out["iterations"], int)
    assert isinstance(out["converged"], bool)
    assert 0 <= out["confidence"] <= 1
    assert out["elapsed_ms"] >= 0
    moved = post_frame(client, sid, encoded(kind, 165, 122), media_type).json()
    centre = as_array(moved["nodes"]).mean(axis=0)
    assert np.hypot(centre[0] - 165, centre[1] - 122) < 2


@pytest.mark.parametrize("kind", ["jpeg", "png", "webp"])
def test_frames_multipart(client: TestClient, kind: str) -> None:
    sid = create(client)["id"]
    response = client.post(
        f"/v1/sessions/{sid}/frames",
        files={"file": (f"frame.{kind}", encoded(kind), f"image/{kind}")},
    )
    assert response.status_code == 200, response.text
    assert response.json()["frame_index"] == 0


def test_multipart_needs_a_file_field_named_file(client: TestClient) -> None:
    sid = create(client)["id"]
    url = f"/v1/sessions/{sid}/frames"
    wrong_name = client.post(url, files={"image": ("f.jpg", disc_frame(160, 120), "image/jpeg")})
    assert error_of(wrong_name, 422)["code"] == "invalid"
    not_a_file = client.post(
        url, data={"file": "not a file"}, files={"other": ("f.jpg", b"x", "image/jpeg")}
    )
    error_of(not_a_file, 422)
    text_file = client.post(url, files={"file": ("f.txt", b"hello", "text/plain")})
    assert error_of(text_file, 415)["code"] == "unsupported_media_type"
    broken = client.post(
        url,
        content=b"--xyz\r\nContent-Disposition: form-data; name=file\r\n\r\nabc",
        headers={"content-type": "multipart/form-data; boundary=xyz"},
    )
    assert 400 <= broken.status_code < 500
    no_boundary = client.post(
        url, content=b"abc", headers={"content-type": "multipart/form-data"}
    )  # Starlette refuses it: one of the service's codes, not its generic http_error
    assert error_of(no_boundary, 400)["code"] == "bad_request"
    two_files = client.post(
        url,
        files=[("file", ("a.jpg", b"x", "image/jpeg")), ("file", ("b.jpg", b"y", "image/jpeg"))],
    )
    assert error_of(two_files, 400)["code"] == "bad_request"
    assert client.get(f"/v1/sessions/{sid}").json()["frame_index"] == -1


def test_frame_index_and_version_increment(client: TestClient) -> None:
    sid = create(client)["id"]
    for i in range(4):
        response = post_frame(client, sid, disc_frame(160 + i, 120))
        out = response.json()
        assert (out["frame_index"], out["version"]) == (i, i + 2)
        assert response.headers["etag"] == f'"{i + 2}"'
    session = client.get(f"/v1/sessions/{sid}")
    assert session.json()["frame_index"] == 3
    assert session.json()["version"] == 5
    assert session.json()["nodes"] == out["nodes"]
    assert session.headers["etag"] == '"5"'


def test_frames_on_an_open_contour_are_refused(client: TestClient) -> None:
    sid = create(client, {"nodes": POLYGON, "closed": False})["id"]
    error = error_of(post_frame(client, sid, disc_frame(160, 120)), 422)
    assert error["code"] == "invalid"
    assert "closed" in error["message"]


# -- If-Match ---------------------------------------------------------------------------------


def test_if_match_on_forces(client: TestClient) -> None:
    body = create(client, {"nodes": POLYGON})
    url = f"/v1/sessions/{body['id']}/forces"
    forces = {"forces": [[1, 1]] * len(POLYGON)}
    stale = client.post(url, json=forces, headers={"if-match": '"7"'})
    assert error_of(stale, 412)["code"] == "version_mismatch"
    assert client.get(f"/v1/sessions/{body['id']}").json()["version"] == 1  # unchanged
    current = client.post(url, json=forces, headers={"if-match": '"1"'})
    assert current.status_code == 200
    assert current.headers["etag"] == '"2"'
    error_of(client.post(url, json=forces, headers={"if-match": '"1"'}), 412)  # now stale
    assert client.post(url, json=forces, headers={"if-match": "*"}).status_code == 200
    assert client.post(url, json=forces, headers={"if-match": 'W/"3"'}).status_code == 200
    assert client.post(url, json=forces, headers={"if-match": "4"}).status_code == 200


def test_if_match_on_frames(client: TestClient) -> None:
    sid = create(client)["id"]
    frame = disc_frame(160, 120)
    error_of(post_frame(client, sid, frame, **{"if-match": '"2"'}), 412)
    assert client.get(f"/v1/sessions/{sid}").json()["frame_index"] == -1
    ok = post_frame(client, sid, frame, **{"if-match": '"1"'})
    assert ok.status_code == 200
    etag = ok.headers["etag"]
    assert post_frame(client, sid, frame, **{"if-match": etag}).status_code == 200
    error_of(post_frame(client, sid, frame, **{"if-match": etag}), 412)
    assert post_frame(client, sid, frame, **{"if-match": "*"}).status_code == 200


# -- tracking options -------------------------------------------------------------------------


def test_tracking_options_are_passed_to_the_tracker(client: TestClient) -> None:
    # without the band cut the chain's contour, which the stiffness shapes, is the result
    tracking = {"stiffness": 30, "cut_band": 0}
    body = create(client, {**CIRCLE, "tracking": tracking})
    assert body["tracking"] == tracking
    frames = [disc_frame(160 + 3 * i, 120 + 2 * i) for i in range(3)]
    for data in frames:
        out = post_frame(client, body["id"], data).json()
    decoded = [bgr(f) for f in frames]
    results = {}
    for stiffness in (30.0, 40.0):
        tracker = Tracker(circle_nodes((160, 120), 40, 64), stiffness=stiffness, cut_band=0)
        for img in decoded:
            nodes = tracker.step(img).nodes
        results[stiffness] = nodes
    assert not np.array_equal(results[30.0], results[40.0])  # the option matters here
    assert np.array_equal(as_array(out["nodes"]), results[30.0])


@pytest.mark.parametrize(
    "tracking",
    [
        {"stiffness": 0},
        {"stiffness": -1},
        {"stiffness": "stiff"},
        {"iterations": 0},
        {"iterations": 1.5},
        {"search_radius": 10_000},
        {"occlusion": "yes"},
        {"lighting": "maybe"},
        {"learning_rate": 2},
        {"no_such_option": 1},
        {"nodes": [[0, 0]]},
        {"closed": False},
    ],
)
def test_invalid_tracking_options(client: TestClient, tracking: dict[str, Any]) -> None:
    error = error_of(client.post("/v1/sessions", json={**CIRCLE, "tracking": tracking}), 422)
    assert error["code"] == "invalid"
    assert error["message"].startswith("tracking")


@pytest.mark.parametrize(
    "spec",
    [
        {},
        {**CIRCLE, "nodes": POLYGON},
        {**CIRCLE, "extra": 1},
        {**CIRCLE, "method": "fastest"},
        {**CIRCLE, "closed": "maybe"},
        {"circle": {"center": [0, 0]}},
        {"circle": {"center": [0, 0], "radius": -1}},
        {"circle": {"center": [0, 0], "radius": 5, "count": 2}},
        {"circle": {"center": [0], "radius": 5}},
        {"nodes": [[0, 0, 0], [1, 1, 1], [2, 2, 2]]},
        {"nodes": "0,0 1,1 2,2"},
        {"nodes": [["a", "b"], [1, 1], [2, 2]]},
    ],
)
def test_invalid_session_specs(client: TestClient, spec: dict[str, Any]) -> None:
    assert error_of(client.post("/v1/sessions", json=spec), 422)["code"] == "invalid"


@pytest.mark.parametrize(
    ("body", "where"), [(b"{not json", "character 1"), (b'{"nodes": [[1, 2],]}', "character 18")]
)
def test_malformed_json_is_a_400_saying_where(client: TestClient, body: bytes, where: str) -> None:
    """As the README says: 400 for a body that is not JSON, 422 for JSON with bad values."""
    response = client.post(
        "/v1/sessions", content=body, headers={"content-type": "application/json"}
    )
    error = error_of(response, 400)
    assert error["code"] == "bad_json"
    assert "not valid JSON" in error["message"]
    assert where in error["message"]


def test_a_contour_outside_the_first_frame_is_a_422_that_changes_nothing(
    client: TestClient,
) -> None:
    """As a snapped box and an object of a session of several are refused."""
    sid = create(client, {"box": [5000, 5000, 5100, 5100], "snap": False})["id"]
    error = error_of(post_frame(client, sid, disc_frame(160, 120)), 422)
    assert error["message"].startswith("the contour lies outside the first frame (320")
    assert client.get(f"/v1/sessions/{sid}").json()["frame_index"] == -1


@pytest.mark.parametrize(
    ("body", "message"),
    [
        (b"", "the body is empty"),
        (b"[" * 100_000 + b"]" * 100_000, "error parsing the body"),  # nested too deep
        (b'{"nodes": "\xff\xfe"}', ""),  # not UTF-8
    ],
    ids=["empty", "nested", "not UTF-8"],
)
def test_bodies_that_are_not_json_are_all_bad_json(
    client: TestClient, body: bytes, message: str
) -> None:
    response = client.post(
        "/v1/sessions", content=body, headers={"content-type": "application/json"}
    )
    error = error_of(response, 400)
    assert error["code"] == "bad_json"
    assert message in error["message"]


@pytest.mark.parametrize("media_type", ["text/plain", "application/x-www-form-urlencoded"])
def test_json_sent_as_another_media_type_is_a_415(client: TestClient, media_type: str) -> None:
    body = b'{"circle": {"center": [160, 120], "radius": 40}}'
    response = client.post("/v1/sessions", content=body, headers={"content-type": media_type})
    error = error_of(response, 415)
    assert error["message"] == f"send the body as application/json; got {media_type}"


def test_a_frame_of_another_size_says_tracking_restarted(client: TestClient) -> None:
    sid = create(client)["id"]
    assert post_frame(client, sid, encoded("png")).json()["reset"] is None
    before = post_frame(client, sid, encoded("png", 163)).json()
    assert before["reset"] is None
    bigger = cv2.resize(bgr(encoded("png")), (400, 300))
    ok, data = cv2.imencode(".png", bigger)
    assert ok
    result = post_frame(client, sid, data.tobytes(), "image/png")
    assert result.status_code == 200
    assert result.json()["reset"] == (
        "frame size changed from 320\u00d7240 to 400\u00d7300: "
        "tracking restarted from the current contour"
    )
    assert result.json()["nodes"] == before["nodes"]  # as on a first frame: the contour as it was
    assert post_frame(client, sid, data.tobytes(), "image/png").json()["reset"] is None


@pytest.mark.parametrize("path", ["/docs", "/redoc"])
def test_the_api_docs_reference_no_other_host(client: TestClient, path: str) -> None:
    page = client.get(path)
    assert page.status_code == 200
    assert not re.findall(r"(?:https?:)?//[a-z0-9.-]+\.[a-z]{2,}", page.text)  # no CDN, no fonts
    assets = re.findall(r'(?:src|href)="([^"]+)"', page.text)
    assert assets
    for asset in assets:
        assert asset.startswith("/docs-assets/")
        assert client.get(asset).status_code == 200


def test_a_session_may_ask_for_a_shorter_life(client: TestClient, settings: Settings) -> None:
    def lifetime(body: dict[str, Any]) -> float:
        expires = datetime.fromisoformat(body["expires_at"])
        return (expires - datetime.now(UTC)).total_seconds()

    assert 100 < lifetime(create(client, {**CIRCLE, "ttl_seconds": 120})) <= 121
    longest = settings.session_ttl_seconds
    assert lifetime(create(client, {**CIRCLE, "ttl_seconds": 1e6})) <= longest + 1  # at most
    listed = client.get("/v1/sessions").json()["sessions"]
    assert sorted(round(lifetime(s), -1) for s in listed) == sorted([120.0, round(longest, -1)])
    for bad in (0, -5, "soon"):
        error_of(client.post("/v1/sessions", json={**CIRCLE, "ttl_seconds": bad}), 422)


def test_a_720p_camera_is_followed_in_its_own_pixels(client: TestClient) -> None:
    """Frames above 480 lines are tracked downscaled inside (``working_side``); the
    contour the API returns is in the posted frame's pixels."""
    sid = create(client, {"circle": {"center": [400, 360], "radius": 120}})["id"]
    for k in range(4):
        cx = 400.0 + 24.0 * k
        frame = disc_frame(cx, 360.0, r=120, shape=(720, 1280))
        body = post_frame(client, sid, frame).json()
        nodes = as_array(body["nodes"])
        centre = nodes.mean(axis=0)
        radius = np.linalg.norm(nodes - centre, axis=1).mean()
        assert abs(centre[0] - cx) < 3.0
        assert abs(centre[1] - 360.0) < 3.0
        assert abs(radius - 120.0) < 4.0
        assert body["reset"] is None
