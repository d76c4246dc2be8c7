"""efdm track --init-mask: binary masks and label images are read; photos are refused."""

from __future__ import annotations

import json
from pathlib import Path

import cv2
import numpy as np
import pytest
from numpy.typing import NDArray

from efdm_cli import EXIT_INVALID, main
from efdm_cli._masks import MaskError, labels_of, object_mask, voc_colours

W, H = 160, 120


def frames(tmp_path: Path) -> Path:
    folder = tmp_path / "frames"
    folder.mkdir()
    for i in range(3):
        frame = np.full((H, W, 3), 170, np.uint8)
        cv2.circle(frame, (40 + 2 * i, 60), 20, (40, 40, 200), -1)
        cv2.circle(frame, (115, 60), 18, (200, 60, 40), -1)
        assert cv2.imwrite(str(folder / f"{i:03d}.png"), frame)
    return folder


def two_objects() -> NDArray[np.uint8]:
    labels = np.zeros((H, W), np.uint8)
    cv2.circle(labels, (40, 60), 20, 1, -1)
    cv2.circle(labels, (115, 60), 18, 2, -1)
    return labels


def first_centre(tmp_path: Path, argv: list[str]) -> NDArray[np.float64]:
    out = tmp_path / "t.jsonl"
    assert main([*argv, "-o", str(out), "-q", "-n", "32"]) == 0

    first = json.loads(out.read_text().splitlines()[0])
    centre: NDArray[np.float64] = np.asarray(first["nodes"], dtype=np.float64).mean(axis=0)
    return centre


def test_a_grey_label_image_gives_every_object_or_the_one_of_its_label(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    mask = tmp_path / "labels.png"
    assert cv2.imwrite(str(mask), two_objects())
    argv = ["track", str(frames(tmp_path)), "--init-mask", str(mask)]
    out, masks = tmp_path / "all.jsonl", tmp_path / "labels"
    assert main([*argv, "-q", "-n", "32", "-o", str(out), "--masks-out", str(masks)]) == 0
    records = [json.loads(line) for line in out.read_text().splitlines()]
    assert len(records) == 3
    for record in records:
        assert [o["id"] for o in record["objects"]] == [1, 2]
        assert {o["status"] for o in record["objects"]} <= {"tracking", "uncertain", "lost"}
        assert [o["behind"] for o in record["objects"]] == [[], []]  # apart
    centres = [np.asarray(o["nodes"]).mean(axis=0) for o in records[0]["objects"]]
    np.testing.assert_allclose(centres, [[40, 60], [115, 60]], atol=1)
    written = cv2.imread(str(masks / "000.png"), cv2.IMREAD_UNCHANGED)
    assert written is not None
    assert (written[60, 40], written[60, 115], written[5, 5]) == (1, 2, 0)  # labels, as given
    np.testing.assert_allclose(first_centre(tmp_path, [*argv, "--label", "2"]), [115, 60], atol=1)
    np.testing.assert_allclose(first_centre(tmp_path, [*argv, "--label", "1"]), [40, 60], atol=1)
    assert main([*argv, "--label", "3", "-q"]) == EXIT_INVALID
    assert "has no label 3; its labels are 1, 2" in capsys.readouterr().err


def test_a_binary_mask_needs_no_label(tmp_path: Path) -> None:
    mask = tmp_path / "mask.png"
    assert cv2.imwrite(str(mask), (two_objects() == 1).astype(np.uint8) * 255)
    argv = ["track", str(frames(tmp_path)), "--init-mask", str(mask)]
    np.testing.assert_allclose(first_centre(tmp_path, argv), [40, 60], atol=1)


def test_a_palette_mask_as_davis_writes_it() -> None:
    """OpenCV expands a palette PNG to colours: the VOC colour map gives the labels back."""
    bgr = voc_colours()[:, ::-1][two_objects()]
    labels = labels_of(np.ascontiguousarray(bgr), "m")
    np.testing.assert_array_equal(labels, two_objects())
    assert voc_colours()[1].tolist() == [128, 0, 0]  # DAVIS's first object: dark red
    assert voc_colours()[2].tolist() == [0, 128, 0]


def test_a_coloured_binary_mask_is_a_mask() -> None:
    image = np.zeros((H, W, 3), np.uint8)
    image[two_objects() == 1] = (10, 200, 30)  # no palette colour: black and one colour
    mask = object_mask(b"\x89PNG", image, "m", None)
    np.testing.assert_array_equal(mask, two_objects() == 1)


@pytest.mark.parametrize(
    ("kind", "message"),
    [
        ("jpeg", "is a JPEG: a mask must be lossless (PNG)"),
        ("photo", "distinct values, a photo rather than a mask"),
        ("colours", "colours that are not a label palette"),
    ],
)
def test_a_photo_is_refused_not_thresholded(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], kind: str, message: str
) -> None:
    rng = np.random.default_rng(0)
    if kind == "jpeg":
        path = tmp_path / "mask.jpg"
        image = (two_objects() > 0).astype(np.uint8) * 255
    elif kind == "photo":
        path = tmp_path / "photo.png"
        image = rng.integers(0, 256, (H, W), dtype=np.uint8)
    else:
        path = tmp_path / "colours.png"
        image = np.zeros((H, W, 3), np.uint8)
        image[two_objects() == 1] = (10, 200, 30)
        image[two_objects() == 2] = (200, 10, 30)
    assert cv2.imwrite(str(path), image)
    argv = ["track", str(frames(tmp_path)), "--init-mask", str(path), "-q"]
    assert main(argv) == EXIT_INVALID
    assert message in capsys.readouterr().err


def test_label_without_a_mask_is_an_error(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    argv = ["track", str(frames(tmp_path)), "--init-circle", "40,60,20", "--label", "1", "-q"]
    assert main(argv) == EXIT_INVALID
    assert "--label chooses an object of --init-mask" in capsys.readouterr().err


def test_several_objects_on_worker_processes_give_the_same_records(tmp_path: Path) -> None:
    mask = tmp_path / "labels.png"
    assert cv2.imwrite(str(mask), two_objects())
    argv = ["track", str(frames(tmp_path)), "--init-mask", str(mask), "-q", "-n", "32"]
    here, there = tmp_path / "here.jsonl", tmp_path / "there.jsonl"
    assert main([*argv, "-o", str(here)]) == 0
    assert main([*argv, "-o", str(there), "--processes", "2"]) == 0

    def without_time(path: Path) -> list[dict[str, object]]:
        records = [json.loads(line) for line in path.read_text().splitlines()]
        return [{k: v for k, v in r.items() if k != "elapsed_ms"} for r in records]

    assert without_time(there) == without_time(here)
    assert len(without_time(here)) == 3
    assert main([*argv, "--processes", "-1"]) == EXIT_INVALID


def test_mask_error_is_a_value_error() -> None:
    assert issubclass(MaskError, ValueError)


def test_several_boxes_give_several_snapped_objects(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "boxes.jsonl"
    argv = ["track", str(frames(tmp_path)), "--init-box", "17,37,64,84"]
    argv += ["--init-box", "94,39,137,82", "-n", "32", "-q"]
    assert main([*argv, "-o", str(out)]) == 0
    first = json.loads(out.read_text().splitlines()[0])
    assert [o["id"] for o in first["objects"]] == [1, 2]
    centres = [np.asarray(o["nodes"]).mean(axis=0) for o in first["objects"]]
    np.testing.assert_allclose(centres, [[40, 60], [115, 60]], atol=1.5)  # snapped, not boxes
    assert main([*argv, "--init-circle", "40,60,20"]) == EXIT_INVALID
    assert "--init-box cannot be combined" in capsys.readouterr().err
