"""Reference solutions for the solver tests: a dense ``numpy.linalg.solve``."""

from __future__ import annotations

import functools

import numpy as np
from numpy.typing import NDArray

from engine import system_matrix

SIZES_CLOSED = (3, 4, 5, 17, 101, 1000, 2000)
SIZES_OPEN = (2, *SIZES_CLOSED)
STIFFNESSES = (1e-3, 1.0, 10.0, 100.0, 1e4)
GRID = [
    (n, a, closed)
    for closed in (True, False)
    for n in (SIZES_CLOSED if closed else SIZES_OPEN)
    for a in STIFFNESSES
]


def grid_id(case: tuple[int, float, bool]) -> str:
    n, a, closed = case
    return f"{'closed' if closed else 'open'}-N{n}-a{a:g}"


def forces_for(n: int, seed: int = 0) -> NDArray[np.float64]:
    """Seeded forces with a smooth part and a rough part, ``[x, y]`` columns."""
    rng = np.random.default_rng(seed + 7919 * n)
    t = np.linspace(0.0, 2.0 * np.pi, n, endpoint=False)[:, None]
    smooth = 5.0 * np.hstack([np.cos(t), np.sin(2 * t)])
    return np.asarray(smooth + rng.standard_normal((n, 2)), dtype=np.float64)


def dense_solve(forces: NDArray[np.float64], a: float, closed: bool) -> NDArray[np.float64]:
    """U = (I + K)^-1 F by LU factorisation of the dense matrix."""
    matrix = system_matrix(forces.shape[0], a, closed=closed)
    return np.asarray(np.linalg.solve(matrix, forces), dtype=np.float64)


@functools.cache
def reference(n: int, a: float, closed: bool) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Seeded forces and their dense solution (cached across tests)."""
    forces = forces_for(n)
    return forces, dense_solve(forces, a, closed)


def relative_error(u: NDArray[np.float64], ref: NDArray[np.float64]) -> float:
    """Largest deviation relative to the largest reference displacement."""
    return float(np.abs(u - ref).max() / np.abs(ref).max())
