"""The constraints' derivatives in the model's parameters, for exact sensitivities.

A driven mechanism's motion satisfies the constraints at three levels,

    R0 = Φ(q, t; p) = 0
    R1 = Φ_q v + Φ_t = 0
    R2 = Φ_q a − γ(q, v, t; p) = 0,

and differentiating them in a design parameter k (p = p(k), `mechsim.model.parameters`)
gives, by the implicit function theorem, one triangular system with Φ_q on its diagonal
(∂R1/∂v = ∂R2/∂a = Φ_q):

    Φ_q q_k = −R0_p p_k
    Φ_q v_k = −(R1_q q_k + R1_p p_k)
    Φ_q a_k = −(R2_q q_k + R2_v v_k + R2_p p_k).

The multipliers of M q̈ + Φ_qᵀ λ = Q follow from the same sensitivities, with
R3 = Φ_qᵀ λ differentiated in q and p (λ held):

    Φ_qᵀ λ_k = Q_q q_k + Q_v v_k + Q_k − M_k q̈ − M q̈_k − R3_q q_k − R3_p p_k.

sympy differentiates R0, R1, R2 and R3 here; `mechsim.codegen.printer
.sensitivity_source` prints them as two functions.
"""

from __future__ import annotations

import sympy as sp

from .constraints import SymbolicSystem


class SensitivitySystem:
    """R0, R1, R2, R3 of a `SymbolicSystem` and the symbols they are differentiated in
    (`q`, `v`, `a` the accelerations, `l` the multipliers, `t`, `p`)."""

    def __init__(self, system: SymbolicSystem):
        self.system = system
        self.q, self.v, self.t, self.p, self.phi = (system.q, system.v, system.t, system.p,
                                                    system.phi)
        self.a = [sp.Symbol(f"{x.name}_ddot", real=True) for x in system.q]
        self.l = [sp.Symbol(f"lambda{i}", real=True) for i in range(system.phi.rows)]

    def outputs(self) -> list[sp.Matrix]:
        """[R0_p, R1_q, R1_p, R2_q, R2_v, R2_p]."""
        s = self.system
        q, v, a, p = (sp.Matrix(x) for x in (self.q, self.v, self.a, self.p))
        r0 = s.phi
        r1 = s.phi_q * v + s.phi_t
        r2 = s.phi_q * a - s.gamma

        def d(r, x):
            return r.jacobian(x) if len(x) else sp.zeros(r.rows, 0)

        return [d(r0, p), d(r1, q), d(r1, p), d(r2, q), d(r2, v), d(r2, p)]

    def multiplier_outputs(self) -> list[sp.Matrix]:
        """[R3_q, R3_p] of R3 = Φ_qᵀ λ."""
        s = self.system
        r3 = s.phi_q.T * sp.Matrix(self.l) if self.l else sp.zeros(len(self.q), 1)
        p = sp.Matrix(self.p)
        return [r3.jacobian(sp.Matrix(self.q)),
                r3.jacobian(p) if len(self.p) else sp.zeros(r3.rows, 0)]
