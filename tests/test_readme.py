"""The README's examples run as written: its Python and its shell.

Each fenced ``python`` or ``bash`` block runs, in a fresh temporary folder that
holds the files the examples name (a ``clip.mp4``, a ``frames/`` folder and
its ``masks/``, a ``first_mask.png``, ``forces.json``, ``batch.npy``), with this environment's
``efdm`` first on the PATH.  A block right after a comment
``<!-- readme-test: server ... -->`` runs against a live ``efdm serve`` (the
README's ``http://127.0.0.1:8000`` pointed at it); one after
``<!-- readme-test: skip (why) -->`` does not run, and says why.
"""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import cv2
import numpy as np
import pytest

README = Path(__file__).resolve().parents[1] / "README.md"
README_URL = "http://127.0.0.1:8000"
BLOCK = re.compile(r"(?:<!-- readme-test: (\w+)([^>]*)-->\n)?```(python|bash)\n(.*?)```", re.DOTALL)
BLOCKS = [
    (language, mode or "run", why.strip(" ()"), code)
    for mode, why, language, code in BLOCK.findall(README.read_text(encoding="utf-8"))
]
IDS = [f"{language}{i}-{mode}" for i, (language, mode, _, _) in enumerate(BLOCKS)]

SIZE = (640, 480)  # width, height: the examples' circle (320, 240, 60) lies inside
FRAMES = 8


def disc(i: int) -> tuple[np.ndarray, np.ndarray]:
    """Frame ``i`` of a red disc moving right over grey, and its mask."""
    w, h = SIZE
    frame = np.full((h, w, 3), 170, np.uint8)
    mask = np.zeros((h, w), np.uint8)
    centre = (320 + 3 * i, 240)
    cv2.circle(frame, centre, 60, (40, 40, 200), -1)
    cv2.circle(mask, centre, 60, 255, -1)
    return frame, mask


@pytest.fixture
def workdir(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    """A folder with every file the examples name; the current directory meanwhile."""
    writer = cv2.VideoWriter(str(tmp_path / "clip.mp4"), cv2.VideoWriter.fourcc(*"mp4v"), 25, SIZE)
    (tmp_path / "frames").mkdir()
    (tmp_path / "masks").mkdir()
    for i in range(FRAMES):
        frame, mask = disc(i)
        writer.write(frame)
        cv2.imwrite(str(tmp_path / "frames" / f"{i:05d}.jpg"), frame)
        cv2.imwrite(str(tmp_path / "masks" / f"{i:05d}.png"), mask)
        if i == 0:
            cv2.imwrite(str(tmp_path / "first_mask.png"), mask)
    writer.release()
    angles = np.linspace(0, 2 * np.pi, 12, endpoint=False)
    ring = np.c_[100 + 30 * np.cos(angles), 100 + 30 * np.sin(angles)]
    forces = np.zeros_like(ring)
    forces[0] = [5.0, 0.0]
    (tmp_path / "forces.json").write_text(
        json.dumps({"forces": forces.tolist(), "nodes": ring.tolist()})
    )
    np.save(tmp_path / "batch.npy", forces)
    monkeypatch.chdir(tmp_path)
    return tmp_path


@pytest.fixture(scope="module")
def server_url() -> Iterator[str]:
    """A live ``efdm serve`` (uvicorn on loopback, in-memory defaults)."""
    pytest.importorskip("fastapi")
    from service.settings import Settings
    from tests.service.conftest import _serve

    for server in _serve(Settings()):
        yield server.url


def test_readme_has_examples_of_each_kind() -> None:
    kinds = {(language, mode) for language, mode, _, _ in BLOCKS}
    assert {("python", "run"), ("python", "server"), ("bash", "run"), ("bash", "server")} <= kinds
    assert all(why for _, mode, why, _ in BLOCKS if mode == "skip")  # a skip says why


@pytest.mark.parametrize(("language", "mode", "why", "code"), BLOCKS, ids=IDS)
def test_readme_example_runs(
    language: str, mode: str, why: str, code: str, workdir: Path, request: pytest.FixtureRequest
) -> None:
    if mode == "skip":
        pytest.skip(why)
    assert mode in ("run", "server"), f"unknown readme-test mode {mode!r}"
    if mode == "server":
        code = code.replace(README_URL, request.getfixturevalue("server_url"))
    if language == "python":
        exec(compile(code, str(README), "exec"), {"__name__": "__readme__"})
        return
    env = {**os.environ, "PATH": f"{Path(sys.executable).parent}{os.pathsep}{os.environ['PATH']}"}
    done = subprocess.run(
        ["bash", "-euo", "pipefail", "-c", code],
        cwd=workdir,
        env=env,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert done.returncode == 0, f"{code}\n--- stdout\n{done.stdout}\n--- stderr\n{done.stderr}"
