"""What machine a benchmark ran on: shared by every benchmark's report."""

from __future__ import annotations

import os
import platform
from collections.abc import Iterable
from datetime import datetime
from importlib import metadata
from pathlib import Path

import numpy as np


def version(distribution: str) -> str:
    """An installed distribution's version (``?`` when absent)."""
    try:
        return metadata.version(distribution)
    except metadata.PackageNotFoundError:
        return "?"


def load_average() -> str:
    """The 1, 5 and 15 minute load averages (``?`` where unsupported)."""
    try:
        return ", ".join(f"{v:.2f}" for v in os.getloadavg())
    except OSError:
        return "?"


def cpu_model() -> str:
    """The CPU model name from /proc/cpuinfo, else ``platform.processor()``."""
    try:
        text = Path("/proc/cpuinfo").read_text(encoding="utf-8")
    except OSError:
        text = ""
    for line in text.splitlines():
        if line.startswith("model name"):
            return line.split(":", 1)[1].strip()
    return platform.processor() or "?"


def machine_info(libraries: Iterable[str] = (), **extra: str) -> dict[str, str]:
    """The date, platform, CPU, numpy and the named distributions' versions."""
    return {
        "date": datetime.now().astimezone().isoformat(timespec="seconds"),
        "platform": platform.platform(),
        "python": platform.python_version(),
        "cpu": cpu_model(),
        "cpu_count": str(os.cpu_count()),
        "numpy": np.__version__,
        **{name: version(name) for name in libraries},
        **extra,
    }
