"""The benchmark's problem: seeded forces, the baseline solves, and the paper's error measure."""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

import engine
from bench.common.timing import Call

Array = NDArray[np.float64]

SEED = 20240501
NOISE = 0.02
"""Standard deviation of the white noise added to the smooth forces."""


def make_forces(n: int, seed: int = SEED) -> Array:
    """Seeded smooth-ish forces of shape (N, 2) whose displacements stay away from 0.

    A constant pull of magnitude 5 in a random direction, four random Fourier
    modes of orders 1-4 (amplitudes well below the pull) and white noise of
    standard deviation :data:`NOISE`.

    Parameters
    ----------
    n : int
        Number of nodes.
    seed : int
        Seed; combined with ``n`` so every size gets its own forces.

    Returns
    -------
    numpy.ndarray
        Shape (n, 2), ``[x, y]``.
    """
    rng = np.random.default_rng([seed, n])
    angle = rng.uniform(0.0, 2.0 * np.pi)
    forces = np.tile(5.0 * np.array([np.cos(angle), np.sin(angle)]), (n, 1))
    t = 2.0 * np.pi * np.arange(n) / n
    for order in range(1, 5):
        cos_amp, sin_amp = rng.uniform(-1.0, 1.0, size=(2, 2)) * (0.6 / order)
        forces += np.outer(np.cos(order * t), cos_amp) + np.outer(np.sin(order * t), sin_amp)
    noise: Array = NOISE * rng.standard_normal((n, 2))
    return forces + noise


def fft_solve(forces: Array, a: float) -> Array:
    """The closed-chain solve a numpy user would write: divide in Fourier space.

    Parameters
    ----------
    forces : numpy.ndarray
        Shape (N, 2).
    a : float
        Stiffness ``a = k/m``.

    Returns
    -------
    numpy.ndarray
        U = (I + a L)^-1 F, shape (N, 2).
    """
    n = forces.shape[0]
    k = np.arange(n // 2 + 1)
    spectrum = np.fft.rfft(forces, axis=0) / (1.0 + 4.0 * a * np.sin(np.pi * k / n) ** 2)[:, None]
    result: Array = np.fft.irfft(spectrum, n=n, axis=0)
    return result


def literal_solve(forces: Array, a: float) -> Array:
    """U from the paper's eq. 18 weights as printed (:func:`engine.literal_kernel`).

    A dense circulant gather, so the only rounding is the formula's own.

    Parameters
    ----------
    forces : numpy.ndarray
        Shape (N, 2), closed chain.
    a : float
        Stiffness ``a = k/m``.

    Returns
    -------
    numpy.ndarray
        Shape (N, 2); non-finite where the formula overflows.
    """
    n = forces.shape[0]
    weights = engine.literal_kernel(n, a)
    index = np.subtract.outer(np.arange(n), np.arange(n)) % n
    with np.errstate(over="ignore", invalid="ignore"):
        result: Array = weights[index] @ forces
    return result


def solver(method: str, forces: Array, a: float, *, closed: bool = True) -> Call:
    """A zero-argument call that runs ``method`` on ``forces`` (``"fft"``: the baseline)."""
    if method == "fft":
        return lambda: fft_solve(forces, a)
    return lambda: engine.deform(forces, a, closed=closed, method=method)


def percent_error(U: Array, reference: Array) -> float:
    """The paper's eq. 23: mean over nodes of |U_i - U'_i| / |U_i|, in percent.

    Parameters
    ----------
    U : numpy.ndarray
        Approximation, shape (N, 2).
    reference : numpy.ndarray
        DMMA displacements, shape (N, 2); |.| is the Euclidean norm per node.

    Returns
    -------
    float
        The error in percent; nan when ``U`` is not finite.
    """
    if not np.isfinite(U).all():
        return math.nan
    ratio = np.linalg.norm(U - reference, axis=1) / np.linalg.norm(reference, axis=1)
    return float(100.0 * ratio.mean())
