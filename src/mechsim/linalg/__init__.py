"""Linear algebra the solvers share, below every other layer: dense LAPACK calls without
numpy's wrappers (`dense`), sparse Jacobians of fixed pattern (`sparse`), the banded Schur
complement of long chains (`banded`) and the simplified Newton iteration (`newton`)."""
