"""docker/test-container.sh and docker/containers.conf (the script itself runs in
``make test-container``, not here)."""

from __future__ import annotations

import os
import shutil
import subprocess
import tomllib

from tests.deploy._files import CONTAINERS_CONF, ROOT, SCRIPT


def test_script_is_strict_bash_with_a_cleanup_trap() -> None:
    text = SCRIPT.read_text(encoding="utf-8")
    assert text.startswith("#!/usr/bin/env bash\n")
    assert "\nset -euo pipefail\n" in text
    assert "\ntrap cleanup EXIT\n" in text
    assert os.access(SCRIPT, os.X_OK)
    bash = shutil.which("bash")
    assert bash
    result = subprocess.run([bash, "-n", str(SCRIPT)], capture_output=True, text=True, check=False)
    assert result.returncode == 0, result.stderr


def test_makefile_target_runs_the_script() -> None:
    makefile = (ROOT / "Makefile").read_text(encoding="utf-8")
    assert "\ntest-container:" in makefile
    assert "docker/test-container.sh" in makefile


def test_containers_conf_uses_runc_and_explicit_ulimits() -> None:
    conf = tomllib.loads(CONTAINERS_CONF.read_text(encoding="utf-8"))
    assert conf["engine"]["runtime"] == "runc"
    limits = dict(item.split("=", 1) for item in conf["containers"]["default_ulimits"])
    assert limits == {"nofile": "1024:1024", "nproc": "1024:1024"}
