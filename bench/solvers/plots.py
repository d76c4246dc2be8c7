"""The solver benchmark's plots: the paper's fig. 4 (timings) and fig. 2 (errors).

matplotlib is imported on first use, so that it is not loaded while the
benchmark measures.
"""

from __future__ import annotations

import math
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from pathlib import Path
from typing import TYPE_CHECKING, Any

from bench.solvers.config import A_MAIN, ERROR_LABELS, PAPER_ERROR_PCT, TIMED_METHODS
from bench.solvers.results import ErrorRecord, TimingRecord

if TYPE_CHECKING:
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure


@contextmanager
def figure(path: Path, **subplots: Any) -> Iterator[tuple[Figure, Any]]:
    """A figure and its axes (``plt.subplots``, Agg backend); saved into ``path`` and closed."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(layout="constrained", **subplots)
    try:
        yield fig, axes
        fig.savefig(path, dpi=120)
    finally:
        plt.close(fig)


def draw_timings(ax: Axes, records: Sequence[TimingRecord]) -> None:
    """Log-log time per deformation against N, one line per method, and the open chain."""
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


def plot_timings(records: Sequence[TimingRecord], path: Path) -> None:
    """Fig. 4: time per deformation against N."""
    with figure(path, figsize=(8, 5.5)) as (_, ax):
        draw_timings(ax, records)


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
    with figure(path, ncols=2, figsize=(12, 5), sharey=True) as (fig, (left, right)):
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
