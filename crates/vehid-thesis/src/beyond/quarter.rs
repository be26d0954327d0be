//! Fig B-1's job: one seed of the quarter car at one state-noise level, every method on the
//! same samples, ξ (Eq 3.17) of each after the run.

use super::{QuarterMethod, DERIV_SIGMA, EKF_MIN_STATE_SIGMA, ROAD_SIGMA};
use crate::figures::DT;
use vehid_core::identify::{
    BiasCompensatedLs, EkfNoise, Identifier, IvIdentifier, JointEkf, KalmanIdentifier, StructuredPrior,
};
use vehid_core::metrics::xi;
use vehid_core::model::QuarterCar;
use vehid_core::nalgebra::SVector;
use vehid_core::sim::{SimConfig, Simulator};
use vehid_core::structure::{Basis, Structure, Term, Var};

/// Lags of the refined instruments (the Python default for the quarter car).
pub(crate) const IV_LAGS: usize = 6;
/// The refined instruments' predictor capacity: 6 lags of the quarter car's 8 values, and
/// the constant.
const Q: usize = 49;

/// The quarter car's physical structure with the wheel mass known: `k2/M, b/M, M, k1`.
fn physical() -> crate::Result<Structure<f64>> {
    let m = QuarterCar::<f64>::thesis().m_wheel();
    Ok(*QuarterCar::structure([None, Some(m), None, None, None])?.structure())
}

/// The thesis' full rows 1 and 3 with the kinematic rows `ż = v` as known equations (the
/// joint EKF predicts every state).
fn full_rows_complete() -> crate::Result<Structure<f64>> {
    let mut s = Structure::<f64>::full_rows(4, &[1, 3])?;
    for (row, from) in [(0, 1u8), (2, 3)] {
        s.push_equation(row, &[Term { coef: 1.0, param: None, basis: Basis::Var(Var::State(from)) }])?;
    }
    Ok(s)
}

/// The rows 1 and 3 of `A` implied by parameters `p` of `s` (its derivative on unit vectors).
fn implied_rows(s: &Structure<f64>, p: &[f64]) -> [f64; 8] {
    let mut rows = [0.0; 8];
    for j in 0..4 {
        let mut e = [0.0; 4];
        e[j] = 1.0;
        let mut col = [0.0; 4];
        s.derivative(p, &e, &[], &mut col);
        rows[j] = col[1];
        rows[4 + j] = col[3];
    }
    rows
}

/// The joint EKF's rough prior (as `tests/joint_ekf.rs`): each parameter at half or 1.5
/// times its true value (alternately), standard deviation 100 % of the guess.
pub(crate) fn rough_prior(truth: &[f64]) -> (Vec<f64>, Vec<f64>) {
    let g: Vec<f64> = truth.iter().enumerate().map(|(j, t)| t * if j % 2 == 0 { 0.5 } else { 1.5 }).collect();
    let v = g.iter().map(|g| g * g).collect();
    (g, v)
}

/// True physical parameters `k2/M, b/M, M, k1` of the thesis' quarter car.
fn physical_truth() -> [f64; 4] {
    let [mb, _m, k1, k2, b] = QuarterCar::<f64>::thesis().constants();
    [k2 / mb, b / mb, mb, k1]
}

/// One method's result on one realization.
#[derive(Debug, Clone)]
pub(crate) struct QuarterXi {
    /// ξ after the run (∞ without an estimate).
    pub(crate) xi: f64,
    /// Samples the identifier refused.
    pub(crate) refused: u32,
    /// Why there is no estimate, if there is none.
    pub(crate) error: Option<String>,
}

/// One identifier of the sweep, and how its estimate becomes rows 1 and 3 of `A`.
enum Runner {
    /// Its parameters are the rows (row-major).
    Rows(Box<dyn Identifier<f64> + Send>),
    /// Its parameters are a structure's: the rows are the structure's derivative.
    Structure(Box<dyn Identifier<f64> + Send>, Box<Structure<f64>>),
}

impl Runner {
    fn ident(&mut self) -> &mut (dyn Identifier<f64> + Send) {
        match self {
            Runner::Rows(id) | Runner::Structure(id, _) => id.as_mut(),
        }
    }

    /// ξ of the estimate, or the identifier's error when read (no estimate).
    fn xi(&self, truth: &[f64]) -> Result<f64, String> {
        let (id, s) = match self {
            Runner::Rows(id) => (id, None),
            Runner::Structure(id, s) => (id, Some(s.as_ref())),
        };
        let mut p = vec![0.0; id.dims().params];
        id.params_into(&mut p).map_err(|e| e.to_string())?;
        let rows = match s {
            Some(s) => implied_rows(s, &p).to_vec(),
            None => p,
        };
        xi(truth, &rows).map_err(|e| e.to_string())
    }
}

fn make(method: QuarterMethod, sigma_w: f64, substeps: u32) -> crate::Result<Runner> {
    let car = QuarterCar::<f64>::thesis();
    let model = car.model();
    let var = sigma_w * sigma_w;
    Ok(match method {
        QuarterMethod::KalmanRows => {
            let r = model.row_noise_var::<2>(ROAD_SIGMA, DERIV_SIGMA)?;
            Runner::Rows(Box::new(KalmanIdentifier::<f64, 4, 2>::new([1, 3], 1000.0, r)?))
        }
        QuarterMethod::IvRows => Runner::Rows(Box::new(
            IvIdentifier::<f64, 4, 2, Q>::full_rows(4, &[1, 3], 1, StructuredPrior::Exact, &[1.0])?
                .with_lags(IV_LAGS)?,
        )),
        QuarterMethod::IvPhysical => {
            let s = physical()?;
            Runner::Structure(Box::new(IvIdentifier::<f64, 2, 2, Q>::exact(s, 1)?.with_lags(IV_LAGS)?), Box::new(s))
        }
        QuarterMethod::BclsRows => {
            Runner::Rows(Box::new(BiasCompensatedLs::<f64, 4, 2>::full_rows(4, &[1, 3], &[var])?))
        }
        QuarterMethod::BclsPhysical => {
            let s = physical()?;
            let id = BiasCompensatedLs::<f64, 2, 2>::new(s, &[var], &[DERIV_SIGMA * DERIV_SIGMA], &[1.0])?;
            Runner::Structure(Box::new(id), Box::new(s))
        }
        QuarterMethod::EkfRows | QuarterMethod::EkfPhysical => {
            let g = SVector::<f64, 4>::from_column_slice(model.b().as_slice());
            let noise = EkfNoise::from_sigmas(sigma_w.max(EKF_MIN_STATE_SIGMA), DERIV_SIGMA, g, ROAD_SIGMA);
            if method == QuarterMethod::EkfRows {
                let s = full_rows_complete()?;
                let (p0, v0) = rough_prior(car.theta().transpose().as_slice());
                Runner::Structure(
                    Box::new(JointEkf::<f64, 4, 13>::new(s, &p0, &v0, 1.0, noise, DT, substeps)?),
                    Box::new(s),
                )
            } else {
                let s = physical()?;
                let (p0, v0) = rough_prior(&physical_truth());
                Runner::Structure(
                    Box::new(JointEkf::<f64, 4, 9>::new(s, &p0, &v0, 1.0, noise, DT, substeps)?),
                    Box::new(s),
                )
            }
        }
    })
}

/// One realization: `n` samples of the quarter car (white road σ_u, derivative noise σ_v,
/// state noise `pct` % of σ_u, no initial disturbance), every method in
/// [`QuarterMethod::ALL`] on the same samples; per method ξ after the last sample (∞ for a
/// method without an estimate, with the identifier's error) and the samples it refused (an
/// identifier refuses a sample transactionally, e.g. a singular IV step or an EKF covariance
/// that lost definiteness, and goes on with the next).
pub(crate) fn sweep_job(pct: f64, n: usize, seed: u64) -> crate::Result<Vec<QuarterXi>> {
    let car = QuarterCar::<f64>::thesis();
    let sigma_w = pct / 100.0 * ROAD_SIGMA;
    let cfg = SimConfig::new(DT).road_sigma(ROAD_SIGMA).deriv_noise(DERIV_SIGMA).state_noise(sigma_w);
    let mut sim = Simulator::new(car.model(), cfg, seed)?;
    let substeps = sim.substeps() as u32;
    let mut runners =
        QuarterMethod::ALL.iter().map(|&m| make(m, sigma_w, substeps)).collect::<crate::Result<Vec<_>>>()?;
    let mut refused = vec![0u32; runners.len()];
    let mut e = [0.0; 2];
    for _ in 0..n {
        let s = sim.next_sample();
        for (r, f) in runners.iter_mut().zip(refused.iter_mut()) {
            if r.ident().update_into(s.r.as_slice(), s.z.as_slice(), &[], &mut e).is_err() {
                *f += 1;
            }
        }
    }
    let truth = car.theta().transpose();
    Ok(runners
        .iter()
        .zip(refused)
        .map(|(r, refused)| match r.xi(truth.as_slice()) {
            Ok(xi) => QuarterXi { xi, refused, error: None },
            Err(e) => QuarterXi { xi: f64::INFINITY, refused, error: Some(e) },
        })
        .collect())
}
