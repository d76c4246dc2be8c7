"""The cross-validation run's report (``tracking_cv.md``) and raw numbers (``tracking_cv.json``)."""

from __future__ import annotations

import json
from typing import Any

from bench.common.output import finite, run_json
from bench.common.report import GoalLine, fmt, goals_json, goals_table, header, load_line, md_table
from bench.tracking.config import Config
from bench.tracking.cv import CvResults
from bench.tracking.goals import accuracy_goals
from bench.tracking.metrics import SetScore
from bench.tracking.pool import Options, describe
from bench.tracking.report import clip_json, efdm_score, protocol_notes, score_json
from bench.tracking.sets import davis_view
from bench.tracking.tables import RUN_HEADERS, SCORE_HEADERS, run_cells, score_cells, sequence_table

NOT_TUNED = "not tuned on"


def how(results: CvResults) -> str:
    """How the training figures were obtained."""
    return f"cross-validated, {len(results.folds)} folds"


def scores(results: CvResults) -> dict[str, SetScore]:
    """efdm's scores per set: the training set's cross-validated."""
    got = {name: efdm_score(clips) for name, clips in results.others.items() if clips}
    return {"davis-train": results.cv_score, **got} if results.folds else got


def goals(results: CvResults) -> list[GoalLine]:
    """The accuracy goals with the cross-validated training figures (no speed: not timed)."""
    synthetic = results.others.get("synthetic", [])
    return accuracy_goals(scores(results), synthetic, how(results), results.partial)


def summary_section(results: CvResults) -> str:
    """The cross-validated, in-sample and not-tuned-on scores."""
    if results.overall is None:
        return ""
    chosen = describe(results.overall)
    k = len(results.folds)
    in_sample = results.in_sample(results.overall)
    runs = "" if len(results.nodes) == 1 else f"; a run per node count, {len(results.nodes)} each"
    rows = [
        [f"davis-train, cross-validated ({k} folds{runs})", *score_cells(results.cv_score)],
        [f"davis-train, {chosen} (chosen on all; in-sample{runs})", *score_cells(in_sample)],
    ]
    rows += [
        [f"{name}, {chosen} ({NOT_TUNED})", *score_cells(efdm_score(clips))]
        for name, clips in results.others.items()
        if clips
    ]
    return "## Summary (efdm, frames 1..T-2)\n\n" + md_table(["figure", *SCORE_HEADERS], rows)


def bold_if(text: str, chosen: bool) -> str:
    """``**text**`` for the chosen cell."""
    return f"**{text}**" if chosen else text


def folds_section(results: CvResults) -> str:
    """Per fold: what it holds out, every point's score on the other folds, the choice."""
    k = len(results.folds)
    held = [
        [
            str(i + 1),
            ", ".join(fold.held_out),
            describe(fold.chosen),
            fmt(fold.train_scores[fold.chosen], ".3f"),
            fmt(results.fold_score(fold).mean_j, ".3f"),
        ]
        for i, fold in enumerate(results.folds)
    ]
    grid = [
        [
            describe(point),
            *(
                bold_if(fmt(fold.train_scores[point], ".3f"), fold.chosen == point)
                for fold in results.folds
            ),
            bold_if(fmt(results.in_sample(point).mean_j, ".3f"), point == results.overall),
            fmt(results.in_sample(point).decay, "+.3f"),
        ]
        for point in results.grid
    ]
    folds = [f"fold {i + 1}" for i in range(k)]
    return "\n\n".join(
        [
            "## Folds",
            "The training sequences sorted by name and dealt round-robin into "
            f"{k} folds. For each fold, every grid point is scored by its mean J on the "
            "other folds' sequences; the best (bold) tracks the held-out fold.",
            md_table(["fold", "held out", "chosen", "J on the others", "J held out"], held),
            "### Every grid point: mean J on the other folds' sequences (per fold), and on all "
            "of them (in-sample; bold: the choice that tracks the other sets)",
            md_table(["grid point", *folds, "J all (in-sample)", "decay all"], grid),
        ]
    )


def held_out_section(results: CvResults) -> str:
    """Every training sequence with the point chosen without it, worst J first."""
    held = sorted(results.held_out, key=lambda entry: entry[2].mean_j)
    rows = [
        [
            name,
            str(run.total),
            str(len(run.nodes[0])) if run.nodes else "-",
            str(k + 1),
            describe(results.folds[k].chosen),
            *run_cells(run),
        ]
        for k, name, run in held
    ]
    return "\n\n".join(
        [
            "## davis-train held out: each sequence with the point chosen without it (a row per "
            "node count), worst J first",
            md_table(["sequence", "frames", "nodes", "fold", "chosen", *RUN_HEADERS], rows),
        ]
    )


def others_section(results: CvResults, name: str) -> str:
    """Another set, tracked with the point chosen on all the training sequences."""
    chosen = describe(results.overall or ())
    return "\n\n".join(
        [
            f"## {name} with {chosen} ({NOT_TUNED}), worst J first",
            sequence_table(results.others[name], []),
        ]
    )


def notes_section(results: CvResults) -> str:
    """How the folds and choices were made, and what was skipped."""
    lines = [
        "## Notes",
        "",
        "- Cross-validation (`bench/tracking/cv.py`): each (training sequence, grid point) is "
        "tracked once and shared by the folds (a point's J on a sequence does not depend on the "
        "fold); ties go to the first point in grid order. The cross-validated figures score "
        "every training sequence with the point chosen on the other folds. The point chosen on "
        "all the training sequences tracks the other sets: they are reported, never tuned on.",
        "- Options not in the grid keep their `engine.TrackerOptions` defaults. No timings: "
        f"the runs share the machine ({results.workers} worker process(es)); the plain run "
        "(`python -m bench.tracking`) measures speed.",
        *protocol_notes(),
    ]
    if results.config.name == "quick":
        lines.append("- `--quick` run (smoke test): few sequences, truncated.")
    if results.partial:
        lines.append(f"- `*`: {', '.join(results.partial)} not run in full.")
    lines += [f"- {note}" for note in results.notes]
    return "\n".join(lines)


def _resized(config: Config) -> str:
    """``, DAVIS frames and masks resized by F`` and ``, DAVIS frames in grey`` when they
    were, else nothing."""
    return "".join(f", {note}" for note in davis_view(config))


def render(results: CvResults) -> str:
    """The whole markdown report."""
    m = results.machine
    names = list(dict(results.grid[0])) if results.grid else []
    axes = "; ".join(f"{name} in {json.dumps(grid_values(results, name))}" for name in names)
    top = header(
        "Contour tracking benchmark: cross-validation of efdm's options",
        m,
        f"{m['cpu_count']} CPUs",
        load_line(m),
        f"- run: `{results.config.name}`, grid {axes or 'empty'} ({len(results.grid)} points), "
        f"{len(results.folds)} folds, nodes {', '.join(map(str, results.nodes))} (a sequence's "
        f"J: the mean over them), {results.workers} worker process(es), "
        f"{results.wall_seconds:.0f} s wall time{_resized(results.config)}",
    )
    sections = ["\n".join(top), "## Goals\n\n" + goals_table(goals(results))]
    if results.overall is not None:
        sections += [summary_section(results), folds_section(results), held_out_section(results)]
        sections += [others_section(results, n) for n, clips in results.others.items() if clips]
    sections.append(notes_section(results))
    return "\n\n".join(sections) + "\n"


def grid_values(results: CvResults, name: str) -> list[Any]:
    """The values of option ``name`` in the grid, in order of first appearance."""
    values: list[Any] = []
    for point in results.grid:
        value = dict(point)[name]
        if value not in values:
            values.append(value)
    return values


def point_json(point: Options | None) -> dict[str, Any] | None:
    """A grid point as a JSON object."""
    return None if point is None else dict(point)


def to_json(results: CvResults) -> dict[str, Any]:
    """Everything of the run as plain JSON data."""
    return {
        **run_json(results),
        "grid": [dict(p) for p in results.grid],
        "goals": goals_json(goals(results)),
        "folds": [
            {
                "held_out": list(fold.held_out),
                "train_scores": [finite(fold.train_scores[p]) for p in results.grid],
                "chosen": dict(fold.chosen),
            }
            for fold in results.folds
        ],
        "cross_validated": score_json(results.cv_score) if results.folds else None,
        "chosen_on_all": point_json(results.overall),
        "in_sample": [score_json(results.in_sample(p)) for p in results.grid if results.folds],
        "nodes": list(results.nodes),
        "train": {
            describe(p): {
                name: [
                    {"mean_j": finite(run.mean_j), "decay": finite(run.decay), "iou": run.iou}
                    for run in runs
                ]
                for name, runs in by_name.items()
            }
            for p, by_name in results.train.items()
        },
        "not_tuned_on": {
            name: {"scores": score_json(efdm_score(clips)), "clips": [clip_json(c) for c in clips]}
            for name, clips in results.others.items()
        },
        "partial_sets": list(results.partial),
        "notes": results.notes,
    }
