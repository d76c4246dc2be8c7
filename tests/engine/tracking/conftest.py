"""Fixtures of the tracker tests: the moving-disc scene and its frames."""

from __future__ import annotations

import numpy as np
import pytest
from numpy.typing import NDArray

from tests.engine.scenes import DiscScene
from tests.engine.tracking.moving_disc import H, R, T, W, centre


@pytest.fixture(scope="module")
def scene() -> DiscScene:
    return DiscScene(W, H, R, seed=11)


@pytest.fixture(scope="module")
def frames(scene: DiscScene) -> list[NDArray[np.uint8]]:
    return [scene.frame(centre(i)) for i in range(T)]
