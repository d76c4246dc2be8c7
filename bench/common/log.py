"""Progress lines on stderr: ``[bench/<family>] message``."""

from __future__ import annotations

import sys

_prefix = "bench"


def set_family(name: str) -> None:
    """Name the running family in every later progress line (the run skeleton does)."""
    global _prefix
    _prefix = f"bench/{name}"


def log(message: str) -> None:
    """One progress line on stderr."""
    print(f"[{_prefix}] {message}", file=sys.stderr, flush=True)
