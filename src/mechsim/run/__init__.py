"""The run: `solver.simulate` checks a run's settings, chooses its formulation and hands it
to `loop.Run`, which owns the integration loop, the output samples (`samples`), the step
bounds, restarts, passage bridging, events and the status; `runaway` watches for motion
that runs away. It stands above the formulations and integrators it drives and below the
engineering analyses that call it."""
