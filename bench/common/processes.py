"""Processes a benchmark starts: free ports, stopping, log tails, CPU time, fresh interpreters."""

from __future__ import annotations

import json
import os
import socket
import subprocess
import sys
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from bench.common import REPO

HOST = "127.0.0.1"
"""Everything a benchmark starts listens on loopback only."""
STOP_TIMEOUT = 10.0
"""Seconds a process gets to exit after SIGTERM (then SIGKILL), and again after SIGKILL."""


def free_port() -> int:
    """A free TCP port on :data:`HOST`."""
    with socket.socket() as s:
        s.bind((HOST, 0))
        port: int = s.getsockname()[1]
        return port


def stop(process: subprocess.Popen[bytes]) -> int | None:
    """SIGTERM (a graceful shutdown), SIGKILL if it lingers; the exit code."""
    if process.poll() is None:
        process.terminate()
        try:
            process.wait(timeout=STOP_TIMEOUT)
        except subprocess.TimeoutExpired:
            process.kill()
            process.wait(timeout=STOP_TIMEOUT)
    return process.returncode


def tail(path: Path, size: int = 2000) -> str:
    """The end of a log file ("" when unreadable), to quote when a process fails."""
    try:
        return path.read_bytes()[-size:].decode(errors="replace")
    except OSError:
        return ""


def cpu_seconds(pid: int) -> float:
    """User + system CPU seconds of a process, all threads (NaN where unknown)."""
    try:
        fields = Path(f"/proc/{pid}/stat").read_text(encoding="ascii").rsplit(")", 1)[1].split()
        ticks = os.sysconf("SC_CLK_TCK")
    except (OSError, ValueError, IndexError):
        return float("nan")
    return (int(fields[11]) + int(fields[12])) / ticks


def run_python(code: str, env: Mapping[str, str] | None = None) -> dict[str, Any]:
    """Run ``code`` in a fresh interpreter in the repository; parse its last line as JSON."""
    done = subprocess.run(
        [sys.executable, "-c", code],
        cwd=REPO,
        env=None if env is None else dict(env),
        capture_output=True,
        text=True,
        check=True,
    )
    parsed: dict[str, Any] = json.loads(done.stdout.strip().splitlines()[-1])
    return parsed
