"""Reference values for vehid-core's `stats` module, from scipy.stats and statsmodels.

Prints the Rust file `crates/vehid-core/src/stats/tests_ref.rs` (included by `stats/tests.rs`):

- `T_CDF_REF`: Student's t `(x, df, cdf, sf)` from `scipy.stats.t.cdf` / `t.sf`, for
  df in {0.5, 1, 2, 2.5, 3, 5, 7.3, 10, 30, 1e3, 1e6, 1e10, 1e20} and x from -1e6 (df < 1e6)
  or -40 to 40;
- `T_PPF_REF`: `(p, df, quantile)` from `scipy.stats.t.ppf`, p from 1e-300 through 1e-12 to
  1 - 1e-12, same df; `T_PPF_MPMATH_REF`: the points where scipy's `t.ppf` is off by more
  than 1e-13 relative, with 50-digit mpmath quantiles instead (each listed in the header of the
  generated file with scipy's value);
- `T_SWEEP_CDF_REF` / `T_SWEEP_PPF_REF`: mpmath alone (50 digits, 130 for df >= 1e4) (scipy is not the reference
  there) on a wide grid: df from 0.01 to 1e31, x = -1e-6 4^k down to -1.8e7 (-40 for df >= 1e6), p from 1e-300 to
  1 - 1e-12;
- `NORM_REF` / `NORM_PPF_REF`: `scipy.stats.norm.cdf`, `norm.sf`, `norm.ppf`;
- `OLS_REF`: three `statsmodels.api.OLS(...).fit()` regressions on fixed data (a straight line
  with tiny p-values, three correlated regressors with an insignificant one, a cubic with a
  condition number near 1.2e4): the inputs `params`, `normalized_cov_params`, `ssr`, `nobs`, and
  the results `df_resid`, `scale`, `bse`, `tvalues`, `pvalues`, `conf_int(alpha)`,
  `cov_params()`, `t.ppf(1 - alpha/2, df_resid)` and `condition_number`;
- `CUSUM_REF`: three `statsmodels.api.RecursiveLS(...).fit()` runs (stable, a shift in the
  intercept, a tenfold noise increase): the recursive residuals after the diffuse period, the
  `cusum` and `cusum_squares` series, `np.std(..., ddof=1)`, the bounds of
  `_cusum_significance_bounds` (alpha 0.01 and 0.05) and `_cusum_squares_significance_bounds`
  (alpha 0.2, 0.1, 0.05, 0.02, 0.01) at a few points, and the first crossings at alpha 0.05;
- `BDE_A`: Brown, Durbin & Evans' (1975) constant `a`, the root of
  `2 (Q(3a) + exp(-4a^2) (1 - Q(a))) = alpha` (`Q = norm.sf`, `scipy.optimize.brentq`), for
  alpha 0.01, 0.05, 0.10 (statsmodels' CUSUM bound at 0.10 uses 0.950, which is the 5 % root;
  vehid uses 0.850, so the 0.10 CUSUM bound is not taken from statsmodels).

Every scipy distribution value is checked here against mpmath at 50 digits (`mp.betainc`,
`mp.ncdf`; quantiles by Newton's method on those); the largest relative discrepancy of each
table is written into the generated header. The script fails if a CDF/SF value of scipy is off
by more than `1e-14 + 4 eps |ln p|` relative (`scipy_tol`), or a normal quantile by 1e-13.

Data are fixed: regressors and noise come from `numpy.random.RandomState` (the legacy
generator, whose streams numpy keeps frozen) with fixed seeds, rounded to 4 decimals.

Generated with Python 3.11.7, numpy 2.4.6, scipy 1.17.1, statsmodels 0.15.0, mpmath 1.4.1
(the generated header records the versions of the run that wrote it).

Rerun (the environment lives outside the repository):

    python3 -m venv /tmp/statsref
    /tmp/statsref/bin/pip install scipy statsmodels numpy mpmath
    /tmp/statsref/bin/python benches/stats_reference.py > crates/vehid-core/src/stats/tests_ref.rs
    cargo test -p vehid-core --lib stats
"""

import platform
import sys
import warnings

import mpmath as mp
import numpy as np
import scipy
import scipy.optimize
import scipy.stats as st
import statsmodels
import statsmodels.api as sm

mp.mp.dps = 50

EPS = sys.float_info.epsilon


def scipy_tol(p):
    """Largest relative error accepted from scipy against mpmath for a probability `p` (CDF/SF
    values: `1e-14 + 4 eps |ln p|`, the cost of an exponential of a number of size `|ln p|`)
    or for a quantile (`p = None`: 1e-13)."""
    if p is None:
        return 1e-13
    return 1e-14 + 4 * EPS * abs(np.log(max(p, sys.float_info.min)))


T_DFS = [0.5, 1.0, 2.0, 2.5, 3.0, 5.0, 7.3, 10.0, 30.0, 1000.0, 1e6, 1e10, 1e20]
T_XS = [-1e6, -40.0, -6.0, -2.0, -0.3, 0.0, 0.7, 2.0, 5.0, 40.0]
PS = [1e-300, 1e-12, 1e-6, 1e-3, 0.025, 0.05, 0.3, 0.5 + 2.0**-30, 0.7, 0.95, 0.975, 0.999, 1 - 1e-6, 1 - 1e-12]
NORM_XS = [-37.5, -37.0, -20.0, -8.0, -3.0, -1.0, -0.3, 0.0, 0.7, 2.0, 5.0, 8.2]
NORM_PS = [1e-300, 1e-100] + PS[1:]

SWEEP_DFS = [0.01, 0.1, 0.3, 0.9, 1.7, 3.3, 9.9, 33.0, 150.5, 2e3, 5e4, 1e6, 1e9, 1e13, 1e18, 1e25, 1e31]
SWEEP_PS = [1e-300, 1e-200, 1e-100, 1e-50, 1e-20, 1e-10, 1e-6, 1e-3, 0.01, 0.05, 0.1, 0.2, 0.25, 0.2500001, 0.3, 0.4]
SWEEP_PS += [0.45, 0.49, 0.499, 0.4999999, 0.5000001, 0.6, 0.75, 0.9, 0.99, 0.999999, 1 - 1e-12]

HALF = mp.mpf(1) / 2


def lit(v):
    """A Rust f64 literal that reads back to exactly `v`."""
    v = float(v)
    if np.isnan(v):
        return "f64::NAN"
    if np.isinf(v):
        return "f64::INFINITY" if v > 0 else "f64::NEG_INFINITY"
    r = repr(v)
    return r if ("." in r or "e" in r) else r + ".0"


def field(name, values, indent=8, pairs=False):
    """`name: &[...],` on one line, or wrapped at 120 characters, one indent deeper."""
    items = [f"[{lit(a)}, {lit(b)}]" for a, b in values] if pairs else [lit(v) for v in values]
    pad = " " * indent
    one = f"{pad}{name}: &[{', '.join(items)}],"
    if len(one) <= 120:
        return [one]
    lines, line = [f"{pad}{name}: &["], pad + "    "
    for item in items:
        if len(line) + len(item) + 1 > 120:
            lines.append(line.rstrip())
            line = pad + "    "
        line += item + ", "
    lines += [line.rstrip(), f"{pad}],"]
    return lines


def rel(a, b):
    """Relative difference of a float `a` from an mpf `b`, floored at the smallest normal."""
    if np.isinf(a) or mp.isinf(b):
        return 0.0 if float(a) == float(b) else float("inf")
    return float(abs(mp.mpf(a) - b) / max(abs(b), mp.mpf(sys.float_info.min)))


# --- mpmath at 50 digits --------------------------------------------------------------------


def mp_t_tail(x, nu):
    """P(T > x) for x >= 0 (nu = inf: the normal).

    `1/2 I_{nu/(nu+x^2)}(nu/2, 1/2)`; for nu >= 1e4, where `nu/(nu+x^2)` is within `x^2/nu` of 1,
    at 130 digits and through the central part `1/2 - 1/2 I_y(1/2, nu/2)`, `y = x^2/(nu+x^2)`,
    unless the tail is below 1e-80 (then `nu/(nu+x^2)` keeps 50 digits of its complement)."""
    if nu == float("inf"):
        return mp.ncdf(-mp.mpf(x))
    with mp.workdps(mp.mp.dps if nu < 1e4 else 130):
        x, nu = mp.mpf(x), mp.mpf(nu)
        y = x * x / (nu + x * x)
        if nu >= 1e4 and y < HALF:
            t = HALF - mp.betainc(HALF, nu / 2, 0, y, regularized=True) / 2
            if t > mp.mpf(10) ** -80:
                return +t
        return mp.betainc(nu / 2, HALF, 0, nu / (nu + x * x), regularized=True) / 2


def mp_t_cdf(x, nu):
    if x == 0:
        return HALF
    return mp_t_tail(-x, nu) if x < 0 else 1 - mp_t_tail(x, nu)


def mp_t_pdf(x, nu):
    x = mp.mpf(x)
    if nu == float("inf"):
        return mp.npdf(x)
    nu = mp.mpf(nu)
    return mp.exp(
        mp.loggamma((nu + 1) / 2) - mp.loggamma(nu / 2) - mp.log(nu * mp.pi) / 2 - (nu + 1) / 2 * mp.log1p(x * x / nu)
    )


def mp_t_ppf(p, nu, start):
    """The quantile: Newton's method on ln P(T > e^u) = ln min(p, 1 - p) in u = ln|x|."""
    p = mp.mpf(p)
    if p == HALF:
        return mp.mpf(0)
    q = min(p, 1 - p)
    if start is None or not np.isfinite(start) or start == 0:
        # The normal quantile with its first correction in 1/nu (A&S 26.7.5), or for nu < 4 the
        # larger of it and the power-law tail P(T > t) ~ f(0) (sqrt(nu)/t)^nu / sqrt(nu).
        z = mp.mpf(st.norm.isf(float(q)))
        start = z if nu == float("inf") else z + z * (z * z + 1) / (4 * mp.mpf(nu))
        if nu < 4:
            root = mp.sqrt(nu)
            start = max(start, root * (mp_t_pdf(0, nu) / (q * root)) ** (1 / mp.mpf(nu)))
    u = mp.log(abs(mp.mpf(start)))

    def h(u):
        return mp.log(mp_t_tail(mp.exp(u), nu)) - mp.log(q)

    hu = h(u)
    for _ in range(200):
        t = mp.exp(u)
        slope = -t * mp_t_pdf(t, nu) / mp_t_tail(t, nu)
        step = -hu / slope
        while True:  # damped: never let |h| grow
            hn = h(u + step)
            if abs(hn) < abs(hu) or abs(step) < mp.mpf(10) ** -45:
                break
            step /= 2
        u, hu = u + step, hn
        if abs(step) < mp.mpf(10) ** -40:
            break
    else:
        raise RuntimeError(f"mpmath quantile did not converge: p={p}, nu={nu}")
    return (1 if p > HALF else -1) * mp.exp(u)


# --- distribution tables --------------------------------------------------------------------


def t_tables(out, notes):
    cdf_rows, worst = [], 0.0
    for nu in T_DFS:
        # (x = -1e6 with df >= 1e6 is P = 0 in f64, and a betainc that mpmath takes minutes on.)
        for x in [x for x in T_XS if abs(x) <= 40 or nu < 1e6]:
            c, s = st.t.cdf(x, nu), st.t.sf(x, nu)
            exact_c, exact_s = mp_t_cdf(x, nu), mp_t_cdf(-x, nu)
            err = max(rel(c, exact_c) / scipy_tol(c), rel(s, exact_s) / scipy_tol(s))
            if err > 1:
                raise SystemExit(f"scipy t.cdf/sf({x}, {nu}) off by {err:.2f} times the tolerance")
            worst = max(worst, err)
            cdf_rows.append((x, nu, c, s))
    notes.append(f"t.cdf / t.sf: largest difference from mpmath {worst:.2f} x (1e-14 + 4 eps |ln p|)")
    ppf_rows, mp_rows, worst = [], [], 0.0
    for nu in T_DFS:
        for p in PS:
            v = st.t.ppf(p, nu)
            exact = mp_t_ppf(p, nu, v)
            err = rel(v, exact)
            if err > scipy_tol(None):
                mp_rows.append((p, nu, float(exact)))
                notes.append(f"t.ppf({p:.17g}, {nu:g}): scipy {float(v):.17g}, mpmath {float(exact):.17g} ({err:.1e})")
            else:
                worst = max(worst, err)
                ppf_rows.append((p, nu, v))
    notes.append(f"t.ppf where used: largest relative difference from mpmath {worst:.1e}")
    out.append("/// Student's t from scipy: `(x, df, t.cdf(x, df), t.sf(x, df))`.")
    out.append(f"const T_CDF_REF: [(f64, f64, f64, f64); {len(cdf_rows)}] = [")
    out += [f"    ({lit(x)}, {lit(nu)}, {lit(c)}, {lit(s)})," for x, nu, c, s in cdf_rows]
    out.append("];")
    out.append("/// Student's t quantiles from scipy: `(p, df, t.ppf(p, df))` (where scipy is accurate).")
    out.append(f"const T_PPF_REF: [(f64, f64, f64); {len(ppf_rows)}] = [")
    out += [f"    ({lit(p)}, {lit(nu)}, {lit(v)})," for p, nu, v in ppf_rows]
    out.append("];")
    out.append("/// Student's t quantiles where scipy's `t.ppf` is inaccurate: 50-digit mpmath values.")
    out.append(f"const T_PPF_MPMATH_REF: [(f64, f64, f64); {len(mp_rows)}] = [")
    out += [f"    ({lit(p)}, {lit(nu)}, {lit(v)})," for p, nu, v in mp_rows]
    out.append("];")


def sweep_tables(out, notes):
    """mpmath alone, over a wide grid: where scipy cannot be the reference (df 0.01 or 1e25)."""
    xs = [-1e-6 * 4.0**k for k in range(23)]
    rows, qrows = [], []
    for nu in SWEEP_DFS:
        for x in xs:
            if nu >= 1e6 and x < -40:
                continue  # P = 0 in f64
            rows.append((x, nu, float(mp_t_cdf(x, nu))))
        for p in SWEEP_PS:
            qrows.append((p, nu, float(mp_t_ppf(p, nu, None))))
    notes.append(f"sweep: {len(rows)} CDF values and {len(qrows)} quantiles from mpmath alone")
    out.append("/// Student's t from mpmath alone on a wide grid: `(x, df, P(T <= x))`, x = -1e-6 4^k.")
    out.append(f"const T_SWEEP_CDF_REF: [(f64, f64, f64); {len(rows)}] = [")
    out += [f"    ({lit(x)}, {lit(nu)}, {lit(c)})," for x, nu, c in rows]
    out.append("];")
    out.append("/// Student's t quantiles from mpmath alone on a wide grid: `(p, df, quantile)`.")
    out.append(f"const T_SWEEP_PPF_REF: [(f64, f64, f64); {len(qrows)}] = [")
    out += [f"    ({lit(p)}, {lit(nu)}, {lit(v)})," for p, nu, v in qrows]
    out.append("];")


def normal_tables(out, notes):
    rows, worst = [], 0.0
    for x in NORM_XS:
        c, s = st.norm.cdf(x), st.norm.sf(x)
        err = max(rel(c, mp.ncdf(x)) / scipy_tol(c), rel(s, mp.ncdf(-x)) / scipy_tol(s))
        if err > 1:
            raise SystemExit(f"scipy norm.cdf/sf({x}) off by {err:.2f} times the tolerance")
        worst = max(worst, err)
        rows.append((x, c, s))
    notes.append(f"norm.cdf / norm.sf: largest difference from mpmath {worst:.2f} x (1e-14 + 4 eps |ln p|)")
    prow, worst = [], 0.0
    for p in NORM_PS:
        v = st.norm.ppf(p)
        err = rel(v, mp_t_ppf(p, float("inf"), v))
        if err > scipy_tol(None):
            raise SystemExit(f"scipy norm.ppf({p}) off by {err:e} relative")
        worst = max(worst, err)
        prow.append((p, v))
    notes.append(f"norm.ppf: largest relative difference from mpmath {worst:.1e}")
    out.append("/// The standard normal from scipy: `(x, norm.cdf(x), norm.sf(x))`.")
    out.append(f"const NORM_REF: [(f64, f64, f64); {len(rows)}] = [")
    out += [f"    ({lit(x)}, {lit(c)}, {lit(s)})," for x, c, s in rows]
    out.append("];")
    out.append("/// The standard normal quantile from scipy: `(p, norm.ppf(p))`.")
    out.append(f"const NORM_PPF_REF: [(f64, f64); {len(prow)}] = [")
    out += [f"    ({lit(p)}, {lit(v)})," for p, v in prow]
    out.append("];")


# --- OLS ------------------------------------------------------------------------------------


def ols_data():
    """(name, X, y, alpha) of the fixed regressions."""
    rs = np.random.RandomState(20240601)
    n = 20
    x = np.round(np.linspace(0.0, 9.5, n), 4)
    line = np.column_stack([np.ones(n), x])
    y_line = np.round(1.5 + 0.8 * x + 0.05 * rs.standard_normal(n), 4)

    n = 30
    x1 = np.round(rs.standard_normal(n), 4)
    x2 = np.round(0.6 * x1 + 0.8 * rs.standard_normal(n), 4)
    x3 = np.round(rs.standard_normal(n), 4)
    three = np.column_stack([np.ones(n), x1, x2, x3])
    y_three = np.round(0.3 + 1.2 * x1 - 0.7 * x2 + 0.0 * x3 + 0.9 * rs.standard_normal(n), 4)

    n = 25
    t = np.round(np.linspace(0.0, 20.0, n), 4)
    cubic = np.column_stack([np.ones(n), t, t**2, t**3])
    y_cubic = np.round(2.0 - 0.5 * t + 0.3 * t**2 - 0.01 * t**3 + 0.4 * rs.standard_normal(n), 4)
    return [
        ("straight line, tiny p-values", line, y_line, 0.05),
        ("three correlated regressors, one insignificant", three, y_three, 0.10),
        ("cubic on [0, 20], condition number near 1.2e4", cubic, y_cubic, 0.01),
    ]


def ols_table(out):
    out.append("/// One `statsmodels.api.OLS(y, X).fit()`: the inputs of `summary_into` and its results.")
    out.append("struct OlsRef {")
    out.append("    name: &'static str,")
    out.append("    /// `params`, `normalized_cov_params` (row-major), `ssr`, `nobs`, and the level of `conf_int`.")
    out.append("    params: &'static [f64],")
    out.append("    cov_unscaled: &'static [f64],")
    out.append("    ssr: f64,")
    out.append("    nobs: f64,")
    out.append("    alpha: f64,")
    out.append("    /// `df_resid`, `scale`, `bse`, `tvalues`, `pvalues`, `conf_int(alpha)`, `cov_params()`.")
    out.append("    df_resid: f64,")
    out.append("    sigma2: f64,")
    out.append("    bse: &'static [f64],")
    out.append("    tvalues: &'static [f64],")
    out.append("    pvalues: &'static [f64],")
    out.append("    conf_int: &'static [[f64; 2]],")
    out.append("    cov_params: &'static [f64],")
    out.append("    /// `scipy.stats.t.ppf(1 - alpha/2, df_resid)`, the factor of `conf_int`.")
    out.append("    t_crit: f64,")
    out.append("    /// `condition_number` (from the singular values of X).")
    out.append("    condition_number: f64,")
    out.append("}")
    cases = ols_data()
    out.append(f"const OLS_REF: [OlsRef; {len(cases)}] = [")
    for name, X, y, alpha in cases:
        r = sm.OLS(y, X).fit()
        ci = r.conf_int(alpha)
        out.append("    OlsRef {")
        out.append(f'        name: "{name}",')
        out += field("params", r.params)
        out += field("cov_unscaled", r.normalized_cov_params.ravel())
        out.append(f"        ssr: {lit(r.ssr)},")
        out.append(f"        nobs: {lit(r.nobs)},")
        out.append(f"        alpha: {lit(alpha)},")
        out.append(f"        df_resid: {lit(r.df_resid)},")
        out.append(f"        sigma2: {lit(r.scale)},")
        out += field("bse", r.bse)
        out += field("tvalues", r.tvalues)
        out += field("pvalues", r.pvalues)
        out += field("conf_int", ci, pairs=True)
        out += field("cov_params", r.cov_params().ravel())
        out.append(f"        t_crit: {lit(st.t.ppf(1 - alpha / 2, r.df_resid))},")
        out.append(f"        condition_number: {lit(r.condition_number)},")
        out.append("    },")
    out.append("];")


# --- CUSUM ----------------------------------------------------------------------------------


def cusum_data():
    """(name, X, y) of the fixed recursive regressions (n = 60, k = 2)."""
    rs = np.random.RandomState(1975)
    n = 60
    x = np.round(rs.standard_normal(n), 4)
    e = np.round(rs.standard_normal(n), 4)
    X = np.column_stack([np.ones(n), x])
    stable = np.round(1.0 + 0.5 * x + 0.5 * e, 4)
    shift = np.round(stable + np.where(np.arange(n) >= 30, 1.0, 0.0), 4)
    louder = np.round(1.0 + 0.5 * x + 0.5 * e * np.where(np.arange(n) >= 30, 10.0, 1.0), 4)
    return [
        ("stable", X, stable),
        ("intercept shifts by 2 sigma at t = 30", X, shift),
        ("noise tenfold from t = 30", X, louder),
    ]


def first_crossing(values, lower, upper):
    out = np.nonzero((values < lower) | (values > upper))[0]
    return f"Some({out[0]})" if out.size else "None"


def cusum_table(out):
    out.append("/// One `statsmodels.api.RecursiveLS(y, X).fit()` and its CUSUM tests.")
    out.append("struct CusumRef {")
    out.append("    name: &'static str,")
    out.append("    /// `resid_recursive[d:]`, `d = max(nobs_diffuse, loglikelihood_burn) = k`.")
    out.append("    w: &'static [f64],")
    out.append("    /// `np.std(resid_recursive[d:], ddof=1)`, `cusum`, `cusum_squares`.")
    out.append("    sigma: f64,")
    out.append("    cusum: &'static [f64],")
    out.append("    cusum_squares: &'static [f64],")
    out.append("    /// `(alpha, j, upper)` of `_cusum_significance_bounds(alpha, points=d + j)`.")
    out.append("    cusum_bounds: &'static [(f64, f64, f64)],")
    out.append("    /// `(alpha, j, lower, upper)` of `_cusum_squares_significance_bounds(alpha, points=d + j)`.")
    out.append("    cusum_squares_bounds: &'static [(f64, f64, f64, f64)],")
    out.append("    /// First index outside statsmodels' 5 % bounds (point `d + i + 1` for entry `i`).")
    out.append("    first_cusum_crossing: Option<usize>,")
    out.append("    first_cusum_squares_crossing: Option<usize>,")
    out.append("}")
    cases = cusum_data()
    out.append(f"const CUSUM_REF: [CusumRef; {len(cases)}] = [")
    for name, X, y in cases:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            r = sm.RecursiveLS(y, X).fit()
        k = X.shape[1]
        d = max(r.nobs_diffuse, r.loglikelihood_burn)
        assert d == k, (d, k)
        w = r.resid_recursive[d:]
        m = len(w)
        sigma = np.std(w, ddof=1)
        assert np.array_equal(r.cusum, np.cumsum(w) / sigma)
        js = [0, 1, m // 2, m - 1, m]
        at = np.array([d + j for j in js], dtype=float)
        cb = []
        for alpha in (0.01, 0.05):
            _, upper = r._cusum_significance_bounds(alpha, points=at)
            cb += [(alpha, j, u) for j, u in zip(js, upper)]
        sb = []
        for alpha in (0.2, 0.1, 0.05, 0.02, 0.01):
            lower, upper = r._cusum_squares_significance_bounds(alpha, points=at)
            sb += [(alpha, j, lo, hi) for j, lo, hi in zip(js, lower, upper)]
        points = np.arange(d + 1, r.nobs + 1, dtype=float)
        lo5, hi5 = r._cusum_significance_bounds(0.05, points=points)
        slo5, shi5 = r._cusum_squares_significance_bounds(0.05, points=points)
        out.append("    CusumRef {")
        out.append(f'        name: "{name}",')
        out += field("w", w)
        out.append(f"        sigma: {lit(sigma)},")
        out += field("cusum", r.cusum)
        out += field("cusum_squares", r.cusum_squares)
        out.append("        cusum_bounds: &[")
        out += [f"            ({lit(a)}, {lit(j)}, {lit(u)})," for a, j, u in cb]
        out.append("        ],")
        out.append("        cusum_squares_bounds: &[")
        out += [f"            ({lit(a)}, {lit(j)}, {lit(lo)}, {lit(hi)})," for a, j, lo, hi in sb]
        out.append("        ],")
        out.append(f"        first_cusum_crossing: {first_crossing(r.cusum, lo5, hi5)},")
        out.append(f"        first_cusum_squares_crossing: {first_crossing(r.cusum_squares, slo5, shi5)},")
        out.append("    },")
    out.append("];")


def bde_table(out):
    def level(a):
        return 2 * (st.norm.sf(3 * a) + np.exp(-4 * a * a) * st.norm.cdf(a))

    rows = []
    for alpha in (0.01, 0.05, 0.10):
        rows.append((alpha, scipy.optimize.brentq(lambda a, al=alpha: level(a) - al, 0.3, 3.0, xtol=1e-15)))
    out.append("/// `(alpha, a)`: the root of Brown, Durbin & Evans' `2 (Q(3a) + exp(-4a²)(1 - Q(a))) = alpha`.")
    out.append(f"const BDE_A: [(f64, f64); {len(rows)}] = [")
    out += [f"    ({lit(al)}, {lit(a)})," for al, a in rows]
    out.append("];")


def main():
    notes, body = [], []
    t_tables(body, notes)
    sweep_tables(body, notes)
    normal_tables(body, notes)
    ols_table(body)
    cusum_table(body)
    bde_table(body)
    print("// @generated by benches/stats_reference.py: do not edit; rerun it (its docstring says how).")
    print(
        f"// Python {platform.python_version()}, numpy {np.__version__}, scipy {scipy.__version__}, "
        f"statsmodels {statsmodels.__version__}, mpmath {mp.__version__}."
    )
    print("// scipy checked against mpmath at 50 digits (relative differences):")
    for n in notes:
        print(f"// - {n}")
    print()
    print("\n".join(body))


if __name__ == "__main__":
    main()
