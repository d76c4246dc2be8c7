"""The solver benchmark's markdown report."""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from bench.common.report import header, md_table, verdict
from bench.common.timing import Timing
from bench.solvers.config import (
    ERROR_LABELS,
    ERROR_METHODS,
    IMPORT_GOAL_SECONDS,
    LITERAL_N_MAX,
    PAPER_ERROR_PCT,
    TIMED_METHODS,
)
from bench.solvers.problem import NOISE
from bench.solvers.results import ErrorRecord, Results, TimingRecord

EFDMT_NOTE = (
    "Reading the table: EFDM, exact, FFT (and the literal formula while it is finite) differ "
    "from DMMA only by DMMA's own rounding. The paper's M = ceil(mu ln N) drops weights "
    "summing to about 2 r^(M+1) / (s (1 - r)) with r^M = N^(mu ln r) (N^-1.17 at a = 10), "
    "hence EFDMT errors of order 1e-3 to 1 %, far above the paper's 3.14e-6 %; when "
    "2M + 1 >= N nothing is truncated and EFDMT is exact. DMMAT's error depends only on how "
    "much of the force spectrum lies above the kept 25 % of the modes (here: the noise)."
)


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
        f"a = {a}: N = {n}" if n is not None else f"a = {a}: none up to {LITERAL_N_MAX}"
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


def timings_by_point(
    records: Sequence[TimingRecord], closed: bool
) -> dict[tuple[str, int], Timing]:
    """The timings of the closed or the open chain, by (method, N)."""
    return {(r.method, r.n): r.timing for r in records if r.closed == closed}


def timing_table(records: Sequence[TimingRecord], closed: bool, methods: Sequence[str]) -> str:
    """Median seconds per deformation, one row per N."""
    table = timings_by_point(records, closed)
    sizes = sorted({n for _, n in table})
    rows = [
        [f"{n:,}", *(fmt_seconds(table[m, n].median) if (m, n) in table else "-" for m in methods)]
        for n in sizes
    ]
    return md_table(["N", *methods], rows)


def timing_section(results: Results) -> str:
    """Markdown for fig. 4, the open chain and the first calls."""
    first = results.first_call
    efdmt_20k = timings_by_point(results.timings, closed=True).get(("efdmt", 20_000))
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
            verdict(g.passed),
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
            verdict(imports.median < IMPORT_GOAL_SECONDS),
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
            verdict(imports.server_free),
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
    m = results.machine
    top = header(
        "Solver benchmark (Krinidis & Pitas, section IV)",
        m,
        f"{m['cpu_count']} CPUs ({m['usable_cpus']} usable)",
        f"- python {m['python']}, numpy {m['numpy']}, scipy {m['scipy']}, numba {m['numba']}",
        f"- run: `{results.config.name}`, {results.wall_seconds:.0f} s wall time",
    )
    sections = [
        "\n".join(top),
        goals_section(results),
        error_section(results),
        timing_section(results),
    ]
    return "\n\n".join(sections) + "\n"
