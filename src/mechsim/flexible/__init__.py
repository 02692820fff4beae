"""Flexible beam bodies with modal coordinates (floating frame of reference).

So far: the finite-element beam and its modal basis (`beam_modes`). The `FlexibleBeam`
body that couples them to the mechanism's equations is the next step of its issue.
"""

from .modes import BOUNDARIES, ModalBasis, beam_fe_matrices, beam_modes

__all__ = ["BOUNDARIES", "ModalBasis", "beam_fe_matrices", "beam_modes"]
