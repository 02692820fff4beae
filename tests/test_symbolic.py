"""Structural tier: generated Φ_q, Φ_t and γ against finite differences of the generated Φ,
on random configurations of a mechanism that uses every joint and driver type."""


import numpy as np
import pytest

import mechsim as ms


def all_joint_types(rng):
    mech = ms.Mechanism("every joint", gravity=(0.0, -9.81))
    bodies = []
    for i in range(4):
        bodies.append(mech.add(ms.RigidBody(f"b{i}", mass=1.0 + i, inertia=0.1 + 0.05 * i,
                                            position=rng.normal(size=2), angle=rng.normal())))
    b0, b1, b2, b3 = bodies
    pin = mech.add(ms.Revolute(mech.ground, b0, at=rng.normal(size=2), name="pin"))
    mech.add(ms.Revolute(b0, b1, local_a=(0.4, 0.1), local_b=(-0.3, 0.2), name="local pin"))
    slide = mech.add(ms.Prismatic(b1, b2, axis=rng.normal(size=2), at=rng.normal(size=2),
                                  name="slide"))
    mech.add(ms.Prismatic(mech.ground, b3, axis=(0.6, 0.8), at=(1.0, -1.0), name="rail"))
    mech.add(ms.Driver(pin, "0.3*sin(2*t) + t**2/5", name="angle driver"))
    mech.add(ms.Driver(slide, "0.1*cos(3*t) - 0.2*t", name="slide driver"))
    return mech


@pytest.fixture(scope="module")
def problem():
    return all_joint_types(np.random.default_rng(7)).problem()


def test_rows_are_named_after_their_joints(problem):
    assert problem.constraint_owners == ["pin"] * 2 + ["local pin"] * 2 + ["slide"] * 2 + \
        ["rail"] * 2 + ["angle driver", "slide driver"]


@pytest.mark.parametrize("seed", range(5))
def test_jacobians_match_finite_differences(problem, seed):
    rng = np.random.default_rng(seed)
    n = problem.n
    q, v, t = rng.normal(size=n) * 2.0, rng.normal(size=n), rng.uniform(0.0, 3.0)
    h = 1e-6
    J = problem.phi_q(q, t)
    J_fd = np.column_stack([(problem.phi(q + h * e, t) - problem.phi(q - h * e, t)) / (2 * h)
                            for e in np.eye(n)])
    np.testing.assert_allclose(J, J_fd, atol=1e-8)
    phi_t_fd = (problem.phi(q, t + h) - problem.phi(q, t - h)) / (2 * h)
    np.testing.assert_allclose(problem.phi_t(q, t), phi_t_fd, atol=1e-8)
    # Along q(τ) = q + v τ (so q̈ = 0), d²Φ/dτ² = Φ_q q̈ − γ = −γ.
    h2 = 1e-4
    d2 = (problem.phi(q + v * h2, t + h2) - 2 * problem.phi(q, t)
          + problem.phi(q - v * h2, t - h2)) / h2**2
    np.testing.assert_allclose(problem.gamma(q, v, t), -d2, atol=2e-6 * max(1, np.abs(d2).max()))


def test_grouped_functions_agree_with_single_ones_to_the_bit(problem, rng):
    """The functions share one cse (`mechsim.codegen.printer.SharedTerms`): Φ, Φ_q, Φ_t
    and γ are the same arithmetic in every function that returns them."""
    q, v, t = rng.normal(size=problem.n), rng.normal(size=problem.n), 0.7
    same = dict(rtol=0, atol=0)
    phi, J, phi_t, gamma = problem.terms(q, v, t)
    np.testing.assert_allclose(phi, problem.phi(q, t), **same)
    np.testing.assert_allclose(J, problem.phi_q(q, t), **same)
    np.testing.assert_allclose(phi_t, problem.phi_t(q, t), **same)
    np.testing.assert_allclose(gamma, problem.gamma(q, v, t), **same)
    phi2, J2 = problem.position_terms(q, t)
    np.testing.assert_allclose(phi2, phi, **same)
    np.testing.assert_allclose(J2, J, **same)
    J3, gamma3 = problem.dynamics_terms(q, v, t)
    np.testing.assert_allclose(J3, J, **same)
    np.testing.assert_allclose(gamma3, gamma, **same)


def test_parameters_are_arguments_not_constants():
    """Two four-bars of different size share one compiled structure but give their own Φ."""
    small = ms.examples.four_bar(length=1.0)
    large = ms.examples.four_bar(length=2.5)
    ps, pl = small.problem(), large.problem()
    assert ps.model is pl.model
    q = large.initial_coordinates()
    assert np.max(np.abs(pl.phi(q, 0.0))) < 1e-14
    assert np.max(np.abs(ps.phi(q, 0.0))) > 0.1


def test_spring_forces_match_the_gradient_of_the_potential(rng):
    mech = ms.Mechanism("springs", gravity=(0.0, -9.81))
    a = mech.add(ms.RigidBody("a", mass=1.0, inertia=0.1, position=(0, 0)))
    b = mech.add(ms.RigidBody("b", mass=2.0, inertia=0.2, position=(1, 0.5), angle=0.3))
    mech.add(ms.Spring(a, b, at_a=(0.1, 0.1), at_b=(1.2, 0.4), stiffness=300.0, rest_length=0.4))
    mech.add(ms.Spring(mech.ground, b, at_a=(2, 2), at_b=(1.0, 0.6), stiffness=50.0))
    p = mech.problem()
    q = mech.initial_coordinates() + 0.1 * rng.normal(size=6)
    h = 1e-6
    grad = np.array([(p.potential_energy(q + h * e) - p.potential_energy(q - h * e)) / (2 * h)
                     for e in np.eye(6)])
    np.testing.assert_allclose(p.forces(0.0, q, np.zeros(6)), -grad, rtol=1e-7, atol=1e-7)


def test_jacobian_and_second_derivative_of_rows_not_of_rotations_are_sympys(rng):
    """`jacobian_of` (reverse accumulation through a row's shared terms where the row is
    not built of rotations) and `second_derivative_along` (forward along the path there)
    against sympy's plain derivatives of each row, at random points: a pin's row, a curve's
    contact with a root, a quotient and an atan2 sharing terms, a gear's quotient with t."""
    import sympy as sp
    from mechsim.symbolic import jacobian_of, second_derivative_along
    x, y, th, t = sp.symbols("x y th t")
    q, v = [x, y, th], list(sp.symbols("u w r"))
    s = sp.sqrt((x - sp.cos(th)) ** 2 + (y + t) ** 2)
    rows = sp.Matrix([x + 0.3 * sp.cos(th) - y * sp.sin(th) ** 2,
                      s * sp.atan2(y - s, x + 2) + (x * y) / (1 + s) - sp.exp(th / s),
                      (x + t * th) / (2 + sp.sin(th) ** 2) - y ** 3 / s])
    J = jacobian_of(rows, q)
    path = second_derivative_along(rows, q, v, t, J)
    plain = rows.jacobian(q)
    qd = sp.Matrix(v)
    plain_path = (plain * qd).jacobian(q) * qd + 2 * rows.diff(t).jacobian(q) * qd + \
        rows.diff(t, 2)
    fast = sp.lambdify([q, v, t], [J, path])
    slow = sp.lambdify([q, v, t], [plain, plain_path])
    for _ in range(20):
        point = (rng.normal(size=3), rng.normal(size=3), float(rng.normal()))
        for a, b in zip(fast(*point), slow(*point)):
            a, b = np.array(a, float), np.array(b, float)
            np.testing.assert_allclose(a, b, rtol=1e-12, atol=1e-12 * np.abs(b).max())
