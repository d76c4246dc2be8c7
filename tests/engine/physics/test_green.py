"""engine.physics.green: the stable Green's function and the EFDMT neighbourhood."""

from __future__ import annotations

import math

import numpy as np
import pytest

from engine import green_kernel, paper_radius, system_matrix, tolerance_radius
from engine.physics.green import ChainConstants


@pytest.mark.parametrize("a", [1e-6, 1e-3, 1.0, 10.0, 1e4, 1e6])
def test_constants_satisfy_the_paper_identities(a: float) -> None:
    c = ChainConstants.of(a)
    assert c.mu * c.lam == pytest.approx(a, rel=1e-14)
    assert c.mu - c.lam == pytest.approx(1.0, rel=1e-14)
    assert 0.0 < c.r < 1.0
    assert math.exp(c.log_r) == pytest.approx(c.r, rel=1e-14)


@pytest.mark.parametrize("n", [3, 8, 51])
@pytest.mark.parametrize("a", [1e-3, 2.0, 300.0])
def test_kernel_is_first_row_of_inverse(n: int, a: float) -> None:
    inverse = np.linalg.inv(system_matrix(n, a))
    np.testing.assert_allclose(green_kernel(n, a), inverse[0], rtol=1e-11, atol=1e-15)


def test_kernel_sums_to_one_and_is_symmetric() -> None:
    g = green_kernel(1000, 25.0)
    assert g.sum() == pytest.approx(1.0, rel=1e-13)
    np.testing.assert_allclose(g[1:], g[1:][::-1], rtol=1e-13)


def test_kernel_is_finite_for_huge_chains() -> None:
    g = green_kernel(1_000_000, 1e6)
    assert np.isfinite(g).all()
    assert g.sum() == pytest.approx(1.0, rel=1e-10)


def test_paper_radius_is_mu_ln_n() -> None:
    c = ChainConstants.of(10.0)
    assert paper_radius(1000, 10.0) == math.ceil(c.mu * math.log(1000))
    assert paper_radius(2, 1e-6) >= 1


@pytest.mark.parametrize("a", [1e-6, 1e-2, 1.0, 10.0, 1e3, 1e6])
@pytest.mark.parametrize("tol", [1e-2, 1e-8, 1e-14])
def test_tolerance_radius_is_the_smallest_guaranteed(a: float, tol: float) -> None:
    # Dropped weight of the infinite chain beyond M: r^(M+1) (s+1)/s.
    c = ChainConstants.of(a)

    def tail(m: int) -> float:
        return c.power(m + 1) * (c.s + 1.0) / c.s

    m = tolerance_radius(a, tol)
    assert tail(m) <= tol * (1 + 1e-12)
    if m > 0:
        assert tail(m - 1) > tol


def test_tolerance_bound_covers_the_true_tail() -> None:
    # On a finite ring the weights outside the window never exceed the bound.
    n, a, tol = 400, 30.0, 1e-6
    m = tolerance_radius(a, tol)
    g = green_kernel(n, a)
    window = g[0] + 2 * g[1 : m + 1].sum()
    assert 1.0 - window <= tol
