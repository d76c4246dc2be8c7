"""Timing helpers: warm-up, calibrated repeats, medians, calls measured in alternation."""

from __future__ import annotations

import math
import statistics
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Protocol

Call = Callable[[], object]
"""A zero-argument call to time."""


class Budget(Protocol):
    """How hard to time a call (a benchmark's configuration, e.g. ``Config``)."""

    @property
    def budget(self) -> float:
        """Seconds of timed calls aimed at per measurement."""

    @property
    def min_repeats(self) -> int:
        """Fewest timed repeats."""

    @property
    def max_repeats(self) -> int:
        """Most timed repeats."""


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


def measure(fn: Call, config: Budget) -> Timing:
    """Time ``fn``: a warm-up call, then the median of repeats within the budget."""
    first, estimate, number = calibrate(fn, min_block=2e-3)
    wanted = int(config.budget / max(estimate * number, 1e-9))
    repeats = min(config.max_repeats, max(config.min_repeats, wanted))
    samples = [estimate] if number == 1 else []
    samples += [sample(fn, number) for _ in range(repeats - len(samples))]
    return summarise(first, number, samples)


def measure_side_by_side(fns: Sequence[Call], config: Budget) -> list[Timing]:
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
