"""Flexible beam bodies with modal coordinates (floating frame of reference).

The finite-element beam and its modal basis (`beam_modes`), the inertia invariants of the
floating frame (`invariants`) and the generated kernel of a beam's mass block and forces
(`kernel`). The body users add is `mechsim.FlexibleBeam` (`mechsim.model.flexible_beam`).
"""

from .modes import BOUNDARIES, ModalBasis, beam_fe_matrices, beam_modes

__all__ = ["BOUNDARIES", "ModalBasis", "beam_fe_matrices", "beam_modes"]
