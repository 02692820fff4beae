"""Generated code for the mass matrix and forces of a modal beam with k modes.

The formulas of `mechsim.flexible.invariants` are written once in sympy for k modes and
printed to plain `math` code with shared subexpressions (the same code generator as the
constraints), cached on disk under the key ("beam kernel", k, version). Every beam with k
modes, in every scene, uses the same kernel: its invariants are the kernel's parameters.

Kernel functions, with `_q`, `_v` the beam's block of coordinates and velocities
(x, y, θ, η₁ … η_k) and `_p` from `BeamInvariants.kernel_parameters(gravity)`:

    mass_block(_q, _p)          -> (3 + k, 3 + k)
    forces(_q, _v, _p)          -> (3 + k,)  quadratic-velocity, gravity, elastic, damping
    mass_action_q(_q, _a, _p)   -> (3 + k, 3 + k)  ∂(M(q) a)/∂q
    force_jacobians(_q, _v, _p) -> (∂Q/∂q, ∂Q/∂v), each (3 + k, 3 + k)

The last two are what a simulation's sensitivities differentiate the beam's equations of
motion with (`mechsim.problem.sensitivity.MotionEquations`).
"""

from __future__ import annotations

KERNEL_VERSION = 2


def parameter_count(k: int) -> int:
    """Length of the kernel's parameter vector for k modes."""
    return 1 + 2 + 2 * k + 1 + k + k + k * k + k + k + 2


def _source(k: int, key: str) -> str:
    import sympy as sp

    from ..codegen.printer import kernel_source

    q = sp.symbols(f"x y th eta1:{k + 1}", real=True)
    v = sp.symbols(f"xd yd w e1:{k + 1}", real=True)
    acc = sp.symbols(f"xdd ydd wd ed1:{k + 1}", real=True)
    th, eta = q[2], sp.Matrix(q[3:])
    w, e = v[2], sp.Matrix(v[3:])
    p = list(sp.symbols(f"p0:{parameter_count(k)}", real=True))
    it = iter(p)
    take = lambda n: sp.Matrix([next(it) for _ in range(n)])          # noqa: E731
    mass = next(it)
    s0 = take(2)
    s_eta = take(2 * k).reshape(2, k)
    inertia0 = next(it)
    c = take(k)
    b0 = take(k)
    B = take(k * k).reshape(k, k)
    stiff, damp = take(k), take(k)
    g = take(2)

    A = sp.Matrix([[sp.cos(th), -sp.sin(th)], [sp.sin(th), sp.cos(th)]])
    Jt = sp.Matrix([[0, -1], [1, 0]])
    sbar = s0 + s_eta * eta
    ajs = A * Jt * sbar
    ase = A * s_eta
    M = sp.zeros(3 + k, 3 + k)
    M[0, 0] = M[1, 1] = mass
    M[:2, 2] = ajs
    M[2, :2] = ajs.T
    M[:2, 3:] = ase
    M[3:, :2] = ase.T
    M[2, 2] = inertia0 + 2 * (c.T * eta)[0] + (eta.T * eta)[0]
    row = b0.T + eta.T * B
    M[2, 3:] = row
    M[3:, 2] = row.T
    M[3:, 3:] = sp.eye(k)

    ce = c + eta
    Q = sp.zeros(3 + k, 1)
    Q[:2, 0] = A * (sbar * w**2 - 2 * w * Jt * s_eta * e) + mass * g
    Q[2] = -2 * w * (ce.T * e)[0] + (ajs.T * g)[0]
    Q[3:, 0] = w**2 * ce + 2 * w * B * e + ase.T * g \
        - sp.Matrix([stiff[i] * eta[i] + damp[i] * e[i] for i in range(k)])
    return kernel_source(q, v, p, [
        ("mass_block", ("_q", "_p"), [M], "Mass matrix of the beam's block."),
        ("forces", ("_q", "_v", "_p"), [Q],
         "Quadratic-velocity, gravity, elastic and modal damping forces of the block."),
        ("mass_action_q", ("_q", "_a", "_p"), [(M * sp.Matrix(acc)).jacobian(q)],
         "∂(M(q) a)/∂q of the block."),
        ("force_jacobians", ("_q", "_v", "_p"), [Q.jacobian(q), Q.jacobian(v)],
         "(∂Q/∂q, ∂Q/∂v) of the block's forces."),
    ], key, a=acc)


def load_kernel(k: int):
    """The compiled kernel module for k modes (generated once, then from the disk cache)."""
    from ..codegen import load_model, structure_key
    structure = {"beam kernel": k, "version": KERNEL_VERSION}
    module, _ = load_model(structure, lambda: _source(k, structure_key(structure)))
    return module
