//! Fig B-2's job: one seed of the half car on one road (sampled by distance, the rear wheel
//! meeting the front wheel's road one wheelbase later) with noisy states, every method that
//! applies on the same samples; per method ξ of the wheel rows, of the body rows, and the
//! worst entry.

use super::quarter::IV_LAGS;
use super::{HalfMethod, HALF_DERIV_SIGMA, ROAD_SIGMA};
use crate::figures::DT;
use vehid_core::identify::{
    BiasCompensatedLs, Identifier, IvIdentifier, StructuredPrior, TwoAxleConfig, TwoAxleIdentifier,
    TwoAxleStructuredConfig, TwoAxleStructuredKalman, WheelMethod,
};
use vehid_core::metrics::xi_rows;
use vehid_core::model::HalfCar;
use vehid_core::sim::{RoadConfig, RoadSimulator, SimConfig};

/// Road points per wheelbase (3 m at a sample every 0.3 m), as Fig 6-8 and 6-9.
pub(crate) const ROAD_DELAY: usize = 10;
/// Speed, m/s (0.3 m per 0.05 s).
pub(crate) const SPEED: f64 = 6.0;
/// The refined instruments' predictor capacity: 6 lags of the half car's 16 values, and the
/// constant.
const Q: usize = 97;
/// The unknown rows, in the order of the estimates below: front wheel, rear wheel, body
/// heave, pitch.
const ROWS: [usize; 4] = [1, 3, 5, 7];

/// One method's result on one seed.
#[derive(Debug, Clone)]
pub(crate) struct HalfXi {
    /// ξ of the wheel rows 1 and 3 (Eq 3.17 over their entries).
    pub(crate) wheel: f64,
    /// ξ of the body rows 5 and 7.
    pub(crate) body: f64,
    /// The largest relative error over the 28 non-zero entries.
    pub(crate) worst_entry: f64,
    /// Samples the identifier refused.
    pub(crate) refused: u32,
    /// Why there is no estimate (the identifier's error when read), if there is none.
    pub(crate) error: Option<String>,
}

/// The half car's physical structure with `m1`, `m2`, `l1`, `l2` known: 12 parameters.
fn physical() -> crate::Result<vehid_core::structure::Structure<f64>> {
    let c = HalfCar::<f64>::thesis().constants();
    let mut known = [None; 12];
    for (k, v) in known.iter_mut().zip(c).skip(8) {
        *k = Some(v);
    }
    Ok(*HalfCar::structure(known)?.structure())
}

type Physical = TwoAxleStructuredKalman<f64, 4, 3, 16>;

/// One identifier of the table, by how its estimate becomes rows 1, 3, 5, 7 of `A`.
enum HalfId {
    /// `params_into` gives the rows in [`ROWS`] order (row-major).
    Rows(Box<dyn Identifier<f64> + Send>),
    /// Road cancellation on the physical structure: its rows of `A` in its equations' order.
    Physical(Box<Physical>),
}

impl HalfId {
    fn ident(&mut self) -> &mut dyn Identifier<f64> {
        match self {
            HalfId::Rows(id) => id.as_mut(),
            HalfId::Physical(id) => id.as_mut(),
        }
    }

    /// The estimate as rows 1, 3, 5, 7 (row-major), or the identifier's error when read.
    fn rows(&self) -> Result<[f64; 32], String> {
        let mut out = [0.0; 32];
        match self {
            HalfId::Rows(id) => {
                let mut p = vec![0.0; id.dims().params];
                id.params_into(&mut p).map_err(|e| e.to_string())?;
                out.copy_from_slice(&p[..32]);
            }
            HalfId::Physical(id) => {
                let mut a = [0.0; 32];
                id.a_rows_into(&mut a).map_err(|e| e.to_string())?;
                for (i, &r) in id.rows().iter().enumerate() {
                    let at = ROWS.iter().position(|&x| x == r).ok_or("an equation outside rows 1, 3, 5, 7")?;
                    out[8 * at..8 * at + 8].copy_from_slice(&a[8 * i..8 * i + 8]);
                }
            }
        }
        Ok(out)
    }
}

fn make(method: HalfMethod, sigma_w: f64) -> crate::Result<HalfId> {
    let car = HalfCar::<f64>::thesis();
    let model = car.model();
    let rows_cfg = |m| TwoAxleConfig::new(m, 1000.0, ROAD_SIGMA, HALF_DERIV_SIGMA);
    let iv = |delay| -> crate::Result<HalfId> {
        Ok(HalfId::Rows(Box::new(
            IvIdentifier::<f64, 8, 4, Q>::full_rows(8, &ROWS, delay, StructuredPrior::Exact, &[1.0])?
                .with_lags(IV_LAGS)?,
        )))
    };
    type Rows = TwoAxleIdentifier<f64, 8, 16, 2, 16>;
    Ok(match method {
        HalfMethod::PlainRows => HalfId::Rows(Box::new(Rows::new(&model, ROAD_DELAY, rows_cfg(WheelMethod::None))?)),
        HalfMethod::CancelRows => HalfId::Rows(Box::new(Rows::new(&model, ROAD_DELAY, rows_cfg(WheelMethod::Cancel))?)),
        HalfMethod::CancelPhysical => {
            let cfg = TwoAxleStructuredConfig::new(ROAD_SIGMA, HALF_DERIV_SIGMA);
            HalfId::Physical(Box::new(Physical::new(physical()?, &model, ROAD_DELAY, cfg)?))
        }
        HalfMethod::IvRows => iv(1)?,
        HalfMethod::IvRowsPastWheelbase => iv(ROAD_DELAY + 1)?,
        HalfMethod::BclsRows => {
            HalfId::Rows(Box::new(BiasCompensatedLs::<f64, 8, 4>::full_rows(8, &ROWS, &[sigma_w * sigma_w])?))
        }
    })
}

/// ξ per pair of rows and the worst entry of an estimate (∞ without one).
fn score(est: Result<[f64; 32], String>, refused: u32) -> HalfXi {
    // The true rows 1, 3, 5, 7, row-major.
    let t = HalfCar::<f64>::thesis().theta().transpose();
    let t = t.as_slice();
    let e = match est {
        Ok(e) => e,
        Err(error) => {
            let inf = f64::INFINITY;
            return HalfXi { wheel: inf, body: inf, worst_entry: inf, refused, error: Some(error) };
        }
    };
    let mut per_row = [0.0; 4];
    if xi_rows(t, &e, 8, &mut per_row).is_err() {
        per_row = [f64::INFINITY; 4];
    }
    let worst_entry = t
        .iter()
        .zip(&e)
        .filter(|(t, _)| **t != 0.0)
        .map(|(t, e)| if e.is_finite() { ((e - t) / t).abs() } else { f64::INFINITY })
        .fold(0.0, f64::max);
    HalfXi { wheel: per_row[0] + per_row[1], body: per_row[2] + per_row[3], worst_entry, refused, error: None }
}

/// One realization: `n` samples of the half car on one white road (σ_u), a sample every
/// 0.3 m at 6 m/s, state noise `pct` % of σ_u on every state, derivative noise σ_v as Fig
/// 6-8; every method in [`HalfMethod::ALL`] on the same samples.
pub(crate) fn half_job(pct: f64, n: usize, seed: u64) -> crate::Result<Vec<HalfXi>> {
    let car = HalfCar::<f64>::thesis();
    let sigma_w = pct / 100.0 * ROAD_SIGMA;
    let cfg = SimConfig::<f64, 8, 2>::new(DT).road_sigma(ROAD_SIGMA).state_noise(sigma_w).deriv_noise(HALF_DERIV_SIGMA);
    let spacing = SPEED * DT;
    let road = RoadConfig::new(spacing, spacing * ROAD_DELAY as f64);
    let mut sim = RoadSimulator::<f64, 8, 16>::new(car.model(), cfg, road, seed)?;
    let mut ids = HalfMethod::ALL.iter().map(|&m| make(m, sigma_w)).collect::<crate::Result<Vec<_>>>()?;
    let mut refused = vec![0u32; ids.len()];
    let mut e = [0.0; 4];
    for _ in 0..n {
        let s = sim.next_sample(SPEED)?;
        for (id, f) in ids.iter_mut().zip(refused.iter_mut()) {
            if id.ident().update_into(s.r.as_slice(), s.z.as_slice(), &[], &mut e).is_err() {
                *f += 1;
            }
        }
    }
    Ok(ids.iter().zip(refused).map(|(id, f)| score(id.rows(), f)).collect())
}
