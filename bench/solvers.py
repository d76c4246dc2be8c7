"""Solver benchmark: section IV of Krinidis & Pitas on this machine.

Reproduces the paper's fig. 2 (error of EFDM, EFDMT and DMMAT against DMMA,
eq. 23) and fig. 4 (time per deformation against the number of nodes N), adds
the O(N) ``"exact"`` solver and a plain numpy FFT solve as baselines, shows the
paper's eq. 18 as printed breaking down, and checks the project's speed goals.

Run ``python bench/solvers.py`` (``make bench-solvers``); ``--quick`` runs a
reduced set for smoke tests, ``--out DIR`` changes where the results go
(default ``bench/results/``): ``solvers.md``, ``solvers.json``,
``solvers.png`` (fig. 4) and ``solvers_error.png`` (fig. 2).
"""

from __future__ import annotations

import argparse
import json
import math
import os
import platform
import statistics
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import asdict, dataclass
from datetime import datetime
from importlib import metadata
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

import engine

if TYPE_CHECKING:
    from matplotlib.axes import Axes

Array = NDArray[np.float64]
Call = Callable[[], object]

REPO = Path(__file__).resolve().parent.parent
DEFAULT_OUT = REPO / "bench" / "results"
SEED = 20240501
A_MAIN = 10.0
EFDMT_TOL = 1e-8
NOISE = 0.02
"""Standard deviation of the white noise added to the smooth forces."""

PAPER_ERROR_PCT = {"efdm": 0.0, "efdmt": 0.00000314, "dmmat": 0.00293462}
"""The paper's average errors against DMMA (section IV, fig. 2), in percent."""

TIMED_METHODS = ("dmma", "dmmat", "efdm", "efdmt", "exact", "fft")
ERROR_METHODS = ("efdm", "efdmt", "efdmt_tol", "dmmat", "exact", "fft", "literal")
ERROR_LABELS = {
    "efdm": "EFDM",
    "efdmt": "EFDMT (paper M)",
    "efdmt_tol": f"EFDMT (tol={EFDMT_TOL:g})",
    "dmmat": "DMMAT (25 %)",
    "exact": "exact",
    "fft": "numpy FFT",
    "literal": "literal eq. 18",
}
EFDMT_NOTE = (
    "Reading the table: EFDM, exact, FFT (and the literal formula while it is finite) differ "
    "from DMMA only by DMMA's own rounding. The paper's M = ceil(mu ln N) drops weights "
    "summing to about 2 r^(M+1) / (s (1 - r)) with r^M = N^(mu ln r) (N^-1.17 at a = 10), "
    "hence EFDMT errors of order 1e-3 to 1 %, far above the paper's 3.14e-6 %; when "
    "2M + 1 >= N nothing is truncated and EFDMT is exact. DMMAT's error depends only on how "
    "much of the force spectrum lies above the kept 25 % of the modes (here: the noise)."
)
LITERAL_CASES = ((101, 10.0), (101, 100.0), (500, 10.0), (541, 10.0), (1000, 10.0), (2000, 10.0))
IMPORT_SNIPPET = (
    "import json, sys, time; t = time.perf_counter(); import engine; "
    "dt = time.perf_counter() - t; "
    "print(json.dumps({'seconds': dt, 'loaded': sorted(m for m in "
    "('fastapi', 'uvicorn', 'numba', 'scipy', 'matplotlib') if m in sys.modules)}))"
)
FIRST_CALL_SNIPPET = (
    "import json, time; import numpy as np; import engine; F = np.ones((1000, 2)); "
    "t = time.perf_counter(); engine.deform(F, 10.0); t1 = time.perf_counter() - t; "
    "t = time.perf_counter(); engine.deform(F, 10.0); t2 = time.perf_counter() - t; "
    "print(json.dumps({'first': t1, 'second': t2}))"
)


@dataclass(frozen=True, slots=True)
class Config:
    """What to measure, and how hard.

    Attributes
    ----------
    name : str
        ``"full"`` or ``"quick"``.
    error_sizes, error_stiffnesses : tuple
        The (N, a) grid of the error study (fig. 2).
    timing_sizes : tuple of int
        N of the timing study (fig. 4), closed chain, a = 10.
    open_sizes : tuple of int
        N at which the open chain is timed with ``"exact"``.
    limits : Mapping[str, int]
        Largest N timed per method (absent: no limit).
    budget : float
        Seconds of timed calls aimed at per measurement.
    min_repeats, max_repeats : int
        Bounds on the number of timed repeats (the median is reported).
    import_runs : int
        Fresh interpreters started to time ``import engine``.
    """

    name: str
    error_sizes: tuple[int, ...]
    error_stiffnesses: tuple[float, ...]
    timing_sizes: tuple[int, ...]
    open_sizes: tuple[int, ...]
    limits: Mapping[str, int]
    budget: float
    min_repeats: int
    max_repeats: int
    import_runs: int


FULL = Config(
    name="full",
    error_sizes=(50, 100, 200, 500, 1000, 2000),
    error_stiffnesses=(1.0, 10.0, 100.0),
    timing_sizes=(
        100,
        300,
        1000,
        3000,
        5000,
        10_000,
        20_000,
        50_000,
        100_000,
        200_000,
        500_000,
        1_000_000,
    ),
    open_sizes=(1000, 10_000, 100_000, 1_000_000),
    limits={"dmma": 3000, "dmmat": 3000, "efdm": 20_000},
    budget=1.0,
    min_repeats=3,
    max_repeats=51,
    import_runs=5,
)
QUICK = Config(
    name="quick",
    error_sizes=(50, 100, 200, 500),
    error_stiffnesses=(1.0, 10.0, 100.0),
    timing_sizes=(100, 300, 1000, 3000, 5000, 10_000, 20_000),
    open_sizes=(1000, 20_000),
    limits={"dmma": 1000, "dmmat": 1000, "efdm": 5000},
    budget=0.2,
    min_repeats=3,
    max_repeats=15,
    import_runs=3,
)


@dataclass(frozen=True, slots=True)
class Goal:
    """A speed goal: ``fast`` must beat ``slow`` by ``target`` times at N nodes."""

    n: int
    fast: str
    slow: str
    target: float


GOALS = (
    Goal(1_000_000, "exact", "fft", 4.0),
    Goal(20_000, "exact", "fft", 2.0),
    Goal(5000, "efdmt", "efdm", 20.0),
)
IMPORT_GOAL_SECONDS = 0.5


@dataclass(frozen=True, slots=True)
class Timing:
    """Seconds per call of one measurement.

    Attributes
    ----------
    first : float
        The warm-up call (includes compilation, lazy imports, cold caches).
    median, best : float
        Median and minimum over the repeats.
    repeats : int
        Timed repeats.
    number : int
        Calls per repeat (several for very fast calls).
    samples : tuple of float
        Seconds per call of each repeat.
    """

    first: float
    median: float
    best: float
    repeats: int
    number: int
    samples: tuple[float, ...]


@dataclass(frozen=True, slots=True)
class TimingRecord:
    """One point of fig. 4."""

    method: str
    n: int
    closed: bool
    timing: Timing


@dataclass(frozen=True, slots=True)
class ErrorRecord:
    """One (N, a) point of fig. 2: errors against DMMA in percent (eq. 23)."""

    n: int
    a: float
    m_paper: int
    m_tol: int
    errors: dict[str, float]


@dataclass(frozen=True, slots=True)
class LiteralRecord:
    """The paper's eq. 18 as printed, against DMMA, next to the stable form."""

    n: int
    a: float
    literal_pct: float
    efdm_pct: float
    finite: bool


@dataclass(frozen=True, slots=True)
class GoalResult:
    """A measured speed goal."""

    goal: Goal
    fast: Timing
    slow: Timing

    @property
    def speedup(self) -> float:
        """Median time of ``slow`` over median time of ``fast``."""
        return self.slow.median / self.fast.median

    @property
    def passed(self) -> bool:
        """Whether the speed-up reaches the target."""
        return self.speedup >= self.goal.target


@dataclass(frozen=True, slots=True)
class ImportResult:
    """``import engine`` in fresh interpreters."""

    seconds: tuple[float, ...]
    loaded: tuple[str, ...]

    @property
    def median(self) -> float:
        """Median import time in seconds."""
        return statistics.median(self.seconds)

    @property
    def server_free(self) -> bool:
        """Whether fastapi and uvicorn stayed out of ``sys.modules``."""
        return not {"fastapi", "uvicorn"} & set(self.loaded)


@dataclass(frozen=True, slots=True)
class FirstCall:
    """Cost of the first ``"exact"`` call (numba compilation or cache load), seconds."""

    in_process: float
    cold_cache: float
    warm_cache: float
    after_first: float


@dataclass(frozen=True, slots=True)
class Results:
    """Everything one run measured."""

    config: Config
    machine: dict[str, str]
    first_call: FirstCall
    errors: list[ErrorRecord]
    literal: list[LiteralRecord]
    literal_breakdown: dict[str, int | None]
    timings: list[TimingRecord]
    goals: list[GoalResult]
    imports: ImportResult
    wall_seconds: float


def log(message: str) -> None:
    """Progress line on stderr."""
    print(f"[bench/solvers] {message}", file=sys.stderr, flush=True)


# --------------------------------------------------------------------------- forces and solvers


def make_forces(n: int, seed: int = SEED) -> Array:
    """Seeded smooth-ish forces of shape (N, 2) whose displacements stay away from 0.

    A constant pull of magnitude 5 in a random direction, four random Fourier
    modes of orders 1-4 (amplitudes well below the pull) and white noise of
    standard deviation :data:`NOISE`.

    Parameters
    ----------
    n : int
        Number of nodes.
    seed : int
        Seed; combined with ``n`` so every size gets its own forces.

    Returns
    -------
    numpy.ndarray
        Shape (n, 2), ``[x, y]``.
    """
    rng = np.random.default_rng([seed, n])
    angle = rng.uniform(0.0, 2.0 * np.pi)
    forces = np.tile(5.0 * np.array([np.cos(angle), np.sin(angle)]), (n, 1))
    t = 2.0 * np.pi * np.arange(n) / n
    for order in range(1, 5):
        cos_amp, sin_amp = rng.uniform(-1.0, 1.0, size=(2, 2)) * (0.6 / order)
        forces += np.outer(np.cos(order * t), cos_amp) + np.outer(np.sin(order * t), sin_amp)
    noise: Array = NOISE * rng.standard_normal((n, 2))
    return forces + noise


def fft_solve(forces: Array, a: float) -> Array:
    """The closed-chain solve a numpy user would write: divide in Fourier space.

    Parameters
    ----------
    forces : numpy.ndarray
        Shape (N, 2).
    a : float
        Stiffness ``a = k/m``.

    Returns
    -------
    numpy.ndarray
        U = (I + a L)^-1 F, shape (N, 2).
    """
    n = forces.shape[0]
    k = np.arange(n // 2 + 1)
    spectrum = np.fft.rfft(forces, axis=0) / (1.0 + 4.0 * a * np.sin(np.pi * k / n) ** 2)[:, None]
    result: Array = np.fft.irfft(spectrum, n=n, axis=0)
    return result


def literal_solve(forces: Array, a: float) -> Array:
    """U from the paper's eq. 18 weights as printed (:func:`engine.literal_kernel`).

    A dense circulant gather, so the only rounding is the formula's own.

    Parameters
    ----------
    forces : numpy.ndarray
        Shape (N, 2), closed chain.
    a : float
        Stiffness ``a = k/m``.

    Returns
    -------
    numpy.ndarray
        Shape (N, 2); non-finite where the formula overflows.
    """
    n = forces.shape[0]
    weights = engine.literal_kernel(n, a)
    index = np.subtract.outer(np.arange(n), np.arange(n)) % n
    with np.errstate(over="ignore", invalid="ignore"):
        result: Array = weights[index] @ forces
    return result


def solver(method: str, forces: Array, a: float, *, closed: bool = True) -> Call:
    """A zero-argument call that runs ``method`` on ``forces`` (``"fft"``: the baseline)."""
    if method == "fft":
        return lambda: fft_solve(forces, a)
    return lambda: engine.deform(forces, a, closed=closed, method=method)


def percent_error(U: Array, reference: Array) -> float:
    """The paper's eq. 23: mean over nodes of |U_i - U'_i| / |U_i|, in percent.

    Parameters
    ----------
    U : numpy.ndarray
        Approximation, shape (N, 2).
    reference : numpy.ndarray
        DMMA displacements, shape (N, 2); |.| is the Euclidean norm per node.

    Returns
    -------
    float
        The error in percent; nan when ``U`` is not finite.
    """
    if not np.isfinite(U).all():
        return math.nan
    ratio = np.linalg.norm(U - reference, axis=1) / np.linalg.norm(reference, axis=1)
    return float(100.0 * ratio.mean())


# --------------------------------------------------------------------------- timing


def sample(fn: Call, number: int) -> float:
    """Seconds per call of ``number`` back-to-back calls."""
    start = time.perf_counter()
    for _ in range(number):
        fn()
    return (time.perf_counter() - start) / number


def calibrate(fn: Call, min_block: float) -> tuple[float, float, int]:
    """Warm up ``fn``, then choose how many calls make one timed repeat.

    Returns
    -------
    first : float
        Seconds of the warm-up call.
    estimate : float
        Seconds of a second call.
    number : int
        Calls per repeat so that a repeat lasts at least ``min_block``.
    """
    first = sample(fn, 1)
    estimate = sample(fn, 1)
    number = max(1, math.ceil(min_block / max(estimate, 1e-9)))
    return first, estimate, number


def summarise(first: float, number: int, samples: Sequence[float]) -> Timing:
    """Median, best and raw samples of one measurement."""
    return Timing(
        first=first,
        median=statistics.median(samples),
        best=min(samples),
        repeats=len(samples),
        number=number,
        samples=tuple(samples),
    )


def measure(fn: Call, config: Config) -> Timing:
    """Time ``fn``: a warm-up call, then the median of repeats within the budget."""
    first, estimate, number = calibrate(fn, min_block=2e-3)
    wanted = int(config.budget / max(estimate * number, 1e-9))
    repeats = min(config.max_repeats, max(config.min_repeats, wanted))
    samples = [estimate] if number == 1 else []
    samples += [sample(fn, number) for _ in range(repeats - len(samples))]
    return summarise(first, number, samples)


def measure_side_by_side(fns: Sequence[Call], config: Config) -> list[Timing]:
    """Time several calls in alternation, so that they see the same machine state."""
    calibrated = [calibrate(fn, min_block=5e-3) for fn in fns]
    per_round = sum(est * number for _, est, number in calibrated)
    wanted = int(2.0 * config.budget / max(per_round, 1e-9))
    repeats = min(2 * config.max_repeats, max(2 * config.min_repeats + 1, wanted))
    samples: list[list[float]] = [[] for _ in fns]
    for _ in range(repeats):
        for fn, (_, _, number), into in zip(fns, calibrated, samples, strict=True):
            into.append(sample(fn, number))
    return [
        summarise(first, number, got)
        for (first, _, number), got in zip(calibrated, samples, strict=True)
    ]


def is_timed(method: str, n: int, config: Config) -> bool:
    """Whether ``method`` is cheap enough to time at N nodes."""
    return n <= config.limits.get(method, n)


def timing_study(config: Config) -> list[TimingRecord]:
    """Fig. 4: time per deformation of every method (closed, a = 10; open: exact)."""
    records: list[TimingRecord] = []
    for n in config.timing_sizes:
        forces = make_forces(n)
        for method in TIMED_METHODS:
            if is_timed(method, n, config):
                timing = measure(solver(method, forces, A_MAIN), config)
                records.append(TimingRecord(method, n, True, timing))
                log(f"time {method:>6} closed N={n:>8}: {fmt_seconds(timing.median)}")
    for n in config.open_sizes:
        timing = measure(solver("exact", make_forces(n), A_MAIN, closed=False), config)
        records.append(TimingRecord("exact", n, False, timing))
        log(f"time  exact   open N={n:>8}: {fmt_seconds(timing.median)}")
    return records


def goal_study(config: Config) -> list[GoalResult]:
    """The speed goals, each pair measured in alternation in this process."""
    results: list[GoalResult] = []
    for goal in GOALS:
        forces = make_forces(goal.n)
        fast, slow = measure_side_by_side(
            [solver(goal.fast, forces, A_MAIN), solver(goal.slow, forces, A_MAIN)], config
        )
        result = GoalResult(goal, fast, slow)
        results.append(result)
        log(f"goal {goal.fast} vs {goal.slow} N={goal.n}: {result.speedup:.1f}x")
    return results


def run_python(code: str, env: Mapping[str, str] | None = None) -> dict[str, Any]:
    """Run ``code`` in a fresh interpreter in the repository; parse its JSON output."""
    done = subprocess.run(
        [sys.executable, "-c", code],
        cwd=REPO,
        env=None if env is None else dict(env),
        capture_output=True,
        text=True,
        check=True,
    )
    parsed: dict[str, Any] = json.loads(done.stdout.strip().splitlines()[-1])
    return parsed


def import_study(config: Config) -> ImportResult:
    """``import engine`` time in fresh interpreters, and which heavy modules it loads."""
    runs = [run_python(IMPORT_SNIPPET) for _ in range(config.import_runs)]
    loaded = sorted({name for run in runs for name in run["loaded"]})
    result = ImportResult(tuple(float(run["seconds"]) for run in runs), tuple(loaded))
    log(f"import engine: median {fmt_seconds(result.median)}, loaded {loaded or 'nothing heavy'}")
    return result


def first_call_study(in_process: float) -> FirstCall:
    """First ``"exact"`` call: numba compiling into an empty cache, then loading it."""
    with tempfile.TemporaryDirectory(prefix="efdm-numba-cache-") as cache:
        env = {**os.environ, "NUMBA_CACHE_DIR": cache}
        cold = run_python(FIRST_CALL_SNIPPET, env)
        warm = run_python(FIRST_CALL_SNIPPET, env)
    result = FirstCall(
        in_process=in_process,
        cold_cache=float(cold["first"]),
        warm_cache=float(warm["first"]),
        after_first=float(warm["second"]),
    )
    log(
        f"first exact call: compile {fmt_seconds(result.cold_cache)}, cached load "
        f"{fmt_seconds(result.warm_cache)}"
    )
    return result


def time_first_exact_call() -> float:
    """Seconds of this process's first ``"exact"`` call (before any other use)."""
    return sample(solver("exact", make_forces(1000), A_MAIN), 1)


# --------------------------------------------------------------------------- errors


def error_record(n: int, a: float) -> ErrorRecord:
    """Every method's eq. 23 error against DMMA at one (N, a)."""
    forces = make_forces(n)
    reference = engine.deform(forces, a, method="dmma")
    results: dict[str, Array] = {
        "efdm": engine.deform(forces, a, method="efdm"),
        "efdmt": engine.deform(forces, a, method="efdmt"),
        "efdmt_tol": engine.deform(forces, a, method="efdmt", tol=EFDMT_TOL),
        "dmmat": engine.deform(forces, a, method="dmmat"),
        "exact": engine.deform(forces, a, method="exact"),
        "fft": fft_solve(forces, a),
        "literal": literal_solve(forces, a),
    }
    errors = {name: percent_error(U, reference) for name, U in results.items()}
    return ErrorRecord(
        n=n,
        a=a,
        m_paper=engine.paper_radius(n, a),
        m_tol=engine.tolerance_radius(a, EFDMT_TOL),
        errors=errors,
    )


def error_study(config: Config) -> list[ErrorRecord]:
    """Fig. 2: errors against DMMA over the (N, a) grid."""
    records: list[ErrorRecord] = []
    for a in config.error_stiffnesses:
        for n in config.error_sizes:
            record = error_record(n, a)
            records.append(record)
            log(
                f"error a={a:g} N={n}: "
                + ", ".join(f"{k}={fmt_pct(v)}" for k, v in record.errors.items())
            )
    return records


def literal_study() -> list[LiteralRecord]:
    """The paper's eq. 18 as printed at a few (N, a), next to the stable EFDM."""
    records: list[LiteralRecord] = []
    for n, a in LITERAL_CASES:
        forces = make_forces(n)
        reference = engine.deform(forces, a, method="dmma")
        literal = literal_solve(forces, a)
        records.append(
            LiteralRecord(
                n=n,
                a=a,
                literal_pct=percent_error(literal, reference),
                efdm_pct=percent_error(engine.deform(forces, a, method="efdm"), reference),
                finite=bool(np.isfinite(engine.literal_kernel(n, a)).all()),
            )
        )
    return records


def literal_breakdown(a: float, n_max: int = 5000, rtol: float = 1e-6) -> int | None:
    """Smallest N whose printed eq. 18 weights are non-finite or off by more than ``rtol``."""
    for n in range(3, n_max + 1):
        stable = engine.green_kernel(n, a)
        literal = engine.literal_kernel(n, a)
        with np.errstate(invalid="ignore"):
            bad = ~(np.abs(literal - stable) <= rtol * stable)
        if bad.any():
            return n
    return None


# --------------------------------------------------------------------------- report


def fmt_seconds(seconds: float) -> str:
    """Seconds with a readable unit."""
    if seconds < 1e-3:
        return f"{seconds * 1e6:.1f} us"
    if seconds < 1.0:
        return f"{seconds * 1e3:.2f} ms"
    return f"{seconds:.2f} s"


def fmt_pct(value: float) -> str:
    """A percentage for the tables (non-finite: ``nan/inf``)."""
    if not math.isfinite(value):
        return "nan/inf"
    if value == 0.0:
        return "0"
    return f"{value:.3g}" if value >= 1e-3 else f"{value:.2e}"


def md_table(headers: Sequence[str], rows: Sequence[Sequence[str]]) -> str:
    """A markdown table."""
    lines = ["| " + " | ".join(headers) + " |", "|" + "|".join("---" for _ in headers) + "|"]
    lines += ["| " + " | ".join(row) + " |" for row in rows]
    return "\n".join(lines)


def machine_info() -> dict[str, str]:
    """Platform, CPU and library versions, and the date."""
    affinity = getattr(os, "sched_getaffinity", None)
    return {
        "date": datetime.now().astimezone().isoformat(timespec="seconds"),
        "platform": platform.platform(),
        "python": platform.python_version(),
        "cpu": cpu_model(),
        "cpu_count": str(os.cpu_count()),
        "usable_cpus": str(len(affinity(0))) if affinity is not None else "?",
        "numpy": np.__version__,
        "scipy": metadata.version("scipy"),
        "numba": metadata.version("numba"),
    }


def cpu_model() -> str:
    """The CPU model name from /proc/cpuinfo, else ``platform.processor()``."""
    try:
        text = Path("/proc/cpuinfo").read_text(encoding="utf-8")
    except OSError:
        return platform.processor() or "?"
    for line in text.splitlines():
        if line.startswith("model name"):
            return line.split(":", 1)[1].strip()
    return platform.processor() or "?"


def mean_errors(records: Sequence[ErrorRecord], a: float) -> dict[str, float]:
    """Average error per method over N at stiffness ``a`` (nan if any is non-finite)."""
    chosen = [r for r in records if r.a == a]
    return {m: float(np.mean([r.errors[m] for r in chosen])) for m in ERROR_METHODS}


def error_section(results: Results) -> str:
    """Markdown for fig. 2 and the literal eq. 18."""
    headers = ["a", "N", "M paper", *(ERROR_LABELS[m] for m in ERROR_METHODS)]
    rows = [
        [f"{r.a:g}", str(r.n), str(r.m_paper), *(fmt_pct(r.errors[m]) for m in ERROR_METHODS)]
        for r in results.errors
    ]
    for a in results.config.error_stiffnesses:
        means = mean_errors(results.errors, a)
        rows.append([f"{a:g}", "**mean**", "", *(fmt_pct(means[m]) for m in ERROR_METHODS)])
    rows.append(
        [
            "",
            "**paper**",
            "",
            *(fmt_pct(PAPER_ERROR_PCT[m]) if m in PAPER_ERROR_PCT else "" for m in ERROR_METHODS),
        ]
    )
    m_tol = ", ".join(sorted({f"{r.m_tol} (a = {r.a:g})" for r in results.errors}))
    literal_rows = [
        [
            str(r.n),
            f"{r.a:g}",
            "yes" if r.finite else "no",
            fmt_pct(r.literal_pct),
            fmt_pct(r.efdm_pct),
        ]
        for r in results.literal
    ]
    breakdown = ", ".join(
        f"a = {a}: N = {n}" if n is not None else f"a = {a}: none up to 5000"
        for a, n in results.literal_breakdown.items()
    )
    return "\n\n".join(
        [
            "## Fig. 2: error against DMMA (eq. 23, percent)",
            "E = (1/N) sum_i |U_i - U'_i| / |U_i| * 100, U = DMMA (eigendecomposition), closed "
            f"chain. Forces: constant pull of 5 px in a random direction, Fourier modes 1-4 with "
            f"amplitudes <= 0.6/k, white noise sigma = {NOISE}; seeded per N. "
            f"EFDMT (paper M) uses M = ceil(mu ln N); EFDMT (tol) uses the tolerance rule, "
            f"M = {m_tol}.",
            md_table(headers, rows),
            EFDMT_NOTE,
            "### The paper's eq. 18 as printed (`engine.literal_kernel`)",
            md_table(
                ["N", "a", "weights finite", "literal eq. 18", "EFDM (stable form)"], literal_rows
            ),
            f"First N at which the printed weights are non-finite or off by > 1e-6 relative: "
            f"{breakdown}.",
        ]
    )


def timing_table(records: Sequence[TimingRecord], closed: bool, methods: Sequence[str]) -> str:
    """Median seconds per deformation, one row per N."""
    table = {(r.method, r.n): r.timing for r in records if r.closed == closed}
    sizes = sorted({n for _, n in table})
    rows = [
        [f"{n:,}", *(fmt_seconds(table[m, n].median) if (m, n) in table else "-" for m in methods)]
        for n in sizes
    ]
    return md_table(["N", *methods], rows)


def timing_section(results: Results) -> str:
    """Markdown for fig. 4, the open chain and the first calls."""
    first = results.first_call
    lookup = {(r.method, r.n): r.timing for r in results.timings if r.closed}
    efdmt_20k = lookup.get(("efdmt", 20_000))
    rate = f"{1.0 / efdmt_20k.median:,.0f} deformations/s" if efdmt_20k else "not measured"
    slow_first = [
        f"{r.method} N={r.n:,}: first {fmt_seconds(r.timing.first)} vs median "
        f"{fmt_seconds(r.timing.median)}"
        for r in results.timings
        if r.timing.first > 3.0 * r.timing.median and r.timing.first > 0.02
    ]
    return "\n\n".join(
        [
            "## Fig. 4: time per deformation (closed chain, a = 10, median)",
            "Each entry: one warm-up call, then the median of timed repeats (several calls per "
            "repeat when a call is shorter than 2 ms). `fft` is the numpy FFT baseline "
            "`irfft(rfft(F) / (1 + 4a sin^2(pi k/N)))`. `-`: not timed (too slow).",
            timing_table(results.timings, True, TIMED_METHODS),
            f"EFDMT at N = 20,000: {rate} (paper, Pentium III 700 MHz: 100/s).",
            "### Open chain, `exact`",
            timing_table(results.timings, False, ("exact",)),
            "### First call of `exact` (numba; informational)",
            md_table(
                ["case", "time"],
                [
                    [
                        "first call in this benchmark process (on-disk cache as found)",
                        fmt_seconds(first.in_process),
                    ],
                    [
                        "fresh process, empty NUMBA_CACHE_DIR (compilation)",
                        fmt_seconds(first.cold_cache),
                    ],
                    ["fresh process, cache filled by the run above", fmt_seconds(first.warm_cache)],
                    ["second call in that process (N = 1000)", fmt_seconds(first.after_first)],
                ],
            ),
            "Warm-up calls much slower than the median (> 3x and > 20 ms): "
            + ("; ".join(slow_first) if slow_first else "none")
            + ".",
        ]
    )


def goal_rows(results: Results) -> list[list[str]]:
    """Rows of the goals table."""
    rows = [
        [
            f"{g.goal.fast} vs {g.goal.slow}",
            f"{g.goal.n:,}",
            fmt_seconds(g.fast.median),
            fmt_seconds(g.slow.median),
            f"{g.speedup:.1f}x",
            f">= {g.goal.target:g}x",
            "PASS" if g.passed else "FAIL",
        ]
        for g in results.goals
    ]
    imports = results.imports
    rows.append(
        [
            "`import engine` (fresh process)",
            "-",
            fmt_seconds(imports.median),
            "-",
            "-",
            f"< {IMPORT_GOAL_SECONDS:g} s",
            "PASS" if imports.median < IMPORT_GOAL_SECONDS else "FAIL",
        ]
    )
    rows.append(
        [
            "no fastapi/uvicorn after `import engine`",
            "-",
            "-",
            "-",
            "-",
            "not in sys.modules",
            "PASS" if imports.server_free else "FAIL",
        ]
    )
    return rows


def goals_section(results: Results) -> str:
    """Markdown for the goals."""
    imports = results.imports
    loaded = ", ".join(imports.loaded) or "none of fastapi, uvicorn, numba, scipy, matplotlib"
    return "\n\n".join(
        [
            "## Goals (each pair measured in alternation in one process)",
            md_table(
                ["goal", "N", "fast", "slow", "speed-up", "target", "result"], goal_rows(results)
            ),
            f"`import engine` runs: {', '.join(fmt_seconds(s) for s in imports.seconds)}; "
            f"heavy modules loaded by the import: {loaded}.",
        ]
    )


def render(results: Results) -> str:
    """The whole markdown report."""
    machine = results.machine
    header = "\n".join(
        [
            "# Solver benchmark (Krinidis & Pitas, section IV)",
            "",
            f"- date: {machine['date']}",
            f"- machine: {machine['platform']}; CPU {machine['cpu']}; "
            f"{machine['cpu_count']} CPUs ({machine['usable_cpus']} usable)",
            f"- python {machine['python']}, numpy {machine['numpy']}, scipy {machine['scipy']}, "
            f"numba {machine['numba']}",
            f"- run: `{results.config.name}`, {results.wall_seconds:.0f} s wall time",
        ]
    )
    sections = [header, goals_section(results), error_section(results), timing_section(results)]
    return "\n\n".join(sections) + "\n"


# --------------------------------------------------------------------------- plots and files


def plot_timings(records: Sequence[TimingRecord], path: Path) -> None:
    """Fig. 4: log-log time per deformation against N, one line per method."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(8, 5.5), layout="constrained")
    styles = {"dmma": "o-", "dmmat": "s-", "efdm": "^-", "efdmt": "v-", "exact": "D-", "fft": "x--"}
    for method in TIMED_METHODS:
        points = sorted((r.n, r.timing.median) for r in records if r.method == method and r.closed)
        if points:
            xs, ys = zip(*points, strict=True)
            label = "numpy FFT" if method == "fft" else method
            hollow = method == "dmma"  # dmmat costs the same: keep both visible
            ax.plot(
                xs,
                ys,
                styles[method],
                label=label,
                markersize=9 if hollow else 5,
                markerfacecolor="none" if hollow else None,
            )
    open_points = sorted((r.n, r.timing.median) for r in records if not r.closed)
    if open_points:
        xs, ys = zip(*open_points, strict=True)
        ax.plot(xs, ys, "D:", color="grey", label="exact (open chain)", markersize=4)
    ax.set(
        xscale="log",
        yscale="log",
        xlabel="nodes N",
        ylabel="seconds per deformation",
        title="Time per deformation (closed chain, a = 10; cf. paper fig. 4)",
    )
    ax.grid(True, which="both", alpha=0.3)
    ax.legend()
    fig.savefig(path, dpi=120)
    plt.close(fig)


ERROR_COLOURS = {"efdm": "C0", "efdmt": "C1", "efdmt_tol": "C4", "dmmat": "C2", "literal": "C3"}


def error_points(
    records: Sequence[ErrorRecord], method: str, a: float, floor: float
) -> tuple[list[int], list[float], list[int]]:
    """N and error of the finite points (clipped below at ``floor``), and the non-finite N."""
    chosen = [(r.n, r.errors[method]) for r in records if r.a == a]
    finite = [(n, max(e, floor)) for n, e in chosen if math.isfinite(e)]
    return (
        [n for n, _ in finite],
        [e for _, e in finite],
        [n for n, e in chosen if not math.isfinite(e)],
    )


def draw_paper_lines(ax: Axes) -> None:
    """The paper's average EFDMT and DMMAT errors as horizontal bands."""
    for method, value in PAPER_ERROR_PCT.items():
        if value > 0:
            ax.axhline(value, color=ERROR_COLOURS[method], alpha=0.35, linewidth=4)
            ax.annotate(
                f"paper {ERROR_LABELS[method]}: {value:g} %",
                (0.02, value),
                xycoords=("axes fraction", "data"),
                fontsize=7,
                va="bottom",
            )


def draw_main_panel(ax: Axes, records: Sequence[ErrorRecord], floor: float) -> None:
    """Every method at a = 10; non-finite literal points marked at the top."""
    for method, colour in ERROR_COLOURS.items():
        xs, ys, bad = error_points(records, method, A_MAIN, floor)
        hollow = method == "efdm"  # drawn under the literal and exact curves otherwise
        ax.plot(
            xs,
            ys,
            "s-" if hollow else "o-",
            color=colour,
            label=ERROR_LABELS[method],
            markersize=8 if hollow else 4,
            markerfacecolor="none" if hollow else colour,
        )
        if bad:
            top = max(r.errors["efdmt"] for r in records) * 30.0
            ax.plot(bad, [top] * len(bad), "x", color=colour, markersize=9, mew=2)
            ax.annotate(
                f"{ERROR_LABELS[method]}: nan/inf",
                (bad[0], top),
                textcoords="offset points",
                xytext=(-60, -14),
                fontsize=7,
                color=colour,
            )
    draw_paper_lines(ax)
    ax.set_title(f"a = {A_MAIN:g}, every method", fontsize=10)
    ax.legend(fontsize=7, loc="center right", bbox_to_anchor=(1.0, 0.3))


def draw_stiffness_panel(ax: Axes, records: Sequence[ErrorRecord], floor: float) -> None:
    """EFDMT (paper M) and DMMAT at every stiffness."""
    styles = ("^:", "o-", "s--", "D-.")
    for method in ("efdmt", "dmmat"):
        for a, style in zip(sorted({r.a for r in records}), styles, strict=False):
            xs, ys, _ = error_points(records, method, a, floor)
            label = f"{ERROR_LABELS[method]}, a = {a:g}"
            ax.plot(xs, ys, style, color=ERROR_COLOURS[method], label=label, markersize=3)
    draw_paper_lines(ax)
    ax.set_title("the truncated methods at every a", fontsize=10)
    ax.legend(fontsize=7, loc="lower right")


def plot_errors(records: Sequence[ErrorRecord], path: Path, floor: float = 1e-14) -> None:
    """Fig. 2: error against DMMA (percent, log scale) against N."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (left, right) = plt.subplots(1, 2, figsize=(12, 5), layout="constrained", sharey=True)
    draw_main_panel(left, records, floor)
    draw_stiffness_panel(right, records, floor)
    sizes = sorted({r.n for r in records})
    for ax in (left, right):
        ax.set(xscale="log", yscale="log", xlabel="nodes N")
        ax.set_xticks(sizes, [str(n) for n in sizes])
        ax.minorticks_off()
        ax.grid(True, which="both", alpha=0.3)
    left.set_ylabel("error against DMMA, eq. 23 (%)")
    fig.suptitle("Error against DMMA, closed chain (cf. paper fig. 2)")
    fig.savefig(path, dpi=120)
    plt.close(fig)


def jsonable(value: Any) -> Any:
    """Replace non-finite floats by None and tuples by lists, recursively."""
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, dict):
        return {str(k): jsonable(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [jsonable(v) for v in value]
    return value


def to_json(results: Results) -> dict[str, Any]:
    """Raw numbers of the run (non-finite errors as null)."""
    raw = asdict(results)
    raw["config"]["limits"] = dict(results.config.limits)
    for goal, record in zip(raw["goals"], results.goals, strict=True):
        goal["speedup"] = record.speedup
        goal["passed"] = record.passed
    raw["imports"]["median"] = results.imports.median
    raw["imports"]["server_free"] = results.imports.server_free
    raw["paper_error_pct"] = PAPER_ERROR_PCT
    raw["units"] = {"time": "seconds per deformation", "error": "percent (eq. 23)"}
    converted: dict[str, Any] = jsonable(raw)
    return converted


def write_outputs(results: Results, out: Path) -> str:
    """Write the report, the JSON and both plots into ``out``; return the report."""
    out.mkdir(parents=True, exist_ok=True)
    report = render(results)
    (out / "solvers.md").write_text(report, encoding="utf-8")
    (out / "solvers.json").write_text(
        json.dumps(to_json(results), indent=1, allow_nan=False) + "\n", encoding="utf-8"
    )
    plot_timings(results.timings, out / "solvers.png")
    plot_errors(results.errors, out / "solvers_error.png")
    return report


# --------------------------------------------------------------------------- main


def run(config: Config) -> Results:
    """Run every study of ``config``."""
    start = time.perf_counter()
    in_process = time_first_exact_call()
    log(f"first exact call in this process: {fmt_seconds(in_process)}")
    imports = import_study(config)
    first_call = first_call_study(in_process)
    errors = error_study(config)
    literal = literal_study()
    breakdown: dict[str, int | None] = {f"{a:g}": literal_breakdown(a) for a in (1.0, 10.0, 100.0)}
    log(f"literal eq. 18 breaks down at {breakdown}")
    goals = goal_study(config)
    timings = timing_study(config)
    return Results(
        config=config,
        machine=machine_info(),
        first_call=first_call,
        errors=errors,
        literal=literal,
        literal_breakdown=breakdown,
        timings=timings,
        goals=goals,
        imports=imports,
        wall_seconds=time.perf_counter() - start,
    )


def parse_args(argv: Sequence[str] | None) -> argparse.Namespace:
    """Command line: ``--quick`` and ``--out DIR``."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0] if __doc__ else None)
    parser.add_argument("--quick", action="store_true", help="reduced sizes for smoke tests")
    parser.add_argument("--out", type=Path, default=DEFAULT_OUT, help="output directory")
    return parser.parse_args(argv)


def main(argv: Sequence[str] | None = None) -> int:
    """Run the benchmark, print the report, write the result files."""
    args = parse_args(argv)
    results = run(QUICK if args.quick else FULL)
    out: Path = args.out
    print(write_outputs(results, out), end="")
    log(f"wrote {out / 'solvers.md'}, solvers.json, solvers.png, solvers_error.png")
    return 0


if __name__ == "__main__":
    sys.exit(main())
