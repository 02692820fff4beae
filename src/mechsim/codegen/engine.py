"""The evaluations of small rigid mechanisms, compiled with the model's C twins.

An evaluation of "lu" or "qr" on a small rigid mechanism is about twenty small numpy and
LAPACK calls (the chord Newton on the dependent coordinates, Φ_q, the velocity solve, γ
and the Schur complement of the accelerations), each costing a few µs of Python call
overhead for a few hundred floating-point operations: about 100 µs an evaluation on the
double four-bar, three times the projection method's. Here the same steps run in one C
function, compiled together with the model's C twins of Φ, Φ_q, Φ_t and γ (so no call
between them crosses into Python), with LAPACK's dgesv and dposv taken from scipy's own
LAPACK (the function pointers `scipy.linalg.cython_lapack` exports). Python keeps the
forces, which may be any user code, between the state and the accelerations.

The same library serves the projection method and the solver manager:

- the projection method's accelerations (`ProjectionEngine.accelerations`, `rhs`): by the
  Cholesky factor of J W Jᵀ where LAPACK's condition estimate clears it, else by the SVD
  of J̃ where no singular value is under the truncation cut;
- the projection of a state onto the constraints (`project_state`), one Cholesky factor
  for the positions' chord Newton and the velocities;
- the singularity monitor's σ_min, σ_max and their rates (`measure`);
- the hybrid's test for a return to LU, cond₁ of the block LU pivoting picks
  (`lu_condition`).

The compiled path takes only the plain case: a chord Newton converging by the same rule as
`Partitioned._newton` (residual max|Φ| ≤ newton_tol, each iteration at least four times
smaller), a nonsingular square Φ_q D and a positive definite Schur complement; for the
projection method, a state outside the truncation band. Anything else (a stalled chord
that needs fresh Jacobians, redundant constraints, Newton failing altogether, a singular
value under the cut) returns a status and the Python path takes the evaluation from the
start, so the two agree on every decision and differ only in the rounding of their sums.

The library is built beside the cached model module on first use (`library`); without a
compiler, with `MECHSIM_NO_COMPILE` set, or for a model kept in memory only, there is none
and the formulations run in Python as before.
"""

from __future__ import annotations

import ctypes
import hashlib
from pathlib import Path

import numpy as np

from .compiled import shared_library

SOURCE = r"""
#include <math.h>
#include <stdint.h>
#include <string.h>

typedef void (*mechsim_gesv_t)(int *, int *, double *, int *, int *, double *, int *, int *);
typedef void (*mechsim_posv_t)(char *, int *, int *, double *, int *, double *, int *, int *);
typedef void (*mechsim_potrf_t)(char *, int *, double *, int *, int *);
typedef void (*mechsim_pocon_t)(char *, int *, double *, int *, double *, double *, double *,
                                int *, int *);
typedef void (*mechsim_potrs_t)(char *, int *, int *, double *, int *, double *, int *, int *);
typedef void (*mechsim_getrf_t)(int *, int *, double *, int *, int *, int *);
typedef void (*mechsim_gesdd_t)(char *, int *, int *, double *, int *, double *, double *, int *,
                                double *, int *, double *, int *, int *, int *);
static mechsim_gesv_t mechsim_dgesv = 0;
static mechsim_posv_t mechsim_dposv = 0;
static mechsim_potrf_t mechsim_dpotrf = 0;
static mechsim_pocon_t mechsim_dpocon = 0;
static mechsim_potrs_t mechsim_dpotrs = 0;
static mechsim_gesdd_t mechsim_dgesdd = 0;
static mechsim_getrf_t mechsim_dgetrf = 0;

void mechsim_engine_init(void *gesv, void *posv, void *potrf, void *pocon, void *potrs,
                         void *gesdd, void *getrf) {
  mechsim_dgesv = (mechsim_gesv_t)gesv;
  mechsim_dposv = (mechsim_posv_t)posv;
  mechsim_dpotrf = (mechsim_potrf_t)potrf;
  mechsim_dpocon = (mechsim_pocon_t)pocon;
  mechsim_dpotrs = (mechsim_potrs_t)potrs;
  mechsim_dgesdd = (mechsim_gesdd_t)gesdd;
  mechsim_dgetrf = (mechsim_getrf_t)getrf;
}

/* The partition and the last accepted step; buffers owned by the Python side. */
typedef struct {
  int64_t n, m, f, max_newton, rheonomic;
  double newton_tol, t_last;
  const double *p, *q_ref, *P, *C, *winv;  /* P: r x (3 + f) predictor, C: (Phi_q D)^-1 */
  const int64_t *ind, *dep;
  double *y, *q, *v, *J, *Q, *out, *work;
  int *ipiv;
} mechsim_lu;

/* Positions by the chord Newton from the prediction, Phi_q there and the velocities.
   0: done; 1: Newton failed or slowed down (Python decides); 2: Phi_q D singular. */
static int lu_state(mechsim_lu *c, double t, const double *y, double *q, double *v,
                    double *J) {
  const int64_t n = c->n, m = c->m, f = c->f, r = n - f, cols = 3 + f;
  const double *z = y, *zd = y + f;
  double *w = c->work, *phi = w + r, *A = phi + m, *b = A + r * r, *phit = b + r;
  const double d = t - c->t_last;
  for (int64_t i = 0; i < r; i++) {
    const double *Pi = c->P + i * cols;
    double s = Pi[0] + Pi[1] * d + Pi[2] * (d * d);
    for (int64_t k = 0; k < f; k++) s += Pi[3 + k] * z[k];
    w[i] = s;
  }
  double err_prev = INFINITY;
  for (int64_t it = 0;; it++) {
    memcpy(q, c->q_ref, n * sizeof(double));
    for (int64_t k = 0; k < f; k++) q[c->ind[k]] += z[k];
    for (int64_t i = 0; i < r; i++) q[c->dep[i]] += w[i];
    mechsim_phi(q, t, c->p, phi);
    double err = 0.0;
    for (int64_t i = 0; i < m; i++) {
      const double a = fabs(phi[i]);
      if (isnan(a)) return 1;
      if (a > err) err = a;
    }
    if (err <= c->newton_tol) break;
    if (it == c->max_newton || !isfinite(err) || err > 0.25 * err_prev) return 1;
    err_prev = err;
    for (int64_t i = 0; i < r; i++) {
      const double *Ci = c->C + i * m;
      double s = 0.0;
      for (int64_t j = 0; j < m; j++) s += Ci[j] * phi[j];
      w[i] -= s;
    }
  }
  memset(J, 0, m * n * sizeof(double));
  mechsim_phi_q(q, t, c->p, J);
  memset(phit, 0, m * sizeof(double));
  if (c->rheonomic) mechsim_phi_t(q, t, c->p, phit);
  for (int64_t i = 0; i < r; i++) {
    const double *Ji = J + i * n;
    double s = 0.0;
    for (int64_t k = 0; k < f; k++) s += Ji[c->ind[k]] * zd[k];
    b[i] = -s - phit[i];
    for (int64_t j = 0; j < r; j++) A[i + j * r] = Ji[c->dep[j]];   /* column-major */
  }
  int N = (int)r, nrhs = 1, info = 0;
  mechsim_dgesv(&N, &nrhs, A, &N, c->ipiv, b, &N, &info);
  if (info != 0) return 2;
  for (int64_t k = 0; k < f; k++) v[c->ind[k]] = zd[k];
  for (int64_t i = 0; i < r; i++) v[c->dep[i]] = b[i];
  return 0;
}

int mechsim_lu_state(mechsim_lu *c, double t) {
  return lu_state(c, t, c->y, c->q, c->v, c->J);
}

/* k output samples (rows of Y) into the rows of Qo and Vo; the first failure's status. */
int mechsim_lu_states(mechsim_lu *c, int64_t k, const double *ts, const double *Y,
                      double *Qo, double *Vo, double *Jwork) {
  const int64_t n = c->n, f = c->f;
  for (int64_t s = 0; s < k; s++) {
    const int status = lu_state(c, ts[s], Y + s * 2 * f, Qo + s * n, Vo + s * n, Jwork);
    if (status) return status;
  }
  return 0;
}

/* S = J W J^T (both triangles, column-major); returns max S_ii. */
static double complement(int64_t n, int64_t m, const double *J, const double *winv,
                         double *S) {
  double diag = 0.0;
  for (int64_t i = 0; i < m; i++) {
    const double *Ji = J + i * n;
    for (int64_t k = 0; k <= i; k++) {
      const double *Jk = J + k * n;
      double e = 0.0;
      for (int64_t j = 0; j < n; j++) e += Ji[j] * winv[j] * Jk[j];
      S[i + k * m] = e;
      S[k + i * m] = e;
    }
    if (S[i + i * m] > diag) diag = S[i + i * m];
  }
  return diag;
}

/* The Schur complement's terms: wq = W Q, lam = J wq - g (the right-hand side) and
   S = J W J^T; returns max S_ii. */
static double schur_terms(int64_t n, int64_t m, const double *J, const double *winv,
                          const double *Q, const double *g, double *wq, double *lam,
                          double *S) {
  for (int64_t j = 0; j < n; j++) wq[j] = winv[j] * Q[j];
  for (int64_t i = 0; i < m; i++) {
    const double *Ji = J + i * n;
    double s = 0.0;
    for (int64_t j = 0; j < n; j++) s += Ji[j] * wq[j];
    lam[i] = s - g[i];
  }
  return complement(n, m, J, winv, S);
}

/* [zd; zdd] at the state mechsim_lu_state left in the buffers, with the forces c->Q, by
   the partition's reduced equations (as `Partitioned._qdd`): with A = J D, X = A^-1 J B
   and s = A^-1 gamma (one LU of A with f + 1 right-hand sides),
   (M_B + X^T M_D X) zdd = Q_B - X^T (Q_D - M_D s). 1: A or the reduced mass is singular
   (Python decides). */
int mechsim_lu_accelerations(mechsim_lu *c, double t) {
  const int64_t n = c->n, m = c->m, f = c->f, r = n - f;
  const double *J = c->J, *winv = c->winv, *Q = c->Q;
  double *g = c->work + 2 * r + 2 * m + r * r, *A = g + m, *X = A + r * r, *Mh = X + r * (f + 1);
  double *Qh = Mh + f * f, *s = X + r * f;
  memset(g, 0, m * sizeof(double));
  mechsim_gamma(c->q, c->v, t, c->p, g);
  for (int64_t i = 0; i < r; i++) {                      /* column-major A and [J B, gamma] */
    const double *Ji = J + i * n;
    for (int64_t j = 0; j < r; j++) A[i + j * r] = Ji[c->dep[j]];
    for (int64_t k = 0; k < f; k++) X[i + k * r] = Ji[c->ind[k]];
    s[i] = g[i];
  }
  int R = (int)r, nrhs = (int)(f + 1), info = 0;
  mechsim_dgesv(&R, &nrhs, A, &R, c->ipiv, X, &R, &info);
  if (info != 0) return 1;
  for (int64_t k = 0; k < f; k++) {
    const double *Xk = X + k * r;
    double qk = Q[c->ind[k]];
    for (int64_t i = 0; i < r; i++) {
      const int64_t d = c->dep[i];
      qk -= Xk[i] * (Q[d] - s[i] / winv[d]);
    }
    Qh[k] = qk;
    for (int64_t l = 0; l <= k; l++) {
      const double *Xl = X + l * r;
      double e = l == k ? 1.0 / winv[c->ind[k]] : 0.0;
      for (int64_t i = 0; i < r; i++) e += Xk[i] * Xl[i] / winv[c->dep[i]];
      Mh[k + l * f] = e;
      Mh[l + k * f] = e;
    }
  }
  char uplo = 'U';
  int F = (int)f, one = 1;
  if (f > 0) {
    mechsim_dposv(&uplo, &F, &one, Mh, &F, Qh, &F, &info);
    if (info != 0) return 1;
  }
  memcpy(c->out, c->y + f, f * sizeof(double));
  memcpy(c->out + f, Qh, f * sizeof(double));
  return 0;
}

/* The projection method's accelerations where J W J^T is well conditioned (there they
   are the exact constrained accelerations, as `Projection.accelerations` computes them by
   Cholesky): qdd = W Q - W J^T lam, (J W J^T) lam = J W Q - gamma, with J = Phi_q and
   gamma from the C twins, into c->out as [v; qdd]. The Cholesky factor serves unless it
   fails or, with min_rcond >= 0, LAPACK's estimate of 1/cond_1 of J W J^T (norm bounded
   by m max S_ii, as `dense.cholesky_conditioned`) is not above min_rcond; then, with
   cut > 0, the SVD decides (`svd_accelerations`), else 1. */
typedef struct {
  int64_t n, m, count;
  const double *p, *winv;
  double *q, *v, *Q, *out, *work;
  int *iwork;
  double *svd_work;
  int64_t lwork;
} mechsim_projection;

/* The Cholesky factor of S = J W J^T in place (upper triangle); 1 where it fails or, with
   min_rcond >= 0, LAPACK's estimate of 1/cond_1 (the norm bounded by m max S_ii, as
   `dense.cholesky_conditioned`) is not above min_rcond. */
static int cholesky(mechsim_projection *c, double *S, double diag, double *cw,
                    double min_rcond) {
  char uplo = 'U';
  int M = (int)c->m, info = 0;
  mechsim_dpotrf(&uplo, &M, S, &M, &info);
  if (info != 0) return 1;
  if (min_rcond >= 0.0) {
    double anorm = (double)c->m * diag, rcond = 0.0;
    mechsim_dpocon(&uplo, &M, S, &M, &anorm, &rcond, cw, c->iwork, &info);
    if (info != 0 || !(rcond > min_rcond)) return 1;
  }
  return 0;
}

/* A = J W^(1/2) (row-major m x n; A may be J). */
static void scale_columns(const mechsim_projection *c, const double *J, double *A) {
  for (int64_t i = 0; i < c->m; i++)
    for (int64_t j = 0; j < c->n; j++) A[i * c->n + j] = J[i * c->n + j] * sqrt(c->winv[j]);
}

/* The thin SVD of A = J~ (row-major m x n, m <= n; destroyed) by LAPACK's dgesdd: the
   singular values sig (largest first), the right singular vectors of J~ as the columns
   of U (n x m, column-major) and the left ones as the rows of VT (m x m, column-major):
   row-major J~ is J~^T column-major, and J~^T = U S VT. 1 where dgesdd fails. */
static int scaled_svd(mechsim_projection *c, double *A, double *sig, double *U, double *VT) {
  char jobz = 'S';
  int N = (int)c->n, M = (int)c->m, LW = (int)c->lwork, info = 0;
  mechsim_dgesdd(&jobz, &N, &M, A, &N, sig, U, &N, VT, &M, c->svd_work, &LW, c->iwork,
                 &info);
  return info != 0;
}

/* The projection method's accelerations by the SVD of J~ = J W^(1/2) (m <= n), as
   `Projection.accelerations` computes them where truncation drops nothing: every
   singular value above cut * sigma_max. x = W^(1/2) Q, x -= V V^T x - V S^-1 U^T g,
   qdd = W^(1/2) x into c->out as [v; qdd]. 1 where some singular value is at or below
   the cut (the band: Python truncates and interpolates) or the SVD fails. */
static int svd_accelerations(mechsim_projection *c, const double *J, const double *g,
                             double cut, double *buf) {
  const int64_t n = c->n, m = c->m;
  double *A = buf, *sig = A + m * n, *U = sig + m, *VT = U + n * m, *x = VT + m * m;
  double *y = x + n;
  if (m > n) return 1;
  scale_columns(c, J, A);
  if (scaled_svd(c, A, sig, U, VT) || !(sig[0] > 0.0) || !(sig[m - 1] > cut * sig[0]))
    return 1;
  for (int64_t j = 0; j < n; j++) x[j] = sqrt(c->winv[j]) * c->Q[j];
  for (int64_t k = 0; k < m; k++) {            /* y_k = V_k^T x - (U^T g)_k / sigma_k */
    double vx = 0.0, ug = 0.0;
    for (int64_t j = 0; j < n; j++) vx += U[j + k * n] * x[j];
    for (int64_t i = 0; i < m; i++) ug += VT[k + i * m] * g[i];
    y[k] = vx - ug / sig[k];
  }
  memcpy(c->out, c->v, n * sizeof(double));
  for (int64_t j = 0; j < n; j++) {
    double s = 0.0;
    for (int64_t k = 0; k < m; k++) s += U[j + k * n] * y[k];
    c->out[n + j] = sqrt(c->winv[j]) * (x[j] - s);
  }
  return 0;
}

int mechsim_projection_accelerations(mechsim_projection *c, double t, double min_rcond,
                                     double cut) {
  const int64_t n = c->n, m = c->m;
  const double *winv = c->winv;
  double *J = c->work, *g = J + m * n, *wq = g + m, *lam = wq + n, *S = lam + m;
  double *cw = S + m * m;
  memset(J, 0, m * n * sizeof(double));
  mechsim_phi_q(c->q, t, c->p, J);
  memset(g, 0, m * sizeof(double));
  mechsim_gamma(c->q, c->v, t, c->p, g);
  const double diag = schur_terms(n, m, J, winv, c->Q, g, wq, lam, S);
  char uplo = 'U';
  int M = (int)m, nrhs = 1, info = 0;
  if (cholesky(c, S, diag, cw, min_rcond))
    return cut > 0.0 ? svd_accelerations(c, J, g, cut, cw + 3 * m) : 1;
  mechsim_dpotrs(&uplo, &M, &nrhs, S, &M, lam, &M, &info);
  if (info != 0) return 1;
  memcpy(c->out, c->v, n * sizeof(double));
  for (int64_t j = 0; j < n; j++) {
    double s = 0.0;
    for (int64_t i = 0; i < m; i++) s += J[i * n + j] * lam[i];
    c->out[n + j] = wq[j] - winv[j] * s;
  }
  return 0;
}

static double max_abs(int64_t m, const double *x) {
  double e = 0.0;
  for (int64_t i = 0; i < m; i++) {
    const double a = fabs(x[i]);
    if (isnan(a)) return NAN;
    if (a > e) e = a;
  }
  return e;
}

/* x -= W J^T (S^-1 r), S the Cholesky factor in place; r is overwritten. */
static int correct(mechsim_projection *c, const double *J, const double *S, double *r,
                   double *x) {
  const int64_t n = c->n, m = c->m;
  char uplo = 'U';
  int M = (int)m, nrhs = 1, info = 0;
  mechsim_dpotrs(&uplo, &M, &nrhs, (double *)S, &M, r, &M, &info);
  if (info != 0) return 1;
  for (int64_t j = 0; j < n; j++) {
    double s = 0.0;
    for (int64_t i = 0; i < m; i++) s += J[i * n + j] * r[i];
    x[j] -= c->winv[j] * s;
  }
  return 0;
}

/* (c->q, c->v) projected in place onto the constraints in the mass metric, as
   `NumericProblem.project_state`: a chord Newton on Phi with the one Cholesky factor of
   J W J^T at the given q (stopping at max|Phi| <= tol or where `newton_stalled` says
   round-off, then `extra` further iterations), and the velocity projection
   v -= W J^T S^-1 (J v + Phi_t) with J at the new q and the same factor. 0: projected,
   c->count the Newton iterations; 2: max|Phi| <= skip_tol, left as it is; 1: declined
   (the factor fails, or with min_rcond >= 0 its condition estimate is not above it; the
   chord does not converge within max_iter). */
int mechsim_project_state(mechsim_projection *c, double t, double skip_tol, double tol,
                          double min_rcond, int64_t extra, int64_t max_iter) {
  const int64_t n = c->n, m = c->m;
  double *q = c->q, *v = c->v;
  double *J = c->work, *phi = J + m * n, *r = phi + m, *S = r + m, *cw = S + m * m;
  mechsim_phi(q, t, c->p, phi);
  double err = max_abs(m, phi);
  if (err <= skip_tol) return 2;
  memset(J, 0, m * n * sizeof(double));
  mechsim_phi_q(q, t, c->p, J);
  const double diag = complement(n, m, J, c->winv, S);
  if (cholesky(c, S, diag, cw, min_rcond)) return 1;
  double prev = INFINITY;
  int64_t count = 0;
  for (int64_t k = 0;; k++) {
    if (isnan(err)) return 1;
    if (err <= tol || (err > 0.5 * prev && err <= 1e3 * tol)) break;
    if (k == max_iter) return 1;
    prev = err;
    memcpy(r, phi, m * sizeof(double));
    if (correct(c, J, S, r, q)) return 1;
    count++;
    mechsim_phi(q, t, c->p, phi);
    err = max_abs(m, phi);
  }
  for (int64_t k = 0; k < extra; k++) {
    memcpy(r, phi, m * sizeof(double));
    if (correct(c, J, S, r, q)) return 1;
    count++;
    mechsim_phi(q, t, c->p, phi);
  }
  memset(J, 0, m * n * sizeof(double));
  mechsim_phi_q(q, t, c->p, J);        /* S keeps the factor at the given q */
  memset(r, 0, m * sizeof(double));
  mechsim_phi_t(q, t, c->p, r);
  for (int64_t i = 0; i < m; i++) {
    const double *Ji = J + i * n;
    double s = 0.0;
    for (int64_t j = 0; j < n; j++) s += Ji[j] * v[j];
    r[i] += s;
  }
  if (correct(c, J, S, r, v)) return 1;
  c->count = count;
  return 0;
}

/* J~ = Phi_q W^(1/2) at (q, t) into Jt (row-major m x n). */
static void scaled_jacobian(mechsim_projection *c, const double *q, double t, double *Jt) {
  memset(Jt, 0, c->m * c->n * sizeof(double));
  mechsim_phi_q(q, t, c->p, Jt);
  scale_columns(c, Jt, Jt);
}

/* The singularity monitor's measurement (`SingularityMonitor._measure`, m <= n): the
   extreme singular values of J~ = Phi_q W^(1/2) at c->q by LAPACK's dgesdd and, with
   eps > 0, their derivatives along the motion, u^T dJ~ v with dJ~ from J~ at
   (q + eps v, t + eps). out: [s_min, s_max, ds_min, ds_max, u_min (m)]; J~ in Jt.
   1 where the SVD fails. */
int mechsim_measure(mechsim_projection *c, double t, double eps, double *out, double *Jt) {
  const int64_t n = c->n, m = c->m;
  double *A = c->work, *sig = A + m * n, *U = sig + m, *VT = U + n * m, *J1 = VT + m * m;
  double *q1 = J1 + m * n;
  scaled_jacobian(c, c->q, t, Jt);
  memcpy(A, Jt, m * n * sizeof(double));
  if (scaled_svd(c, A, sig, U, VT)) return 1;
  const int64_t k = m - 1;
  out[0] = sig[k];
  out[1] = sig[0];
  out[2] = out[3] = 0.0;
  for (int64_t i = 0; i < m; i++) out[4 + i] = VT[k + i * m];
  if (eps > 0.0) {
    for (int64_t j = 0; j < n; j++) q1[j] = c->q[j] + eps * c->v[j];
    scaled_jacobian(c, q1, t + eps, J1);
    double dmin = 0.0, dmax = 0.0;
    for (int64_t i = 0; i < m; i++) {
      double smin = 0.0, smax = 0.0;
      for (int64_t j = 0; j < n; j++) {
        const double d = J1[i * n + j] - Jt[i * n + j];
        smin += d * U[j + k * n];
        smax += d * U[j];
      }
      dmin += VT[k + i * m] * smin;
      dmax += VT[i * m] * smax;
    }
    out[2] = dmin / eps;
    out[3] = dmax / eps;
  }
  return 0;
}

/* ||A||_1 ||A^-1||_1 of the block A = Phi_q D that `Partitioned.choose` picks at (c->q, t)
   for a Phi_q of full row rank (m <= n): the dependent coordinates are the first m of
   the row permutation of LU with partial pivoting of Phi_q^T. INFINITY where the
   pivoting or the block is singular. */
double mechsim_lu_condition(mechsim_projection *c, double t) {
  const int64_t n = c->n, m = c->m;
  double *J = c->work, *F = J + m * n, *A = F + m * n, *X = A + m * m;
  int64_t *perm = (int64_t *)(X + m * m);
  memset(J, 0, m * n * sizeof(double));
  mechsim_phi_q(c->q, t, c->p, J);
  memcpy(F, J, m * n * sizeof(double));
  /* Row-major J is J^T column-major (n x m), the matrix `choose` factors. */
  int N = (int)n, M = (int)m, info = 0;
  mechsim_dgetrf(&N, &M, F, &N, c->iwork, &info);
  if (info < 0) return INFINITY;
  for (int64_t j = 0; j < n; j++) perm[j] = j;
  for (int64_t i = 0; i < m; i++) {
    const int64_t p = c->iwork[i] - 1, s = perm[i];
    perm[i] = perm[p];
    perm[p] = s;
  }
  double norm = 0.0, inorm = 0.0;
  for (int64_t k = 0; k < m; k++) {
    double col = 0.0;
    for (int64_t i = 0; i < m; i++) {
      const double a = J[i * n + perm[k]];
      A[i + k * m] = a;                       /* column-major */
      X[i + k * m] = i == k ? 1.0 : 0.0;
      col += fabs(a);
    }
    if (col > norm) norm = col;
  }
  mechsim_dgesv(&M, &M, A, &M, c->iwork, X, &M, &info);
  if (info != 0) return INFINITY;
  for (int64_t k = 0; k < m; k++) {
    double col = 0.0;
    for (int64_t i = 0; i < m; i++) col += fabs(X[i + k * m]);
    if (col > inorm) inorm = col;
  }
  return norm * inorm;
}
"""

_HASH = hashlib.sha256(SOURCE.encode()).hexdigest()[:12]


class _Context(ctypes.Structure):
    _fields_ = ([(name, ctypes.c_int64) for name in ("n", "m", "f", "max_newton", "rheonomic")]
                + [("newton_tol", ctypes.c_double), ("t_last", ctypes.c_double)]
                + [(name, ctypes.c_void_p) for name in (
                    "p", "q_ref", "P", "C", "winv", "ind", "dep",
                    "y", "q", "v", "J", "Q", "out", "work", "ipiv")])


def _lapack(name: str) -> int:
    """The address of scipy's LAPACK routine `name` (from its Cython capsule)."""
    from scipy.linalg import cython_lapack
    capsule = cython_lapack.__pyx_capi__[name]
    get_name = ctypes.pythonapi.PyCapsule_GetName
    get_name.restype, get_name.argtypes = ctypes.c_char_p, [ctypes.py_object]
    get_pointer = ctypes.pythonapi.PyCapsule_GetPointer
    get_pointer.restype, get_pointer.argtypes = ctypes.c_void_p, [ctypes.py_object,
                                                                  ctypes.c_char_p]
    return get_pointer(capsule, get_name(capsule))


def for_problem(problem):
    """The compiled engine for a NumericProblem whose evaluations it can take: constraints,
    a constant diagonal mass (no flexible bodies) and the dense Schur complement (not a
    long chain's banded one); None elsewhere or where there is no library."""
    if not problem.m or not problem.constant_mass or problem.schur is not None:
        return None
    return library(problem.model)


def library_path(module_path: Path) -> Path:
    """Where the engine library of the model module at `module_path` is cached."""
    return module_path.with_name(f"{module_path.stem}.lu-{_HASH}.so")


def why_not(problem) -> str:
    """Why `for_problem` gives no engine for a problem it does not take ("" if it takes it)."""
    if not problem.m:
        return "the mechanism has no constraints: nothing to compile"
    if not problem.constant_mass:
        return ("flexible bodies: the compiled evaluations take rigid mechanisms "
                "(constant diagonal mass) only")
    if problem.schur is not None:
        return "a long chain: its banded Schur complement runs on the Python path"
    return ""


def library(model):
    """The compiled engine for `model` (a generated module), or None where there is none."""
    lib = getattr(model, "_ENGINE", False)
    if lib is not False:
        return lib
    model._ENGINE = None
    source, path = getattr(model, "C_SOURCE", None), getattr(model, "__file__", None)
    if not source or not path:
        return None
    lib = shared_library(source + SOURCE, library_path(Path(path)))
    if lib is None:
        return None
    try:
        routines = ("dgesv", "dposv", "dpotrf", "dpocon", "dpotrs", "dgesdd", "dgetrf")
        lib.mechsim_engine_init.argtypes = [ctypes.c_void_p] * len(routines)
        lib.mechsim_engine_init.restype = None
        lib.mechsim_engine_init(*map(_lapack, routines))
        for name in ("mechsim_lu_state", "mechsim_lu_accelerations"):
            fn = getattr(lib, name)
            fn.argtypes, fn.restype = [ctypes.c_void_p, ctypes.c_double], ctypes.c_int
        lib.mechsim_lu_states.argtypes = [ctypes.c_void_p, ctypes.c_int64] + [ctypes.c_void_p] * 5
        lib.mechsim_lu_states.restype = ctypes.c_int
        fn = lib.mechsim_projection_accelerations
        fn.argtypes = [ctypes.c_void_p, ctypes.c_double, ctypes.c_double, ctypes.c_double]
        fn.restype = ctypes.c_int
        fn = lib.mechsim_project_state
        fn.argtypes = [ctypes.c_void_p] + [ctypes.c_double] * 4 + [ctypes.c_int64] * 2
        fn.restype = ctypes.c_int
        fn = lib.mechsim_lu_condition
        fn.argtypes, fn.restype = [ctypes.c_void_p, ctypes.c_double], ctypes.c_double
        fn = lib.mechsim_measure
        fn.argtypes = [ctypes.c_void_p, ctypes.c_double, ctypes.c_double] + \
            [ctypes.c_void_p] * 2
        fn.restype = ctypes.c_int
    except (OSError, AttributeError, KeyError):
        return None
    model._ENGINE = lib
    return lib


class PartitionedEngine:
    """One partition's compiled evaluation (`library`): the buffers the C side reads and
    writes, and the calls. `accept` loads an accepted step's predictor and chord factor;
    `state` and `accelerations` mirror `Partitioned.full_state` and its q̈ solve."""

    def __init__(self, lib, problem, basis, newton_tol, max_newton, rheonomic):
        n, m, f = problem.n, problem.m, basis.f
        r = n - f
        self.f = f
        self.p = np.ascontiguousarray(problem.p, dtype=float)
        self.q_ref = np.zeros(n)
        self.P = np.zeros((r, 3 + f))
        self.C = np.zeros((r, m))
        self.winv = np.ascontiguousarray(problem.inverse_mass_diagonal, dtype=float)
        self.ind = np.ascontiguousarray(basis.ind, dtype=np.int64)
        self.dep = np.ascontiguousarray(basis.dep, dtype=np.int64)
        self.y, self.out = np.zeros(2 * f), np.zeros(2 * f)
        self.q, self.v, self.Q = np.zeros(n), np.zeros(n), np.zeros(n)
        self.J, self.J_samples = np.zeros((m, n)), np.zeros((m, n))
        self.work = np.zeros(2 * r + 2 * m + r * r + m + n + m + m * m + r * r + r * (f + 1)
                             + f * f + f)
        self.ipiv = np.zeros(max(r, 1), dtype=np.intc)
        addr = {name: getattr(self, name).ctypes.data for name in (
            "p", "q_ref", "P", "C", "winv", "ind", "dep", "y", "q", "v", "J", "Q", "out",
            "work", "ipiv")}
        self.ctx = _Context(n=n, m=m, f=f, max_newton=max_newton, rheonomic=int(rheonomic),
                            newton_tol=newton_tol, t_last=0.0, **addr)
        self._ptr = ctypes.addressof(self.ctx)
        self._state, self._acc = lib.mechsim_lu_state, lib.mechsim_lu_accelerations
        self._states = lib.mechsim_lu_states
        self.ready = False

    def accept(self, t, q_ref, P, chord_inverse):
        """The last accepted step: its time, the prediction's matrix and the inverse of
        Φ_q D there (None: not available, the Python path serves until the next step)."""
        if chord_inverse is None:
            self.ready = False
            return
        self.q_ref[:] = q_ref
        self.P[:] = P
        self.C[:] = chord_inverse
        self.ctx.t_last = t
        self.ready = True

    def state(self, t, y):
        """(q, v, Φ_q) of y = [z; ż], or None where the Python path must decide."""
        self.y[:] = y
        if self._state(self._ptr, t):
            return None
        return self.q.copy(), self.v.copy(), self.J.copy()

    def accelerations(self, t, Q):
        """[ż; z̈] at the state the last successful `state` left in the buffers, with the
        applied forces Q there; None if the Schur complement is not positive definite."""
        self.Q[:] = Q
        if self._acc(self._ptr, t):
            return None
        return self.out.copy()

    def states(self, ts, Y):
        """(Q, V) of the output samples (rows of Y at the times ts), or None."""
        ts = np.ascontiguousarray(ts, dtype=float)
        Y = np.ascontiguousarray(Y, dtype=float)
        k, n = len(ts), self.q.size
        Qs, Vs = np.empty((k, n)), np.empty((k, n))
        if self._states(self._ptr, k, ts.ctypes.data, Y.ctypes.data, Qs.ctypes.data,
                        Vs.ctypes.data, self.J_samples.ctypes.data):
            return None
        return Qs, Vs


class _ProjectionContext(ctypes.Structure):
    _fields_ = [(name, ctypes.c_int64) for name in ("n", "m", "count")] + [
        (name, ctypes.c_void_p) for name in ("p", "winv", "q", "v", "Q", "out", "work", "iwork",
                                             "svd_work")] + [("lwork", ctypes.c_int64)]


class ProjectionEngine:
    """The projection method's accelerations outside the truncation band (`library`): one
    call instead of Φ_q, γ, the mass scaling, the Cholesky factor of J̃J̃ᵀ with its
    condition estimate (or the SVD of J̃) in numpy and LAPACK; the projection of a state
    onto the constraints with one such factor (`project_state`); the singularity
    monitor's measurement (`measure`) and the hybrid's LU test (`lu_condition`)."""

    def __init__(self, lib, problem):
        n, m = problem.n, problem.m
        self.p = np.ascontiguousarray(problem.p, dtype=float)
        self.winv = np.ascontiguousarray(problem.inverse_mass_diagonal, dtype=float)
        self.y, self.Q, self.out = np.zeros(2 * n), np.zeros(n), np.zeros(2 * n)
        self.q, self.v = self.y[:n], self.y[n:]
        self.work = np.zeros(3 * m * n + 2 * m * m + 8 * m + 2 * n)
        self.iwork = np.zeros(max(8 * m, 1), dtype=np.intc)
        k = min(m, n)
        self.svd_work = np.zeros(3 * k + max(max(m, n), 5 * k * k + 4 * k) + 64)
        self.measured, self.Jt = np.zeros(4 + m), np.zeros((m, n))
        self.ctx = _ProjectionContext(n=n, m=m, **{
            name: getattr(self, name).ctypes.data
            for name in ("p", "winv", "q", "v", "Q", "out", "work", "iwork", "svd_work")},
            lwork=self.svd_work.size)
        self.n = n
        self._ptr = ctypes.addressof(self.ctx)
        self._fn = lib.mechsim_projection_accelerations
        self._project = lib.mechsim_project_state
        self._measure = lib.mechsim_measure
        self._lu_condition = lib.mechsim_lu_condition
        self.counters = problem.counters

    def accelerations(self, t, q, v, Q, min_rcond, cut=0.0):
        """q̈ at (t, q, v) under the forces Q by the Cholesky factor of J W Jᵀ where it is
        positive definite and (min_rcond ≥ 0) its reciprocal condition estimate is above
        min_rcond; else, with cut > 0, by the SVD of J̃ where every singular value is
        above cut σ_max (truncation drops nothing); else None."""
        self.q[:] = q
        self.v[:] = v
        return None if self._evaluate(t, Q, min_rcond, cut) else self.out[self.n:].copy()

    def rhs(self, t, y, Q, min_rcond, cut=0.0):
        """`accelerations` as the right-hand side [v; q̈] at y = [q; v]."""
        self.y[:] = y
        return None if self._evaluate(t, Q, min_rcond, cut) else self.out.copy()

    def _evaluate(self, t, Q, min_rcond, cut):
        """[v; q̈] into `out` at the state in the buffers; nonzero where declined."""
        self.Q[:] = Q
        return self._fn(self._ptr, t, min_rcond, cut)

    def project_state(self, t, q, v, tol, min_rcond=-1.0, skip_tol=-1.0, extra=0, max_iter=8):
        """`NumericProblem.project_state` compiled: (q, v) with ‖Φ‖∞ ≤ tol (or at round-off;
        then `extra` further chord iterations) and Φ_q v + Φ_t = 0, by the chord Newton
        and velocity projection on one Cholesky factor of Φ_q M⁻¹ Φ_qᵀ at the given q.
        False where ‖Φ‖∞ ≤ skip_tol already (nothing done); None where the Python path
        must decide: the factor fails, its condition estimate is not above min_rcond
        (when min_rcond ≥ 0), or the chord does not converge in max_iter iterations."""
        self.q[:] = q
        self.v[:] = v
        status = self._project(self._ptr, t, skip_tol, tol, min_rcond, extra, max_iter)
        if status == 2:
            return False
        if status:
            return None
        self.counters.projections += self.ctx.count
        return self.q.copy(), self.v.copy()

    def measure(self, t, q, v=None, eps=0.0):
        """The extreme singular values of J̃ = Φ_q M^{-1/2} at (q, t) and, with eps > 0,
        their rates along v (from J̃ at (q + eps v, t + eps)): (σ_min, σ_max, σ̇_min,
        σ̇_max, left singular vector of σ_min, J̃); None where the SVD fails. Needs
        m ≤ n (else σ_min is 0 by count)."""
        self.q[:] = q
        if eps > 0.0:
            self.v[:] = v
        out = self.measured
        if self._measure(self._ptr, t, eps, out.ctypes.data, self.Jt.ctypes.data):
            return None
        smin, smax, dmin, dmax = out[:4].tolist()
        return smin, smax, dmin, dmax, out[4:].copy(), self.Jt.copy()

    def lu_condition(self, t, q):
        """cond₁ of the dependent block Φ_q D that LU partitioning (`Partitioned.choose`)
        picks at (q, t), for Φ_q of full row rank; inf where it is singular."""
        self.q[:] = q
        return self._lu_condition(self._ptr, t)
