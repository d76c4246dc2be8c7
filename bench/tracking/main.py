"""Tracking benchmark: contour trackers on DAVIS-2016 (training and validation) and synthetic clips.

Trackers: ``efdm`` (``engine.Tracker``), ``static`` (the contour never moves)
and ``skimage`` (``skimage.segmentation.active_contour`` frame by frame).
Each starts from the first mask's largest outer contour (128 nodes) and then
sees only frames.  DAVIS protocol: J = IoU of the filled contour with the
mask over frames 1..T-2 (first and last left out), mean of the per-sequence
means; decay, and how well efdm's status tells lost frames
(:mod:`bench.tracking.metrics`).  Sets (:mod:`bench.tracking.sets`):
``davis-train`` (30, tuned on by cross-validation only), ``davis-val`` (5,
never tuned on), ``synthetic``.

Run ``python -m bench.tracking`` (``make bench-tracking``): every set, no
tuning (the defaults are fixed); results ``tracking.md``, ``tracking.json``
(per-frame J, status, timings), ``tracking.png`` and contact sheets
``tracking_sheet_<davis|synthetic>_<name>.jpg`` of the clips where efdm
scores lowest.  Speed: the validation set (else the first set run) is tracked
first, in this process, one thread, nothing else running, twice
(:data:`~bench.tracking.config.TIMED_PASSES`): the speed figures are the faster
pass's, and both passes must give the same contours; the other sets on
``--workers`` processes (default 2).

Options: ``--quick`` (smoke test: a few short sequences), ``--out DIR``
(default ``bench/results/``), ``--sets davis-train,davis-val,synthetic``,
``--sequences a,b`` (DAVIS sequences / synthetic conditions),
``--trackers efdm,static,skimage``, ``--workers N``, ``--seeds N`` (synthetic seeds
0..N-1; default 3: seeds beyond them are conditions the defaults never saw), ``--length
N`` (frames of every synthetic clip; default 40: a longer clip is the same condition
drawn slower where its change is spread over the clip, and longer otherwise), ``--resize
F`` (the DAVIS frames and masks resized by F before tracking and scoring: 1.5 and 2.25 are
720- and 1080-line views of the same scenes), ``--grey`` (the DAVIS frames turned grey, as
a grey camera gives them), ``--tint`` (in a sepia tone through YUV 4:2:0, as a monochrome
camera with a warm cast gives them), ``--noise SIGMA`` (Gaussian noise of SIGMA grey
levels added to every channel of the DAVIS frames, as a noisy sensor gives them),
``--stride K`` (one DAVIS frame in K tracked and scored, the masks alike: a camera at 1/K
of the frame rate, or a service that drops frames it cannot keep up with), ``--codec
mp4v|vp8`` (the DAVIS frames written as a video by OpenCV's encoder and read back, as a
user's compressed video reaches the tracker).

Cross-validation (:mod:`bench.tracking.cv`): ``--cv "search_radius=10,12,16"
[--cv "stiffness=20,40"] [--folds 5]`` tracks efdm with every point of the
grid on the training sequences, chooses on folds of them, reports the
cross-validated figures, and tracks the other sets asked for with the point
chosen on all the training sequences (not tuned on); results
``tracking_cv.md`` and ``tracking_cv.json``.
"""

from __future__ import annotations

import argparse
import dataclasses
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import cv2

from bench.common import machine
from bench.common.benchmark import Benchmark
from bench.common.log import log
from bench.common.machine import load_average
from bench.tracking import cv_report, report
from bench.tracking.config import FOLDS, FULL, NODES, QUICK, SETS, TIMED_PASSES, WORKERS, Config
from bench.tracking.cv import CvResults, parse_axis, parse_nodes, run_cv
from bench.tracking.plots import plot_scores, write_sheets
from bench.tracking.pool import Job, track_all
from bench.tracking.report import Results
from bench.tracking.run import ClipResult, pooled_median_ms, same_tracks
from bench.tracking.sets import CODECS, ClipSpec, choose, is_partial, limits
from bench.tracking.trackers import TRACKERS, Factory, factory

MIN_LENGTH = 3
"""Fewest frames of a synthetic clip: the first and the last are not scored, so three
leave one that is."""
MIN_RESIZE, MAX_RESIZE = 0.25, 4.0
"""Resize factors of ``--resize``: 120 to 1920 lines from DAVIS's 480."""
MAX_NOISE = 64.0
"""Largest ``--noise`` deviation: a quarter of the range, far beyond any camera's."""
MAX_STRIDE = 8
"""Largest ``--stride``: 3 frames a second from DAVIS's 24; the shortest sequence
(dog-agility, 25 frames) then keeps 4, two of them scored."""
TIMED_ORDER = ("davis-val", "davis-train", "synthetic")
"""The set whose timings are the speed figures: the first of these that runs."""


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


def set_jobs(
    config: Config, set_name: str, specs: Sequence[ClipSpec], trackers: tuple[str, ...]
) -> list[Job]:
    """The jobs of one set: its clips, the trackers in an order alternating from clip to clip."""
    capped = tuple(sorted(limits(config, set_name).items()))
    return [Job(s, trackers, capped, reverse=k % 2 == 1) for k, s in enumerate(specs)]


def machine_info(load_before: str) -> dict[str, str]:
    """Platform, CPU, library versions, the date and the load before and after."""
    info = machine.machine_info(opencv=cv2.__version__, skimage=machine.version("scikit-image"))
    return {**info, "load_before": load_before, "load_after": load_average()}


def run_plain(config: Config, args: argparse.Namespace) -> Results:
    """Every chosen tracker on every chosen clip of every chosen set, with the default options."""
    start, load_before = time.perf_counter(), load_average()
    factories, unavailable = load_factories(args.trackers)
    trackers = tuple(factories)
    chosen = {name: choose(config, name, args.sequences) for name in args.sets}
    notes = [why for _, why in chosen.values() if why]
    timed = next((name for name in TIMED_ORDER if chosen.get(name, ([], None))[0]), None)
    jobs = {name: set_jobs(config, name, specs, trackers) for name, (specs, _) in chosen.items()}
    sets: dict[str, list[ClipResult]] = {}
    pass_ms: dict[str, list[float]] = {}
    repeatable = True
    if timed is not None:
        passes: list[list[ClipResult]] = []
        for k in range(TIMED_PASSES):
            log(f"{timed}: tracked here, alone, pass {k + 1} of {TIMED_PASSES} (the speed figures)")
            passes.append(track_all(jobs[timed], workers=1))
        sets[timed] = passes[0]
        pass_ms = {t: [pooled_median_ms(p, t) for p in passes] for t in trackers}
        repeatable = all(same_tracks(passes[0], p) for p in passes[1:])
        if not repeatable:
            log(f"{timed}: the passes gave different contours")
    rest = [job for name in args.sets if name != timed for job in jobs[name]]
    log(f"{len(rest)} more clips on {args.workers} worker process(es)")
    for job, result in zip(rest, track_all(rest, args.workers), strict=True):
        sets.setdefault(job.clip.set, []).append(result)
    ran = {c.name for clips in sets.values() for c in clips}
    unknown = [name for name in args.sequences or () if name not in ran]
    if unknown:
        notes.append(f"requested but not found (or their set skipped): {', '.join(unknown)}")
        log(notes[-1])
    ordered = {name: sets.get(name, []) for name in SETS if name in args.sets}
    sheets = write_sheets(
        ordered, config.davis_sheets, config.synthetic_sheets, args.out, config.davis_stride
    )
    partial = tuple(n for n, (specs, _) in chosen.items() if is_partial(config, n, specs))
    return Results(
        config=config,
        trackers=trackers,
        sets=ordered,
        timed=timed,
        workers=args.workers,
        machine=machine_info(load_before),
        wall_seconds=time.perf_counter() - start,
        partial=partial,
        notes=notes,
        unavailable=unavailable,
        sheets=sheets,
        pass_ms=pass_ms,
        repeatable=repeatable,
    )


def run_tuning(config: Config, args: argparse.Namespace) -> CvResults:
    """The cross-validation mode (``--cv``): efdm only."""
    start, load_before = time.perf_counter(), load_average()
    if "efdm" not in args.trackers:
        raise SystemExit("--cv tunes efdm: --trackers must include efdm")
    results = run_cv(config, args)
    ignored = [t for t in args.trackers if t != "efdm"]
    if ignored:
        results.notes.append(f"--cv runs efdm only: {', '.join(ignored)} not run")
    results.machine = machine_info(load_before)
    results.wall_seconds = time.perf_counter() - start
    return results


def run(config: Config, args: argparse.Namespace) -> Results | CvResults:
    """The plain run, or the cross-validation with ``--cv``."""
    cv2.setNumThreads(1)
    if args.seeds is not None:
        config = dataclasses.replace(config, synthetic_seeds=args.seeds)
    if args.length is not None:
        config = dataclasses.replace(config, synthetic_length=args.length)
    if args.resize is not None:
        config = dataclasses.replace(config, davis_resize=args.resize)
    if args.grey:
        config = dataclasses.replace(config, davis_grey=True)
    if args.tint:
        config = dataclasses.replace(config, davis_tint=True)
    if args.noise:
        config = dataclasses.replace(config, davis_noise=args.noise)
    if args.stride != 1:
        config = dataclasses.replace(config, davis_stride=args.stride)
    if args.codec:
        config = dataclasses.replace(config, davis_codec=args.codec)
    return run_tuning(config, args) if args.cv else run_plain(config, args)


def render(results: Results | CvResults) -> str:
    """The markdown report of either mode."""
    if isinstance(results, CvResults):
        return cv_report.render(results)
    return report.render(results)


def to_json(results: Results | CvResults) -> Any:
    """The raw numbers of either mode."""
    if isinstance(results, CvResults):
        return cv_report.to_json(results)
    return report.to_json(results)


def stem(results: Results | CvResults) -> str:
    """``tracking_cv`` for a cross-validation, else ``tracking``."""
    return "tracking_cv" if isinstance(results, CvResults) else "tracking"


def figures(results: Results | CvResults, out: Path) -> list[str]:
    """The bar chart ``tracking.png`` (the contact sheets were written while running)."""
    if isinstance(results, CvResults):
        return []
    plot_scores(results.sets, results.trackers, out / "tracking.png")
    return ["tracking.png", *results.sheets]


def names(text: str) -> list[str]:
    """A comma-separated list."""
    return [part.strip() for part in text.split(",") if part.strip()]


def choices(allowed: Sequence[str]) -> Any:
    """An argparse type: a non-empty comma-separated list of names from ``allowed``."""

    def parse(text: str) -> list[str]:
        chosen = names(text)
        unknown = [name for name in chosen if name not in allowed]
        if unknown or not chosen:
            raise argparse.ArgumentTypeError(f"unknown {unknown}; choose from {allowed}")
        return chosen

    return parse


def count(least: int, most: int | None = None) -> Any:
    """An argparse type: an integer of at least ``least`` (and at most ``most``)."""

    def parse(text: str) -> int:
        value = int(text)
        if value < least:
            raise argparse.ArgumentTypeError(f"must be at least {least}; got {value}")
        if most is not None and value > most:
            raise argparse.ArgumentTypeError(f"must be at most {most}; got {value}")
        return value

    return parse


def factor(text: str) -> float:
    """An argparse type: a resize factor in [:data:`MIN_RESIZE`, :data:`MAX_RESIZE`]."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"must be a number; got {text!r}") from None
    if not MIN_RESIZE <= value <= MAX_RESIZE:
        raise argparse.ArgumentTypeError(
            f"must be in [{MIN_RESIZE:g}, {MAX_RESIZE:g}]; got {value:g}"
        )
    return value


def noise_level(text: str) -> float:
    """An argparse type: a noise deviation in [0, :data:`MAX_NOISE`] grey levels."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"must be a number; got {text!r}") from None
    if not 0.0 <= value <= MAX_NOISE:
        raise argparse.ArgumentTypeError(f"must be in [0, {MAX_NOISE:g}]; got {value:g}")
    return value


def arguments(parser: argparse.ArgumentParser) -> None:
    """``--sets``, ``--sequences``, ``--trackers``, ``--workers``, ``--cv``, ``--folds``,
    ``--seeds``, ``--length``, ``--resize``, ``--grey``, ``--tint``, ``--noise``,
    ``--stride``, ``--codec`` and ``--nodes``."""
    parser.add_argument("--sets", type=choices(SETS), default=list(SETS), help=",".join(SETS))
    parser.add_argument(
        "--sequences", type=names, default=None, help="DAVIS sequences / synthetic conditions"
    )
    parser.add_argument(
        "--trackers", type=choices(TRACKERS), default=list(TRACKERS), help=",".join(TRACKERS)
    )
    parser.add_argument(
        "--workers", type=count(1), default=WORKERS, help="processes for the untimed sets"
    )
    parser.add_argument(
        "--cv",
        type=parse_axis,
        action="append",
        default=[],
        metavar="OPTION=V1,V2",
        help="cross-validate efdm's option over these values (JSON); repeat for a grid",
    )
    parser.add_argument("--folds", type=count(2), default=FOLDS, help="cross-validation folds")
    parser.add_argument(
        "--seeds",
        type=count(1),
        default=None,
        help="seeds 0..N-1 of every synthetic condition (default: 3, with --quick 1)",
    )
    parser.add_argument(
        "--length",
        type=count(MIN_LENGTH),
        default=None,
        help="frames of every synthetic clip (default: 40, with --quick 12)",
    )
    parser.add_argument(
        "--resize",
        type=factor,
        default=None,
        help="resize the DAVIS frames and masks by this factor before tracking (1.5: 720 "
        "lines; default 1)",
    )
    parser.add_argument(
        "--grey", action="store_true", help="turn the DAVIS frames grey before tracking"
    )
    parser.add_argument(
        "--tint",
        action="store_true",
        help="give the DAVIS frames a sepia tone (a monochrome camera with a warm cast, "
        "through YUV 4:2:0) before tracking",
    )
    parser.add_argument(
        "--noise",
        type=noise_level,
        default=0.0,
        metavar="SIGMA",
        help="add Gaussian noise of SIGMA grey levels to every channel of the DAVIS frames "
        "before tracking (a noisy sensor; default 0)",
    )
    parser.add_argument(
        "--stride",
        type=count(1, MAX_STRIDE),
        default=1,
        metavar="K",
        help="track and score one DAVIS frame in K (a camera at 1/K of the frame rate, or "
        "a service dropping frames; default 1)",
    )
    parser.add_argument(
        "--codec",
        choices=sorted(CODECS),
        default="",
        help="write the DAVIS frames as a video with this codec (OpenCV's encoder, default "
        "quality) and track the frames read back (default: none)",
    )
    parser.add_argument(
        "--nodes",
        type=parse_nodes,
        default=(NODES,),
        metavar="N1,N2",
        help="with --cv: node counts each training sequence is tracked with (J: their mean)",
    )


BENCHMARK: Benchmark[Config, Results | CvResults] = Benchmark(
    "tracking",
    __doc__,
    FULL,
    QUICK,
    run,
    render,
    to_json,
    stem_of=stem,
    figures=figures,
    arguments=arguments,
)
