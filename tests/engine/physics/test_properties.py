"""Physical properties of the equilibrium, checked on random chains (hypothesis)."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from engine import deform, system_matrix

finite = st.floats(-1e3, 1e3, allow_nan=False, allow_infinity=False)


@st.composite
def chains(draw: st.DrawFn) -> tuple[np.ndarray, float, bool]:
    closed = draw(st.booleans())
    n = draw(st.integers(3 if closed else 2, 300))
    forces = draw(arrays(np.float64, (n, 2), elements=finite))
    a = 10.0 ** draw(st.floats(-6, 6))
    return forces, a, closed


@settings(max_examples=150, deadline=None)
@given(chains())
def test_residual_is_at_rounding_level(chain: tuple[np.ndarray, float, bool]) -> None:
    forces, a, closed = chain
    U = deform(forces, a, closed=closed)
    residual = system_matrix(len(forces), a, closed=closed) @ U - forces
    scale = np.abs(forces).max() + 1e-300
    assert np.abs(residual).max() <= 1e-12 * (1 + 4 * a) * scale


@settings(max_examples=60, deadline=None)
@given(chains(), st.floats(-1e3, 1e3), st.floats(-1e3, 1e3))
def test_uniform_force_translates_rigidly(
    chain: tuple[np.ndarray, float, bool], fx: float, fy: float
) -> None:
    forces, a, closed = chain
    uniform = np.broadcast_to([fx, fy], forces.shape)
    np.testing.assert_allclose(
        deform(uniform, a, closed=closed),
        uniform,
        rtol=1e-9,
        atol=1e-9 * (abs(fx) + abs(fy)) + 1e-300,  # subnormal forces round to 0
    )


@settings(max_examples=60, deadline=None)
@given(chains(), st.floats(-10, 10))
def test_linear_in_forces(chain: tuple[np.ndarray, float, bool], k: float) -> None:
    forces, a, closed = chain
    other = np.roll(forces, 1, axis=0)[:, ::-1]
    lhs = deform(k * forces + other, a, closed=closed)
    rhs = k * deform(forces, a, closed=closed) + deform(other, a, closed=closed)
    scale = (abs(k) + 1) * (np.abs(forces).max() + 1)
    np.testing.assert_allclose(lhs, rhs, atol=1e-11 * scale)


@settings(max_examples=60, deadline=None)
@given(chains())
def test_equivariant_under_reversal_and_rotation(chain: tuple[np.ndarray, float, bool]) -> None:
    forces, a, closed = chain
    U = deform(forces, a, closed=closed)
    scale = np.abs(forces).max() + 1
    np.testing.assert_allclose(deform(forces[::-1], a, closed=closed), U[::-1], atol=1e-12 * scale)
    if closed:  # a ring has no first node
        np.testing.assert_allclose(
            deform(np.roll(forces, 5, axis=0), a), np.roll(U, 5, axis=0), atol=1e-12 * scale
        )
