"""``python -m bench.serving.state --quick``: state sizes and resume quality on DAVIS data."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from bench.common.data import DAVIS_ROOT, DAVIS_TRAIN_ROOT, davis_names
from bench.serving import state


@pytest.mark.skipif(
    not (davis_names(DAVIS_ROOT) or davis_names(DAVIS_TRAIN_ROOT)),
    reason="../shared/data holds no DAVIS sequences",
)
def test_a_quick_run_measures_both_states(tmp_path: Path) -> None:
    assert state.main(["--quick", "--out", str(tmp_path)]) == 0
    data = json.loads((tmp_path / "state.json").read_text())
    for figures in data["sets"].values():
        assert figures["compact_bytes"]["mean"] * 4 < figures["exact_bytes"]["mean"]
        assert figures["compact_bytes"]["max"] <= 64 * 1024
        assert set(figures["j"]) == set(state.MODES)
    assert "one failover" in (tmp_path / "state.md").read_text()
