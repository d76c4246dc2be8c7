"""engine.Chain: static deformation (eq. 15) and implicit-Euler dynamics."""

from __future__ import annotations

import numpy as np
import pytest

from engine import Chain, ChainState, deform
from tests.engine.reference import forces_for


def circle(n: int, radius: float = 50.0) -> np.ndarray:
    t = np.linspace(0.0, 2.0 * np.pi, n, endpoint=False)
    return np.stack([100 + radius * np.cos(t), 80 + radius * np.sin(t)], axis=1)


def test_deformed_is_rest_plus_displacement() -> None:
    chain = Chain(circle(32), stiffness=4.0)
    forces = forces_for(32)
    np.testing.assert_allclose(chain.deformed(forces), circle(32) + deform(forces, 4.0))
    batch = np.stack([forces, -forces])
    assert chain.deformed(batch).shape == (2, 32, 2)


@pytest.mark.parametrize("method", ["efdm", "efdmt", "dmma"])
def test_method_and_topology_are_used(method: str) -> None:
    chain = Chain(circle(20), stiffness=2.0, closed=False, method=method)
    forces = forces_for(20)
    np.testing.assert_allclose(
        chain.displacement(forces),
        deform(forces, 2.0, closed=False, method=method),
    )


def test_chain_is_immutable_and_copies_its_rest_shape() -> None:
    rest = circle(10)
    chain = Chain(rest, stiffness=1.0)
    rest[0] = -1.0
    assert chain.rest[0, 0] != -1.0
    with pytest.raises(ValueError, match="read-only"):
        chain.rest[0, 0] = 5.0
    with pytest.raises(AttributeError):
        chain.stiffness = 3.0  # type: ignore[misc]
    stiffer = chain.replace(stiffness=9.0)
    assert stiffer.stiffness == 9.0
    assert chain.stiffness == 1.0


def test_dynamics_settle_at_the_static_equilibrium() -> None:
    chain = Chain(circle(40), stiffness=8.0, mass=1.0, damping=0.5, dt=0.5)
    forces = forces_for(40)
    state = chain.at_rest()
    for _ in range(400):
        state = chain.step(state, forces)
    np.testing.assert_allclose(chain.nodes(state), chain.deformed(forces), atol=1e-8)
    assert np.abs(state.velocity).max() < 1e-8


def test_massless_undamped_step_is_the_static_solution() -> None:
    chain = Chain(circle(16), stiffness=3.0, mass=0.0, damping=0.0)
    forces = forces_for(16)
    state = chain.step(chain.at_rest(), forces)
    np.testing.assert_allclose(state.displacement, chain.displacement(forces), atol=1e-13)


def test_inertia_lags_and_overshoots() -> None:
    # A light damping lets the chain overshoot; a heavy one approaches monotonically.
    forces = np.ones((12, 2))  # uniform pull: equilibrium displacement is 1
    for damping, overshoots in [(0.2, True), (5.0, False)]:
        chain = Chain(circle(12), stiffness=1.0, mass=1.0, damping=damping, dt=0.2)
        state, peak = chain.at_rest(), 0.0
        first = chain.step(state, forces).displacement[0, 0]
        assert 0.0 < first < 0.5  # the mass cannot jump to equilibrium
        for _ in range(300):
            state = chain.step(state, forces)
            peak = max(peak, float(state.displacement[0, 0]))
        assert (peak > 1.0 + 1e-3) is overshoots


def test_no_force_from_rest_stays_at_rest() -> None:
    chain = Chain(circle(8), stiffness=1.0)
    state = chain.step(chain.at_rest(), np.zeros((8, 2)))
    assert not state.displacement.any()
    assert not state.velocity.any()


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"rest": np.zeros((2, 2))}, "N >= 3"),
        ({"rest": np.zeros((5, 3))}, "shape"),
        ({"rest": [[0.0, np.nan]] * 4}, "finite"),
        ({"rest": "abc"}, "shape|real numbers"),
        ({"stiffness": -1.0}, "stiffness"),
        ({"method": "nope"}, "unknown method"),
        ({"tol": 1e-3}, "only to method='efdmt'"),
        ({"mass": -1.0}, "mass"),
        ({"damping": float("inf")}, "damping"),
        ({"dt": 0.0}, "dt"),
        ({"stiffness": 10**400}, "stiffness must be finite"),
        ({"mass": 10**400}, "mass must be finite"),
        ({"closed": "False"}, "closed must be True or False"),
    ],
)
def test_bad_parameters(kwargs: dict[str, object], message: str) -> None:
    args: dict[str, object] = {"rest": circle(6), "stiffness": 1.0, **kwargs}
    with pytest.raises(ValueError, match=message):
        Chain(**args)  # type: ignore[arg-type]


def test_bad_forces_and_state() -> None:
    chain = Chain(circle(6), stiffness=1.0)
    with pytest.raises(ValueError, match="shape"):
        chain.deformed(np.zeros((7, 2)))
    with pytest.raises(ValueError, match="shape"):
        chain.step(chain.at_rest(), np.zeros((2, 6, 2)))
    bad = ChainState(np.zeros((5, 2)), np.zeros((5, 2)))
    with pytest.raises(ValueError, match="state"):
        chain.step(bad, np.zeros((6, 2)))
    with pytest.raises(ValueError, match="finite"):
        chain.step(chain.at_rest(), np.full((6, 2), np.nan))
