"""The model-specific C the compiled engine links (`mechsim.codegen.engine`): the
declarations of the model's C twins it calls, and the straight-line code of its sums over
Φ_q's pattern for one model (`pattern_kernels`), compiled with the model's twins into the
model's library.

A sum over the pattern in the engine is an index loop (`layout.pair_pattern`'s arrays);
its kernel is that loop written out, statement by statement, in the same order and with
the same parentheses (compiled without contracted multiply-adds), so each number is the
loop's to the bit while the loop's index reads and bounds go (docs/design-notes.md has
the counts).
"""

from __future__ import annotations

from .layout import pair_pattern

# Bump with any change to the kernels' code: the libraries' names take it
# (`engine.library_path`).
KERNELS_VERSION = 1

# The model's C twins the engine calls (`mechsim.assembly.unrolled`: (Φ, Φ_q) and
# (Φ_q, γ) at one state share their terms, each output the bits of its own function's) and
# its pattern kernels, declared for the engine compiled on its own (`engine.engine_object`).
MODEL_DECLARATIONS = """void mechsim_phi(const double *q, double t, const double *p, double *o0);
void mechsim_phi_q(const double *q, double t, const double *p, double *o0);
void mechsim_phi_t(const double *q, double t, const double *p, double *o0);
void mechsim_gamma(const double *q, const double *v, double t, const double *p, double *o0);
void mechsim_position_terms(const double *q, double t, const double *p, double *o0,
                            double *o1);
void mechsim_dynamics_terms(const double *q, const double *v, double t, const double *p,
                            double *o0, double *o1);
void mechsim_kernel_products(const double *J, const double *w, double *S);
int mechsim_kernel_cholesky(const double *S, double *R);
void mechsim_kernel_solve(const double *R, const double *rdiag, double *b);
void mechsim_kernel_rows(const double *J, const double *x, double *out);
void mechsim_kernel_cols(const double *J, const double *y, double *out);

"""

# The kernels of a model without a pattern: never called (its `kernels` is 0).
_STUBS = """void mechsim_kernel_products(const double *J, const double *w, double *S) {}
int mechsim_kernel_cholesky(const double *S, double *R) { return 1; }
void mechsim_kernel_solve(const double *R, const double *rdiag, double *b) {}
void mechsim_kernel_rows(const double *J, const double *x, double *out) {}
void mechsim_kernel_cols(const double *J, const double *y, double *out) {}
"""


def pattern_kernels(model, m: int, n: int) -> str:
    """C of the engine's sums over Φ_q's pattern (`layout.pair_pattern`) for this model of m
    constraint rows and n coordinates: J W Jᵀ (`pair_products` with weights), its
    Cholesky factor (`pattern_cholesky`) and solves (`factor_solve`), J x and Jᵀ y
    (`row_times` and `col_times` of every row and column), each the index loop's sums in
    its order; stubs where the model has no pattern."""
    if not hasattr(model, "JACOBIAN_ROWS"):
        return _STUBS
    pat = {name: values.tolist() for name, values in pair_pattern(model, m, n).items()}

    def spans(name):
        start, items = pat[name + "_start"], pat[name + "_" + _ITEMS[name]]
        return [items[start[k]:start[k + 1]] for k in range(len(start) - 1)]

    out = ["void mechsim_kernel_products(const double *J, const double *w, double *S) {",
           f"  for (int a = 0; a < {m * m}; a++) S[a] = 0.0;", "  double e;"]
    rows = pat["pair_rows"]
    for p, shared in enumerate(spans("pair")):
        i, k = rows[2 * p], rows[2 * p + 1]
        store = f" S[{i + k * m}] = e;" + ("" if i == k else f" S[{k + i * m}] = e;")
        out.append(_sum("0.0", "+", (f"J[{i * n + j}] * w[{j}] * J[{k * n + j}]" for j in shared),
                        store))
    out += ["}", "", "int mechsim_kernel_cholesky(const double *S, double *R) {",
            "  double e, r, inv = 0.0;"]
    ij = pat["chol_ij"]
    for p, ks in enumerate(spans("chol")):
        i, j = ij[2 * p], ij[2 * p + 1]
        store = (f" if (!(e > 0.0)) return 1; r = sqrt(e); inv = 1.0 / r; R[{j * m + j}] = r;"
                 if i == j else f" R[{i * m + j}] = e * inv;")
        out.append(_sum(f"S[{i * m + j}]", "-", (f"R[{i * m + k}] * R[{j * m + k}]" for k in ks),
                        store))
    out += ["  (void)inv;", "  return 0;", "}", "",
            "void mechsim_kernel_solve(const double *R, const double *rdiag, double *b) {",
            "  double e;"]
    for j, cols in enumerate(spans("lrow")):                 # Rᵀ y = b
        out.append(_sum(f"b[{j}]", "-", (f"R[{j * m + k}] * b[{k}]" for k in cols),
                        f" b[{j}] = e * rdiag[{j}];"))
    for j, below in reversed(list(enumerate(spans("lcol")))):      # R x = y
        out.append(_sum(f"b[{j}]", "-", (f"R[{k * m + j}] * b[{k}]" for k in below),
                        f" b[{j}] = e * rdiag[{j}];"))
    out += ["}", "", "void mechsim_kernel_rows(const double *J, const double *x, double *out) {",
            "  double e;"]
    for i, cols in enumerate(spans("row")):
        out.append(_sum("0.0", "+", (f"J[{i * n + j}] * x[{j}]" for j in cols),
                        f" out[{i}] = e;"))
    out += ["}", "", "void mechsim_kernel_cols(const double *J, const double *y, double *out) {",
            "  double e;"]
    for j, below in enumerate(spans("col")):
        out.append(_sum("0.0", "+", (f"J[{i * n + j}] * y[{i}]" for i in below),
                        f" out[{j}] = e;"))
    return "#include <math.h>\n\n" + "\n".join(out + ["}", ""])


# Each span's entries in `pair_pattern`'s arrays: <name>_start over <name>_<items>.
_ITEMS = {"pair": "cols", "chol": "ks", "lrow": "cols", "lcol": "rows", "row": "cols",
          "col": "rows"}


def _sum(first: str, op: str, terms, store: str) -> str:
    """One sum of the index loops as statements: e = first, then e op= each term in order,
    then `store`."""
    return f"  e = {first};" + "".join(f" e {op}= {term};" for term in terms) + store
