/* mechsim's compiled evaluations of small rigid mechanisms (see engine.py).

   Compiled after the model's C twins (mechsim_phi, mechsim_phi_q, mechsim_phi_t,
   mechsim_gamma) and the typedefs of mechsim_lu and mechsim_projection, which Python
   writes from one description (layout.py): every buffer below is a named member of those
   structs, allocated by Python at the size the description gives, and every threshold of
   a rule shared with the Python path (the chord's contraction, the round-off stall) is a
   member set from its one Python definition (mechsim/newton.py). LAPACK comes from scipy
   (the function pointers scipy.linalg.cython_lapack exports). */

typedef void (*mechsim_gesv_t)(int *, int *, double *, int *, int *, double *, int *, int *);
typedef void (*mechsim_potrf_t)(char *, int *, double *, int *, int *);
typedef void (*mechsim_pocon_t)(char *, int *, double *, int *, double *, double *, double *,
                                int *, int *);
typedef void (*mechsim_potrs_t)(char *, int *, int *, double *, int *, double *, int *, int *);
typedef void (*mechsim_getrf_t)(int *, int *, double *, int *, int *, int *);
typedef void (*mechsim_lasq1_t)(int *, double *, double *, double *, int *);
typedef void (*mechsim_gesdd_t)(char *, int *, int *, double *, int *, double *, double *, int *,
                                double *, int *, double *, int *, int *, int *);
static mechsim_gesv_t mechsim_dgesv = 0;
static mechsim_potrf_t mechsim_dpotrf = 0;
static mechsim_pocon_t mechsim_dpocon = 0;
static mechsim_potrs_t mechsim_dpotrs = 0;
static mechsim_gesdd_t mechsim_dgesdd = 0;
static mechsim_getrf_t mechsim_dgetrf = 0;
static mechsim_lasq1_t mechsim_dlasq1 = 0;

void mechsim_engine_init(void *gesv, void *potrf, void *pocon, void *potrs, void *gesdd,
                         void *getrf, void *lasq1) {
  mechsim_dgesv = (mechsim_gesv_t)gesv;
  mechsim_dpotrf = (mechsim_potrf_t)potrf;
  mechsim_dpocon = (mechsim_pocon_t)pocon;
  mechsim_dpotrs = (mechsim_potrs_t)potrs;
  mechsim_dgesdd = (mechsim_gesdd_t)gesdd;
  mechsim_dgetrf = (mechsim_getrf_t)getrf;
  mechsim_dlasq1 = (mechsim_lasq1_t)lasq1;
}

/* The rows a reflector tracks its nonzero entries in (a longer column: every row). */
#define SPARSE_ROWS 128

/* A = P L U in place (r x r, column-major), partial pivoting on the first largest |entry|
   of each column (as LAPACK's dgetf2 chooses), ipiv 1-based as LAPACK's. The partitions'
   blocks are a few rows: a library call costs more than the arithmetic there. 0: done;
   1: a zero pivot (A singular). */
static int small_lu(int64_t r, double *A, int *ipiv) {
  for (int64_t j = 0; j < r; j++) {
    int64_t p = j;
    double best = fabs(A[j + j * r]);
    for (int64_t i = j + 1; i < r; i++)
      if (fabs(A[i + j * r]) > best) { best = fabs(A[i + j * r]); p = i; }
    ipiv[j] = (int)(p + 1);
    if (!(best > 0.0)) return 1;
    if (p != j)
      for (int64_t k = 0; k < r; k++) {
        const double keep = A[j + k * r];
        A[j + k * r] = A[p + k * r];
        A[p + k * r] = keep;
      }
    const double pivot = A[j + j * r];
    if (fabs(pivot) >= DBL_MIN) {                   /* dgetf2: 1/pivot where it is finite */
      const double inv = 1.0 / pivot;
      for (int64_t i = j + 1; i < r; i++) A[i + j * r] *= inv;
    } else {
      for (int64_t i = j + 1; i < r; i++) A[i + j * r] /= pivot;
    }
    for (int64_t k = j + 1; k < r; k++) {
      const double a = A[j + k * r];
      if (a != 0.0)
        for (int64_t i = j + 1; i < r; i++) A[i + k * r] -= A[i + j * r] * a;
    }
  }
  return 0;
}

/* B (r x nrhs, column-major) = A^-1 B from small_lu's factors of A. */
static void small_solve(int64_t r, const double *LU, const int *ipiv, int64_t nrhs, double *B) {
  for (int64_t c = 0; c < nrhs; c++) {
    double *b = B + c * r;
    for (int64_t i = 0; i < r; i++) {
      const int64_t p = ipiv[i] - 1;
      if (p != i) { const double keep = b[i]; b[i] = b[p]; b[p] = keep; }
    }
    for (int64_t i = 1; i < r; i++) {
      double s = b[i];
      for (int64_t k = 0; k < i; k++) s -= LU[i + k * r] * b[k];
      b[i] = s;
    }
    for (int64_t i = r - 1; i >= 0; i--) {
      const double inv = 1.0 / LU[i + i * r];  /* off the sums' chain of dependences */
      double s = b[i];
      for (int64_t k = i + 1; k < r; k++) s -= LU[i + k * r] * b[k];
      b[i] = s * inv;
    }
  }
}

/* A X = B by small_lu and small_solve (A overwritten by its factors). 0: done; 1: A
   singular. */
static int small_gesv(int64_t r, double *A, int *ipiv, int64_t nrhs, double *B) {
  if (small_lu(r, A, ipiv)) return 1;
  small_solve(r, A, ipiv, nrhs, B);
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

/* ---- the partitioned evaluation (Partitioned.full_state and its accelerations) ---- */

/* Newton on the dependent coordinates w of Phi(q_ref + B z + D w, t) = 0 from the guess in
   w, into w and q: the chord with C, the inverse of Phi_q D at the last accepted step, and
   fresh Phi_q D from the iteration where the chord contracts too slowly, or from the start
   where `fresh` (as Partitioned._newton), counted in c->fresh. 0: converged; 1: failed. */
static int newton_w(mechsim_lu *c, double t, const double *z, double *w, double *q, double *J,
                    int fresh) {
  const int64_t n = c->n, m = c->m, f = c->f, r = n - f;
  double *phi = c->phi, *A = c->A, *b = c->b;
  c->fresh = 0;
  double err_prev = INFINITY;
  for (int64_t it = 0;; it++) {
    memcpy(q, c->q_ref, n * sizeof(double));
    for (int64_t k = 0; k < f; k++) q[c->ind[k]] += z[k];
    for (int64_t i = 0; i < r; i++) q[c->dep[i]] += w[i];
    mechsim_phi(q, t, c->p, phi);
    const double err = max_abs(m, phi);
    if (isnan(err)) return 1;
    if (err <= c->newton_tol ||
        (err > c->stall_ratio * err_prev && err <= c->stall_span * c->newton_tol)) return 0;
    if (it == c->max_newton || !isfinite(err)) return 1;
    if (!(err <= c->chord_contraction * err_prev)) fresh = 1;
    err_prev = err;
    if (fresh) {                       /* w -= (Phi_q D)^-1 Phi at this q */
      memset(J, 0, m * n * sizeof(double));
      mechsim_phi_q(q, t, c->p, J);
      for (int64_t i = 0; i < r; i++)
        for (int64_t j = 0; j < r; j++) A[i + j * r] = J[i * n + c->dep[j]];
      memcpy(b, phi, r * sizeof(double));
      if (small_gesv(r, A, c->ipiv, 1, b)) return 1;
      for (int64_t i = 0; i < r; i++) w[i] -= b[i];
      c->fresh++;
      continue;
    }
    for (int64_t i = 0; i < r; i++) {
      const double *Ci = c->C + i * m;
      double s = 0.0;
      for (int64_t j = 0; j < m; j++) s += Ci[j] * phi[j];
      w[i] -= s;
    }
  }
}

/* Newton along the straight path from the last accepted state (t_last, z_last, w_last) to
   (t, z) in `first`, then 4 and 16 times as many pieces, each from the one before with fresh
   Jacobians (as Partitioned._follow): 0 with w and q solved at (t, z); 1: failed. */
static int follow(mechsim_lu *c, double t, const double *z, double *w, double *q, double *J,
                  int64_t first) {
  const int64_t f = c->f, r = c->n - f;
  double *zk = c->zk;
  for (int64_t pieces = first; pieces <= 16 * first; pieces *= 4) {
    memcpy(w, c->w_last, r * sizeof(double));
    int64_t k = 1;
    for (; k <= pieces; k++) {
      const double a = (double)k / (double)pieces;
      for (int64_t i = 0; i < f; i++) zk[i] = c->z_last[i] + a * (z[i] - c->z_last[i]);
      if (newton_w(c, c->t_last + a * (t - c->t_last), zk, w, q, J, 1)) break;
    }
    if (k > pieces) return 0;
  }
  return 1;
}

/* The velocities of the positions in q at (t, zd): Phi_q into J, v, and (where sign is not
   NULL) the sign of det(Phi_q D) from the LU they are solved with. 0: done; 2: Phi_q D
   singular. */
static int velocities(mechsim_lu *c, double t, const double *zd, const double *q, double *v,
                      double *J, double *sign) {
  const int64_t n = c->n, m = c->m, f = c->f, r = n - f;
  double *A = c->A, *b = c->b, *phit = c->phit;
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
  memcpy(c->A0, A, r * r * sizeof(double));
  if (small_gesv(r, A, c->ipiv, 1, b)) return 2;
  memcpy(c->LU, A, r * r * sizeof(double));      /* kept for the accelerations (same A) */
  memcpy(c->LUpiv, c->ipiv, r * sizeof(int));
  if (sign) {                          /* P A = L U: det A = (-1)^swaps prod U_ii */
    double s = 1.0;
    for (int64_t i = 0; i < r; i++) {
      if (A[i + i * r] < 0.0) s = -s;
      if (c->ipiv[i] != (int)(i + 1)) s = -s;
    }
    *sign = s;
  }
  for (int64_t k = 0; k < f; k++) v[c->ind[k]] = zd[k];
  for (int64_t i = 0; i < r; i++) v[c->dep[i]] = b[i];
  return 0;
}

/* Positions by the chord Newton from the prediction (Partitioned._positions: where it
   fails, by following the path from the last accepted state) into q (J: scratch).
   0: done; 1: Newton failed (Python decides). */
static int lu_positions(mechsim_lu *c, double t, const double *y, double *q, double *J) {
  const int64_t f = c->f, r = c->n - f, cols = 3 + f;
  const double *z = y;
  double *w = c->w;
  const double d = t - c->t_last;
  for (int64_t i = 0; i < r; i++) {
    const double *Pi = c->P + i * cols;
    double s = Pi[0] + Pi[1] * d + Pi[2] * (d * d);
    for (int64_t k = 0; k < f; k++) s += Pi[3 + k] * z[k];
    w[i] = s;
  }
  return newton_w(c, t, z, w, q, J, 0) && follow(c, t, z, w, q, J, 4);
}

/* lu_positions, then Phi_q there and the velocities into J, v, and (where sign is not NULL)
   the sign of det(Phi_q D). 0: done; 1: Newton failed (Python decides); 2: Phi_q D
   singular. */
static int lu_state(mechsim_lu *c, double t, const double *y, double *q, double *v,
                    double *J, double *sign) {
  if (lu_positions(c, t, y, q, J)) return 1;
  return velocities(c, t, y + c->f, q, v, J, sign);
}

int mechsim_lu_state(mechsim_lu *c, double t) {
  return lu_state(c, t, c->y, c->q, c->v, c->J, NULL);
}

int mechsim_lu_accelerations(mechsim_lu *c, double t);

/* [zd; zdd] at c->y under the applied forces c->Q in one call (mechsim_lu_state, then
   mechsim_lu_accelerations): 0 done; else the state's status, or 3 where the reduced
   accelerations fail (Python decides). */
int mechsim_lu_rhs(mechsim_lu *c, double t) {
  const int status = lu_state(c, t, c->y, c->q, c->v, c->J, NULL);
  if (status) return status;
  return mechsim_lu_accelerations(c, t) ? 3 : 0;
}

/* k output samples (rows of Y) into the rows of Qo and Vo, the signs of det(Phi_q D) there
   into signs; the first failure's status. */
int mechsim_lu_states(mechsim_lu *c, int64_t k, const double *ts, const double *Y,
                      double *Qo, double *Vo, double *Jwork, double *signs) {
  const int64_t n = c->n, f = c->f;
  for (int64_t s = 0; s < k; s++) {
    const int status = lu_state(c, ts[s], Y + s * 2 * f, Qo + s * n, Vo + s * n, Jwork,
                                signs + s);
    if (status) return status;
  }
  return 0;
}

/* The end of a step (Partitioned.keeps_branch and after_step): the state at c->y solved as
   mechsim_lu_state solves it (q, v, J, c->fresh), and of A = Phi_q D there the inverse into
   Ainv (r x r, row-major), X = A^-1 Phi_q B into X (r x f, row-major), and out = (the sign
   of det A, cond_1 A = |A|_1 |A^-1|_1), from one LU of A with the r + f right-hand sides
   [I, Phi_q B]. 0: done; else the state's status, or 2 where A is singular. */
int mechsim_lu_end(mechsim_lu *c, double t, double *Ainv, double *Xo, double *out) {
  const int64_t n = c->n, f = c->f, r = n - f;
  const int status = lu_state(c, t, c->y, c->q, c->v, c->J, NULL);
  if (status) return status;
  double *A = c->A, *E = c->E, norm = 0.0;
  memset(E, 0, r * n * sizeof(double));
  for (int64_t i = 0; i < r; i++) {                 /* column-major A and [I, J B] */
    const double *Ji = c->J + i * n;
    for (int64_t j = 0; j < r; j++) A[i + j * r] = Ji[c->dep[j]];
    E[i + i * r] = 1.0;
    for (int64_t k = 0; k < f; k++) E[i + (r + k) * r] = Ji[c->ind[k]];
  }
  for (int64_t j = 0; j < r; j++) {
    double col = 0.0;
    for (int64_t i = 0; i < r; i++) col += fabs(A[i + j * r]);
    if (col > norm) norm = col;
  }
  if (small_gesv(r, A, c->ipiv, n, E)) return 2;
  double sign = 1.0, inorm = 0.0;                   /* P A = L U: det A = (-1)^swaps prod U_ii */
  for (int64_t i = 0; i < r; i++) {
    if (A[i + i * r] < 0.0) sign = -sign;
    if (c->ipiv[i] != (int)(i + 1)) sign = -sign;
  }
  for (int64_t j = 0; j < r; j++) {
    double col = 0.0;
    for (int64_t i = 0; i < r; i++) {
      Ainv[i * r + j] = E[i + j * r];
      col += fabs(E[i + j * r]);
    }
    if (col > inorm) inorm = col;
  }
  for (int64_t i = 0; i < r; i++)
    for (int64_t k = 0; k < f; k++) Xo[i * f + k] = E[i + (r + k) * r];
  out[0] = sign;
  out[1] = norm * inorm;
  return 0;
}

static int small_cholesky(int64_t m, const double *S, double *R);
static void cholesky_solve(int64_t m, const double *R, const double *rdiag, double *b);

/* [zd; zdd] at the state mechsim_lu_state left in the buffers, with the forces c->Q, by
   the partition's reduced equations (as Partitioned._qdd): with A = J D, X = A^-1 J B
   and s = A^-1 gamma (one LU of A with f + 1 right-hand sides),
   (M_B + X^T M_D X) zdd = Q_B - X^T (Q_D - M_D s). 1: A or the reduced mass is singular
   (Python decides). */
int mechsim_lu_accelerations(mechsim_lu *c, double t) {
  const int64_t n = c->n, f = c->f, r = n - f;
  const double *J = c->J, *winv = c->winv, *Q = c->Q;
  double *g = c->g, *A = c->A, *X = c->X, *Mh = c->Mh, *Qh = c->Qh, *s = c->X + r * f;
  memset(g, 0, c->m * sizeof(double));
  mechsim_gamma(c->q, c->v, t, c->p, g);
  for (int64_t i = 0; i < r; i++) {                      /* column-major A and [J B, gamma] */
    const double *Ji = J + i * n;
    for (int64_t j = 0; j < r; j++) A[i + j * r] = Ji[c->dep[j]];
    for (int64_t k = 0; k < f; k++) X[i + k * r] = Ji[c->ind[k]];
    s[i] = g[i];
  }
  if (memcmp(A, c->A0, r * r * sizeof(double)) == 0)
    small_solve(r, c->LU, c->LUpiv, f + 1, X);     /* the velocities' matrix: its factors */
  else if (small_gesv(r, A, c->ipiv, f + 1, X))
    return 1;
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
  /* The reduced mass is f x f (one row for a crank): its Cholesky factor and solves in
     plain loops, as a complement's (LAPACK's call costs more than their arithmetic at
     these sizes); zk (free here) holds the diagonal's reciprocals. */
  if (f > 0) {
    if (small_cholesky(f, Mh, Mh)) return 1;
    for (int64_t k = 0; k < f; k++) c->zk[k] = 1.0 / Mh[k * f + k];
    cholesky_solve(f, Mh, c->zk, Qh);
  }
  memcpy(c->out, c->y + f, f * sizeof(double));
  memcpy(c->out + f, Qh, f * sizeof(double));
  return 0;
}

/* ---- the projection method (Projection.accelerations, NumericProblem.project_state) ---- */

/* S = J W J^T (m x m, symmetric) over the columns each pair of rows shares in c's pattern
   of Phi_q (J: Phi_q or J~, row-major m x n; W = diag(w), or the identity where w is
   NULL); the entries of rows that share none are zero. */
static void pair_products(const mechsim_projection *c, const double *J, const double *w,
                          double *S) {
  const int64_t n = c->n, m = c->m;
  const int64_t *rows = c->pair_rows, *start = c->pair_start, *shared = c->pair_cols;
  if (w && c->kernels) {
    mechsim_kernel_products(J, w, S);
    return;
  }
  memset(S, 0, m * m * sizeof(double));
  for (int64_t p = 0; p < c->pairs; p++) {
    const int64_t i = rows[2 * p], k = rows[2 * p + 1];
    const double *Ji = J + i * n, *Jk = J + k * n;
    double e = 0.0;
    if (w) {
      for (int64_t a = start[p]; a < start[p + 1]; a++) {
        const int64_t j = shared[a];
        e += Ji[j] * w[j] * Jk[j];
      }
    } else {
      for (int64_t a = start[p]; a < start[p + 1]; a++) e += Ji[shared[a]] * Jk[shared[a]];
    }
    S[i + k * m] = e;
    S[k + i * m] = e;
  }
}

/* S = J W J^T (both triangles, column-major) of J = Phi_q (row-major m x n) or J~ with
   W = winv; returns max S_ii. Each entry sums over the columns its two rows share in c's
   pattern of Phi_q (c->pairs; the entries of rows that share none are zero), or where
   there is none, over the columns where row i of J is not zero (nz: scratch of m n + m
   entries), in their order: a product with a zero factor leaves a sum as it was, so S is
   the dense sums' to the bit either way, at a fraction of them (a joint's rows touch two
   bodies' coordinates; rows of joints on other bodies share none). */
static double complement(const mechsim_projection *c, const double *J, const double *winv,
                         double *S, int64_t *nz) {
  const int64_t n = c->n, m = c->m;
  double diag = 0.0;
  if (c->pairs) {
    pair_products(c, J, winv, S);
    for (int64_t i = 0; i < m; i++)
      if (S[i + i * m] > diag) diag = S[i + i * m];
    return diag;
  }
  int64_t *count = nz + m * n;
  for (int64_t i = 0; i < m; i++) {
    const double *Ji = J + i * n;
    int64_t *cols = nz + i * n, used = 0;
    for (int64_t j = 0; j < n; j++)
      if (Ji[j] != 0.0) cols[used++] = j;
    count[i] = used;
  }
  for (int64_t i = 0; i < m; i++) {
    const double *Ji = J + i * n;
    const int64_t *cols = nz + i * n, ci = count[i];
    for (int64_t k = 0; k <= i; k++) {
      const double *Jk = J + k * n;
      double e = 0.0;
      for (int64_t a = 0; a < ci; a++) {
        const int64_t j = cols[a];
        e += Ji[j] * winv[j] * Jk[j];
      }
      S[i + k * m] = e;
      S[k + i * m] = e;
    }
    if (S[i + i * m] > diag) diag = S[i + i * m];
  }
  return diag;
}

/* W = R^-1 of the upper triangular m x m R (column-major; W upper, its lower part left as
   it was). */
static void upper_inverse(int64_t m, const double *R, double *W) {
  for (int64_t j = 0; j < m; j++) {
    W[j + j * m] = 1.0 / R[j + j * m];
    for (int64_t i = j - 1; i >= 0; i--) {        /* W[i + i m] = 1 / R_ii, made already */
      double e = 0.0;
      for (int64_t k = i + 1; k <= j; k++) e += R[i + k * m] * W[k + j * m];
      W[i + j * m] = -e * W[i + i * m];
    }
  }
}

/* An upper bound of ||S^-1||_1 from the upper Cholesky factor R of S = R^T R (column-major,
   m x m, upper triangle): with W = R^-1 (into Winv), S^-1 = W W^T, so ||S^-1||_1 is at most
   ||W||_1 ||W||_inf and sqrt(m) ||W||_F^2. */
double mechsim_inverse_norm_bound(int64_t m, const double *R, double *Winv) {
  double frob = 0.0, rows = 0.0, cols = 0.0;
  upper_inverse(m, R, Winv);
  for (int64_t j = 0; j < m; j++) {
    double col = 0.0;
    for (int64_t i = 0; i <= j; i++) {
      col += fabs(Winv[i + j * m]);
      frob += Winv[i + j * m] * Winv[i + j * m];
    }
    if (col > cols) cols = col;
  }
  for (int64_t i = 0; i < m; i++) {
    double row = 0.0;
    for (int64_t j = i; j < m; j++) row += fabs(Winv[i + j * m]);
    if (row > rows) rows = row;
  }
  return fmin(rows * cols, sqrt((double)m) * frob);
}

/* The Cholesky factor R (upper, S = R^T R) of the symmetric positive definite m x m S
   (column-major, its upper triangle read) into the upper triangle of R (R may be S; its
   strictly lower part is left as it was), in plain loops, as LAPACK's dpotf2 does it: a
   few rows, where BLAS's per-call cost exceeds the arithmetic (`small_lu`). 1 where a
   pivot is not positive (S not positive definite, as dpotrf's info > 0). */
static int small_cholesky(int64_t m, const double *S, double *R) {
  for (int64_t j = 0; j < m; j++) {
    double d = S[j * m + j];
    for (int64_t k = 0; k < j; k++) d -= R[j * m + k] * R[j * m + k];
    if (!(d > 0.0)) return 1;
    const double rjj = sqrt(d), inv = 1.0 / rjj;   /* dpotf2 scales the row by 1/rjj */
    R[j * m + j] = rjj;
    for (int64_t i = j + 1; i < m; i++) {
      double e = S[i * m + j];
      for (int64_t k = 0; k < j; k++) e -= R[i * m + k] * R[j * m + k];
      R[i * m + j] = e * inv;
    }
  }
  return 0;
}

/* b = S^-1 b from the factor R of `small_cholesky` (dpotrs's two triangular solves), with
   rdiag the reciprocals of R's diagonal (`cholesky` keeps them): a division's latency is
   several multiplications', and the solves' sums are short chains. */
static void cholesky_solve(int64_t m, const double *R, const double *rdiag, double *b) {
  for (int64_t j = 0; j < m; j++) {                /* R^T y = b */
    double e = b[j];
    for (int64_t k = 0; k < j; k++) e -= R[j * m + k] * b[k];
    b[j] = e * rdiag[j];
  }
  for (int64_t j = m - 1; j >= 0; j--) {           /* R x = y */
    double e = b[j];
    for (int64_t k = j + 1; k < m; k++) e -= R[k * m + j] * b[k];
    b[j] = e * rdiag[j];
  }
}

/* out = J x for J (m x n row-major, Phi_q or J~): the model's kernel where c has one,
   else each row over its entries of c's pattern where it has one (the products left out
   are of an exact zero: the same sums), or over every entry. */
static void rows_times(const mechsim_projection *c, const double *J, const double *x,
                       double *out) {
  const int64_t n = c->n;
  if (c->kernels) {
    mechsim_kernel_rows(J, x, out);
    return;
  }
  for (int64_t i = 0; i < c->m; i++) {
    const double *Ji = J + i * n;
    double s = 0.0;
    if (c->pairs) {
      for (int64_t a = c->row_start[i]; a < c->row_start[i + 1]; a++)
        s += Ji[c->row_cols[a]] * x[c->row_cols[a]];
    } else {
      for (int64_t j = 0; j < n; j++) s += Ji[j] * x[j];
    }
    out[i] = s;
  }
}

/* out = J^T y, as `rows_times` by columns. */
static void cols_times(const mechsim_projection *c, const double *J, const double *y,
                       double *out) {
  const int64_t n = c->n;
  if (c->kernels) {
    mechsim_kernel_cols(J, y, out);
    return;
  }
  for (int64_t j = 0; j < n; j++) {
    double s = 0.0;
    if (c->pairs) {
      for (int64_t a = c->col_start[j]; a < c->col_start[j + 1]; a++)
        s += J[c->col_rows[a] * n + j] * y[c->col_rows[a]];
    } else {
      for (int64_t i = 0; i < c->m; i++) s += J[i * n + j] * y[i];
    }
    out[j] = s;
  }
}

/* Whether an m x n matrix has c's pattern of Phi_q (c has one, of these sizes). */
static int patterned(const mechsim_projection *c, int64_t m, int64_t n) {
  return c && c->pairs && m == c->m && n == c->n;
}

/* `small_cholesky` of S (m x m, both triangles) into R on c's pattern of L
   (layout._cholesky_pattern: the entries of S's pattern and their fill, each a sum over
   the columns where its row and column have entries): the products it leaves out are of
   an exact zero, so R is small_cholesky's to the bit, its other entries left as they
   were in R (zero: S's, or set by the caller). 0: done; 1: not positive definite. */
static int pattern_cholesky(const mechsim_projection *c, const double *S, double *R) {
  const int64_t m = c->m, *ij = c->chol_ij, *start = c->chol_start, *ks = c->chol_ks;
  double inv = 0.0;
  if (c->kernels) return mechsim_kernel_cholesky(S, R);
  for (int64_t p = 0; p < c->chol_ops; p++) {
    const int64_t i = ij[2 * p], j = ij[2 * p + 1];
    double e = S[i * m + j];
    for (int64_t a = start[p]; a < start[p + 1]; a++) {
      const int64_t k = ks[a];
      e -= R[i * m + k] * R[j * m + k];
    }
    if (i == j) {                                   /* each column's diagonal first */
      if (!(e > 0.0)) return 1;
      const double rjj = sqrt(e);
      inv = 1.0 / rjj;
      R[j * m + j] = rjj;
    } else {
      R[i * m + j] = e * inv;
    }
  }
  return 0;
}

/* `cholesky_solve` on c's pattern of L where it has one (the products it leaves out are
   of an exact zero). */
static void factor_solve(const mechsim_projection *c, const double *R, const double *rdiag,
                         double *b) {
  const int64_t m = c->m;
  if (!c->chol_ops) {
    cholesky_solve(m, R, rdiag, b);
    return;
  }
  if (c->kernels) {
    mechsim_kernel_solve(R, rdiag, b);
    return;
  }
  for (int64_t j = 0; j < m; j++) {                /* R^T y = b */
    double e = b[j];
    for (int64_t a = c->lrow_start[j]; a < c->lrow_start[j + 1]; a++) {
      const int64_t k = c->lrow_cols[a];
      e -= R[j * m + k] * b[k];
    }
    b[j] = e * rdiag[j];
  }
  for (int64_t j = m - 1; j >= 0; j--) {           /* R x = y */
    double e = b[j];
    for (int64_t a = c->lcol_start[j]; a < c->lcol_start[j + 1]; a++) {
      const int64_t k = c->lcol_rows[a];
      e -= R[k * m + j] * b[k];
    }
    b[j] = e * rdiag[j];
  }
}

/* The Cholesky factor of S = J W J^T in place (upper triangle: `small_cholesky`, or
   LAPACK's dpotrf with `lapack`, as the multipliers take it to agree with the Python path's
   state by state to round-off of the same algorithm); 1 where it fails or, with
   min_rcond >= 0, LAPACK's estimate of 1/cond_1 is not above min_rcond. The norm is
   bounded by m max S_ii, as dense.cholesky_conditioned bounds it. LAPACK's estimate
   (dpocon) bounds ||S^-1||_1 from below, so where the rigorous upper bound of
   `mechsim_inverse_norm_bound` already puts 1/cond_1 above twice min_rcond (the factor for
   the round-off of both), dpocon would accept too and is not called: the same decisions,
   a few triangular sums instead of LAPACK's estimator. */
static int cholesky(mechsim_projection *c, double *S, double diag, double min_rcond,
                    int lapack) {
  char uplo = 'U';
  int M = (int)c->m, info = 0;
  if (lapack) {
    mechsim_dpotrf(&uplo, &M, S, &M, &info);
    if (info != 0) return 1;
  } else if (c->chol_ops ? pattern_cholesky(c, S, S) : small_cholesky(c->m, S, S)) {
    return 1;
  }
  for (int64_t j = 0; j < c->m; j++) c->rdiag[j] = 1.0 / S[j + j * c->m];
  if (min_rcond >= 0.0) {
    double anorm = (double)c->m * diag, rcond = 0.0;
    const double bound = anorm * mechsim_inverse_norm_bound(c->m, S, c->Winv);
    if (isfinite(bound) && bound * (2.0 * min_rcond) < 1.0) return 0;
    mechsim_dpocon(&uplo, &M, S, &M, &anorm, &rcond, c->cw, c->iwork, &info);
    if (info != 0 || !(rcond > min_rcond)) return 1;
  }
  return 0;
}

/* A = J W^(1/2) (row-major m x n; A may be J). */
static void scale_columns(const mechsim_projection *c, const double *J, double *A) {
  const int64_t n = c->n;
  if (c->pairs) {                    /* the entries of Phi_q's pattern: the others are 0 */
    if (A != J) memset(A, 0, c->m * n * sizeof(double));
    for (int64_t i = 0; i < c->m; i++)
      for (int64_t a = c->row_start[i]; a < c->row_start[i + 1]; a++) {
        const int64_t j = c->row_cols[a];
        A[i * n + j] = J[i * n + j] * c->wsqrt[j];
      }
    return;
  }
  for (int64_t i = 0; i < c->m; i++)
    for (int64_t j = 0; j < n; j++) A[i * n + j] = J[i * n + j] * c->wsqrt[j];
}

/* LAPACK's dgesdd of A = J~ (row-major m x n, m <= n; destroyed) with `jobz`: c->sig
   (largest first) and, with 'S', the right singular vectors of J~ as the columns of c->U
   (n x m, column-major) and the left ones as the rows of c->VT (m x m, column-major):
   row-major J~ is J~^T column-major, and J~^T = U S VT. 1 where dgesdd fails. */
static int dgesdd_of(mechsim_projection *c, double *A, char jobz) {
  int N = (int)c->n, M = (int)c->m, LW = (int)c->lwork, info = 0;
  mechsim_dgesdd(&jobz, &N, &M, A, &N, c->sig, c->U, &N, c->VT, &M, c->svd_work, &LW,
                 c->iwork, &info);
  return info != 0;
}

/* The thin SVD (dgesdd_of with 'S'). */
static int scaled_svd(mechsim_projection *c, double *A) { return dgesdd_of(c, A, 'S'); }

/* x, y = c x - s y, s x + c y (n entries each): a plane rotation of two rows; in pairs of
   entries, which compilers take two at a time. */
static void rotate_rows(int64_t n, double c, double s, double *restrict x, double *restrict y) {
  int64_t l = 0;
  for (; l + 1 < n; l += 2) {
    const double x0 = x[l], x1 = x[l + 1], y0 = y[l], y1 = y[l + 1];
    x[l] = c * x0 - s * y0;
    x[l + 1] = c * x1 - s * y1;
    y[l] = s * x0 + c * y0;
    y[l + 1] = s * x1 + c * y1;
  }
  for (; l < n; l++) {
    const double x0 = x[l], y0 = y[l];
    x[l] = c * x0 - s * y0;
    y[l] = s * x0 + c * y0;
  }
}

/* x^T y over n entries, the even and the odd ones summed apart. */
static double dot_pairs(int64_t n, const double *x, const double *y) {
  double even = 0.0, odd = 0.0;
  int64_t l = 0;
  for (; l + 1 < n; l += 2) {
    even += x[l] * y[l];
    odd += x[l + 1] * y[l + 1];
  }
  if (l < n) even += x[l] * y[l];
  return even + odd;
}

/* The rows up to which the monitor's measure takes `jacobi_svd` (at most this many rows it
   costs fewer instructions than dgesdd: 52 k against 92 k on the crank-rocker's 8 x 9 J~,
   232 k against 320 k on the double four-bar's 14 x 15; 1.5 M against 0.9 M at 26 x 27). */
#define JACOBI_ROWS 16
/* Sweeps after which `jacobi_svd` gives up (7 or 8 settle the mechanisms above). */
#define JACOBI_SWEEPS 30

/* The thin SVD of J~ (row-major m x n, m <= n) by one-sided Jacobi (Hestenes) into A
   (m x n): plane rotations of the rows, swept pair by pair until each pair is orthogonal
   to within m eps of its norms, make A = P J~ with P orthogonal and A's rows sigma_l times
   the right singular vectors. Where c->jacobi_warm, the rows start rotated by the last
   SVD's P (c->jacobi_from): J~ moves little from one step's end to the next, and its
   rows so rotated are nearly orthogonal already (docs/design-notes.md); else from J~
   itself. Into c->sig, c->U and c->VT as dgesdd_of
   leaves them (largest first; a vector's sign may differ); its singular values are
   accurate to the largest's round-off. 1 where a row's norm is not positive and finite or
   the sweeps do not settle within JACOBI_SWEEPS (A is then left rotated; the next SVD
   starts afresh). */
static int jacobi_svd(mechsim_projection *c, const double *Jt, double *A) {
  const int64_t m = c->m, n = c->n;
  double *Q = c->svd_work, *d = Q + m * m;     /* P: row i at Q + i m; squared norms */
  int64_t *order = c->perm;
  const double tol = (double)m * DBL_EPSILON;
  const int warm = (int)c->jacobi_warm;
  c->jacobi_warm = 0;                              /* 1 again once this SVD settles */
  if (warm) {
    /* P's rows made orthonormal again (modified Gram-Schmidt): the rotations' round-off
       would otherwise add up from one SVD to the next */
    memcpy(Q, c->jacobi_from, m * m * sizeof(double));
    for (int64_t i = 0; i < m; i++) {
      double *Pi = Q + i * m;
      for (int64_t k = 0; k < i; k++) {
        const double *Pk = Q + k * m;
        const double e = dot_pairs(m, Pi, Pk);
        for (int64_t r = 0; r < m; r++) Pi[r] -= e * Pk[r];
      }
      const double norm = sqrt(dot_pairs(m, Pi, Pi));
      if (!(norm > 0.5)) return 1;             /* not a rotation: measured afresh */
      for (int64_t r = 0; r < m; r++) Pi[r] /= norm;
    }
    for (int64_t i = 0; i < m; i++) {
      double *Ai = A + i * n;
      memset(Ai, 0, n * sizeof(double));
      for (int64_t r = 0; r < m; r++) {
        const double p = Q[i * m + r];
        const double *Jr = Jt + r * n;
        for (int64_t j = 0; j < n; j++) Ai[j] += p * Jr[j];
      }
    }
  } else {
    memcpy(A, Jt, m * n * sizeof(double));
    memset(Q, 0, m * m * sizeof(double));
    for (int64_t i = 0; i < m; i++) Q[i + i * m] = 1.0;
  }
  int settled = 0;
  for (int sweep = 0; sweep < JACOBI_SWEEPS && !settled; sweep++) {
    settled = 1;
    for (int64_t i = 0; i < m; i++) d[i] = dot_pairs(n, A + i * n, A + i * n);  /* afresh */
    for (int64_t i = 0; i + 1 < m; i++)
      for (int64_t j = i + 1; j < m; j++) {
        const double g = dot_pairs(n, A + i * n, A + j * n);
        if (!(fabs(g) > tol * sqrt(d[i]) * sqrt(d[j]))) continue;  /* no product of d's:
                                                             they may underflow together */
        settled = 0;
        /* The rotation by t = tan, |t| <= 1, with the sign of zeta = (d_j - d_i) / (2 g),
           that makes rows i and j orthogonal, from h = |(a, b)|, a = |d_j - d_i|,
           b = 2 |g|: |t| = b / (a + h), cos = sqrt((a + h) / (2 h)), |sin| =
           b / sqrt(2 h (a + h)), sums of positive terms only, and three roots and
           quotients in a row where zeta, t and cos took five. */
        const double diff = d[j] - d[i], a = fabs(diff), b = 2.0 * fabs(g);
        const double sign = diff == 0.0 || (diff > 0.0) == (g > 0.0) ? 1.0 : -1.0;
        const double h = sqrt(a * a + b * b), ah = a + h;
        const double cs = sqrt(ah / (2.0 * h)), sn = sign * b / sqrt(2.0 * h * ah);
        const double tg = sign * b * g / ah;
        rotate_rows(n, cs, sn, A + i * n, A + j * n);
        rotate_rows(m, cs, sn, Q + i * m, Q + j * m);
        d[i] -= tg;
        d[j] += tg;
      }
  }
  if (!settled) return 1;
  for (int64_t i = 0; i < m; i++) {
    d[i] = sqrt(dot_pairs(n, A + i * n, A + i * n));
    if (!(d[i] > 0.0 && d[i] <= DBL_MAX)) return 1;
    int64_t k = i;                                  /* insert i by falling norm */
    for (; k > 0 && d[order[k - 1]] < d[i]; k--) order[k] = order[k - 1];
    order[k] = i;
  }
  for (int64_t l = 0; l < m; l++) {
    const int64_t i = order[l];
    const double scale = 1.0 / d[i];
    c->sig[l] = d[i];
    for (int64_t j = 0; j < n; j++) c->U[j + l * n] = A[i * n + j] * scale;
    for (int64_t r = 0; r < m; r++) c->VT[l + r * m] = Q[r + i * m];
  }
  memcpy(c->jacobi_from, Q, m * m * sizeof(double));
  c->jacobi_warm = 1;
  return 0;
}

/* The singular values alone (dgesdd without vectors) into c->sig, largest first. */
static int singular_values(mechsim_projection *c, double *A) { return dgesdd_of(c, A, 'N'); }

/* The Householder reflection H = I - beta v v^T taking column k of the column-major M x N
   matrix A (rows k..M-1) to alpha e_k, applied to its columns k+1..N-1; v is left in
   column k (rows k..), beta in *beta (0 where the column is zero: H = I). Returns alpha
   (-sign(a_kk) |a_k|). J~ is sparse, and so are the first reflectors: the sums and
   updates run over the rows where v is not zero (the products left out are of an exact
   zero), a column v does not meet is left as it is. */
static double reflect_column(double *A, int64_t M, int64_t N, int64_t k, double *beta) {
  double *col = A + k * M, norm = 0.0;
  for (int64_t i = k; i < M; i++) norm += col[i] * col[i];
  norm = sqrt(norm);
  const double alpha = col[k] > 0.0 ? -norm : norm;
  *beta = 0.0;
  if (!(norm > 0.0)) return alpha;
  *beta = 1.0 / (norm * (norm + fabs(col[k])));
  col[k] -= alpha;
  int64_t rows[SPARSE_ROWS], used = 0;
  const int sparse = M <= SPARSE_ROWS;
  if (sparse)
    for (int64_t i = k; i < M; i++)
      if (col[i] != 0.0) rows[used++] = i;
  for (int64_t j = k + 1; j < N; j++) {
    double *cj = A + j * M, e = 0.0;
    if (sparse) {
      for (int64_t u = 0; u < used; u++) e += col[rows[u]] * cj[rows[u]];
      if (e == 0.0) continue;
      e *= *beta;
      for (int64_t u = 0; u < used; u++) cj[rows[u]] -= e * col[rows[u]];
    } else {
      for (int64_t i = k; i < M; i++) e += col[i] * cj[i];
      e *= *beta;
      for (int64_t i = k; i < M; i++) cj[i] -= e * col[i];
    }
  }
  return alpha;
}

static int extremes_of(mechsim_projection *c, double *A, int64_t M, int64_t N, int64_t kk,
                       double *out);

/* The accelerations where the Cholesky factor of J W J^T is too ill-conditioned, as
   Projection.accelerations computes them by the SVD of J~ = J W^(1/2) (m <= n) where
   truncation drops nothing: every singular value above cut * sigma_max (the extremes of
   the QR's R, `extremes_of`). Then x = W^(1/2) Q, x -= V V^T x - V S^-1 U^T g, qdd = W^(1/2) x, which
   is x -= Q1 (Q1^T x - R^-T g) for the Householder QR J~^T = Q1 R (V V^T = Q1 Q1^T, J~+ =
   Q1 R^-T): the same numbers to round-off (both backward stable), without the singular
   vectors. Into c->out as [v; qdd]. 1 where some singular value is at or below the cut
   (the band: Python truncates and interpolates) or the extremes fail. */
static int svd_accelerations(mechsim_projection *c, const double *J, const double *g,
                             double cut) {
  const int64_t n = c->n, m = c->m;
  double *A = c->A, *x = c->x, *ex = c->cw, *R = c->X;
  if (m > n) return 1;
  scale_columns(c, J, A);                      /* J~^T: column-major n x m */
  double *beta = c->ext_work + 6 * m, *rdiag = beta + m;   /* after extremes_of's 6 m */
  for (int64_t k = 0; k < m; k++) {            /* Householder QR, reflectors below R */
    rdiag[k] = reflect_column(A, n, m, k, beta + k);
    if (!(beta[k] > 0.0)) return 1;
  }
  for (int64_t j = 0; j < m; j++)              /* R's singular values are J~'s */
    for (int64_t i = 0; i < m; i++)
      R[i + j * m] = i < j ? A[i + j * n] : (i == j ? rdiag[j] : 0.0);
  if (extremes_of(c, R, m, m, m - 1, ex) || !(ex[1] > 0.0) || !(ex[0] > cut * ex[1])) return 1;
  double *a = rdiag + m, *b = a + m, *w = b + m;
  for (int64_t j = 0; j < n; j++) x[j] = c->wsqrt[j] * c->Q[j];
  memcpy(w, x, n * sizeof(double));            /* a = Q1^T x */
  for (int64_t k = 0; k < m; k++) {
    const double *v = A + k * n;
    double e = 0.0;
    for (int64_t i = k; i < n; i++) e += v[i] * w[i];
    e *= beta[k];
    for (int64_t i = k; i < n; i++) w[i] -= e * v[i];
  }
  for (int64_t i = 0; i < m; i++) {            /* b = R^-T g; y = a - b into w */
    double e = g[i];
    for (int64_t k = 0; k < i; k++) e -= A[k + i * n] * b[k];
    b[i] = e / rdiag[i];
    a[i] = w[i] - b[i];
  }
  memcpy(w, a, m * sizeof(double));            /* Q1 y */
  memset(w + m, 0, (n - m) * sizeof(double));
  for (int64_t k = m - 1; k >= 0; k--) {
    const double *v = A + k * n;
    double e = 0.0;
    for (int64_t i = k; i < n; i++) e += v[i] * w[i];
    e *= beta[k];
    for (int64_t i = k; i < n; i++) w[i] -= e * v[i];
  }
  memcpy(c->out, c->v, n * sizeof(double));
  for (int64_t j = 0; j < n; j++) c->out[n + j] = c->wsqrt[j] * (x[j] - w[j]);
  return 0;
}

int mechsim_projection_accelerations(mechsim_projection *c, double t, double min_rcond,
                                     double cut) {
  const int64_t n = c->n, m = c->m;
  const double *winv = c->winv;
  double *J = c->J, *g = c->g, *wq = c->wq, *lam = c->lam, *S = c->S;
  memset(J, 0, m * n * sizeof(double));
  memset(g, 0, m * sizeof(double));
  mechsim_dynamics_terms(c->q, c->v, t, c->p, J, g);      /* Phi_q and gamma, their bits */
  for (int64_t j = 0; j < n; j++) wq[j] = winv[j] * c->Q[j];
  rows_times(c, J, wq, lam);
  for (int64_t i = 0; i < m; i++) lam[i] -= g[i];                     /* J W Q - gamma */
  const double diag = complement(c, J, winv, S, c->nz);
  if (cholesky(c, S, diag, min_rcond, 0))
    return cut > 0.0 ? svd_accelerations(c, J, g, cut) : 1;
  factor_solve(c, S, c->rdiag, lam);
  memcpy(c->out, c->v, n * sizeof(double));
  cols_times(c, J, lam, c->tj);
  for (int64_t j = 0; j < n; j++) c->out[n + j] = wq[j] - winv[j] * c->tj[j];
  return 0;
}

/* The Lagrange multipliers at k consistent states (NumericProblem.multipliers): row s of
   Lam solves (J W J^T) lam = J W F - gamma at (ts[s], row s of Qs and Vs) under the applied
   forces in row s of Fs, by the Cholesky factor where LAPACK's estimate of 1/cond_1 is
   above min_rcond (min_rcond < 0: not estimated) and every pivot is above min_pivot
   max S_ii; done[s] says whether it did (elsewhere Python decides). Phit, unless NULL,
   gets Phi_t at each state in its row s (k x m; a driver's power is lam^T Phi_t over its
   rows). Returns the number done. */
int64_t mechsim_multipliers(mechsim_projection *c, int64_t k, const double *ts,
                            const double *Qs, const double *Vs, const double *Fs,
                            double min_rcond, double min_pivot, double *Lam, int64_t *done,
                            double *Phit) {
  const int64_t n = c->n, m = c->m;
  const double *winv = c->winv;
  double *J = c->J, *g = c->g, *wq = c->wq, *S = c->S;
  char uplo = 'U';
  int M = (int)m, nrhs = 1, info = 0;
  int64_t count = 0;
  for (int64_t s = 0; s < k; s++) {
    const double *q = Qs + s * n, *v = Vs + s * n, *F = Fs + s * n;
    double *lam = Lam + s * m;
    if (Phit) {
      memset(Phit + s * m, 0, m * sizeof(double));
      mechsim_phi_t(q, ts[s], c->p, Phit + s * m);
    }
    memset(J, 0, m * n * sizeof(double));
    memset(g, 0, m * sizeof(double));
    mechsim_dynamics_terms(q, v, ts[s], c->p, J, g);
    for (int64_t j = 0; j < n; j++) wq[j] = winv[j] * F[j];
    rows_times(c, J, wq, lam);
    for (int64_t i = 0; i < m; i++) lam[i] -= g[i];
    done[s] = 0;
    const double diag = complement(c, J, winv, S, c->nz);
    if (cholesky(c, S, diag, min_rcond, 1)) continue;
    int small = 0;
    for (int64_t i = 0; i < m; i++) small |= !(S[i + i * m] * S[i + i * m] > min_pivot * diag);
    if (small) continue;
    mechsim_dpotrs(&uplo, &M, &nrhs, S, &M, lam, &M, &info);
    if (info == 0) {
      done[s] = 1;
      count++;
    }
  }
  return count;
}

/* x -= W J^T (S^-1 r), S the Cholesky factor in place; r is overwritten. */
static int correct(mechsim_projection *c, const double *J, const double *S, double *r,
                   double *x) {
  const int64_t n = c->n;
  factor_solve(c, S, c->rdiag, r);
  cols_times(c, J, r, c->tj);
  for (int64_t j = 0; j < n; j++) x[j] -= c->winv[j] * c->tj[j];
  return 0;
}

/* The velocity c->v projected in place onto J v + Phi_t = 0 in the mass metric,
   v -= W J^T S^-1 (J v + Phi_t), with J = c->J Phi_q at c->q and S = c->S the Cholesky
   factor of `cholesky`. 0: done; 1: declined. */
static int project_velocity(mechsim_projection *c, double t) {
  const int64_t m = c->m;
  double *r = c->r;
  memset(r, 0, m * sizeof(double));
  mechsim_phi_t(c->q, t, c->p, r);
  rows_times(c, c->J, c->v, c->tj);
  for (int64_t i = 0; i < m; i++) r[i] += c->tj[i];
  return correct(c, c->J, c->S, r, c->v);
}

/* c->q projected in place onto the constraints in the mass metric, as
   NumericProblem.project_state's positions: a chord Newton on Phi with the one Cholesky
   factor of J W J^T at the given q (stopping at max|Phi| <= tol or at round-off: the
   residual shrinks by less than stall_ratio and lies within stall_span tol; then `extra`
   further iterations); c->J is Phi_q at the new q after it (evaluated with each Phi, into
   the scratch c->J1), c->S the factor at the given q. 0: projected, c->count the Newton
   iterations; 2: max|Phi| <= skip_tol, left as it
   is (c->J is Phi_q there); 1: declined (the factor fails, or with min_rcond >= 0 its
   condition estimate is not above it; the chord does not converge within max_iter). */
static int project_positions(mechsim_projection *c, double t, double skip_tol, double tol,
                             double min_rcond, int64_t extra, int64_t max_iter) {
  const int64_t n = c->n, m = c->m;
  double *q = c->q, *J = c->J, *phi = c->phi, *r = c->r, *S = c->S;
  memset(J, 0, m * n * sizeof(double));
  mechsim_position_terms(q, t, c->p, phi, J);   /* Phi and Phi_q, their bits, at once */
  double err = max_abs(m, phi);
  if (err <= skip_tol) return 2;
  const double diag = complement(c, J, c->winv, S, c->nz);
  if (cholesky(c, S, diag, min_rcond, 0)) return 1;
  /* Phi_q at each new q with its Phi (one call, shared sines), into J1: the chord goes on
     with J at the given q; the last one is Phi_q at the projected q */
  double *Jq = c->J1;
  memset(Jq, 0, m * n * sizeof(double));
  double prev = INFINITY;
  int64_t count = 0;
  for (int64_t k = 0;; k++) {
    if (isnan(err)) return 1;
    if (err <= tol || (err > c->stall_ratio * prev && err <= c->stall_span * tol)) break;
    if (k == max_iter) return 1;
    prev = err;
    memcpy(r, phi, m * sizeof(double));
    if (correct(c, J, S, r, q)) return 1;
    count++;
    mechsim_position_terms(q, t, c->p, phi, Jq);
    err = max_abs(m, phi);
  }
  for (int64_t k = 0; k < extra; k++) {
    memcpy(r, phi, m * sizeof(double));
    if (correct(c, J, S, r, q)) return 1;
    count++;
    mechsim_position_terms(q, t, c->p, phi, Jq);
  }
  if (count > 0) memcpy(J, Jq, m * n * sizeof(double));
  c->count = count;
  return 0;
}

/* (c->q, c->v) projected in place onto the constraints in the mass metric, as
   NumericProblem.project_state: the positions (`project_positions`), then the velocity
   (`project_velocity`) with J at the new q and the factor at the given q. Returns as
   `project_positions`, or 1 where the velocity's projection declines. */
int mechsim_project_state(mechsim_projection *c, double t, double skip_tol, double tol,
                          double min_rcond, int64_t extra, int64_t max_iter) {
  const int status = project_positions(c, t, skip_tol, tol, min_rcond, extra, max_iter);
  return status ? status : project_velocity(c, t);
}

/* The state (t, q, v) projected in place as mechsim_project_state with skip_tol = tol (no
   condition test, no extra iterations), but the velocity of the moved state projected on
   the factor at its new q (the chord's factor at the old q would leave J v off by
   |dJ| |dv|; a projection there first changes nothing but round-off: the projection onto
   J v + Phi_t = 0 in the mass metric takes v + W J^T y where it takes v): 0 (projected),
   2 (within tol already, left) or 1 (declined: left, for the Python path). */
static int settle_state(mechsim_projection *c, double t, double *q, double *v, double tol,
                        int64_t max_iter) {
  const int64_t n = c->n;
  memcpy(c->q, q, n * sizeof(double));
  memcpy(c->v, v, n * sizeof(double));
  const int status = project_positions(c, t, tol, tol, -1.0, 0, max_iter);
  if (status != 0) return status;
  /* c->J is Phi_q at the new q (status 0 took a Newton step at least: Phi was above
     tol = skip_tol): its own factor makes J v + Phi_t vanish */
  const double diag = complement(c, c->J, c->winv, c->S, c->nz);
  if (cholesky(c, c->S, diag, -1.0, 0) || project_velocity(c, t)) return 1;
  memcpy(q, c->q, n * sizeof(double));
  memcpy(v, c->v, n * sizeof(double));
  return 0;
}

/* The k states (T[i], Q[i, :], V[i, :]) projected in place, each as mechsim_project_state
   with skip_tol = tol = tols[i] (no condition test, no extra iterations), the velocity
   of a moved state projected once more on the factor at its new q (the chord's factor
   at the old q leaves J v off by |dJ| |dv|): status[i] is 0 (projected), 2 (within
   tols[i] already, left) or 1 (declined: left, for the Python path). Output samples of a
   step settled in one call. */
void mechsim_project_states(mechsim_projection *c, int64_t k, const double *T, double *Q,
                            double *V, const double *tols, int64_t max_iter,
                            int64_t *status) {
  for (int64_t i = 0; i < k; i++)
    status[i] = settle_state(c, T[i], Q + i * c->n, V + i * c->n, tols[i], max_iter);
}

/* ---- the singularity monitor and the hybrid's LU test ---- */

/* J~ = Phi_q W^(1/2) at (q, t) into Jt (row-major m x n). */
static void scaled_jacobian(mechsim_projection *c, const double *q, double t, double *Jt) {
  memset(Jt, 0, c->m * c->n * sizeof(double));
  mechsim_phi_q(q, t, c->p, Jt);
  scale_columns(c, Jt, Jt);
}

/* The singularity monitor's measurement (SingularityMonitor.measure, m <= n): the
   extreme singular values of J~ = Phi_q W^(1/2) at c->q (`jacobi_svd` up to JACOBI_ROWS
   rows, else or where it gives up LAPACK's dgesdd) and, with
   eps > 0, their derivatives along the motion, u^T dJ~ v with dJ~ from J~ at
   (q + eps v, t + eps), and the Frobenius norm of dJ~/dt there.
   out: [s_min, s_max, ds_min, ds_max, u_min (m), ||dJ~/dt||_F]; J~ in Jt.
   1 where the SVD fails. */
int mechsim_measure(mechsim_projection *c, double t, double eps, double *out, double *Jt) {
  const int64_t n = c->n, m = c->m;
  const double *U = c->U, *VT = c->VT;
  double *J1 = c->J1, *q1 = c->q1;
  scaled_jacobian(c, c->q, t, Jt);
  if (m > JACOBI_ROWS || jacobi_svd(c, Jt, c->A)) {
    memcpy(c->A, Jt, m * n * sizeof(double));
    if (scaled_svd(c, c->A)) return 1;
  }
  const int64_t k = m - 1;
  out[0] = c->sig[k];
  out[1] = c->sig[0];
  out[2] = out[3] = out[4 + m] = 0.0;
  for (int64_t i = 0; i < m; i++) out[4 + i] = VT[k + i * m];
  if (eps > 0.0) {
    for (int64_t j = 0; j < n; j++) q1[j] = c->q[j] + eps * c->v[j];
    scaled_jacobian(c, q1, t + eps, J1);
    double dmin = 0.0, dmax = 0.0, frob = 0.0;
    for (int64_t i = 0; i < m; i++) {
      double smin = 0.0, smax = 0.0;
      for (int64_t j = 0; j < n; j++) {
        const double d = J1[i * n + j] - Jt[i * n + j];
        smin += d * U[j + k * n];
        smax += d * U[j];
        frob += d * d;
      }
      dmin += VT[k + i * m] * smin;
      dmax += VT[i * m] * smax;
    }
    out[2] = dmin / eps;
    out[3] = dmax / eps;
    out[4 + m] = sqrt(frob) / eps;
  }
  return 0;
}

/* J~ = Phi_q W^1/2 at (c->q, t) into Jt; returns |J~ - Jm|_F (Jm: m x n, row-major), the
   singularity monitor's Weyl bound on how far the singular values moved since Jm. */
double mechsim_change(mechsim_projection *c, double t, const double *Jm, double *Jt) {
  const int64_t size = c->m * c->n;
  scaled_jacobian(c, c->q, t, Jt);
  double e = 0.0;
  for (int64_t i = 0; i < size; i++) {
    const double d = Jt[i] - Jm[i];
    e += d * d;
  }
  return sqrt(e);
}

/* |X P|_F^2 for X (m x n) and P (n x r), both row-major; with `start`, X has entries only
   in row i's columns cols[start[i]:start[i + 1]] (Phi_q's pattern: the products left out
   are of an exact zero, the same sums). */
static double product_square(int64_t m, int64_t n, int64_t r, const double *X, const double *P,
                             const int64_t *start, const int64_t *cols) {
  double total = 0.0;
  for (int64_t i = 0; i < m; i++) {
    const double *Xi = X + i * n;
    for (int64_t l = 0; l < r; l++) {
      double s = 0.0;
      if (start) {
        for (int64_t a = start[i]; a < start[i + 1]; a++) s += Xi[cols[a]] * P[cols[a] * r + l];
      } else {
        for (int64_t j = 0; j < n; j++) s += Xi[j] * P[j * r + l];
      }
      total += s * s;
    }
  }
  return total;
}

/* How fast sigma_min/sigma_max can fall along a step from its end a to its end b (the
   singularity monitor's fall rates, mechsim.linalg.dense.fall_rates): J~ taken as the cubic
   through J~ (Ja, Jb) and D = dJ~/dt (Da, Db) at both ends, C = (Jb - Ja)/h - (Da + Db)/2,
   P_e the ends' fall bases (n x r, row-major); in = (ta, tb, smin_a, smax_a, rise_a,
   smin_b, smax_b, rise_b), out = (rate seen from a, rate seen from b). C goes to work
   (m x n). J~, D and so C have entries only in Phi_q's pattern, which c gives where it
   has one of these sizes (c may be NULL): the products then skip its zeros. */
void mechsim_fall_rates(const mechsim_projection *c, int64_t m, int64_t n, int64_t r,
                        const double *in, const double *Ja, const double *Da,
                        const double *Pa, const double *Jb, const double *Db,
                        const double *Pb, double *work, double *out) {
  const int64_t *start = patterned(c, m, n) ? c->row_start : NULL;
  const int64_t *cols = start ? c->row_cols : NULL;
  const double scale = 1.0 / (in[1] - in[0]);
  double cc = 0.0;
  for (int64_t i = 0; i < m * n; i++) {
    work[i] = (Jb[i] - Ja[i]) * scale - 0.5 * (Da[i] + Db[i]);
    cc += work[i] * work[i];
  }
  const double da_a = product_square(m, n, r, Da, Pa, start, cols);
  const double db_a = product_square(m, n, r, Db, Pa, start, cols);
  const double da_b = product_square(m, n, r, Da, Pb, start, cols);
  const double db_b = product_square(m, n, r, Db, Pb, start, cols);
  const double c_a = product_square(m, n, r, work, Pa, start, cols);
  const double c_b = product_square(m, n, r, work, Pb, start, cols);
  const double rise = fmax(in[4], in[7]) + 1.5 * sqrt(cc);
  const double fall_a = sqrt(fmax(da_a, db_a)) + 1.5 * sqrt(c_a);
  const double fall_b = sqrt(fmax(da_b, db_b)) + 1.5 * sqrt(c_b);
  out[0] = (fall_a + in[2] / in[3] * rise) / in[3];
  out[1] = (fall_b + in[5] / in[6] * rise) / in[6];
}

/* min(||D||_F, (||D||_1 ||D||_inf)^(1/2)), an upper bound of ||D||_2, of D = A - B (m x n
   row-major, both of Phi_q's pattern where c has it: the sums then skip its zeros, to
   the same bits); cols: n scratch. */
static double difference_norm(const mechsim_projection *c, int64_t m, int64_t n,
                              const double *A, const double *B, double *cols) {
  double frob = 0.0, rows = 0.0, colmax = 0.0;
  const int sparse = patterned(c, m, n);
  memset(cols, 0, n * sizeof(double));
  for (int64_t i = 0; i < m; i++) {
    double r = 0.0;
    const int64_t first = sparse ? c->row_start[i] : 0;
    const int64_t last = sparse ? c->row_start[i + 1] : n;
    for (int64_t a = first; a < last; a++) {
      const int64_t j = sparse ? c->row_cols[a] : a;
      const double d = A[i * n + j] - B[i * n + j], e = fabs(d);
      frob += d * d;
      r += e;
      cols[j] += e;
    }
    if (r > rows) rows = r;
  }
  for (int64_t j = 0; j < n; j++)
    if (cols[j] > colmax) colmax = cols[j];
  const double holder = sqrt(rows * colmax);
  frob = sqrt(frob);
  return holder < frob ? holder : frob;
}

/* The passage search's grid inside a step (SingularityMonitor._anchored): out[i] bounds
   ||J~(T[i+1], Q[i+1]) - J~(T[i], Q[i])||_2 for i < k - 1, no SVD. */
void mechsim_chords(mechsim_projection *c, int64_t k, const double *T, const double *Q,
                    double *out) {
  const int64_t n = c->n, m = c->m;
  double *prev = c->J1, *next = c->A;
  for (int64_t i = 0; i < k; i++) {
    scaled_jacobian(c, Q + i * n, T[i], next);
    if (i > 0) out[i - 1] = difference_norm(c, m, n, next, prev, c->x);
    double *swap = prev;
    prev = next;
    next = swap;
  }
}

/* sigma_kk and sigma_max of the column-major M x N matrix A (M >= N; destroyed) into out[0],
   out[1]: A reduced to an upper bidiagonal by Householder reflections from the left and the
   right (Golub-Kahan, as LAPACK's dgebd2, in plain loops: BLAS's calls cost more than
   their work at this size), its singular values by LAPACK's dlasq1 (dqds, to high relative
   accuracy, as dgesdd finds them). 1 where M < N, dlasq1 fails or A is not finite. */
static int extremes_of(mechsim_projection *c, double *A, int64_t M, int64_t N, int64_t kk,
                       double *out) {
  double *d = c->ext_work, *e = d + N, *work = e + N;
  if (M < N) return 1;
  for (int64_t k = 0; k < N; k++) {
    double beta_k;
    d[k] = reflect_column(A, M, N, k, &beta_k);      /* column k, rows k.. */
    if (k + 1 >= N) break;
    double rnorm = 0.0;                        /* row k, columns k+1.. */
    for (int64_t j = k + 1; j < N; j++) rnorm += A[k + j * M] * A[k + j * M];
    rnorm = sqrt(rnorm);
    const double y0 = A[k + (k + 1) * M];
    e[k] = y0 > 0.0 ? -rnorm : rnorm;
    if (rnorm > 0.0) {
      const double beta = 1.0 / (rnorm * (rnorm + fabs(y0)));
      double *u = work;
      for (int64_t j = k + 1; j < N; j++) u[j] = A[k + j * M];
      u[k + 1] -= e[k];
      for (int64_t i = k + 1; i < M; i++) {
        double w = 0.0;
        for (int64_t j = k + 1; j < N; j++) w += A[i + j * M] * u[j];
        w *= beta;
        for (int64_t j = k + 1; j < N; j++) A[i + j * M] -= w * u[j];
      }
    }
  }
  int NN = (int)N, info = 0;
  mechsim_dlasq1(&NN, d, e, work, &info);
  if (info != 0 || !isfinite(d[0]) || !isfinite(d[kk])) return 1;
  out[0] = d[kk];
  out[1] = d[0];
  return 0;
}

/* sigma_kk and sigma_max of J~ in c->A (destroyed; `extremes_of` on J~^T, n x m). */
static int svd_extremes(mechsim_projection *c, int64_t kk, double *out) {
  return extremes_of(c, c->A, c->n, c->m, kk, out);
}

/* sigma_kk and sigma_max of J~ at each of the k states (T[i], Q[i, :]) into out[2 i],
   out[2 i + 1] (dgesdd without vectors). 1 where an SVD fails. */
int mechsim_extremes(mechsim_projection *c, int64_t k, int64_t kk, const double *T,
                     const double *Q, double *out) {
  for (int64_t i = 0; i < k; i++) {
    scaled_jacobian(c, Q + i * c->n, T[i], c->A);
    if (svd_extremes(c, kk, out + 2 * i)) return 1;
  }
  return 0;
}

static int extreme_bounds(const mechsim_projection *c, int64_t m, int64_t n,
                          const double *J, double *G, double *H, double *out);

/* `extreme_bounds` of J~ (row-major m x n) into out[0], out[1] (a lower bound of
   sigma_min, an upper bound of sigma_max; NaN where the bounds decline), c->S and c->X as
   scratch; mechsim_extreme_bounds: of J~ at each of the k states (T[i], Q[i, :]) into
   out[2 i], out[2 i + 1]. */
void mechsim_bounds_of(mechsim_projection *c, const double *Jt, double *out) {
  if (extreme_bounds(c, c->m, c->n, Jt, c->S, c->X, out)) out[0] = out[1] = NAN;
}

void mechsim_extreme_bounds(mechsim_projection *c, int64_t k, const double *T,
                            const double *Q, double *out) {
  for (int64_t i = 0; i < k; i++) {
    scaled_jacobian(c, Q + i * c->n, T[i], c->A);
    mechsim_bounds_of(c, c->A, out + 2 * i);
  }
}

/* ||A||_1 ||A^-1||_1 of the block A = Phi_q D that Partitioned.choose picks at (c->q, t)
   for a Phi_q of full row rank (m <= n): the dependent coordinates are the first m of
   the row permutation of LU with partial pivoting of Phi_q^T. INFINITY where the
   pivoting or the block is singular. */
double mechsim_lu_condition(mechsim_projection *c, double t) {
  const int64_t n = c->n, m = c->m;
  double *J = c->J, *F = c->J1, *A = c->S, *X = c->X;
  int64_t *perm = c->perm;
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

/* ---- a DOP853 step over the compiled rate (mechsim.integrators.compiled) ---- */

/* The formulation's own rate in Python, for a state the engine declines: 0 done. */
typedef int (*mechsim_rate_t)(double, const double *, double *);

/* The rate at (t, y) into f: [v; qdd] of the projection method (kind 0, ctx a
   mechsim_projection, min_rcond and cut as mechsim_projection_accelerations takes them)
   or [zd; zdd] of the partition (kind 1, ctx a mechsim_lu), under the forces the context
   holds; where the engine declines the state, by `fallback` (counted in *python).
   Nonzero where that fails too (the Python step decides). */
static int compiled_rate(void *ctx, int64_t kind, double t, const double *y, double *f,
                         int64_t N, double min_rcond, double cut, mechsim_rate_t fallback,
                         int64_t *python) {
  int declined;
  if (kind == 0) {
    mechsim_projection *c = (mechsim_projection *)ctx;
    memcpy(c->q, y, c->n * sizeof(double));
    memcpy(c->v, y + c->n, c->n * sizeof(double));
    declined = mechsim_projection_accelerations(c, t, min_rcond, cut);
    if (!declined) memcpy(f, c->out, N * sizeof(double));
  } else {
    mechsim_lu *c = (mechsim_lu *)ctx;
    memcpy(c->y, y, N * sizeof(double));
    declined = mechsim_lu_rhs(c, t);
    if (!declined) memcpy(f, c->out, N * sizeof(double));
  }
  if (!declined) return 0;
  (*python)++;
  return fallback(t, y, f);
}

/* One accepted step of scipy's DOP853 from (t, y) with f = f(t, y): its step-size rule
   and error norm as scipy.integrate.DOP853._step_impl has them, on the coefficients
   scipy's class holds (coef: A (S x S), B, C (S), E3, E5 (S + 1)) and its controller's
   constants (in: S, t, h_abs, t_bound, direction, max_step, rtol, min_rcond, cut,
   safety, min_factor, max_factor, exponent). The stages go to the rows of K ((S + 1) x N,
   the last f_new), the step's end to y_new and f_new, and out = (t_new, h, the next
   h_abs, the engine's evaluations, the fallback's). A stage the engine declines is
   evaluated by `fallback`. 0: accepted; 1: the fallback failed (nothing changed, the
   Python step serves); 2: the step fell below scipy's smallest. */
int mechsim_dop853(void *ctx, int64_t kind, int64_t N, const double *coef, const double *in,
                   const double *y, const double *f, const double *atol, double *K,
                   double *y_new, double *f_new, double *work, double *out, void *fallback) {
  const mechsim_rate_t rate = (mechsim_rate_t)fallback;
  int64_t python = 0;
  const int64_t S = (int64_t)in[0];
  const double t = in[1], t_bound = in[3], direction = in[4], max_step = in[5];
  const double rtol = in[6], min_rcond = in[7], cut = in[8], safety = in[9];
  const double min_factor = in[10], max_factor = in[11], exponent = in[12];
  const double *A = coef, *B = coef + S * S, *C = B + S, *E3 = C + S, *E5 = E3 + S + 1;
  const double min_step = 10.0 * fabs(nextafter(t, direction * INFINITY) - t);
  double h_abs = in[2];
  int64_t nfev = 0;
  int rejected = 0;
  if (h_abs > max_step) h_abs = max_step;
  else if (h_abs < min_step) h_abs = min_step;
  for (;;) {
    out[3] = (double)(nfev - python);
    out[4] = (double)python;
    if (h_abs < min_step) return 2;
    double h = h_abs * direction, t_new = t + h;
    if (direction * (t_new - t_bound) > 0.0) t_new = t_bound;
    h = t_new - t;
    h_abs = fabs(h);
    memcpy(K, f, N * sizeof(double));
    for (int64_t s = 1; s < S; s++) {
      const double *a = A + s * S;
      for (int64_t i = 0; i < N; i++) {
        double dy = 0.0;
        for (int64_t j = 0; j < s; j++) dy += K[j * N + i] * a[j];
        work[i] = y[i] + dy * h;
      }
      nfev++;
      const int failed = compiled_rate(ctx, kind, t + C[s] * h, work, K + s * N, N,
                                       min_rcond, cut, rate, &python);
      out[3] = (double)(nfev - python);
      out[4] = (double)python;
      if (failed) return 1;
    }
    for (int64_t i = 0; i < N; i++) {
      double dy = 0.0;
      for (int64_t j = 0; j < S; j++) dy += K[j * N + i] * B[j];
      y_new[i] = y[i] + h * dy;
    }
    nfev++;
    const int failed = compiled_rate(ctx, kind, t + h, y_new, f_new, N, min_rcond, cut, rate,
                                     &python);
    out[3] = (double)(nfev - python);
    out[4] = (double)python;
    if (failed) return 1;
    memcpy(K + S * N, f_new, N * sizeof(double));
    double e5 = 0.0, e3 = 0.0;
    for (int64_t i = 0; i < N; i++) {
      const double scale = atol[i] + fmax(fabs(y[i]), fabs(y_new[i])) * rtol;
      double a5 = 0.0, a3 = 0.0;
      for (int64_t j = 0; j <= S; j++) {
        a5 += K[j * N + i] * E5[j];
        a3 += K[j * N + i] * E3[j];
      }
      a5 /= scale;
      a3 /= scale;
      e5 += a5 * a5;
      e3 += a3 * a3;
    }
    const double norm = (e5 == 0.0 && e3 == 0.0) ? 0.0 :
        h_abs * e5 / sqrt((e5 + 0.01 * e3) * (double)N);
    if (norm < 1.0) {
      double factor = norm == 0.0 ? max_factor : fmin(max_factor, safety * pow(norm, exponent));
      if (rejected) factor = fmin(1.0, factor);
      out[0] = t_new;
      out[1] = h;
      out[2] = h_abs * factor;
      return 0;
    }
    h_abs *= fmax(min_factor, safety * pow(norm, exponent));   /* NaN: min_factor */
    rejected = 1;
  }
}

/* The extra stages of DOP853's dense output for the step just taken from (t_old, y_old)
   with step h: rows first .. first + extra - 1 of K (each row s from the rows before it,
   with coefficients coef[(s - first) * width ...] and nodes coef[extra * width + s -
   first]); in = (first, extra, width, t_old, h, min_rcond, cut); out = (the engine's
   evaluations, the fallback's). 0: done; 1: the fallback failed (Python computes them). */
int mechsim_dop853_extra(void *ctx, int64_t kind, int64_t N, const double *coef,
                         const double *in, const double *y_old, double *K, double *work,
                         double *out, void *fallback) {
  int64_t python = 0;
  const int64_t first = (int64_t)in[0], extra = (int64_t)in[1], width = (int64_t)in[2];
  const double t_old = in[3], h = in[4], min_rcond = in[5], cut = in[6];
  for (int64_t e = 0; e < extra; e++) {
    const int64_t s = first + e;
    const double *a = coef + e * width;
    for (int64_t i = 0; i < N; i++) {
      double dy = 0.0;
      for (int64_t j = 0; j < s; j++) dy += K[j * N + i] * a[j];
      work[i] = y_old[i] + dy * h;
    }
    const int failed = compiled_rate(ctx, kind, t_old + coef[extra * width + e] * h, work,
                                     K + s * N, N, min_rcond, cut,
                                     (mechsim_rate_t)fallback, &python);
    out[0] = (double)(e + 1 - python);
    out[1] = (double)python;
    if (failed) return 1;
  }
  return 0;
}

/* The coefficients F ((rows + 3) x N) of DOP853's dense output over the step of length h
   from y_old to y (f: the rate at y), from its stages K (cols x N, the extra ones included)
   and scipy's matrix Dm (rows x cols), as scipy's _dense_output_impl forms them: F[0] = dy,
   F[1] = h K[0] - dy, F[2] = 2 dy - h (f + K[0]), F[3 + i] = h (Dm K)[i]. */
void mechsim_dense_coefficients(int64_t N, int64_t rows, int64_t cols, const double *Dm,
                                const double *K, const double *y_old, const double *y,
                                const double *f, double h, double *F) {
  for (int64_t j = 0; j < N; j++) {
    const double dy = y[j] - y_old[j];
    F[j] = dy;
    F[N + j] = h * K[j] - dy;
    F[2 * N + j] = 2.0 * dy - h * (f[j] + K[j]);
  }
  for (int64_t i = 0; i < rows; i++) {
    const double *Di = Dm + i * cols;
    double *Fi = F + (3 + i) * N;
    for (int64_t j = 0; j < N; j++) {
      double s = 0.0;
      for (int64_t k = 0; k < cols; k++) s += Di[k] * K[k * N + j];
      Fi[j] = h * s;
    }
  }
}

/* DOP853's dense output over the step from t_old (length h) at the k times ts into the
   rows of Y (k x N): scipy's Dop853DenseOutput, its operations in its order (x = (t -
   t_old) / h, y = (F[rows-1] + 0) x, then y += F[rows-1-i] and y *= 1 - x (i odd) or x,
   finally y += y_old), so that the numbers are scipy's to the bit (the engine is
   compiled without contracting a product and a sum into one rounding). */
void mechsim_interpolate(int64_t N, int64_t rows, const double *F, double t_old, double h,
                         const double *y_old, int64_t k, const double *ts, double *Y) {
  for (int64_t s = 0; s < k; s++) {
    const double x = (ts[s] - t_old) / h, u = 1.0 - x;
    double *y = Y + s * N;
    const double *top = F + (rows - 1) * N;
    for (int64_t i = 0; i < N; i++) y[i] = (top[i] + 0.0) * x;
    for (int64_t r = 1; r < rows; r++) {
      const double *row = F + (rows - 1 - r) * N;
      const double w = (r % 2) ? u : x;
      for (int64_t i = 0; i < N; i++) y[i] = (y[i] + row[i]) * w;
    }
    for (int64_t i = 0; i < N; i++) y[i] += y_old[i];
  }
}

/* The structures' sizes as this compiler lays them out: Python checks them against its
   ctypes twins before using the library. */
int64_t mechsim_sizeof_lu(void) { return (int64_t)sizeof(mechsim_lu); }
int64_t mechsim_sizeof_projection(void) { return (int64_t)sizeof(mechsim_projection); }
int64_t mechsim_sizeof_search(void) { return (int64_t)sizeof(mechsim_search); }
int64_t mechsim_sizeof_segment(void) { return (int64_t)sizeof(mechsim_segment); }

/* ---- consecutive plain steps of a partition in one call (mechsim.run.segment) ---- */

/* What the compiled predictor of the next dependent coordinates (Partitioned._accept) reads:
   the accepted state's z, zd, w, wd (f, f, r, r) at t, G = -A^-1 Phi_q B (r x f, row-major),
   and the accepted state before it (t0, z0, w0; `first`: none). It writes P (r x (3 + f)) as
   [w - G z, wd - G zd, cw - G cz, G] with cw = (w0 - w - wd e)/e^2, cz likewise, e = t0 - t
   (zero where first or t0 = t), then loads the engine: C = Ainv, q_ref, z_last, w_last, t_last.
   Partitioned._accept calls it, so that a step in a segment and one in Python agree to the
   bit. */
void mechsim_lu_predictor(mechsim_lu *c, double t, int64_t first, double t0, const double *z,
                          const double *zd, const double *w, const double *wd,
                          const double *z0, const double *w0, const double *reduced,
                          const double *Ainv, double *P) {
  const int64_t f = c->f, r = c->n - f, cols = 3 + f;
  const int same = first || t0 == t;
  const double e = t0 - t, e2 = pow(e, 2.0);
  for (int64_t i = 0; i < r; i++) {
    const double *Gi = reduced + i * f;
    double gz = 0.0, gzd = 0.0, gcz = 0.0;
    for (int64_t k = 0; k < f; k++) {
      const double g = -Gi[k];
      const double cz = same ? 0.0 : (z0[k] - z[k] - zd[k] * e) / e2;
      gz += g * z[k];
      gzd += g * zd[k];
      gcz += g * cz;
      P[i * cols + 3 + k] = g;
    }
    const double cw = same ? 0.0 : (w0[i] - w[i] - wd[i] * e) / e2;
    P[i * cols] = w[i] - gz;
    P[i * cols + 1] = wd[i] - gzd;
    P[i * cols + 2] = cw - gcz;
  }
  memcpy((double *)c->P, P, r * cols * sizeof(double));
  memcpy((double *)c->C, Ainv, r * r * sizeof(double));
  memcpy(c->z_last, z, f * sizeof(double));
  memcpy(c->w_last, w, r * sizeof(double));
  c->t_last = t;
}

static double py_max(double a, double b) { return b > a ? b : a; }   /* Python's max(a, b) */
static double py_min(double a, double b) { return b < a ? b : a; }   /* Python's min(a, b) */

/* intervals.lowest: the least over [0, h] of max(sa - ra tau, sb - rb (h - tau)). */
static double lowest(double sa, double sb, double h, double ra, double rb) {
  if (!(ra > 0.0 && rb > 0.0)) return -INFINITY;
  const double tau = py_min(py_max((sa - sb + rb * h) / (ra + rb), 0.0), h);
  return py_max(sa - ra * tau, sb - rb * (h - tau));
}

static int declined_rate(double t, const double *y, double *f) {
  (void)t; (void)y; (void)f;
  return 1;
}

/* The step's dense output (its extra stages and coefficients formed once a step, into s->F;
   their rates counted in *evaluations) on the step's rate (s->rate_ctx of s->kind, with
   s->rate_rcond and s->cut), the state of N entries. 0: done; 1: a stage the engine
   declines. */
static int dense_ready(mechsim_segment *s, int64_t N, double t_old, double h, const double *y,
                       const double *y_new, const double *f_new, int *ready,
                       int64_t *evaluations) {
  if (*ready) return 0;
  double *ein = s->extra_in;
  ein[0] = (double)(s->stages + 1); ein[1] = (double)s->extra_rows;
  ein[2] = (double)s->extra_width; ein[3] = t_old; ein[4] = h; ein[5] = s->rate_rcond;
  ein[6] = s->cut;
  if (mechsim_dop853_extra(s->rate_ctx, s->kind, N, s->extra_coef, ein, y, s->K, s->work,
                           s->extra_out, (void *)declined_rate)) return 1;
  *evaluations += s->extra_rows;
  mechsim_dense_coefficients(N, s->dense_rows, s->dense_cols, s->dense, s->K, y, y_new, f_new,
                             h, s->F);
  *ready = 1;
  return 0;
}

/* The configurations at the k times ts on the search's dense output: solved on the
   partition c (lu_state), or q = y[:n] where c is NULL. 0: done; 1: a state declined. */
static int search_positions(mechsim_lu *c, mechsim_search *w, int64_t k, const double *ts,
                            double *Q) {
  const int64_t N = w->N, n = w->n;
  mechsim_interpolate(N, w->rows, w->F, w->t_old, w->h, w->y_old, k, ts, w->Yn);
  for (int64_t j = 0; j < k; j++) {
    if (c == NULL) memcpy(Q + j * n, w->Yn + j * N, n * sizeof(double));
    else if (lu_positions(c, ts[j], w->Yn + j * N, Q + j * n, c->J)) return 1;
  }
  return 0;
}

/* s = sigma_kk / sigma_max of J~ (0 where sigma_max is not positive) at t on the search's
   dense output, the positions as search_positions finds them. 0: done. */
static int s_on_step(mechsim_lu *c, mechsim_projection *pc, mechsim_search *w, double t,
                     double *s) {
  double ex[2];
  if (search_positions(c, w, 1, &t, w->node_mq)) return 1;
  if (mechsim_extremes(pc, 1, w->kk, &t, w->node_mq, ex)) return 1;
  *s = ex[1] > 0.0 ? ex[0] / ex[1] : 0.0;
  return 0;
}

static double sign_or_one(double x) { return x > 0.0 ? 1.0 : (x < 0.0 ? -1.0 : 1.0); }

/* The least of s (s_on_step) over [ta, tb] (SingularityMonitor._refine): Brent's bounded
   search for the least of s^2, golden sections and parabolic steps to the tolerance
   sqrt(2.2e-16) |t| + xatol / 3 (the rule of scipy's minimize_scalar "bounded"), at most
   500 evaluations: (t, s) into out. s is V-shaped where a singular value passes through
   zero, s^2 smooth there (a parabola's step lands on its least), so the search takes about
   half the evaluations. 0: done; 1: a state or an SVD declined (Python decides). */
int mechsim_passage_minimum(mechsim_lu *c, mechsim_projection *pc, mechsim_search *w,
                            double ta, double tb, double xatol, double *out) {
  const double sqrt_eps = sqrt(2.2e-16), golden_mean = 0.5 * (3.0 - sqrt(5.0));
  double a = ta, b = tb;
  double fulc = a + golden_mean * (b - a), nfc = fulc, xf = fulc;
  double rat = 0.0, e = 0.0, x = xf, fx, fu, sx, su;
  if (s_on_step(c, pc, w, x, &sx)) return 1;
  fx = sx * sx;
  int num = 1;
  double ffulc = fx, fnfc = fx, xm = 0.5 * (a + b);
  double tol1 = sqrt_eps * fabs(xf) + xatol / 3.0, tol2 = 2.0 * tol1;
  while (fabs(xf - xm) > tol2 - 0.5 * (b - a)) {
    int golden = 1;
    if (fabs(e) > tol1) {                       /* a parabola through the three best */
      golden = 0;
      double r = (xf - nfc) * (fx - ffulc), q = (xf - fulc) * (fx - fnfc);
      double p = (xf - fulc) * q - (xf - nfc) * r;
      q = 2.0 * (q - r);
      if (q > 0.0) p = -p;
      q = fabs(q);
      r = e;
      e = rat;
      if (fabs(p) < fabs(0.5 * q * r) && p > q * (a - xf) && p < q * (b - xf)) {
        rat = (p + 0.0) / q;
        x = xf + rat;
        if (x - a < tol2 || b - x < tol2) rat = tol1 * sign_or_one(xm - xf);
      } else {
        golden = 1;
      }
    }
    if (golden) {
      e = xf >= xm ? a - xf : b - xf;
      rat = golden_mean * e;
    }
    x = xf + sign_or_one(rat) * (fabs(rat) > tol1 ? fabs(rat) : tol1);
    if (s_on_step(c, pc, w, x, &su)) return 1;
    fu = su * su;
    num++;
    if (fu <= fx) {
      if (x >= xf) a = xf; else b = xf;
      fulc = nfc; ffulc = fnfc;
      nfc = xf; fnfc = fx;
      xf = x; fx = fu; sx = su;
    } else {
      if (x < xf) a = x; else b = x;
      if (fu <= fnfc || nfc == xf) {
        fulc = nfc; ffulc = fnfc;
        nfc = x; fnfc = fu;
      } else if (fu <= ffulc || fulc == xf || fulc == nfc) {
        fulc = x; ffulc = fu;
      }
    }
    xm = 0.5 * (a + b);
    tol1 = sqrt_eps * fabs(xf) + xatol / 3.0;
    tol2 = 2.0 * tol1;
    if (num >= 500) break;
  }
  out[0] = xf;
  out[1] = sx;
  return 0;
}

/* Does [ta, tb] lie within reach of the times lows (ascending)? (intervals.covered) */
static int covered(double ta, double tb, const double *lows, int64_t nl, double reach) {
  double edge = ta;
  for (int64_t i = 0; i < nl; i++) {
    const double tk = lows[i];
    if (!(ta - reach <= tk && tk <= tb + reach)) continue;
    if (tk - reach > edge) return 0;
    edge = py_max(edge, tk + reach);
    if (edge >= tb) return 1;
  }
  return 0;
}

/* The intervals of the search's `count` nodes its anchors do not clear (intervals.uncleared:
   the nearest anchor on either side, its sigma_k less and its sigma_max plus the chords to
   the interval's far end, or the anchors at both its ends, their average less and plus half
   its chord, above `enter`; not within `apart` of a value under it; not joined to one, or
   to the step's start with open_at_start; the joins' upper bounds from the nearest measured
   anchors and from the two measured ends alike) into todo, in order: how many. A node's
   anchor (node_has) is measured (1: sigma_k and sigma_max by an SVD) or a floor (2:
   `extreme_bounds`, a lower bound of sigma_k and an upper bound of sigma_max): a floor
   serves the lower bounds only; values under `enter`, the upper bounds that join intervals
   to them and the values that part passages are the measured anchors'. */
static int64_t uncleared(mechsim_search *w, int64_t count, double h, int64_t *todo) {
  const int64_t intervals = count - 1;
  const double *T = w->nodes, *ch = w->node_chords, *an = w->node_anchor;
  const double enter = w->enter, leave = w->leave;
  const int64_t *has = (const int64_t *)w->node_has;
  double *low = w->node_low, *high = w->node_high, *lows = w->node_lows;
  int64_t *joined = (int64_t *)w->node_joined, nl = 0;
  for (int64_t j = 0; j < intervals; j++) {
    low[j] = -INFINITY;
    high[j] = INFINITY;
    joined[j] = 0;
  }
  for (int side = 0; side < 2; side++) {
    int anchored = 0, measured = 0;
    double a0 = 0.0, a1 = 0.0, reach = 0.0, m0 = 0.0, m1 = 0.0, mreach = 0.0;
    for (int64_t jj = 0; jj < intervals; jj++) {
      const int64_t j = side ? intervals - 1 - jj : jj, node = j + side;
      if (has[node]) { anchored = 1; a0 = an[2 * node]; a1 = an[2 * node + 1]; reach = 0.0; }
      if (has[node] == 1) { measured = 1; m0 = a0; m1 = a1; mreach = 0.0; }
      reach += ch[j];
      mreach += ch[j];
      if (anchored) {
        const double bound = (a0 - reach) / (a1 + reach);
        if (bound > low[j]) low[j] = bound;
      }
      if (measured) {
        const double bound = (m0 - mreach) / (m1 + mreach);
        if (bound > low[j]) low[j] = bound;
        if (m1 > mreach) {
          const double top = (m0 + mreach) / (m1 - mreach);
          if (top < high[j]) high[j] = top;
        }
      }
    }
  }
  for (int64_t j = 0; j < intervals; j++)         /* anchors at both ends: their average */
    if (has[j] && has[j + 1] && low[j] < enter) {
      const double smax2 = an[2 * j + 1] + an[2 * (j + 1) + 1];
      const double both = (an[2 * j] + an[2 * (j + 1)] - ch[j]) / (smax2 + ch[j]);
      if (both > low[j]) low[j] = both;
      if (has[j] == 1 && has[j + 1] == 1 && smax2 > ch[j]) {     /* measured: above too */
        const double top = (an[2 * j] + an[2 * (j + 1)] + ch[j]) / (smax2 - ch[j]);
        if (top < high[j]) high[j] = top;
      }
    }
  for (int64_t i = 0; i < count; i++)
    if (has[i] == 1 && an[2 * i] < enter * an[2 * i + 1]) lows[nl++] = T[i];
  for (int64_t j = 0; j < intervals;) {
    int64_t k = j;
    while (k < intervals && high[k] < leave) k++;
    int hold = w->open_at_start && j == 0;
    for (int64_t i = j; i <= k && !hold; i++)
      hold = has[i] == 1 && an[2 * i] < enter * an[2 * i + 1];
    if (k > j && hold)
      for (int64_t i = j; i < k; i++) joined[i] = 1;
    j = k + 1;
  }
  const double shortest = 1e-9 * h;
  int64_t nt = 0;
  for (int64_t j = 0; j < intervals; j++)
    if (low[j] < enter && !joined[j] && T[j + 1] - T[j] >= shortest &&
        !(nl && covered(T[j], T[j + 1], lows, nl, w->apart)))
      todo[nt++] = j;
  return nt;
}

/* |S^2|_F^2 of the symmetric m x m S (row-major): its largest eigenvalue's fourth power at
   most. */
static double square_frobenius2(int64_t m, const double *S) {
  double total = 0.0;
  for (int64_t i = 0; i < m; i++)
    for (int64_t j = i; j < m; j++) {
      double e = 0.0;
      for (int64_t k = 0; k < m; k++) e += S[i * m + k] * S[k * m + j];
      total += (i == j ? 1.0 : 2.0) * e * e;
    }
  return total;
}

/* Bounds of sigma_min and sigma_max of J (m x n row-major, m <= n) without an SVD, for the
   passage search's floor anchors: with G = J J^T = L L^T (Cholesky) and H = G^-1 = L^-T L^-1,
   sigma_min^2 = 1 / lambda_max(H) and sigma_max^2 = lambda_max(G), and the largest
   eigenvalue of a symmetric positive definite S is at most |S|_F and |S^2|_F^(1/2)
   (within m^(1/4) of it). out = (a lower bound of sigma_min lowered by 1e-6 of itself for
   round-off, an upper bound of sigma_max raised by 1e-12); G and H: m x m scratch.
   1 where G is not positive definite in floating point or so ill-conditioned that
   round-off (about (m + n) eps cond(G) of the bound) could reach that margin: the node
   takes an SVD. */
static int extreme_bounds(const mechsim_projection *c, int64_t m, int64_t n,
                          const double *J, double *G, double *H, double *out) {
  const int sparse = patterned(c, m, n);
  if (sparse) {                                 /* J's pattern: `complement`'s sums */
    pair_products(c, J, NULL, G);
  } else {
    for (int64_t i = 0; i < m; i++)
      for (int64_t j = 0; j <= i; j++) {
        double e = 0.0;
        for (int64_t k = 0; k < n; k++) e += J[i * n + k] * J[j * n + k];
        G[i * m + j] = G[j * m + i] = e;
      }
  }
  double frob = 0.0;
  for (int64_t i = 0; i < m * m; i++) frob += G[i] * G[i];
  const double top = fmin(sqrt(frob), pow(square_frobenius2(m, G), 0.25));
  const int factored = sparse && c->chol_ops;
  if (factored) memset(H, 0, m * m * sizeof(double));
  if (factored ? pattern_cholesky(c, G, H) : small_cholesky(m, G, H))
    return 1;                                  /* L (lower, row-major) into H */
  /* M = L^-1 into G: row-major lower L is column-major upper R = L^T, whose inverse
     (column-major upper) is row-major lower L^-1 */
  upper_inverse(m, H, G);
  for (int64_t i = 0; i < m; i++)                  /* H = M^T M */
    for (int64_t j = 0; j <= i; j++) {
      double e = 0.0;
      for (int64_t k = i; k < m; k++) e += G[k * m + i] * G[k * m + j];
      H[i * m + j] = H[j * m + i] = e;
    }
  double hfrob = 0.0;
  for (int64_t i = 0; i < m * m; i++) hfrob += H[i] * H[i];
  const double inverse_top = fmin(sqrt(hfrob), pow(square_frobenius2(m, H), 0.25));
  if (!(inverse_top > 0.0) || !isfinite(inverse_top) || !(top > 0.0)) return 1;
  const double cond = top * inverse_top;           /* at least cond(G) */
  if (!(4.0 * (double)(m + n) * 2.220446049250313e-16 * cond <= 1e-7)) return 1;
  out[0] = (1.0 - 1e-6) / sqrt(inverse_top);
  out[1] = (1.0 + 1e-12) * sqrt(top);
  return 0;
}

/* J~ of the search's node i: its slot of node_J (J~ is evaluated once a node). */
static double *node_jacobian(mechsim_search *w, int64_t i) {
  return w->node_J + ((int64_t *)w->node_slot)[i] * w->m * w->n;
}

/* The row of w->node_cache (w->cached rows t, sigma_kk, sigma_max, in time order) at time
   t, or NULL. */
static const double *cached_node(const mechsim_search *w, double t) {
  int64_t lo = 0, hi = w->cached;
  while (lo < hi) {
    const int64_t mid = (lo + hi) / 2;
    if (w->node_cache[3 * mid] < t) lo = mid + 1;
    else hi = mid;
  }
  return lo < w->cached && w->node_cache[3 * lo] == t ? w->node_cache + 3 * lo : NULL;
}

/* Measure the search's node i (sigma_kk and sigma_max of its J~; taken from w->node_cache
   where the search before measured the same time, the same J~). 0: done. */
static int measure_node(mechsim_projection *pc, mechsim_search *w, int64_t i) {
  double *ex = w->node_ex;
  const double *row = cached_node(w, w->nodes[i]);
  if (row) {
    ex[0] = row[1];
    ex[1] = row[2];
  } else {
    memcpy(pc->A, node_jacobian(w, i), w->m * w->n * sizeof(double));
    if (svd_extremes(pc, w->kk, ex)) return 1;
  }
  ((int64_t *)w->node_has)[i] = 1;
  w->node_anchor[2 * i] = ex[0];
  w->node_anchor[2 * i + 1] = ex[1];
  return 0;
}

/* A floor anchor at the search's node i (`extreme_bounds` of its J~). 0: done; 1: the
   bounds declined (the node takes an SVD). */
static int floor_node(const mechsim_projection *pc, mechsim_search *w, int64_t i) {
  if (extreme_bounds(pc, w->m, w->n, node_jacobian(w, i), w->gram, w->inverse,
                     w->node_anchor + 2 * i))
    return 1;
  ((int64_t *)w->node_has)[i] = 2;
  w->floors_taken++;
  return 0;
}

/* `anchored_search`'s grid, with floor anchors where `floors`: an uncleared interval's nodes
   without an anchor take a floor first, an SVD where the interval stays uncleared (or the
   floor declines), and the search stops at the first measured value under `enter`.
   *proved: 1 where the search ended with every interval cleared and no measured value
   under `enter` (s >= enter over the step: no passage in it); -1 where the search with
   floors stopped at a measured value under `enter` (the search without them is to be
   made: it finds the passage's dips and the values that part them). */
static int grid_search(mechsim_lu *c, mechsim_projection *pc, mechsim_search *w,
                       double t0, double t1, int64_t budget, const double *end0,
                       const double *end1, int floors, int *proved) {
  const int64_t n = w->n, mn = w->m * w->n, cap = w->nodes_cap, grid = w->grid;
  double *T = w->nodes, *Q = w->node_q, *ch = w->node_chords, *an = w->node_anchor;
  double *mid = w->node_mid, *mq = w->node_mq;
  int64_t *has = (int64_t *)w->node_has, *slot = (int64_t *)w->node_slot;
  const double step = (t1 - t0) / (double)grid, h = t1 - t0, chord = w->chord;
  int64_t count = grid + 1;
  *proved = 0;
  w->floored = 0;
  if (count > cap) return 1;
  for (int64_t i = 0; i < grid; i++) T[i] = (double)i * step + t0;
  T[grid] = t1;
  if (search_positions(c, w, count, T, Q)) return 1;
  for (int64_t i = 0; i < count; i++) {       /* J~ at the nodes, and the chords between */
    slot[i] = i;
    scaled_jacobian(pc, Q + i * n, T[i], node_jacobian(w, i));
    if (i > 0) ch[i - 1] = difference_norm(pc, w->m, n, node_jacobian(w, i),
                                           node_jacobian(w, i - 1), pc->x);
  }
  int64_t slots = count;
  for (int64_t i = 0; i < grid; i++) ch[i] = chord * ch[i];
  for (int64_t i = 0; i < count; i++) has[i] = 0;
  if (end0) { has[0] = 1; an[0] = end0[0]; an[1] = end0[1]; }
  if (end1) { has[grid] = 1; an[2 * grid] = end1[0]; an[2 * grid + 1] = end1[1]; }
  if (!has[0] && measure_node(pc, w, 0)) return 1;
  if (!has[grid] && measure_node(pc, w, grid)) return 1;
  int64_t spent = 2;
  int64_t *todo = (int64_t *)w->node_todo, *fresh = (int64_t *)w->node_fresh;
  while (spent < budget) {
    const int64_t nt = uncleared(w, count, h, todo);
    if (!nt) {
      *proved = 1;
      break;
    }
    int64_t nf = 0;      /* of each run of consecutive intervals, the middle one of its
                            nodes not measured (intervals.fresh_nodes), in order */
    for (int64_t a = 0; a < nt;) {
      int64_t b = a, free = 0, seen = 0;
      while (b + 1 < nt && todo[b + 1] == todo[b] + 1) b++;
      for (int64_t i = todo[a]; i <= todo[b] + 1; i++) free += has[i] != 1;
      for (int64_t i = todo[a]; free && i <= todo[b] + 1; i++)
        if (has[i] != 1 && seen++ == free / 2) {
          fresh[nf++] = i;
          break;
        }
      a = b + 1;
    }
    if (nf) {
      int64_t floored = 0;
      for (int64_t a = 0; floors && a < nf; a++)
        if (!has[fresh[a]] && !floor_node(pc, w, fresh[a])) floored++;
      w->floored += floored;
      if (floored) continue;                   /* what the floors clear, first */
      if (nf > budget - spent) nf = budget - spent;
      int low = 0;
      for (int64_t a = 0; a < nf; a++) {
        if (measure_node(pc, w, fresh[a])) return 1;
        low |= an[2 * fresh[a]] < w->enter * an[2 * fresh[a] + 1];
      }
      spent += nf;
      if (floors && low) {             /* a passage: the search without floors finds it */
        *proved = -1;
        break;
      }
      continue;
    }
    if (count + nt > cap) return 1;
    for (int64_t a = 0; a < nt; a++) mid[a] = 0.5 * (T[todo[a]] + T[todo[a] + 1]);
    if (search_positions(c, w, nt, mid, mq)) return 1;
    /* J~ at each midpoint (a fresh slot), the chords to its interval's ends */
    double *pieces = w->node_pieces;
    for (int64_t a = 0; a < nt; a++) {
      const int64_t j = todo[a];
      double *Jm = w->node_J + (slots + a) * mn;
      scaled_jacobian(pc, mq + a * n, mid[a], Jm);
      pieces[2 * a] = chord * difference_norm(pc, w->m, n, Jm, node_jacobian(w, j), pc->x);
      pieces[2 * a + 1] = chord * difference_norm(pc, w->m, n, node_jacobian(w, j + 1), Jm,
                                                  pc->x);
    }
    for (int64_t a = nt - 1; a >= 0; a--) {      /* insert each midpoint, last first */
      const int64_t j = todo[a];
      for (int64_t i = count; i > j + 1; i--) {
        T[i] = T[i - 1];
        memcpy(Q + i * n, Q + (i - 1) * n, n * sizeof(double));
        has[i] = has[i - 1];
        slot[i] = slot[i - 1];
        an[2 * i] = an[2 * (i - 1)];
        an[2 * i + 1] = an[2 * (i - 1) + 1];
      }
      for (int64_t i = count - 1; i > j; i--) ch[i + 1] = ch[i];
      T[j + 1] = mid[a];
      memcpy(Q + (j + 1) * n, mq + a * n, n * sizeof(double));
      has[j + 1] = 0;
      slot[j + 1] = slots + a;
      ch[j] = pieces[2 * a];
      ch[j + 1] = pieces[2 * a + 1];
      count++;
    }
    slots += nt;
  }
  int64_t found = 0;
  for (int64_t i = 0; i < count; i++)
    if (has[i] == 1) {
      w->out[3 * found] = T[i];
      w->out[3 * found + 1] = an[2 * i];
      w->out[3 * found + 2] = an[2 * i + 1];
      if (an[2 * i] < w->enter * an[2 * i + 1] && *proved == 1) *proved = 0;
      found++;
    }
  w->found = found;
  return 0;
}

/* The singularity monitor's search for passages hidden inside the step [t0, t1] on its
   dense output (SingularityMonitor._anchored): a grid of `grid` intervals, J~'s chords
   between nodes enlarged by `chord`, every run of intervals its anchors do not clear
   (`uncleared`) measured at its middle node not measured yet, one a run at a time, and
   halved once all its nodes are, at most `budget` SVDs; the anchors at the ends are
   end0 / end1 ((sigma_kk, sigma_max) measured there) where not NULL. The measured nodes into
   w->out (rows t, sigma_kk, sigma_max, in time order; w->found of them). 0: done; 1: a state
   or an SVD declined, or the grid outgrew its `nodes_cap` nodes (Python searches).
   With w->floors (sigma_kk the least singular value, no passage open at the start), floor
   anchors (`extreme_bounds`) clear first what they can: where they prove s >= enter over
   the whole step, the measured nodes are those it took; elsewhere (a value under `enter`,
   the budget spent) the search is made again without floors, so that a step with a
   passage, its dips and the values that part them, are found as before, each node's
   values taken from the first search where it measured the same time (the same node, the
   same numbers: only the SVDs the first search did not take are taken). Either way the
   verdict is the same: floors only clear where s is above `enter`. */
static int anchored_search(mechsim_lu *c, mechsim_projection *pc, mechsim_search *w,
                           double t0, double t1, int64_t budget, const double *end0,
                           const double *end1) {
  int proved = 0;
  w->cached = 0;
  if (w->floors && !w->open_at_start && w->kk == w->m - 1) {
    if (grid_search(c, pc, w, t0, t1, budget, end0, end1, 1, &proved)) return 1;
    /* proved, or searched as without floors (no floor taken, not stopped at a passage) */
    if (proved == 1 || (proved == 0 && !w->floored)) return 0;
    memcpy(w->node_cache, w->out, 3 * w->found * sizeof(double));
    w->cached = w->found;
  }
  const int done = grid_search(c, pc, w, t0, t1, budget, end0, end1, 0, &proved);
  w->cached = 0;
  return done;
}

/* The request of a search (its step, budget, end anchors and w's settings) into key
   (MECHSIM_SEARCH_KEY numbers, layout.SEARCH_KEY). */
static void search_request(const mechsim_search *w, double t0, double t1, int64_t budget,
                           const double *end0, const double *end1, double *key) {
  const double got[MECHSIM_SEARCH_KEY] = {t0, t1, (double)budget, end0 ? 1.0 : 0.0, end0 ? end0[0] : 0.0,
                          end0 ? end0[1] : 0.0, end1 ? 1.0 : 0.0, end1 ? end1[0] : 0.0,
                          end1 ? end1[1] : 0.0, (double)w->grid, (double)w->kk,
                          (double)w->N, (double)w->rows, (double)w->open_at_start, w->chord,
                          w->enter, w->leave, w->apart, w->t_old, w->h};
  memcpy(key, got, sizeof(got));
}

/* Keep the search just made (its request, partition and dense output) for the loop's
   search of the same step (mechsim_anchored). */
static void keep_search(mechsim_lu *c, mechsim_search *w, double t0, double t1,
                        int64_t budget, const double *end0, const double *end1) {
  search_request(w, t0, t1, budget, end0, end1, w->key);
  w->key_c = c;
  memcpy(w->key_F, w->F, w->rows * w->N * sizeof(double));
  memcpy(w->key_y, w->y_old, w->N * sizeof(double));
  w->kept = 1;
}

/* `anchored_search` for Python (SingularityMonitor._anchored): c the partition the
   positions are solved on, or NULL; w's dense output and thresholds set by the caller.
   Where a segment searched the same step (the same request, partition, coefficients and
   start: the loop takes a step a segment declined from the same state) its result is
   taken as it stands. */
int mechsim_anchored(mechsim_lu *c, mechsim_projection *pc, mechsim_search *w, double t0,
                     double t1, int64_t budget, const double *ends, int64_t which) {
  const double *end0 = (which & 1) ? ends : NULL, *end1 = (which & 2) ? ends + 2 : NULL;
  if (w->kept) {
    search_request(w, t0, t1, budget, end0, end1, w->asked);
    if (w->key_c == c && !memcmp(w->asked, w->key, MECHSIM_SEARCH_KEY * sizeof(double)) &&
        !memcmp(w->F, w->key_F, w->rows * w->N * sizeof(double)) &&
        !memcmp(w->y_old, w->key_y, w->N * sizeof(double)))
      return 0;
  }
  w->kept = 0;
  return anchored_search(c, pc, w, t0, t1, budget, end0, end1);
}

/* Whether a measured (sigma_min, sigma_max) is under `enter` as the search's values or its
   anchors would count it (either form, or sigma_max not positive: a value of 0). */
static int under(double smin, double smax, double enter) {
  return !(smax > 0.0) || !(smin >= enter * smax) || smin / smax < enter;
}

/* The monitor's search inside the step [t0, t1] of a segment (anchored_search on the step's
   dense output of N entries, the positions solved on the partition c, or q = y[:n] where c
   is NULL, with the loop's thresholds and `open` as the passage open at the step's start),
   kept for the loop's search of the same step (keep_search): its measured nodes in
   w->out. 0: done; 1: the search declined. */
static int step_search(mechsim_lu *c, mechsim_projection *pc, mechsim_segment *s, int64_t N,
                       double t0, double t1, double t_old, double h_step, const double *y,
                       int64_t budget, double enter, double leave, double apart,
                       const double *end0, const double *end1, int open) {
  mechsim_search *w = (mechsim_search *)s->search;
  w->grid = s->grid;
  w->kk = pc->m - 1;
  w->N = N;
  w->rows = s->dense_rows + 3;
  w->open_at_start = open;
  w->chord = s->chord;
  w->enter = enter;
  w->leave = leave;
  w->apart = apart;
  w->t_old = t_old;
  w->h = h_step;
  w->F = s->F;
  w->y_old = y;
  w->kept = 0;
  if (anchored_search(c, pc, w, t0, t1, budget, end0, end1)) return 1;
  keep_search(c, w, t0, t1, budget, end0, end1);
  return 0;
}

/* Partitioned.choose at Phi_q = J (row-major m x n): *rank from the singular values of J
   (above max(m, n) eps rank_factor sigma_max, as ConstraintAlgebra.rank) and perm, the
   coordinates in the order LU with partial pivoting of J^T picks them (DenseAlgebra.pivots:
   dgetrf on the same column-major J^T scipy's lu_factor takes), with A (m n doubles) and
   piv (m ints) as scratch. 1 where a factorisation fails. */
static int choose_set(mechsim_projection *pc, const double *J, double eps,
                      double rank_factor, double *A, int *piv, int64_t *perm,
                      int64_t *rank) {
  const int64_t n = pc->n, m = pc->m;
  memcpy(A, J, m * n * sizeof(double));            /* J^T, column-major n x m */
  if (singular_values(pc, A)) return 1;
  int N = (int)n, M = (int)m, info = 0;
  const double threshold = (double)(m > n ? m : n) * eps * rank_factor * pc->sig[0];
  *rank = 0;
  for (int64_t i = 0; i < (m < n ? m : n); i++) *rank += pc->sig[i] > threshold;
  memcpy(A, J, m * n * sizeof(double));
  mechsim_dgetrf(&N, &M, A, &N, piv, &info);
  if (info < 0) return 1;
  for (int64_t i = 0; i < n; i++) perm[i] = i;      /* perm from the row swaps */
  for (int64_t i = 0; i < (m < n ? m : n); i++) {
    const int64_t p = piv[i] - 1, keep = perm[i];
    perm[i] = perm[p];
    perm[p] = keep;
  }
  return 0;
}

/* `choose_set` for Python (Partitioned.choose): perm (n) and rank[0]; pc's J1 and iwork
   as scratch. 1 where a factorisation fails. */
int mechsim_choose(mechsim_projection *pc, const double *J, double eps, double rank_factor,
                   int64_t *perm, int64_t *rank) {
  return choose_set(pc, J, eps, rank_factor, pc->J1, pc->iwork, perm, rank);
}

/* Whether Partitioned.choose at Phi_q = J (row-major m x n) keeps the partition's
   independent set (c->ind): `choose_set`'s rank and pivots. 1: kept; 0: another set, or a
   factorization failed. */
static int keeps_set(mechsim_lu *c, mechsim_projection *pc, mechsim_segment *s,
                     const double *J) {
  const int64_t n = c->n, f = c->f;
  int64_t *mark = (int64_t *)s->set_mark, rank = 0;
  if (choose_set(pc, J, s->machine_eps, s->rank_factor, s->set_work, (int *)s->set_piv,
                 mark, &rank))
    return 0;
  if (n - rank != f) return 0;
  for (int64_t k = 0; k < f; k++) {                 /* perm[rank:] is the set c->ind */
    int found = 0;
    for (int64_t i = rank; i < n; i++) found |= mark[i] == c->ind[k];
    if (!found) return 0;
  }
  return 1;
}

/* Why a segment stopped (mechsim_segment.reason). */
enum { SEG_BUDGET = 0, SEG_STEP, SEG_BRANCH, SEG_SAMPLES, SEG_ROOM, SEG_DUE, SEG_FINITE,
       SEG_MEASURE, SEG_SEARCH, SEG_BAND, SEG_LEAVE, SEG_PARTITION, SEG_FINISHED, SEG_SHORT,
       SEG_LIMIT, SEG_PROJECT, SEG_BRIDGE, SEG_OPEN };

/* A pending step (s->pending): its observation by the monitor taken (PENDING_DECIDE: the
   formulation's and the bridge's decisions after it are the loop's), or not
   (PENDING_OBSERVE: a measurement the engine declines, the band, a dip the search does not
   rule out, a passage open at the step's start; the loop observes it, and decides). */
enum { PENDING_DECIDE = 1, PENDING_OBSERVE = 2 };


/* A step's observation by the singularity monitor, as candidates the segment commits once
   the step stands. */
typedef struct {
  int skip, slot, has_fall;
  double speed, floor_value, floor_lo, floor_hi, smin, smax, srel, rate, rate_norm, peak,
      peak_rate, ratio_speed;
} seg_observation;

/* Whether a floor of sigma_min / sigma_max (not normalized) at t_new clears the step from
   t_old (s/peak `start` there) and a next one up to twice as long for the monitor's skip
   (SingularityMonitor._skip_clears). */
static int skip_clears(const mechsim_segment *s, double t_old, double t_new, double speed,
                       double start, double floor) {
  const double h = t_new - t_old, f = floor / s->peak;
  const double span = t_new - s->prev_t;
  const double fall = py_max(s->prev_s - f, 0.0) / span, was = py_max(-s->prev_rate, 0.0);
  const double ahead = was + 2.0 * (fall - was) * (1.0 + 2.0 * h / span);
  const double bound = py_max(py_max(2.0 * fabs(s->prev_rate), s->peak_rate), ahead) *
                       py_max(1.0, speed / s->m_speed);
  return f - 2.0 * h * bound > 2.0 * s->enter && start + f - h * bound > 4.0 * s->enter;
}

/* SingularityMonitor.observe at the end (q_new, v_new; |v|inf = speed) of the step from
   t_old: its skip by the bounds of SingularityMonitor._may_skip (o->skip, o->floor_value
   and the bounds o->floor_lo, o->floor_hi), or its measurement into the free slot of the
   fall buffers. 0: the step is plain for the monitor so far (a passage
   hidden in it is `hidden_clear`'s to rule out); else the reason it is not (a measurement
   that fails, the band). */
static int64_t observe_step(mechsim_projection *pc, mechsim_segment *s, double t_old,
                            double t_new, const double *q_new, const double *v_new,
                            double speed, seg_observation *o) {
  const int64_t n = pc->n, m = pc->m, mn = m * n, nr = n * m;
  o->skip = 0;
  o->floor_value = 0.0;
  o->speed = speed;
  const int starts = s->has_prev && (s->prev_t == t_old ||
                                      (s->skipped && s->has_floor && s->floor_t == t_old));
  if (!s->has_open && starts && t_new > t_old && s->skipped < s->max_skip &&
      s->has_measured && s->m_speed > 0.0) {
    /* SingularityMonitor._may_skip */
    const double start = s->prev_t == t_old ? s->prev_s : s->floor_v / s->peak;
    const double cap = s->skip_rise * py_max(s->prev_s, start) * s->peak;
    if (skip_clears(s, t_old, t_new, speed, start, cap)) {   /* where s may have risen so */
      memcpy(pc->q, q_new, n * sizeof(double));
      const double E = mechsim_change(pc, t_new, s->Jm, s->Jc);
      o->floor_lo = py_max(s->m_smin - E, 0.0);
      o->floor_hi = s->m_smax + E;
      o->floor_value = o->floor_lo / o->floor_hi;
      const double top = s->m_smax - E, most = top > 0.0 ? (s->m_smin + E) / top : INFINITY;
      double b[2];
      if (s->small && skip_clears(s, t_old, t_new, speed, start, py_min(most, cap)) &&
          !extreme_bounds(pc, m, n, s->Jc, pc->svd_work, pc->svd_work + m * m, b)) {
        if (b[0] / b[1] > o->floor_value) {              /* J~'s own floor */
          o->floor_lo = b[0];
          o->floor_hi = b[1];
          o->floor_value = b[0] / b[1];
        }
      }
      o->skip = skip_clears(s, t_old, t_new, speed, start, o->floor_value);
    }
  }
  const int slot = o->slot = 1 - (int)s->cur;
  double *Jn = s->Js + slot * mn, *Dn = s->Ds + slot * mn, *Pn = s->Ps + slot * nr;
  o->smin = o->smax = o->srel = o->rate = o->rate_norm = o->ratio_speed = 0.0;
  o->peak = s->peak;
  o->peak_rate = s->peak_rate;
  o->has_fall = 0;
  if (o->skip) return 0;
  memcpy(pc->q, q_new, n * sizeof(double));
  const double eps = speed > 0.0 ? s->rate_step / speed : 0.0;
  if (eps > 0.0) memcpy(pc->v, v_new, n * sizeof(double));
  if (mechsim_measure(pc, t_new, eps, s->measured, Jn)) return SEG_MEASURE;
  const double smin = o->smin = s->measured[0], smax = o->smax = s->measured[1];
  const double rate_norm = o->rate_norm = s->measured[4 + m];
  if (!(smax > 0.0)) return SEG_MEASURE;
  double rate = eps ? (s->measured[2] * smax - smin * s->measured[3]) / pow(smax, 2.0) : 0.0;
  const double raw = smin / smax;
  if (s->small && eps > 0.0) {                /* its Fall: D = dJ~/dt and fall_basis P */
    const double scale = 1.0 / eps, *U = pc->U, *sig = pc->sig;
    const int64_t kk = m - 1;
    for (int64_t i = 0; i < mn; i++) Dn[i] = (pc->J1[i] - Jn[i]) * scale;
    for (int64_t l = 0; l < m; l++) {
      const double wl = sig[kk] > 0.0 ? sig[kk] / sig[l] : (sig[l] <= 0.0 ? 1.0 : 0.0);
      for (int64_t j = 0; j < n; j++) Pn[j * m + l] = U[j + l * n] * wl;
    }
    o->has_fall = 1;
  }
  o->ratio_speed = s->small ? 2.0 * rate_norm / smax : 0.0;
  const double peak = o->peak = py_max(s->peak, raw);
  if (peak < s->blind) return SEG_MEASURE;
  const double srel = o->srel = raw / peak;
  rate = o->rate = rate / peak;
  o->peak_rate = py_max(s->peak_rate, fabs(rate));
  return srel < s->enter && !s->through ? SEG_BAND : 0;
}

/* The start of the measured step (observation o) from t_old as the monitor's search takes
   it (SingularityMonitor.observe): the latest measured observation, or the skip's floor at
   t_old; and whether _hidden_passages' bounds clear the step to t_new (the rate bound, and
   with `falls` _fall_clears), with the rate bound into *rate_bound. Returns -1 where there
   is no start (no search), else whether cleared; a = (t, s/peak, rate/peak) of the start. */
static int search_clear(const mechsim_projection *pc, mechsim_segment *s,
                        const seg_observation *o, int64_t m, int64_t n,
                        double t_old, double t_new, int falls, double *a,
                        double *rate_bound) {
  const int64_t mn = m * n, nr = n * m;
  const int slot = o->slot;
  const double *Jn = s->Js + slot * mn, *Dn = s->Ds + slot * mn, *Pn = s->Ps + slot * nr;
  const double smin = o->smin, smax = o->smax, rate_norm = o->rate_norm;
  const double peak = o->peak, srel = o->srel, rate = o->rate, peak_rate = o->peak_rate;
  int has_a = (int)s->has_prev;
  double a_t = s->prev_t, a_s = s->prev_s, a_d = s->prev_rate;
  if (has_a && a_t != t_old) {
    has_a = s->skipped && s->has_floor && s->floor_t == t_old;
    a_t = t_old;
    a_s = s->floor_v / peak;
    a_d = 0.0;
  }
  a[0] = a_t; a[1] = a_s; a[2] = a_d;
  if (!has_a) return -1;
  const double hh = t_new - a_t, enter = s->enter * peak;
  const double observed = peak * py_max(py_max(peak_rate, fabs(a_d)), fabs(rate));
  const double speed_bound = py_max(s->ratio_speed, o->ratio_speed);
  const double bound = *rate_bound = 2.0 * py_max(observed, observed > 0.0 ?
      py_min(speed_bound, s->weyl_span * observed) : speed_bound);
  if (!(hh > 0.0) || !(bound > 0.0) || (a_s + srel) * peak - bound * hh >= 2.0 * enter)
    return 1;
  if (falls && s->has_fall && o->has_fall) {           /* _fall_clears */
    const int64_t cur = s->cur;
    const double *fs_a = s->fall_scalars + 4 * cur;   /* t, smin, smax, rise */
    const double least = 2.0 * observed;
    const double ea = fs_a[1] / fs_a[2], eb = smin / smax, span = t_new - fs_a[0];
    if (!(least > 0.0 && lowest(ea, eb, span, least, least) < enter)) {
      double fin[8], rates[2];
      fin[0] = fs_a[0]; fin[1] = t_new; fin[2] = fs_a[1]; fin[3] = fs_a[2];
      fin[4] = fs_a[3]; fin[5] = smin; fin[6] = smax; fin[7] = rate_norm;
      mechsim_fall_rates(pc, m, n, m, fin, s->Js + cur * mn, s->Ds + cur * mn,
                         s->Ps + cur * nr, Jn, Dn, Pn, s->fall_work, rates);
      const double r0 = py_max(s->hermite_margin * rates[0], least);
      const double r1 = py_max(s->hermite_margin * rates[1], least);
      return lowest(ea, eb, span, r0, r1) >= enter;
    }
  }
  return 0;
}

/* SingularityMonitor._anchored's search of the step from the start a (`search_clear`) to
   t_new (observation o; the dense output formed first), its budget and end anchors as the
   monitor sets them, `open` the passage open at the start (`step_search`). 0: done, the
   measured nodes in the search's out; 1: declined. */
static int monitor_search(mechsim_lu *c, mechsim_projection *pc, mechsim_segment *s,
                          int64_t N, const seg_observation *o, const double *a,
                          double rate_bound, double t_old, double t_new, double h,
                          const double *y, const double *y_new, const double *f_new,
                          int open, int *ready, int64_t *evaluations) {
  const double peak = o->peak, enter = s->enter * peak, leave = s->leave * peak;
  const double sum = (a[1] + o->srel) * peak;
  const double budget = py_min(4000.0, 16.0 + 4.0 * rate_bound * (t_new - a[0]) /
                               py_max(sum, enter));
  const double *end0 = NULL, end1[2] = {o->smin, o->smax};
  for (int64_t j = 0; j < s->known_n; j++)
    if (s->known[3 * j] == a[0]) end0 = s->known + 3 * j + 1;
  return dense_ready(s, N, t_old, h, y, y_new, f_new, ready, evaluations) ||
      step_search(c, pc, s, N, a[0], t_new, t_old, h, y, (int64_t)budget, enter, leave,
                  2.0 * (leave - enter) / rate_bound, end0, end1, open);
}

/* Whether a passage hidden in the measured step (observation o) from t_old of length h
   is ruled out as SingularityMonitor._hidden_passages rules it out (the rate bound,
   _fall_clears, the anchored search where it finds none), the positions solved on the
   partition c (NULL: the state is [q; v]). 0: cleared; SEG_SEARCH where not. */
static int64_t hidden_clear(mechsim_lu *c, mechsim_projection *pc, mechsim_segment *s,
                            double t_old, double t_new, double h, const double *y,
                            const double *y_new, const double *f_new,
                            const seg_observation *o, int *ready, int64_t *evaluations) {
  if (o->skip) return 0;
  const int64_t n = pc->n, m = pc->m, N = c ? 2 * c->f : 2 * n;
  double a[3], rate_bound = 0.0;
  if (search_clear(pc, s, o, m, n, t_old, t_new, 1, a, &rate_bound)) return 0;
  if (!s->small ||
      monitor_search(c, pc, s, N, o, a, rate_bound, t_old, t_new, h, y, y_new, f_new, 0,
                     ready, evaluations))
    return SEG_SEARCH;
  const mechsim_search *w = (const mechsim_search *)s->search;
  for (int64_t i = 0; i < w->found; i++)
    if (under(w->out[3 * i + 1], w->out[3 * i + 2], s->enter * o->peak)) return SEG_SEARCH;
  return 0;
}

/* The passages a segment's observation of a step leaves (SingularityMonitor.observe where
   the segment observes passages itself, s->handles_passages): the open passage (its start,
   least sigma_min/sigma_max and where, whether the bridge crossed it, and the left singular
   vector of that least value in s->cand_u where u_set; else its joints are the loop's) and
   `added` passages recorded after the s->passages_n rows of s->passages (t_start, t_end,
   s_min, t_min, bridged, u_set, u). */
typedef struct {
  int has_open, u_set;
  double t_start, t_min, s_min, bridged;
  int64_t added;
} seg_passages;

/* Record a passage (t_start, t_end, least value s_min at t_min, whether bridged, its
   singular vector u where u_set) after the rows p added already. 0: done; 1: no room
   (the loop observes the step). */
static int record_passage(mechsim_segment *s, seg_passages *p, int64_t m, double t_start,
                          double t_end, double s_min, double t_min, double bridged,
                          int u_set, const double *u) {
  if (s->passages_n + p->added >= s->passages_cap) return 1;
  double *row = s->passages + (s->passages_n + p->added) * (6 + m);
  row[0] = t_start; row[1] = t_end; row[2] = s_min; row[3] = t_min;
  row[4] = bridged; row[5] = (double)u_set;
  memcpy(row + 6, u, m * sizeof(double));
  p->added++;
  return 0;
}

/* Close the open passage of p at t (SingularityMonitor.close): recorded. 0: done; 1: no
   room. */
static int close_passage(mechsim_segment *s, seg_passages *p, int64_t m, double t) {
  if (record_passage(s, p, m, p->t_start, t, p->s_min, p->t_min, p->bridged, p->u_set,
                     s->cand_u)) return 1;
  p->has_open = 0;
  return 0;
}

/* The passage open from t_start, its least value s_min at t_min with singular vector u
   (OpenPassage; not bridged). */
static void open_at(mechsim_segment *s, seg_passages *p, int64_t m, double t_start,
                    double t_min, double s_min, const double *u) {
  p->has_open = 1; p->t_start = t_start; p->bridged = 0.0;
  p->t_min = t_min; p->s_min = s_min; p->u_set = 1;
  memcpy(s->cand_u, u, m * sizeof(double));
}

/* The open passage's least value lowered to s_min at t_min (vector u) where below it. */
static void lower(mechsim_segment *s, seg_passages *p, int64_t m, double t_min,
                  double s_min, const double *u) {
  if (!(s_min < p->s_min)) return;
  p->t_min = t_min; p->s_min = s_min; p->u_set = 1;
  memcpy(s->cand_u, u, m * sizeof(double));
}

/* The left singular vector of sigma_min at tm on the step's dense output (the monitor's
   `vectors`: the step's end, or its start where the latest measurement was there; else
   measured, as SingularityMonitor.measure at the positions there) into *u. 0: done; 1: a
   state or the SVD declined. */
static int vector_at(mechsim_lu *c, mechsim_projection *pc, mechsim_segment *s, double tm,
                     double t_old, double t_new, const double *u_end, const double **u) {
  if (tm == t_new) { *u = u_end; return 0; }
  if (tm == t_old && s->has_vector && s->vector_t == t_old) { *u = s->vector; return 0; }
  mechsim_search *w = (mechsim_search *)s->search;
  if (search_positions(c, w, 1, &tm, pc->q)) return 1;
  if (mechsim_measure(pc, tm, 0.0, s->dip_measured, s->dip_J)) return 1;
  *u = s->dip_measured + 4;
  return 0;
}

/* SingularityMonitor._dips_seen and observe's use of each dip, on the measured nodes of
   the search just made (w->out, in time order) over the step [t0, t1] (t0 = t_old),
   `width` either side of a dip's least value its span, into p. 0: done; SEG_SEARCH where
   a refinement, a value or a vector the engine declines, or no room for a passage. */
static int64_t dips_step(mechsim_lu *c, mechsim_projection *pc, mechsim_segment *s,
                         double t0, double t1, double width, double enter, double leave,
                         const double *u_end, seg_passages *p) {
  const mechsim_search *w = (const mechsim_search *)s->search;
  const int64_t m = pc->m, last = w->found - 1;
  const double *rows = w->out;
  #define T_AT(i) (rows[3 * (i)])
  #define S_AT(i) (rows[3 * (i) + 2] > 0.0 ? rows[3 * (i) + 1] / rows[3 * (i) + 2] : 0.0)
  int64_t first = -1, least = -1;            /* the run being collected (intervals.dips) */
  if (p->has_open && w->found) first = least = 0;
  for (int64_t k = 0; k <= w->found; k++) {
    int closed = 0, emit = 0;
    if (k < w->found) {
      const double value = S_AT(k);
      if (value < enter && !(first == 0 && k == 0)) {
        if (first < 0) first = least = k;
        else if (value < S_AT(least)) least = k;
      } else if (value > leave && first >= 0) {
        emit = closed = 1;
      }
    } else {
      emit = first >= 0;
    }
    if (!emit) continue;
    /* the dip: its least value refined between its neighbours, or inside the step from
       an end */
    double tm = T_AT(least), sm = S_AT(least), found[2];
    const double xatol_share = s->refine_tol;
    if (0 < least && least < last) {
      const double ta = T_AT(least - 1), tb = T_AT(least + 1);
      if (mechsim_passage_minimum(c, pc, (mechsim_search *)w, ta, tb, xatol_share * (tb - ta),
                                  found)) return SEG_SEARCH;
      if (found[1] < sm) { tm = found[0]; sm = found[1]; }
    } else if (last > 0) {
      const int64_t j = least == 0 ? 1 : last - 1;
      const double inside = T_AT(least) + 1e-3 * (T_AT(j) - T_AT(least));
      double value;
      if (s_on_step(c, pc, (mechsim_search *)w, inside, &value)) return SEG_SEARCH;
      if (value < sm) {
        const double ta = py_min(T_AT(least), T_AT(j)), tb = py_max(T_AT(least), T_AT(j));
        if (mechsim_passage_minimum(c, pc, (mechsim_search *)w, ta, tb,
                                    xatol_share * (tb - ta), found)) return SEG_SEARCH;
        if (found[1] < sm) { tm = found[0]; sm = found[1]; }
      }
    }
    const double *um;
    if (vector_at(c, pc, s, tm, t0, t1, u_end, &um)) return SEG_SEARCH;
    const int at_start = first == 0, at_end = !closed;
    const double d_start = at_start ? t0 : py_max(t0, tm - width);
    const double d_end = at_end ? t1 : py_min(t1, tm + width);
    if (p->has_open && at_start) {              /* the open passage goes on */
      lower(s, p, m, tm, sm, um);
      if (!at_end && close_passage(s, p, m, d_end)) return SEG_SEARCH;
    } else if (at_end) {                        /* the step ends inside it */
      open_at(s, p, m, d_start, tm, sm, um);
    } else if (record_passage(s, p, m, d_start, d_end, sm, tm, 0.0, 1, um)) {
      return SEG_SEARCH;                        /* a passage inside the step: no room */
    }
    first = least = -1;
  }
  #undef T_AT
  #undef S_AT
  return 0;
}

/* SingularityMonitor.observe's passages after the measured step from t_old (observation o;
   hidden_clear's clears, the search with the open passage as it stands, each dip found,
   then the step's end) as candidates in p, committed with the observation
   (commit_passages). 0: done; SEG_SEARCH where the loop observes the step (a mechanism
   that is not small, a search, refinement or vector the engine declines, no room). */
static int64_t passages_step(mechsim_lu *c, mechsim_projection *pc, mechsim_segment *s,
                             int64_t N, double t_old, double t_new, double h, const double *y,
                             const double *y_new, const double *f_new,
                             const seg_observation *o, seg_passages *p, int *ready,
                             int64_t *evaluations) {
  const int64_t n = pc->n, m = pc->m;
  p->has_open = (int)s->has_open;
  p->u_set = (int)s->open_u_set;
  p->t_start = s->open_t_start; p->t_min = s->open_t_min; p->s_min = s->open_s_min;
  p->bridged = s->open_bridged;
  p->added = 0;
  memcpy(s->cand_u, s->open_u, m * sizeof(double));
  if (o->skip) return 0;
  const double *u_end = s->measured + 4;
  const double peak = o->peak, enter = s->enter * peak, leave = s->leave * peak;
  double a[3], rate_bound = 0.0;
  if (!search_clear(pc, s, o, m, n, t_old, t_new, !p->has_open, a, &rate_bound)) {
    if (!s->small ||                          /* _anchored, then _dips_seen */
        monitor_search(c, pc, s, N, o, a, rate_bound, t_old, t_new, h, y, y_new, f_new,
                       p->has_open, ready, evaluations))
      return SEG_SEARCH;
    const int64_t why = dips_step(c, pc, s, a[0], t_new, enter / (rate_bound / 2.0), enter,
                                  leave, u_end, p);
    if (why) return why;
  }
  const double raw = o->smin / o->smax;       /* the step's end */
  if (p->has_open) {
    lower(s, p, m, t_new, raw, u_end);
    if (o->srel > s->leave && close_passage(s, p, m, t_new)) return SEG_SEARCH;
  } else if (o->srel < s->enter) {
    open_at(s, p, m, t_new, t_new, raw, u_end);
  }
  return 0;
}

/* The passages of a step that stands (passages_step's candidates p). */
static void commit_passages(mechsim_segment *s, const seg_passages *p, int64_t m) {
  s->has_open = p->has_open;
  s->open_u_set = p->u_set;
  s->open_t_start = p->t_start; s->open_t_min = p->t_min; s->open_s_min = p->s_min;
  s->open_bridged = p->bridged;
  memcpy(s->open_u, s->cand_u, m * sizeof(double));
  s->passages_n += p->added;
}

/* HybridPolicy.lu_limit and leave_lu after an LU step of length h, the monitor at `last`
   falling at `rate`: the next step's limit (*has_limit, *limit) and the held steps
   (*held) as candidates; 1 where the hybrid hands over to projection. */
static int policy_step(const mechsim_segment *s, double h, double last, double rate,
                       int *has_limit, double *limit, int *held) {
  if (rate < 0.0 && last > s->enter) {
    *has_limit = 1;
    *limit = py_max(0.5 * (last - s->enter) / -rate, 1e-6);
  }
  const int was_held = s->has_limit && h >= 0.99 * s->limit;
  *held = was_held ? *held + 1 : 0;
  const int predicted = last < s->enter || (rate < 0.0 && last + rate * h < s->enter);
  return predicted || *held >= 2;
}

/* The k output samples at s->ts[k0 ...] inside the step from t_old (Recorder.within,
   Partitioned.states) into the rows after s->held: 0 done; 1 where a stage or a state is
   declined, a sample lands on the other branch or is not finite (the loop's to solve). */
static int samples_step(mechsim_lu *c, mechsim_segment *s, double t_old, double h,
                        const double *y, const double *y_new, const double *f_new, int64_t k0,
                        int64_t k, int *ready, int64_t *evaluations) {
  const int64_t N = 2 * c->f, n = c->n, width = 1 + 2 * n;
  if (dense_ready(s, N, t_old, h, y, y_new, f_new, ready, evaluations)) return 1;
  mechsim_interpolate(N, s->dense_rows + 3, s->F, t_old, h, y, k, s->ts + k0, s->Y);
  double *rows = s->rows + s->held * width;
  for (int64_t j = 0; j < k; j++) {
    double *row = rows + j * width, sign = 0.0;
    row[0] = s->ts[k0 + j];
    if (lu_state(c, row[0], s->Y + j * N, row + 1, row + 1 + n, c->J, &sign)) return 1;
    if (sign != 0.0 && sign != s->sign) return 1;
    for (int64_t i = 1; i < width; i++)
      if (!isfinite(row[i])) return 1;
  }
  return 0;
}

/* The partition's accepted state (predictor, chord, reference, last z, w, t), kept to go
   back to (keep_partition, restore_partition). */
static void keep_partition(const mechsim_lu *c, mechsim_segment *s) {
  const int64_t f = c->f, n = c->n, r = n - f;
  memcpy(s->keep_P, c->P, r * (3 + f) * sizeof(double));
  memcpy(s->keep_C, c->C, r * r * sizeof(double));
  memcpy(s->keep_q_ref, c->q_ref, n * sizeof(double));
  memcpy(s->keep_z, c->z_last, f * sizeof(double));
  memcpy(s->keep_w, c->w_last, r * sizeof(double));
  s->keep_t = c->t_last;
}

static void restore_partition(mechsim_lu *c, const mechsim_segment *s) {
  const int64_t f = c->f, n = c->n, r = n - f;
  memcpy((double *)c->P, s->keep_P, r * (3 + f) * sizeof(double));
  memcpy((double *)c->C, s->keep_C, r * r * sizeof(double));
  memcpy((double *)c->q_ref, s->keep_q_ref, n * sizeof(double));
  memcpy(c->z_last, s->keep_z, f * sizeof(double));
  memcpy(c->w_last, s->keep_w, r * sizeof(double));
  c->t_last = s->keep_t;
}

/* The warm start of the monitor's SVD (`jacobi_svd`) as it stands before a step's
   observation, kept in s: where the observation does not stand (the segment leaves the
   step to the loop, or ends before it), `restore_measures` puts it back, and the loop's
   measurements of the step start where the segment's did, to the same bits. */
static void keep_measures(const mechsim_projection *pc, mechsim_segment *s) {
  s->jacobi_kept = pc->jacobi_warm;
  if (pc->jacobi_warm) memcpy(s->jacobi_keep, pc->jacobi_from, pc->m * pc->m * sizeof(double));
  s->jacobi_open = 1;
}

static void restore_measures(mechsim_projection *pc, mechsim_segment *s) {
  if (!s->jacobi_open) return;
  pc->jacobi_warm = s->jacobi_kept;
  if (s->jacobi_kept) memcpy(pc->jacobi_from, s->jacobi_keep, pc->m * pc->m * sizeof(double));
  s->jacobi_open = 0;
}

/* The monitor's state after the step from t_old to t_new that stands, from its
   observation o (SingularityMonitor.observe's assignments). */
static void commit_observation(mechsim_segment *s, const seg_observation *o, int64_t mn,
                               double t_old, double t_new) {
  s->jacobi_open = 0;                  /* its measurements stand */
  if (o->skip) {
    s->skipped += 1;
    s->floor_t = t_new; s->floor_v = o->floor_value; s->has_floor = 1;
    s->known_n = 1;                    /* the floor's bounds: the next search's anchor */
    s->known[0] = t_new; s->known[1] = o->floor_lo; s->known[2] = o->floor_hi;
    return;
  }
  int64_t kept = 0;                    /* the measurements known: the one at t_old, if any */
  for (int64_t j = 0; j < s->known_n; j++)
    if (s->known[3 * j] == t_old) {
      memmove(s->known, s->known + 3 * j, 3 * sizeof(double));
      kept = 1;
      break;
    }
  s->known_n = kept;
  double *kn = s->known + 3 * s->known_n;
  kn[0] = t_new; kn[1] = o->smin; kn[2] = o->smax;
  s->known_n += 1;
  memcpy(s->Jm, s->Js + o->slot * mn, mn * sizeof(double));
  s->m_smin = o->smin; s->m_smax = o->smax; s->m_speed = o->speed; s->has_measured = 1;
  s->ratio_speed = o->ratio_speed;
  if (o->has_fall) {
    double *fs = s->fall_scalars + 4 * o->slot;
    fs[0] = t_new; fs[1] = o->smin; fs[2] = o->smax; fs[3] = o->rate_norm;
    s->cur = o->slot;
  }
  s->has_fall = o->has_fall;
  s->peak = o->peak; s->peak_rate = o->peak_rate;
  s->prev_t = t_new; s->prev_s = o->srel; s->prev_rate = o->rate; s->has_prev = 1;
  s->skipped = 0;
  const int64_t m = ((const mechsim_search *)s->search)->m;   /* the end's singular vector */
  memcpy(s->vector, s->measured + 4, m * sizeof(double));
  s->vector_t = t_new;
  s->has_vector = 1;
  s->last = o->srel; s->rate = o->rate;
}

/* Partitioned.after_step's accepted end at t_new (y_new, q_new, v_new): with `shift`, the
   reference moved to it (q_ref + B z, z_last - z) and the state shifted to z = 0 into
   s->y_here (adapters.shift_in_place: y + (corrected - y)); the predictor formed from the
   accepted state before it (mechsim_lu_predictor, as Partitioned._accept). */
static void accept_end(mechsim_lu *c, mechsim_segment *s, double t_new, const double *y_new,
                       const double *q_new, const double *v_new, int shift) {
  const int64_t f = c->f, n = c->n, r = n - f, N = 2 * f;
  double *z = s->z, *w = s->w, *wd = s->wd;
  if (shift) {
    double *q_ref = (double *)c->q_ref;
    for (int64_t i = 0; i < f; i++) {
      q_ref[c->ind[i]] = q_ref[c->ind[i]] + y_new[i];
      c->z_last[i] = c->z_last[i] - y_new[i];
      z[i] = 0.0;
    }
    for (int64_t i = 0; i < r; i++) q_ref[c->dep[i]] = q_ref[c->dep[i]] + 0.0;
  } else {
    memcpy(z, y_new, f * sizeof(double));
  }
  for (int64_t i = 0; i < r; i++) {
    w[i] = q_new[c->dep[i]] - c->q_ref[c->dep[i]];
    wd[i] = v_new[c->dep[i]];
  }
  memcpy(s->z0, c->z_last, f * sizeof(double));
  memcpy(s->w0, c->w_last, r * sizeof(double));
  mechsim_lu_predictor(c, t_new, 0, c->t_last, z, y_new + f, w, wd, s->z0, s->w0, s->reduced,
                       s->inverse, s->P);
  if (shift) {
    for (int64_t i = 0; i < f; i++) s->y_here[i] = y_new[i] + (0.0 - y_new[i]);
    for (int64_t i = f; i < N; i++) s->y_here[i] = y_new[i] + (y_new[i] - y_new[i]);
  }
}

/* mechsim_dop853 from (s->t, s->y, s->fy) with the integrator's settings in s, on the
   step's rate (s->rate_ctx of s->kind; min_rcond s->rate_rcond, s->cut), the state of N
   entries: its end into s->y_new, s->f_new, s->out. Its status (0 accepted). */
static int dop853_step(mechsim_segment *s, int64_t N) {
  double *in = s->in;
  in[0] = (double)s->stages; in[1] = s->t; in[2] = s->h_abs; in[3] = s->t_bound;
  in[4] = s->direction; in[5] = s->max_step; in[6] = s->rtol; in[7] = s->rate_rcond;
  in[8] = s->cut; in[9] = s->safety; in[10] = s->min_factor; in[11] = s->max_factor;
  in[12] = s->exponent;
  return mechsim_dop853(s->rate_ctx, s->kind, N, s->coef, in, s->y, s->fy, s->atol, s->K,
                        s->y_new, s->f_new, s->work, s->out, (void *)declined_rate);
}

/* A segment's next step (CompiledDOP853.step) from (s->t, s->y, s->fy) on the step's rate
   (s->rate_ctx of s->kind; min_rcond s->rate_rcond, s->cut), the state of N entries: its
   end into s->y_new, s->f_new, out = (t_new, h, next h_abs, evaluations). 0: a step the
   segment may take (one to the run's end included: `ends_run`); else why not (the step
   limit, a stage declined, a step shorter than the stall rule's span). */
static int64_t segment_step(mechsim_segment *s, int64_t N) {
  if (s->max_steps >= 0 && s->steps + 1 > s->max_steps) return SEG_LIMIT;
  const double *out = s->out;
  if (dop853_step(s, N)) return SEG_STEP;
  if (out[1] < s->min_advance) return SEG_SHORT;
  return 0;
}

/* Whether the step to t_new ends the run (CompiledDOP853's status "finished" after it):
   the segment takes it up to the monitor's observation and leaves it pending, as a step
   with a sample due at its end (`sample_window`), for the loop to finish (Run._after_step,
   _after_accept: the formulation's correction, the sample at the end, no rate evaluated
   again after the last step). */
static int ends_run(const mechsim_segment *s, double t_new) {
  return s->direction * (t_new - s->t_bound) >= 0.0;
}

/* The output samples inside the step from t_old to t_new (Recorder.within): s->ts[*k0 ...
   *k0 + *k - 1], the grid's next index after them *next, and *due whether the grid's next
   sample falls at t_new itself (Recorder.due: the loop's to record, the step pending).
   0, or why the segment cannot record them (no room; a sample at every step's end without
   room). */
static int64_t sample_window(mechsim_segment *s, double t_old, double t_new, int64_t *k0,
                             int64_t *k, int64_t *next, int *due) {
  int64_t j = s->next;
  while (j < s->n_ts && s->ts[j] < t_new) j++;
  int64_t first = s->next;
  while (first < j && !(s->ts[first] > t_old)) first++;
  *k0 = first;
  *k = j - first;
  *next = j;
  if (*k > 0 && (s->held + *k > s->capacity || *k > s->y_rows)) return SEG_ROOM;
  *due = j < s->n_ts && s->ts[j] == t_new;
  if (s->every_step && s->held + 1 > s->capacity) return SEG_ROOM;
  return 0;
}

/* |v|inf of the step's end (q, v), NaN where an entry of q or v is not finite. */
static double end_speed(int64_t n, const double *q, const double *v) {
  double speed = 0.0;
  for (int64_t i = 0; i < n; i++) {
    if (!isfinite(q[i]) || !isfinite(v[i])) return NAN;
    const double a = fabs(v[i]);
    if (a > speed) speed = a;
  }
  return speed;
}

/* The integrator and the run after the step from t_old that stands (its end y_end, f_end,
   N entries; k samples inside it; the sample at its end (t_new, q_end, v_end) where every
   step records one; the log's row). */
static void commit_step(mechsim_segment *s, int64_t N, int64_t n, double t_old,
                        const double *y_end, const double *f_end, int64_t evaluations,
                        int64_t next, int64_t k, const double *q_end, const double *v_end,
                        double speed, double s_un, double rate_un) {
  /* q_end NULL: the step's end is the loop's to record (a pending step) */
  const double t_new = s->out[0], h = s->out[1], h_next = s->out[2];
  memcpy(s->y_old, s->y, N * sizeof(double));
  memcpy(s->y, y_end, N * sizeof(double));
  memcpy(s->fy, f_end, N * sizeof(double));
  s->t_old = t_old;
  s->t = t_new;
  s->h_previous = h;
  s->h_abs = h_next;
  s->evaluations += evaluations;
  s->steps += 1;
  s->next = next;
  s->held += k;
  if (s->every_step && q_end) {                /* Recorder.record_due at the step's end */
    double *row = s->rows + s->held * (1 + 2 * n);
    row[0] = t_new;
    memcpy(row + 1, q_end, n * sizeof(double));
    memcpy(row + 1 + n, v_end, n * sizeof(double));
    s->held += 1;
  }
  double *log = s->log + 6 * s->count;
  log[0] = t_new; log[1] = h; log[2] = speed; log[3] = h_next; log[4] = s_un;
  log[5] = rate_un;
  s->count += 1;
}

/* Whether the runaway rule looks at the run after its latest step (Run._advance). */
static int runaway_due(const mechsim_segment *s) {
  return s->steps >= s->runaway_from && s->steps % s->runaway_every == 0;
}

/* Whether the monitor's verdict on a step (observe_step, hidden_clear) leaves its
   observation to the loop: the step is still taken, pending. */
static int observed_by_loop(int64_t why) {
  return why == SEG_MEASURE || why == SEG_BAND || why == SEG_SEARCH || why == SEG_OPEN;
}

/* Commit a pending step (its end y_new, f_new; k samples inside it) and what it leaves to
   the loop: PENDING_DECIDE with its observation o committed, PENDING_OBSERVE without. */
static void commit_pending(mechsim_segment *s, int64_t N, int64_t n, int64_t mn, double t_old,
                           const seg_observation *o, int64_t kind, int64_t why,
                           int64_t evaluations, int64_t next, int64_t k, double speed,
                           int ready) {
  if (kind == PENDING_DECIDE) commit_observation(s, o, mn, t_old, s->out[0]);
  commit_step(s, N, n, t_old, s->y_new, s->f_new, evaluations, next, k, NULL, NULL, speed,
              0.0, 0.0);
  s->pending = kind;
  s->dense_formed = ready;
  s->reason = why;
}

/* Up to s->budget accepted steps of DOP853 on the partition c (kind 1), each followed by
   what Run._advance does after a plain step of a small rigid mechanism in LU (the hybrid's LU
   phase, or "lu"): its output samples (dense output, positions and velocities) written to
   the rows of s->rows, the singularity monitor's observation (its skip, `observe_step`, or
   its measurement and the cheap clears of a hidden passage, or its search and the passages
   found inside the step recorded, passages_step; with s->through, where the run's
   tolerances stay its own inside a passage, also the band, the open passage going on and
   a step that ends inside one), the hybrid's policy and step
   limit, the partition's end (branch, condition, re-reference, predictor). Where the
   hybrid switches to the projection method or the partition changes, the step is taken up
   to the monitor's observation and its samples and the segment ends with it pending
   (s->pending, s->reason): the Python loop finishes it (Run._after_step). Where anything
   else would happen (a stage or state the engine declines, a step whose search the engine
   cannot finish, without s->through one that ends inside a passage or in a passage's
   band, a sample due at the
   step's end, no room for the samples, a
   step shorter than the stall rule's span), the step is dropped and the segment ends
   before it with s->reason: the Python loop takes it, from the same state, with the same
   numbers. Everything a committed step changes is in s, c and the buffers s points to;
   Python reads it back (mechsim.run.segment). */
int64_t mechsim_lu_segment(mechsim_lu *c, mechsim_projection *pc, mechsim_segment *s) {
  const int64_t N = 2 * c->f, f = c->f, n = c->n, m = c->m;
  const int64_t mn = m * n;
  double *y = s->y, *y_new = s->y_new, *f_new = s->f_new;
  s->rate_ctx = c;
  s->kind = 1;
  s->rate_rcond = -1.0;
  s->cut = 0.0;
  s->pending = 0;
  s->count = 0;
  s->reason = SEG_BUDGET;
  s->jacobi_open = 0;
  while (s->count < s->budget) {
    int64_t why = segment_step(s, N);
    if (why) { s->reason = why; break; }
    int64_t evaluations = (int64_t)s->out[3];
    const double t_old = s->t, t_new = s->out[0], h = s->out[1];
    /* the step's end (Partitioned.keeps_branch, after_step: one LU of Phi_q D) */
    memcpy(c->y, y_new, N * sizeof(double));
    if (mechsim_lu_end(c, t_new, s->inverse, s->reduced, s->block) ||
        s->block[0] != s->sign) { s->reason = SEG_BRANCH; break; }
    const int64_t fresh = c->fresh;
    const double condition = s->block[1];
    memcpy(s->Jq, c->J, mn * sizeof(double));          /* Phi_q there, kept below */
    double *q_new = s->q_new, *v_new = s->v_new;
    memcpy(q_new, c->q, n * sizeof(double));
    memcpy(v_new, c->v, n * sizeof(double));
    /* the output samples inside the step (Recorder.within): computed once the step is
       known to stand, below */
    int64_t k0, k, next;
    int due = 0;
    why = sample_window(s, t_old, t_new, &k0, &k, &next, &due);
    if (why) { s->reason = why; break; }
    const double speed = end_speed(n, q_new, v_new);
    if (isnan(speed)) { s->reason = SEG_FINITE; break; }
    /* the monitor (SingularityMonitor.observe), its state changed only once the step
       stands: the candidates in o */
    seg_observation o;
    seg_passages p;
    int ready = 0;                       /* the step's dense output formed */
    keep_measures(pc, s);
    why = s->open_at_start && !s->count && !s->through ? SEG_OPEN :
        observe_step(pc, s, t_old, t_new, q_new, v_new, speed, &o);
    if (why && !observed_by_loop(why)) { s->reason = why; break; }
    /* The hybrid's policy (HybridPolicy.lu_limit, leave_lu) and the partition's choice
       (Partitioned.after_step): where either is the loop's (`pending`: a switch to the
       projection method, a new partition), the step is still taken here up to the
       monitor's observation and its samples, and the loop finishes it. */
    int64_t pending = 0;
    int has_limit = 0, held = (int)s->held_steps;
    double limit = 0.0;
    if (!why) {
      const double last = o.skip ? s->last : o.srel, mon_rate = o.skip ? s->rate : o.rate;
      if (s->hybrid && policy_step(s, h, last, mon_rate, &has_limit, &limit, &held))
        pending = SEG_LEAVE;
      /* a passage hidden in the step, ruled out (the search last: a step the loop takes
         anyway spends none) */
      why = passages_step(c, pc, s, N, t_old, t_new, h, y, y_new, f_new, &o, &p, &ready,
                          &evaluations);
      /* a step that ends inside a passage: the loop's where LU's tolerances change there */
      if (!why && p.has_open && !s->through) why = SEG_SEARCH;
    }
    if (why) {     /* the loop's observation (of a dip found: the kept search), pending */
      if (k > 0 && samples_step(c, s, t_old, h, y, y_new, f_new, k0, k, &ready,
                                &evaluations)) {
        s->reason = SEG_SAMPLES;
        break;
      }
      commit_pending(s, N, n, mn, t_old, &o, PENDING_OBSERVE, why, evaluations, next, k,
                     speed, ready);
      break;
    }
    if (!pending && (due || ends_run(s, t_new))) pending = due ? SEG_DUE : SEG_FINISHED;
    double repartition_at = s->repartition_at;
    if (!pending && (fresh >= 2 || condition > repartition_at)) {
      /* Partitioned.after_step's choose: the same set stands until its condition grows as
         much again; another is a new partition (the loop's) */
      if (!keeps_set(c, pc, s, s->Jq)) pending = SEG_PARTITION;
      else repartition_at = py_min(s->cond_max, s->growth * py_max(condition, 1.0));
    }
    /* the output samples (Recorder.within, Partitioned.states), before the partition
       moves its reference */
    if (k > 0 && samples_step(c, s, t_old, h, y, y_new, f_new, k0, k, &ready, &evaluations)) {
      s->reason = SEG_SAMPLES;
      break;
    }
    if (pending) {
      commit_pending(s, N, n, mn, t_old, &o, PENDING_DECIDE, pending, evaluations, next, k,
                     speed, ready);
      commit_passages(s, &p, m);
      break;
    }
    double zmax = 0.0;
    for (int64_t i = 0; i < f; i++) zmax = py_max(zmax, fabs(y_new[i]));
    const int shift = zmax > s->reference_span;
    const int resolve = shift && s->every_step;  /* the end's sample solved again, below */
    if (resolve) keep_partition(c, s);           /* the partition as it was, to go back to */
    accept_end(c, s, t_new, y_new, q_new, v_new, shift);
    /* A sample at every step's end (Run._accept's record_due): after a re-reference the
       loop solves it from the new reference, through the partition's state (Partitioned.
       state); where that declines, the partition goes back and the loop takes the step. */
    double *q_end = q_new, *v_end = v_new;
    if (resolve) {
      int bad = lu_state(c, t_new, s->y_here, s->q_here, s->v_here, c->J, NULL);
      for (int64_t i = 0; i < n && !bad; i++)
        bad = !isfinite(s->q_here[i]) || !isfinite(s->v_here[i]);
      if (bad) {
        restore_partition(c, s);
        s->reason = SEG_DUE;
        break;
      }
      q_end = s->q_here;
      v_end = s->v_here;
    }
    /* committed from here: nothing below declines */
    memcpy(s->J_end, s->Jq, mn * sizeof(double));
    memcpy(s->kept_inverse, s->inverse, (n - f) * (n - f) * sizeof(double));
    memcpy(s->kept_reduced, s->reduced, (n - f) * f * sizeof(double));
    memcpy(s->kept_block, s->block, 2 * sizeof(double));
    s->factorizations += 1;
    s->repartition_at = repartition_at;
    if (shift) {
      memcpy(y_new, s->y_here, N * sizeof(double));
      s->corrections += 1;
    }
    s->max_step = s->run_max_step;             /* StepBound.after_step */
    if (s->hybrid) {
      s->held_steps = held;
      s->has_limit = has_limit;
      s->limit = limit;
      s->policy_steps += 1;
      if (has_limit) s->max_step = py_min(s->run_max_step, limit);
    }
    commit_observation(s, &o, mn, t_old, t_new);
    commit_passages(s, &p, m);
    s->sign = s->block[0];
    commit_step(s, N, n, t_old, y_new, f_new, evaluations, next, k, q_end, v_end, speed, 0.0,
                0.0);
    if (runaway_due(s)) break;
  }
  restore_measures(pc, s);
  return s->count;
}

/* The rate [v; qdd] of the projection method at the state y (2n entries) at t into f, on its
   compiled accelerations with min_rcond and cut (compiled_rate, no fallback). 0: done;
   1: declined. */
static int projection_rate(mechsim_projection *pc, double t, const double *y, double min_rcond,
                           double cut, double *f) {
  int64_t declined = 0;
  return compiled_rate(pc, 0, t, y, f, 2 * pc->n, min_rcond, cut,
                       (mechsim_rate_t)declined_rate, &declined);
}

/* SingularityMonitor.predicted_within(h) at s/peak = last falling at `rate`. */
static int predicted_within(double last, double rate, double h, double enter) {
  return last < enter || (rate < 0.0 && last + rate * h < enter);
}

/* The passage bridge's plan as a segment carries it (PassageBridge's _prev, landing,
   free_step, _free_bound; not standing down, nothing declined). */
typedef struct {
  int has_prev, has_landing, has_free, free_bound, has_planned, reset;
  double prev_t, prev_rate, landing, free_step, planned_t, planned_star, rate;
} seg_bridge;

/* PassageBridge.plan after a step ending at t with sigma_min/sigma_max = sv falling at
   `rate` (unnormalized), the next step h_next (`bound`: the run's max_step), from the plan
   b carries, which it changes as plan does: 1 where it returns None, 2 where it lands
   (the next step up to *land), 0 where it would cross or stand down (the loop's). */
static int bridge_plan(const mechsim_segment *s, seg_bridge *b, double t, double sv,
                       double rate, double h_next, int bound, double *land) {
  const int has_prev = b->has_prev;
  const double prev_t = b->prev_t, prev_rate = b->prev_rate;
  b->has_prev = 1;
  b->prev_t = t;
  b->prev_rate = rate;
  if (rate >= 0.0) {
    b->has_landing = b->has_prev = b->has_free = 0;
    b->reset = 1;
  }
  if (!(rate < 0.0)) return 1;
  if (sv < s->edge) return 0;
  const double curv = has_prev && t > prev_t ? (rate - prev_rate) / (t - prev_t) : 0.0;
  const double disc = rate * rate - 2.0 * curv * sv;
  const double to_star = disc > 0.0 ? 2.0 * sv / (-rate + sqrt(disc)) : sv / -rate;
  b->has_planned = 1;                               /* plan's _planned and _rate */
  b->planned_t = t;
  b->planned_star = to_star;
  b->rate = -rate;
  if (!b->has_landing) {
    if (to_star > 3.0 * h_next) {                  /* note_step */
      if (!b->has_free || h_next >= b->free_step) {
        b->has_free = 1;
        b->free_step = h_next;
        b->free_bound = bound;
      }
      return 1;
    }
    const double floor = (b->free_bound ? 3.2 : 1.6) * s->edge / -rate;
    const double base = b->has_free && b->free_step != 0.0 ? b->free_step : h_next;
    b->landing = py_max(s->landing_share * base, floor);
    b->has_landing = 1;
  }
  if (to_star <= 1.5 * b->landing) return 0;
  const double reach = to_star - py_max(b->landing, 0.25 * to_star);
  if (reach <= 0.0) return 0;
  if (!(reach < h_next)) return 1;
  *land = reach;
  return 2;
}

/* The output samples at s->ts[k0 ...] inside the step from t_old (Recorder.within,
   FullCoordinates.states: each put onto the constraints as settle_samples does in the
   engine, to ROUND_OFF of its largest coordinate) into the rows after s->held, the
   projections counted in *projections. 0: done; 1 where a stage is declined, a sample's
   projection is the Python path's, or a sample is not finite. */
static int projection_samples(mechsim_projection *pc, mechsim_segment *s, double t_old,
                              double h, const double *y, const double *y_new,
                              const double *f_new, int64_t k0, int64_t k, int *ready,
                              int64_t *evaluations, int64_t *projections) {
  const int64_t n = pc->n, N = 2 * n, width = 1 + 2 * n;
  if (dense_ready(s, N, t_old, h, y, y_new, f_new, ready, evaluations)) return 1;
  mechsim_interpolate(N, s->dense_rows + 3, s->F, t_old, h, y, k, s->ts + k0, s->Y);
  double *rows = s->rows + s->held * width;
  for (int64_t j = 0; j < k; j++) {
    double *row = rows + j * width, *q = row + 1, *v = row + 1 + n;
    row[0] = s->ts[k0 + j];
    memcpy(q, s->Y + j * N, n * sizeof(double));
    memcpy(v, s->Y + j * N + n, n * sizeof(double));
    const double top = max_abs(n, q);
    const double tol = s->round_off * (top > 1.0 ? top : 1.0);
    const int status = settle_state(pc, row[0], q, v, tol, 8);
    if (status == 1) return 1;
    *projections += status == 0;
    for (int64_t i = 1; i < width; i++)
      if (!isfinite(row[i])) return 1;
  }
  return 0;
}

/* Up to s->budget accepted steps of DOP853 of the projection method on its compiled
   accelerations (kind 0, pc; the Cholesky path with s->min_rcond and s->cut, or without the
   condition estimate while far from the band, as Projection._far_from_band decides after
   each step), each followed by what Run._advance does after a plain step of the projection
   method (the hybrid's projection phase, or "projection") clear of a passage: the output
   samples put onto the constraints, the singularity monitor's observation (as in
   mechsim_lu_segment, the positions q = y[:n]), the state projected onto the constraints
   (Projection.after_step, NumericProblem.project_state compiled) and its rate evaluated
   again there (adapters.correct_in_place), the hybrid's count of stable steps towards LU
   (SwitchPolicy.back_to_lu, its condition test mechsim_lu_condition), the passage bridge's
   plan (nothing, or the approach's landing as the next step's bound). Where the formulation
   or the bridge decides something else (a switch to LU, a crossing, a projection or a rate
   the engine declines) the step is taken up to the monitor's observation and the segment
   ends with it pending (s->pending, s->reason): the Python loop finishes that step
   (Run.finish_step). Where the bridge crosses the passages (s->handles_passages and
   s->through) the
   monitor's passages are observed here too (passages_step: the open one going on,
   closing and opening, the dips a search finds); else the band, a passage open at the
   start and a search that finds a dip leave the step's observation to the loop. Where
   anything else would happen (the reasons of mechsim_lu_segment) the step is dropped and
   the segment ends before it with s->reason: the Python loop takes it from the same
   state. */
int64_t mechsim_projection_segment(mechsim_projection *pc, mechsim_segment *s) {
  const int64_t n = pc->n, m = pc->m, N = 2 * n, mn = m * n;
  double *y = s->y, *y_new = s->y_new, *f_new = s->f_new, *y_here = s->y_here;
  s->rate_ctx = pc;
  s->kind = 0;
  s->count = 0;
  s->pending = 0;
  s->reason = SEG_BUDGET;
  s->jacobi_open = 0;
  while (s->count < s->budget) {
    s->rate_rcond = s->far ? -1.0 : s->min_rcond;
    int64_t why = segment_step(s, N);
    if (why) { s->reason = why; break; }
    int64_t evaluations = (int64_t)s->out[3], projections = 0;
    const double t_old = s->t, t_new = s->out[0], h = s->out[1], h_next = s->out[2];
    const double *q_new = y_new, *v_new = y_new + n;
    int64_t k0, k, next;
    int due = 0;
    why = sample_window(s, t_old, t_new, &k0, &k, &next, &due);
    if (why) { s->reason = why; break; }
    const double speed = end_speed(n, q_new, v_new);
    if (isnan(speed)) { s->reason = SEG_FINITE; break; }
    seg_observation o;
    seg_passages p;
    int ready = 0;
    const int own = (int)s->handles_passages;       /* the passages observed here */
    keep_measures(pc, s);
    why = s->open_at_start && !s->count && !s->through ? SEG_OPEN :
        observe_step(pc, s, t_old, t_new, q_new, v_new, speed, &o);
    if (why && !observed_by_loop(why)) { s->reason = why; break; }
    if (why) {                     /* the loop's observation: the step's samples, pending */
      if (k > 0 && projection_samples(pc, s, t_old, h, y, y_new, f_new, k0, k, &ready,
                                      &evaluations, &projections)) {
        s->reason = SEG_SAMPLES;
        break;
      }
      s->projections += projections;
      commit_pending(s, N, n, mn, t_old, &o, PENDING_OBSERVE, why, evaluations, next, k,
                     speed, ready);
      break;
    }
    const double last = o.skip ? s->last : o.srel, mon_rate = o.skip ? s->rate : o.rate;
    const double peak = o.peak;
    /* What the formulation and the bridge decide after the step (Projection.after_step,
       SwitchPolicy.back_to_lu, bridge_passage): where that is the loop's (`pending`: a
       projection or a rate the engine declines, a switch to LU, a crossing), the step is
       still taken here up to the monitor's observation, and the loop finishes it. */
    int64_t pending = 0;
    const int far = s->leave * peak > 100.0 * s->cut && last >= s->leave &&
        !predicted_within(last, mon_rate, 3.0 * h, s->enter);
    memcpy(pc->q, q_new, n * sizeof(double));
    memcpy(pc->v, v_new, n * sizeof(double));
    const int status = mechsim_project_state(pc, t_new, s->skip_tol, s->project_tol,
                                             s->min_rcond, 0, 8);
    const int moved = status == 0;
    if (status == 1) pending = SEG_PROJECT;
    else if (moved) {
      memcpy(y_here, pc->q, n * sizeof(double));
      memcpy(y_here + n, pc->v, n * sizeof(double));
    } else {
      memcpy(y_here, y_new, N * sizeof(double));
    }
    const int64_t end_projections = moved ? pc->count : 0;
    /* the hybrid's way back to LU (SwitchPolicy.back_to_lu, Hybrid._lu_ready) */
    int64_t stable = 0;
    if (!pending && s->hybrid) {
      const int growing = h >= 0.99 * s->previous;
      const int clear = last > s->leave && !predicted_within(last, mon_rate, h, s->enter);
      int fit = clear && growing;
      if (fit && !(last * peak > 1e-6)) pending = SEG_LEAVE;   /* Python's choice */
      else if (fit) {
        memcpy(pc->q, y_here, n * sizeof(double));
        fit = mechsim_lu_condition(pc, t_new) < s->lu_limit;
      }
      stable = fit ? s->stable + 1 : 0;
      if (stable >= s->stable_steps) pending = SEG_LEAVE;
    }
    /* the passage bridge's plan (Run._bridge, bridge_passage): nothing, or a landing */
    const double s_un = last * peak, rate_un = mon_rate * peak;
    seg_bridge b = {(int)s->has_bprev, (int)s->has_landing, (int)s->has_free,
                    (int)s->free_bound, (int)s->has_planned, (int)s->plan_reset,
                    s->bprev_t, s->bprev_rate, s->landing, s->free_step, s->planned_t,
                    s->planned_star, s->plan_rate};
    int plan = 1;
    double land = 0.0;
    if (!pending && s->bridging) {
      plan = h_next != 0.0 ? bridge_plan(s, &b, t_new, s_un, rate_un,
                                         py_min(h_next, s->run_max_step),
                                         h_next >= s->run_max_step, &land) : 0;
      if (!plan) pending = SEG_BRIDGE;
    }
    why = own ? passages_step(NULL, pc, s, N, t_old, t_new, h, y, y_new, f_new, &o, &p,
                              &ready, &evaluations) :
        hidden_clear(NULL, pc, s, t_old, t_new, h, y, y_new, f_new, &o, &ready, &evaluations);
    if (k > 0 && projection_samples(pc, s, t_old, h, y, y_new, f_new, k0, k, &ready,
                                    &evaluations, &projections)) {
      s->reason = SEG_SAMPLES;
      break;
    }
    if (why) {             /* a dip not ruled out: the loop observes (the kept search) */
      s->projections += projections;
      commit_pending(s, N, n, mn, t_old, &o, PENDING_OBSERVE, why, evaluations, next, k,
                     speed, ready);
      break;
    }
    if (!pending && (due || ends_run(s, t_new))) pending = due ? SEG_DUE : SEG_FINISHED;
    /* the projected state's rate (adapters.correct_in_place), on the next step's far */
    const double *f_end = f_new;
    if (!pending && moved) {
      if (projection_rate(pc, t_new, y_here, far ? -1.0 : s->min_rcond, s->cut, s->f_here))
        pending = SEG_PROJECT;
      else
        f_end = s->f_here;
    }
    /* committed from here: the observation, samples and the step; the rest where it is
       not pending */
    s->projections += projections;
    if (pending) {
      commit_pending(s, N, n, mn, t_old, &o, PENDING_DECIDE, pending, evaluations, next, k,
                     speed, ready);
      if (own) commit_passages(s, &p, m);
      break;
    }
    commit_observation(s, &o, mn, t_old, t_new);
    if (own) commit_passages(s, &p, m);
    s->projections += end_projections;
    s->corrections += moved;       /* each with its rate evaluated again */
    s->far_taken = s->far;
    s->far = far;
    s->max_step = plan == 2 ? py_min(s->run_max_step, land) : s->run_max_step;
    if (s->hybrid) {
      s->stable = stable;
      s->previous = h;
      s->policy_steps += 1;
    }
    s->has_bprev = b.has_prev; s->bprev_t = b.prev_t; s->bprev_rate = b.prev_rate;
    s->has_landing = b.has_landing; s->landing = b.landing;
    s->has_free = b.has_free; s->free_step = b.free_step; s->free_bound = b.free_bound;
    s->has_planned = b.has_planned; s->planned_t = b.planned_t;
    s->planned_star = b.planned_star; s->plan_rate = b.rate; s->plan_reset = b.reset;
    commit_step(s, N, n, t_old, y_here, f_end, evaluations, next, k, y_here, y_here + n, speed,
                s_un, rate_un);
    if (runaway_due(s)) break;
  }
  restore_measures(pc, s);
  return s->count;
}


/* PassageBridge._norm: the RMS over N entries of (hi - lo) / (atol + rtol max(|a|, |b|))
   (adams.error_norm). */
static double bridge_norm(int64_t N, const double *hi, const double *lo, const double *a,
                          const double *b, double rtol, const double *atol) {
  if (N == 0) return 0.0;
  double sum = 0.0;
  for (int64_t i = 0; i < N; i++) {
    const double scale = atol[i] + rtol * py_max(fabs(a[i]), fabs(b[i]));
    const double r = (hi[i] - lo[i]) / scale;
    sum += r * r;
  }
  return sqrt(sum / (double)N);
}

/* y_n + H (w0 f + w[1:] . F) into y (N entries; F: K rows of N, f NULL: the weights w are
   F's alone). */
static void adams_sum(int64_t N, int64_t K, const double *y_n, double H, const double *w,
                      const double *f, const double *F, double *y) {
  const int64_t first = f != NULL;
  for (int64_t i = 0; i < N; i++) {
    double sum = f != NULL ? w[0] * f[i] : 0.0;
    for (int64_t j = 0; j < K; j++) sum += w[first + j] * F[j * N + i];
    y[i] = y_n[i] + H * sum;
  }
}

/* The passage bridge's Adams interpolant (PassageBridge._finish) at the P fractions s of
   its step: row p of Y (P x N) is y_n + H (w(s_p) . F), F the K rates (rows of N) at the
   nodes (in units of the step), w_j(s) the integral over [0, s] of node j's Lagrange
   polynomial by the G-point Gauss-Legendre rule gx, gw on [0, 1] scaled to [0, s], as
   adams.integration_weights (its sums in another order: round-off apart); W: 2 K scratch. */
void mechsim_adams_values(int64_t N, int64_t K, const double *y_n, double H,
                          const double *nodes, const double *F, int64_t P, const double *s,
                          int64_t G, const double *gx, const double *gw, double *W,
                          double *Y) {
  double *den = W + K;                      /* the Lagrange polynomials' denominators */
  for (int64_t j = 0; j < K; j++) {
    den[j] = 1.0;
    for (int64_t i = 0; i < K; i++)
      if (i != j) den[j] *= nodes[j] - nodes[i];
  }
  for (int64_t p = 0; p < P; p++) {
    for (int64_t j = 0; j < K; j++) W[j] = 0.0;
    for (int64_t g = 0; g < G; g++) {
      const double x = s[p] * gx[g];
      for (int64_t j = 0; j < K; j++) {
        double L = 1.0;
        for (int64_t i = 0; i < K; i++)
          if (i != j) L *= x - nodes[i];
        W[j] += gw[g] * (L / den[j]);
      }
    }
    for (int64_t j = 0; j < K; j++) W[j] *= s[p];
    adams_sum(N, K, y_n, H, W, NULL, F, Y + p * N);
  }
}

/* The passage bridge's corrector and its order estimates (PassageBridge._corrected_end
   and cross) on the projection method's compiled accelerations (min_rcond, cut): from the
   state y_n (N = 2n entries) and the K rates F of its history (rows, at t_n first), a step
   of H to t_b. The prediction y = y_n + H (w_pred . F), then up to `iterations`
   corrections y = y_n + H (w_corr . [f_b; F]), f_b the rate at y put onto the constraints
   (mechsim_project_state to 1e-13 and one more chord iteration, as
   PassageBridge._consistent), until the change's norm (rtol, atol) is under 1e-2: the
   last f_b into f_b. Then the L orders' ends y_n + H (W[l] . [f_b; F]) (rows of K + 1
   weights, zero past their nodes) into Y (L x N), and the norms of their successive
   differences (against y_n and the higher order) into errs (L - 1). counts: the rates and
   the chord iterations taken; work: 3 N. 0: done; 1: a projection or a rate the engine
   declines (the Python corrector takes the step from its start). */
int mechsim_bridge_corrector(mechsim_projection *pc, int64_t N, int64_t K, const double *y_n,
                             const double *F, const double *w_pred, const double *w_corr,
                             int64_t L, const double *W, double H, double t_b, double rtol,
                             const double *atol, int64_t iterations, double min_rcond,
                             double cut, double *work, double *counts, double *f_b,
                             double *Y, double *errs) {
  const int64_t n = pc->n;
  double *y_c = work, *y_new = work + N, *settled = work + 2 * N;
  int64_t rates = 0, projections = 0;
  adams_sum(N, K, y_n, H, w_pred, NULL, F, y_c);
  for (int64_t it = 0; it < iterations; it++) {
    memcpy(pc->q, y_c, n * sizeof(double));
    memcpy(pc->v, y_c + n, n * sizeof(double));
    if (mechsim_project_state(pc, t_b, -1.0, 1e-13, -1.0, 1, 8) == 1) return 1;
    projections += pc->count;
    memcpy(settled, pc->q, n * sizeof(double));
    memcpy(settled + n, pc->v, n * sizeof(double));
    if (projection_rate(pc, t_b, settled, min_rcond, cut, f_b)) return 1;
    rates++;
    adams_sum(N, K, y_n, H, w_corr, f_b, F, y_new);
    const double change = bridge_norm(N, y_new, y_c, y_c, y_new, rtol, atol);
    memcpy(y_c, y_new, N * sizeof(double));
    if (change < 1e-2) break;
  }
  for (int64_t l = 0; l < L; l++) adams_sum(N, K, y_n, H, W + l * (K + 1), f_b, F, Y + l * N);
  for (int64_t l = 0; l + 1 < L; l++)
    errs[l] = bridge_norm(N, Y + (l + 1) * N, Y + l * N, y_n, Y + (l + 1) * N, rtol, atol);
  counts[0] = (double)rates;
  counts[1] = (double)projections;
  return 0;
}

/* The first step of an integrator at (s->t, s->y) with rate s->fy (N entries) towards
   s->t_bound on the projection context pc, into s->h_abs: the starting step of Hairer,
   Nørsett and Wanner (Solving Ordinary Differential Equations I, II.4) as scipy's
   `select_initial_step` takes it for DOP853 (error order 7; its RMS norms as
   `bridge_norm`'s): h0 from the sizes of y and its rate, one more rate at an Euler
   step of h0 (on the step's rate, s->rate_rcond; into s->f_new, counted in
   s->evaluations) for the rate's change, and the step that keeps the next term of
   order 8 at 1 % of the tolerance, at most 100 h0, the interval and s->max_step. 0, or 1
   where that rate is declined. */
static int starting_step(mechsim_projection *pc, mechsim_segment *s, int64_t N) {
  const double *y = s->y, *f0 = s->fy, *atol = s->atol;
  double *y1 = s->y_new, *f1 = s->f_new;
  const double rtol = s->rtol, interval = fabs(s->t_bound - s->t);
  if (interval == 0.0) {
    s->h_abs = 0.0;
    return 0;
  }
  memset(y1, 0, N * sizeof(double));            /* zeros, for the sizes of y and f0 */
  const double d0 = bridge_norm(N, y, y1, y, y, rtol, atol);
  const double d1 = bridge_norm(N, f0, y1, y, y, rtol, atol);
  const double h0 = py_min(d0 < 1e-5 || d1 < 1e-5 ? 1e-6 : 0.01 * d0 / d1, interval);
  for (int64_t i = 0; i < N; i++) y1[i] = y[i] + h0 * s->direction * f0[i];
  if (projection_rate(pc, s->t + h0 * s->direction, y1, s->rate_rcond, s->cut, f1))
    return 1;
  s->evaluations += 1;
  const double d2 = bridge_norm(N, f1, f0, y, y, rtol, atol) / h0;
  const double h1 = d1 <= 1e-15 && d2 <= 1e-15 ? py_max(1e-6, h0 * 1e-3)
                                               : pow(0.01 / py_max(d1, d2), 1.0 / 8.0);
  s->h_abs = py_min(py_min(100.0 * h0, h1), py_min(interval, s->max_step));
  return 0;
}

/* The rate at s->y (s->t; min_rcond s->min_rcond) into s->fy and f0 (N entries), and
   from there `starting_step`'s first step into s->h_abs: the history's start, as
   mechsim_history makes it, for the history the Python loop integrates
   (PassageBridge._history) to take the same first step. 0, or 1 where a rate is
   declined. */
int mechsim_history_start(mechsim_projection *pc, mechsim_segment *s, double *f0) {
  const int64_t N = 2 * pc->n;
  s->rate_ctx = pc;
  s->kind = 0;
  if (projection_rate(pc, s->t, s->y, s->min_rcond, s->cut, s->fy)) return 1;
  memcpy(f0, s->fy, N * sizeof(double));
  return starting_step(pc, s, N);
}

/* The passage bridge's history (PassageBridge._history and the rates of _start): DOP853
   from (s->t, s->y, s->fy) towards s->t_bound on the projection method's compiled
   accelerations (s->rate_rcond, s->cut), as CompiledDOP853.step takes its steps, the state
   at each of the k times ts it passes taken from the step's dense output and put onto the
   constraints (mechsim_project_state to 1e-13 with one more chord iteration, as
   PassageBridge._consistent) into the rows of `states` (k x 2n); then the rates at the
   start and at each of those states into the rows of F ((k + 1) x 2n; min_rcond
   s->min_rcond). s->evaluations: the integrator's count so far, which may not exceed
   `budget` after a step (the history grinds); the rates of the steps and their dense
   output add to it, the chord iterations to s->projections. Where s->h_abs is 0 the
   integrator starts here: its rate at the start is F's first row and its first step
   `starting_step`'s. Returns k; -1 where a stage, a projection or a rate is declined (the
   Python path takes the history from its start); -2 where the step falls below scipy's
   smallest or the count exceeds the budget (the bridge declines). */
int64_t mechsim_history(mechsim_projection *pc, mechsim_segment *s, int64_t k,
                        const double *ts, double budget, double *states, double *F) {
  const int64_t n = pc->n, N = 2 * n;
  double *y = s->y, *fy = s->fy, *y_new = s->y_new, *f_new = s->f_new;
  double *out = s->out, *row = s->y_here;
  const double t0 = s->t;
  s->rate_ctx = pc;
  s->kind = 0;
  s->projections = 0;
  if (s->h_abs == 0.0 ? mechsim_history_start(pc, s, F)
                      : projection_rate(pc, t0, y, s->min_rcond, s->cut, F))
    return -1;
  int64_t j = 0;
  while (j < k) {
    const int status = dop853_step(s, N);
    if (status == 1) return -1;
    if (status == 2) return -2;
    s->evaluations += (int64_t)out[3];
    if ((double)s->evaluations > budget) return -2;
    const double t_old = s->t, t_new = out[0], h = out[1];
    const int64_t first = j;
    while (j < k && s->direction * (t_new - ts[j]) >= 0.0) j++;
    if (j > first) {
      int ready = 0;
      int64_t extra = 0;
      if (dense_ready(s, N, t_old, h, y, y_new, f_new, &ready, &extra)) return -1;
      s->evaluations += extra;
      for (int64_t i = first; i < j; i++) {
        mechsim_interpolate(N, s->dense_rows + 3, s->F, t_old, h, y, 1, ts + i, row);
        memcpy(pc->q, row, n * sizeof(double));
        memcpy(pc->v, row + n, n * sizeof(double));
        if (mechsim_project_state(pc, ts[i], -1.0, 1e-13, -1.0, 1, 8)) return -1;
        s->projections += pc->count;
        memcpy(states + i * N, pc->q, n * sizeof(double));
        memcpy(states + i * N + n, pc->v, n * sizeof(double));
      }
    }
    memcpy(y, y_new, N * sizeof(double));
    memcpy(fy, f_new, N * sizeof(double));
    s->t = t_new;
    s->h_abs = out[2];
  }
  for (int64_t i = 0; i < k; i++)
    if (projection_rate(pc, ts[i], states + i * N, s->min_rcond, s->cut, F + (i + 1) * N))
      return -1;
  return k;
}

/* A passage bridge's attempt in one call (PassageBridge.cross up to its decision: `_start`,
   `_out_of_band` at the first length, `_corrector_in_engine`) on the projection context pc
   and the integrator of s (`PlainSteps.start_integrator` set it up, its rates' min_rcond and
   cut in s): the landing state y (N = 2n entries; out: put onto the constraints as
   PassageBridge._consistent puts it, mechsim_project_state to 1e-13 and one more chord
   iteration) at ts[0], its history at the K - 1 times ts[1..] (`mechsim_history` with at
   most `budget` evaluations: states, F), then the prediction of the step of H to
   t_b = ts[0] + H with the weights w_pred; where sigma_kk / sigma_max of J~ there (kk) is
   above `edge2`, the corrector and the orders' estimates (`mechsim_bridge_corrector` with
   w_pred, w_corr, the L orders' rows W, rtol, atol, `iterations`: f_b, Y, errs). counts:
   the chord iterations of the landing state's projection, the history's rates and
   projections, the corrector's rates and chord iterations; work: 3 N. Returns 0 (the
   corrector's estimates made); 1 (the prediction at H lies in the band: the history is
   made, the caller lengthens the step); -1 (a projection, a rate or an SVD the engine
   declines: the Python path takes the attempt from its start); -2 (the history fails or
   grinds: the bridge stands down). */
int64_t mechsim_bridge_attempt(mechsim_projection *pc, mechsim_segment *s, int64_t K,
                               const double *ts, double *y, double H, double budget,
                               int64_t kk, double edge2, const double *w_pred,
                               const double *w_corr, int64_t L, const double *W,
                               double rtol, const double *atol, int64_t iterations,
                               double *work, double *counts, double *states, double *F,
                               double *f_b, double *Y, double *errs) {
  const int64_t n = pc->n, N = 2 * n;
  const double t_n = ts[0], t_b = t_n + H;
  memcpy(pc->q, y, n * sizeof(double));
  memcpy(pc->v, y + n, n * sizeof(double));
  if (mechsim_project_state(pc, t_n, -1.0, 1e-13, -1.0, 1, 8)) return -1;
  counts[0] = (double)pc->count;
  memcpy(y, pc->q, n * sizeof(double));
  memcpy(y + n, pc->v, n * sizeof(double));
  memcpy(s->y, y, N * sizeof(double));
  s->evaluations = 0;
  const int64_t got = mechsim_history(pc, s, K - 1, ts + 1, budget, states, F);
  if (got < 0) return got;
  counts[1] = (double)s->evaluations;
  counts[2] = (double)s->projections;
  counts[3] = counts[4] = 0.0;
  adams_sum(N, K, y, H, w_pred, NULL, F, work);
  double ex[2];
  scaled_jacobian(pc, work, t_b, pc->A);
  if (svd_extremes(pc, kk, ex)) return -1;
  if (!((ex[1] > 0.0 ? ex[0] / ex[1] : 0.0) > edge2)) return 1;
  if (mechsim_bridge_corrector(pc, N, K, y, F, w_pred, w_corr, L, W, H, t_b, rtol, atol,
                               iterations, s->min_rcond, s->cut, work, counts + 3, f_b, Y,
                               errs))
    return -1;
  return 0;
}
