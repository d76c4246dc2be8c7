"""``efdm deform``: equilibrium displacements from the command line."""

from __future__ import annotations

import io
import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from efdm_cli import EXIT_INVALID, EXIT_IO, main
from engine import deform
from tests.engine.reference import forces_for


def test_deform_json_file_with_nodes(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    forces = forces_for(10)
    nodes = np.arange(20.0).reshape(10, 2)
    src = tmp_path / "in.json"
    src.write_text(json.dumps({"forces": forces.tolist(), "nodes": nodes.tolist()}))
    assert main(["deform", str(src), "--stiffness", "3", "--open"]) == 0
    out = json.loads(capsys.readouterr().out)
    expected = deform(forces, 3.0, closed=False)
    np.testing.assert_allclose(out["displacements"], expected, atol=1e-12)
    np.testing.assert_allclose(out["nodes"], nodes + expected, atol=1e-12)


def test_deform_npy_to_npy(tmp_path: Path) -> None:
    batch = np.stack([forces_for(12), forces_for(12, 1)])
    np.save(tmp_path / "f.npy", batch)
    code = main(
        ["deform", str(tmp_path / "f.npy"), "-a", "2", "--method", "efdmt", "--tol", "1e-9",
         "-o", str(tmp_path / "u.npy")]
    )  # fmt: skip
    assert code == 0
    np.testing.assert_allclose(np.load(tmp_path / "u.npy"), deform(batch, 2.0), atol=1e-8)


def test_deform_from_stdin_in_a_real_process() -> None:
    doc = json.dumps({"forces": [[1, 0], [1, 0], [1, 0]]})
    proc = subprocess.run(
        [sys.executable, "-m", "efdm_cli", "deform", "-", "-a", "5"],
        input=doc, capture_output=True, text=True, check=False,
    )  # fmt: skip
    assert proc.returncode == 0, proc.stderr
    np.testing.assert_allclose(json.loads(proc.stdout)["displacements"], [[1, 0]] * 3)


@pytest.mark.parametrize(
    ("content", "args", "code", "message"),
    [
        ("{not json", [], EXIT_INVALID, "not valid JSON"),
        ('{"f": 1}', [], EXIT_INVALID, '"forces"'),
        ('{"forces": [[1, 2]]}', [], EXIT_INVALID, "at least 3 nodes"),
        ('{"forces": [[1, "x"], [1, 2], [3, 4]]}', [], EXIT_INVALID, "numbers"),
        ('{"forces": [[1, 2], [1, 2], [3, 4]], "nodes": [[0, 0]]}', [], EXIT_INVALID, "shape"),
        ('{"forces": [[1, 2], [1, 2], [3, 4]]}', ["--tol", "1e-3"], EXIT_INVALID, "tol"),
    ],
)
def test_deform_invalid_input(
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
    content: str,
    args: list[str],
    code: int,
    message: str,
) -> None:
    src = tmp_path / "in.json"
    src.write_text(content)
    assert main(["deform", str(src), "-a", "1", *args]) == code
    assert message in capsys.readouterr().err


def test_a_file_that_is_not_text_is_invalid_json(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    src = tmp_path / "clip.mp4"
    src.write_bytes(b"\xff\xfe\x00\x00ftypmp42")
    assert main(["deform", str(src), "-a", "1"]) == EXIT_INVALID
    assert "not valid JSON: not UTF-8 text" in capsys.readouterr().err


def test_a_reader_that_stops_early_ends_the_output_quietly(tmp_path: Path) -> None:
    """``efdm deform big.json | head -c 50``: a closed pipe is no error and no traceback."""
    src = tmp_path / "big.json"
    src.write_text(json.dumps({"forces": [[1.0, 0.0]] * 20_000}))
    with subprocess.Popen(
        [sys.executable, "-m", "efdm_cli", "deform", str(src), "-a", "10"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
    ) as proc:
        assert proc.stdout is not None
        assert proc.stderr is not None
        assert proc.stdout.read(50).startswith(b'{"displacements": ')
        proc.stdout.close()
        err = proc.stderr.read().decode()
        assert proc.wait(timeout=60) == 0, err
    assert "Traceback" not in err


def test_missing_file_is_an_io_error(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["deform", str(tmp_path / "nope.json"), "-a", "1"]) == EXIT_IO
    assert "cannot read" in capsys.readouterr().err


def test_usage_errors_exit_2() -> None:
    with pytest.raises(SystemExit) as info:
        main(["deform", "x.json"])  # --stiffness is required
    assert info.value.code == 2


def test_stdout_argument_is_used(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(sys, "stdin", io.StringIO('{"forces": [[0, 1], [0, 1], [0, 1]]}'))
    buf = io.StringIO()
    monkeypatch.setattr(sys, "stdout", buf)
    assert main(["deform", "-", "-a", "1"]) == 0
    np.testing.assert_allclose(json.loads(buf.getvalue())["displacements"], [[0, 1]] * 3)
