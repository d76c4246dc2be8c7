"""``import engine`` stays light: no web stack, no compiler, no OpenCV."""

from __future__ import annotations

import json
import subprocess
import sys


def test_engine_import_loads_no_heavy_or_web_modules() -> None:
    code = (
        "import json, sys, engine; "
        "print(json.dumps(sorted(m for m in ('fastapi', 'uvicorn', 'starlette', 'numba', "
        "'scipy', 'cv2') if m in sys.modules)))"
    )
    out = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, check=True
    ).stdout
    assert json.loads(out) == []
