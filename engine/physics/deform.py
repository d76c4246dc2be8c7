"""``deform``: equilibrium of a deformable contour under forces (paper eq. 13, 16)."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from numpy.typing import ArrayLike, NDArray

from engine.physics._validation import (
    METHODS,
    as_closed,
    as_forces,
    as_method,
    as_stiffness,
    as_tol,
    raise_non_finite,
)
from engine.physics.efdm import solve_efdm
from engine.physics.efdmt import solve_efdmt
from engine.physics.modal import TRUNCATED_FRACTION, solve_modal
from engine.physics.recursive import solve_exact

__all__ = ["METHODS", "deform"]


def _dense(
    solver: Callable[[NDArray[np.float64], float, bool], NDArray[np.float64]],
    forces: NDArray[np.float64],
    a: float,
    closed: bool,
) -> NDArray[np.float64]:
    """Run a solver of (N, k) columns on (B, N, 2) forces."""
    b, n, _ = forces.shape
    columns = forces.transpose(1, 0, 2).reshape(n, 2 * b)
    return np.ascontiguousarray(solver(columns, a, closed).reshape(n, b, 2).transpose(1, 0, 2))


def _dmmat(columns: NDArray[np.float64], a: float, closed: bool) -> NDArray[np.float64]:
    return solve_modal(columns, a, closed, TRUNCATED_FRACTION)


def _dmma(columns: NDArray[np.float64], a: float, closed: bool) -> NDArray[np.float64]:
    return solve_modal(columns, a, closed)


_DENSE = {"efdm": solve_efdm, "dmma": _dmma, "dmmat": _dmmat}


def deform(
    forces: ArrayLike,
    stiffness: float,
    *,
    closed: bool = True,
    method: str = "exact",
    tol: float | None = None,
) -> NDArray[np.float64]:
    """Displacements of a spring chain in equilibrium under nodal forces.

    Solves (I + K) U = F (paper eq. 13 and 16) with K = a L, L the chain's
    graph Laplacian: each of the N nodes is tied to its rest position by a
    unit spring and to its neighbours by springs of stiffness ``a = k/m``.
    The x and y columns are independent.  The deformed contour is
    ``X0 + U`` (eq. 15); see :class:`engine.Chain`.

    Parameters
    ----------
    forces : array_like
        Shape (N, 2), or (B, N, 2) for B contours of equal N; columns are
        ``[x, y]`` in pixels (x = column, y = row, as in OpenCV).
    stiffness : float
        ``a = k/m`` > 0.  Large: the contour moves like a solid; small: like an
        elastic band.  ``"exact"``, ``"efdm"`` and ``"dmma"`` are exact to rounding
        for a in [1e-6, 1e6] and any N; ``"efdmt"`` and ``"dmmat"`` are truncated
        (``"dmmat"`` by 0.05 to 0.9 of the displacement, relative, at N = 64, the
        more the softer the chain).
    closed : bool, default True
        Closed ring (N >= 3) or open line with free ends (N >= 2).
    method : {"exact", "efdm", "efdmt", "dmma", "dmmat"}, default "exact"
        - ``"exact"``: two first-order recursions, O(N), exact to rounding
          (beyond the paper; the fast one).
        - ``"efdm"``: the paper's explicit solution (eq. 18; open: eq. 19-20)
          in its stable form, evaluated densely, O(N^2).
        - ``"efdmt"``: the truncated explicit solution (eq. 21), O(N M).
        - ``"dmma"``: modal analysis by eigendecomposition of K (eq. 5-16),
          O(N^3), the paper's reference.
        - ``"dmmat"``: DMMA keeping the lowest 25 % of the modes.
    tol : float, optional
        Only for ``"efdmt"``: use the smallest neighbourhood M that
        guarantees ``|error| <= tol * max|F|`` instead of the paper's
        M = ceil(mu ln N).

    Returns
    -------
    numpy.ndarray
        Displacements U, float64, the shape of ``forces``, ``[x, y]`` pixels.

    Raises
    ------
    ValueError
        If the forces have the wrong shape, too few nodes or non-finite
        values; if the stiffness is not a finite number > 0; if the method is
        unknown; if ``tol`` is not > 0 or is given for another method.

    Examples
    --------
    >>> import numpy as np
    >>> from engine import deform
    >>> U = deform(np.ones((8, 2)), stiffness=10.0)  # a uniform pull moves rigidly
    >>> bool(np.allclose(U, 1.0))
    True
    """
    a = as_stiffness(stiffness)
    name = as_method(method)
    t = as_tol(tol, name)
    closed = as_closed(closed)
    F, batched = as_forces(forces, closed)
    if F.shape[0] == 0:
        U = np.zeros_like(F)
    elif name == "exact":
        try:
            U = solve_exact(F, a, closed)  # checks finiteness in its own pass
        except ValueError:
            raise_non_finite(F if batched else F[0])  # name the index as the caller sees it
            raise
    else:
        raise_non_finite(F if batched else F[0])
        U = solve_efdmt(F, a, closed, t) if name == "efdmt" else _dense(_DENSE[name], F, a, closed)
    return U if batched else U[0]
