"""Cross-validation of efdm's options on folds of the thirty training sequences.

``--cv "search_radius=10,12,16" [--cv "stiffness=20,40"] --folds 5 [--nodes 112,128,144]``:
each ``--cv`` names a ``TrackerOptions`` field and its values (each parsed as JSON); several
form a grid (their product; the other fields keep their defaults).

- Node counts: each sequence is tracked from its first mask's contour resampled to each of
  the ``--nodes`` counts (default 128 alone), and its J for a point is the mean over them.
  One run of a clip swings by up to 0.2 with a sub-pixel change of its start, so the mean
  over several starts says more about a choice than any one of them.

- Folds: the training sequences sorted by name and dealt round-robin (sequence ``i`` of the
  sorted list goes to fold ``i mod k``), ``k = min(--folds, sequences)``: fixed, no seed.
- Every (sequence, grid point, node count) is tracked once; a point's J on a sequence does
  not depend on the fold, so the folds share the runs.
- For each fold, every point is scored by its mean J over the other folds' sequences (mean of
  the per-sequence means) and the best is chosen (ties: the first in grid order); the held-out
  fold's sequences count with that point.  The cross-validated J (and decay, and lost
  detection) is over the held-out runs of all the sequences: every sequence is scored by a
  point chosen without it.
- The point chosen on all the training sequences tracks the other sets asked for (the five
  validation sequences, the synthetic conditions): they are reported, never tuned on.
"""

from __future__ import annotations

import argparse
import itertools
import json
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

from bench.common.log import log
from bench.tracking.config import NODES, Config
from bench.tracking.metrics import SetScore, mean
from bench.tracking.pool import Job, Options, describe, track_all
from bench.tracking.run import ClipResult, TrackRun
from bench.tracking.sets import choose, is_partial

Axis = tuple[str, tuple[Any, ...]]
"""One ``--cv`` flag: an option's name and its values."""


def parse_axis(text: str) -> Axis:
    """``name=v1,v2,...`` with JSON values, checked against ``engine.TrackerOptions``.

    Raises
    ------
    argparse.ArgumentTypeError
        On a malformed flag, an unknown option or a value out of its bounds.
    """
    name, _, values = text.partition("=")
    name = name.strip()
    try:
        parsed = tuple(json.loads(v) for v in values.split(",") if v.strip())
    except json.JSONDecodeError as exc:
        raise argparse.ArgumentTypeError(f"--cv {text!r}: values must be JSON ({exc})") from None
    if not name or not parsed:
        raise argparse.ArgumentTypeError(f"--cv {text!r}: expected name=value1,value2,...")
    try:
        from engine import TrackerOptions

        for value in parsed:
            TrackerOptions.from_mapping({name: value})
    except (ImportError, ValueError, TypeError) as exc:
        raise argparse.ArgumentTypeError(f"--cv {text!r}: {exc}") from None
    return name, parsed


def parse_nodes(text: str) -> tuple[int, ...]:
    """``112,128,144``: distinct node counts of at least 3.

    Raises
    ------
    argparse.ArgumentTypeError
        On anything else.
    """
    try:
        counts = tuple(int(v) for v in text.split(",") if v.strip())
    except ValueError:
        counts = ()
    if not counts or min(counts) < 3 or len(set(counts)) != len(counts):
        raise argparse.ArgumentTypeError(
            f"--nodes {text!r}: expected distinct node counts of at least 3, e.g. 112,128,144"
        )
    return counts


def grid(axes: Sequence[Axis]) -> list[Options]:
    """The product of the axes, in the order given (duplicate option names: an error)."""
    names = [name for name, _ in axes]
    if len(set(names)) != len(names):
        raise ValueError(f"--cv names an option twice: {names}")
    points = itertools.product(*(values for _, values in axes))
    return [tuple(sorted(zip(names, point, strict=True))) for point in points]


def make_folds(names: Sequence[str], count: int) -> list[tuple[str, ...]]:
    """``min(count, len(names))`` folds: the sorted names dealt round-robin."""
    ordered = sorted(names)
    k = max(1, min(count, len(ordered)))
    return [tuple(ordered[i::k]) for i in range(k)]


def best(scores: Mapping[Options, float]) -> Options:
    """The point of highest score (ties and NaN: the first in order)."""
    return max(scores, key=lambda p: scores[p] if math.isfinite(scores[p]) else -math.inf)


Runs = Mapping[Options, Mapping[str, Sequence[TrackRun]]]
"""efdm's runs of every training sequence (by name) with every grid point: one per node count."""


def score(train: Runs, point: Options, names: Sequence[str]) -> float:
    """Mean J of ``point`` over the training sequences ``names`` (each: the mean of its runs)."""
    return mean(mean(run.mean_j for run in train[point][n]) for n in names)


@dataclass(frozen=True, slots=True)
class Fold:
    """One fold: its held-out sequences, every point's score on the others, the choice."""

    held_out: tuple[str, ...]
    train_scores: dict[Options, float]
    chosen: Options


def cross_validate(train: Runs, folds: int) -> tuple[list[Fold], Options | None]:
    """The folds with their choices, and the point chosen on all the sequences (None: none)."""
    if not train:
        return [], None
    names = list(next(iter(train.values())))
    result: list[Fold] = []
    for held_out in make_folds(names, folds):
        rest = [n for n in names if n not in held_out]
        scores = {p: score(train, p, rest) for p in train}
        result.append(Fold(held_out, scores, best(scores)))
        log(f"fold {len(result)}: chose {describe(result[-1].chosen)}, held out {held_out}")
    return result, best({p: score(train, p, names) for p in train})


@dataclass(slots=True)
class CvResults:
    """A cross-validation run.

    Attributes
    ----------
    grid : list of Options
        The grid points, in the order of the flags.
    train : dict of Options to dict of str to list of TrackRun
        efdm's runs of every training sequence with every point, one per node count.
    folds : list of Fold
        The folds and their choices.
    overall : Options or None
        The point chosen on all the training sequences (None: none ran).
    others : dict of str to list of ClipResult
        The other sets tracked with ``overall`` (reported, never tuned on).
    partial : tuple of str
        Sets not run in full (``--quick``, ``--sequences``).
    """

    config: Config
    workers: int
    grid: list[Options]
    train: dict[Options, dict[str, list[TrackRun]]]
    folds: list[Fold]
    overall: Options | None
    others: dict[str, list[ClipResult]]
    partial: tuple[str, ...] = ()
    notes: list[str] = field(default_factory=list)
    machine: dict[str, str] = field(default_factory=dict)
    wall_seconds: float = 0.0
    nodes: tuple[int, ...] = (NODES,)

    @property
    def held_out(self) -> list[tuple[int, str, TrackRun]]:
        """(fold, sequence, run with the fold's choice) of every training sequence, one per
        node count: pooled, they weigh every sequence alike."""
        return [
            (k, name, run)
            for k, fold in enumerate(self.folds)
            for name in fold.held_out
            for run in self.train[fold.chosen][name]
        ]

    @property
    def cv_score(self) -> SetScore:
        """The cross-validated scores: every sequence with the point chosen without it."""
        return SetScore.of(run for _, _, run in self.held_out)

    def in_sample(self, point: Options) -> SetScore:
        """A point's scores on all the training sequences (in-sample)."""
        return SetScore.of(run for runs in self.train[point].values() for run in runs)

    def fold_score(self, fold: Fold) -> SetScore:
        """The scores of a fold's held-out sequences with its choice."""
        return SetScore.of(run for n in fold.held_out for run in self.train[fold.chosen][n])


def run_cv(config: Config, args: argparse.Namespace) -> CvResults:
    """Track the grid on the training sequences, cross-validate, then track the other sets
    asked for with the point chosen on all of them."""
    grid_points = grid(args.cv)
    specs, why = choose(config, "davis-train", args.sequences)
    notes = [why] if why else []
    partial = ["davis-train"] if is_partial(config, "davis-train", specs) else []
    if len(specs) < 2:
        notes.append("cross-validation needs at least two training sequences: nothing tuned")
        log(notes[-1])
        specs = []
    elif len(specs) < args.folds:
        notes.append(f"{len(specs)} training sequences: {len(specs)} folds, not {args.folds}")
    counts = tuple(args.nodes)
    log(f"{len(grid_points)} grid points x {len(specs)} training sequences x {counts} nodes")
    jobs = [
        Job(s, ("efdm",), options=p, nodes=n) for p in grid_points for s in specs for n in counts
    ]
    done = iter(track_all(jobs, args.workers))
    train = {
        p: {s.name: [next(done).runs["efdm"] for _ in counts] for s in specs} for p in grid_points
    }
    folds, overall = cross_validate(train if specs else {}, args.folds)
    others: dict[str, list[ClipResult]] = {}
    if overall is not None:
        jobs = []
        for set_name in (s for s in args.sets if s != "davis-train"):
            chosen, why = choose(config, set_name, args.sequences)
            notes += [why] if why else []
            partial += [set_name] if is_partial(config, set_name, chosen) else []
            jobs += [Job(s, ("efdm",), options=overall) for s in chosen]
            others[set_name] = []
        for job, result in zip(jobs, track_all(jobs, args.workers), strict=True):
            others[job.clip.set].append(result)
    return CvResults(
        config,
        args.workers,
        grid_points,
        train,
        folds,
        overall,
        others,
        tuple(partial),
        notes,
        nodes=counts,
    )
