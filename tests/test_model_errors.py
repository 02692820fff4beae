"""Bad input gets an error that names the object and says what is wrong."""

import math

import numpy as np
import pytest

import mechsim as ms


@pytest.mark.parametrize("kwargs, words", [
    (dict(mass=-1.0, inertia=1.0), ["'crank'", "mass", "positive"]),
    (dict(mass=1.0, inertia=float("nan")), ["'crank'", "inertia", "finite"]),
    (dict(mass=1.0, inertia=1.0, position=(0.0, math.inf)), ["'crank'", "position", "finite"]),
    (dict(mass=1.0, inertia=1.0, position=(0.0, 1.0, 2.0)), ["'crank'", "position", "length 2"]),
    (dict(mass="heavy", inertia=1.0), ["'crank'", "mass", "number"]),
])
def test_bad_body_arguments(kwargs, words):
    with pytest.raises(ms.ModelError) as err:
        ms.RigidBody("crank", **kwargs)
    for w in words:
        assert w in str(err.value)


def test_rod_of_zero_length():
    with pytest.raises(ms.ModelError, match="'link'.*coincide"):
        ms.RigidBody.rod("link", (1, 1), (1, 1), mass=1.0)


def test_spring_with_negative_stiffness_or_length():
    a = ms.RigidBody("a", 1.0, 1.0)
    with pytest.raises(ms.ModelError, match="spring 'k1'.*stiffness.*non-negative"):
        ms.Spring(a, a, (0, 0), (1, 0), stiffness=-5.0, name="k1")
    with pytest.raises(ms.ModelError, match="rest_length"):
        ms.Spring(a, a, (0, 0), (1, 0), stiffness=5.0, rest_length=-1.0)


def test_joint_to_a_body_not_in_the_mechanism():
    mech = ms.Mechanism("m")
    crank = mech.add(ms.RigidBody("crank", 1.0, 1.0))
    stray = ms.RigidBody("stray", 1.0, 1.0)
    with pytest.raises(ms.ModelError, match="'stray' is not in mechanism 'm'"):
        mech.add(ms.Revolute(crank, stray, at=(0, 0), name="J"))


def test_zero_prismatic_axis():
    with pytest.raises(ms.ModelError, match="prismatic joint 'P'.*axis.*non-zero"):
        ms.Prismatic(ms.Ground(), ms.RigidBody("s", 1.0, 1.0), axis=(0.0, 0.0), name="P")


def test_duplicate_names():
    mech = ms.Mechanism("m")
    mech.add(ms.RigidBody("crank", 1.0, 1.0))
    with pytest.raises(ms.ModelError, match="'crank' exists already"):
        mech.add(ms.RigidBody("crank", 1.0, 1.0))


def test_unknown_method_lists_the_valid_ones():
    mech = ms.examples.pendulum()
    with pytest.raises(ValueError, match="unknown method 'rk99'; valid methods: .*baumgarte"):
        mech.simulate(t_end=1.0, method="rk99")
    with pytest.raises(ValueError, match="unknown integrator 'Euler'; valid integrators: adams, RK45"):
        mech.simulate(t_end=1.0, integrator="Euler")
    with pytest.raises(ValueError, match="does not take .gamma.*valid names: atol"):
        mech.simulate(t_end=1.0, gamma=3.0)
    # Names are matched in any letter case.
    assert mech.simulate(t_end=0.05, integrator="radau").stats["integrator"] == "Radau"
    with pytest.raises(ValueError, match="rtol"):
        mech.simulate(t_end=1.0, rtol=-1.0)


def test_driver_expression_errors_come_when_the_driver_is_made():
    pin = ms.examples.pendulum().joint("pivot")
    with pytest.raises(ms.ModelError, match="driver 'spin'.*unknown name 'omega'"):
        ms.Driver(pin, "omega*t", name="spin")
    with pytest.raises(ms.ModelError, match="driver 'typo'.*cannot parse"):
        ms.Driver(pin, "2*t +* 3", name="typo")


def test_unassemblable_four_bar_names_the_joint():
    """A coupler 0.5 m long cannot close a four-bar whose cranks stand 3 m apart."""
    mech = ms.Mechanism("broken")
    crank = mech.add(ms.RigidBody.rod("crank", (0, 0), (0, 1), 1.0))
    coupler = mech.add(ms.RigidBody.rod("coupler", (0, 1), (0.5, 1), 1.0))
    rocker = mech.add(ms.RigidBody.rod("rocker", (3, 0), (3, 1), 1.0))
    mech.add(ms.Revolute(mech.ground, crank, at=(0, 0), name="A"))
    mech.add(ms.Revolute(crank, coupler, at=(0, 1), name="B"))
    mech.add(ms.Revolute(coupler, rocker, local_a=(0.25, 0.0), local_b=(0.5, 0.0), name="C"))
    mech.add(ms.Revolute(mech.ground, rocker, at=(3, 0), name="D"))
    with pytest.raises(ms.AssemblyError) as err:
        mech.assemble()
    msg = str(err.value)
    assert "cannot be assembled" in msg and "largest residual" in msg
    assert any(f"of '{j}'" in msg for j in "ABCD")


def test_closable_guess_is_assembled_with_a_small_change():
    mech = ms.Mechanism("guess")
    crank = mech.add(ms.RigidBody.rod("crank", (0, 0), (0, 1), 1.0))
    coupler = mech.add(ms.RigidBody.rod("coupler", (0, 1), (1, 1), 1.0))
    rocker = mech.add(ms.RigidBody.rod("rocker", (1, 0), (1, 1), 1.0))
    mech.add(ms.Revolute(mech.ground, crank, at=(0, 0)))
    mech.add(ms.Revolute(crank, coupler, at=(0, 1)))
    # The rocker is 1.05 m by its local points: the guess is 5 cm off and must move.
    mech.add(ms.Revolute(coupler, rocker, local_a=(0.5, 0.0), local_b=(0.55, 0.0), name="C"))
    mech.add(ms.Revolute(mech.ground, rocker, at=(1, 0)))
    rep = mech.assemble()
    assert rep.residual < 1e-10 and 0.0 < rep.position_change < 0.2
    assert np.max(np.abs(mech.problem().phi(rep.q, 0.0))) < 1e-10


def test_dof_reports_redundant_constraints():
    """A single coupler on three parallel cranks: Grübler says 0 DOF, the rank says 1 DOF with
    one redundant equation, and names the joints that share it."""
    mech = ms.Mechanism("triple crank")
    coupler = mech.add(ms.RigidBody.rod("coupler", (0, 1), (2, 1), 1.0))
    for i in range(3):
        crank = mech.add(ms.RigidBody.rod(f"crank{i}", (i, 0), (i, 1), 1.0))
        mech.add(ms.Revolute(mech.ground, crank, at=(i, 0), name=f"A{i}"))
        mech.add(ms.Revolute(crank, coupler, at=(i, 1), name=f"B{i}"))
    rep = mech.dof()
    assert (rep.coordinates, rep.constraints, rep.rank, rep.dof, rep.redundant) == (12, 12, 11, 1, 1)
    assert set(rep.redundant_joints) >= {"A0", "B0"} and "redundant" in str(rep)
    # A four-bar is not redundant.
    four = ms.examples.four_bar().dof()
    assert (four.dof, four.redundant, four.redundant_joints) == (1, 0, [])


def test_scene_errors_name_file_table_and_key(tmp_path):
    bad = tmp_path / "bad.toml"
    bad.write_text('[[body]]\nname = "crank"\nrod = [[0, 0], [1, 0]]\nmass = 1.0\nmas = 2\n'
                   '[simulation]\nt_end = 1\n')
    with pytest.raises(ms.ModelError, match=r"bad.toml: body\[0\] \('crank'\): unknown key.*'mas'"):
        ms.load_scene(bad)
    bad.write_text('[[body]]\nname = "crank"\nrod = [[0, 0], [1, 0]]\nmass = -1.0\n'
                   '[simulation]\nt_end = 1\n')
    with pytest.raises(ms.ModelError, match=r"body\[0\].*'crank'.*mass.*positive"):
        ms.load_scene(bad)
    bad.write_text('[[joint]]\ntype = "revolute"\nbodies = ["ground", "crank"]\nat = [0, 0]\n'
                   '[simulation]\nt_end = 1\n')
    with pytest.raises(ms.ModelError, match=r"joint\[0\]: no body named 'crank'"):
        ms.load_scene(bad)
    bad.write_text('[parameters]\nL = "2*M"\n')
    with pytest.raises(ms.ModelError, match=r"\[parameters\] L: unknown name 'M'"):
        ms.load_scene(bad)
    bad.write_text('[parameters]\nL = "__import__(\'os\')"\n')
    with pytest.raises(ms.ModelError, match=r"\[parameters\] L: unknown function '__import__'"):
        ms.load_scene(bad)


def test_bodies_own_their_frames_and_help_reads_as_theirs():
    """The base class held one position array for every body that did not set its own (the
    ground's): shared, mutable, and help(RigidBody) printed numpy's ndarray docstring
    through it."""
    import pydoc
    a, b = ms.Ground(), ms.Ground()
    a.position[0] = 5.0
    assert b.position[0] == 0.0
    text = pydoc.render_doc(ms.RigidBody, renderer=pydoc.plaintext)
    assert "ndarray(shape" not in text and "A uniform rectangular plate" in text


def test_a_pin_typed_far_off_and_a_body_joined_to_nothing_are_warned_of():
    """A four-bar whose rocker pin was typed 10 m off (for 1.0), and a loose body: both run,
    but the build warns, naming them (before: silently accepted)."""
    mech = ms.Mechanism("typo")
    crank = mech.add(ms.RigidBody.rod("crank", (0, 0), (0, 1), 1.0))
    coupler = mech.add(ms.RigidBody.rod("coupler", (0, 1), (1, 1), 1.0))
    rocker = mech.add(ms.RigidBody.rod("rocker", (1, 0), (1, 1), 1.0))
    mech.add(ms.RigidBody("loose", 1.0, 0.1, position=(3.0, 0.0)))
    mech.add(ms.Revolute(mech.ground, crank, at=(0, 0), name="A"))
    mech.add(ms.Revolute(crank, coupler, at=(0, 1), name="B"))
    mech.add(ms.Revolute(coupler, rocker, at=(1, 1), name="C"))
    mech.add(ms.Revolute(mech.ground, rocker, at=(10.0, 0.0), name="D"))
    with pytest.warns(UserWarning) as caught:
        mech.problem()
    texts = [str(w.message) for w in caught]
    assert any("body 'loose' is joined to nothing" in t for t in texts), texts
    assert any("joint 'D' is at (10, 0), 9.01 m from body 'rocker'" in t for t in texts), texts
    assert not any("joint 'A'" in t or "joint 'B'" in t for t in texts)
    good = ms.examples.four_bar()
    assert good.placement_warnings() == []


@pytest.mark.parametrize("field, value, message", [
    ("stiffness", "abc", "`stiffness` must be a number"),
    ("damping", -1.0, "`damping` must be non-negative"),
    ("rest_length", float("nan"), "`rest_length` must be finite"),
])
def test_a_spring_s_constants_are_checked_naming_the_spring(field, value, message):
    """Stiffness, damping and rest length take Parameters, and anything else than a
    number is still refused naming the spring and the argument."""
    mech = ms.examples.pendulum()
    arguments = {"stiffness": 10.0, **{field: value}}
    with pytest.raises(ms.ModelError, match=f"spring 'pull': {message}"):
        ms.Spring(mech.ground, mech.body("rod"), (0.0, 0.0), (1.0, 0.0), name="pull",
                  **arguments)
