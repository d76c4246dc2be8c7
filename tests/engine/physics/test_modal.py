"""engine.physics.modal: DMMA and DMMAT (paper eq. 5-16)."""

from __future__ import annotations

import numpy as np
import pytest

from engine import deform
from engine.physics.modal import kept_modes


@pytest.mark.parametrize("closed", [True, False])
def test_dmmat_is_exact_on_low_frequencies(closed: bool) -> None:
    n = 64
    t = np.arange(n)
    # closed: a ring mode of wave number 3; open: a DCT-II mode of order 3.
    phase = 2 * np.pi * 3 * t / n if closed else np.pi * 3 * (2 * t + 1) / (2 * n)
    forces = np.stack([np.cos(phase), 2.0 * np.cos(phase)], axis=1)
    np.testing.assert_allclose(
        deform(forces, 5.0, closed=closed, method="dmmat"),
        deform(forces, 5.0, closed=closed),
        atol=1e-12,
    )


@pytest.mark.parametrize("closed", [True, False])
def test_dmmat_drops_high_frequencies(closed: bool) -> None:
    n = 64
    t = np.arange(n)
    # the highest mode: alternating signs on a ring, the last DCT-II mode on a line
    phase = np.pi * t if closed else np.pi * (n - 1) * (2 * t + 1) / (2 * n)
    forces = np.stack([np.cos(phase), -np.cos(phase)], axis=1)
    U = deform(forces, 5.0, closed=closed, method="dmmat")
    exact = deform(forces, 5.0, closed=closed)
    assert np.abs(exact).max() > 1e-2  # the exact answer is not negligible...
    assert np.abs(U).max() < 1e-3 * np.abs(exact).max()  # ...DMMAT discards it


def test_kept_modes_keeps_a_quarter_without_splitting_pairs() -> None:
    ring = np.sort(4 * np.sin(np.pi * np.arange(8) / 8) ** 2)  # pairs of equal values
    assert kept_modes(ring, 0.25) == 3  # 2 would split the pair {w1, w1}
    line = 4 * np.sin(np.pi * np.arange(8) / 16) ** 2  # distinct values
    assert kept_modes(line, 0.25) == 2
    assert kept_modes(line, 1e-9) == 1
