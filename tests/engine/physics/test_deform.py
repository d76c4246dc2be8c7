"""engine.physics.deform: every method against a dense solve of (I + K) U = F."""

from __future__ import annotations

import numpy as np
import pytest

from engine import METHODS, deform, literal_kernel
from tests.engine.reference import GRID, dense_solve, forces_for, grid_id, reference, relative_error

EXACT_METHODS = ("exact", "efdm", "dmma")


@pytest.mark.parametrize("case", GRID, ids=grid_id)
@pytest.mark.parametrize("method", EXACT_METHODS)
def test_exact_methods_match_dense_solve(method: str, case: tuple[int, float, bool]) -> None:
    n, a, closed = case
    forces, ref = reference(n, a, closed)
    U = deform(forces, a, closed=closed, method=method)
    assert U.shape == forces.shape
    assert U.dtype == np.float64
    assert relative_error(U, ref) <= 1e-10


@pytest.mark.parametrize("case", GRID, ids=grid_id)
def test_efdmt_with_tolerance_is_within_tolerance(case: tuple[int, float, bool]) -> None:
    n, a, closed = case
    forces, ref = reference(n, a, closed)
    U = deform(forces, a, closed=closed, method="efdmt", tol=1e-8)
    assert np.abs(U - ref).max() <= 1e-8 * np.abs(forces).max()


def test_literal_formula_fails_where_stable_form_is_exact() -> None:
    # The paper's eq. 18 as printed: mu^N overflows at N = 2000, a = 10 ...
    n, a = 2000, 10.0
    assert not np.isfinite(literal_kernel(n, a)).all()
    forces, ref = reference(n, a, True)
    for method in ("efdm", "exact"):
        assert relative_error(deform(forces, a, method=method), ref) <= 1e-12
    # ... and from N = 541 its denominator overflows: all weights silently 0,
    assert not literal_kernel(541, a).any()
    # while below that it is the same function as the stable form.
    n = 101
    forces, ref = reference(n, a, True)
    idx = np.subtract.outer(np.arange(n), np.arange(n)) % n
    literal = literal_kernel(n, a)[idx] @ forces
    assert relative_error(literal, ref) <= 1e-12


@pytest.mark.parametrize("method", METHODS)
@pytest.mark.parametrize("closed", [True, False])
def test_batch_equals_one_by_one(method: str, closed: bool) -> None:
    batch = np.stack([forces_for(40, seed) for seed in range(3)])
    kw = {"tol": 1e-9} if method == "efdmt" else {}
    U = deform(batch, 3.0, closed=closed, method=method, **kw)
    assert U.shape == batch.shape
    for b in range(3):
        one = deform(batch[b], 3.0, closed=closed, method=method, **kw)
        np.testing.assert_allclose(U[b], one, rtol=0, atol=1e-12)


def test_batched_error_names_contour_node_and_coordinate() -> None:
    batch = np.stack([forces_for(12, seed) for seed in range(3)])
    batch[2, 5, 0] = np.nan
    with pytest.raises(ValueError, match=r"index \(2, 5, 0\)"):
        deform(batch, 1.0)


def test_empty_batch() -> None:
    assert deform(np.zeros((0, 5, 2)), 1.0).shape == (0, 5, 2)


def test_accepts_lists_and_non_contiguous_arrays() -> None:
    forces = forces_for(30)
    expected = deform(forces, 2.0)
    np.testing.assert_allclose(deform(forces.tolist(), 2.0), expected, atol=1e-13)
    wide = np.zeros((30, 4))
    wide[:, ::2] = forces
    np.testing.assert_allclose(deform(wide[:, ::2], 2.0), expected, atol=1e-13)
    np.testing.assert_allclose(deform(forces.astype(np.float32), 2.0), expected, atol=1e-5)


def test_does_not_modify_input() -> None:
    forces = forces_for(50)
    before = forces.copy()
    for method in METHODS:
        deform(forces, 5.0, method=method)
    np.testing.assert_array_equal(forces, before)


@pytest.mark.parametrize("a", [1e-6, 1e6])
@pytest.mark.parametrize("closed", [True, False])
def test_extreme_stiffness(a: float, closed: bool) -> None:
    forces = forces_for(300)
    U = deform(forces, a, closed=closed)
    residual = dense_solve(forces, a, closed) - U
    assert np.abs(residual).max() <= 1e-9 * np.abs(forces).max()


def test_large_chain_is_exact_by_residual() -> None:
    # N = 10^5: check (I + K) U = F through the banded product, no dense matrix.
    n, a = 100_000, 50.0
    forces = forces_for(n)
    U = deform(forces, a)
    lap_u = 2 * U - np.roll(U, 1, axis=0) - np.roll(U, -1, axis=0)
    assert np.abs(U + a * lap_u - forces).max() <= 1e-9 * np.abs(forces).max()


BAD_INPUTS: list[tuple[object, dict[str, object], str]] = [
    (np.zeros(6), {}, "shape"),
    (np.zeros((5, 3)), {}, "shape"),
    (np.zeros((2, 3, 4, 2)), {}, "shape"),
    (np.zeros((2, 2)), {}, "at least 3 nodes"),
    (np.zeros((1, 2)), {"closed": False}, "at least 2 nodes"),
    ([["a", "b"]] * 4, {}, "real numbers"),
    (np.array([[1.0, np.nan]] * 4), {}, "finite"),
    (np.array([[1.0, np.inf]] * 4), {"method": "efdm"}, "finite"),
    (np.ones((4, 2)), {"stiffness": 0.0}, "stiffness"),
    (np.ones((4, 2)), {"stiffness": -1.0}, "stiffness"),
    (np.ones((4, 2)), {"stiffness": float("nan")}, "stiffness"),
    (np.ones((4, 2)), {"stiffness": float("inf")}, "stiffness"),
    (np.ones((4, 2)), {"stiffness": "10"}, "stiffness"),
    (np.ones((4, 2)), {"stiffness": True}, "stiffness"),
    (np.ones((4, 2)), {"method": "fft"}, "unknown method"),
    (np.ones((4, 2)), {"method": "efdmt", "tol": 0.0}, "tol"),
    (np.ones((4, 2)), {"method": "efdmt", "tol": -1e-3}, "tol"),
    (np.ones((4, 2)), {"method": "efdmt", "tol": float("nan")}, "tol"),
    (np.ones((4, 2)), {"method": "exact", "tol": 1e-6}, "only to method='efdmt'"),
    (np.ones((4, 2)), {"stiffness": 10**400}, "stiffness must be finite"),
    (np.ones((4, 2)), {"method": "efdmt", "tol": 10**400}, "tol must be finite"),
    (np.ones((4, 2)) * (1 + 2j), {}, "complex"),
    ([[1 + 1j, 0.0]] * 4, {}, "complex"),
    (np.ones((4, 2)), {"closed": "False"}, "closed must be True or False"),
    (np.ones((4, 2)), {"closed": 1}, "closed must be True or False"),
]


@pytest.mark.parametrize(("forces", "kwargs", "message"), BAD_INPUTS)
def test_bad_input_raises_clear_value_error(
    forces: object, kwargs: dict[str, object], message: str
) -> None:
    args: dict[str, object] = {"stiffness": 1.0, **kwargs}
    with pytest.raises(ValueError, match=message):
        deform(forces, **args)  # type: ignore[arg-type]


@pytest.mark.parametrize("method", METHODS)
def test_non_finite_force_error_names_its_index(method: str) -> None:
    forces = forces_for(20)
    forces[7, 1] = -np.inf
    with pytest.raises(ValueError, match=r"index \(7, 1\)"):
        deform(forces, 1.0, method=method)


def test_overflowing_result_is_a_value_error() -> None:
    forces = np.full((10, 2), 1e308)  # finite, but U would exceed float64
    with pytest.raises(ValueError, match="overflow"):
        deform(forces, 1e6)
