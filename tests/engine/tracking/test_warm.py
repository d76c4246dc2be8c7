"""engine.warm_up: after it, tracking compiles nothing (the service's first frame is fast)."""

from __future__ import annotations

import json
import subprocess
import sys

import pytest

# in a fresh interpreter: which compiled kernels gain a signature while tracking after warm_up
_PROBE = """
import json, sys
import numpy as np
import engine
from numba.core.registry import CPUDispatcher

def signatures():
    found = {}
    for module in list(sys.modules.values()):
        if getattr(module, "__name__", "").startswith("engine"):
            for name, value in vars(module).items():
                if isinstance(value, CPUDispatcher):
                    found[module.__name__ + "." + name] = [str(s) for s in value.signatures]
    return found

engine.warm_up()
from engine.geometry import mask_to_contour
from engine.testing.synthetic import make_sequence
from engine.tracking import ObjectsTracker, Tracker

before = signatures()
scene = make_sequence(sys.argv[1], seed=0, length=4)
start = mask_to_contour(scene.masks[0], 64)
# frames as a decoder gives them: writable, colour and grey
for frames in ([f.copy() for f in scene.frames], [f[..., 1].copy() for f in scene.frames]):
    for tracker in (Tracker(start), ObjectsTracker({0: start})):
        for frame in frames:
            tracker.step(frame)
after = signatures()
print(json.dumps({k: v for k, v in after.items() if len(v) > len(before.get(k, []))}))
"""


@pytest.mark.parametrize("condition", ["plain", "occluder"])
def test_tracking_after_warm_up_compiles_no_kernel(condition: str) -> None:
    done = subprocess.run(
        [sys.executable, "-c", _PROBE, condition],
        capture_output=True,
        text=True,
        timeout=600,
        check=True,
    )
    compiled = json.loads(done.stdout.strip().splitlines()[-1])
    assert compiled == {}, f"compiled while tracking, after warm_up: {compiled}"
