"""Exact sensitivities of a free motion, through singular passages, and what they cost.

The double four-bar (IFToMM A02: three cranks, two couplers, all 1 m, 1 kg) falls through
a singular configuration every time its cranks pass horizontal. On its parallelogram
branch every crank turns by the same angle θ with M_eff θ̈ = −K cos θ, so ∂θ/∂L, the
sensitivity of the crank angle to the links' length, solves the one-degree-of-freedom
variational equation exactly (scipy at 1e-13). `simulate(..., sensitivities=["L"])`
carries ∂q/∂L and ∂v/∂L with the motion (the passage bridge carries them over each
passage); the script prints its error against that reference and its time against the
plain run's, at three tolerances, and the cost of one and two parameters on a free
slider-crank, rigid and with its rod a flexible beam, of one on the flexible four-bar, and
of up to 21 on the 10-window chain (the forward method's cost per parameter: whether an
adjoint method would pay).

    python examples/motion_sensitivity.py
"""

from __future__ import annotations

import math
import time

import numpy as np
from scipy.integrate import solve_ivp

import mechsim as ms
from mechsim.examples import double_four_bar, parallelogram_constants

T_END = 10.0


def branch_rate(length):
    m_eff, k = parallelogram_constants(2, length, 1.0, 9.81)
    return k / m_eff


def exact(t):
    """∂θ/∂L on the branch θ̈ = −c(L) cos θ from θ = π/2, θ̇ = −1."""
    c, h = branch_rate(1.0), 1e-6
    dc = (branch_rate(1.0 + h) - branch_rate(1.0 - h)) / (2 * h)

    def f(_, y):
        th, w, s, sw = y
        return [w, -c * math.cos(th), sw, c * math.sin(th) * s - dc * math.cos(th)]
    return solve_ivp(f, (0.0, t[-1]), [math.pi / 2, -1.0, 0.0, 0.0], method="DOP853",
                     rtol=1e-13, atol=1e-14, t_eval=t).y[2]


def best_of(run, repeat=3):
    times, out = [], None
    for _ in range(repeat):
        began = time.perf_counter()
        out = run()
        times.append(time.perf_counter() - began)
    return out, min(times)


def double_four_bar_table():
    print(f"double four-bar, {T_END:g} s, ∂θ/∂L against the branch's variational equation")
    print(f"{'rtol':>6} {'passages':>8} {'rel. error':>11} {'plain [s]':>10} "
          f"{'with ∂/∂L [s]':>14} {'ratio':>6}")
    for rtol in (1e-6, 1e-8, 1e-10):
        plain, t_plain = best_of(lambda: double_four_bar().simulate(
            T_END, output_step=0.01, rtol=rtol))
        mech = double_four_bar(length=ms.Parameter("L", 1.0))
        res, t_sens = best_of(lambda: mech.simulate(T_END, output_step=0.01, rtol=rtol,
                                                    sensitivities=["L"]))
        col = res.coordinate_names.index("crank1.angle")
        reference = exact(res.t)
        error = np.max(np.abs(res.sensitivity("L")[:, col] - reference)) / \
            np.max(np.abs(reference))
        print(f"{rtol:6.0e} {len(res.singular_passages):8d} {error:11.2e} {t_plain:10.3f} "
              f"{t_sens:14.3f} {t_sens / t_plain:6.2f}")


def cost_table(title, build, values, t_end, output_step, rtol=1e-8):
    """The time of `build(**Parameters)` simulated with the sensitivities of its first one,
    then two, of `values` (name: value), against the plain run of `build()`."""
    print(f"{title}, {t_end:g} s, rtol {rtol:g}")
    names = list(values)
    plain, t_plain = best_of(lambda: build().simulate(t_end, output_step=output_step,
                                                      rtol=rtol))
    for k in range(1, len(names) + 1):
        mech = build(**{n: ms.Parameter(n, values[n]) for n in names[:k]})
        _, t_sens = best_of(lambda: mech.simulate(t_end, output_step=output_step, rtol=rtol,
                                                  sensitivities=names[:k]))
        print(f"  {k} parameter(s): {t_sens:.3f} s against {t_plain:.3f} s plain "
              f"({t_sens / t_plain:.2f}×)")


def flexible_slider_crank(**values):
    return ms.examples.slider_crank(flexible=True, **values)


def flexible_four_bar(**values):
    return ms.examples.flexible_four_bar(**values)


def many_parameters_table(n=10, counts=(1, 5, 10, 21)):
    """The forward sensitivities' cost as the parameters grow: the N-window chain's 2N + 1
    link masses, the first K of them Parameters (the columns are solved together)."""
    names = [f"m{i}" for i in range(2 * n + 1)]
    print(f"{n}-window chain ({6 * n + 3} coordinates), 3 s, rtol 1e-8: "
          "K of its link masses as Parameters")
    _, t_plain = best_of(lambda: double_four_bar(n).simulate(3.0, output_step=0.01,
                                                            rtol=1e-8))
    for k in counts:
        mech = double_four_bar(n, mass=[ms.Parameter(x, 1.0) if i < k else 1.0
                                        for i, x in enumerate(names)])
        mech.simulate(0.1, sensitivities=names[:k])          # builds its derivatives
        _, t_sens = best_of(lambda: mech.simulate(3.0, output_step=0.01, rtol=1e-8,
                                                  sensitivities=names[:k]))
        print(f"  {k:2d} parameter(s): {t_sens:.3f} s against {t_plain:.3f} s plain "
              f"({t_sens / t_plain:.2f}×)")


def main():
    double_four_bar().simulate(0.1)                  # builds and caches the models
    double_four_bar(length=ms.Parameter("L", 1.0)).simulate(0.1, sensitivities=["L"])
    double_four_bar_table()
    masses = {"crank_mass": 0.36, "slider_mass": 0.075552}
    cost_table("free slider-crank (crank 0.15 m, rod 0.3 m, 150 rad/s)",
               ms.examples.slider_crank, masses, 0.2, 1e-3)
    cost_table("the same with the rod a steel beam of two modes", flexible_slider_crank,
               masses, 0.03, 1e-3)
    cost_table("flexible four-bar (copper coupler, two modes), through its first passage",
               flexible_four_bar, {"crank_mass": 1.0}, 0.3, 0.01)
    many_parameters_table()


if __name__ == "__main__":
    main()
