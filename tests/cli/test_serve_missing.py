"""``efdm serve`` without the ``[service]`` extra: a clear message and exit code 3."""

from __future__ import annotations

import subprocess
import sys

from efdm_cli import EXIT_MISSING

# the web stack made unimportable, as in an environment with the engine alone
WITHOUT_SERVICE = (
    "import sys\n"
    "for name in ('uvicorn', 'fastapi', 'starlette'):\n"
    "    sys.modules[name] = None\n"
    "from efdm_cli import main\n"
    "raise SystemExit(main(['serve', '--port', '1']))\n"
)


def test_serve_without_the_service_installed_says_how_to_install_it() -> None:
    done = subprocess.run(
        [sys.executable, "-c", WITHOUT_SERVICE], capture_output=True, text=True, timeout=60
    )
    assert done.returncode == EXIT_MISSING == 3
    assert "efdm serve: error: the service is not installed" in done.stderr
    assert "pip install 'efdm-tracker[service]'" in done.stderr
    assert "Traceback" not in done.stderr


def test_track_and_deform_need_no_web_stack() -> None:
    code = WITHOUT_SERVICE.replace(
        "raise SystemExit(main(['serve', '--port', '1']))",
        "raise SystemExit(main(['deform', '-', '--stiffness', '2']))",
    )
    done = subprocess.run(
        [sys.executable, "-c", code],
        input='{"forces": [[1, 0], [0, 0], [0, 0]]}',
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert done.returncode == 0, done.stderr
    assert '"displacements"' in done.stdout
