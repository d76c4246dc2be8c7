"""Input checks shared by the solvers: clear ``ValueError`` messages."""

from __future__ import annotations

import math
import numbers
from typing import Any

import numpy as np
from numpy.typing import NDArray

METHODS = ("exact", "efdm", "efdmt", "dmma", "dmmat")
"""Every solver of :func:`engine.deform`: the one list the library, the command
line and the service take their choices from."""
MODAL_METHODS = ("dmma", "dmmat")
"""The O(N^3) modal references (an eigen-decomposition per call)."""


def min_nodes(closed: bool) -> int:
    """Smallest chain: a ring needs 3 nodes, a line 2."""
    return 3 if closed else 2


def as_forces(forces: Any, closed: bool) -> tuple[NDArray[np.float64], bool]:
    """Return forces as a C-contiguous float64 array of shape (B, N, 2).

    Parameters
    ----------
    forces : array_like
        Shape (N, 2) or (B, N, 2); columns are ``[x, y]`` pixels.
    closed : bool
        Ring (needs N >= 3) or open line (N >= 2).

    Returns
    -------
    array : numpy.ndarray
        The forces as (B, N, 2) float64 (a view when no copy is needed).
    batched : bool
        Whether the input had a batch axis.
    """
    if np.iscomplexobj(forces):  # converting would drop the imaginary parts
        raise ValueError("forces must be real numbers; got complex ones")
    try:
        arr = np.asarray(forces, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"forces must be an array of real numbers: {exc}") from None
    if arr.ndim not in (2, 3) or arr.shape[-1] != 2:
        raise ValueError(
            f"forces must have shape (N, 2) or (B, N, 2) with [x, y] columns; got {arr.shape}"
        )
    n = arr.shape[-2]
    need = min_nodes(closed)
    if n < need:
        kind = "closed" if closed else "open"
        raise ValueError(f"a {kind} chain needs at least {need} nodes; got N = {n}")
    batched = arr.ndim == 3
    return np.ascontiguousarray(arr.reshape(-1, n, 2)), batched


def raise_non_finite(forces: NDArray[np.float64]) -> None:
    """Raise a ``ValueError`` naming the first non-finite force, if any."""
    bad = ~np.isfinite(forces)
    if bad.any():
        where = tuple(int(i) for i in np.argwhere(bad)[0])
        raise ValueError(
            f"forces must be finite; found {forces[where]} at index {where} "
            f"({int(bad.sum())} non-finite values)"
        )


def _real(name: str, value: Any) -> float:
    """``value`` as a float: a real number, not a bool (ValueError otherwise, and for an
    integer too large for a float, rather than an OverflowError)."""
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise ValueError(f"{name} must be a real number; got {value!r}")
    try:
        return float(value)
    except OverflowError:
        raise ValueError(
            f"{name} must be finite; got an integer of {len(str(value))} digits"
        ) from None


def as_closed(closed: Any) -> bool:
    """Validate the chain's kind: True (a ring) or False (a line), not a string or a number
    (``bool("False")`` is true)."""
    if not isinstance(closed, bool | np.bool_):
        raise ValueError(f"closed must be True or False; got {closed!r}")
    return bool(closed)


def as_stiffness(stiffness: Any) -> float:
    """Validate ``a = k/m``: a finite real number > 0."""
    a = _real("stiffness", stiffness)
    if not math.isfinite(a) or a <= 0.0:
        raise ValueError(f"stiffness must be finite and > 0; got {a}")
    return a


def as_method(method: Any) -> str:
    """Validate a solver name."""
    if not isinstance(method, str) or method not in METHODS:
        raise ValueError(f"unknown method {method!r}; choose one of {', '.join(METHODS)}")
    return method


def as_tol(tol: Any, method: str) -> float | None:
    """Validate the EFDMT tolerance (only meaningful for ``method='efdmt'``)."""
    if tol is None:
        return None
    if method != "efdmt":
        raise ValueError(f"tol applies only to method='efdmt'; got method={method!r}")
    t = _real("tol", tol)
    if not math.isfinite(t) or t <= 0.0:
        raise ValueError(f"tol must be finite and > 0; got {t}")
    return t


def as_positive(name: str, value: Any, *, allow_zero: bool = False) -> float:
    """Validate a finite real parameter that must be > 0 (or >= 0)."""
    v = _real(name, value)
    ok = v >= 0.0 if allow_zero else v > 0.0
    if not math.isfinite(v) or not ok:
        bound = ">= 0" if allow_zero else "> 0"
        raise ValueError(f"{name} must be finite and {bound}; got {v}")
    return v
