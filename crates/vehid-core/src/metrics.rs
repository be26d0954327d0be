//! Error measures of the thesis: the normalized parameter error ξ (Eq 3.17, 6.10) and the
//! sensor signal-to-noise ratio (Eq 4.31–4.32).

use crate::error::check_finite;
use crate::{Error, Real, Result};

/// The parameter error measure ξ of Eq 3.17 / 6.10:
/// `ξ = Σ_i ((θ_i − θ̂_i) / θ_i)²` over the entries whose true value is non-zero
/// (structurally zero parameters cannot be normalized and are left out, Eq 6.10).
///
/// Both slices hold the unknown rows row-major. Acceptable identification (every parameter
/// within 10 %) requires `ξ ≤ 0.08` for the 4-state model (Eq 3.18).
///
/// # Errors
/// [`Error::Shape`] when the lengths differ; [`Error::NonFinite`] for NaN/inf in the true
/// values. A non-finite *estimate* is not an error: ξ is then `+∞`, which is what a diverged
/// identifier deserves.
///
/// # Examples
/// ```
/// let xi = vehid_core::metrics::xi(&[2.0_f64, 0.0, -4.0], &[2.2, 5.0, -4.0]).unwrap();
/// assert!((xi - 0.01).abs() < 1e-12); // only the non-zero entries count
/// ```
pub fn xi<T: Real>(theta: &[T], theta_hat: &[T]) -> Result<T> {
    if theta.len() != theta_hat.len() {
        return Err(Error::Shape { arg: "theta_hat", expected: theta.len(), got: theta_hat.len() });
    }
    check_finite("theta", theta)?;
    let mut s = T::zero();
    for (t, h) in theta.iter().zip(theta_hat) {
        if *t != T::zero() {
            if !h.finite() {
                return Ok(T::of(f64::INFINITY));
            }
            let e = (*t - *h) / *t;
            s += e * e;
        }
    }
    Ok(s)
}

/// The per-row share of ξ: the terms of Eq 3.17 summed over each unknown row separately
/// (`theta` and `theta_hat` are `k × n` row-major; `out` has `k` entries). Used to say which
/// row is converged (Fig 4-2: the body row long before the wheel row).
///
/// # Errors
/// As [`xi`], plus [`Error::Shape`] when `out.len() * n` is not the slice length.
pub fn xi_rows<T: Real>(theta: &[T], theta_hat: &[T], n: usize, out: &mut [T]) -> Result<()> {
    if n == 0 || out.len() * n != theta.len() {
        return Err(Error::Shape { arg: "theta", expected: out.len() * n, got: theta.len() });
    }
    for (i, o) in out.iter_mut().enumerate() {
        *o = xi(
            &theta[i * n..(i + 1) * n],
            theta_hat.get(i * n..(i + 1) * n).ok_or(Error::Shape {
                arg: "theta_hat",
                expected: theta.len(),
                got: theta_hat.len(),
            })?,
        )?;
    }
    Ok(())
}

/// Sensor signal-to-noise ratio in dB (Eq 4.31–4.32): `η = 20 log₁₀(σ_signal / σ_noise)`.
///
/// # Errors
/// [`Error::InvalidArgument`] when either standard deviation is not finite and > 0.
pub fn snr_db<T: Real>(signal_std: T, noise_std: T) -> Result<T> {
    crate::error::check_positive("signal_std", signal_std)?;
    crate::error::check_positive("noise_std", noise_std)?;
    Ok(T::of(20.0 * libm::log10((signal_std / noise_std).to_f64())))
}

/// How well a simulation `simulated` reproduces measurements `measured` (both `samples × n`,
/// row-major), per column `j`: the root-mean-square error `rmse_j = √(mean (x − x̂)²)` and the
/// fit percentage `fit_j = 100 (1 − ‖x − x̂‖ / ‖x − mean(x)‖)` (the normalized-RMSE fit of
/// Ljung's *System Identification*, 2nd ed., §16.6, and MATLAB's `compare`): 100 for a perfect
/// simulation, 0 for one no better than the measured mean, negative when worse.
///
/// # Errors
/// [`Error::Shape`] for lengths that disagree (or `n = 0`); [`Error::NonFinite`] naming
/// `measured` or `simulated`. A constant measured column gives `fit = -inf` (or NaN when the
/// simulation matches it exactly).
pub fn simulation_fit<T: Real>(measured: &[T], simulated: &[T], n: usize, fit: &mut [T], rmse: &mut [T]) -> Result<()> {
    if n == 0 || measured.len() % n != 0 {
        return Err(Error::Shape { arg: "measured", expected: n, got: measured.len() });
    }
    if simulated.len() != measured.len() {
        return Err(Error::Shape { arg: "simulated", expected: measured.len(), got: simulated.len() });
    }
    if fit.len() != n || rmse.len() != n {
        return Err(Error::Shape { arg: "fit", expected: n, got: fit.len().min(rmse.len()) });
    }
    check_finite("measured", measured)?;
    check_finite("simulated", simulated)?;
    let samples = measured.len() / n;
    if samples == 0 {
        return Err(Error::Shape { arg: "measured", expected: n, got: 0 });
    }
    for j in 0..n {
        let mean = measured.iter().skip(j).step_by(n).fold(0.0, |a, v| a + v.to_f64()) / samples as f64;
        let (mut err, mut dev) = (0.0f64, 0.0f64);
        for k in 0..samples {
            let (x, s) = (measured[k * n + j].to_f64(), simulated[k * n + j].to_f64());
            err += (x - s) * (x - s);
            dev += (x - mean) * (x - mean);
        }
        rmse[j] = T::of(libm::sqrt(err / samples as f64));
        fit[j] = T::of(100.0 * (1.0 - libm::sqrt(err / dev)));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn xi_by_hand() {
        // ((1-1.1)/1)^2 + ((-2+1.8)/-2)^2 = 0.01 + 0.01
        let v = xi(&[1.0_f64, -2.0], &[1.1, -1.8]).unwrap();
        assert!((v - 0.02).abs() < 1e-12);
        assert_eq!(xi(&[1.0_f64], &[f64::NAN]).unwrap(), f64::INFINITY);
        assert!(xi(&[1.0_f64], &[1.0, 2.0]).is_err());
        assert!(xi(&[f64::NAN], &[1.0]).is_err());
        let mut rows = [0.0; 2];
        xi_rows(&[1.0_f64, 2.0, 4.0, 8.0], &[1.0, 2.0, 4.4, 8.0], 2, &mut rows).unwrap();
        assert!(rows[0] == 0.0 && (rows[1] - 0.01).abs() < 1e-12);
    }

    #[test]
    fn snr_by_hand() {
        assert!((snr_db(10.0_f64, 1.0).unwrap() - 20.0).abs() < 1e-12);
        assert!(snr_db(1.0_f64, 0.0).is_err());
    }
}
