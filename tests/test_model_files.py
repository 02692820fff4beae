"""A mechanism built in Python saved as a scene (TOML or JSON) and built again."""

import math
import re
from pathlib import Path

import numpy as np
import pytest

import mechsim as ms

ROOT = Path(__file__).resolve().parents[1]


def every_element():
    """A model with every element a scene holds: rigid bodies, a flexible beam, revolute
    joints at a point and by local points, a prismatic joint, a driver, a spring with its
    rest length and damping, a rotational spring, a constant force and torque, and a joint
    speed; names with quotes, backslashes, accents and a newline."""
    mech = ms.Mechanism('rig "test" \\ é\nline', gravity=(0.5, -9.81))
    crank = mech.add(ms.RigidBody.rod("crank", (0, 0), (0.2, 0.1), 1.2))
    beam = mech.add(ms.FlexibleBeam("beam", length=0.8, youngs_modulus=70e9, density=2700.0,
                                    area=2e-4, second_moment=1e-9, n_elements=6, n_modes=2,
                                    start=(0.2, 0.1), angle=-0.1, damping_ratio=0.01))
    block = mech.add(ms.RigidBody.rectangle("block", (1.0, -0.3), 0.1, 0.05, 0.5))
    arm = mech.add(ms.RigidBody.polygon("arm", [(1.0, -0.3), (1.3, -0.3), (1.1, 0.0)], 0.7))
    pivot = mech.add(ms.Revolute(mech.ground, crank, at=(0, 0), name="O"))
    mech.add(ms.Revolute(crank, beam, at=(0.2, 0.1), name="A"))
    mech.add(ms.Prismatic(mech.ground, block, axis=(1.0, 0.2), at=(1.0, -0.3), name="rail"))
    mech.add(ms.Revolute(block, arm, local_a=(0.0, 0.0),
                         local_b=np.array([1.0, -0.3]) - arm.position, name='pin "p"'))
    mech.add(ms.Spring(crank, block, at_a=(0.2, 0.1), at_b=(1.0, -0.3), stiffness=300.0,
                       rest_length=0.7, damping=2.0, name="link spring"))
    mech.add(ms.RotationalSpring(mech.ground, arm, stiffness=5.0, damping=0.1,
                                 rest_angle=0.05, name="arm spring"))
    mech.add(ms.Force(arm, (1.0, -2.0), at=(1.2, -0.2), name="push"))
    mech.add(ms.Torque(beam, 0.3, name="twist"))
    mech.set_speed(pivot, 2.0)
    mech.add(ms.Channel("arm swing", "degrees(arm.angle)", unit="deg"))
    return mech


@pytest.mark.parametrize("suffix", ["toml", "json"])
@pytest.mark.parametrize("make", [every_element, ms.examples.four_bar,
                                  lambda: ms.examples.slider_crank(driven=True,
                                                                   crank_speed=100.0)],
                         ids=["every element", "four-bar", "driven slider-crank"])
def test_a_saved_mechanism_builds_again_exactly(make, suffix, tmp_path):
    """The same structure, masses and initial state, and the same motion to the last bit."""
    mech = make()
    back = ms.load_mechanism(mech.save(tmp_path / f"model.{suffix}"))
    assert back.name == mech.name and back.structure() == mech.structure()
    np.testing.assert_array_equal(back.problem().mass_diagonal, mech.problem().mass_diagonal)
    assert back.speeds == mech.speeds
    for b, m in zip(back.bodies, mech.bodies):
        outline = getattr(m, "outline", None)
        assert (outline is None) == (getattr(b, "outline", None) is None), m.name
        if outline is not None:
            np.testing.assert_array_equal(b.outline, outline)
    assert [(c.name, c.expression, c.unit) for c in back.channels] == \
        [(c.name, c.expression, c.unit) for c in mech.channels]
    a = mech.simulate(0.05, rtol=1e-9, output_step=0.01)
    b = back.simulate(0.05, rtol=1e-9, output_step=0.01)
    assert a.status == b.status == "success", (a.message, b.message)
    np.testing.assert_array_equal(a.q, b.q)
    np.testing.assert_array_equal(a.v, b.v)


def test_what_a_scene_cannot_hold_is_refused_naming_it(tmp_path):
    mech = ms.examples.pendulum()
    mech.add(ms.Torque(mech.body("rod"), lambda t: math.sin(t), name="motor"))
    with pytest.raises(ms.ModelError, match="torque 'motor' is a Python function"):
        mech.save(tmp_path / "m.toml")
    assert not (tmp_path / "m.toml").exists()
    bent = ms.Mechanism("bent")
    bent.add(ms.FlexibleBeam("b", length=1.0, youngs_modulus=1e9, density=1e3, area=1e-4,
                             second_moment=1e-8, eta=[1e-3, 0.0]))
    with pytest.raises(ms.ModelError, match="beam 'b' starts deformed"):
        bent.save(tmp_path / "b.json")


_REPLAY = """
import sys, numpy as np, mechsim as ms
for saved, after, gif in zip(*[iter(sys.argv[1:])] * 3):
    res = ms.load_result(saved)
    joint = res.mechanism.joints[0].name
    ext = res.extend(res.t[-1] + 0.02)
    fig = res.plot_motion()
    lines = [np.asarray(l.get_xydata()) for l in fig.axes[0].get_lines()]
    np.savez(after, force=res.joint_force(joint), ext_q=ext.q, ext_t=ext.t,
             **{f"line{k}": l for k, l in enumerate(lines)})
    res.animate(gif, fps=4)
"""
SCENES = sorted(p.name for p in (ROOT / "mechanisms").glob("*.toml"))
# The scenes replay in groups, one new process each (all of them in one fixture took 25 s
# on an empty cache): a group's scenes share their fixture's process and worker.
GROUPS = 5


def _group(scene) -> int:
    return SCENES.index(scene) % GROUPS


@pytest.fixture(scope="module")
def replays():
    """{group: what `_replay` gave for its scenes}, filled as the tests ask."""
    return {}


def _replay(scenes, tmp_path_factory):
    """Each of `scenes` run briefly, saved, and what is compared after (its joint force,
    extension, motion plot, animation); then every saved result loaded in one new process
    (its answers beside each): {scene: (result, extension, plot lines, directory)}."""
    import subprocess
    import sys
    runs, arguments = {}, []
    for scene in scenes:
        where = tmp_path_factory.mktemp(scene.replace(".", "_"))
        res = ms.load_scene(ROOT / "mechanisms" / scene).simulate(t_end=0.03,
                                                                 output_step=0.005)
        assert res.status == "success", (scene, res.message)
        saved = res.save(where / "run.npz")
        ext = res.extend(res.t[-1] + 0.02)
        fig = res.plot_motion()
        lines = [np.asarray(line.get_xydata()) for line in fig.axes[0].get_lines()]
        res.animate(where / "before.gif", fps=4)
        runs[scene] = (res, ext, lines, where)
        arguments += [str(saved), str(where / "after"), str(where / "after.gif")]
    done = subprocess.run([sys.executable, "-c", _REPLAY, *arguments], capture_output=True,
                          text=True, timeout=300)
    assert done.returncode == 0, done.stderr[-2000:]
    return runs


@pytest.mark.parametrize("scene", [
    pytest.param(s, marks=pytest.mark.xdist_group(f"replays-{_group(s)}")) for s in SCENES])
def test_a_saved_result_replays_in_a_fresh_process(scene, replays, tmp_path_factory):
    """Each shipped scene, run briefly and saved: loaded in a new process it has its
    mechanism, and its joint force, its extension, its motion plot and its animation are
    those of the result before saving (arrays to 1e-12, the GIF byte for byte)."""
    group = _group(scene)
    if group not in replays:
        replays[group] = _replay([s for s in SCENES if _group(s) == group], tmp_path_factory)
    res, ext, lines, where = replays[group][scene]
    joint = res.mechanism.joints[0].name
    after = np.load(where / "after.npz")
    np.testing.assert_allclose(after["force"], res.joint_force(joint), rtol=0, atol=1e-12)
    np.testing.assert_array_equal(after["ext_t"], ext.t)
    np.testing.assert_allclose(after["ext_q"], ext.q, rtol=0, atol=1e-12)
    for k, line in enumerate(lines):
        np.testing.assert_allclose(after[f"line{k}"], line, rtol=0, atol=1e-12)
    assert (where / "after.gif").read_bytes() == (where / "before.gif").read_bytes()


def test_a_result_whose_mechanism_a_scene_cannot_hold_says_why_when_loaded(tmp_path):
    mech = ms.examples.pendulum()
    mech.add(ms.Torque(mech.body("rod"), lambda t: 0.1 * math.sin(t), name="motor"))
    res = mech.simulate(0.1, output_step=0.01)
    back = ms.load_result(res.save(tmp_path / "r.npz"))
    assert back.mechanism is None
    with pytest.raises(RuntimeError, match="extending the run needs the mechanism's model.*"
                                           "torque 'motor' is a Python function"):
        back.extend(0.2)


SHAPED = """
name = "shapes"
[parameters]
w = 0.12
[[body]]
name = "block"
mass = 0.5
rectangle = ["w", 0.05]
position = [1.0, -0.3]
angle = 0.2
[[body]]
name = "wheel"
mass = 3.0
disc = 0.25
position = [0.0, 0.0]
[[body]]
name = "arm"
mass = 0.7
polygon = [[1.0, -0.3], [1.3, -0.3], [1.1, 0.0]]
[[body]]
name = "plate"
mass = 2.0
inertia = 0.01
position = [0.5, 0.5]
outline = [[-0.1, -0.1], [0.1, -0.1], [0.0, 0.2]]
"""


def test_a_scene_builds_bodies_from_their_shapes(tmp_path):
    """rectangle, disc and polygon in a scene are the shape constructors' bodies exactly
    (mass properties, frame and outline), an outline is kept (closed) on a general body."""
    path = tmp_path / "shapes.toml"
    path.write_text(SHAPED, encoding="utf-8")
    mech = ms.load_mechanism(path)
    expected = [ms.RigidBody.rectangle("block", (1.0, -0.3), 0.12, 0.05, 0.5, angle=0.2),
                ms.RigidBody.disc("wheel", (0.0, 0.0), 0.25, 3.0),
                ms.RigidBody.polygon("arm", [(1.0, -0.3), (1.3, -0.3), (1.1, 0.0)], 0.7)]
    for body, want in zip(mech.bodies, expected):
        assert (body.mass, body.inertia, body.angle) == (want.mass, want.inertia, want.angle)
        np.testing.assert_array_equal(body.position, want.position)
        np.testing.assert_array_equal(body.outline, want.outline)
    # a plate 0.12 × 0.05 of 0.5 kg: m (w² + h²) / 12
    assert mech.bodies[0].inertia == pytest.approx(0.5 * (0.12**2 + 0.05**2) / 12, rel=1e-15)
    assert mech.bodies[1].inertia == pytest.approx(3.0 * 0.25**2 / 2, rel=1e-15)
    plate = mech.bodies[3]
    np.testing.assert_array_equal(plate.outline, [[-0.1, -0.1], [0.1, -0.1], [0.0, 0.2],
                                                  [-0.1, -0.1]])
    back = ms.load_mechanism(mech.save(tmp_path / "again.toml"))
    for a, b in zip(back.bodies, mech.bodies):
        np.testing.assert_array_equal(a.outline, b.outline)
        assert (a.mass, a.inertia) == (b.mass, b.inertia)


@pytest.mark.parametrize("change, message", [
    ('disc = 0.25\n', "give one shape, got `rectangle`, `disc`"),
    ('inertia = 0.1\n', "a `rectangle` body takes its inertia from its shape; remove `inertia`"),
    ('outline = [[0, 0], [1, 0], [0, 1]]\n',
     "a `rectangle` body takes its inertia from its shape; remove `outline`"),
])
def test_a_shape_in_a_scene_is_checked(tmp_path, change, message):
    text = SHAPED.replace('rectangle = ["w", 0.05]\n', 'rectangle = ["w", 0.05]\n' + change)
    path = tmp_path / "shapes.toml"
    path.write_text(text, encoding="utf-8")
    with pytest.raises(ms.ModelError, match=r"body\[0\] \('block'\): " + re.escape(message)):
        ms.load_mechanism(path)


def test_a_shape_without_its_centre_or_with_two_points_is_refused(tmp_path):
    path = tmp_path / "shapes.toml"
    path.write_text(SHAPED.replace("position = [0.0, 0.0]\n", ""), encoding="utf-8")
    with pytest.raises(ms.ModelError, match=r"body\[1\] \('wheel'\): a `disc` body needs "
                                            r"`position`, its centre"):
        ms.load_mechanism(path)
    path.write_text(SHAPED.replace("[1.1, 0.0]]", "]").replace("[1.3, -0.3], ]", "[1.3, -0.3]]"),
                    encoding="utf-8")
    with pytest.raises(ms.ModelError, match=r"body\[2\] \('arm'\) polygon: expected an array "
                                            r"of 3 to 10000 points"):
        ms.load_mechanism(path)
