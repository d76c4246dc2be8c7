"""Tracking benchmark: contour trackers on DAVIS-2016 and on synthetic sequences.

Trackers: ``efdm`` (``engine.Tracker``), ``static`` (the contour never moves)
and ``skimage`` (``skimage.segmentation.active_contour`` frame by frame).
Each starts from the first mask's largest outer contour (128 nodes) and then
sees only frames; J = IoU of the filled contour with the ground-truth mask,
mean over frames 1..T per clip, then over clips.  Only ``step`` calls are
timed, on one thread.

Run ``python bench/tracking.py`` (``make bench-tracking``); ``--quick`` runs a
reduced set for smoke tests, ``--out DIR`` changes where the results go
(default ``bench/results/``): ``tracking.md``, ``tracking.json`` (per-frame J
and timings), ``tracking.png`` and ``tracking_sheet_<name>.jpg`` contact
sheets; ``--sequences a,b`` picks DAVIS sequences / synthetic conditions,
``--trackers efdm,static,skimage`` picks trackers.
"""

from __future__ import annotations

import os

# One thread everywhere, for fair timings: set before numpy / OpenCV / numba load.
for _variable in (
    "OMP_NUM_THREADS",
    "OPENBLAS_NUM_THREADS",
    "MKL_NUM_THREADS",
    "NUMBA_NUM_THREADS",
):
    os.environ[_variable] = "1"

import argparse  # noqa: E402
import json  # noqa: E402
import math  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from collections.abc import Sequence  # noqa: E402
from dataclasses import asdict  # noqa: E402
from pathlib import Path  # noqa: E402
from typing import Any  # noqa: E402

import cv2  # noqa: E402
import numpy as np  # noqa: E402

import _machine  # noqa: E402
from _machine import load_average  # noqa: E402
from _tracking_data import (  # noqa: E402
    DAVIS_ROOT,
    davis_names,
    load_davis,
    load_synthetic,
    select,
    synthetic_conditions,
)
from _tracking_plots import contact_sheet, plot_scores, write_sheet  # noqa: E402
from _tracking_report import REFERENCES, Results, goals, render  # noqa: E402
from _tracking_run import FULL, QUICK, ClipResult, Config, log, run_clip  # noqa: E402
from _tracking_trackers import SKIMAGE_PARAMS, TRACKERS, Factory, factory  # noqa: E402

REPO = Path(__file__).resolve().parent.parent
DEFAULT_OUT = REPO / "bench" / "results"


def load_factories(names: Sequence[str]) -> tuple[dict[str, Factory], dict[str, str]]:
    """The trackers that can be built, and why the others cannot."""
    factories: dict[str, Factory] = {}
    unavailable: dict[str, str] = {}
    for name in names:
        try:
            factories[name] = factory(name)
        except (ImportError, AttributeError) as exc:
            unavailable[name] = f"{type(exc).__name__}: {exc}"
            log(f"tracker {name} unavailable ({unavailable[name]}); running the others")
    return factories, unavailable


def run_davis(
    config: Config, wanted: Sequence[str] | None, factories: dict[str, Factory], out: Path
) -> tuple[list[ClipResult], list[str], list[str]]:
    """Every chosen DAVIS sequence: results, sheet file names and notes."""
    available = davis_names()
    if not available:
        message = f"DAVIS-2016 subset not found at {DAVIS_ROOT}: DAVIS part skipped"
        log(message)
        return [], [], [message]
    limits = {} if config.skimage_davis is None else {"skimage": config.skimage_davis}
    results: list[ClipResult] = []
    sheets: list[str] = []
    for order, name in enumerate(select(available, wanted, config.davis_count)):
        clip = load_davis(name, config.davis_frames)
        result = run_clip(clip, factories, limits, reverse=order % 2 == 1)
        results.append(result)
        sheets.append(save_sheet(contact_sheet(clip, result), f"davis_{name}", out))
    return results, sheets, []


def run_synthetic(
    config: Config, wanted: Sequence[str] | None, factories: dict[str, Factory], out: Path
) -> tuple[list[ClipResult], list[str], list[str]]:
    """Every chosen synthetic condition: results, sheet file names and notes.

    Contact sheets are written for the ``config.synthetic_sheets`` conditions
    where efdm scores lowest (the first ones when efdm did not run).
    """
    try:
        available = synthetic_conditions()
    except (ImportError, AttributeError) as exc:
        message = f"engine.synthetic unavailable ({type(exc).__name__}: {exc}): synthetic skipped"
        log(message)
        return [], [], [message]
    limits = {} if config.skimage_synthetic is None else {"skimage": config.skimage_synthetic}
    results: list[ClipResult] = []
    candidates: list[tuple[float, int, np.ndarray[Any, Any], str]] = []
    for order, name in enumerate(select(available, wanted, config.synthetic_count)):
        clip = load_synthetic(name, config.synthetic_length)
        result = run_clip(clip, factories, limits, reverse=order % 2 == 1)
        results.append(result)
        score = result.runs["efdm"].mean_j if "efdm" in result.runs else float(order)
        candidates.append(
            (score if math.isfinite(score) else -1.0, order, contact_sheet(clip, result), name)
        )
    chosen = sorted(candidates, key=lambda c: (c[0], c[1]))[: config.synthetic_sheets]
    sheets = [
        save_sheet(image, f"synthetic_{name}", out)
        for _, _, image, name in sorted(chosen, key=lambda c: c[1])
    ]
    return results, sheets, []


def save_sheet(image: np.ndarray[Any, Any], name: str, out: Path) -> str:
    """Write ``tracking_sheet_<name>.jpg`` into ``out``; return the file name.

    Sheets of DAVIS frames are named ``tracking_sheet_davis_*`` and kept out of
    git: the data set's terms allow evaluation, not copies in this repository.
    """
    file_name = f"tracking_sheet_{name}.jpg"
    out.mkdir(parents=True, exist_ok=True)
    write_sheet(image, out / file_name)
    return file_name


def machine_info() -> dict[str, str]:
    """Platform, CPU, library versions and the date."""
    return _machine.machine_info(opencv=cv2.__version__, skimage=_machine.version("scikit-image"))


def finite(value: float) -> float | None:
    """A float for JSON (non-finite: None)."""
    return value if math.isfinite(value) else None


def clip_json(clip: ClipResult) -> dict[str, Any]:
    """Raw per-frame numbers of one clip (contours left out)."""
    runs = {
        name: {
            "frames_tracked": run.frames,
            "mean_j": finite(run.mean_j),
            "j": run.scores,
            "j_frame0": run.iou[0] if run.iou else None,
            "median_ms": finite(run.median_ms),
            "ms": run.ms,
            "extras": run.extras,
            "error": run.error,
        }
        for name, run in clip.runs.items()
    }
    return {"name": clip.name, "frames": clip.frames, "shape": list(clip.shape), "runs": runs}


def to_json(results: Results) -> dict[str, Any]:
    """Everything of the run as plain JSON data."""
    return {
        "config": asdict(results.config),
        "machine": results.machine,
        "trackers": list(results.trackers),
        "unavailable": results.unavailable,
        "skimage_params": SKIMAGE_PARAMS,
        "wall_seconds": results.wall_seconds,
        "goals": [
            {
                "goal": g.goal,
                "measured": finite(g.measured),
                "target": g.target,
                "result": g.verdict,
            }
            for g in goals(results)
        ],
        "davis": [clip_json(c) for c in results.davis],
        "synthetic": [clip_json(c) for c in results.synthetic],
        "davis_references": {k: list(v) for k, v in REFERENCES.items()},
        "notes": results.notes,
        "units": {"j": "IoU of frames 1..T", "ms": "milliseconds per step call, frame 0 first"},
    }


def write_outputs(results: Results, out: Path) -> str:
    """Write the report, the JSON and the bar chart into ``out``; return the report."""
    out.mkdir(parents=True, exist_ok=True)
    report = render(results)
    (out / "tracking.md").write_text(report, encoding="utf-8")
    text = json.dumps(to_json(results), indent=1, allow_nan=False)
    (out / "tracking.json").write_text(text + "\n", encoding="utf-8")
    plot_scores(results.davis, results.synthetic, results.trackers, out / "tracking.png")
    return report


def run(config: Config, args: argparse.Namespace) -> Results:
    """Run every chosen tracker on every chosen clip."""
    start = time.perf_counter()
    load_before = load_average()
    cv2.setNumThreads(1)
    factories, unavailable = load_factories(args.trackers)
    out: Path = args.out
    davis, davis_sheets, davis_notes = run_davis(config, args.sequences, factories, out)
    synthetic, synthetic_sheets, synthetic_notes = run_synthetic(
        config, args.sequences, factories, out
    )
    notes = davis_notes + synthetic_notes
    ran = {c.name for c in [*davis, *synthetic]}
    unknown = [name for name in args.sequences or () if name not in ran]
    if unknown:
        notes.append(f"requested but not found (or their part skipped): {', '.join(unknown)}")
        log(notes[-1])
    return Results(
        config=config,
        trackers=tuple(factories),
        davis=davis,
        synthetic=synthetic,
        machine={**machine_info(), "load_before": load_before, "load_after": load_average()},
        wall_seconds=time.perf_counter() - start,
        notes=notes,
        unavailable=unavailable,
        sheets=davis_sheets + synthetic_sheets,
    )


def names(text: str) -> list[str]:
    """A comma-separated list."""
    return [part.strip() for part in text.split(",") if part.strip()]


def tracker_names(text: str) -> list[str]:
    """A comma-separated list of known tracker names."""
    chosen = names(text)
    unknown = [name for name in chosen if name not in TRACKERS]
    if unknown or not chosen:
        raise argparse.ArgumentTypeError(f"unknown trackers {unknown}; choose from {TRACKERS}")
    return chosen


def parse_args(argv: Sequence[str] | None) -> argparse.Namespace:
    """Command line: ``--quick``, ``--out DIR``, ``--sequences a,b``, ``--trackers x,y``."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0] if __doc__ else None)
    parser.add_argument("--quick", action="store_true", help="reduced set for smoke tests")
    parser.add_argument("--out", type=Path, default=DEFAULT_OUT, help="output directory")
    parser.add_argument(
        "--sequences", type=names, default=None, help="DAVIS sequences / synthetic conditions"
    )
    parser.add_argument(
        "--trackers", type=tracker_names, default=list(TRACKERS), help="efdm,static,skimage"
    )
    return parser.parse_args(argv)


def main(argv: Sequence[str] | None = None) -> int:
    """Run the benchmark, print the report, write the result files."""
    args = parse_args(argv)
    results = run(QUICK if args.quick else FULL, args)
    print(write_outputs(results, args.out), end="")
    sheets = len(results.sheets)
    log(f"wrote {args.out / 'tracking.md'}, tracking.json, tracking.png and {sheets} sheets")
    return 0


if __name__ == "__main__":
    sys.exit(main())
