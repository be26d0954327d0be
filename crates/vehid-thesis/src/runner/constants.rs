//! The car's physical constants along one realization: the engineer's reading of an
//! estimate, beside ξ (Eq 3.17).
//!
//! On a decimated grid ([`constants_grid`]) the estimate is mapped to the constants of the
//! car and their 95 % intervals:
//! - an identifier of the free unknown rows of A (Kalman, Eq 4.3–4.7; stochastic gradient,
//!   Eq 5.2–5.18; two-axle, Ch. VI.D): the constants by the model's own map from the rows,
//!   [`QuarterCar::from_theta`] with the wheel mass `m` known, [`HalfCar::from_theta`] with the
//!   wheel masses and B known. Their standard errors follow by the delta method,
//!   `se² = gᵀ Σ g`, with `g` the gradient of the constant in θ (central differences, step
//!   `10⁻⁶ max(|θ_j|, 1)`) and `Σ = s² P` the identifier's covariance of θ̂
//!   ([`estimate_stats`]);
//! - the quarter car in its physical structure (Fig 4-2's extension): the constants and
//!   their standard errors by [`PhysicalStructure::constant`] on the structure's own
//!   parameters and covariance, as the Python binding's `QuarterCar.physical(stats)`.
//!
//! The interval is `value ± t₀.₉₇₅(df) se`, `df` the smallest residual degrees of freedom
//! of the parameter groups (as `physical(stats)`). An identifier without a covariance (the
//! stochastic gradient, the two-axle identifier) gets no interval (NaN ends); an estimate
//! that gives no positive constants (early, not converged) is NaN.

use crate::figures::Ident;
use crate::report::{ConstantSeries, IdentifiedConstants, KnownConstant};
use vehid_core::identify::{estimate_stats, Identifier};
use vehid_core::model::{HalfCar, PhysicalStructure, QuarterCar, QuarterKnown};
use vehid_core::nalgebra::SMatrix;
use vehid_core::stats::t_interval_factor;

/// About how many iterations of a curve record the constants: half evenly spaced on a log
/// axis, half on a linear one (fewer where they coincide). 40 keep a report's JSON small
/// (a quarter-car curve adds about 10 kB) and draw smooth curves on either axis.
pub const CONSTANT_POINTS: usize = 40;

/// The level of the intervals: 95 %.
const ALPHA: f64 = 0.05;

/// One constant's estimate: `[value, lo, hi]` (NaN where undefined, module docs).
pub(crate) type Estimate = [f64; 3];

const NAN3: Estimate = [f64::NAN; 3];

/// The car whose constants are identified (the thesis' values are the truth).
#[derive(Debug, Clone, Copy)]
pub(crate) enum Car {
    /// The quarter car (Eq 3.8–3.13); the wheel mass `m` is known.
    Quarter(QuarterCar<f64>),
    /// The half car (Eq 6.1–6.8); the wheel masses and B (so `k11`, `k21`) are known.
    Half(HalfCar<f64>),
}

impl Car {
    /// The constants' names, in the model's order (`QuarterCar::CONSTANTS`,
    /// `HalfCar::CONSTANTS`).
    pub(crate) fn names(&self) -> &'static [&'static str] {
        match self {
            Car::Quarter(_) => &QuarterCar::<f64>::CONSTANTS,
            Car::Half(_) => &HalfCar::<f64>::CONSTANTS,
        }
    }

    fn truth(&self) -> Vec<f64> {
        match self {
            Car::Quarter(c) => c.constants().to_vec(),
            Car::Half(c) => c.constants().to_vec(),
        }
    }

    /// Whether constant `name` is held known (it fixes the scale, or B gives it).
    fn known(&self, name: &str) -> bool {
        match self {
            Car::Quarter(_) => name == "m",
            Car::Half(_) => matches!(name, "m1" | "m2" | "k11" | "k21"),
        }
    }

    /// The unit of a constant, from its name's first letter (masses M, m…; inertia J;
    /// stiffnesses k…; dampings b…; lever arms l…).
    fn unit(name: &str) -> &'static str {
        match name.as_bytes().first() {
            Some(b'M' | b'm') => "kg",
            Some(b'J') => "kg·m²",
            Some(b'k') => "N/m",
            Some(b'b') => "N·s/m",
            Some(b'l') => "m",
            _ => "",
        }
    }

    /// The constants (model order) from the unknown rows `theta` (row-major, rows 1, 3
    /// (quarter) or 1, 3, 5, 7 (half) of A) into `out`.
    fn constants_of(&self, theta: &[f64], out: &mut [f64]) -> crate::Result<()> {
        let shape = |n: usize| crate::Error::Shape { arg: "theta", expected: n, got: theta.len() };
        match self {
            Car::Quarter(c) => {
                if theta.len() != 8 || out.len() != 5 {
                    return Err(shape(8));
                }
                let t = SMatrix::<f64, 2, 4>::from_fn(|i, j| theta[i * 4 + j]);
                out.copy_from_slice(&QuarterCar::from_theta(&t, QuarterKnown::WheelMass(c.m_wheel()))?.constants());
            }
            Car::Half(c) => {
                if theta.len() != 32 || out.len() != 12 {
                    return Err(shape(32));
                }
                let t = SMatrix::<f64, 4, 8>::from_fn(|i, j| theta[i * 8 + j]);
                let (p, model) = (c.params(), c.model());
                let (b21, b42) = (model.b()[(1, 0)], model.b()[(3, 1)]);
                out.copy_from_slice(&HalfCar::from_theta(&t, p.m1, p.m2, b21, b42)?.constants());
            }
        }
        Ok(())
    }
}

/// `t₀.₉₇₅` at the smallest of the degrees of freedom (`t_interval_factor`; NaN where a
/// degree of freedom is not positive).
fn t_quantile(df: &[f64]) -> f64 {
    t_interval_factor(ALPHA, df).unwrap_or(f64::NAN)
}

/// The standard errors of the constants `car.constants_of(theta) = value` by the delta method
/// on the covariance `cov` of θ (module docs); NaN where a perturbed θ gives no constants.
fn delta_se(car: &Car, theta: &[f64], cov: &[f64], value: &[f64]) -> Vec<f64> {
    let (np, nc) = (theta.len(), value.len());
    let mut var = vec![0.0; nc];
    // g_j for every parameter with a variance; the covariance is 0 outside them.
    let mut grads: Vec<(usize, Vec<f64>)> = vec![];
    let (mut t, mut hi, mut lo) = (theta.to_vec(), vec![0.0; nc], vec![0.0; nc]);
    for j in (0..np).filter(|&j| cov[j * np + j] > 0.0) {
        let h = 1e-6 * theta[j].abs().max(1.0);
        t[j] = theta[j] + h;
        let a = car.constants_of(&t, &mut hi);
        t[j] = theta[j] - h;
        let b = car.constants_of(&t, &mut lo);
        t[j] = theta[j];
        if a.is_err() || b.is_err() {
            return vec![f64::NAN; nc];
        }
        grads.push((j, hi.iter().zip(&lo).map(|(p, m)| (p - m) / (2.0 * h)).collect()));
    }
    for (a, ga) in &grads {
        for (b, gb) in &grads {
            let s = cov[a * np + b];
            if s != 0.0 {
                for ((v, x), y) in var.iter_mut().zip(ga).zip(gb) {
                    *v += x * s * y;
                }
            }
        }
    }
    var.into_iter().map(|v| v.max(0.0).sqrt()).collect()
}

/// The constants of `car` (model order) from an identifier of its free unknown rows.
pub(crate) fn rows_constants<I: Identifier<f64> + ?Sized>(id: &I, car: &Car, out: &mut [Estimate]) {
    out.fill(NAN3);
    let mut theta = vec![0.0; id.dims().params];
    let mut value = vec![0.0; out.len()];
    if id.params_into(&mut theta).is_err() || car.constants_of(&theta, &mut value).is_err() {
        return;
    }
    let (se, q) = match estimate_stats(id, ALPHA) {
        Ok(st) if st.cov.len() == theta.len() * theta.len() => {
            (delta_se(car, &theta, &st.cov, &value), t_quantile(&st.df))
        }
        _ => (vec![f64::NAN; value.len()], f64::NAN),
    };
    for (o, (v, s)) in out.iter_mut().zip(value.iter().zip(&se)) {
        *o = [*v, v - q * s, v + q * s];
    }
}

/// The quarter car's constants (order of `QuarterCar::CONSTANTS`) from an identifier of its
/// physical structure `ph` (parameters `k2/M, b/M, M, k1`).
pub(crate) fn structure_constants<I: Identifier<f64> + ?Sized>(
    id: &I,
    ph: &PhysicalStructure<f64>,
    out: &mut [Estimate],
) {
    out.fill(NAN3);
    let np = ph.structure().params();
    let (theta, cov, q) = match estimate_stats(id, ALPHA) {
        Ok(st) => (st.params, st.cov, t_quantile(&st.df)),
        Err(_) => {
            // No interval yet: the estimate alone.
            let mut p = vec![0.0; np];
            if id.params_into(&mut p).is_err() {
                return;
            }
            (p, vec![0.0; np * np], f64::NAN)
        }
    };
    for (c, o) in out.iter_mut().enumerate().take(ph.constant_names().len()) {
        *o = match (ph.known(c), ph.constant(c, &theta, &cov)) {
            (Some(v), _) => [v; 3],
            (None, Ok((v, se))) if v.is_finite() && v > 0.0 => [v, v - q * se, v + q * se],
            _ => NAN3,
        };
    }
}

/// What the report says about how a curve's constants were obtained.
fn method(ident: &Ident, car: &Car) -> String {
    let map = match car {
        Car::Quarter(_) => "QuarterCar::from_theta (m known)",
        Car::Half(_) => "HalfCar::from_theta (m1, m2 and B known)",
    };
    match ident {
        Ident::Physical => "the physical structure's parameters k2/M, b/M, M, k1 (m known); 95 % interval by the \
                            delta method on their covariance (PhysicalStructure::constant)"
            .to_string(),
        Ident::Kalman { .. } => {
            format!("{map} on the estimated rows; 95 % interval by the delta method on the filter's covariance s²P")
        }
        Ident::Gradient { .. } => {
            format!("{map} on the estimated rows; no interval (the gradient keeps no covariance)")
        }
        Ident::TwoAxle { .. } => {
            format!("{map} on the estimated rows; no interval (the two-axle identifier reports no covariance)")
        }
        Ident::BatchLs => format!("{map} on the estimated rows"),
    }
}

/// The iterations of the figure's grid `k` where the constants are recorded, as indices into
/// `k`: [`CONSTANT_POINTS`]` / 2` targets evenly spaced on a log axis and as many on a linear
/// one, each the first grid point at or after its target, the last point always included.
pub(crate) fn constants_grid(k: &[u64]) -> Vec<usize> {
    let (Some(&first), Some(&last)) = (k.first(), k.last()) else { return vec![] };
    let (first, last) = (first.max(1) as f64, last.max(1) as f64);
    let half = CONSTANT_POINTS / 2;
    let mut idx = vec![];
    for j in 0..half {
        let f = j as f64 / (half - 1) as f64;
        for target in [first * (last / first).powf(f), first + (last - first) * f] {
            idx.push(k.partition_point(|&x| (x as f64) < target - 1e-9).min(k.len() - 1));
        }
    }
    idx.push(k.len() - 1);
    idx.sort_unstable();
    idx.dedup();
    idx
}

/// The constants of one job, recorded on the decimated grid.
pub(crate) struct Recorder {
    car: Car,
    seed: u64,
    method: String,
    /// The iterations to record, increasing.
    at: Vec<u64>,
    /// Per recorded iteration, every constant (model order).
    points: Vec<Vec<Estimate>>,
}

impl Recorder {
    /// A recorder for a job of `ident` on `car` with grid `grid` and simulator seed `seed`.
    pub(crate) fn new(car: Car, ident: &Ident, grid: &[u64], seed: u64) -> Self {
        let at = constants_grid(grid).into_iter().map(|i| grid[i]).collect::<Vec<_>>();
        Self { car, seed, method: method(ident, &car), points: Vec::with_capacity(at.len()), at }
    }

    /// Whether iteration `k` is recorded (called with increasing `k`).
    pub(crate) fn wants(&self, k: u64) -> bool {
        self.at.get(self.points.len()) == Some(&k)
    }

    /// Records the estimate of the next iteration: `f` fills every constant (model order).
    pub(crate) fn record(&mut self, f: impl FnOnce(&Car, &mut [Estimate])) {
        let mut p = vec![NAN3; self.car.names().len()];
        f(&self.car, &mut p);
        self.points.push(p);
    }

    /// The report's form: known constants apart, one series per identified constant.
    pub(crate) fn finish(self) -> IdentifiedConstants {
        let truth = self.car.truth();
        let (mut known, mut constants) = (vec![], vec![]);
        for (c, &name) in self.car.names().iter().enumerate() {
            let unit = Car::unit(name);
            if self.car.known(name) {
                known.push(KnownConstant { name, unit, value: truth[c] });
                continue;
            }
            let col = |i: usize| self.points.iter().map(|p| p[c][i]).collect::<Vec<f64>>();
            constants.push(ConstantSeries { name, unit, truth: truth[c], value: col(0), lo: col(1), hi: col(2) });
        }
        let k = self.at[..self.points.len()].to_vec();
        IdentifiedConstants { seed: self.seed, method: self.method, k, known, constants }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn grid_is_decimated_increasing_and_ends_at_the_last_iteration() {
        let k: Vec<u64> = (1..=50).chain((1..=200).map(|i| i * 50)).filter(|&x| x <= 10_000).collect();
        let idx = constants_grid(&k);
        assert!(idx.len() <= CONSTANT_POINTS + 1 && idx.len() >= CONSTANT_POINTS / 2, "{}", idx.len());
        assert!(idx.windows(2).all(|w| w[0] < w[1]));
        assert_eq!(idx.first(), Some(&0));
        assert_eq!(idx.last(), Some(&(k.len() - 1)));
        assert!(constants_grid(&[]).is_empty());
        assert_eq!(constants_grid(&[7]), vec![0]);
    }

    #[test]
    fn exact_rows_give_the_true_constants() {
        for car in [Car::Quarter(QuarterCar::thesis()), Car::Half(HalfCar::thesis())] {
            let theta: Vec<f64> = match car {
                Car::Quarter(c) => c.theta().transpose().as_slice().to_vec(),
                Car::Half(c) => c.theta().transpose().as_slice().to_vec(),
            };
            let mut v = vec![0.0; car.names().len()];
            car.constants_of(&theta, &mut v).unwrap();
            for (a, b) in v.iter().zip(car.truth()) {
                assert!((a - b).abs() <= 1e-9 * b.abs(), "{a} vs {b}");
            }
            // A diagonal covariance: the delta method's standard errors are finite and > 0
            // for the identified constants, 0 for the known ones.
            let np = theta.len();
            let mut cov = vec![0.0; np * np];
            for j in 0..np {
                cov[j * np + j] = 1e-4;
            }
            let se = delta_se(&car, &theta, &cov, &v);
            for (c, name) in car.names().iter().enumerate() {
                if car.known(name) {
                    assert!(se[c].abs() < 1e-9, "{name}: {}", se[c]);
                } else {
                    assert!(se[c].is_finite() && se[c] > 0.0, "{name}: {}", se[c]);
                }
            }
        }
    }

    #[test]
    fn units_name_every_constant() {
        for car in [Car::Quarter(QuarterCar::thesis()), Car::Half(HalfCar::thesis())] {
            assert!(car.names().iter().all(|n| !Car::unit(n).is_empty()));
        }
    }
}
