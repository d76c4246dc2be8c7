"""Writing a benchmark's results: the markdown report and the raw numbers as JSON."""

from __future__ import annotations

import json
import math
from dataclasses import asdict
from pathlib import Path
from typing import Any, Protocol

from bench.common.config import Config


class Run(Protocol):
    """What every family's results carry."""

    @property
    def config(self) -> Config:
        """What was run."""

    @property
    def machine(self) -> dict[str, str]:
        """What it ran on (:func:`bench.common.machine.machine_info`)."""

    @property
    def wall_seconds(self) -> float:
        """How long it took."""


def finite(value: float) -> float | None:
    """A float for JSON (non-finite: None)."""
    return value if math.isfinite(value) else None


def jsonable(value: Any) -> Any:
    """Non-finite floats as None and tuples as lists, recursively."""
    if isinstance(value, float):
        return finite(value)
    if isinstance(value, dict):
        return {str(k): jsonable(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [jsonable(v) for v in value]
    return value


def run_json(results: Run) -> dict[str, Any]:
    """The part of every results JSON that says what ran where: config, machine, wall time."""
    return {
        "config": asdict(results.config),
        "machine": results.machine,
        "wall_seconds": results.wall_seconds,
    }


def write_results(out: Path, stem: str, report: str, data: Any) -> None:
    """``<stem>.md`` (the report) and ``<stem>.json`` (the raw numbers) into ``out``."""
    out.mkdir(parents=True, exist_ok=True)
    (out / f"{stem}.md").write_text(report, encoding="utf-8")
    text = json.dumps(data, indent=1, allow_nan=False)
    (out / f"{stem}.json").write_text(text + "\n", encoding="utf-8")
