"""Writing a benchmark's results, and its standard command line."""

from __future__ import annotations

import argparse
import json
from collections.abc import Sequence
from pathlib import Path
from typing import Any


def write_results(out: Path, stem: str, report: str, data: Any) -> None:
    """``<stem>.md`` (the report) and ``<stem>.json`` (the raw numbers) into ``out``."""
    out.mkdir(parents=True, exist_ok=True)
    (out / f"{stem}.md").write_text(report, encoding="utf-8")
    text = json.dumps(data, indent=1, allow_nan=False)
    (out / f"{stem}.json").write_text(text + "\n", encoding="utf-8")


def quick_and_out(
    doc: str | None, default_out: Path, argv: Sequence[str] | None
) -> argparse.Namespace:
    """Parse ``--quick`` (tiny counts for smoke tests) and ``--out DIR``."""
    parser = argparse.ArgumentParser(description=doc.splitlines()[0] if doc else None)
    parser.add_argument("--quick", action="store_true", help="tiny counts for smoke tests")
    parser.add_argument("--out", type=Path, default=default_out, help="output directory")
    return parser.parse_args(argv)
