/* The order-th derivative of ((c0 u + c1) u + c2) u + c3 (0 beyond the third). */
static double mechsim_cubic(int order, const double *c, double u) {
  switch (order) {
    case 0: return ((c[0] * u + c[1]) * u + c[2]) * u + c[3];
    case 1: return (3.0 * c[0] * u + 2.0 * c[1]) * u + c[2];
    case 2: return 6.0 * c[0] * u + 2.0 * c[1];
    case 3: return 6.0 * c[0];
    default: return 0.0;
  }
}

/* The periodic cubic spline of mechsim.model.splines.evaluate: the order-th derivative at
   phi of the spline of k pieces whose k + 1 knots and 4 k coefficients are p[0 .. 5 k]. */
static double mechsim_pspline(int order, double phi, int k, const double *p) {
  const double two_pi = 6.283185307179586;
  double x = fmod(phi - p[0], two_pi);
  if (x < 0.0) x += two_pi;
  x += p[0];
  int lo = 0, hi = k - 1;               /* the last piece whose knot is at or below x */
  while (lo < hi) {
    int mid = (lo + hi + 1) / 2;
    if (x >= p[mid]) lo = mid; else hi = mid - 1;
  }
  return mechsim_cubic(order > 3 ? 3 : order, p + k + 1 + 4 * lo, x - p[lo]);
}

/* The table's cubic spline of mechsim.model.splines.evaluate_table: the order-th
   derivative at t of the spline of k pieces whose k + 1 knots and 4 k coefficients are
   p[0 .. 5 k], its end pieces going on past the ends. */
static double mechsim_tspline(int order, double t, int k, const double *p) {
  int lo = 0, hi = k - 1;               /* the last piece whose knot is at or below t */
  while (lo < hi) {
    int mid = (lo + hi + 1) / 2;
    if (t >= p[mid]) lo = mid; else hi = mid - 1;
  }
  return mechsim_cubic(order, p + k + 1 + 4 * lo, t - p[lo]);
}
