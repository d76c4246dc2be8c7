"""engine.physics.efdmt: the truncated explicit solution (paper eq. 21)."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from engine import deform, paper_radius
from engine.physics.efdmt import truncation_radius
from engine.physics.green import ChainConstants
from tests.engine.reference import dense_solve, forces_for


@pytest.mark.parametrize("closed", [True, False])
@pytest.mark.parametrize("a", [1.0, 10.0, 100.0])
def test_paper_neighbourhood_error_is_within_its_bound(closed: bool, a: float) -> None:
    # M = ceil(mu ln N) drops weights worth at most r^(M+1) (s+1)/s of max|F|.
    n = 3000
    c = ChainConstants.of(a)
    bound = c.power(paper_radius(n, a) + 1) * (c.s + 1) / c.s
    assert bound < 1e-3
    forces = forces_for(n)
    ref = dense_solve(forces, a, closed)
    U = deform(forces, a, closed=closed, method="efdmt")
    assert np.abs(U - ref).max() <= bound * np.abs(forces).max()


def test_paper_neighbourhood_really_truncates() -> None:
    # Weights beyond M are dropped: EFDMT differs from the exact solution,
    # just by little (otherwise the test above could not fail).
    n, a = 3000, 10.0
    assert 2 * paper_radius(n, a) + 1 < n
    forces = forces_for(n)
    diff = np.abs(deform(forces, a, method="efdmt") - deform(forces, a)).max()
    assert diff > 0.0


def test_whole_ring_neighbourhood_is_exact() -> None:
    forces = forces_for(9)
    a = 1e4  # M = ceil(mu ln 9) far exceeds the ring
    np.testing.assert_allclose(
        deform(forces, a, method="efdmt"), dense_solve(forces, a, True), rtol=0, atol=1e-12
    )


def test_truncation_radius_switches_rule() -> None:
    assert truncation_radius(1000, 10.0, None) == paper_radius(1000, 10.0)
    assert truncation_radius(1000, 10.0, 1e-3) < truncation_radius(1000, 10.0, 1e-12)


@settings(max_examples=60, deadline=None)
@given(
    n=st.integers(2, 400),
    log_a=st.floats(-6, 5),
    log_tol=st.floats(-13, -1),
    closed=st.booleans(),
    seed=st.integers(0, 2**16),
)
def test_tolerance_is_guaranteed(
    n: int, log_a: float, log_tol: float, closed: bool, seed: int
) -> None:
    if closed and n < 3:
        n = 3
    a, tol = 10.0**log_a, 10.0**log_tol
    forces = np.random.default_rng(seed).uniform(-1, 1, (n, 2)) * 10.0 ** (seed % 7 - 3)
    U = deform(forces, a, closed=closed, method="efdmt", tol=tol)
    error = np.abs(U - dense_solve(forces, a, closed)).max()
    # plus rounding of the dense reference, which grows with cond(I + K) ~ 1 + 4a
    rounding = 1e-14 * (1 + 4 * a)
    assert error <= (tol + rounding) * np.abs(forces).max()
