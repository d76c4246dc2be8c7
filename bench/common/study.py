"""The command line of a one-off study over the DAVIS sets (``--quick``, ``--out``).

A study (``python -m bench.serving.state``, ``python -m bench.tracking.snap``) runs over
every DAVIS-2016 set there is, on one thread per process, and writes ``<stem>.md`` and
``<stem>.json``; :func:`study_main` is the part they share.
"""

from __future__ import annotations

import argparse
import multiprocessing
import os
import sys
import time
from collections.abc import Callable, Mapping
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path
from typing import Any, TypeVar

from bench.common import RESULTS
from bench.common.data import DAVIS_ROOT, DAVIS_TRAIN_ROOT, davis_names
from bench.common.output import write_results

__all__ = ["davis_sets", "on_two_processes", "single_threaded", "study_main"]

T = TypeVar("T")
THREAD_VARIABLES = (
    "OMP_NUM_THREADS",
    "OPENBLAS_NUM_THREADS",
    "MKL_NUM_THREADS",
    "NUMBA_NUM_THREADS",
)


def single_threaded() -> None:
    """One thread for the numeric libraries of this process and of those it starts."""
    for variable in THREAD_VARIABLES:
        os.environ[variable] = "1"


def on_two_processes(work: Callable[[Any], T], jobs: list[Any]) -> list[T]:
    """``[work(job) for job in jobs]`` on two spawned processes (spawned, not forked: a forked
    child can inherit a lock some thread of the parent held)."""
    context = multiprocessing.get_context("spawn")
    with ProcessPoolExecutor(max_workers=2, mp_context=context) as pool:
        return list(pool.map(work, jobs))


def davis_sets() -> dict[str, Path]:
    """The DAVIS-2016 sets present, by label (``davis-train``, ``davis-val``)."""
    found = (("davis-train", DAVIS_TRAIN_ROOT), ("davis-val", DAVIS_ROOT))
    return {label: root for label, root in found if davis_names(root)}


def study_main(
    argv: list[str] | None,
    doc: str | None,
    stem: str,
    run: Callable[..., dict[str, Any]],
    render: Callable[[dict[str, Any], float], str],
    quick_help: str,
    flags: Mapping[str, str] | None = None,
) -> int:
    """Parse ``--quick``, ``--out`` and the study's own ``flags``, run over the sets, write
    and print the report.

    ``flags`` maps a switch's name (``"grey"`` is ``--grey``) to its help.  ``run`` gets
    the sets and ``--quick``, then each switch as a keyword; each switch given adds
    ``_<name>`` to the files' stem (``confidence_grey.md``).

    Returns 1 (with a message on stderr) when no DAVIS set is there, else 0.
    """
    parser = argparse.ArgumentParser(description=(doc or stem).splitlines()[0])
    parser.add_argument("--quick", action="store_true", help=quick_help)
    parser.add_argument("--out", type=Path, default=RESULTS, help="output directory")
    for name, text in (flags or {}).items():
        parser.add_argument(f"--{name}", action="store_true", help=text)
    args = parser.parse_args(argv)
    switches = {name: bool(getattr(args, name)) for name in flags or {}}
    stem += "".join(f"_{name}" for name, given in switches.items() if given)
    single_threaded()
    sets = davis_sets()
    if not sets:
        print(f"{stem}: no DAVIS data under ../shared/data", file=sys.stderr)
        return 1
    start = time.perf_counter()
    results = run(sets, args.quick, **switches)
    seconds = time.perf_counter() - start
    report = render(results, seconds)
    write_results(args.out, stem, report, {"sets": results, "wall_seconds": seconds})
    print(report)
    return 0
