"""Blajer's projection method (seed 001, eqs. 7–13), in the mass metric.

With J̃ = Φ_q M^{-1/2} = U Σ Vᵀ, the right inverse I_R = M^{-1/2} J̃⁺ and the null-space
projector P_T = I − J̃⁺J̃ give the constrained accelerations with the constraint forces
eliminated:

    q̈ = M^{-1/2} [ J̃⁺ γ + P_T M^{-1/2} Q ]

(the mass-orthogonal complement makes Blajer's M₁₁ = P_Tᵀ M P_T the identity on the null
space, so eq. 10 needs no further solve). The SVD is recomputed at every evaluation, so the
null space is tracked every step. In the accelerations, singular values below
`rcond · σ_max` are dropped (`regularization="truncate"`; "damp" uses σ/(σ² + μ²) instead):
inside that narrow band the nearly-lost constraint direction is held by the position and
velocity projections, which use the exact pseudo-inverse, instead of by J̃⁺γ, whose
1/σ_min would amplify any inconsistency of the state.

Inside the band, where the motion crosses the singular configuration, the lost direction's
component uᵀγ/σ (0/0 on the configuration) is taken from the slopes of uᵀγ and uᵀJ̃w
across it (`_across`); dropping it was off by 5 % in q̈ on the double four-bar and made the
step size collapse (to 7e-8 s) wherever a step landed within the band: 99 of 213 steps at
rtol 1e-8, now 130 steps in all and 0.54 s instead of 0.87 s, error 7.6e-8.

Measured (rtol 1e-8; crank error over the seed's parallelogram 2 s / the double four-bar
10 s, DOP853): rcond 1e-8 leaves the branch at the second passage; truncation at 1e-4 with
exact projections gives 2.4e-11 / 2.4e-7 and takes the 40-window chain through its first
passage in 8 steps; damping (rcond 1e-6) gives 2.9e-10 / 2.5e-4; truncated projections made
the chain collapse to microsecond steps. Positions are corrected by Newton on [Φ_q; P_Tᵀ] Δq = [−Φ; 0] — the
minimum-norm (row-space) correction −I_R Φ — whenever ‖Φ‖ exceeds `projection_tol`.
"""

from __future__ import annotations

import numpy as np

from .full import FullCoordinates


class Projection(FullCoordinates):
    name = "projection"
    default_integrator = "DOP853"
    options = {**FullCoordinates.options, "rcond": 1e-4, "exact_projection": True,
               "regularization": "truncate"}

    def __init__(self, problem, rtol, atol, **options):
        if options.get("projection_tol") is None:
            # Near a singular configuration any inconsistency of (q, v) enters γ and is
            # amplified by 1/σ_min in J̃⁺γ: keep the state on the manifold to round-off.
            # (The integrators keep ‖Φ‖ that small on their own most of the time, so this
            # costs a handful of restarts per run, measured on the seed four-bar.)
            options["projection_tol"] = max(1e-13, 1e-3 * atol)
        super().__init__(problem, rtol, atol, **options)

    @staticmethod
    def _pinv_exact(Jt):
        """(V_r, Σ_r⁻¹ U_rᵀ) of the mass-scaled J̃, truncated only at round-off: for the
        projections, which must restore consistency in every direction the constraints
        still control. The singular values come third."""
        U, sig, Vt = np.linalg.svd(Jt, full_matrices=False)
        r = int(np.sum(sig > 1e-12 * sig[0])) if sig.size else 0
        return Vt[:r].T, (U[:, :r] / sig[:r]).T, sig

    def _pinv(self, Jt):
        """(V, Σ⁺ Uᵀ) of J̃ = J M^{-1/2} = J L⁻ᵀ: truncated below rcond·σ_max, or damped
        (1/σ becomes σ/(σ² + μ²), μ = rcond·σ_max), which keeps q̈ continuous as σ_min passes
        μ. The singular values come third."""
        U, sig, Vt = np.linalg.svd(Jt, full_matrices=False)
        self.problem.counters.factorizations += 1
        if not sig.size:
            return Vt.T, U.T, sig
        if self.regularization == "truncate":
            r = int(np.sum(sig > self.rcond * sig[0]))
            return Vt[:r].T, (U[:, :r] / sig[:r]).T, sig
        mu2 = (self.rcond * sig[0]) ** 2
        return Vt.T, (U * (sig / (sig**2 + mu2))).T, sig

    def accelerations(self, t, q, v):
        prob = self.problem
        _, J, _, gamma = prob.terms(q, v, t)
        f = prob.mass_factor(q)
        x = f.left(prob.forces(t, q, v))                   # L⁻¹ Q
        if J.shape[0]:
            Jt = f.cols(J)
            V, Ui, sig = self._pinv(Jt)
            x = x - V @ (V.T @ x) + V @ (Ui @ gamma)
            r = V.shape[1]
            # Dropped singular values at round-off level are redundant constraints (or,
            # with probability nil, a step landing exactly on the singularity): no crossing.
            if self.regularization == "truncate" and r < min(Jt.shape) and \
                    sig[r] > 1e-12 * sig[0]:
                x = self._across(t, q, v, Jt, f, x, r)
        return f.right(x)

    def _across(self, t, q, v, Jt, f, x, r):
        """Inside the truncation band the lost direction w (right singular vector of the
        dropped σ, left vector u) gets no constraint acceleration, a jump of a few percent in
        q̈ that collapses the step size where a step lands on the singular configuration.
        Where the motion crosses the singularity (the signed σ̃ = uᵀJ̃w changes sign along
        ±Δ v), the component uᵀγ/σ̃ — 0/0 on the configuration itself — is taken as the ratio
        of the changes of uᵀγ and σ̃ across it (their slopes: l'Hôpital along the motion)."""
        prob = self.problem
        speed = float(np.max(np.abs(v)))
        if speed == 0.0:
            return x
        # The singular vectors a hair along the motion, on whichever side is further from
        # the singular configuration: on it σ = 0 and the SVD's choice of w within the null
        # space is arbitrary; just off it, w is the direction being lost.
        d0 = 1e-7 / speed
        nudged = []
        for sign in (1.0, -1.0):
            J0 = f.cols(prob.phi_q(q + sign * d0 * v, t + sign * d0))
            nudged.append((np.linalg.svd(J0, full_matrices=False), sign * d0))
        (U, sig, Vt), d = max(nudged, key=lambda item: item[0][1][r])
        cut = self.rcond * sig[0]
        for k in range(r, min(Jt.shape)):
            u, w = U[:, k], Vt[k]
            slope = (sig[k] - u @ Jt @ w) / d
            delta = 3.0 * cut / abs(slope) if slope != 0.0 else np.inf
            if delta * speed > 1e-2:
                continue               # σ is not moving through zero (a redundant constraint)
            ends = []
            for sign in (1.0, -1.0):
                qs, ts = q + sign * delta * v, t + sign * delta
                _, Js, _, gs = prob.terms(qs, v, ts)
                ends.append((u @ (f.cols(Js) @ w), u @ gs))
            (s_plus, g_plus), (s_minus, g_minus) = ends
            if not (s_plus * s_minus < 0.0 and min(abs(s_plus), abs(s_minus)) > cut):
                continue                   # not a crossing (e.g. a redundant constraint)
            c = (g_plus - g_minus) / (s_plus - s_minus)
            x = x - w * (w @ x) + w * c
        return x

    def project_positions(self, q, t):
        prob = self.problem
        q = np.array(q, float)
        tol = 0.01 * self.projection_tol
        f = prob.mass_factor(q)
        for k in range(20):
            phi, J = prob.position_terms(q, t)
            err = float(np.max(np.abs(phi)))
            if err <= tol:
                break
            Jt = f.cols(J)
            V, Ui, _ = self._pinv_exact(Jt) if self.exact_projection else self._pinv(Jt)
            q -= f.right(V @ (Ui @ phi))
            prob.counters.projections += 1
        return q, k, err

    def project_velocities(self, q, v, t):
        prob = self.problem
        J = prob.phi_q(q, t)
        f = prob.mass_factor(q)
        Jt = f.cols(J)
        V, Ui, _ = self._pinv_exact(Jt) if self.exact_projection else self._pinv(Jt)
        return v - f.right(V @ (Ui @ (J @ v + prob.phi_t(q, t))))
