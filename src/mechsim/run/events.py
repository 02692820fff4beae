"""Where a run's event value falls through zero inside a step (`mechsim.run.loop.Run`'s
events: a stop, a condition the user gave)."""

from __future__ import annotations

# An event value counts as crossed below −EVENT_SLACK (a stop left at its limit reads ±1e-16);
# its time, where it passes 0, is found to EVENT_XTOL (relative to t, at least 1 s).
EVENT_SLACK = 1e-12
EVENT_XTOL = 1e-13


def crossing(g, t_old, t_new, g_old) -> float:
    """The first time in [t_old, t_new] where g falls through 0, g(t_new) being below it:
    from t_old where g was above 0, else (a run begun at the stop it left) from where g
    peaks in the step, by Brent's method to `EVENT_XTOL`; t_old where g never rose above 0
    (the joint went straight into the stop)."""
    from scipy.optimize import brentq, minimize_scalar
    xtol = EVENT_XTOL * max(1.0, abs(t_new))
    start = t_old
    if not g_old > 0.0:
        peak = minimize_scalar(lambda t: -g(t), bounds=(t_old, t_new), method="bounded",
                               options={"xatol": xtol})
        if not -peak.fun > 0.0:
            return t_old
        start = float(peak.x)
    return float(brentq(g, start, t_new, xtol=xtol))
