"""efdm eval: DAVIS J and F of predicted masks, one sequence or a folder of them."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import pytest

from efdm_cli import EXIT_INVALID, main
from engine.geometry import contour_to_mask

DAVIS = Path(__file__).resolve().parents[2] / ".." / "shared" / "data" / "davis2016"


def write_masks(folder: Path, shift: int = 0, frames: int = 6) -> Path:
    folder.mkdir(parents=True)
    for i in range(frames):
        mask = np.zeros((60, 80), np.uint8)
        mask[20:40, 10 + 3 * i + shift : 30 + 3 * i + shift] = 255
        assert cv2.imwrite(str(folder / f"{i:05d}.png"), mask)
    return folder


def scores(capsys: pytest.CaptureFixture[str], *argv: str) -> dict[str, Any]:
    assert main(["eval", *argv, "--json", "-q"]) == 0
    body: dict[str, Any] = json.loads(capsys.readouterr().out)
    return body


def test_masks_against_themselves_score_one(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    truth = write_masks(tmp_path / "gt")
    body = scores(capsys, str(truth), str(truth))
    assert body["mean"] == {"J": 1.0, "F": 1.0, "J&F": 1.0, "J decay": 0.0, "F decay": 0.0}
    assert body["sequences"]["gt"]["frames"] == 4  # first and last left out


def test_one_folder_per_sequence(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    for name, shift in (("a", 0), ("b", 2)):
        write_masks(tmp_path / "gt" / name)
        write_masks(tmp_path / "pred" / name, shift)
    body = scores(capsys, str(tmp_path / "pred"), str(tmp_path / "gt"))
    assert set(body["sequences"]) == {"a", "b"}
    assert body["sequences"]["a"]["J"]["mean"] == 1.0
    assert body["sequences"]["b"]["J"]["mean"] == pytest.approx(18 / 22)
    assert body["mean"]["J"] == pytest.approx((1 + 18 / 22) / 2)
    # the table says the same
    assert main(["eval", str(tmp_path / "pred"), str(tmp_path / "gt"), "-q"]) == 0
    table = capsys.readouterr().out
    assert "J&F" in table
    assert table.splitlines()[0].startswith("sequence")


def test_missing_predictions_are_named(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    truth = write_masks(tmp_path / "gt")
    pred = write_masks(tmp_path / "pred")
    (pred / "00003.png").unlink()
    assert main(["eval", str(pred), str(truth), "-q"]) == EXIT_INVALID
    assert "has no mask for 1 frame(s): 00003" in capsys.readouterr().err
    write_masks(tmp_path / "many" / "x")
    assert main(["eval", str(tmp_path / "pred"), str(tmp_path / "many"), "-q"]) == EXIT_INVALID
    assert "has no folder for x" in capsys.readouterr().err


@pytest.mark.skipif(not DAVIS.is_dir(), reason="../shared/data/davis2016 is absent")
def test_tracked_masks_score_as_the_tracker_did(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """efdm track --masks-out, then efdm eval: the J the tracking benchmark computes."""
    sequence = DAVIS / "blackswan"
    truth = sorted((sequence / "masks").glob("*.png"))[:12]
    frames = tmp_path / "frames"
    frames.mkdir()
    gt = tmp_path / "gt"
    gt.mkdir()
    for path in truth:
        (frames / f"{path.stem}.jpg").write_bytes(
            (sequence / "frames" / f"{path.stem}.jpg").read_bytes()
        )
        (gt / path.name).write_bytes(path.read_bytes())
    out, pred = tmp_path / "t.jsonl", tmp_path / "pred"
    argv = ["track", str(frames), "--init-mask", str(truth[0]), "--masks-out", str(pred)]
    assert main([*argv, "-o", str(out), "-q"]) == 0
    assert sorted(p.name for p in pred.iterdir()) == [p.name for p in truth]
    records = [json.loads(line) for line in out.read_text().splitlines()]
    js = []
    for record, path in zip(records[1:-1], truth[1:-1], strict=True):
        g = np.asarray(cv2.imread(str(path), cv2.IMREAD_GRAYSCALE)) > 0
        m = contour_to_mask(np.asarray(record["nodes"]), g.shape) > 0
        js.append(np.count_nonzero(g & m) / np.count_nonzero(g | m))
    body = scores(capsys, str(pred), str(gt))
    assert body["mean"]["J"] == pytest.approx(np.mean(js), abs=0.005)  # nodes rounded to 1e-3 px
