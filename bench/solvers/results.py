"""What one run of the solver benchmark measured, and its JSON form."""

from __future__ import annotations

import statistics
from dataclasses import asdict, dataclass
from typing import Any

from bench.common.output import jsonable
from bench.common.timing import Timing
from bench.solvers.config import PAPER_ERROR_PCT, Config, Goal


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


def to_json(results: Results) -> dict[str, Any]:
    """Raw numbers of the run (non-finite errors as null)."""
    raw = asdict(results)
    for goal, record in zip(raw["goals"], results.goals, strict=True):
        goal["speedup"] = record.speedup
        goal["passed"] = record.passed
    raw["imports"]["median"] = results.imports.median
    raw["imports"]["server_free"] = results.imports.server_free
    raw["paper_error_pct"] = PAPER_ERROR_PCT
    raw["units"] = {"time": "seconds per deformation", "error": "percent (eq. 23)"}
    converted: dict[str, Any] = jsonable(raw)
    return converted
