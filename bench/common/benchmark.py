"""The run skeleton of every family: parse the command line, run, print and write the results."""

from __future__ import annotations

import argparse
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Generic, TypeVar

from bench.common.config import Config, parse_args
from bench.common.log import log, set_family
from bench.common.output import write_results

C = TypeVar("C", bound=Config)
R = TypeVar("R")


def no_figures(results: Any, out: Path) -> list[str]:
    """For families without pictures."""
    return []


@dataclass(frozen=True, slots=True)
class Benchmark(Generic[C, R]):
    """One family: its configurations, its run and its result files.

    Declared positionally, ``Benchmark(name, doc, full, quick, run, render, to_json)``,
    with the optional parts by keyword.

    Attributes
    ----------
    name : str
        The family (``python -m bench.<name>``; progress lines ``[bench/<name>]``).
    doc : str or None
        The family's docstring (the first line describes the command).
    full, quick : Config
        What a plain and a ``--quick`` run measure.
    run : callable
        ``run(config, args)``: measure everything, return the results.
    render : callable
        The markdown report of the results.
    to_json : callable
        The raw numbers of the results, as JSON data.
    stem : str
        Result files ``<stem>.md`` (the report, also printed) and ``<stem>.json``
        (default: ``name``).
    stem_of : callable, optional
        ``stem_of(results)``: the stem for results of another mode (instead of ``stem``).
    figures : callable
        ``figures(results, out)``: write the pictures into ``out``, return their file names.
    arguments : callable, optional
        Adds the family's own command-line options.
    """

    name: str
    doc: str | None
    full: C
    quick: C
    run: Callable[[C, argparse.Namespace], R]
    render: Callable[[R], str]
    to_json: Callable[[R], Any]
    stem: str = ""
    stem_of: Callable[[R], str] | None = None
    figures: Callable[[R, Path], list[str]] = no_figures
    arguments: Callable[[argparse.ArgumentParser], None] | None = None

    def main(self, argv: Sequence[str] | None = None) -> int:
        """Run the benchmark, print the report, write the result files; the exit code."""
        set_family(self.name)
        args = parse_args(self.doc, argv, self.arguments)
        start = time.perf_counter()
        results = self.run(self.quick if args.quick else self.full, args)
        out: Path = args.out
        report = self.render(results)
        stem = self.stem_of(results) if self.stem_of else self.stem or self.name
        write_results(out, stem, report, self.to_json(results))
        extra = self.figures(results, out)
        print(report, end="")
        written = ", ".join([f"{stem}.json", *extra])
        log(f"wrote {out / f'{stem}.md'}, {written} ({time.perf_counter() - start:.0f} s)")
        return 0
