//! The adapter through which a job drives the identifiers: [`Step`], implemented for batch
//! least squares, the Kalman-filter identifier and the stochastic gradient.
//!
//! Kept private and in this one file on purpose: it is to be replaced by vehid-core's common
//! identifier trait once that exists.

use crate::figures::{Curve, GainKind, Ident};
use vehid_core::identify::{Fixed, Gain, KalmanIdentifier, KalmanOptions, LsAccumulator, StochasticGradient};
use vehid_core::model::LinearModel;
use vehid_core::nalgebra::SVector;

pub(super) trait Step<const N: usize> {
    fn step(&mut self, r: &SVector<f64, N>, z: &SVector<f64, N>);
    /// θ̂ row-major into `out`; `false` when not available yet (LS rank deficient).
    fn theta(&mut self, out: &mut [f64]) -> bool;
    fn reinits(&self) -> u32 {
        0
    }
}

struct Ls<const N: usize, const K: usize>(LsAccumulator<f64, N, Fixed<K>>);
impl<const N: usize, const K: usize> Step<N> for Ls<N, K> {
    fn step(&mut self, r: &SVector<f64, N>, z: &SVector<f64, N>) {
        let _ = self.0.push(r, z);
    }
    fn theta(&mut self, out: &mut [f64]) -> bool {
        self.0.solve_into(out).is_ok()
    }
}

struct Kf<const N: usize, const K: usize>(KalmanIdentifier<f64, N, K>, bool);
impl<const N: usize, const K: usize> Step<N> for Kf<N, K> {
    fn step(&mut self, r: &SVector<f64, N>, z: &SVector<f64, N>) {
        if !self.1 && self.0.update(r, z).is_err() {
            self.1 = true; // overflowed: θ̂ stays where it was, ξ reports it
        }
    }
    fn theta(&mut self, out: &mut [f64]) -> bool {
        self.0.theta_into(out).is_ok()
    }
    fn reinits(&self) -> u32 {
        self.0.reinit_count()
    }
}

struct Sg<const N: usize, const K: usize>(StochasticGradient<f64, N, K>, bool);
impl<const N: usize, const K: usize> Step<N> for Sg<N, K> {
    fn step(&mut self, r: &SVector<f64, N>, z: &SVector<f64, N>) {
        if !self.1 && self.0.update(r, z).is_err() {
            self.1 = true;
        }
    }
    fn theta(&mut self, out: &mut [f64]) -> bool {
        if self.1 {
            out.iter_mut().for_each(|v| *v = f64::INFINITY);
            return true;
        }
        self.0.theta_into(out).is_ok()
    }
}

pub(super) fn make_ident<const N: usize, const M: usize, const K: usize>(
    model: &LinearModel<f64, N, M>,
    curve: &Curve,
    road: &[f64; M],
) -> crate::Result<Box<dyn Step<N> + Send>> {
    let rows: [usize; K] = model.unknown_rows().to_array()?;
    Ok(match curve.ident {
        Ident::BatchLs => Box::new(Ls::<N, K>(LsAccumulator::new(rows)?)),
        Ident::Kalman { p0_wheel, p0_body, r_scale, reinit } => {
            let mut r = [0.0; K];
            model.row_noise_var_into(road, &[curve.deriv], &mut r)?;
            // A row with no noise at all (e.g. σ_v = 0) still needs r > 0 for a well-posed gain.
            let r: [f64; K] = r.map(|v| (v * r_scale).max(1e-12));
            // Wheel rows are those the road enters (B non-zero); the others are body rows.
            let p0: [f64; K] = core::array::from_fn(|i| {
                let row = rows[i];
                if (0..M).any(|j| model.b()[(row, j)] != 0.0) || N == 4 {
                    p0_wheel
                } else {
                    p0_body
                }
            });
            let opts = KalmanOptions { reinit, ..Default::default() };
            Box::new(Kf::<N, K>(KalmanIdentifier::from_slices(&rows, &p0, &r, opts)?, false))
        }
        Ident::Gradient { gain, h } => {
            let g = match gain {
                GainKind::Venter(p) => Gain::Venter { p },
                GainKind::Lyapunov => Gain::Lyapunov,
                GainKind::Ljung => Gain::Ljung { lambda0: 0.99, lambda_init: 0.95 },
            };
            let hs: [f64; K] = core::array::from_fn(|i| {
                let row = rows[i];
                if (0..M).any(|j| model.b()[(row, j)] != 0.0) {
                    h / 10.0
                } else {
                    h
                }
            });
            let snv = [curve.state * curve.state];
            Box::new(Sg::<N, K>(StochasticGradient::from_slices(&rows, g, &hs, &snv, 1)?, false))
        }
        Ident::TwoAxle { .. } => {
            return Err(crate::Error::InvalidArgument {
                arg: "ident",
                expected: "a one-road model for the two-axle identifier",
            })
        }
    })
}
