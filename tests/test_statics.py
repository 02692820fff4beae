"""Static equilibrium, linearized modes, torsion springs and the power a driver delivers,
against closed forms and models derived here by hand."""

import math

import numpy as np
import pytest
from scipy.linalg import eigh
from scipy.optimize import brentq

import mechsim as ms
from mechsim.examples import four_bar_angles, general_four_bar
from test_reactions import differentiate

G = 9.81


def torsion_rod(m=2.0, L=0.8, k=15.0, angle=0.0):
    mech = ms.Mechanism("rod on a torsion spring")
    rod = mech.add(ms.RigidBody.rod("rod", (0, 0), (L * math.cos(angle), L * math.sin(angle)),
                                    mass=m))
    mech.add(ms.Revolute(mech.ground, rod, at=(0, 0), name="pin"))
    mech.add(ms.RotationalSpring(mech.ground, rod, k, rest_angle=0.0, name="spring"))
    return mech


@pytest.mark.parametrize("k", [8.0, 15.0, 60.0])
def test_a_rod_on_a_torsion_spring_rests_where_k_theta_balances_its_weight(k):
    m, L = 2.0, 0.8
    eq = torsion_rod(m, L, k).equilibrium()
    exact = brentq(lambda th: k * th + m * G * L / 2 * math.cos(th), -math.pi / 2, 0.0)
    assert eq.converged and eq.stable and eq.stability == "stable", eq.message
    assert abs(eq.q[2] - exact) < 1e-12
    assert eq.stiffness[0, 0] == pytest.approx(k - m * G * L / 2 * math.sin(exact), rel=1e-8)
    # The pin holds the weight; the spring's torque its moment.
    np.testing.assert_allclose(eq.joint_force("pin"), [0.0, m * G], atol=1e-12)
    lin = torsion_rod(m, L, k).linearize()
    omega = math.sqrt((k - m * G * L / 2 * math.sin(exact)) / (m * L * L / 3))
    assert lin.frequencies[0] == pytest.approx(omega, rel=1e-8)
    assert lin.damping_ratios[0] == 0.0 and lin.equilibrium


def test_a_torsion_spring_damper_rings_down_as_the_damped_oscillator():
    """No gravity: I θ̈ + c θ̇ + k (θ − θ_rest) = 0 in closed form; the damper's and a
    viscous load's (a torque of the joint's rate) work close the energy balance."""
    m, L, k, c, rest = 3.0, 1.0, 10.0, 0.5, -0.1
    mech = ms.Mechanism("torsion", gravity=(0, 0))
    rod = mech.add(ms.RigidBody.rod("rod", (0, 0), (L, 0), mass=m))
    pin = mech.add(ms.Revolute(mech.ground, rod, at=(0, 0), name="pin"))
    mech.add(ms.RotationalSpring(mech.ground, rod, k, damping=c, rest_angle=rest))
    mech.add(ms.Torque(rod, lambda t, angle, rate: -0.2 * rate, joint=pin, name="viscous"))
    res = mech.simulate(5.0, rtol=1e-10, atol=1e-12, output_step=0.01)
    I, ct = m * L * L / 3, c + 0.2
    wn, z = math.sqrt(k / I), ct / (2 * math.sqrt(k * I))
    wd = wn * math.sqrt(1 - z * z)
    exact = rest - rest * np.exp(-z * wn * res.t) * (np.cos(wd * res.t)
                                                    + z * wn / wd * np.sin(wd * res.t))
    assert np.max(np.abs(res.joint_coordinate(pin) - exact)) < 1e-9
    assert np.max(np.abs(res.energy_drift)) < 1e-8
    assert len(res.energy.channels) == 2
    lin = mech.linearize()
    assert lin.frequencies[0] == pytest.approx(wn, rel=1e-8)
    assert lin.damping_ratios[0] == pytest.approx(z, rel=1e-7)


def test_an_inverted_pendulum_is_reported_unstable():
    mech = ms.examples.pendulum(angle=math.pi / 2)
    eq = mech.equilibrium()
    assert eq.converged and not eq.stable and eq.stability == "unstable"
    assert eq.q[2] == pytest.approx(math.pi / 2, abs=1e-12)
    assert eq.stiffness[0, 0] < 0
    lin = mech.linearize(eq.q)
    assert not lin.stable and lin.damping_ratios[0] == -1.0


@pytest.mark.parametrize("angle", [0.0, 0.3, 2.0])
def test_a_pendulum_drawn_off_its_rest_finds_it(angle):
    """From a horizontal pendulum (where the reduced stiffness vanishes) or one tilted
    upwards, the equilibrium found is the stable one the rod falls to."""
    eq = ms.examples.pendulum(angle=angle).equilibrium()
    assert eq.converged and eq.stable
    assert math.cos(eq.q[2]) == pytest.approx(0.0, abs=1e-12) and math.sin(eq.q[2]) < 0


def test_the_compound_double_pendulum_frequencies_solve_det_K_minus_w2_M():
    m1, L1, m2, L2 = 1.0, 1.0, 1.5, 0.7
    mech = ms.Mechanism("double pendulum")
    a = mech.add(ms.RigidBody.rod("a", (0, 0), (0, -L1), mass=m1))
    b = mech.add(ms.RigidBody.rod("b", (0, -L1), (0, -L1 - L2), mass=m2))
    mech.add(ms.Revolute(mech.ground, a, at=(0, 0)))
    mech.add(ms.Revolute(a, b, at=(0, -L1)))
    lin = mech.linearize()
    # θ1, θ2 from the vertical: T = ½ θ̇ᵀ M θ̇, V = ½ θᵀ K θ about hanging.
    M = np.array([[m1 * L1 ** 2 / 3 + m2 * L1 ** 2, m2 * L1 * L2 / 2],
                  [m2 * L1 * L2 / 2, m2 * L2 ** 2 / 3]])
    K = np.diag([(m1 / 2 + m2) * G * L1, m2 * G * L2 / 2])
    omega = np.sqrt(eigh(K, M, eigvals_only=True))
    np.testing.assert_allclose(lin.frequencies, omega, rtol=1e-9)
    # The first mode swings both rods the same way, the second against each other; shapes
    # in all six coordinates, the lower rod's tip moving as the angles say.
    th = lin.modes[:, [2, 5]]
    assert np.sign(th[0, 0]) == np.sign(th[0, 1]) and np.sign(th[1, 0]) != np.sign(th[1, 1])
    np.testing.assert_allclose(lin.modes[:, 0], L1 / 2 * th[:, 0], rtol=1e-9)


def spring_four_bar(a=0.3, b=0.8, c=0.6, d=0.7, masses=(1.0, 2.0, 1.5), k=400.0,
                    anchor=(0.2, 0.9), rest=0.3, theta=1.2):
    """A four-bar under gravity whose coupler's middle is tied to the ground at `anchor` by
    a spring of rest length `rest`."""
    mech = general_four_bar(a, b, c, d, theta=theta, masses=masses)
    coupler = mech.body("coupler")
    mech.add(ms.Spring(mech.ground, coupler, at_a=anchor, at_b=coupler.position,
                       stiffness=k, rest_length=rest, name="spring"))
    return mech


def one_dof_model(a=0.3, b=0.8, c=0.6, d=0.7, masses=(1.0, 2.0, 1.5), k=400.0,
                  anchor=(0.2, 0.9), rest=0.3):
    """V(θ) and J(θ) of the spring four-bar in its crank angle θ, by hand: closed-form
    positions, and their derivatives by a 5-point central difference."""
    m = np.asarray(masses)
    inertia = m * np.array([a, b, c]) ** 2 / 12

    def frames(th):
        th3, th4 = four_bar_angles(np.array(th), a, b, c, d, 1)
        A = np.array([a * np.cos(th), a * np.sin(th)])
        cm = [A / 2, A + b / 2 * np.array([np.cos(th3), np.sin(th3)]),
              np.array([d, 0.0]) + c / 2 * np.array([np.cos(th4), np.sin(th4)])]
        return np.array(cm), np.array([th, th3, th4])

    def V(th):
        cm, _ = frames(th)
        stretch = np.hypot(*(cm[1] - anchor)) - rest
        return G * np.dot(m, cm[:, 1]) + 0.5 * k * stretch ** 2

    def deriv(f, th, h=1e-4):
        return (f(th - 2 * h) - 8 * f(th - h) + 8 * f(th + h) - f(th + 2 * h)) / (12 * h)

    def J(th):
        dcm = deriv(lambda x: frames(x)[0], th)
        dang = deriv(lambda x: frames(x)[1], th)
        return float(np.dot(m, np.sum(dcm ** 2, axis=1)) + np.dot(inertia, dang ** 2))

    return V, J, (lambda th: deriv(V, th)), (lambda th: deriv(lambda x: deriv(V, x), th))


def test_a_spring_four_bar_about_equilibrium_matches_its_one_dof_model():
    mech = spring_four_bar()
    eq = mech.equilibrium()
    assert eq.converged and eq.stable, eq.message
    V, J, dV, d2V = one_dof_model()
    theta = eq.q[2]
    exact = brentq(dV, theta - 0.2, theta + 0.2)
    assert abs(theta - exact) < 1e-8
    lin = mech.linearize()
    assert lin.frequencies[0] == pytest.approx(math.sqrt(d2V(exact) / J(exact)), rel=1e-6)
    # At rest every body's joint forces, weight and spring force balance, moments too.
    spring_force = _spring_force(mech, eq)
    for body in mech.bodies:
        F = np.array([0.0, -body.mass * G])
        M = 0.0
        R = eq.q[[_start(mech, body), _start(mech, body) + 1]]
        for joint in mech.joints:
            for side, sign in ((joint.body_b, 1.0), (joint.body_a, -1.0)):
                if side is body:
                    f = sign * eq.joint_force(joint)
                    P = _joint_point(mech, eq, joint)
                    F = F + f
                    M += (P - R)[0] * f[1] - (P - R)[1] * f[0]
        if body.name == "coupler":
            F = F + spring_force
        scale = 10 * body.mass * G
        assert np.max(np.abs(F)) < 1e-10 * scale, body.name
        assert abs(M) < 1e-10 * scale, body.name


def _start(mech, body):
    return 3 * mech.bodies.index(body)


def _joint_point(mech, eq, joint):
    body = joint.body_b
    s = body.local_point(joint.at)
    k = _start(mech, body)
    c, sn = math.cos(eq.q[k + 2]), math.sin(eq.q[k + 2])
    return eq.q[k:k + 2] + np.array([c * s[0] - sn * s[1], sn * s[0] + c * s[1]])


def _spring_force(mech, eq, anchor=(0.2, 0.9), k=400.0, rest=0.3):
    P = eq.q[3:5]                              # the coupler's centre of mass
    d = P - np.asarray(anchor)
    length = np.hypot(*d)
    return -k * (length - rest) * d / length


def test_a_driver_delivers_the_rate_of_change_of_energy_plus_dissipation():
    """A driven slider-crank under gravity with a spring–damper on its slider: the motor's
    power effort × rate equals dE/dt + c ṡ², E and ṡ computed here from the motion."""
    mech = ms.examples.slider_crank(driven=True, crank_speed=40.0)
    slider = mech.body("slider")
    x0 = slider.position[0]
    c_damp, k = 3.0, 200.0
    mech.add(ms.Spring(mech.ground, slider, at_a=(x0 + 0.5, 0.0), at_b=(x0, 0.0),
                       stiffness=k, damping=c_damp, name="buffer"))
    res = mech.simulate(0.3, rtol=1e-10, atol=1e-12, output_step=2e-4)
    assert res.success, res.message
    E = np.zeros(len(res.t))
    for body in mech.bodies:
        j = 3 * mech.bodies.index(body)
        v = res.v[:, j:j + 3]
        E += 0.5 * body.mass * (v[:, 0] ** 2 + v[:, 1] ** 2) + 0.5 * body.inertia * v[:, 2] ** 2
        E += body.mass * G * res.q[:, j + 1]
    length = np.abs(x0 + 0.5 - res.coordinate("slider.x"))
    E += 0.5 * k * (length - 0.5) ** 2
    rate = -res.v[:, mech.bodies.index(slider) * 3]            # the spring's extension rate
    power = differentiate(res.t, E) + c_damp * rate[4:-4] ** 2
    driver = mech.drivers[0]
    delivered = res.driver_power(driver)[4:-4]
    assert np.max(np.abs(delivered - power)) < 1e-6 * np.max(np.abs(delivered))


def test_a_heavy_crank_leaves_the_flexible_coupler_its_pinned_pinned_frequency():
    """The seed's flexible four-bar held at 40° by a torsion spring on its crank: the first
    elastic frequency couples the coupler's bending with the links' motion, and approaches
    the beam's own pinned–pinned frequency as the crank is made heavy (the shift falls as
    1/mass: the crank, and through the loop the rocker, stand still)."""
    shifts = []
    for mass in (1.0, 100.0, 1e4):
        mech = ms.examples.flexible_four_bar(crank_mass=mass, tilt=math.radians(40.0))
        mech.add(ms.RotationalSpring(mech.ground, mech.body("crank"), 20 * (mass + 1) * G))
        lin = mech.linearize()
        assert lin.equilibrium and lin.stable
        beam = mech.body("coupler").frequencies
        shifts.append(lin.frequencies[1] / beam[0] - 1.0)
        assert lin.frequencies[2] == pytest.approx(beam[1], rel=1e-9)
    assert shifts[0] > 0.1 and shifts[0] > 20 * shifts[1] and \
        80 < shifts[1] / shifts[2] < 120, shifts
    assert shifts[2] < 1e-4


def test_equilibrium_starts_a_simulation_at_rest():
    mech = spring_four_bar()
    eq = mech.equilibrium()
    mech.set_state(eq.q)
    res = mech.simulate(1.0, rtol=1e-10, atol=1e-12, output_step=0.1)
    assert np.max(np.abs(res.q - eq.q)) < 1e-9
    with pytest.raises(ms.ModelError, match="does not satisfy the constraints"):
        mech.set_state(eq.q + 0.01)
