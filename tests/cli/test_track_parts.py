"""``efdm track`` pieces: argument parsing, tracker wiring (with a fake), progress."""

from __future__ import annotations

import io
import json
import sys
import types
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import pytest
from numpy.typing import ArrayLike, NDArray

from efdm_cli import EXIT_INVALID, CliError, main
from efdm_cli._progress import Progress
from efdm_cli.track import parse_circle, parse_options, parse_polygon


class FakeResult:
    def __init__(self, nodes: NDArray[np.float64], index: int) -> None:
        self.nodes, self.iterations = nodes, index
        self.converged, self.confidence, self.status = True, 0.123456, "uncertain"


class FakeTracker:
    """Records how it was built; moves the contour 1 px right per frame."""

    calls: list[dict[str, Any]] = []  # noqa: RUF012  (reset by the fixture)

    def __init__(self, nodes: ArrayLike, *, closed: bool = True, **options: Any) -> None:
        self.nodes = np.asarray(nodes, dtype=np.float64)
        self.index = -1
        FakeTracker.calls.append({"n": len(self.nodes), "closed": closed, **options})

    def step(self, frame: NDArray[np.uint8]) -> FakeResult:
        if frame.mean() < 1:
            raise ValueError("frame is all black")
        self.index += 1
        return FakeResult(self.nodes + np.array([self.index, 0.0]), self.index)


@pytest.fixture
def fake(monkeypatch: pytest.MonkeyPatch) -> type[FakeTracker]:
    module = types.ModuleType("engine.tracking.tracker")
    module.Tracker = FakeTracker  # type: ignore[attr-defined]
    monkeypatch.setitem(sys.modules, "engine.tracking.tracker", module)
    FakeTracker.calls = []
    return FakeTracker


def make_frames(folder: Path, count: int, size: int = 32) -> Path:
    folder.mkdir()
    for i in range(count):
        assert cv2.imwrite(str(folder / f"{i:04d}.png"), np.full((size, size), 128, np.uint8))
    return folder


def test_options_reach_the_tracker(fake: type[FakeTracker], tmp_path: Path) -> None:
    frames = make_frames(tmp_path / "f", 3)
    out = tmp_path / "t.jsonl"
    argv = ["track", str(frames), "--init-circle", "16,16,5", "-n", "7", "-o", str(out)]
    assert main([*argv, "-a", "3.5", "-O", "iterations=4", "-O", "mode=fast"]) == 0
    assert main(argv) == 0
    assert fake.calls == [
        {"n": 7, "closed": True, "stiffness": 3.5, "iterations": 4, "mode": "fast"},
        {"n": 7, "closed": True},  # stiffness only when given
    ]
    records = [json.loads(line) for line in out.read_text().splitlines()]
    assert [r["iterations"] for r in records] == [0, 1, 2]
    assert records[2]["confidence"] == 0.1235
    x0 = records[0]["nodes"][0][0]
    assert records[2]["nodes"][0][0] == pytest.approx(x0 + 2)  # the tracker's nodes, rounded
    assert all(len(r["nodes"]) == 7 for r in records)


def test_tracker_errors_name_the_frame(
    fake: type[FakeTracker], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    frames = make_frames(tmp_path / "f", 2)
    assert cv2.imwrite(str(frames / "0002.png"), np.zeros((32, 32), np.uint8))
    assert main(["track", str(frames), "--init-circle", "16,16,5"]) == EXIT_INVALID
    captured = capsys.readouterr()
    assert len(captured.out.splitlines()) == 2
    assert "error: frame 2 (" in captured.err
    assert "0002.png): frame is all black" in captured.err


def test_long_input_prints_progress_lines(
    fake: type[FakeTracker], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    frames = make_frames(tmp_path / "f", 100, size=16)
    argv = ["track", str(frames), "--init-circle", "8,8,3", "-o", str(tmp_path / "t.jsonl")]
    assert main(argv) == 0
    lines = capsys.readouterr().err.splitlines()
    assert len(lines) == 21
    assert lines[0].startswith("efdm track: frame 5/100 (5 %), ")
    assert ", ETA " in lines[0]
    assert lines[-2].startswith("efdm track: frame 100/100 (100 %), ")
    assert lines[-2].endswith(" fps")  # done: no ETA
    # the closing summary
    assert lines[-1].startswith("efdm track: 100 frames in ")
    assert "ms per frame); confidence mean " in lines[-1]
    assert lines[-1].endswith(" uncertain")
    assert main([*argv, "--quiet"]) == 0
    assert capsys.readouterr().err == ""


class Clock:
    def __init__(self) -> None:
        self.now = 0.0

    def __call__(self) -> float:
        return self.now


class Tty(io.StringIO):
    def isatty(self) -> bool:
        return True


def test_progress_on_a_tty_redraws_one_line() -> None:
    clock, stream = Clock(), Tty()
    progress = Progress(10, stream, clock=clock, delay=0.5, interval=0.1)
    progress.update(1)
    assert stream.getvalue() == ""  # nothing during the first half second
    clock.now = 1.0
    progress.update(2)
    clock.now = 1.05
    progress.update(3)  # too soon to redraw
    clock.now = 2.0
    progress.update(9)
    progress.update(10)  # too soon again; drawn by close
    progress.close()
    assert stream.getvalue() == (
        "\refdm track: frame 2/10 (20 %), 2.0 fps, ETA 4 s"
        "\refdm track: frame 9/10 (90 %), 4.5 fps, ETA 0 s"
        "\refdm track: frame 10/10 (100 %), 5.0 fps       \n"  # over the longer line
    )


def test_progress_on_a_tty_stays_silent_for_short_runs() -> None:
    stream = Tty()
    progress = Progress(3, stream, clock=Clock())
    for i in range(1, 4):
        progress.update(i)
    progress.close()
    assert stream.getvalue() == ""


def test_progress_lines_without_a_known_total() -> None:
    clock, stream = Clock(), io.StringIO()
    progress = Progress(None, stream, clock=clock, every=2)
    for i in range(1, 6):
        clock.now = i / 10
        progress.update(i)
    progress.close()
    assert stream.getvalue() == "efdm track: frame 2, 10.0 fps\nefdm track: frame 4, 10.0 fps\n"


def test_progress_plain_and_quiet() -> None:
    stream = io.StringIO()
    short = Progress(50, stream, clock=Clock())  # below min_frames: no lines
    quiet = Progress(1000, stream, enabled=False, clock=Clock())
    for i in range(1, 51):
        short.update(i)
        quiet.update(i)
    assert stream.getvalue() == ""
    assert not Progress(None, Tty(), enabled=False).tty


def test_progress_total_may_be_an_underestimate() -> None:
    stream = io.StringIO()
    progress = Progress(100, stream, clock=Clock())
    progress.update(120)
    assert "frame 120/100 (100 %)" in stream.getvalue()


def test_parse_polygon_and_circle() -> None:
    poly = parse_polygon(" 1,2  3.5,2;3.5,-4e0 ")
    np.testing.assert_array_equal(poly, [[1, 2], [3.5, 2], [3.5, -4]])
    assert parse_circle("10,20.5,3") == (10.0, 20.5, 3.0)
    with pytest.raises(CliError) as info:
        parse_circle("1,2,3,4")
    assert info.value.code == EXIT_INVALID


def test_parse_options() -> None:
    assert parse_options(["a=1", "b-c=0.5", "d=true", "e=text", "f=[1, 2]"]) == {
        "a": 1, "b_c": 0.5, "d": True, "e": "text", "f": [1, 2],
    }  # fmt: skip
    for bad in ["=1", "x", "closed=false", "stiffness=3", "1a=2"]:
        with pytest.raises(CliError):
            parse_options([bad])


class Broken(io.StringIO):
    def write(self, text: str) -> int:
        raise BrokenPipeError(32, "Broken pipe")


def test_progress_on_a_broken_stream_falls_silent() -> None:
    progress = Progress(100, Broken(), clock=Clock())
    for i in range(1, 101):
        progress.update(i)  # does not raise
    progress.close()
    assert not progress.plain


def test_the_summary_line() -> None:
    from efdm_cli.track import summary

    line = summary([1.0, 0.9, 0.2, 0.7], ["tracking", "tracking", "lost", "uncertain"], 2.0)
    assert line == (
        "efdm track: 4 frames in 2.0 s (500.0 ms per frame); confidence mean 0.70, "
        "worst 0.20 (frame 2); 1 reported lost, 1 uncertain"
    )


@pytest.mark.parametrize(
    ("seconds", "text"),
    [(4.4, "4 s"), (59.6, "1 min 00 s"), (185, "3 min 05 s"), (3720, "1 h 02 min")],
)
def test_eta_durations(seconds: float, text: str) -> None:
    from efdm_cli._progress import _duration

    assert _duration(seconds) == text
