"""End to end: the demo page at ``/`` in a real Chromium against a real server.

``?demo=synthetic`` (a red disc drawn by the page) is tracked from a dragged
box that snaps onto it, a dragged circle and a clicked polygon, and with other
objects beside it, one added mid-stream; a WebM file, Chromium's fake camera, a
missing camera and a server that needs an API key are driven too.  The
screenshot lands in ``test-artifacts/demo_page.png`` (and ``/tmp``).

The browser is Debian's ``/usr/bin/chromium`` driven by Playwright's sync API
(Playwright's own browser builds are never downloaded).  Without it the tests
skip, except under CI (``CI`` set), where they fail: CI must not skip silently.
"""

from __future__ import annotations

import contextlib
import math
import os
import shutil
import time
from collections.abc import Iterator
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

import cv2
import httpx
import numpy as np
import pytest
from playwright.sync_api import (
    Browser,
    ConsoleMessage,
    FloatRect,
    Page,
    Playwright,
    expect,
    sync_playwright,
)
from playwright.sync_api import TimeoutError as PlaywrightTimeout

from service.settings import Settings
from tests.service.conftest import LiveServer, disc_frame

CHROMIUM = Path("/usr/bin/chromium")
CHROMIUM_ARGS = [
    "--headless=new",
    "--no-sandbox",
    "--disable-gpu",
    "--disable-quic",
    "--no-first-run",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
]
ARTIFACTS = Path(__file__).resolve().parents[2] / "test-artifacts"
TIMEOUT_MS = 30_000
MAX_IN_FLIGHT = 2  # the page's default


@pytest.fixture(scope="module")
def playwright() -> Iterator[Playwright]:
    """Playwright's driver; skipped (failed under CI) when Debian's Chromium is missing."""
    if not CHROMIUM.exists():
        why = f"{CHROMIUM} is missing (apt-get install chromium)"
        if os.environ.get("CI"):
            pytest.fail(f"{why}: CI must run the browser test (.ci/run installs it)")
        pytest.skip(why)
    driver = sync_playwright().start()
    try:
        yield driver
    finally:
        driver.stop()


@contextlib.contextmanager
def launched(playwright: Playwright, *extra_args: str) -> Iterator[Browser]:
    """Debian's Chromium, headless."""
    chromium = playwright.chromium.launch(
        executable_path=str(CHROMIUM), args=[*CHROMIUM_ARGS, *extra_args]
    )
    try:
        yield chromium
    finally:
        chromium.close()


@pytest.fixture(scope="module")
def browser(playwright: Playwright) -> Iterator[Browser]:
    """One browser for the module's tests."""
    with launched(playwright) as chromium:
        yield chromium


@contextlib.contextmanager
def watched_page(browser: Browser) -> Iterator[Page]:
    """A page in a fresh context; console errors and uncaught exceptions fail the test."""
    context = browser.new_context(viewport={"width": 1280, "height": 860})
    page = context.new_page()
    page.set_default_timeout(TIMEOUT_MS)
    problems: list[str] = []

    def on_console(message: ConsoleMessage) -> None:
        # A refused request (the API-key test's 401) is logged by the browser itself.
        if message.type == "error" and "status of 401" not in message.text:
            problems.append(f"console: {message.text}")

    page.on("console", on_console)
    page.on("pageerror", lambda exc: problems.append(f"page error: {exc}"))
    try:
        yield page
    finally:
        context.close()
    assert not problems, problems


@pytest.fixture
def page(browser: Browser, live_server: LiveServer) -> Iterator[Page]:
    """A watched page, closed before the server stops."""
    with watched_page(browser) as page:
        yield page


def state(page: Page) -> dict[str, Any]:
    """A snapshot of ``window.efdmDemo``."""
    snapshot: dict[str, Any] = page.evaluate("() => JSON.parse(JSON.stringify(window.efdmDemo))")
    return snapshot


def source_geometry(page: Page) -> tuple[dict[str, float], float, FloatRect]:
    """The picture's centre (video px), CSS px per video px, and the overlay's page box."""
    box = page.locator("#overlay").bounding_box()
    assert box is not None
    width, height = page.evaluate(
        "() => ((c) => [c.width, c.height])(document.getElementById('overlay'))"
    )
    assert width > 0
    assert height > 0
    return {"x": width / 2, "y": height / 2}, box["width"] / width, box


def open_demo(page: Page, url: str) -> tuple[dict[str, float], float, FloatRect]:
    """Open the synthetic demo; the disc (video px), CSS px per video px, the overlay box."""
    page.goto(f"{url}/?demo=synthetic")
    page.wait_for_function("() => window.efdmDemo && window.efdmDemo.disc !== null")
    disc: dict[str, float] = state(page)["disc"]
    centre, scale, box = source_geometry(page)
    assert centre == {"x": 256, "y": 160}  # 512 x 320
    return disc, scale, box


def css_point(box: FloatRect, scale: float, x: float, y: float) -> tuple[float, float]:
    """Page coordinates of the video pixel ``[x, y]``."""
    return box["x"] + x * scale, box["y"] + y * scale


def drag(page: Page, start: tuple[float, float], end: tuple[float, float]) -> None:
    """Press at ``start``, move to ``end`` in steps, release (page coordinates)."""
    page.mouse.move(*start)
    page.mouse.down()
    page.mouse.move(*end, steps=6)
    page.mouse.up()


def draw_box(
    page: Page, box: FloatRect, scale: float, corners: tuple[float, float, float, float]
) -> None:
    """Drag a box from corner ``[x0, y0]`` to ``[x1, y1]`` (video px), the default shape."""
    x0, y0, x1, y1 = corners
    page.get_by_role("radio", name="a box").check()
    drag(page, css_point(box, scale, x0, y0), css_point(box, scale, x1, y1))


def draw_circle(page: Page, disc: dict[str, float], scale: float, box: FloatRect) -> None:
    """Press at the disc's centre and drag out a radius a little larger than the disc."""
    page.get_by_role("radio", name="a circle").check()
    cx, cy = css_point(box, scale, disc["x"], disc["y"])
    page.mouse.move(cx, cy)
    page.mouse.down()
    page.mouse.move(cx + (disc["r"] + 8) * scale, cy, steps=6)
    page.mouse.up()


def draw_polygon(page: Page, disc: dict[str, float], scale: float, box: FloatRect) -> None:
    """Click 16 points around the disc; double-click the last to close the polygon."""
    points = [
        css_point(
            box,
            scale,
            disc["x"] + (disc["r"] + 6) * math.cos(2 * math.pi * k / 16),
            disc["y"] + (disc["r"] + 6) * math.sin(2 * math.pi * k / 16),
        )
        for k in range(16)
    ]
    for x, y in points[:-1]:
        page.mouse.click(x, y)
    page.mouse.dblclick(*points[-1])


def wait_for_tracking(page: Page, start: dict[str, float], results: int = 10) -> dict[str, Any]:
    """Wait (bounded) for ``results`` results, the last of a disc moved >= 20 px; on a
    timeout, fail with the page's state (what arrived, the last contour, any error)."""
    try:
        page.wait_for_function(
            """([n, x0, y0]) => {
                const d = window.efdmDemo;
                if (d.lastError || d.closed) return true;  // fail fast below
                const disc = d.lastResultDisc;
                return d.results >= n && disc && Math.hypot(disc.x - x0, disc.y - y0) >= 20;
            }""",
            arg=[results, start["x"], start["y"]],
            timeout=TIMEOUT_MS,
        )
    except PlaywrightTimeout:
        raise AssertionError(
            f"no {results} tracked results with the disc moved 20 px from {start} within "
            f"{TIMEOUT_MS} ms; the page's state: {state(page)}"
        ) from None
    snapshot = state(page)
    assert snapshot["lastError"] is None, snapshot["lastError"]
    assert snapshot["closed"] is None, snapshot["closed"]
    return snapshot


def overlay_ring_pixels(page: Page) -> tuple[int, int]:
    """Bright green overlay pixels (within 6 px of the drawn contour's circle, elsewhere).

    Read in an animation frame callback, right after the page's own has drawn
    ``lastNodes``, so the pixels and the nodes belong together.
    """
    counts: list[int] = page.evaluate(
        """() => new Promise((resolve) => requestAnimationFrame(() => {
            const nodes = window.efdmDemo.lastNodes;
            const cx = nodes.reduce((s, p) => s + p[0], 0) / nodes.length;
            const cy = nodes.reduce((s, p) => s + p[1], 0) / nodes.length;
            const r = nodes.reduce((s, p) => s + Math.hypot(p[0] - cx, p[1] - cy), 0)
                / nodes.length;
            const c = document.getElementById('overlay');
            const px = c.getContext('2d').getImageData(0, 0, c.width, c.height).data;
            let near = 0, far = 0;
            for (let y = 0; y < c.height; y++) {
                for (let x = 0; x < c.width; x++) {
                    const i = 4 * (y * c.width + x);
                    const green = px[i + 3] > 200 && px[i + 1] > 200 && px[i] < 150;
                    if (!green) continue;
                    if (Math.abs(Math.hypot(x - cx, y - cy) - r) <= 6) near++; else far++;
                }
            }
            resolve([near, far]);
        }))"""
    )
    return counts[0], counts[1]


def check_tracked(page: Page, snapshot: dict[str, Any]) -> None:
    """Frames flowed, the contour follows the disc, and it is drawn on the overlay."""
    assert isinstance(snapshot["sessionId"], str)
    assert snapshot["sessionId"]
    assert snapshot["tracking"] is True
    assert snapshot["results"] >= 10
    # Every frame sent is answered, reported dropped, or still in flight (at most 2).
    unsettled = snapshot["sent"] - snapshot["results"] - snapshot["dropped"]
    assert 0 <= unsettled <= MAX_IN_FLIGHT, snapshot
    result = snapshot["lastResult"]
    assert result["frame_index"] >= 9
    assert 0 <= result["confidence"] <= 1
    nodes = snapshot["lastNodes"]
    assert len(nodes) >= 16
    disc = snapshot["lastResultDisc"]
    cx = sum(x for x, _ in nodes) / len(nodes)
    cy = sum(y for _, y in nodes) / len(nodes)
    radius = sum(math.hypot(x - cx, y - cy) for x, y in nodes) / len(nodes)
    # within 5 px of a 44 px disc: the page drops frames when the machine is busy, the
    # disc then moves further between the frames tracked, and the flat disc's contour
    # trails it by up to about 4 px (3.5 and 3.7 px seen at 0d5d975 under load)
    assert math.hypot(cx - disc["x"], cy - disc["y"]) < 5, (cx, cy, disc)
    assert abs(radius - disc["r"]) < 3, (radius, disc)
    near, far = overlay_ring_pixels(page)
    assert near > 150, (near, far)
    assert far < near / 10, (near, far)
    stats = {k: page.text_content(f"#stat-{k}") for k in ("fps", "latency", "frame")}
    assert stats["latency"] is not None
    assert stats["latency"].endswith(" ms"), stats


def stop(page: Page, url: str, session_id: str, key: str | None = None) -> None:
    """Stop closes the socket normally and deletes the session."""
    page.get_by_role("button", name="Stop").click()
    page.wait_for_function("() => !window.efdmDemo.tracking && window.efdmDemo.closed")
    assert state(page)["closed"]["code"] == 1000
    page.wait_for_function("() => document.getElementById('track').disabled === false")
    headers = {"Authorization": f"Bearer {key}"} if key else {}
    with httpx.Client(base_url=url, timeout=10, headers=headers) as http:
        assert http.get(f"/v1/sessions/{session_id}").status_code == 404


def screenshot(page: Page, name: str) -> Path:
    """Save a full-page screenshot under test-artifacts/ (git-ignored)."""
    ARTIFACTS.mkdir(exist_ok=True)
    path = ARTIFACTS / name
    page.screenshot(path=str(path), full_page=True)
    return path


def test_demo_page_tracks_a_circle(page: Page, live_server: LiveServer) -> None:
    disc, scale, box = open_demo(page, live_server.url)
    assert page.get_by_role("button", name="Track").is_disabled()
    draw_circle(page, disc, scale, box)
    page.get_by_role("button", name="Track").click()
    snapshot = wait_for_tracking(page, disc)
    check_tracked(page, snapshot)
    page.wait_for_function("() => /\\d/.test(document.getElementById('stat-fps').textContent)")
    shutil.copyfile(screenshot(page, "demo_page.png"), "/tmp/demo_page.png")
    stop(page, live_server.url, snapshot["sessionId"])


def test_demo_page_snaps_a_dragged_box_onto_the_disc(page: Page, live_server: LiveServer) -> None:
    disc, scale, box = open_demo(page, live_server.url)
    margin = 14.0  # a loose box: the snap finds the disc inside it
    x, y, r = disc["x"], disc["y"], disc["r"]
    draw_box(page, box, scale, (x - r - margin, y - r - margin, x + r + margin, y + r + 4))
    assert state(page)["outlines"] == 1
    page.get_by_role("button", name="Track").click()
    snapshot = wait_for_tracking(page, disc)
    check_tracked(page, snapshot)
    stop(page, live_server.url, snapshot["sessionId"])


def overlay_colour_near(page: Page, nodes: list[list[float]], colour: str) -> int:
    """Overlay pixels of ``colour`` (#rrggbb, +-40 per channel) within 4 px of ``nodes``' points."""
    count: int = page.evaluate(
        """([nodes, colour]) => new Promise((resolve) => requestAnimationFrame(() => {
            const want = [1, 3, 5].map((i) => parseInt(colour.slice(i, i + 2), 16));
            const c = document.getElementById('overlay');
            const px = c.getContext('2d').getImageData(0, 0, c.width, c.height).data;
            let n = 0;
            for (const [x, y] of nodes) {
                for (let dy = -4; dy <= 4; dy++) for (let dx = -4; dx <= 4; dx++) {
                    const u = Math.round(x) + dx, v = Math.round(y) + dy;
                    if (u < 0 || v < 0 || u >= c.width || v >= c.height) continue;
                    const i = 4 * (v * c.width + u);
                    if (px[i + 3] > 200 && want.every((w, k) => Math.abs(px[i + k] - w) <= 40)) n++;
                }
            }
            resolve(n);
        }))""",
        [nodes, colour],
    )
    return count


def test_demo_page_tracks_several_objects_and_adds_one_mid_stream(
    page: Page, live_server: LiveServer
) -> None:
    """The disc and a patch of background from the start (a third outline drawn and removed
    again); a third object joins while tracking, and the second is removed."""
    disc, scale, box = open_demo(page, live_server.url)
    page.get_by_label("Snap onto the object").uncheck()  # the patches have no object to snap to
    draw_circle(page, disc, scale, box)
    draw_box(page, box, scale, (20.0, 20.0, 70.0, 60.0))  # clear of the disc's path
    draw_box(page, box, scale, (20.0, 250.0, 70.0, 300.0))
    assert state(page)["outlines"] == 3
    expect(page.locator("#object-list li")).to_have_count(3)  # repainted 4 times a second
    page.get_by_role("button", name="Remove outline 3").click()  # a slip: gone
    assert state(page)["outlines"] == 2
    expect(page.locator("#object-list li")).to_have_count(2)
    page.get_by_role("button", name="Track").click()
    snapshot = wait_for_tracking(page, disc)
    objects = snapshot["lastObjects"]
    assert [o["id"] for o in objects] == ["1", "2"], objects
    assert snapshot["lastNodes"] == objects[0]["nodes"]
    check_tracked(page, snapshot)
    # each in its own colour: the disc green, the second blue
    assert overlay_colour_near(page, objects[1]["nodes"], "#4dc3ff") > 50
    draw_box(page, box, scale, (440.0, 250.0, 500.0, 305.0))
    page.wait_for_function(
        "() => (window.efdmDemo.lastResult?.objects || []).length === 3"
        " || window.efdmDemo.lastError"
    )
    snapshot = state(page)
    assert snapshot["lastError"] is None, snapshot["lastError"]
    assert snapshot["pendingObjects"] == 0
    third = snapshot["lastObjects"][2]
    assert third["id"] == "3"
    xs = [p[0] for p in third["nodes"]]
    assert min(xs) > 430, third
    assert max(xs) < 510, third
    expect(page.locator("#object-list li")).to_have_count(3)
    assert overlay_colour_near(page, third["nodes"], "#ff5ca8") > 50
    screenshot(page, "demo_page_objects.png")
    page.get_by_role("button", name="Remove object #2").click()  # mid-stream
    page.wait_for_function(
        "() => (window.efdmDemo.lastResult?.objects || []).map((o) => o.id).join() === '1,3'"
        " || window.efdmDemo.lastError"
    )
    snapshot = state(page)
    assert snapshot["lastError"] is None, snapshot["lastError"]
    expect(page.locator("#object-list li")).to_have_count(2)
    stop(page, live_server.url, snapshot["sessionId"])
    assert state(page)["outlines"] == 2  # the last contours, ready to be tracked again


def test_demo_page_tracks_a_polygon(page: Page, live_server: LiveServer) -> None:
    disc, scale, box = open_demo(page, live_server.url)
    draw_polygon(page, disc, scale, box)
    assert page.get_by_role("button", name="Close polygon").is_disabled()  # closed already
    page.get_by_role("button", name="Track").click()
    # A loose polygon of few nodes settles on the boundary more slowly than a circle of 64.
    snapshot = wait_for_tracking(page, disc, results=20)
    check_tracked(page, snapshot)
    screenshot(page, "demo_page_polygon.png")
    stop(page, live_server.url, snapshot["sessionId"])


def disc_video(path: Path, frames: int = 75, fps: int = 25) -> None:
    """A WebM (VP8) of the red disc moving right 1 px and down 0.3 px a frame from (120, 120)."""
    writer = cv2.VideoWriter(str(path), cv2.VideoWriter.fourcc(*"VP80"), fps, (320, 240))
    assert writer.isOpened(), "OpenCV cannot write VP8 WebM here"
    try:
        for i in range(frames):
            jpeg = np.frombuffer(disc_frame(120 + i, 120 + 0.3 * i), np.uint8)
            frame = cv2.imdecode(jpeg, cv2.IMREAD_COLOR)
            assert frame is not None
            writer.write(frame)
    finally:
        writer.release()


def test_demo_page_tracks_a_video_file(page: Page, live_server: LiveServer, tmp_path: Path) -> None:
    video = tmp_path / "disc.webm"
    disc_video(video)
    page.goto(live_server.url)
    page.get_by_label("Video file").set_input_files(video)
    page.wait_for_function("() => window.efdmDemo.source === 'file'")
    centre, scale, box = source_geometry(page)
    assert centre == {"x": 160, "y": 120}  # 320 x 240
    draw_circle(page, {"x": 120, "y": 120, "r": 40}, scale, box)
    page.get_by_role("button", name="Track").click()
    page.wait_for_function(
        "() => window.efdmDemo.results >= 10 && window.efdmDemo.lastResultTime > 0.8"
        " || window.efdmDemo.lastError || window.efdmDemo.closed"
    )
    snapshot = state(page)
    assert snapshot["lastError"] is None, snapshot["lastError"]
    nodes = snapshot["lastNodes"]
    i = snapshot["lastResultTime"] * 25  # the frame of the result, give or take one
    cx = sum(x for x, _ in nodes) / len(nodes)
    cy = sum(y for _, y in nodes) / len(nodes)
    assert math.hypot(cx - (120 + i), cy - (120 + 0.3 * i)) < 3, (cx, cy, i)
    stop(page, live_server.url, snapshot["sessionId"])


def test_demo_page_reports_a_missing_camera(page: Page, live_server: LiveServer) -> None:
    page.goto(live_server.url)
    page.get_by_role("button", name="Use camera").click()
    page.wait_for_function("() => window.efdmDemo.lastError !== null")
    assert "Cannot use the camera" in (page.text_content("#error") or "")
    assert state(page)["source"] is None
    assert page.get_by_role("button", name="Track").is_disabled()


def test_demo_page_streams_the_camera(playwright: Playwright, live_server: LiveServer) -> None:
    fake_camera = ("--use-fake-device-for-media-stream", "--use-fake-ui-for-media-stream")
    with launched(playwright, *fake_camera) as chromium, watched_page(chromium) as page:
        page.goto(live_server.url)
        page.get_by_role("button", name="Use camera").click()
        page.wait_for_function("() => window.efdmDemo.source === 'camera'")
        disc, scale, box = source_geometry(page)
        draw_circle(page, {"x": disc["x"], "y": disc["y"], "r": 60}, scale, box)
        page.get_by_role("button", name="Track").click()
        page.wait_for_function(
            "() => window.efdmDemo.results >= 5 || window.efdmDemo.lastError"
            " || window.efdmDemo.closed"
        )
        snapshot = state(page)
        assert snapshot["lastError"] is None, snapshot["lastError"]
        stop(page, live_server.url, snapshot["sessionId"])


class TestWithApiKeys:
    """A server that needs a key: REST sends the Bearer header, the socket ?api_key=."""

    @pytest.fixture
    def settings(self) -> Settings:
        return Settings(max_sessions=50, session_ttl_seconds=600, api_keys=("demo-key",))

    def test_the_key_field_is_used(self, page: Page, live_server: LiveServer) -> None:
        disc, scale, box = open_demo(page, live_server.url)
        draw_circle(page, disc, scale, box)
        page.get_by_role("button", name="Track").click()
        page.wait_for_function("() => window.efdmDemo.lastError !== null")
        assert "401" in (page.text_content("#error") or "")
        assert state(page)["sessionId"] is None

        page.get_by_label("API key").fill("demo-key")
        page.get_by_role("button", name="Track").click()
        snapshot = wait_for_tracking(page, disc, results=3)
        assert page.is_hidden("#error")
        stop(page, live_server.url, snapshot["sessionId"], key="demo-key")


@pytest.mark.parametrize(("path", "rendered"), [("/docs", ".swagger-ui .info"), ("/redoc", "h1")])
def test_the_api_docs_render_with_no_request_leaving_the_machine(
    page: Page, live_server: LiveServer, path: str, rendered: str
) -> None:
    """Swagger UI and ReDoc came from a CDN: blank on an air-gapped machine."""
    outside: list[str] = []

    def only_local(route: Any) -> None:
        url = route.request.url
        if url.startswith((live_server.url, "data:", "blob:")):
            route.continue_()
        else:
            outside.append(url)
            route.abort()

    page.route("**/*", only_local)
    page.goto(f"{live_server.url}{path}")
    page.locator(rendered).first.wait_for(state="visible")
    assert "efdm-tracker" in page.locator(rendered).first.inner_text()
    assert outside == []


@pytest.mark.parametrize("leave", ["close", "reload"])
def test_leaving_the_page_deletes_its_short_lived_session(
    browser: Browser, live_server: LiveServer, leave: str
) -> None:
    """Closing or reloading the page frees its session; demo sessions expire after 2 minutes."""
    with watched_page(browser) as page:
        disc, scale, box = open_demo(page, live_server.url)
        draw_circle(page, disc, scale, box)
        page.get_by_role("button", name="Track").click()
        snapshot = wait_for_tracking(page, disc, results=3)
        session = httpx.get(f"{live_server.url}/v1/sessions/{snapshot['sessionId']}").json()
        lifetime = datetime.fromisoformat(session["expires_at"]) - datetime.now(UTC)
        assert 100 < lifetime.total_seconds() <= 121  # the page's 120 s, not the server's 900
        if leave == "close":
            page.close(run_before_unload=True)
        else:
            page.reload()
        listed: list[Any] = []
        for _ in range(100):  # the keep-alive DELETE lands within moments
            listed = httpx.get(f"{live_server.url}/v1/sessions").json()["sessions"]
            if not listed:
                break
            time.sleep(0.1)
        assert listed == []
