"""Tracking benchmark: contour trackers on DAVIS-2016 and on synthetic sequences.

Trackers: ``efdm`` (``engine.Tracker``), ``static`` (the contour never moves)
and ``skimage`` (``skimage.segmentation.active_contour`` frame by frame).
Each starts from the first mask's largest outer contour (128 nodes) and then
sees only frames; J = IoU of the filled contour with the ground-truth mask,
mean over frames 1..T per clip, then over clips.  Only ``step`` calls are
timed, on one thread (``python -m bench.tracking`` pins the thread counts
before numpy loads).

Run ``python -m bench.tracking`` (``make bench-tracking``); ``--quick`` runs a
reduced set for smoke tests, ``--out DIR`` changes where the results go
(default ``bench/results/``): ``tracking.md``, ``tracking.json`` (per-frame J
and timings), ``tracking.png`` and ``tracking_sheet_<name>.jpg`` contact
sheets; ``--sequences a,b`` picks DAVIS sequences / synthetic conditions,
``--trackers efdm,static,skimage`` picks trackers.
"""

from __future__ import annotations

import argparse
import math
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from bench.common import machine
from bench.common.benchmark import Benchmark
from bench.common.data import (
    DAVIS_ROOT,
    davis_names,
    load_davis,
    load_synthetic,
    select,
    synthetic_conditions,
)
from bench.common.log import log
from bench.common.machine import load_average
from bench.tracking.config import FULL, QUICK, Config
from bench.tracking.plots import contact_sheet, plot_scores, write_sheet
from bench.tracking.report import Results, render, to_json
from bench.tracking.run import ClipResult, run_clip
from bench.tracking.trackers import TRACKERS, Factory, factory


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
        why = f"{type(exc).__name__}: {exc}"
        message = f"engine.testing.synthetic unavailable ({why}): synthetic skipped"
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
    return machine.machine_info(opencv=cv2.__version__, skimage=machine.version("scikit-image"))


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


def arguments(parser: argparse.ArgumentParser) -> None:
    """``--sequences a,b`` and ``--trackers x,y``."""
    parser.add_argument(
        "--sequences", type=names, default=None, help="DAVIS sequences / synthetic conditions"
    )
    parser.add_argument(
        "--trackers", type=tracker_names, default=list(TRACKERS), help="efdm,static,skimage"
    )


def figures(results: Results, out: Path) -> list[str]:
    """The bar chart ``tracking.png`` (the contact sheets were written while running)."""
    plot_scores(results.davis, results.synthetic, results.trackers, out / "tracking.png")
    return ["tracking.png", *results.sheets]


BENCHMARK = Benchmark(
    "tracking", __doc__, FULL, QUICK, run, render, to_json, figures=figures, arguments=arguments
)
