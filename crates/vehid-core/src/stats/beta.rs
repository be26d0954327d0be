//! The pieces of the regularized incomplete beta function `I_x(a, b)` that Student's t needs,
//! written so that they keep their relative accuracy for very large `a` (degrees of freedom).
//!
//! `I_x(a, b) = x^a y^b / B(a, b) × (a continued fraction or a series)`, with `y = 1 − x`
//! passed in separately so that neither `x` nor `y` is ever formed by a cancelling `1 − ·`.
//! The power terms `x^a y^b / B(a, b)` follow DiDonato & Morris (1992, ACM TOMS 708, `brcomp`):
//! Stirling's series with the exponents written as `a·rlog1(x/p − 1) + b·rlog1(y/q − 1)`,
//! `p = a/(a+b)`, `q = b/(a+b)`, so that nothing of size `a ln x` is ever formed and cancelled.
//! The continued fraction is the one Boost.Math evaluates in `ibeta_fraction2` (an even
//! contraction of DLMF 8.17.22 whose coefficients depend on `a y − b x` rather than on `1 − x`);
//! the plain Numerical-Recipes fraction loses `~a·ε` there, which is 1e-10 at a = 10⁶.

/// `ln √(2π)`.
pub(crate) const LN_SQRT_2PI: f64 = 0.918_938_533_204_672_8;

/// Iteration cap of the series and the continued fraction (they need < 100 in the regions
/// where they are used; the cap only guards against an unforeseen input).
const MAX_TERMS: usize = 10_000;

/// Smallest magnitude a Lentz denominator may take.
const TINY: f64 = 1e-300;

/// `e − ln(1 + e)` for `e > −1`, without cancellation near `e = 0`
/// (DiDonato & Morris' `rlog1`): with `r = e / (2 + e)`, `ln(1 + e) = 2 atanh r`, hence
/// `e − ln(1 + e) = r e − 2 r (r²/3 + r⁴/5 + …)`, both terms of one sign for `|e| ≤ ½`.
pub(crate) fn rlog1(e: f64) -> f64 {
    if (-0.5..=0.5).contains(&e) {
        let r = e / (2.0 + e);
        let r2 = r * r;
        let (mut sum, mut power, mut k) = (0.0, r2, 3.0);
        loop {
            let term = power / k;
            sum += term;
            if term <= 1e-17 * sum || power == 0.0 {
                break;
            }
            power *= r2;
            k += 2.0;
        }
        r * e - 2.0 * r * sum
    } else {
        e - libm::log1p(e)
    }
}

/// Stirling's remainder `δ(z) = ln Γ(z) − ((z − ½) ln z − z + ln √(2π))`, `z > 0`.
///
/// For `z ≥ 10` the asymptotic series `Σ B₂ₙ / (2n (2n−1) z^{2n−1})` (eight terms: the first
/// omitted one is below 2e-18); below, `lgamma` minus the closed part (absolute error a few
/// 1e-15, which is what matters: δ enters exponents additively).
pub(crate) fn stirling_delta(z: f64) -> f64 {
    if z >= 10.0 {
        const C: [f64; 8] = [
            1.0 / 12.0,
            -1.0 / 360.0,
            1.0 / 1260.0,
            -1.0 / 1680.0,
            1.0 / 1188.0,
            -691.0 / 360_360.0,
            1.0 / 156.0,
            -3617.0 / 122_400.0,
        ];
        let z2 = 1.0 / (z * z);
        let mut s = 0.0;
        for c in C.iter().rev() {
            s = s * z2 + c;
        }
        s / z
    } else {
        libm::lgamma(z) - ((z - 0.5) * libm::log(z) - z + LN_SQRT_2PI)
    }
}

/// `x^a y^b / B(a, b)` for `a, b > 0`, `x, y ∈ (0, 1)` with `x + y = 1` (both given to full
/// relative accuracy).
///
/// With `p = a/(a+b)`, `q = b/(a+b)` and Stirling's formula for `ln B(a, b)`:
/// `ln(x^a y^b / B) = −a·rlog1(x/p − 1) − b·rlog1(y/q − 1) + ½ ln(ab/(a+b)) − ln √(2π)
/// − (δ(a) + δ(b) − δ(a+b))`, where `x/p − 1 = (x b − y a)/a` and `y/q − 1 = −(x b − y a)/b`
/// (the linear terms cancel exactly: `a(x/p − 1) + b(y/q − 1) = 0`). Far below the mode
/// (`x/p − 1 < −½`) the power `x^a` itself is split off and taken with `pow`
/// (`−a·rlog1(e) = −a e + a ln(1 + b/a) + a ln x`), so that a large `|a ln x|` costs no
/// accuracy; the exponential of the rest then carries an error of `ε` times its (moderate)
/// argument.
pub(crate) fn power_terms(a: f64, b: f64, x: f64, y: f64) -> f64 {
    let d = x * b - y * a;
    let (e1, e2) = (d / a, -d / b);
    let mut ln = 0.5 * libm::log(a / (a + b) * b)
        - LN_SQRT_2PI
        - (stirling_delta(a) + stirling_delta(b) - stirling_delta(a + b));
    // The powers split off, as (base, exponent); (1, 0) when none.
    let mut pow_x = (1.0, 0.0);
    let mut pow_y = (1.0, 0.0);
    if e1 < -0.5 {
        ln -= a * (e1 - libm::log1p(b / a));
        pow_x = (x, a);
    } else {
        ln -= a * rlog1(e1);
    }
    if e2 < -0.5 {
        ln -= b * (e2 - libm::log1p(a / b));
        pow_y = (y, b);
    } else {
        ln -= b * rlog1(e2);
    }
    let v = libm::exp(ln) * libm::pow(pow_x.0, pow_x.1) * libm::pow(pow_y.0, pow_y.1);
    if v.is_finite() && v > 0.0 {
        v
    } else {
        // A factor over- or underflowed on its own: combine in logarithms.
        libm::exp(ln + pow_x.1 * libm::log(pow_x.0) + pow_y.1 * libm::log(pow_y.0))
    }
}

/// The continued fraction `F` with `I_x(a, b) = (x^a y^b / B(a, b)) / F`, evaluated by the
/// modified Lentz method; converges fast for `x < (a + 1)/(a + b + 2)`, where it is used.
///
/// `F = b₀ + a₁/(b₁ + a₂/(b₂ + …))` with `b₀ = a (a y − b x + 1)/(a + 1)` and, for `m ≥ 1`,
/// `a_m = (a+m−1)(a+b+m−1) m (b−m) x² / (a+2m−1)²`,
/// `b_m = m + m (b−m) x/(a+2m−1) + (a+m)(a y − b x + 1 + m (1 + y))/(a+2m+1)`
/// (Boost.Math `ibeta_fraction2`; `2 − x` is written `1 + y`).
pub(crate) fn ibeta_fraction(a: f64, b: f64, x: f64, y: f64) -> f64 {
    let lin = a * y - b * x + 1.0;
    let b0 = a * lin / (a + 1.0);
    lentz(b0, |m| {
        let den = a + 2.0 * m - 1.0;
        let am = ((a + m - 1.0) / den) * ((a + b + m - 1.0) / den) * m * (b - m) * x * x;
        let bm = m + m * (b - m) * x / den + (a + m) * (lin + m * (1.0 + y)) / (den + 2.0);
        (am, bm)
    })
}

/// `b₀ + a₁/(b₁ + a₂/(b₂ + …))` by the modified Lentz method (Press et al., *Numerical
/// Recipes*, §5.2), `terms(m)` giving `(a_m, b_m)` for `m = 1, 2, …`; stops when a step changes
/// the value by at most one ulp, or after [`MAX_TERMS`] terms.
pub(crate) fn lentz(b0: f64, mut terms: impl FnMut(f64) -> (f64, f64)) -> f64 {
    let mut f = if b0 == 0.0 { TINY } else { b0 };
    let (mut c, mut d) = (f, 0.0);
    for m in 1..=MAX_TERMS {
        let (am, bm) = terms(m as f64);
        d = bm + am * d;
        if libm::fabs(d) < TINY {
            d = TINY;
        }
        c = bm + am / c;
        if libm::fabs(c) < TINY {
            c = TINY;
        }
        d = 1.0 / d;
        let step = c * d;
        f *= step;
        if libm::fabs(step - 1.0) <= f64::EPSILON {
            break;
        }
    }
    f
}

/// The hypergeometric series `S = Σₙ (a+b)ₙ/(a+1)ₙ xⁿ` with
/// `I_x(a, b) = (x^a y^b / (a B(a, b))) S` (DLMF 8.17.8, `₂F₁(a+b, 1; a+1; x)`): all terms are
/// positive, and where it is used (`x (a + b + 2) ≤ a + 1`) they decrease from the first on.
pub(crate) fn ibeta_series(a: f64, b: f64, x: f64) -> f64 {
    let (mut sum, mut term) = (1.0, 1.0);
    for n in 0..MAX_TERMS {
        let n = n as f64;
        term *= (a + b + n) / (a + 1.0 + n) * x;
        sum += term;
        if term <= 0.25 * f64::EPSILON * sum {
            break;
        }
    }
    sum
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rlog1_matches_its_definition_where_that_is_accurate() {
        for e in [-0.9, -0.6, -0.5, -0.3, 0.3, 0.5, 0.7, 3.0, 1e6] {
            let direct = e - libm::log1p(e);
            assert!(libm::fabs(rlog1(e) - direct) <= 1e-15 * direct.max(1e-300) * 8.0, "e = {e}");
        }
        // Near 0: e − ln(1 + e) = Σ_{n≥2} (−e)ⁿ/n.
        for e in [1e-3, -1e-3, 1e-8, -1e-8] {
            let series: f64 = (2..12).map(|n| libm::pow(-e, n as f64) / n as f64).sum();
            assert!(libm::fabs(rlog1(e) / series - 1.0) < 1e-15, "e = {e}");
        }
    }

    #[test]
    fn stirling_delta_is_continuous_at_the_switch_and_exact_at_one_half() {
        // δ(½) = ½ − ½ ln 2 (Γ(½) = √π).
        let exact = 0.5 - 0.5 * core::f64::consts::LN_2;
        assert!(libm::fabs(stirling_delta(0.5) - exact) < 1e-15);
        // Both branches agree around z = 10.
        let z = 10.0;
        let via_lgamma = libm::lgamma(z) - ((z - 0.5) * libm::log(z) - z + LN_SQRT_2PI);
        assert!(libm::fabs(stirling_delta(z) - via_lgamma) < 5e-15);
        // δ(z) ≈ 1/(12 z) for large z.
        assert!(libm::fabs(stirling_delta(1e8) * 12e8 - 1.0) < 1e-15);
    }
}
