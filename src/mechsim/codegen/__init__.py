"""Generated model modules and their compiled twins, cached on disk by model structure.

A mechanism's model is written from its joint types' kernels (`mechsim.assembly.unrolled`;
sympy derives a kernel once per machine); `load_model(structure, build)` returns a module
with the functions

    phi(q, t, p)             -> (m,)
    phi_q(q, t, p)           -> (m, n)
    phi_t(q, t, p)           -> (m,)
    gamma(q, v, t, p)        -> (m,)
    position_terms(q, t, p)  -> (phi, phi_q)
    terms(q, v, t, p)        -> (phi, phi_q, phi_t, gamma)
    dynamics_terms(q, v, t, p) -> (phi_q, gamma)

where `q`, `v` are float arrays and `p` a sequence of parameter values. On a cache hit the
module is imported from the cache directory and sympy is never imported. A large model's
functions run as compiled C where a compiler is available (`mechsim.codegen.compiled`).
"""

from .cache import CODEGEN_VERSION, cache_dir, cached_model, load_model, structure_key

__all__ = ["CODEGEN_VERSION", "cache_dir", "cached_model", "load_model", "structure_key"]
