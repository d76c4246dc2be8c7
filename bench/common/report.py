"""What every report is made of: numbers, markdown tables, the header and the goal lines."""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

from bench.common.output import finite


def fmt(value: float, spec: str) -> str:
    """A number for the tables (``-`` when not measured)."""
    return format(value, spec) if math.isfinite(value) else "-"


def plural(count: int, noun: str) -> str:
    """``1 client``, ``8 clients``."""
    return f"{count} {noun}" if count == 1 else f"{count} {noun}s"


def md_table(headers: Sequence[str], rows: Sequence[Sequence[str]]) -> str:
    """A markdown table."""
    lines = ["| " + " | ".join(headers) + " |", "|" + "|".join("---" for _ in headers) + "|"]
    lines += ["| " + " | ".join(row) + " |" for row in rows]
    return "\n".join(lines)


def header(title: str, machine: Mapping[str, str], cpus: str, *lines: str) -> list[str]:
    """The top of a report: title, date, machine (``cpus`` says how many and how shared), more."""
    return [
        f"# {title}",
        "",
        f"- date: {machine['date']}",
        f"- machine: {machine['platform']}; CPU {machine['cpu']}; {cpus}",
        *lines,
    ]


def load_line(machine: Mapping[str, str], note: str = "") -> str:
    """The header line of the load averages before and after the run."""
    return (
        f"- load average (1, 5, 15 min) before: {machine.get('load_before', '?')}; after: "
        f"{machine.get('load_after', '?')}{note}"
    )


def verdict(passed: bool | None) -> str:
    """``PASS``, ``FAIL`` or (None) ``NOT RUN``."""
    if passed is None:
        return "NOT RUN"
    return "PASS" if passed else "FAIL"


@dataclass(frozen=True, slots=True)
class GoalLine:
    """One goal: what was measured against what was wanted.

    Attributes
    ----------
    goal : str
        What the goal is about.
    measured : float
        The number compared with the target (NaN: not measured).
    shown : str
        How the report shows it.
    target : str
        The target, as the report shows it.
    passed : bool or None
        Whether it was reached (None: not run).
    """

    goal: str
    measured: float
    shown: str
    target: str
    passed: bool | None

    @classmethod
    def at_least(
        cls, goal: str, measured: float, shown: str, threshold: float, target: str
    ) -> GoalLine:
        """A goal reached when ``measured >= threshold`` (not run: ``measured`` not finite)."""
        passed = None if not math.isfinite(measured) else bool(measured >= threshold)
        return cls(goal, measured, shown, target, passed)

    @classmethod
    def at_most(
        cls, goal: str, measured: float, shown: str, threshold: float, target: str
    ) -> GoalLine:
        """A goal reached when ``measured <= threshold`` (not run: ``measured`` not finite)."""
        passed = None if not math.isfinite(measured) else bool(measured <= threshold)
        return cls(goal, measured, shown, target, passed)

    @property
    def verdict(self) -> str:
        """``PASS``, ``FAIL`` or ``NOT RUN``."""
        return verdict(self.passed)


def goals_table(lines: Sequence[GoalLine]) -> str:
    """The report's goals table."""
    rows = [[g.goal, g.shown, g.target, g.verdict] for g in lines]
    return md_table(["goal", "measured", "target", "result"], rows)


def goals_json(lines: Sequence[GoalLine]) -> list[dict[str, Any]]:
    """The goals for the results JSON."""
    return [
        {"goal": g.goal, "measured": finite(g.measured), "target": g.target, "result": g.verdict}
        for g in lines
    ]
