//! Recursive residuals of a linear regression (Brown, Durbin & Evans 1975; statsmodels
//! `RecursiveLS(...).fit().resid_recursive`), which the CUSUM tests ([`super::Cusum`]) read.
//!
//! For `y_t = h_tᵀ θ + ε_t` (`p` parameters), least squares on the first `t` samples gives
//! `θ_t`; the recursive residual of sample `t + 1` is its one-step forecast error, scaled to the
//! noise's variance:
//!
//! ```text
//! w_{t+1} = (y_{t+1} − h_{t+1}ᵀ θ_t) / √(1 + h_{t+1}ᵀ (H_tᵀ H_t)⁻¹ h_{t+1}),   t ≥ p
//! ```
//!
//! Under the model (white Gaussian `ε`, constant `θ`) the `w` are independent `N(0, σ²)`; a
//! parameter that changes, or an input the model leaves out, shows as a drift of their
//! cumulative sum. Started exactly from the first `m ≥ p` samples that determine the
//! parameters (`θ_m` their least squares, `P_m = (H_mᵀ H_m)⁻¹`), then the recursive least-squares update `f = 1 + hᵀ P h`, `w = (y − hᵀ θ)/√f`,
//! `θ ← θ + P h (y − hᵀ θ)/f`, `P ← P − P h hᵀ P / f` (in `f64`).

use crate::{Error, Result};
use alloc::vec;
use alloc::vec::Vec;

/// The recursive residuals of the regression of `y` (`n` values) on the rows of `h` (`n × p`,
/// row-major), for samples `m..n` (module documentation): `m` is the first count of samples
/// whose rows determine the parameters (`p` when the first `p` rows are independent; more when
/// the record begins without excitation, e.g. at rest).
///
/// # Errors
/// [`Error::Shape`] when `h` is not `n` rows; [`Error::InvalidArgument`] naming `y` for
/// `n ≤ p` or no sample left after the first `m`; [`Error::NonFinite`];
/// [`Error::RankDeficient`] when no prefix of the rows determines the parameters;
/// [`Error::OutOfMemory`].
pub fn recursive_residuals(h: &[f64], y: &[f64], p: usize) -> Result<Vec<f64>> {
    let n = y.len();
    if p == 0 || h.len() != n * p {
        return Err(Error::Shape { arg: "h", expected: n.saturating_mul(p.max(1)), got: h.len() });
    }
    if n <= p {
        return Err(Error::InvalidArgument { arg: "y", expected: "more samples than parameters" });
    }
    crate::error::check_finite("h", h)?;
    crate::error::check_finite("y", y)?;
    let mut out = Vec::new();
    out.try_reserve(n - p).map_err(|_| Error::OutOfMemory { what: "the recursive residuals", bytes: 8 * (n - p) })?;
    // Exact start on the first m rows that determine the parameters (m = p unless the record
    // begins without excitation, e.g. at rest): θ_m, P_m = (H_mᵀ H_m)⁻¹ by Cholesky.
    let (mut a, mut c) = (nalgebra::DMatrix::<f64>::zeros(p, p), nalgebra::DVector::<f64>::zeros(p));
    let mut m = 0;
    let (mut theta, mut pm) = loop {
        if m == n {
            let rank = a.clone().svd(false, false).singular_values.iter().filter(|&&s| s > 1e-10 * a.amax()).count();
            return Err(Error::RankDeficient { rank, needed: p });
        }
        let row = nalgebra::DVector::from_column_slice(&h[m * p..(m + 1) * p]);
        a += &row * row.transpose();
        c += &row * y[m];
        m += 1;
        if m < p {
            continue;
        }
        let scale = (0..p).map(|i| a[(i, i)]).fold(0.0, f64::max);
        if let Some(ch) = nalgebra::linalg::Cholesky::new(a.clone()) {
            if (0..p).all(|i| ch.l()[(i, i)] * ch.l()[(i, i)] > 1e-10 * scale) {
                break (ch.solve(&c), ch.inverse());
            }
        }
    };
    if m == n {
        return Err(Error::InvalidArgument {
            arg: "y",
            expected: "more samples than the first ones that determine the parameters",
        });
    }
    let mut ph = vec![0.0; p];
    for (row, &yt) in h.chunks_exact(p).zip(y).skip(m) {
        for (i, v) in ph.iter_mut().enumerate() {
            *v = (0..p).map(|j| pm[(i, j)] * row[j]).sum();
        }
        let f = 1.0 + row.iter().zip(&ph).map(|(a, b)| a * b).sum::<f64>();
        let e = yt - row.iter().zip(theta.iter()).map(|(a, b)| a * b).sum::<f64>();
        out.push(e / libm::sqrt(f));
        for i in 0..p {
            theta[i] += ph[i] * e / f;
            for j in 0..p {
                pm[(i, j)] -= ph[i] * ph[j] / f;
            }
        }
    }
    Ok(out)
}
