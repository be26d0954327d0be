//! The identifier of a curve, built from the figure table. Jobs drive it through
//! vehid-core's common [`Identifier`] interface.

use super::constants::{rows_constants, structure_constants, Car, Estimate};
use crate::figures::{Curve, GainKind, Ident};
use vehid_core::identify::TwoAxleIdentifier;
use vehid_core::identify::{
    Dims, Fixed, Gain, Identifier, KalmanIdentifier, KalmanOptions, LsAccumulator, StochasticGradient,
    StructuredKalmanVec,
};
use vehid_core::model::{LinearModel, PhysicalStructure, QuarterCar};

/// What a rejected sample (an update that would overflow) means for the figure.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum OnFailure {
    /// The estimate stays where it was (the Kalman identifier and least squares reject the
    /// sample transactionally); ξ reports that estimate.
    Hold,
    /// The identifier diverged (the stochastic gradient's step blew up): ξ is infinite.
    Diverged,
}

/// An identifier a job runs: vehid-core's [`Identifier`], and the map of its estimate to the
/// car's physical constants (see the `constants` module).
pub(super) trait JobIdentifier: Identifier<f64> + Send {
    /// Every constant of `car` (model order) as `[value, lo, hi]` of its 95 % interval, from
    /// the current estimate; by default through the identified rows of A.
    fn constants_into(&self, car: &Car, out: &mut [Estimate]) {
        rows_constants(self, car, out);
    }
}

impl<const N: usize, const K: usize> JobIdentifier for LsAccumulator<f64, N, Fixed<K>> {}
impl<const N: usize, const K: usize> JobIdentifier for KalmanIdentifier<f64, N, K> {}
impl<const N: usize, const K: usize> JobIdentifier for StochasticGradient<f64, N, K> {}
impl<const N: usize, const P: usize, const KB: usize, const C: usize> JobIdentifier
    for TwoAxleIdentifier<f64, N, P, KB, C>
{
}

/// The boxed identifier of a curve.
pub(super) type Boxed = Box<dyn JobIdentifier>;

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
        Ident::Physical => {
            if N != 4 || K != 2 {
                return Err(crate::Error::InvalidArgument { arg: "ident", expected: "the quarter car for Physical" });
            }
            // A and B fix only ratios of the constants: the known wheel mass is the thesis' 1 kg.
            (Box::new(PhysicalRows::new(QuarterCar::<f64>::thesis().m_wheel())?), OnFailure::Hold)
        }
        Ident::TwoAxle { .. } => {
            return Err(crate::Error::InvalidArgument {
                arg: "ident",
                expected: "a one-road model for the two-axle identifier",
            })
        }
    })
}

/// The quarter car identified in its physical structure (m known), read back as the rows
/// 1 and 3 of A for ξ: body `[k2/M, b/M, −k2/M, −b/M]`, wheel `[−(k1+k2)/m, −b/m, k2/m, b/m]`
/// with k2 = (k2/M)·M and b = (b/M)·M.
#[derive(Debug, Clone)]
struct PhysicalRows {
    inner: StructuredKalmanVec<f64, 2>,
    /// The structure, for the constants and their intervals.
    ph: PhysicalStructure<f64>,
    m: f64,
    /// Position of rows 1 and 3 among the structure's equations.
    eq_of_row: [usize; 2],
}

impl PhysicalRows {
    fn new(m: f64) -> crate::Result<Self> {
        let ph = QuarterCar::<f64>::structure([None, Some(m), None, None, None])?;
        if ph.param_names() != ["k2/M", "b/M", "M", "k1"] {
            return Err(crate::Error::InvalidArgument { arg: "ident", expected: "the parameters k2/M, b/M, M, k1" });
        }
        let s = *ph.structure();
        let opts = KalmanOptions::default();
        let inner = StructuredKalmanVec::<f64, 2>::exact(s, opts)?;
        let rows = inner.rows();
        let pos = |r: usize| rows.iter().position(|&x| x == r).unwrap_or(0);
        let eq_of_row = [pos(1), pos(3)];
        Ok(Self { inner, ph, m, eq_of_row })
    }
}

impl JobIdentifier for PhysicalRows {
    /// The constants straight from the structure's parameters (exact delta method), not
    /// through the rows of A they are read back as.
    fn constants_into(&self, _car: &Car, out: &mut [Estimate]) {
        structure_constants(&self.inner, &self.ph, out);
    }
}

/// Not saved: the reproduction runs each identifier once.
impl vehid_core::identify::Persist for PhysicalRows {}

impl Identifier<f64> for PhysicalRows {
    fn dims(&self) -> Dims {
        Dims { states: 4, inputs: 0, equations: 2, params: 8 }
    }

    fn rows(&self) -> &[usize] {
        &[1, 3]
    }

    fn update_into(&mut self, x: &[f64], z: &[f64], u: &[f64], e: &mut [f64]) -> vehid_core::Result<()> {
        let mut inner_e = [0.0; 2];
        self.inner.update_into(x, z, u, &mut inner_e)?;
        for (i, &j) in self.eq_of_row.iter().enumerate() {
            e[i] = inner_e[j];
        }
        Ok(())
    }

    fn params_into(&self, out: &mut [f64]) -> vehid_core::Result<()> {
        let mut p = [0.0; 4];
        self.inner.params_into(&mut p)?;
        let [k2_m, b_m, mb, k1] = p;
        let (k2, b, m) = (k2_m * mb, b_m * mb, self.m);
        out.copy_from_slice(&[-(k1 + k2) / m, -b / m, k2 / m, b / m, k2_m, b_m, -k2_m, -b_m]);
        Ok(())
    }

    fn samples(&self) -> u64 {
        self.inner.samples()
    }
}
