"""``Chain``: a deformable contour model, static and dynamic."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike, NDArray

from engine.physics._validation import (
    as_closed,
    as_method,
    as_positive,
    as_stiffness,
    as_tol,
    min_nodes,
)
from engine.physics.deform import deform

__all__ = ["Chain", "ChainState"]


def _frozen(array: NDArray[np.float64]) -> NDArray[np.float64]:
    array.setflags(write=False)
    return array


@dataclass(frozen=True, slots=True)
class ChainState:
    """Displacement and velocity of every node, relative to the rest shape.

    Attributes
    ----------
    displacement : numpy.ndarray
        Shape (N, 2), ``[x, y]`` pixels.
    velocity : numpy.ndarray
        Shape (N, 2), ``[x, y]`` pixels per unit of time.
    """

    displacement: NDArray[np.float64]
    velocity: NDArray[np.float64]


@dataclass(frozen=True, slots=True)
class Chain:
    """Immutable description of a physics-based deformable contour.

    N masses at rest positions X0 joined into a ring or a line by springs,
    each also tied to its rest position by a unit spring (paper section II).

    Parameters
    ----------
    rest : array_like
        Rest nodes X0, shape (N, 2), ``[x, y]`` pixels (x = column, y = row).
    stiffness : float
        ``a = k/m`` > 0.
    closed : bool, default True
        Ring or open line with free ends.
    method : str, default "exact"
        Solver used by :meth:`deformed` and :meth:`step` (see :func:`engine.physics.deform`).
    tol : float, optional
        EFDMT tolerance (``method="efdmt"`` only).
    mass : float, default 1.0
        Node mass m >= 0 for :meth:`step`, in units where the rest spring is 1.
    damping : float, default 2.0
        Viscous damping c >= 0 for :meth:`step` (2 * sqrt(m) damps the rigid
        motion critically).
    dt : float, default 1.0
        Time step h > 0 for :meth:`step` (e.g. one video frame).

    Raises
    ------
    ValueError
        On a malformed rest shape or an invalid parameter.
    """

    rest: NDArray[np.float64]
    stiffness: float
    closed: bool = True
    method: str = "exact"
    tol: float | None = None
    mass: float = 1.0
    damping: float = 2.0
    dt: float = 1.0
    _shape: tuple[int, int] = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        try:
            rest = np.array(self.rest, dtype=np.float64)
        except (TypeError, ValueError) as exc:
            raise ValueError(f"rest nodes must be an array of real numbers: {exc}") from None
        closed = as_closed(self.closed)
        need = min_nodes(closed)
        if rest.ndim != 2 or rest.shape[1] != 2 or rest.shape[0] < need:
            raise ValueError(
                f"rest nodes must have shape (N, 2) with N >= {need}; got {rest.shape}"
            )
        if not np.isfinite(rest).all():
            raise ValueError("rest nodes must be finite")
        set_ = object.__setattr__
        set_(self, "rest", _frozen(rest))
        set_(self, "stiffness", as_stiffness(self.stiffness))
        set_(self, "closed", closed)
        set_(self, "method", as_method(self.method))
        set_(self, "tol", as_tol(self.tol, self.method))
        set_(self, "mass", as_positive("mass", self.mass, allow_zero=True))
        set_(self, "damping", as_positive("damping", self.damping, allow_zero=True))
        set_(self, "dt", as_positive("dt", self.dt))
        set_(self, "_shape", (rest.shape[0], 2))

    @property
    def n(self) -> int:
        """Number of nodes N."""
        return self._shape[0]

    def replace(self, **changes: object) -> Chain:
        """A copy with some fields changed (validated like the constructor)."""
        return dataclasses.replace(self, **changes)  # type: ignore[arg-type]

    def displacement(self, forces: ArrayLike) -> NDArray[np.float64]:
        """Equilibrium displacement U under ``forces`` (paper eq. 16).

        Parameters
        ----------
        forces : array_like
            Shape (N, 2) or (B, N, 2), ``[x, y]``.

        Returns
        -------
        numpy.ndarray
            U, the shape of ``forces``.
        """
        self._check(forces)
        return deform(forces, self.stiffness, closed=self.closed, method=self.method, tol=self.tol)

    def deformed(self, forces: ArrayLike) -> NDArray[np.float64]:
        """Nodes in equilibrium under ``forces``: X = X0 + U (paper eq. 15).

        Parameters
        ----------
        forces : array_like
            Shape (N, 2) or (B, N, 2), ``[x, y]`` pixels.

        Returns
        -------
        numpy.ndarray
            Deformed nodes, the shape of ``forces``, ``[x, y]`` pixels.
        """
        return self.rest + self.displacement(forces)

    def at_rest(self) -> ChainState:
        """The state with zero displacement and velocity."""
        zeros = np.zeros(self._shape)
        return ChainState(_frozen(zeros), _frozen(zeros.copy()))

    def nodes(self, state: ChainState) -> NDArray[np.float64]:
        """Node positions X0 + u of a dynamic state, ``[x, y]`` pixels."""
        return self.rest + state.displacement

    def step(self, state: ChainState, forces: ArrayLike) -> ChainState:
        """Advance the dynamics one implicit-Euler step of length ``dt``.

        Solves m u'' + c u' + (I + K) u = F (paper eq. 2 with the unit rest
        springs, so that the fixed point is the static equilibrium of eq. 16).
        With u' and u'' as backward differences of step h,

            ((1 + alpha) I + K) u_new = F + (m/h^2)(u + h v) + (c/h) u,
            alpha = m/h^2 + c/h,

        which, divided by 1 + alpha, is the static problem with stiffness
        a / (1 + alpha): the same O(N) solver, unconditionally stable.  With
        m = c = 0 a step is the static equilibrium.

        Parameters
        ----------
        state : ChainState
            Current displacement and velocity.
        forces : array_like
            Shape (N, 2), ``[x, y]``, held constant over the step.

        Returns
        -------
        ChainState
            The state after the step.
        """
        self._check(forces)
        u, v = state.displacement, state.velocity
        if u.shape != self._shape or v.shape != self._shape:
            raise ValueError(f"state arrays must have shape {self._shape}")
        F = np.asarray(forces, dtype=np.float64)
        if F.ndim != 2:
            raise ValueError(f"step takes forces of shape {self._shape}; got {F.shape}")
        h, m, c = self.dt, self.mass, self.damping
        alpha = m / h**2 + c / h
        rhs = F + (m / h**2) * (u + h * v) + (c / h) * u
        u_new = deform(
            rhs / (1.0 + alpha),
            self.stiffness / (1.0 + alpha),
            closed=self.closed,
            method=self.method,
            tol=self.tol,
        )
        return ChainState(_frozen(u_new), _frozen((u_new - u) / h))

    def _check(self, forces: ArrayLike) -> None:
        shape = np.shape(forces)
        if tuple(shape[-2:]) != self._shape:
            raise ValueError(
                f"forces must have shape {self._shape} (or a batch of them); got {shape}"
            )
