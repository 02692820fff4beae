"""The average-velocity rule of seed 000 for nonlinear ODEs: the implicit trapezoidal rule
at a fixed step, solved by Newton each step.

    y_{n+1} = y_n + h/2 (f(t_n, y_n) + f(t_{n+1}, y_{n+1}))

On a linear system it is exactly the state-space Newmark method (eq. 8); it is A-stable, so a
stiff mechanism (flexible modes) can be stepped far beyond an explicit method's limit. The
Newton matrix I − h/2 ∂f/∂y is formed by finite differences once per step from the converged
state of the previous one and reused (a modified Newton); if Newton stalls it is refreshed,
and if it still fails the step is halved (up to h/64) for that step only.
"""

from __future__ import annotations

import numpy as np
from scipy.integrate import DenseOutput, OdeSolver


class Trapezoidal(OdeSolver):
    """Fixed-step implicit trapezoidal rule (scipy `OdeSolver` interface).

    `first_step` (or `h`) is the step; the last step is shortened to land on t_bound. Newton
    converges when the scaled correction ‖Δy / (atol + rtol |y|)‖ < 0.01.
    """
    fixed_step = True          # its step is given (`h`), not chosen

    def __init__(self, fun, t0, y0, t_bound, max_step=np.inf, rtol=1e-6, atol=1e-8,
                 first_step=None, h=None, max_newton=8, vectorized=False, **extraneous):
        super().__init__(fun, t0, y0, t_bound, vectorized, support_complex=False)
        step = h if h is not None else first_step
        if step is None or not step > 0:
            raise ValueError("the trapezoidal (ss-newmark) integrator needs a fixed step `h`")
        self.h = float(min(step, max_step))
        self.max_step = max_step
        self.rtol, self.atol = rtol, atol
        self.max_newton = max_newton
        self.f = self.fun(self.t, self.y)
        self.n_rejected = 0
        self.nlu = 0
        self.njev = 0
        self._iter = None
        self._old = None

    def _newton_matrix(self, t, y, f, h):
        n = y.size
        J = np.empty((n, n))
        for j in range(n):
            d = 1e-7 * max(1.0, abs(y[j]))
            yj = y.copy()
            yj[j] += d
            J[:, j] = (self.fun(t, yj) - f) / d
        self.njev += 1
        self.nlu += 1
        return np.linalg.inv(np.eye(n) - 0.5 * h * J)

    def _step_impl(self):
        t, y, f = self.t, self.y, self.f
        h = min(self.h, self.max_step, self.t_bound - t)
        # Where Newton fails at the nominal step (a singular configuration, where the reduced
        # equations change fast), the step is halved up to six times for this step only.
        for k in range(7):
            hk = h / 2**k
            if self._newton_step(t, y, f, hk):
                return True, None
        return False, (f"Newton did not converge in the trapezoidal step at t = {t:.9g}, "
                       f"not even at h/64 = {h / 64:.3g}")

    def _newton_step(self, t, y, f, h) -> bool:
        if self._iter is None or self._iter[1] != h:
            self._iter = (self._newton_matrix(t, y, f, h), h)
        for attempt in range(2):
            Jinv = self._iter[0]
            Y = y + h * f                                  # explicit predictor
            for _ in range(self.max_newton):
                FY = self.fun(t + h, Y)
                G = Y - y - 0.5 * h * (f + FY)
                dY = -(Jinv @ G)
                Y = Y + dY
                scale = self.atol + self.rtol * np.abs(Y)
                if not np.all(np.isfinite(Y)):
                    break
                if np.sqrt(np.mean((dY / scale) ** 2)) < 0.01:
                    f_new = self.fun(t + h, Y)
                    if not np.all(np.isfinite(f_new)):
                        break
                    self._old = (t, y, f, h)
                    self.t, self.y, self.f = t + h, Y, f_new
                    return True
            self.n_rejected += 1
            if attempt == 0:
                self._iter = (self._newton_matrix(t, y, f, h), h)   # refresh, try once more
        return False

    def _dense_output_impl(self):
        t, y, f, h = self._old
        return _Hermite(t, self.t, y, f, self.y, self.f)


class _Hermite(DenseOutput):
    """Cubic Hermite interpolant between the step's ends (third order, matching the rule)."""

    def __init__(self, t0, t1, y0, f0, y1, f1):
        super().__init__(t0, t1)
        self.y0, self.f0, self.y1, self.f1, self.hh = y0, f0, y1, f1, t1 - t0

    def _call_impl(self, t):
        s = (np.atleast_1d(t) - self.t_old) / self.hh
        h00, h10 = 2 * s**3 - 3 * s**2 + 1, s**3 - 2 * s**2 + s
        h01, h11 = -2 * s**3 + 3 * s**2, s**3 - s**2
        out = (np.outer(self.y0, h00) + self.hh * np.outer(self.f0, h10)
               + np.outer(self.y1, h01) + self.hh * np.outer(self.f1, h11))
        return out[:, 0] if np.ndim(t) == 0 else out
