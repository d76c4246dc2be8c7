"""Green's function of the spring chain and the EFDMT neighbourhood.

The equilibrium (I + K) U = F of a chain of N masses (paper eq. 13 with the
unit tie of every node to its rest position) has the explicit solution
U_i = sum_j G(d_ij) F_j (paper eq. 18 closed, eq. 19-20 open).  The paper
writes G with powers mu^N and lambda^N that overflow float64; this module
evaluates the same function divided through by mu^N, in terms of
r = lambda / mu in (0, 1), which is exact for every N and a.

Notation (paper section III): s = sqrt(1 + 4a), mu = (s + 1) / 2,
lambda = (s - 1) / 2, so that mu * lambda = a and mu - lambda = 1.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

__all__ = [
    "ChainConstants",
    "green_kernel",
    "literal_kernel",
    "paper_radius",
    "tolerance_radius",
]


@dataclass(frozen=True, slots=True)
class ChainConstants:
    """Constants of a chain with characteristic value ``a = k/m``.

    Attributes
    ----------
    a : float
        Stiffness over mass, ``a = k/m`` (paper section II).
    s : float
        ``sqrt(1 + 4a)``.
    mu, lam : float
        The paper's mu = (s + 1)/2 and lambda = (s - 1)/2 (eq. 18).
    r : float
        ``lambda / mu`` in (0, 1): the decay of the Green's function per node.
    log_r : float
        ``ln r``, computed without cancellation (``log1p(-2/(s+1))``).
    """

    a: float
    s: float
    mu: float
    lam: float
    r: float
    log_r: float

    @classmethod
    def of(cls, a: float) -> ChainConstants:
        """Constants for stiffness ``a`` (> 0, finite; not re-validated here)."""
        s = math.sqrt(1.0 + 4.0 * a)
        mu = 0.5 * (s + 1.0)
        lam = 2.0 * a / (s + 1.0)  # = (s - 1)/2 without cancellation for small a
        r = lam / mu
        # r = 1 - 2/(s+1): log1p keeps ln r exact when r is close to 1; for
        # small r (tiny a) take the logarithm directly
        log_r = math.log1p(-2.0 / (s + 1.0)) if r > 0.5 else math.log(r)
        return cls(a=a, s=s, mu=mu, lam=lam, r=r, log_r=log_r)

    def power(self, n: float) -> float:
        """``r**n`` evaluated as ``exp(n ln r)`` (underflows cleanly to 0)."""
        return math.exp(n * self.log_r)

    def one_minus_power(self, n: float) -> float:
        """``1 - r**n`` without cancellation when r is close to 1."""
        return -math.expm1(n * self.log_r)


def green_kernel(n: int, a: float, *, period: int | None = None) -> NDArray[np.float64]:
    """Periodic Green's function G(d), d = 0 ... n-1, in the stable form.

    For a closed chain of P nodes (paper eq. 18, divided through by mu^P):

        G(d) = (r^d + r^(P-d)) / (s (1 - r^P))

    Parameters
    ----------
    n : int
        How many distances to return (d = 0 ... n-1).
    a : float
        Stiffness ``a = k/m`` (> 0).
    period : int, optional
        Ring size P; defaults to ``n``.  The open chain of N nodes uses the
        ring of P = 2N nodes (method of images, paper eq. 19-20).

    Returns
    -------
    numpy.ndarray
        Shape (n,), float64, positive; over one full period the weights sum
        to 1 (a uniform force moves the whole chain rigidly).
    """
    c = ChainConstants.of(a)
    p = n if period is None else period
    d = np.arange(n, dtype=np.float64)
    near = np.exp(d * c.log_r)
    far = np.exp((p - d) * c.log_r)
    result: NDArray[np.float64] = (near + far) / (c.s * c.one_minus_power(p))
    return result


def literal_kernel(n: int, a: float) -> NDArray[np.float64]:
    """The paper's eq. 18 weights exactly as printed, for demonstration only.

    ``a^d (mu^(N-2d) + lambda^(N-2d)) / (sqrt(1+4a) (mu^N - lambda^N))`` with
    d = min(|i-j|, N-|i-j|).  Mathematically equal to :func:`green_kernel`
    and accurate to about 1e-14 while s mu^N fits in float64, but once
    N ln(mu) exceeds about 709 the denominator overflows: from N = 1474 at
    a = 1, N = 541 at a = 10 and N = 301 at a = 100 every weight is silently
    0 (100 % error), and a few nodes later inf or nan.  Never used by the
    solvers; kept so tests and benchmarks can show the failure the stable
    form fixes.

    Parameters
    ----------
    n : int
        Number of nodes N of the closed chain.
    a : float
        Stiffness ``a = k/m``.

    Returns
    -------
    numpy.ndarray
        Shape (n,), the weights for d = min(k, n-k), k = 0 ... n-1; may hold
        inf or nan where the literal formula overflows.
    """
    c = ChainConstants.of(a)
    k = np.arange(n, dtype=np.float64)
    d = np.minimum(k, n - k)
    with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
        num = np.power(a, d) * (np.power(c.mu, n - 2 * d) + np.power(c.lam, n - 2 * d))
        den = c.s * (np.power(c.mu, float(n)) - np.power(c.lam, float(n)))
        result: NDArray[np.float64] = num / den
    return result


def paper_radius(n: int, a: float) -> int:
    """The paper's EFDMT neighbourhood M = ceil(mu ln N) (section III, fig. 1).

    Parameters
    ----------
    n : int
        Number of nodes N.
    a : float
        Stiffness ``a = k/m``.

    Returns
    -------
    int
        M >= 1.
    """
    mu = ChainConstants.of(a).mu
    return max(1, math.ceil(mu * math.log(n)))


def tolerance_radius(a: float, tol: float) -> int:
    """Smallest M whose EFDMT error is guaranteed at most ``tol * max|F|``.

    Dropping every node farther than M (on the ring, or on the mirrored ring
    of an open chain) drops weights of the infinite chain's Green's function
    r^|m| / s with |m| > M, whose sum is r^(M+1) (s + 1) / s.  The returned M
    is the smallest one for which that bound is <= tol.

    Parameters
    ----------
    a : float
        Stiffness ``a = k/m`` (> 0).
    tol : float
        Tolerance relative to the largest force magnitude (> 0).

    Returns
    -------
    int
        M >= 0.
    """
    c = ChainConstants.of(a)
    target = math.log(tol * c.s / (c.s + 1.0))
    if target >= 0.0:  # tol so loose that only the node itself is needed
        return 0
    if c.log_r == -math.inf:
        return 0
    # r^(M+1) <= tol s/(s+1)  <=>  (M + 1) ln r <= target
    m = max(0, math.ceil(target / c.log_r - 1.0))
    while (m + 1) * c.log_r > target:  # guard against rounding, either way
        m += 1
    while m > 0 and m * c.log_r <= target:
        m -= 1
    return m
