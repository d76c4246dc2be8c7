"""Exact equilibrium in O(N): the Green's function as two recursions.

Beyond the paper.  The stable closed-chain Green's function (paper eq. 18)

    G(d) = (r^d + r^(N-d)) / (s (1 - r^N))

is the periodic sum of r^|m| / s, so U = G * F splits into a causal and an
anti-causal first-order recursion (docs/math.md, "Exact linear-time solver"):

    c_i = F_i + r c_(i-1),    b_i = F_i + r b_(i+1),    U_i = (c_i + b_i - F_i) / s

with the periodic start values c_(-1) = sum_m r^m F_(N-1-m) / (1 - r^N) and
b_N = sum_m r^m F_m / (1 - r^N).  The open chain (eq. 19-20) runs the same
recursions on the mirrored sequence of 2N nodes, which only changes the
start values.  About four flops per node and coordinate, exact to rounding.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable
from typing import Any

import numpy as np
from numpy.typing import NDArray

from engine.physics._validation import raise_non_finite
from engine.physics.green import ChainConstants

__all__ = ["kernel_arguments", "solve_exact", "warm_up"]

# Terms of the start-value sums are dropped once their total weight is below
# this fraction of the largest one: far below float64 rounding.
_DROP = 2.0**-64


@functools.cache
def _kernel() -> Callable[..., bool]:
    from engine.physics._kernels import solve_chain

    kernel: Callable[..., bool] = solve_chain
    return kernel


def head_terms(c: ChainConstants, n: int) -> int:
    """How many forces at each end enter the start values exactly to rounding."""
    if c.log_r == -math.inf:
        return 1
    # r^L / (1 - r) <= _DROP  <=>  L >= ln(_DROP (1 - r)) / ln r, with 1 - r = 2/(s+1)
    needed = math.log(_DROP * 2.0 / (c.s + 1.0)) / c.log_r
    return int(min(n, max(1.0, math.ceil(needed) + 1)))


def kernel_arguments(a: float, n: int, closed: bool) -> tuple[float, float, float, float, int]:
    """The solver kernel's constants ``(r, 1/s, r^N, 1/(1 - r^period), head)`` for N nodes."""
    c = ChainConstants.of(a)
    period = n if closed else 2 * n
    return c.r, 1.0 / c.s, c.power(n), 1.0 / c.one_minus_power(period), head_terms(c, n)


def solve_exact(forces: NDArray[np.float64], a: float, closed: bool) -> NDArray[np.float64]:
    """Solve (I + K) U = F exactly in O(N) time and memory.

    Parameters
    ----------
    forces : numpy.ndarray
        Shape (B, N, 2), C-contiguous float64, ``[x, y]`` columns.
    a : float
        Stiffness ``a = k/m`` (> 0).
    closed : bool
        Ring or open line with free ends.

    Returns
    -------
    numpy.ndarray
        Displacements U, shape (B, N, 2).

    Raises
    ------
    ValueError
        If a force is not finite or the displacement overflows float64.
    """
    r, inv_s, r_n, inv_den, head = kernel_arguments(a, forces.shape[1], closed)
    out = np.empty_like(forces)
    ok = _kernel()(forces, r, inv_s, closed, r_n, inv_den, head, out)
    if not ok:
        raise_non_finite(forces)
        raise ValueError("forces are too large: the displacements overflow float64")
    return out


def warm_up() -> None:
    """Compile (or load from the on-disk cache) the exact solver's kernel.

    :func:`engine.warm_up` warms every compiled kernel of the engine.
    """
    dummy: Any = np.zeros((1, 3, 2))
    solve_exact(dummy, 1.0, True)
    solve_exact(dummy, 1.0, False)
