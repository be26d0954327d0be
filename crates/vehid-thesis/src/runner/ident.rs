//! The identifier of a curve, built from the figure table. Jobs drive it through
//! vehid-core's common [`Identifier`] interface.

use crate::figures::{Curve, GainKind, Ident};
use vehid_core::identify::{
    Fixed, Gain, Identifier, KalmanIdentifier, KalmanOptions, LsAccumulator, StochasticGradient,
};
use vehid_core::model::LinearModel;

/// What a rejected sample (an update that would overflow) means for the figure.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum OnFailure {
    /// The estimate stays where it was (the Kalman identifier and least squares reject the
    /// sample transactionally); ξ reports that estimate.
    Hold,
    /// The identifier diverged (the stochastic gradient's step blew up): ξ is infinite.
    Diverged,
}

/// The boxed identifier of a curve.
pub(super) type Boxed = Box<dyn Identifier<f64> + Send>;

pub(super) fn make_ident<const N: usize, const M: usize, const K: usize>(
    model: &LinearModel<f64, N, M>,
    curve: &Curve,
    road: &[f64; M],
) -> crate::Result<(Boxed, OnFailure)> {
    let rows: [usize; K] = model.unknown_rows().to_array()?;
    Ok(match curve.ident {
        Ident::BatchLs => (Box::new(LsAccumulator::<f64, N, Fixed<K>>::new(rows)?), OnFailure::Hold),
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
            (Box::new(KalmanIdentifier::<f64, N, K>::from_slices(&rows, &p0, &r, opts)?), OnFailure::Hold)
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
            (Box::new(StochasticGradient::<f64, N, K>::from_slices(&rows, g, &hs, &snv, 1)?), OnFailure::Diverged)
        }
        Ident::TwoAxle { .. } => {
            return Err(crate::Error::InvalidArgument {
                arg: "ident",
                expected: "a one-road model for the two-axle identifier",
            })
        }
    })
}
