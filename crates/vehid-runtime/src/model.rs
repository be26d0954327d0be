//! Linear models as plain data ([`ModelData`]) and their one-off algebra at run-time sizes:
//! each function here validates or computes through the core's `LinearModel<f64, N, M>`,
//! built on demand from the data by the size table.

use crate::sizes::{bad_dims, dispatch_n, dispatch_nm};
use vehid_core::analysis::{discrete_stationary_cov, output_std};
use vehid_core::model::LinearModel;
use vehid_core::nalgebra::SMatrix;
use vehid_core::sim::{Method, SimConfig, Simulator};
use vehid_core::{Error, Result};

/// A validated model as plain data: `A` (`n × n`) and `B` (`n × m`) row-major, the unknown
/// rows (ascending) and the structurally-zero entries of the unknown rows.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct ModelData {
    pub n: usize,
    pub m: usize,
    pub a: Vec<f64>,
    pub b: Vec<f64>,
    pub rows: Vec<usize>,
    pub zeros: Vec<(usize, usize)>,
}

impl ModelData {
    /// Copies a core model out.
    pub fn from_core<const N: usize, const M: usize>(model: &LinearModel<f64, N, M>) -> Self {
        let a = (0..N * N).map(|k| model.a()[(k / N, k % N)]).collect();
        let b = (0..N * M).map(|k| model.b()[(k / M, k % M)]).collect();
        let rows = model.unknown_rows().as_slice().to_vec();
        let zeros = rows
            .iter()
            .flat_map(|&r| (0..N).map(move |c| (r, c)))
            .filter(|&(r, c)| model.is_structural_zero(r, c))
            .collect();
        Self { n: N, m: M, a, b, rows, zeros }
    }

    /// Rebuilds the core model (cheap: a copy and the core's own validation).
    pub fn model<const N: usize, const M: usize>(&self) -> Result<LinearModel<f64, N, M>> {
        self.check::<N, M>()?;
        let a = SMatrix::<f64, N, N>::from_fn(|i, j| self.a[i * N + j]);
        let b = SMatrix::<f64, N, M>::from_fn(|i, j| self.b[i * M + j]);
        LinearModel::new(a, b, &self.rows)?.with_structural_zeros(&self.zeros)
    }

    /// The core model with `B` replaced by one zero column, for what depends on `A` alone.
    pub fn model_a<const N: usize>(&self) -> Result<LinearModel<f64, N, 1>> {
        if self.n != N || self.a.len() != N * N {
            return Err(bad_dims());
        }
        let a = SMatrix::<f64, N, N>::from_fn(|i, j| self.a[i * N + j]);
        LinearModel::new(a, SMatrix::zeros(), &self.rows)?.with_structural_zeros(&self.zeros)
    }

    fn check<const N: usize, const M: usize>(&self) -> Result<()> {
        if self.n != N || self.m != M || self.a.len() != N * N || self.b.len() != N * M {
            return Err(bad_dims());
        }
        Ok(())
    }
}

/// Validates a user model through the core constructor and copies it back out.
fn new_model_nm<const N: usize, const M: usize>(
    a: &[f64],
    b: &[f64],
    rows: &[usize],
    zeros: Option<&[(usize, usize)]>,
) -> Result<ModelData> {
    if a.len() != N * N {
        return Err(Error::Shape { arg: "a", expected: N * N, got: a.len() });
    }
    if b.len() != N * M {
        return Err(Error::Shape { arg: "b", expected: N * M, got: b.len() });
    }
    let am = SMatrix::<f64, N, N>::from_fn(|i, j| a[i * N + j]);
    let bm = SMatrix::<f64, N, M>::from_fn(|i, j| b[i * M + j]);
    let mut model = LinearModel::new(am, bm, rows)?;
    if let Some(z) = zeros {
        model = model.with_structural_zeros(z)?;
    }
    Ok(ModelData::from_core(&model))
}

/// Eq 4.27 output standard deviations.
fn output_std_nm<const N: usize, const M: usize>(d: &ModelData, road_sigma: &[f64], hold: f64) -> Result<Vec<f64>> {
    Ok(output_std(&d.model::<N, M>()?, road_sigma, hold)?.as_slice().to_vec())
}

/// Diagonal of `R_v + B R_u Bᵀ` on the unknown rows (Eq 4.7).
fn row_noise_var_nm<const N: usize, const M: usize>(
    d: &ModelData,
    road_sigma: &[f64],
    deriv_noise: &[f64],
) -> Result<Vec<f64>> {
    let model = d.model::<N, M>()?;
    let mut out = vec![0.0; d.rows.len()];
    model.row_noise_var_into(road_sigma, deriv_noise, &mut out)?;
    Ok(out)
}

/// Stationary covariance (`n × n`, row-major) of the state at the sample instants of the
/// discretized system a `Simulator` with these settings steps: its own `(Φ, Γ)` (so the
/// sub-step choice and the RK4 stability check are the simulator's, not repeated here).
fn sampled_cov_nm<const N: usize, const M: usize>(
    d: &ModelData,
    road_sigma: &[f64],
    dt: f64,
    method: Method,
    substeps: Option<usize>,
) -> Result<Vec<f64>> {
    let mut cfg = SimConfig::<f64, N, M>::new(dt);
    cfg.method = method;
    cfg.substeps = substeps;
    let sim = Simulator::new(d.model::<N, M>()?, cfg, 0)?;
    let (phi, gamma) = sim.transition();
    let p = discrete_stationary_cov(phi, gamma, road_sigma)?;
    Ok((0..N * N).map(|k| p[(k / N, k % N)]).collect())
}

/// Poles, sorted as the core sorts them.
fn poles_n<const N: usize>(d: &ModelData) -> Result<Vec<(f64, f64)>> {
    Ok(d.model_a::<N>()?.poles()?.iter().map(|p| (p.re, p.im)).collect())
}

/// The true unknown rows, row-major.
fn theta_n<const N: usize>(d: &ModelData) -> Result<Vec<f64>> {
    let mut out = vec![0.0; d.rows.len() * N];
    d.model_a::<N>()?.theta_into(&mut out)?;
    Ok(out)
}

/// `Â`, row-major.
fn a_hat_n<const N: usize>(d: &ModelData, theta: &[f64]) -> Result<Vec<f64>> {
    let a = d.model_a::<N>()?.a_hat(theta)?;
    Ok((0..N * N).map(|k| a[(k / N, k % N)]).collect())
}

impl ModelData {
    /// A model validated by the core's constructor (`LinearModel::new`, then the structural
    /// zeros): `a` (`n × n`) and `b` (`n × m`) row-major, the unknown `rows`, the entries of
    /// the unknown rows known to be zero.
    ///
    /// # Errors
    /// The core's validation errors; sizes outside 1..=16 states and 1..=4 inputs.
    pub fn new(
        n: usize,
        m: usize,
        a: &[f64],
        b: &[f64],
        rows: &[usize],
        zeros: Option<&[(usize, usize)]>,
    ) -> Result<Self> {
        dispatch_nm!(n, m, new_model_nm(a, b, rows, zeros))
    }

    /// Output standard deviations of the sampled model driven by white road noise of
    /// intensities `road_sigma` held for `hold` s (Eq 4.27).
    ///
    /// # Errors
    /// The core's (`analysis::output_std`).
    pub fn output_std(&self, road_sigma: &[f64], hold: f64) -> Result<Vec<f64>> {
        dispatch_nm!(self.n, self.m, output_std_nm(self, road_sigma, hold))
    }

    /// Per-row regression-error variances `diag(R_v + B R_u Bᵀ)` on the unknown rows (Eq 4.7).
    ///
    /// # Errors
    /// The core's (`LinearModel::row_noise_var_into`).
    pub fn row_noise_var(&self, road_sigma: &[f64], deriv_noise: &[f64]) -> Result<Vec<f64>> {
        dispatch_nm!(self.n, self.m, row_noise_var_nm(self, road_sigma, deriv_noise))
    }

    /// Stationary state covariance at the sample instants (`n × n`, row-major) of the
    /// discretization a simulator with these settings steps.
    ///
    /// # Errors
    /// The simulator's settings errors; an unstable model.
    pub fn sampled_cov(
        &self,
        road_sigma: &[f64],
        dt: f64,
        method: Method,
        substeps: Option<usize>,
    ) -> Result<Vec<f64>> {
        dispatch_nm!(self.n, self.m, sampled_cov_nm(self, road_sigma, dt, method, substeps))
    }

    /// The poles (eigenvalues of `A`) as `(re, im)`, rad/s, sorted as the core sorts them.
    ///
    /// # Errors
    /// The core's (`LinearModel::poles`).
    pub fn poles(&self) -> Result<Vec<(f64, f64)>> {
        dispatch_n!(self.n, poles_n(self))
    }

    /// The true unknown rows of `A`, row-major (`rows.len() × n`).
    ///
    /// # Errors
    /// Sizes outside the table.
    pub fn theta(&self) -> Result<Vec<f64>> {
        dispatch_n!(self.n, theta_n(self))
    }

    /// `Â`: `A` with its unknown rows replaced by `theta` (row-major, `n × n`).
    ///
    /// # Errors
    /// [`Error::Shape`] for a `theta` of the wrong length.
    pub fn a_hat(&self, theta: &[f64]) -> Result<Vec<f64>> {
        dispatch_n!(self.n, a_hat_n(self, theta))
    }
}
