//! The stochastic-gradient identifier (Eq 2.56, 5.2–5.18) on a [`Structure`]: every
//! identified equation `i` gives a regression `y_i = h_iᵀ θ + v_i` over all parameters, and
//!
//! `θ ← θ + γ(k) w ∘ Σ_i h_i e_i`,  `e_i = y_i − h_iᵀ θ`,
//!
//! with `w` the per-parameter weights and `γ(k)` one of the thesis' gain sequences
//! ([`Gain`]: Venter's `k^(−p)`, the normalized `1 / Σ_j w_j Σ_i h_ij²`, Ljung's with
//! forgetting). For a structure with every entry of a row a parameter this is
//! [`super::StochasticGradient`] without the state-noise correction. No allocation; the
//! parameter count is at most the const generic `P`.

use super::checks::check_slices;
use super::{Dims, Gain, Identifier, OVERFLOW};
use crate::structure::{Structure, MAX_EQUATIONS};
use crate::{Error, Real, Result};

/// Stochastic gradient on a structure of at most `P` parameters (module docs).
#[derive(Debug, Clone)]
#[cfg_attr(
    feature = "serde",
    derive(serde::Serialize, serde::Deserialize),
    serde(remote = "Self", bound(serialize = "T: serde::Serialize", deserialize = "T: crate::Real"))
)]
pub struct StructuredGradient<T: Real, const P: usize> {
    structure: Structure<T>,
    rows: [usize; MAX_EQUATIONS],
    #[cfg_attr(feature = "serde", serde(with = "crate::persist::array"))]
    theta: [T; P],
    #[cfg_attr(feature = "serde", serde(with = "crate::persist::array"))]
    w: [T; P],
    gain: Gain<T>,
    spacing: u32,
    phase: u32,
    k: u64,
    gamma: T,
    lambda: T,
    samples: u64,
}

impl<T: Real, const P: usize> StructuredGradient<T, P> {
    /// Checks a deserialized identifier (feature `serde`; its structure checked itself): at
    /// most `P` parameters, the equations' states, the sample spacing and phase, the gain.
    #[cfg(feature = "serde")]
    pub(crate) fn restored(&mut self) -> Result<()> {
        let corrupt =
            Error::InvalidArgument { arg: "state", expected: "a structured gradient identifier's saved state" };
        let ne = self.structure.equations();
        if self.structure.params() > P
            || self.spacing == 0
            || self.phase >= self.spacing
            || self.structure.equation_states().enumerate().any(|(i, s)| self.rows[i] != s)
            || self.rows[ne..].iter().any(|&r| r != 0)
        {
            return Err(corrupt);
        }
        self.gain.validate()
    }

    /// The identifier of `structure`'s parameters from `theta0` (`None`: 0) with weights `w`
    /// (one value, or one per parameter), gain `gain`, using every `spacing`-th sample.
    ///
    /// # Errors
    /// [`Error::NotIdentifiable`] for an unused or confounded parameter; [`Error::Capacity`]
    /// for more than `P` parameters; [`Error::InvalidArgument`] for `w ≤ 0`, `spacing = 0` or
    /// bad gain constants; [`Error::Shape`] / [`Error::NonFinite`] naming `w` or `theta0`.
    pub fn new(structure: Structure<T>, gain: Gain<T>, w: &[T], theta0: Option<&[T]>, spacing: u32) -> Result<Self> {
        structure.check_identifiable()?;
        gain.validate()?;
        let np = structure.params();
        if np > P {
            return Err(Error::Capacity { arg: "P", needed: np, capacity: P });
        }
        if spacing == 0 {
            return Err(Error::InvalidArgument { arg: "spacing", expected: "at least 1 sample" });
        }
        crate::error::check_finite("w", w)?;
        let mut wb = [T::zero(); P];
        for (j, o) in wb[..np].iter_mut().enumerate() {
            *o = match w.len() {
                1 => w[0],
                l if l == np => w[j],
                l => return Err(Error::Shape { arg: "h", expected: np, got: l }),
            };
            crate::error::check_positive("h", *o)?;
        }
        let mut theta = [T::zero(); P];
        if let Some(t) = theta0 {
            if t.len() != np {
                return Err(Error::Shape { arg: "theta0", expected: np, got: t.len() });
            }
            crate::error::check_finite("theta0", t)?;
            theta[..np].copy_from_slice(t);
        }
        let mut rows = [0; MAX_EQUATIONS];
        for (i, s) in structure.equation_states().enumerate() {
            rows[i] = s;
        }
        let lambda = match gain {
            Gain::Ljung { lambda_init, .. } => lambda_init,
            _ => T::one(),
        };
        Ok(Self { structure, rows, theta, w: wb, gain, spacing, phase: 0, k: 0, gamma: T::one(), lambda, samples: 0 })
    }

    /// The structure.
    pub fn structure(&self) -> &Structure<T> {
        &self.structure
    }

    /// The gain sequence.
    pub fn gain(&self) -> Gain<T> {
        self.gain
    }

    /// Gradient steps taken (`k` of Eq 5.8).
    pub fn steps(&self) -> u64 {
        self.k
    }
}

super::persist_by_serde!([T: Real, const P: usize] StructuredGradient<T, P>);

impl<T: Real, const P: usize> Identifier<T> for StructuredGradient<T, P> {
    fn dims(&self) -> Dims {
        super::buffers::structure_dims(&self.structure)
    }

    fn rows(&self) -> &[usize] {
        &self.rows[..self.structure.equations()]
    }

    fn update_into(&mut self, x: &[T], z: &[T], u: &[T], e: &mut [T]) -> Result<()> {
        check_slices(self.dims(), x, z, u, e)?;
        let (ne, np) = (self.structure.equations(), self.structure.params());
        let mut grad = [T::zero(); P];
        // Σ_j w_j Σ_i h_ij², the normalized gain's denominator (Eq 5.9), only for that gain.
        let lyapunov = matches!(self.gain, Gain::Lyapunov);
        let mut h2 = T::zero();
        let mut h = [T::zero(); P];
        for i in 0..ne {
            let y = self.structure.regression(i, x, z, u, &mut h[..np]);
            let pred = h[..np].iter().zip(&self.theta[..np]).fold(T::zero(), |a, (&hj, &tj)| a + hj * tj);
            let ei = y - pred;
            if !ei.finite() {
                return Err(OVERFLOW);
            }
            e[i] = ei;
            for j in 0..np {
                grad[j] += h[j] * ei;
            }
            if lyapunov {
                for j in 0..np {
                    h2 += self.w[j] * h[j] * h[j];
                }
            }
        }
        let active = self.phase == 0;
        let next_phase = if self.phase + 1 >= self.spacing { 0 } else { self.phase + 1 };
        if !active {
            self.phase = next_phase;
            self.samples += 1;
            return Ok(());
        }
        let step = self.k + 1;
        let Some((gamma, lambda)) = self.gain.next(step, self.gamma, self.lambda, || h2) else {
            // The normalized gain with zero regressors: no direction to move in.
            self.phase = next_phase;
            self.samples += 1;
            return Ok(());
        };
        let mut new = self.theta;
        for j in 0..np {
            new[j] += gamma * self.w[j] * grad[j];
            if !new[j].finite() {
                return Err(OVERFLOW);
            }
        }
        self.theta = new;
        self.gamma = gamma;
        self.lambda = lambda;
        self.k = step;
        self.phase = next_phase;
        self.samples += 1;
        Ok(())
    }

    fn params_into(&self, out: &mut [T]) -> Result<()> {
        let np = self.structure.params();
        if out.len() != np {
            return Err(Error::Shape { arg: "out", expected: np, got: out.len() });
        }
        out.copy_from_slice(&self.theta[..np]);
        Ok(())
    }

    fn samples(&self) -> u64 {
        self.samples
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::identify::StochasticGradient;

    /// On a full-row structure the structured gradient takes the plain one's steps.
    #[test]
    fn full_rows_equal_the_plain_stochastic_gradient() {
        let s = Structure::<f64>::full_rows(3, &[1]).unwrap();
        for gain in [Gain::Venter { p: 0.6 }, Gain::Lyapunov, Gain::Ljung { lambda0: 0.99, lambda_init: 0.95 }] {
            let mut a = StructuredGradient::<f64, 4>::new(s, gain, &[0.3], None, 2).unwrap();
            let mut b = StochasticGradient::<f64, 3, 1>::from_slices(&[1], gain, &[0.3], &[0.0], 2).unwrap();
            let mut seed = 7u64;
            let mut rnd = || {
                seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
                (seed >> 11) as f64 / (1u64 << 53) as f64 - 0.5
            };
            for _ in 0..500 {
                let x = [rnd(), rnd(), rnd()];
                let z = [0.0, 2.0 * x[0] - x[1] + 0.5 * x[2] + 0.01 * rnd(), 0.0];
                let mut e = [0.0];
                a.update_into(&x, &z, &[], &mut e).unwrap();
                let mut f = [0.0];
                b.update_into(&x, &z, &[], &mut f).unwrap();
                assert!((e[0] - f[0]).abs() <= 1e-9 * f[0].abs().max(1e-3), "{gain:?}: {e:?} vs {f:?}");
            }
            let (mut pa, mut pb) = ([0.0; 3], [0.0; 3]);
            a.params_into(&mut pa).unwrap();
            b.params_into(&mut pb).unwrap();
            for j in 0..3 {
                assert!((pa[j] - pb[j]).abs() <= 1e-12 * pb[j].abs().max(1.0), "{gain:?}: {pa:?} vs {pb:?}");
            }
        }
    }

    /// A rejected sample (NaN) changes nothing.
    #[test]
    fn rejected_samples_change_nothing() {
        let s = Structure::<f64>::full_rows(2, &[0]).unwrap();
        let mut a = StructuredGradient::<f64, 2>::new(s, Gain::Venter { p: 0.51 }, &[1.0], None, 1).unwrap();
        a.update_into(&[1.0, 0.5], &[0.3, 0.0], &[], &mut [0.0]).unwrap();
        let before = (a.theta, a.k, a.samples, a.gamma);
        assert!(a.update_into(&[f64::NAN, 0.5], &[0.3, 0.0], &[], &mut [0.0]).is_err());
        assert!(a.update_into(&[1e300, 1e300], &[1e300, 0.0], &[], &mut [0.0]).is_err());
        assert_eq!(before, (a.theta, a.k, a.samples, a.gamma));
    }
}
