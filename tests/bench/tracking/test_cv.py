"""bench.tracking.cv: folds, choices and the mean over node counts."""

from __future__ import annotations

import argparse

import pytest

from bench.tracking.config import QUICK
from bench.tracking.cv import CvResults, cross_validate, parse_nodes
from bench.tracking.pool import Options
from bench.tracking.run import TrackRun

SEQUENCES = ("a", "b", "c", "d", "e")
STEADY: Options = (("figure_ground", False),)
SWINGING: Options = (("figure_ground", True),)


def run(j: float) -> TrackRun:
    """A five-frame run whose scored frames (1..3) all have J = ``j``."""
    return TrackRun("efdm", 5, 5, iou=[1.0, j, j, j, 1.0])


def test_node_counts_parse_and_bad_ones_are_refused() -> None:
    assert parse_nodes("112,128, 144") == (112, 128, 144)
    for bad in ("", "2,128", "128,128", "many"):
        with pytest.raises(argparse.ArgumentTypeError, match="--nodes"):
            parse_nodes(bad)


def test_a_sequence_counts_with_the_mean_of_its_runs() -> None:
    # at the first node count the swinging point is worse everywhere, over both it is better
    train = {
        STEADY: {n: [run(0.6), run(0.6)] for n in SEQUENCES},
        SWINGING: {n: [run(0.55), run(0.75)] for n in SEQUENCES},
    }
    folds, overall = cross_validate(train, 5)
    assert overall == SWINGING
    assert [fold.chosen for fold in folds] == [SWINGING] * 5
    results = CvResults(QUICK, 1, [STEADY, SWINGING], train, folds, overall, {})
    assert results.cv_score.mean_j == pytest.approx(0.65)
    assert len(results.held_out) == 10  # a row per sequence and node count
    assert results.fold_score(folds[0]).mean_j == pytest.approx(0.65)
    assert results.in_sample(STEADY).mean_j == pytest.approx(0.6)
