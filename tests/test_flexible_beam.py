"""FlexibleBeam bodies: mass matrix and forces against independent computations, conservation
laws, the rigid limit, the seed's flexible four-bar and slider-crank, errors and export."""

import math
from pathlib import Path

import numpy as np
import pytest

import mechsim as ms
from mechsim.model import ModelError
from mechsim.kinematics import frame_point

ROOT = Path(__file__).resolve().parents[1]
SCENES = ROOT / "mechanisms"


def spinning_beam(gravity=(0.0, 0.0)):
    mech = ms.Mechanism("spinning beam", gravity=gravity)
    beam = mech.add(ms.FlexibleBeam(
        "beam", length=1.0, youngs_modulus=70e9, density=2700.0, area=1e-4,
        second_moment=1e-8 / 12, n_elements=8, n_modes=3, boundary="free-free", start=(0.1, 0.2),
        angle=0.3, velocity=(0.2, -0.1), angular_velocity=20.0, eta=[1e-3, -5e-4, 2e-4],
        eta_velocity=[0.05, 0.0, -0.1]))
    return mech, beam


def quadrature_kinetic_and_momentum(beam, x, v, points=400):
    """½∫ρA|ṙ|² dξ and ∫ρA r × ṙ dξ by the midpoint rule on `points` sections, from the
    positions and velocities of material points (no inertia shape integrals involved)."""
    xi = (np.arange(points) + 0.5) * beam.length / points
    w = beam.density * beam.area * beam.length / points
    th, eta, om, e = x[2], x[3:], v[2], v[3:]
    A = np.array([[math.cos(th), -math.sin(th)], [math.sin(th), math.cos(th)]])
    T = H = 0.0
    for s in xi:
        modal = beam.point_modes((s, 0.0))
        u = np.array([s, 0.0]) + modal @ eta
        r = x[:2] + A @ u
        rd = v[:2] + om * (A @ np.array([-u[1], u[0]])) + A @ (modal @ e)
        T += 0.5 * w * rd @ rd
        H += w * (r[0] * rd[1] - r[1] * rd[0])
    return T, H


def test_kinetic_energy_and_momentum_match_quadrature_of_material_points(rng):
    mech, beam = spinning_beam()
    with pytest.warns(UserWarning, match="body 'beam' is joined to nothing"):
        prob = mech.problem()                   # a free beam, on purpose
    fb = prob.flexible[0]
    for _ in range(3):
        x = np.concatenate([rng.normal(size=3), 1e-2 * rng.normal(size=3)])
        v = rng.normal(size=6)
        T_ref, H_ref = quadrature_kinetic_and_momentum(beam, x, v, points=4000)
        M = prob.mass(x)
        assert np.allclose(M, M.T, atol=1e-15)
        # The midpoint rule converges as 1/points²: 4000 sections give ~1e-7 relative.
        assert 0.5 * v @ M @ v == pytest.approx(T_ref, rel=1e-6)
        assert prob.kinetic_energy(x, v) == pytest.approx(0.5 * v @ M @ v, rel=1e-13)
        # H is a difference of terms of size m·|R|·|Ṙ| ~ 0.3: compare on that scale.
        scale = beam.mass * (1 + np.abs(x[:2]).sum()) * (1 + np.abs(v).sum())
        assert fb.invariants.angular_momentum(x, v) == pytest.approx(H_ref, abs=1e-6 * scale)
    # The factor used by every formulation: L⁻¹ M L⁻ᵀ = I.
    f = prob.mass_factor(x)
    assert np.allclose(f.Linv @ M @ f.Linv.T, np.eye(6), atol=1e-12)


def test_free_spinning_beam_conserves_energy_and_angular_momentum():
    mech, beam = spinning_beam()
    res = mech.simulate(0.5, method="projection", rtol=1e-9, atol=1e-12, output_step=0.01)
    assert res.success
    inv = mech.problem().flexible[0].invariants
    H = inv.angular_momentum(res.q, res.v)
    assert np.max(np.abs(res.energy_drift)) < 1e-8
    assert np.max(np.abs(H - H[0])) < 1e-10 * abs(H[0])
    # It really vibrates: strain energy swings between near zero and a sizeable fraction of
    # the elastic plus modal kinetic energy it was given.
    assert res.energy.strain.max() > 0.1 and res.energy.strain.min() < 0.02
    # Linear momentum: the centre of mass moves in a straight line at constant speed.
    sbar = inv.s0 + res.q[:, 3:] @ inv.s_eta.T
    c, s = np.cos(res.q[:, 2]), np.sin(res.q[:, 2])
    com = res.q[:, :2] + np.stack([c * sbar[:, 0] - s * sbar[:, 1],
                                   s * sbar[:, 0] + c * sbar[:, 1]], axis=-1) / inv.mass
    fit = np.polyfit(res.t, com, 1)
    assert np.max(np.abs(np.polyval(fit[:, 0], res.t) - com[:, 0])) < 1e-9
    assert np.max(np.abs(np.polyval(fit[:, 1], res.t) - com[:, 1])) < 1e-9


def test_free_beam_falls_with_its_centre_of_mass_at_g():
    mech, beam = spinning_beam(gravity=(0.0, -9.81))
    res = mech.simulate(0.2, method="lu", rtol=1e-10, atol=1e-12, output_step=0.005)
    inv = mech.problem().flexible[0].invariants
    sbar = inv.s0 + res.q[:, 3:] @ inv.s_eta.T
    c, s = np.cos(res.q[:, 2]), np.sin(res.q[:, 2])
    com_y = res.q[:, 1] + (s * sbar[:, 0] + c * sbar[:, 1]) / inv.mass
    quad = np.polyfit(res.t, com_y, 2)
    assert quad[0] == pytest.approx(-9.81 / 2, rel=1e-8)
    assert np.max(np.abs(res.energy_drift)) < 1e-8


def test_rigid_limit_follows_the_rigid_four_bar_as_one_over_e():
    rigid = ms.examples.flexible_four_bar(rigid=True).simulate(
        0.2, rtol=1e-9, atol=1e-11, output_step=0.01)
    gaps = []
    for scale in (1.0, 1000.0):
        flex = ms.examples.flexible_four_bar(youngs_modulus=117e9 * scale).simulate(
            0.2, rtol=1e-8, atol=1e-10, output_step=0.01)
        assert flex.success
        gaps.append(np.max(np.abs(flex.coordinate("crank.angle")
                                  - rigid.coordinate("crank.angle"))))
        mid = np.max(np.abs(flex.point("coupler", (0.5, 0.0)) - rigid.point("coupler")))
        assert mid < 5e-4 / scale
    # The elastic coupler's effect on the crank is its compliance, ∝ 1/E: ~1e-4 rad at the
    # seed's stiffness, 1000 times less with E × 1000 (down to 1.7e-7 rad, 20× the
    # integration tolerance).
    assert 5e-5 < gaps[0] < 5e-4
    assert gaps[1] == pytest.approx(gaps[0] / 1000.0, rel=0.2)


def test_flexible_four_bar_scene_passes_both_singular_configurations():
    scene = ms.load_scene(SCENES / "flexible_four_bar.toml")
    res = scene.simulate()
    assert res.success, res.message
    assert res.t[-1] == pytest.approx(1.2)
    assert np.max(np.abs(res.energy_drift)) <= 1e-5
    assert res.energy.strain.max() > 0.01                 # ~0.05 J of ~22 J
    # Passages near the rigid parallelogram's crossings at 0.173 and 0.955 s (the elastic
    # coupler lets the crank lag a little), each entered and left by a switch.
    assert [(s.from_method, s.to_method) for s in res.switches] == \
        [("lu", "projection"), ("projection", "lu")] * 2
    # Crank angle against the parallelogram branch of the rigid mechanism with the same
    # coupler mass: within the elastic lag (2.0e-3 rad by 1.2 s, grown through the two
    # passages), no branch jump; the passages within 2e-3 s of the rigid one's (3e-5 s and
    # 6e-4 s apart).
    rigid = ms.examples.flexible_four_bar(rigid=True).simulate(
        1.2, rtol=1e-9, atol=1e-11, output_step=0.001)
    assert np.max(np.abs(res.coordinate("crank.angle") - rigid.coordinate("crank.angle"))) < 4e-3
    mins = [p.t_min for p in res.singular_passages]
    assert len(mins) == 2
    np.testing.assert_allclose(mins, [p.t_min for p in rigid.singular_passages], atol=2e-3)
    # Seed 000's average-velocity rule at a fixed step 10× the seed's 5e-4 s (the first mode
    # gets 12 steps per period) passes both singular configurations, halving its step where
    # Newton needs it, and stays close to the adaptive hybrid run (measured: crank 2.0e-4
    # rad, coupler midpoint 3.6e-4 m, drift 3.9e-5).
    newmark = scene.mechanism.simulate(1.2, method="ss-newmark", h=5e-3, output_step=1e-3)
    assert newmark.success, newmark.message
    assert len(newmark.singular_passages) == 2
    assert np.max(np.abs(newmark.coordinate("crank.angle") - res.coordinate("crank.angle"))) < 1e-3
    assert np.max(np.abs(newmark.point("coupler", (0.5, 0.0))
                         - res.point("coupler", (0.5, 0.0)))) < 1e-3
    assert np.max(np.abs(newmark.energy_drift)) < 1e-4


def test_flexible_slider_crank_deflection_follows_the_quasi_static_estimate():
    mech = ms.examples.slider_crank(flexible=True, driven=True, gravity=(0.0, 0.0),
                                    damping_ratio=0.05)
    beam = mech.body("rod")
    rev = 2 * math.pi / 150.0
    res = mech.simulate(4 * rev, rtol=1e-6, atol=1e-9, output_step=rev / 200)
    assert res.success
    L, E, w, rho = 0.30, 2e11, 0.008, 7870.0
    EI, rhoA = E * w**4 / 12, rho * w * w
    mid = (beam.point_modes((L / 2, 0.0)) @ res.q[:, 6:8].T)[1]
    # Quasi-static estimate: the rigid-body inertia load of the rod is linear along it, from
    # −ρA a_n at the crank pin to −ρA a_n at the slider; each triangle bends a pinned beam by
    # 5 q L⁴ / (768 EI) at midspan.
    phi = res.q[:, 5]
    n = np.stack([-np.sin(phi), np.cos(phi)], axis=1)
    a_pin = np.gradient(res.point_velocity("crank", (0.075, 0.0)), res.t, axis=0)
    a_slider = np.gradient(res.point_velocity("slider"), res.t, axis=0)
    q_ends = -rhoA * (np.sum(a_pin * n, axis=1) + np.sum(a_slider * n, axis=1))
    static = 5 * L**4 * q_ends / (768 * EI)
    last = res.t >= 3 * rev
    peak = np.max(np.abs(static[last]))
    assert 1.2e-3 < peak < 2e-3                               # ~1.55 mm
    assert np.max(np.abs(mid[last] - static[last])) < 0.1 * peak
    # Bounded: no growth from one revolution to the next.
    first = np.max(np.abs(mid[res.t < rev]))
    assert np.max(np.abs(mid[last])) < 1.5 * first
    assert np.max(np.abs(res.energy_drift)) < 1e-4           # modal damping's work included


def test_undamped_slider_crank_scene_runs_with_bounded_deflection():
    res = ms.load_scene(SCENES / "flexible_slider_crank.toml").simulate()
    assert res.success
    mid = res.point("rod", (0.15, 0.0))
    chord = 0.5 * (res.point("rod", (0.0, 0.0)) + res.point("rod", (0.3, 0.0)))
    deflection = np.linalg.norm(mid - chord, axis=1)
    assert 1e-3 < deflection.max() < 4e-3      # about 1.3× the 1.55 mm quasi-static peak
    assert np.max(np.abs(res.energy_drift)) < 1e-4
    # The slider stays on its slide and the driver keeps the crank at 150 rad/s.
    assert np.max(np.abs(res.point("slider")[:, 1])) < 1e-9
    assert np.allclose(res.coordinate("crank.angle"), 150.0 * res.t, atol=1e-8)


def test_bad_beam_input_names_the_beam():
    kw = dict(length=1.0, youngs_modulus=117e9, density=8910.0, area=1e-4,
              second_moment=1e-8 / 12, n_elements=4, n_modes=2)
    with pytest.raises(ModelError, match="beam 'coupler'.*youngs_modulus.*positive"):
        ms.FlexibleBeam("coupler", **{**kw, "youngs_modulus": 0.0})
    with pytest.raises(ModelError, match="beam 'coupler'.*density.*positive"):
        ms.FlexibleBeam("coupler", **{**kw, "density": -1.0})
    with pytest.raises(ModelError, match="beam 'coupler'.*n_modes.*between 1 and 12"):
        ms.FlexibleBeam("coupler", **{**kw, "n_modes": 13})
    with pytest.raises(ModelError, match="beam 'coupler'.*boundary"):
        ms.FlexibleBeam("coupler", **{**kw, "boundary": "hinged"})
    mech = ms.Mechanism("m")
    beam = mech.add(ms.FlexibleBeam("coupler", **kw))
    with pytest.raises(ModelError, match=r"joint 'J'.*\(0\.3, 0\).*not a node of beam "
                                         r"'coupler'.*every 0\.25 m"):
        ms.Revolute(mech.ground, beam, at=(0.3, 0.0), name="J")
    with pytest.raises(ModelError, match="not a node of beam 'coupler'"):
        ms.Revolute(mech.ground, beam, at=(0.5, 0.01), name="J")
    ms.Revolute(mech.ground, beam, at=(0.75, 0.0), name="J")          # a node: fine
    with pytest.raises(ModelError, match="'push'.*not a node of beam 'coupler'"):
        mech.add(ms.Force(beam, (0.0, -1.0), at=(0.6, 0.0), name="push"))
    with pytest.raises(ModelError, match="not a node of beam 'coupler'"):
        mech.add(ms.Spring(mech.ground, beam, at_a=(0, 1), at_b=(0.1, 0.0), stiffness=1.0))


def test_loads_at_nodes_do_work_through_the_modes():
    """A beam pinned at its start and hanging a spring and a force off its nodes conserves
    energy with the force's work: the point-force mapping onto η is consistent."""
    mech = ms.Mechanism("pinned beam", gravity=(0.0, -9.81))
    beam = mech.add(ms.FlexibleBeam("arm", length=0.5, youngs_modulus=2e9, density=1200.0,
                                    area=1e-4, second_moment=1e-8 / 12, n_elements=4,
                                    n_modes=2, boundary="clamped-free"))
    mech.add(ms.Revolute(mech.ground, beam, at=(0.0, 0.0), name="pin"))
    mech.add(ms.Spring(mech.ground, beam, at_a=(0.5, 0.3), at_b=(0.5, 0.0), stiffness=50.0,
                       rest_length=0.2, damping=0.0, name="spring"))
    mech.add(ms.Force(beam, lambda t: (0.0, -2.0 * math.sin(20 * t)), at=(0.25, 0.0),
                      name="shaker"))
    # Samples 10 ms apart, half a period of the second mode (329 rad/s): the work is
    # integrated along the steps, not over the samples (Simpson over them read 8e-4 at
    # 2 ms apart).
    res = mech.simulate(0.25, rtol=1e-8, atol=1e-10, output_step=1e-2)
    assert res.success
    assert np.max(np.abs(res.energy.work)) > 0.01
    assert np.max(np.abs(res.energy_drift)) < 1e-8          # measured 1.1e-10
    assert res.energy.strain.max() > 1e-5


def test_export_writes_a_time_series_paraview_reads(tmp_path, monkeypatch):
    """The XDMF series (its data in HDF5 beside it, single precision) and the VTU series
    with its .pvd collection reload through meshio with the result's point data."""
    meshio = pytest.importorskip("meshio")
    mech = ms.examples.flexible_four_bar()
    res = mech.simulate(0.05, rtol=1e-7, atol=1e-9, output_step=0.01)
    monkeypatch.chdir(tmp_path / "..")           # the data must land beside the file
    path = res.export(tmp_path / "four_bar.xdmf")
    assert (tmp_path / "four_bar.h5").exists() and not (tmp_path / ".." / "four_bar.h5").exists()
    with meshio.xdmf.TimeSeriesReader(path) as reader:
        points, cells = reader.read_points_cells()
        assert reader.num_steps == len(res.t)
        t, data, cell_data = reader.read_data(reader.num_steps - 1)
    assert t == pytest.approx(0.05)
    assert cells[0].type == "line"
    # crank: 2 points + CoM; coupler: 41 points along 10 elements; rocker: 3 points
    assert len(points) == 3 + 41 + 3
    names = (tmp_path / "four_bar_body_names.txt").read_text().split()
    assert names == ["0", "crank", "1", "coupler", "2", "rocker"]
    # The coupler's midpoint (point 3 + 20) moved as the result says.
    moved = res.point("coupler", (0.5, 0.0))
    assert np.allclose(points[23, :2], moved[0], atol=1e-12)
    single = np.finfo(np.float32).eps
    np.testing.assert_allclose(data["displacement"][23, :2], moved[-1] - moved[0],
                               rtol=single, atol=single * np.max(np.abs(moved[-1] - moved[0])))
    elastic = res.point("coupler", (0.5, 0.0)) - frame_point(res.q, 3, (0.5, 0.0))
    np.testing.assert_allclose(data["elastic_displacement"][23, :2], elastic[-1], rtol=single,
                               atol=single * np.max(np.abs(elastic[-1])))
    np.testing.assert_allclose(data["eta1"][3:44], res.coordinate("coupler.eta1")[-1],
                               rtol=single)
    assert np.all(data["eta1"][:3] == 0.0)
    assert set(np.unique(cell_data["body"])) == {0, 1, 2}
    # Other meshio formats: one file per output time, and for VTU a .pvd collection.
    res.export(tmp_path / "series" / "fb.vtu")
    files = sorted((tmp_path / "series").glob("fb_*.vtu"))
    assert len(files) == len(res.t)
    last = meshio.read(files[-1])
    assert np.allclose(last.points[23, :2], moved[-1], atol=1e-12)
    collection = (tmp_path / "series" / "fb.pvd").read_text()
    assert collection.count("<DataSet") == len(res.t) and f'file="{files[-1].name}"' in collection
    # Every other sample, and the last.
    res.export(tmp_path / "half.xdmf", every=2)
    with meshio.xdmf.TimeSeriesReader(tmp_path / "half.xdmf") as reader:
        reader.read_points_cells()
        assert [reader.read_data(k)[0] for k in range(reader.num_steps)] == \
            pytest.approx(res.t[[0, 2, 4, 5]])
    with pytest.raises(ValueError, match="`every`"):
        res.export(tmp_path / "bad.xdmf", every=0)


def test_export_without_h5py_writes_inline_xml_and_says_so(tmp_path, monkeypatch):
    import sys
    monkeypatch.setitem(sys.modules, "h5py", None)             # as if not installed
    res = ms.examples.four_bar().simulate(0.02, output_step=0.01)
    with pytest.warns(UserWarning, match="inline as XML"):
        path = res.export(tmp_path / "x.xdmf")
    assert not (tmp_path / "x.h5").exists() and "<DataItem" in path.read_text()


def test_ss_newmark_on_the_flexible_four_bar_is_second_order():
    """Seed 000's average-velocity rule on the elastic four-bar (before its first singular
    passage, which the LU-partitioned "ss-newmark" does not pass): halving h quarters the
    error of the coupler's midpoint and of its first modal coordinate."""
    mech = ms.examples.flexible_four_bar()
    ref = mech.simulate(0.15, method="projection", rtol=1e-11, atol=1e-13, max_step=5e-4,
                        output_step=1e-3)
    errors = []
    for h in (1e-3, 5e-4):
        res = mech.simulate(0.15, method="ss-newmark", h=h, output_step=1e-3)
        assert res.success
        errors.append((np.max(np.abs(res.point("coupler", (0.5, 0.0))
                                     - ref.point("coupler", (0.5, 0.0)))),
                       np.max(np.abs(res.coordinate("coupler.eta1")
                                     - ref.coordinate("coupler.eta1")))))
    for coarse, fine in zip(*errors):
        assert coarse / fine == pytest.approx(4.0, rel=0.1)
    assert errors[1][1] < 0.01 * np.max(np.abs(ref.coordinate("coupler.eta1")))


def test_driven_spin_up_of_a_cantilever_balances_driver_work():
    """A clamped–free arm spun up by a driven hub (Kane's spin-up profile): the driver's
    work λᵀΦ_t equals the energy the arm gains (kinetic + strain), and the arm lags by a
    small elastic deflection at the tip."""
    mech = ms.Mechanism("spin-up arm", gravity=(0.0, 0.0))
    arm = mech.add(ms.FlexibleBeam("arm", length=1.0, youngs_modulus=7e10, density=2700.0,
                                   area=4e-4, second_moment=2e-9, n_elements=6, n_modes=2,
                                   boundary="clamped-free"))
    hub = mech.add(ms.Revolute(mech.ground, arm, at=(0.0, 0.0), name="hub"))
    mech.add(ms.Driver(hub, "(6/15)*(t**2/2 + (15/(2*pi))**2*(cos(2*pi*t/15) - 1))"))
    res = mech.simulate(3.0, rtol=1e-8, atol=1e-10, output_step=0.01)
    assert res.success
    assert res.energy.work[-1] > 0.01
    assert np.max(np.abs(res.energy_drift)) < 1e-6
    tip = (arm.point_modes((1.0, 0.0)) @ res.q[:, 3:5].T)[1]
    assert 1e-5 < np.max(np.abs(tip)) < 1e-3           # lags the hub: deflection opposite
    assert np.mean(tip[res.t > 0.5]) < 0.0             # to the (positive) spin-up


def test_prismatic_joint_at_a_beam_node():
    """A free–free beam held at its middle node by a rail (no rotation there) slides at its
    initial speed and sags under gravity, energy conserved."""
    mech = ms.Mechanism("sliding beam", gravity=(0.0, -9.81))
    beam = mech.add(ms.FlexibleBeam("beam", length=1.0, youngs_modulus=2e9, density=1200.0,
                                    area=1e-4, second_moment=1e-8 / 12, n_elements=4,
                                    n_modes=2, boundary="free-free", velocity=(0.5, 0.0)))
    mech.add(ms.Prismatic(mech.ground, beam, axis=(1.0, 0.0), at=(0.5, 0.0), name="rail"))
    res = mech.simulate(0.5, rtol=1e-8, atol=1e-10, output_step=0.005)
    assert res.success
    mid = res.point(beam, (0.5, 0.0))
    np.testing.assert_allclose(mid[:, 0], 0.5 + 0.5 * res.t, atol=1e-8)
    assert np.max(np.abs(mid[:, 1])) < 1e-10
    assert res.energy.strain.max() > 1e-3
    assert np.max(np.abs(res.energy_drift)) < 1e-6
