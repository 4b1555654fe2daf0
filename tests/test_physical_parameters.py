"""The log-Cholesky map (Rucker & Wensing 2022): its image is the consistent set, it inverts, its
derivatives match finite differences, and bounds become bounds on phi."""

from __future__ import annotations

import casadi
import numpy as np
import pytest

from dynamics.physical_parameters import (
    ConsistencyBoundsError, InconsistentBodyError, LinkBounds, PhysicalParametrisation, is_consistent,
    log_cholesky_from_link, log_cholesky_link, log_det_divergence, project_link, pseudo_inertia,
)
from dynamics.robot import inertial_parameters


def _random_body(generator):
    """A random rigid body: mass, centre of mass, and an inertia about it from principal moments
    that meet the triangle inequalities, rotated at random."""
    mass = generator.uniform(0.1, 20.0)
    com = generator.normal(0.0, 0.3, 3)
    # second moments of mass along the principal axes, positive: the inertias then meet the triangle inequality
    second = generator.uniform(0.01, 1.0, 3) * mass * 0.05
    principal = np.array([second[1] + second[2], second[0] + second[2], second[0] + second[1]])
    rotation, _ = np.linalg.qr(generator.normal(size=(3, 3)))
    return inertial_parameters(mass, com, rotation @ np.diag(principal) @ rotation.T)


def test_random_phi_gives_a_rigid_body_with_mass_exp_2alpha_and_com_t():
    generator = np.random.default_rng(0)
    link = log_cholesky_link()
    for _ in range(200):
        phi = generator.normal(0.0, 1.5, 10)
        theta, J = (np.asarray(value) for value in link(phi))
        theta = theta.reshape(-1)
        assert np.allclose(pseudo_inertia(theta), J, rtol=1e-12, atol=1e-12)
        assert np.linalg.eigvalsh(J)[0] > 0
        assert theta[0] == pytest.approx(np.exp(2 * phi[0]), rel=1e-12)
        assert np.allclose(theta[1:4] / theta[0], phi[7:], atol=1e-12)
        # the inertia about the centre of mass: positive definite with the triangle inequalities
        m, c = theta[0], theta[1:4] / theta[0]
        inertia = np.array([[theta[4], theta[5], theta[7]], [theta[5], theta[6], theta[8]], [theta[7], theta[8], theta[9]]])
        principal = np.linalg.eigvalsh(inertia - m * (c @ c * np.eye(3) - np.outer(c, c)))
        assert principal[0] > 0
        scale = principal.sum()
        assert principal[2] <= principal[0] + principal[1] + 1e-12 * scale


def test_a_consistent_body_maps_to_phi_and_back_to_itself():
    generator = np.random.default_rng(1)
    link = log_cholesky_link()
    for _ in range(100):
        body = _random_body(generator)
        assert is_consistent(body)
        phi = log_cholesky_from_link(body)
        back = np.asarray(link(phi)[0]).reshape(-1)
        assert np.allclose(back, body, rtol=1e-10, atol=1e-12)


def test_an_inconsistent_body_is_refused_and_its_projection_is_consistent():
    body = inertial_parameters(2.0, [0.1, 0.0, 0.0], np.diag([0.1, 0.01, 0.01]))  # Ixx > Iyy + Izz
    assert not is_consistent(body)
    with pytest.raises(InconsistentBodyError):
        log_cholesky_from_link(body)
    projected = project_link(body)
    assert is_consistent(projected)
    log_cholesky_from_link(projected)


def test_map_derivatives_match_central_differences():
    generator = np.random.default_rng(2)
    parametrisation = PhysicalParametrisation(3, ("nonnegative", "free"), ("a", "b", "c"))
    phi = casadi.SX.sym("phi", parametrisation.n_phi)
    jacobian = casadi.Function("map_jacobian", [phi], [casadi.jacobian(parametrisation.function(phi), phi)])
    for _ in range(5):
        point = generator.normal(0.0, 0.7, parametrisation.n_phi)
        exact = np.asarray(jacobian(point))
        step = 1e-6
        numeric = np.column_stack([
            (parametrisation(point + step * e) - parametrisation(point - step * e)) / (2 * step)
            for e in np.eye(parametrisation.n_phi)
        ])
        assert np.allclose(exact, numeric, rtol=1e-6, atol=1e-7)


def test_effects_are_squares_or_free_and_the_whole_map_inverts():
    generator = np.random.default_rng(3)
    parametrisation = PhysicalParametrisation(2, ("nonnegative", "nonnegative", "free"), ("j1", "j2"))
    theta = np.concatenate([_random_body(generator), _random_body(generator), [0.5, 0.0, -2.0]])
    assert np.allclose(parametrisation(parametrisation.inverse(theta)), theta, rtol=1e-10, atol=1e-12)
    assert parametrisation(-np.ones(parametrisation.n_phi))[20:22].tolist() == [1.0, 1.0]
    with pytest.raises(InconsistentBodyError):
        parametrisation.inverse(np.concatenate([theta[:20], [-0.1, 0.0, 0.0]]))


def test_log_det_divergence_is_zero_at_the_prior_and_positive_elsewhere():
    generator = np.random.default_rng(4)
    body = _random_body(generator)
    phi = casadi.SX.sym("phi", 10)
    divergence = casadi.Function("divergence", [phi], [log_det_divergence(phi, pseudo_inertia(body))])
    assert float(divergence(log_cholesky_from_link(body))) == pytest.approx(0.0, abs=1e-9)
    for _ in range(20):
        assert float(divergence(log_cholesky_from_link(_random_body(generator)))) > 0


def test_bounds_become_bounds_on_phi_and_impossible_ones_are_named():
    bounds = LinkBounds(mass=(1.0, 4.0), com_lower=(-0.1, -0.2, 0.0), com_upper=(0.1, 0.2, 0.5))
    lower, upper = bounds.phi_bounds()
    assert lower[0] == 0.0 and upper[0] == pytest.approx(np.log(2.0))
    assert lower[7:].tolist() == [-0.1, -0.2, 0.0] and upper[7:].tolist() == [0.1, 0.2, 0.5]
    with pytest.raises(ConsistencyBoundsError, match="below zero"):
        LinkBounds(mass=(-2.0, -1.0))
    with pytest.raises(ConsistencyBoundsError, match="above the maximum"):
        LinkBounds(mass=(3.0, 1.0))
    with pytest.raises(ConsistencyBoundsError, match="empty"):
        LinkBounds(com_lower=(0.2, 0, 0), com_upper=(0.1, 1, 1))
    with pytest.raises(ConsistencyBoundsError, match="unknown link"):
        PhysicalParametrisation(1, (), ("j1",), {"j9": bounds})
    parametrisation = PhysicalParametrisation(1, (), ("j1",), {"j1": bounds})
    projected = parametrisation.project(inertial_parameters(9.0, [0.5, 0.0, 0.1], np.diag([0.1, 0.1, 0.1])))
    assert bounds.contains(projected)
