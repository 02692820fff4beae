"""Animations and motion plots: GIFs that Pillow reads back with the expected frames and
size, for a rigid, a flexible and a driven mechanism; traced paths equal to `res.point`."""

import math

import numpy as np
import pytest
from PIL import Image

import mechsim as ms
from mechsim.results.animation import MAX_SECONDS, frame_indices

SIZE = (640, 600)                           # the figure's 6.4 × 6.0 in at 100 dpi


def frames_of(path):
    with Image.open(path) as im:
        return im.n_frames, im.size


def test_a_rigid_four_bar_animates_with_its_coupler_curve(tmp_path):
    res = ms.examples.four_bar().simulate(2.0, output_step=0.02)
    path = res.animate(tmp_path / "four_bar.gif", trace=[("coupler", (0.5, 0.0))], fps=25)
    assert frames_of(path) == (len(res.t), SIZE)
    # Frames differ as the bars move: the first and the middle one are not the same picture.
    with Image.open(path) as im:
        first = np.asarray(im.convert("RGB"))
        im.seek(len(res.t) // 2)
        middle = np.asarray(im.convert("RGB"))
    assert np.mean(np.any(first != middle, axis=2)) > 0.005


def test_a_long_result_is_decimated_to_a_playable_length(tmp_path):
    res = ms.examples.pendulum().simulate(5.0, output_step=1e-3)     # 5001 samples
    assert len(frame_indices(res.t, 10)) == 10 * MAX_SECONDS
    path = res.animate(tmp_path / "pendulum.gif", fps=10, max_frames=30)
    assert frames_of(path) == (30, SIZE)


def test_a_flexible_beam_is_drawn_deformed(tmp_path):
    res = ms.examples.flexible_four_bar().simulate(0.1, output_step=0.01, rtol=1e-6,
                                                   max_step=5e-4)
    path = res.animate(tmp_path / "flexible.gif", exaggeration=100.0, fps=10)
    assert frames_of(path) == (len(res.t), SIZE)
    fig = res.plot_motion(trace=[("coupler", (0.5, 0.0))], exaggeration=100.0)
    curve = [ln for ln in fig.axes[0].lines if ln.get_label().startswith("path of")][0]
    np.testing.assert_allclose(np.column_stack(curve.get_data()),
                               res.point("coupler", (0.5, 0.0)), rtol=0, atol=1e-12)


def test_a_driven_slider_crank_with_its_spring_and_guide(tmp_path):
    mech = ms.examples.slider_crank(driven=True)
    mech.add(ms.Spring(mech.ground, mech.body("slider"), at_a=(0.6, 0.0), at_b=(0.45, 0.0),
                       stiffness=100.0))
    res = mech.simulate(0.05, output_step=1e-3)
    path = res.animate(tmp_path / "slider.gif", trace=[("rod", (0.0, 0.0))], fps=20)
    assert frames_of(path) == (len(res.t), SIZE)
    fig = res.plot_motion(tmp_path / "slider.png", trace=[("rod", (0.0, 0.0))], snapshots=4)
    assert (tmp_path / "slider.png").stat().st_size > 5000
    lines = fig.axes[0].lines
    curve = [ln for ln in lines if ln.get_label().startswith("path of")][0]
    np.testing.assert_allclose(np.column_stack(curve.get_data()), res.point("rod", (0.0, 0.0)),
                               rtol=0, atol=1e-12)
    # The spring is drawn as a zig-zag between its ends, the guide along the slide.
    zigzags = [ln for ln in lines if len(ln.get_xdata()) == 18]
    assert len(zigzags) == 4


def test_animation_arguments_are_checked(tmp_path):
    res = ms.examples.pendulum().simulate(0.1, output_step=0.01)
    with pytest.raises(ValueError, match=".gif or .mp4"):
        res.animate(tmp_path / "x.avi")
    with pytest.raises(ValueError, match="fps"):
        res.animate(tmp_path / "x.gif", fps=0)
    from matplotlib import animation
    if not animation.writers.is_available("ffmpeg"):
        with pytest.raises(ValueError, match="needs ffmpeg"):
            res.animate(tmp_path / "x.mp4")
    res.mechanism = None            # a result without its model (as from solver.simulate)
    saved = ms.load_result(res.save(tmp_path / "r.npz"))
    with pytest.raises(RuntimeError, match="geometry"):
        saved.animate(tmp_path / "y.gif")


def test_plot_draws_what_it_is_asked_for():
    mech = ms.examples.slider_crank(driven=True)
    res = mech.simulate(0.05, output_step=1e-3)
    fig = res.plot(coordinates=["crank.angle"], points=[("slider", (0.0, 0.0))],
                   joints=["B"], reactions=["A"], efforts=[mech.drivers[0]])
    panels = [ax for ax in fig.axes]
    assert len(panels) == 5

    def data(ax, label):
        (line,) = [ln for ln in ax.lines if ln.get_label() == label]
        return line.get_ydata()
    np.testing.assert_array_equal(data(panels[0], "crank.angle"), res.coordinate("crank.angle"))
    np.testing.assert_array_equal(data(panels[1], "slider (0, 0) x"),
                                  res.point("slider", (0.0, 0.0))[:, 0])
    np.testing.assert_array_equal(data(panels[2], "B"), res.joint_coordinate("B"))
    np.testing.assert_allclose(data(panels[3], "A"),
                               np.linalg.norm(res.joint_force("A"), axis=1), rtol=1e-15)
    np.testing.assert_array_equal(data(panels[4], mech.drivers[0].name),
                                  res.driver_effort(mech.drivers[0]))
    assert [ax.get_ylabel() for ax in panels] == [
        "coordinate [rad]", "position [m]", "joint coordinate [rad]", "|F| [N]",
        "torque [N·m]"]
    both = res.plot(coordinates=["crank.angle", "slider.x"])
    assert [ax.get_ylabel() for ax in both.axes] == ["coordinate [rad]", "coordinate [m]"]
    efforts = res.plot_efforts().axes[0]
    assert efforts.get_ylabel() == "torque [N·m]"
    assert [t.get_text() for t in efforts.get_legend().get_texts()][0] == "driver(O) [N·m]"
    with pytest.raises(ValueError, match="name something to plot"):
        res.plot()


def test_the_energy_plot_names_its_mechanism_and_scale_and_summarizes_many_switches(
        monkeypatch):
    """The balance panel (below the energies in joules)."""
    from mechsim.results import plots
    res = ms.examples.four_bar().simulate(2.0, output_step=0.01)
    fig = res.plot_energy()
    top, ax = fig.axes
    assert "four-bar" in top.get_title() and "3 singular passages" in top.get_title()
    assert f"{res.energy_scale:.4g} J" in ax.get_ylabel()
    assert res.switches
    assert len([ln for ln in ax.lines if ln.get_linestyle() == "--"]) == len(res.switches)
    monkeypatch.setattr(plots, "MAX_SWITCH_LINES", 0)
    ax = res.plot_energy().axes[1]
    assert not [ln for ln in ax.lines if ln.get_linestyle() == "--"]
    assert f"{len(res.switches)} solver switches" in \
        [t.get_text() for t in ax.get_legend().get_texts()]


def test_the_energy_plot_shows_each_energy_in_joules():
    """Above the balance: kinetic, potential, strain (a flexible mechanism), total and the
    work of each channel, every line the result's own energy log, the axis in joules."""
    mech = ms.examples.slider_crank(flexible=True, driven=True, crank_speed=30.0)
    res = mech.simulate(0.05, integrator="adams", max_step=5e-4, output_step=1e-3)
    top, bottom = res.plot_energy().axes
    assert top.get_ylabel() == "energy [J]" and bottom.get_xlabel() == "time [s]"
    lines = {ln.get_label(): ln.get_ydata() for ln in top.lines}
    e = res.energy
    np.testing.assert_array_equal(lines["kinetic T"], e.kinetic)
    np.testing.assert_array_equal(lines["potential V"], e.potential)
    np.testing.assert_array_equal(lines["strain U"], e.strain)
    np.testing.assert_array_equal(lines["total E = T + V + U"], e.total)
    assert e.channels and all(f"work W of {c}" in lines for c in e.channels)
    for k, c in enumerate(e.channels):
        np.testing.assert_array_equal(lines[f"work W of {c}"], e.work_by[:, k])
    np.testing.assert_array_equal(bottom.lines[0].get_ydata(), res.energy_drift)


def test_figures_say_their_exaggeration_and_pace_and_show_under_pyplot():
    """A flexible mechanism drawn with its deflection exaggerated says so; an animation
    says how fast it plays against real time (200 samples 1 ms apart at 30 frames a second:
    0.03 × real time); with pyplot imported, mechsim's figures are pyplot's (plt.show()
    shows them)."""
    from mechsim.results.animation import pace_note
    res = ms.examples.flexible_four_bar().simulate(0.02, integrator="adams", max_step=5e-4,
                                                   output_step=1e-3)
    assert "(elastic deflection × 50)" in res.plot_motion(exaggeration=50.0).axes[0].get_title()
    assert "deflection" not in res.plot_motion().axes[0].get_title()
    rigid = ms.examples.four_bar().simulate(0.2, output_step=1e-3)
    assert "deflection" not in rigid.plot_motion(exaggeration=50.0).axes[0].get_title()
    t = np.arange(200) * 1e-3
    assert pace_note(t, np.arange(200), 30) == "   (0.03 × real time)"
    assert pace_note(t, np.arange(200), 1000) == ""
    import sys
    had = "matplotlib.pyplot" in sys.modules
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    try:
        fig = rigid.plot_energy()
        assert fig.number in plt.get_fignums()
    finally:
        plt.close("all")
        if not had:                    # the tests after this one draw without pyplot again
            sys.modules.pop("matplotlib.pyplot", None)


def test_bodies_are_drawn_as_their_shapes():
    """A slider block held at one point is a square of its inertia's size (it was a line of
    no length, invisible); a ternary link is the triangle through its three joints (it was
    a bent line through its centre of mass); a body from a shape constructor is its outline
    (here a rectangle's corners and a disc's rim)."""
    sc = ms.examples.slider_crank(driven=True)
    drawn = {name: local for name, _, local, _ in sc.problem().drawing}
    block = drawn["slider"]
    side = math.sqrt(6 * sc.body("slider").inertia / sc.body("slider").mass)
    np.testing.assert_allclose(np.ptp(block, axis=0), [side, side])
    assert np.array_equal(block[0], block[-1])                      # closed

    mech = ms.Mechanism("ternary")
    tri = mech.add(ms.RigidBody.rod("tri", (0, 0), (1, 0), 1.0))    # a link with 3 pins
    arm = mech.add(ms.RigidBody.rod("arm", (0.5, 0.8), (1.5, 0.8), 1.0))
    plate = mech.add(ms.RigidBody.rectangle("plate", (2.0, 0.0), 0.4, 0.2, 1.0))
    wheel = mech.add(ms.RigidBody.disc("wheel", (1.0, -1.0), 0.3, 2.0))
    mech.add(ms.Revolute(mech.ground, tri, at=(0, 0)))
    mech.add(ms.Revolute(tri, arm, at=(0.5, 0.8)))
    mech.add(ms.Revolute(tri, plate, at=(1.0, 0.0)))
    mech.add(ms.Revolute(mech.ground, wheel, at=(1.0, -1.0)))
    drawn = {name: local for name, _, local, _ in mech.problem().drawing}
    corners = {tuple(np.round(p + tri.position, 12)) for p in drawn["tri"][:-1]}
    assert corners == {(0.0, 0.0), (0.5, 0.8), (1.0, 0.0)} and len(drawn["tri"]) == 4
    assert np.allclose(np.abs(drawn["plate"]), [0.2, 0.1])
    np.testing.assert_allclose(np.hypot(*drawn["wheel"].T), 0.3)
    mech.simulate(0.05, output_step=0.01).plot_motion()              # and they draw


def test_a_gif_stores_what_moved_and_decodes_to_every_drawn_frame():
    """Decoded, every frame equals the picture drawn (in the shared palette), and the file
    is at most half the size of one that stores each frame's changed box whole."""
    import io

    from mechsim.results.animation import _render, gif_bytes
    res = ms.examples.four_bar().simulate(1.0, output_step=0.01)
    _, _, frame, count = _render(res, [("coupler", (0.5, 0.0))], 30, 1.0, None)
    images = [frame(i) for i in range(count)]
    data = gif_bytes(images, 30)
    palette = Image.fromarray(images[0]).quantize(colors=255, method=Image.Quantize.MEDIANCUT)
    drawn = [np.asarray(Image.fromarray(im).quantize(palette=palette, dither=Image.Dither.NONE)
                        .convert("RGB")) for im in images]
    with Image.open(io.BytesIO(data)) as gif:
        assert gif.n_frames == count == len(res.t)
        for k in range(count):
            gif.seek(k)
            np.testing.assert_array_equal(np.asarray(gif.convert("RGB")), drawn[k])
    whole = io.BytesIO()
    every = [Image.fromarray(im).quantize(palette=palette, dither=Image.Dither.NONE)
             for im in images]
    every[0].save(whole, format="GIF", save_all=True, append_images=every[1:], duration=33,
                  loop=0, optimize=False)
    assert len(data) < 0.5 * len(whole.getvalue())


def test_an_animation_shows_inline_and_saves(tmp_path):
    """res.animation(): a GIF in memory that Jupyter shows (an <img> of its bytes), saved
    byte for byte as animate writes it; its pace is the simulated time per second played
    (a sample every 0.02 s at 25 fps: half real time)."""
    import base64
    import re
    res = ms.examples.four_bar().simulate(0.4, output_step=0.02)
    movie = res.animation(fps=25)
    html = movie._repr_html_()
    encoded = re.fullmatch(r'<img src="data:image/gif;base64,([A-Za-z0-9+/=]+)" alt="[^"]*">',
                           html).group(1)
    assert base64.b64decode(encoded) == movie.data
    assert movie.frames == len(res.t) and movie.pace == pytest.approx(0.5, rel=1e-12)
    saved = movie.save(tmp_path / "a.gif")
    assert saved.read_bytes() == res.animate(tmp_path / "b.gif", fps=25).read_bytes()
    with pytest.raises(ValueError, match="must end in .gif"):
        movie.save(tmp_path / "a.mp4")
    assert "0.5 × real time" in repr(movie)


def test_stops_and_slots_are_drawn_where_they_act():
    """A pendulum with stops at −60° and 0.3 rad: a mark from the pin along the rod's line
    at each; a block on a guide with stops at −0.2 and 0.3 m: a bar across the guide where
    its point stops; a pin in a circular slot of a turning disc: the slot's circle, turning
    with the disc."""
    from mechsim.results.animation import Scene
    mech = ms.Mechanism("stops", gravity=(0.0, -9.81))
    rod = mech.add(ms.RigidBody.rod("rod", (0, 0), (1.0, 0), 1.0))
    pin = mech.add(ms.Revolute(mech.ground, rod, at=(0, 0), name="pin"))
    mech.add(ms.Stop(pin, lower=-np.pi / 3, upper=0.3))
    block = mech.add(ms.RigidBody("block", 1.0, 1e-3, position=(0.5, -1.0)))
    guide = mech.add(ms.Prismatic(mech.ground, block, axis=(1, 0), at=(0.5, -1.0)))
    mech.add(ms.Stop(guide, lower=-0.2, upper=0.3))
    disc = mech.add(ms.RigidBody.disc("disc", (2.0, 0.0), 0.3, 1.0, angular_velocity=2.0))
    mech.add(ms.Revolute(mech.ground, disc, at=(2.0, 0.0), name="hub"))
    bead = mech.add(ms.RigidBody.disc("bead", (2.2, 0.0), 0.01, 0.01))
    mech.add(ms.PointOnCurve(disc, bead, at=(2.2, 0.0), centre=(2.0, 0.0),
                             curve=("circle", 0.2), name="slot"))
    res = mech.simulate(0.2, rtol=1e-8, output_step=0.1)
    scene = Scene(res, [0, len(res.t) - 1])
    marks = [g[0] for g in scene.guides]                         # at the first frame
    strokes = [m for m in marks if len(m) == 2 and np.isclose(np.linalg.det(m[:2]), 0.0)
               and np.linalg.norm(m[0]) < 1.0]
    angles = sorted(np.arctan2(m[1, 1], m[1, 0]) for m in strokes)
    np.testing.assert_allclose(angles, [-np.pi / 3, 0.3], atol=1e-12)
    bars = sorted(m[0, 0] for m in marks if len(m) == 2 and np.isclose(m[0, 0], m[1, 0])
                  and abs(m[0, 1] + 1.0) < 0.2)
    np.testing.assert_allclose(bars, [0.3, 0.8], atol=1e-12)
    (circle,) = [g for g in scene.guides if len(g[0]) > 2]
    x = mech.coordinate_names.index("disc.x")
    for k, frame in enumerate(circle):                            # turning with the disc
        centre = res.q[scene.frames[k], x:x + 2]
        np.testing.assert_allclose(np.hypot(*(frame - centre).T), 0.2, atol=1e-12)
    turned = circle[1][0] - res.q[scene.frames[1], x:x + 2]
    angle = res.coordinate("disc.angle")[scene.frames[1]]
    np.testing.assert_allclose(turned, 0.2 * np.array([np.cos(angle), np.sin(angle)]),
                               atol=1e-12)
