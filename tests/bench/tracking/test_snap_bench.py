"""``python -m bench.tracking.snap --quick``: runs and reports on what DAVIS data there is."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from bench.common.data import DAVIS_ROOT, DAVIS_TRAIN_ROOT, davis_names
from bench.tracking import snap


@pytest.mark.skipif(
    not (davis_names(DAVIS_ROOT) or davis_names(DAVIS_TRAIN_ROOT)),
    reason="../shared/data holds no DAVIS sequences",
)
def test_a_quick_run_writes_its_table(tmp_path: Path) -> None:
    assert snap.main(["--quick", "--out", str(tmp_path)]) == 0
    data = json.loads((tmp_path / "snap.json").read_text())
    for figures in data["sets"].values():
        assert figures["sequences"] == snap.QUICK_SEQUENCES
        assert 0.0 <= figures["snap_iou"] <= 1.0
        assert 0.0 < figures["seconds_median"] <= figures["seconds_max"]
    assert "J from the box" in (tmp_path / "snap.md").read_text()
