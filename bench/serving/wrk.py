"""``/forces`` load from ``wrk`` (a C load generator), when it is installed.

The Python clients spend CPU on the same two cores as the server; ``wrk``
spends far less per request, so it shows what the server can do.  A Lua
script POSTs the JSON body round-robin over one session per connection.
Absent ``wrk``, the row is skipped with a note.
"""

from __future__ import annotations

import re
import resource
import shutil
import subprocess
import tempfile
from pathlib import Path

from bench.common.processes import cpu_seconds
from bench.serving.rest import ForcesLoad
from bench.serving.server import Server, forces_paths
from bench.serving.stats import Measurement

SCRIPT = """
local body = [==[{body}]==]
local paths = {{}}
local n = 0
function init(args)
  for i, p in ipairs(args) do paths[i] = p end
end
function request()
  n = n + 1
  local headers = {{["Content-Type"] = "application/json"}}
  return wrk.format("POST", paths[(n % #paths) + 1], headers, body)
end
"""
UNITS = {"us": 1e-3, "ms": 1.0, "s": 1e3}
LATENCY = re.compile(r"^\s*(50|75|90|99)%\s+([\d.]+)(us|ms|s)\s*$", re.MULTILINE)
REQUESTS = re.compile(r"^\s*(\d+) requests in ([\d.]+)(us|ms|s)", re.MULTILINE)
ERRORS = re.compile(r"Non-2xx or 3xx responses: (\d+)|Socket errors: (.*)$", re.MULTILINE)


def available() -> str | None:
    """The path of ``wrk``, or None."""
    return shutil.which("wrk")


def _parse(output: str, row: Measurement) -> None:
    found = REQUESTS.search(output)
    if found is None:
        raise ValueError(f"unexpected wrk output: {output[-400:]!r}")
    row.sent = int(found.group(1))
    row.seconds = float(found.group(2)) * UNITS[found.group(3)] / 1e3
    row.reported_ms = {int(q): float(v) * UNITS[unit] for q, v, unit in LATENCY.findall(output)}
    row.note = "wrk's latency percentiles: " + ", ".join(
        f"p{q} {v:.2f} ms" for q, v in sorted(row.reported_ms.items())
    )
    row.errors = 0
    for match in ERRORS.finditer(output):
        if match.group(1):
            row.errors += int(match.group(1))
        elif match.group(2):
            numbers = [int(n) for n in re.findall(r"\d+", match.group(2))]
            row.errors += sum(numbers)
    row.items = row.sent - row.errors


def _children_cpu() -> float:
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


def wrk_forces(server: Server, load: ForcesLoad, nodes: int, name: str) -> Measurement:
    """Run ``wrk`` for ``load.seconds`` with ``load.clients`` connections (one thread).

    Raises
    ------
    RuntimeError
        If ``wrk`` fails.
    """
    binary = available()
    row = Measurement(name, "requests", clients=load.clients)
    if binary is None:
        row.note = "wrk not installed (apt-get install -y wrk): skipped"
        return row
    paths = forces_paths(server, load.clients, nodes)
    with tempfile.TemporaryDirectory(prefix="efdm-wrk-") as tmp:
        script = Path(tmp) / "forces.lua"
        script.write_text(SCRIPT.format(body=load.body.decode()), encoding="utf-8")
        command = [
            binary, "-t1", f"-c{load.clients}", f"-d{max(1, round(load.seconds))}s",
            "--latency", "--timeout", "10s", "-s", str(script), f"{server.url}/", "--", *paths,
        ]  # fmt: skip
        server_before, children_before = cpu_seconds(server.pid), _children_cpu()
        done = subprocess.run(
            command, capture_output=True, text=True, timeout=load.seconds + 30, check=False
        )
        row.server_cpu = cpu_seconds(server.pid) - server_before
        row.client_cpu = _children_cpu() - children_before
    if done.returncode != 0:
        raise RuntimeError(f"wrk failed ({done.returncode}): {done.stderr.strip()[:300]}")
    _parse(done.stdout, row)
    return row
