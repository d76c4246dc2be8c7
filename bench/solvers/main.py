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
import os
import subprocess
import sys
import tempfile
import time
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

import _machine
import engine
from _solvers_config import (
    A_MAIN,
    EFDMT_TOL,
    FULL,
    GOALS,
    LITERAL_CASES,
    LITERAL_N_MAX,
    LITERAL_STIFFNESSES,
    QUICK,
    TIMED_METHODS,
    Config,
)
from _solvers_plots import plot_errors, plot_timings
from _solvers_problem import Array, fft_solve, literal_solve, make_forces, percent_error, solver
from _solvers_report import fmt_pct, fmt_seconds, render
from _solvers_results import (
    ErrorRecord,
    FirstCall,
    GoalResult,
    ImportResult,
    LiteralRecord,
    Results,
    TimingRecord,
    to_json,
)
from _timing import measure, measure_side_by_side, sample

REPO = Path(__file__).resolve().parent.parent
DEFAULT_OUT = REPO / "bench" / "results"
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


def log(message: str) -> None:
    """Progress line on stderr."""
    print(f"[bench/solvers] {message}", file=sys.stderr, flush=True)


# --------------------------------------------------------------------------- timings


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


def literal_breakdown(a: float, n_max: int = LITERAL_N_MAX, rtol: float = 1e-6) -> int | None:
    """Smallest N whose printed eq. 18 weights are non-finite or off by more than ``rtol``."""
    for n in range(3, n_max + 1):
        stable = engine.green_kernel(n, a)
        literal = engine.literal_kernel(n, a)
        with np.errstate(invalid="ignore"):
            bad = ~(np.abs(literal - stable) <= rtol * stable)
        if bad.any():
            return n
    return None


# --------------------------------------------------------------------------- machine and files


def machine_info() -> dict[str, str]:
    """Platform, CPU and library versions, and the date."""
    affinity = getattr(os, "sched_getaffinity", None)
    usable = str(len(affinity(0))) if affinity is not None else "?"
    return _machine.machine_info(("scipy", "numba"), usable_cpus=usable)


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
    breakdown: dict[str, int | None] = {f"{a:g}": literal_breakdown(a) for a in LITERAL_STIFFNESSES}
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
