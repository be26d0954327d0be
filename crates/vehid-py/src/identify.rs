//! `KalmanIdentifier`, `BatchLeastSquares`, `StochasticGradient`: the Python identifier classes.
//!
//! Each wraps a core identifier with heap row storage (`*Vec` types, one monomorphization per
//! state count `N`) behind the object-safe [`Ident`]. `fit` validates the whole arrays first,
//! then runs the core's per-sample update with the GIL released; nothing numerical happens here.

use crate::convert::{array, finite, shape_str, size};
use crate::dispatch::{a_hat_n, dispatch_n};
use crate::model::{to_array2, PyLinearModel};
use crate::{core_err, VehidError};
use numpy::ndarray::{Array1, Array3};
use numpy::{IntoPyArray, PyArray1, PyArray2, PyArray3};
use pyo3::prelude::*;
use vehid_core::identify::{
    BatchLeastSquares, CovarianceForm, Dynamic, FullKalmanIdentifierVec, Gain, KalmanOptions, KalmanRows,
    RowIdentifier, SharedKalmanIdentifierVec, StochasticGradientVec, DYNAMIC_LANES,
};
use vehid_core::nalgebra::{SMatrix, SVector};
use vehid_core::{Error, Result};

/// What the Python classes need from any recursive identifier, over run-time sizes.
pub trait Ident: Send + Sync {
    /// One sample (`x`, `z` of length n); innovations into `e` (length k).
    fn update(&mut self, x: &[f64], z: &[f64], e: &mut [f64]) -> Result<()>;
    /// Every sample of row-major `r`, `z` (`len × n`); θ row-major appended to `hist` every
    /// `every` samples (0: never). All or nothing: at the first rejected sample the identifier
    /// is restored to its state before the call and that sample's index is reported.
    fn fit(
        &mut self,
        r: &[f64],
        z: &[f64],
        every: usize,
        hist: &mut Vec<f64>,
    ) -> core::result::Result<(), (usize, Error)>;
    /// θ̂ row-major (`k × n`).
    fn theta(&self) -> Vec<f64>;
    /// The covariance in the mode's own layout (see the Python docstrings).
    fn covariance(&self) -> Vec<f64>;
    /// The measurement variances in use (per row; `k × k` for the full mode).
    fn r(&self) -> Vec<f64>;
    /// `tr P`.
    fn trace(&self) -> f64;
    /// Reinitializations so far.
    fn reinit_count(&self) -> u32;
    /// Samples accepted.
    fn samples(&self) -> u64;
}

/// The per-`N` view of a core identifier that [`Adapter`] turns into an [`Ident`]. `Clone`
/// lets `fit` restore the state before a rejected call (a few kB at most, once per call).
trait Core<const N: usize>: Send + Sync + Clone {
    fn step(&mut self, x: &SVector<f64, N>, z: &SVector<f64, N>, e: &mut [f64]) -> Result<()>;
    fn theta_into(&self, out: &mut [f64]) -> Result<()>;
    fn rows_len(&self) -> usize;
    fn covariance(&self) -> Vec<f64>;
    fn r(&self) -> Vec<f64>;
    fn trace(&self) -> f64;
    fn reinit_count(&self) -> u32;
    fn samples(&self) -> u64;
}

struct Adapter<C, const N: usize>(C);

impl<C: Core<N>, const N: usize> Ident for Adapter<C, N> {
    fn update(&mut self, x: &[f64], z: &[f64], e: &mut [f64]) -> Result<()> {
        if x.len() != N {
            return Err(Error::Shape { arg: "r_k", expected: N, got: x.len() });
        }
        if z.len() != N {
            return Err(Error::Shape { arg: "z_k", expected: N, got: z.len() });
        }
        self.0.step(&SVector::from_column_slice(x), &SVector::from_column_slice(z), e)
    }

    fn fit(
        &mut self,
        r: &[f64],
        z: &[f64],
        every: usize,
        hist: &mut Vec<f64>,
    ) -> core::result::Result<(), (usize, Error)> {
        let k = self.0.rows_len();
        let mut e = vec![0.0; k];
        let mut th = vec![0.0; k * N];
        // A sample can pass the up-front checks (finite) and still be rejected by the update
        // itself (overflow, a singular step) after earlier samples were applied: keep the
        // state from before the call to put back then.
        let before = self.0.clone();
        for (i, (x, zk)) in r.chunks_exact(N).zip(z.chunks_exact(N)).enumerate() {
            let mut step = self.0.step(&SVector::from_column_slice(x), &SVector::from_column_slice(zk), &mut e);
            if step.is_ok() && every > 0 && (i + 1) % every == 0 {
                step = self.0.theta_into(&mut th).map(|()| hist.extend_from_slice(&th));
            }
            if let Err(err) = step {
                self.0 = before;
                return Err((i, err));
            }
        }
        Ok(())
    }

    fn theta(&self) -> Vec<f64> {
        let mut out = vec![0.0; self.0.rows_len() * N];
        // The buffer has the right length by construction.
        let _ = self.0.theta_into(&mut out);
        out
    }

    fn covariance(&self) -> Vec<f64> {
        self.0.covariance()
    }
    fn r(&self) -> Vec<f64> {
        self.0.r()
    }
    fn trace(&self) -> f64 {
        self.0.trace()
    }
    fn reinit_count(&self) -> u32 {
        self.0.reinit_count()
    }
    fn samples(&self) -> u64 {
        self.0.samples()
    }
}

fn row_major<const N: usize>(p: &SMatrix<f64, N, N>) -> impl Iterator<Item = f64> + '_ {
    (0..N * N).map(move |i| p[(i / N, i % N)])
}

impl<const N: usize, const L: usize> Core<N> for KalmanRows<f64, N, Dynamic<L>> {
    fn step(&mut self, x: &SVector<f64, N>, z: &SVector<f64, N>, e: &mut [f64]) -> Result<()> {
        self.update_into(x, z, e)
    }
    fn theta_into(&self, out: &mut [f64]) -> Result<()> {
        KalmanRows::theta_into(self, out)
    }
    fn rows_len(&self) -> usize {
        self.rows().len()
    }
    fn covariance(&self) -> Vec<f64> {
        (0..self.rows().len()).flat_map(|i| row_major(self.filter(i).p()).collect::<Vec<_>>()).collect()
    }
    fn r(&self) -> Vec<f64> {
        (0..self.rows().len()).map(|i| self.filter(i).r()).collect()
    }
    fn trace(&self) -> f64 {
        KalmanRows::trace(self)
    }
    fn reinit_count(&self) -> u32 {
        KalmanRows::reinit_count(self)
    }
    fn samples(&self) -> u64 {
        KalmanRows::samples(self)
    }
}

impl<const N: usize> Core<N> for SharedKalmanIdentifierVec<f64, N> {
    fn step(&mut self, x: &SVector<f64, N>, z: &SVector<f64, N>, e: &mut [f64]) -> Result<()> {
        self.update_into(x, z, e)
    }
    fn theta_into(&self, out: &mut [f64]) -> Result<()> {
        SharedKalmanIdentifierVec::theta_into(self, out)
    }
    fn rows_len(&self) -> usize {
        self.rows().len()
    }
    fn covariance(&self) -> Vec<f64> {
        (0..self.rows().len()).flat_map(|i| row_major(&self.p(i)).collect::<Vec<_>>()).collect()
    }
    fn r(&self) -> Vec<f64> {
        (0..self.rows().len()).map(|i| SharedKalmanIdentifierVec::r(self, i)).collect()
    }
    fn trace(&self) -> f64 {
        SharedKalmanIdentifierVec::trace(self)
    }
    fn reinit_count(&self) -> u32 {
        SharedKalmanIdentifierVec::reinit_count(self)
    }
    fn samples(&self) -> u64 {
        SharedKalmanIdentifierVec::samples(self)
    }
}

impl<const N: usize> Core<N> for FullKalmanIdentifierVec<f64, N> {
    fn step(&mut self, x: &SVector<f64, N>, z: &SVector<f64, N>, e: &mut [f64]) -> Result<()> {
        self.update_into(x, z, e)
    }
    fn theta_into(&self, out: &mut [f64]) -> Result<()> {
        FullKalmanIdentifierVec::theta_into(self, out)
    }
    fn rows_len(&self) -> usize {
        self.rows().len()
    }
    fn covariance(&self) -> Vec<f64> {
        // The (k·n) × (k·n) matrix, row-major.
        let k = self.rows().len();
        let kn = k * N;
        (0..kn * kn)
            .map(|idx| {
                let (i, j) = (idx / kn, idx % kn);
                self.p_block(i / N, j / N)[(i % N, j % N)]
            })
            .collect()
    }
    fn r(&self) -> Vec<f64> {
        let k = self.rows().len();
        (0..k * k).map(|idx| FullKalmanIdentifierVec::r(self, idx / k, idx % k)).collect()
    }
    fn trace(&self) -> f64 {
        FullKalmanIdentifierVec::trace(self)
    }
    fn reinit_count(&self) -> u32 {
        FullKalmanIdentifierVec::reinit_count(self)
    }
    fn samples(&self) -> u64 {
        FullKalmanIdentifierVec::samples(self)
    }
}

impl<const N: usize> Core<N> for StochasticGradientVec<f64, N> {
    fn step(&mut self, x: &SVector<f64, N>, z: &SVector<f64, N>, e: &mut [f64]) -> Result<()> {
        self.update_into(x, z, e)
    }
    fn theta_into(&self, out: &mut [f64]) -> Result<()> {
        StochasticGradientVec::theta_into(self, out)
    }
    fn rows_len(&self) -> usize {
        self.rows().len()
    }
    fn covariance(&self) -> Vec<f64> {
        Vec::new()
    }
    fn r(&self) -> Vec<f64> {
        Vec::new()
    }
    fn trace(&self) -> f64 {
        f64::NAN
    }
    fn reinit_count(&self) -> u32 {
        0
    }
    fn samples(&self) -> u64 {
        StochasticGradientVec::samples(self)
    }
}

/// Prior covariance as the user gave it.
pub enum P0 {
    /// One value or one per row (times the identity).
    PerRow(Vec<f64>),
    /// One `n × n` matrix per row (`k × n × n`, row-major).
    RowMatrices(Vec<f64>),
    /// The full `(k·n) × (k·n)` matrix.
    Full(Vec<f64>),
}

/// Settings of a Kalman identifier, already converted.
pub struct KalmanSpec {
    pub rows: Vec<usize>,
    pub p0: P0,
    /// One per row, or `k × k` for the full mode.
    pub r: Vec<f64>,
    pub mode: Mode,
    pub opts: KalmanOptions<f64>,
}

#[derive(Clone, Copy, PartialEq, Eq)]
pub enum Mode {
    Rows,
    Shared,
    Full,
}

/// The decoupled-rows identifier with its rows in groups of `L` lanes.
fn rows_core<const N: usize, const L: usize>(s: &KalmanSpec) -> Result<Box<dyn Ident>> {
    let k = s.rows.len();
    let core = match &s.p0 {
        P0::PerRow(p0) => KalmanRows::<f64, N, Dynamic<L>>::from_slices(&s.rows, p0, &s.r, s.opts)?,
        P0::RowMatrices(m) => {
            let filters = (0..k)
                .map(|i| {
                    let p = SMatrix::<f64, N, N>::from_fn(|a, b| m[i * N * N + a * N + b]);
                    let r = vehid_core_per_row(&s.r, k, i)?;
                    RowIdentifier::with_prior(SVector::zeros(), p, r)
                })
                .collect::<Result<Vec<_>>>()?;
            KalmanRows::<f64, N, Dynamic<L>>::from_filters(&s.rows, &filters, s.opts)?
        }
        P0::Full(_) => {
            return Err(Error::InvalidArgument {
                arg: "p0",
                expected: "a scalar, one value per row, or one (n, n) matrix per row for mode='rows' \
                           (a full (k·n, k·n) matrix needs mode='full')",
            })
        }
    };
    Ok(Box::new(Adapter::<_, N>(core)))
}

fn kalman_n<const N: usize>(s: &KalmanSpec) -> Result<Box<dyn Ident>> {
    let k = s.rows.len();
    Ok(match s.mode {
        // One or two rows: groups of two lanes (no padding lanes); more: the default groups.
        Mode::Rows if k <= 2 => rows_core::<N, 2>(s)?,
        Mode::Rows => rows_core::<N, DYNAMIC_LANES>(s)?,
        Mode::Shared => {
            let P0::PerRow(p0) = &s.p0 else {
                return Err(Error::InvalidArgument {
                    arg: "p0",
                    expected: "a scalar or one value per row for mode='shared'",
                });
            };
            Box::new(Adapter::<_, N>(SharedKalmanIdentifierVec::<f64, N>::from_slices(&s.rows, p0, &s.r, s.opts)?))
        }
        Mode::Full => {
            let r_full: Vec<f64> = if s.r.len() == k * k && k > 1 {
                s.r.clone()
            } else {
                let mut m = vec![0.0; k * k];
                for i in 0..k {
                    m[i * k + i] = vehid_core_per_row(&s.r, k, i)?;
                }
                m
            };
            let (p0, full) = match &s.p0 {
                P0::PerRow(p) => (p.clone(), None),
                P0::Full(m) => (vec![1.0], Some(m)),
                P0::RowMatrices(_) => {
                    return Err(Error::InvalidArgument {
                        arg: "p0",
                        expected: "a scalar, one value per row, or the full (k·n, k·n) matrix for mode='full'",
                    })
                }
            };
            let mut core = FullKalmanIdentifierVec::<f64, N>::from_slices(&s.rows, &p0, &r_full, s.opts)?;
            if let Some(m) = full {
                core.set_p0(m)?;
            }
            Box::new(Adapter::<_, N>(core))
        }
    })
}

/// One value or one per row.
fn vehid_core_per_row(v: &[f64], k: usize, i: usize) -> Result<f64> {
    match v.len() {
        1 => Ok(v[0]),
        n if n == k => Ok(v[i]),
        n => Err(Error::Shape { arg: "r", expected: k, got: n }),
    }
}

/// Settings of a stochastic-gradient identifier, already converted.
pub struct GradientSpec {
    pub rows: Vec<usize>,
    pub gain: Gain<f64>,
    pub h: Vec<f64>,
    pub state_noise_var: Vec<f64>,
    pub spacing: u32,
}

fn gradient_n<const N: usize>(s: &GradientSpec) -> Result<Box<dyn Ident>> {
    let core = StochasticGradientVec::<f64, N>::from_slices(&s.rows, s.gain, &s.h, &s.state_noise_var, s.spacing)?;
    Ok(Box::new(Adapter::<_, N>(core)))
}

/// Batch least squares over run-time sizes.
pub trait Batch: Send + Sync {
    fn extend(&mut self, r: &[f64], z: &[f64]) -> Result<()>;
    fn solve(&self) -> Result<Vec<f64>>;
    fn samples(&self) -> usize;
    fn storage_bytes(&self) -> usize;
    fn clear(&mut self);
}

impl<const N: usize> Batch for BatchLeastSquares<f64, N> {
    fn extend(&mut self, r: &[f64], z: &[f64]) -> Result<()> {
        BatchLeastSquares::extend(self, r, z)
    }
    fn solve(&self) -> Result<Vec<f64>> {
        BatchLeastSquares::solve(self)
    }
    fn samples(&self) -> usize {
        BatchLeastSquares::samples(self)
    }
    fn storage_bytes(&self) -> usize {
        BatchLeastSquares::storage_bytes(self)
    }
    fn clear(&mut self) {
        BatchLeastSquares::clear(self)
    }
}

fn batch_n<const N: usize>(rows: &[usize]) -> Result<Box<dyn Batch>> {
    Ok(Box::new(BatchLeastSquares::<f64, N>::new(rows)?))
}

/// `(len, n)` sample arrays `r` and `z`, validated (shape, finiteness) before any update.
fn samples_arg(r: &Bound<'_, PyAny>, z: &Bound<'_, PyAny>, n: usize) -> PyResult<(usize, Vec<f64>, Vec<f64>)> {
    let ra = array(r, "r")?;
    let za = array(z, "z")?;
    let ok = |s: &[usize]| s.len() == 2 && s[1] == n;
    if !ok(&ra.shape) {
        return Err(VehidError::new_err(format!(
            "`r` must have shape (samples, {n}) (measured states), got {}",
            shape_str(&ra.shape)
        )));
    }
    if !ok(&za.shape) || za.shape[0] != ra.shape[0] {
        return Err(VehidError::new_err(format!(
            "`z` must have shape {} like `r` (measured derivatives), got {}",
            shape_str(&ra.shape),
            shape_str(&za.shape)
        )));
    }
    for (name, a) in [("r", &ra), ("z", &za)] {
        if let Some(i) = a.data.iter().position(|v| !v.is_finite()) {
            return Err(VehidError::new_err(format!(
                "`{name}[{}, {}]` is not finite (NaN or inf): clean or drop that sample",
                i / n,
                i % n
            )));
        }
    }
    Ok((ra.shape[0], ra.data, za.data))
}

/// One sample `r_k`, `z_k` (each of length n).
fn sample_arg(x: &Bound<'_, PyAny>, z: &Bound<'_, PyAny>, n: usize) -> PyResult<(Vec<f64>, Vec<f64>)> {
    let xa = array(x, "r_k")?;
    let za = array(z, "z_k")?;
    for (name, a) in [("r_k", &xa), ("z_k", &za)] {
        if a.shape != [n] {
            return Err(VehidError::new_err(format!("`{name}` must have shape ({n},), got {}", shape_str(&a.shape))));
        }
    }
    Ok((xa.data, za.data))
}

/// Shared state of the recursive identifier classes.
struct Recursive {
    inner: Box<dyn Ident>,
    model: crate::dispatch::ModelData,
    rows: Vec<usize>,
}

impl Recursive {
    fn n(&self) -> usize {
        self.model.n
    }

    fn update<'py>(
        &mut self,
        py: Python<'py>,
        r_k: &Bound<'py, PyAny>,
        z_k: &Bound<'py, PyAny>,
    ) -> PyResult<Bound<'py, PyArray1<f64>>> {
        let (x, z) = sample_arg(r_k, z_k, self.n())?;
        let mut e = vec![0.0; self.rows.len()];
        self.inner.update(&x, &z, &mut e).map_err(core_err)?;
        Ok(e.into_pyarray(py))
    }

    fn fit<'py>(
        &mut self,
        py: Python<'py>,
        r: &Bound<'py, PyAny>,
        z: &Bound<'py, PyAny>,
        record_every: i128,
    ) -> PyResult<Bound<'py, PyArray3<f64>>> {
        let n = self.n();
        let every = size(record_every, "record_every")?;
        let (len, rd, zd) = samples_arg(r, z, n)?;
        let k = self.rows.len();
        let inner = &mut self.inner;
        let mut hist = Vec::with_capacity(if every > 0 { (len / every) * k * n } else { 0 });
        py.detach(|| inner.fit(&rd, &zd, every, &mut hist)).map_err(|(i, e)| {
            VehidError::new_err(format!(
                "sample {i} was rejected ({e}); the identifier is unchanged (none of the {len} samples were applied)"
            ))
        })?;
        let rows = hist.len() / (k * n).max(1);
        Array3::from_shape_vec((rows, k, n), hist)
            .map(|a| a.into_pyarray(py))
            .map_err(|e| VehidError::new_err(format!("internal shape error: {e}")))
    }

    fn theta<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f64>>> {
        to_array2(py, self.rows.len(), self.n(), self.inner.theta())
    }

    fn a_hat<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f64>>> {
        let th = self.inner.theta();
        let d = &self.model;
        let a = dispatch_n!(d.n, a_hat_n(d, &th)).map_err(core_err)?;
        to_array2(py, d.n, d.n, a)
    }
}

fn rows_of(model: &PyLinearModel) -> Vec<usize> {
    model.data.rows.clone()
}

/// The Kalman-filter identifier (Eq 4.3–4.7): recursive weighted least squares for the
/// unknown rows of `A`.
///
/// `p0`: the prior covariance `P(0)`: a scalar (times I), one value per unknown row, one (n, n)
/// matrix per row (shape (k, n, n), mode "rows"), or the full (k·n, k·n) matrix (mode "full").
/// The thesis uses 1000 (4 states) and 1000 on the wheel rows / 8 on the body rows (8 states).
/// `r`: the regression-error variance of each unknown row, `R = R_v + B R_u Bᵀ` (Eq 4.7); or
/// give `road_sigma` (m) and `deriv_noise` and it is computed from the model. For mode "full",
/// `r` may be a (k, k) matrix. `reinit=True` applies Eq 4.36. `mode`: "rows" (decoupled
/// filters, Eq 6.16–6.18), "shared" (one covariance for all rows; needs the same r/p0 on every
/// row), "full" (the stacked filter, general R). After k samples the estimate depends on
/// r/p0 only (see the README on prior regimes).
#[pyclass(name = "KalmanIdentifier", module = "vehid._vehid")]
pub struct PyKalmanIdentifier {
    rec: Recursive,
    mode: &'static str,
}

/// Parses `p0` for a model with `k` unknown rows and `n` states.
fn p0_arg(p0: &Bound<'_, PyAny>, k: usize, n: usize) -> PyResult<P0> {
    let a = array(p0, "p0")?;
    finite("p0", &a.data)?;
    Ok(match a.shape[..] {
        [] => P0::PerRow(a.data),
        [len] if len == k => P0::PerRow(a.data),
        [kk, r, c] if kk == k && r == n && c == n => P0::RowMatrices(a.data),
        [r, c] if r == k * n && c == k * n => P0::Full(a.data),
        _ => {
            return Err(VehidError::new_err(format!(
                "`p0` must be a scalar, shape ({k},), ({k}, {n}, {n}) or ({kn}, {kn}), got {}",
                shape_str(&a.shape),
                kn = k * n
            )))
        }
    })
}

#[pymethods]
impl PyKalmanIdentifier {
    #[new]
    #[pyo3(signature = (model, p0 = None, r = None, *, road_sigma = None, deriv_noise = None, reinit = false, mode = "rows", joseph = false, retire_below = 0.0))]
    #[allow(clippy::too_many_arguments)]
    fn py_new(
        model: &Bound<'_, PyLinearModel>,
        p0: Option<&Bound<'_, PyAny>>,
        r: Option<&Bound<'_, PyAny>>,
        road_sigma: Option<&Bound<'_, PyAny>>,
        deriv_noise: Option<&Bound<'_, PyAny>>,
        reinit: bool,
        mode: &str,
        joseph: bool,
        retire_below: f64,
    ) -> PyResult<Self> {
        let m = model.get();
        let (n, k) = (m.data.n, m.data.rows.len());
        let (mode, mode_name) = match mode {
            "rows" => (Mode::Rows, "rows"),
            "shared" => (Mode::Shared, "shared"),
            "full" => (Mode::Full, "full"),
            other => {
                return Err(VehidError::new_err(format!(
                    "unknown `mode` {other:?}: expected one of \"rows\", \"shared\", \"full\""
                )))
            }
        };
        let p0 = match p0 {
            Some(p) => p0_arg(p, k, n)?,
            None => P0::PerRow(vec![1000.0]),
        };
        let r = match (r, road_sigma, deriv_noise) {
            (Some(r), None, None) => {
                let a = array(r, "r")?;
                finite("r", &a.data)?;
                let ok = match a.shape[..] {
                    [] => true,
                    [len] => len == k,
                    [rr, cc] => mode == Mode::Full && rr == k && cc == k,
                    _ => false,
                };
                if !ok {
                    return Err(VehidError::new_err(format!(
                        "`r` must be a scalar or one variance per unknown row, shape ({k},){}; got {}",
                        if mode == Mode::Full { format!(", or a ({k}, {k}) matrix") } else { String::new() },
                        shape_str(&a.shape)
                    )));
                }
                a.data
            }
            (None, rs, dn) if rs.is_some() || dn.is_some() => {
                let rs = crate::convert::values(rs, "road_sigma", 0.0)?;
                let dn = crate::convert::values(dn, "deriv_noise", 0.0)?;
                m.row_noise_var_vec(&rs, &dn)?
            }
            (None, None, None) => {
                return Err(VehidError::new_err(
                    "give the regression-error variances: `r=` (one per unknown row) or `road_sigma=` and \
                     `deriv_noise=` to compute them from the model (Eq 4.7)",
                ))
            }
            _ => return Err(VehidError::new_err("give either `r=` or `road_sigma=`/`deriv_noise=`, not both")),
        };
        let opts = KalmanOptions {
            form: if joseph { CovarianceForm::Joseph } else { CovarianceForm::Standard },
            reinit,
            retire_below,
        };
        let spec = KalmanSpec { rows: rows_of(m), p0, r, mode, opts };
        let inner = dispatch_n!(n, kalman_n(&spec)).map_err(core_err)?;
        Ok(Self { rec: Recursive { inner, model: m.data.clone(), rows: spec.rows }, mode: mode_name })
    }

    /// One sample: measured state `r_k` (n,) and derivative `z_k` (n,). Returns the
    /// innovations `z − x̂ᵀθ̂` of the unknown rows (k,). A rejected sample (NaN, inf, a
    /// numerically singular step) raises VehidError and leaves the identifier unchanged.
    fn update<'py>(
        &mut self,
        py: Python<'py>,
        r_k: &Bound<'py, PyAny>,
        z_k: &Bound<'py, PyAny>,
    ) -> PyResult<Bound<'py, PyArray1<f64>>> {
        self.rec.update(py, r_k, z_k)
    }

    /// Runs every sample of `r`, `z` (samples, n) with the GIL released. Returns θ̂ recorded
    /// every `record_every` samples, shape (samples // record_every, k, n) (empty when 0).
    #[pyo3(signature = (r, z, record_every = 0))]
    fn fit<'py>(
        &mut self,
        py: Python<'py>,
        r: &Bound<'py, PyAny>,
        z: &Bound<'py, PyAny>,
        record_every: i128,
    ) -> PyResult<Bound<'py, PyArray3<f64>>> {
        self.rec.fit(py, r, z, record_every)
    }

    /// The estimated unknown rows of A, shape (k, n).
    #[getter]
    fn theta<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f64>>> {
        self.rec.theta(py)
    }

    /// Â: the model's A with the unknown rows replaced by the estimate, shape (n, n).
    #[getter]
    fn a_hat<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f64>>> {
        self.rec.a_hat(py)
    }

    /// The covariance: (k, n, n) per-row P_i for modes "rows" and "shared" (P_i = r_i Q),
    /// the full (k·n, k·n) matrix for mode "full".
    #[getter]
    fn covariance<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let (k, n) = (self.rec.rows.len(), self.rec.n());
        let c = self.rec.inner.covariance();
        if self.mode == "full" {
            return Ok(to_array2(py, k * n, k * n, c)?.into_any());
        }
        Array3::from_shape_vec((k, n, n), c)
            .map(|a| a.into_pyarray(py).into_any())
            .map_err(|e| VehidError::new_err(format!("internal shape error: {e}")))
    }

    /// The regression-error variances in use (k,), or the (k, k) R of mode "full"; each
    /// reinitialization doubles them (Eq 4.36).
    #[getter]
    fn r<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let k = self.rec.rows.len();
        let r = self.rec.inner.r();
        if self.mode == "full" {
            return Ok(to_array2(py, k, k, r)?.into_any());
        }
        Ok(Array1::from_vec(r).into_pyarray(py).into_any())
    }

    /// tr P, the quantity Eq 4.36 compares with the innovations.
    #[getter]
    fn trace(&self) -> f64 {
        self.rec.inner.trace()
    }

    /// Number of reinitializations (Eq 4.36) so far.
    #[getter]
    fn reinit_count(&self) -> u32 {
        self.rec.inner.reinit_count()
    }

    /// Number of samples accepted.
    #[getter]
    fn samples(&self) -> u64 {
        self.rec.inner.samples()
    }

    /// The unknown rows (0-based).
    #[getter]
    fn unknown_rows(&self) -> Vec<usize> {
        self.rec.rows.clone()
    }

    /// "rows", "shared" or "full".
    #[getter]
    fn mode(&self) -> &'static str {
        self.mode
    }

    fn __repr__(&self) -> String {
        format!(
            "KalmanIdentifier(mode={:?}, unknown_rows={:?}, samples={}, reinit_count={})",
            self.mode,
            self.rec.rows,
            self.rec.inner.samples(),
            self.rec.inner.reinit_count()
        )
    }
}

/// The stochastic-gradient identifier (Eq 2.56, 5.2–5.18).
///
/// `gain`: "venter" (Eq 5.8, γ = k^(−p), 1/2 < p ≤ 1), "lyapunov" (Eq 5.9, normalized by the
/// data; biased) or "ljung" (Eq 5.15–5.18, forgetting with `lambda0`, `lambda_init`).
/// `h`: the per-parameter weights: a scalar, one per unknown row (k,), or one per parameter
/// (k·n,) / (k, n); the thesis makes the wheel-row weights a tenth of the body-row ones
/// (Eq 5.10). `spacing`: use every l-th sample. `state_noise_var`: the diagonal of Σ_w (a
/// scalar or one per state) for the `[I + R Σ_N]` bias elimination.
#[pyclass(name = "StochasticGradient", module = "vehid._vehid")]
pub struct PyStochasticGradient {
    rec: Recursive,
    gain: &'static str,
}

#[pymethods]
impl PyStochasticGradient {
    #[new]
    #[pyo3(signature = (model, gain = "venter", h = None, p = 0.51, *, spacing = 1, state_noise_var = None, lambda0 = 0.99, lambda_init = 0.95))]
    #[allow(clippy::too_many_arguments)]
    fn py_new(
        model: &Bound<'_, PyLinearModel>,
        gain: &str,
        h: Option<&Bound<'_, PyAny>>,
        p: f64,
        spacing: i128,
        state_noise_var: Option<&Bound<'_, PyAny>>,
        lambda0: f64,
        lambda_init: f64,
    ) -> PyResult<Self> {
        let m = model.get();
        let (gain, name) = match gain {
            "venter" => (Gain::Venter { p }, "venter"),
            "lyapunov" => (Gain::Lyapunov, "lyapunov"),
            "ljung" => (Gain::Ljung { lambda0, lambda_init }, "ljung"),
            other => {
                return Err(VehidError::new_err(format!(
                    "unknown `gain` {other:?}: expected one of \"venter\", \"lyapunov\", \"ljung\""
                )))
            }
        };
        let h = match h {
            None => vec![1.0],
            Some(h) => {
                let a = array(h, "h")?;
                finite("h", &a.data)?;
                a.data
            }
        };
        let snv = crate::convert::values(state_noise_var, "state_noise_var", 0.0)?;
        let spacing = u32::try_from(spacing)
            .map_err(|_| VehidError::new_err(format!("`spacing` must be an integer >= 1, got {spacing}")))?;
        let spec = GradientSpec { rows: rows_of(m), gain, h, state_noise_var: snv, spacing };
        let inner = dispatch_n!(m.data.n, gradient_n(&spec)).map_err(core_err)?;
        Ok(Self { rec: Recursive { inner, model: m.data.clone(), rows: spec.rows }, gain: name })
    }

    /// One sample; returns the innovations (k,). A rejected sample leaves the identifier
    /// unchanged.
    fn update<'py>(
        &mut self,
        py: Python<'py>,
        r_k: &Bound<'py, PyAny>,
        z_k: &Bound<'py, PyAny>,
    ) -> PyResult<Bound<'py, PyArray1<f64>>> {
        self.rec.update(py, r_k, z_k)
    }

    /// Runs every sample (GIL released); returns θ̂ every `record_every` samples,
    /// shape (samples // record_every, k, n).
    #[pyo3(signature = (r, z, record_every = 0))]
    fn fit<'py>(
        &mut self,
        py: Python<'py>,
        r: &Bound<'py, PyAny>,
        z: &Bound<'py, PyAny>,
        record_every: i128,
    ) -> PyResult<Bound<'py, PyArray3<f64>>> {
        self.rec.fit(py, r, z, record_every)
    }

    /// The estimated unknown rows of A, shape (k, n).
    #[getter]
    fn theta<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f64>>> {
        self.rec.theta(py)
    }

    /// Â, shape (n, n).
    #[getter]
    fn a_hat<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f64>>> {
        self.rec.a_hat(py)
    }

    /// Samples seen.
    #[getter]
    fn samples(&self) -> u64 {
        self.rec.inner.samples()
    }

    /// The gain name.
    #[getter]
    fn gain(&self) -> &'static str {
        self.gain
    }

    /// The unknown rows (0-based).
    #[getter]
    fn unknown_rows(&self) -> Vec<usize> {
        self.rec.rows.clone()
    }

    fn __repr__(&self) -> String {
        format!(
            "StochasticGradient(gain={:?}, unknown_rows={:?}, samples={})",
            self.gain,
            self.rec.rows,
            self.rec.inner.samples()
        )
    }
}

/// Batch least squares (Eq 2.14): stores every sample and solves each unknown row by
/// column-pivoted QR. Missing excitation raises VehidError (rank deficiency), never NaN.
#[pyclass(name = "BatchLeastSquares", module = "vehid._vehid")]
pub struct PyBatchLeastSquares {
    inner: Box<dyn Batch>,
    model: crate::dispatch::ModelData,
}

#[pymethods]
impl PyBatchLeastSquares {
    #[new]
    fn py_new(model: &Bound<'_, PyLinearModel>) -> PyResult<Self> {
        let m = model.get();
        let rows = rows_of(m);
        let inner = dispatch_n!(m.data.n, batch_n(&rows)).map_err(core_err)?;
        Ok(Self { inner, model: m.data.clone() })
    }

    /// Stores one sample `r_k`, `z_k` (n,) (nothing is stored if it is rejected).
    fn update(&mut self, r_k: &Bound<'_, PyAny>, z_k: &Bound<'_, PyAny>) -> PyResult<()> {
        let (x, z) = sample_arg(r_k, z_k, self.model.n)?;
        self.inner.extend(&x, &z).map_err(core_err)
    }

    /// Stores every sample of `r`, `z` (samples, n) and solves; returns θ̂ (k, n). Samples
    /// that pass the checks (shape, finite) are stored even when the batch cannot be solved
    /// yet (too few, unexcited): the VehidError then says so, and more samples complete it.
    fn fit<'py>(
        &mut self,
        py: Python<'py>,
        r: &Bound<'py, PyAny>,
        z: &Bound<'py, PyAny>,
    ) -> PyResult<Bound<'py, PyArray2<f64>>> {
        let (len, rd, zd) = samples_arg(r, z, self.model.n)?;
        self.inner.extend(&rd, &zd).map_err(core_err)?;
        let inner = &self.inner;
        let th = py.detach(|| inner.solve()).map_err(|e| {
            VehidError::new_err(format!(
                "{e}; the {len} samples were stored ({} in all): add more with update() or fit(), or clear()",
                inner.samples()
            ))
        })?;
        to_array2(py, self.model.rows.len(), self.model.n, th)
    }

    /// θ̂ (k, n) from the stored samples (solved on each access).
    #[getter]
    fn theta<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f64>>> {
        let inner = &self.inner;
        let th = py.detach(|| inner.solve()).map_err(core_err)?;
        to_array2(py, self.model.rows.len(), self.model.n, th)
    }

    /// Â, shape (n, n).
    #[getter]
    fn a_hat<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f64>>> {
        let th = self.inner.solve().map_err(core_err)?;
        let d = &self.model;
        let a = dispatch_n!(d.n, a_hat_n(d, &th)).map_err(core_err)?;
        to_array2(py, d.n, d.n, a)
    }

    /// Samples stored.
    #[getter]
    fn samples(&self) -> usize {
        self.inner.samples()
    }

    /// Bytes of sample storage (the thesis' objection to batch least squares).
    #[getter]
    fn storage_bytes(&self) -> usize {
        self.inner.storage_bytes()
    }

    /// Drops the stored samples.
    fn clear(&mut self) {
        self.inner.clear()
    }

    /// The unknown rows (0-based).
    #[getter]
    fn unknown_rows(&self) -> Vec<usize> {
        self.model.rows.clone()
    }

    fn __repr__(&self) -> String {
        format!("BatchLeastSquares(unknown_rows={:?}, samples={})", self.model.rows, self.inner.samples())
    }
}
