"""The records a run produces and every layer above reads: what happened at a singular
passage, a change of formulation, the work integrated with the motion, and how the run
ended. They import nothing of mechsim, so the formulations that make them and the results
that keep them need not know each other."""

from __future__ import annotations

import enum
from dataclasses import dataclass, field

import numpy as np


class Status(enum.StrEnum):
    """How a run ended. A member equals its text (`res.status == "success"`), is written as
    its text in saved results, and reads back from it (`Status("failed")`)."""
    SUCCESS = "success"          # reached t_end (its message may still warn)
    FAILED = "failed"            # stopped early: the result holds what was computed
    INTERRUPTED = "interrupted"  # stopped by the user (Ctrl-C): the result holds the samples
    PARTIAL = "partial"          # a streamed run that did not finish writing its files

    def __repr__(self):
        return repr(self.value)


@dataclass(frozen=True)
class SingularPassage:
    """A passage through a singular configuration of Φ_q: from `t_start` to `t_end` the
    normalized smallest singular value of Φ_q M^{-1/2} stayed below the monitor's threshold;
    its minimum `min_sigma` came at `t_min`; `joints` own the rows of its singular vector;
    `bridged`: crossed in one step by the passage bridge, `t_min` being its predicted
    singular instant; `time_sensitivity`: {Parameter: ∂t_min/∂Parameter} of a run with
    sensitivities (its instant's shift as the design changes, to first order)."""
    t_start: float
    t_end: float
    min_sigma: float
    joints: tuple[str, ...] = ()
    t_min: float | None = None
    bridged: bool = False
    time_sensitivity: dict = field(default_factory=dict)


@dataclass(frozen=True)
class Switch:
    """A change of formulation by the solver manager."""
    t: float
    from_method: str
    to_method: str
    reason: str


@dataclass(frozen=True)
class WorkRecord:
    """The work integrated with the motion (`mechsim.results.work`): `channels` as
    `NumericProblem.work_channels`, `values` W of each at the first len(values) output
    samples (shape (s, k); fewer than the samples where the integral stopped), `note` what
    limits it ("" where nothing does)."""
    channels: tuple[str, ...]
    values: np.ndarray
    note: str = ""
