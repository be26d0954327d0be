//! One job: one curve of one figure over one seed, simulated and identified sample by
//! sample, ξ recorded on the grid.

use super::constants::{rows_constants, Car, Recorder};
use super::ident::{make_ident, OnFailure};
use crate::figures::{Curve, Experiment, Ident, ModelKind, DT, PULSE_AMPLITUDE, PULSE_START};
use crate::report::IdentifiedConstants;
use vehid_core::identify::{TwoAxleConfig, TwoAxleIdentifier};
use vehid_core::metrics::xi;
use vehid_core::model::{HalfCar, LinearModel, QuarterCar};
use vehid_core::nalgebra::{SMatrix, SVector};
use vehid_core::sim::{Pulse, RoadConfig, RoadMode, RoadSimulator, SimConfig, Simulator};

/// ξ of one job on the recording grid, the Eq 4.36 reinitializations it made, and the
/// physical constants if the job recorded them.
pub(crate) struct Trace {
    pub(crate) xi: Vec<f64>,
    pub(crate) reinits: u32,
    pub(crate) constants: Option<IdentifiedConstants>,
}

/// Whether a job of `curve` records the car's constants when asked to: every identifier but
/// batch least squares (Ch. III's figures, which show ξ only).
fn records_constants(curve: &Curve) -> bool {
    !matches!(curve.ident, Ident::BatchLs)
}

fn run_job<const N: usize, const M: usize, const K: usize>(
    model: LinearModel<f64, N, M>,
    truth: SMatrix<f64, K, N>,
    curve: &Curve,
    road: [f64; M],
    grid: &[u64],
    seed: u64,
    mut rec: Option<Recorder>,
) -> crate::Result<Trace> {
    let mut cfg = SimConfig::<f64, N, M>::new(DT).ic_sigma(curve.ic).state_noise(curve.state).deriv_noise(curve.deriv);
    cfg.road_sigma = SVector::from(road);
    if curve.pulse_width > 0 {
        cfg = cfg.with_pulse(Pulse { start: PULSE_START, width: curve.pulse_width, amplitude: PULSE_AMPLITUDE })?;
    }
    let (mut ident, on_failure) = make_ident::<N, M, K>(&model, curve, &road)?;
    let mut failed = false;
    let mut e = [0.0; K];
    let mut sim = Simulator::new(model, cfg, seed)?;
    let t = truth.transpose();
    let truth_flat = t.as_slice();
    let mut th = vec![0.0; K * N];
    let mut out = Vec::with_capacity(grid.len());
    let n = grid.last().copied().unwrap_or(0);
    let mut next = 0;
    for k in 1..=n {
        let mut s = sim.next_sample();
        if curve.pulse_width > 0 && s.k == PULSE_START {
            // The pulse switches on just after this measurement: the sample instant sees the
            // input before the switch, so a one-cycle pulse is never measured in z (the
            // thesis' "width less than one measurement cycle": no input–output correlation)
            // and a w-cycle pulse is seen at w − 1 instants.
            let b = *sim.model().b();
            s.z -= b * SVector::<f64, M>::repeat(PULSE_AMPLITUDE);
        }
        // An update that would overflow is rejected (the identifier unchanged); the job stops
        // updating then, and ξ reports the estimate or, for a diverged one, infinity.
        if !failed && ident.update_into(s.r.as_slice(), s.z.as_slice(), &[], &mut e).is_err() {
            failed = true;
        }
        if grid.get(next) == Some(&k) {
            next += 1;
            let v = if failed && on_failure == OnFailure::Diverged {
                f64::INFINITY
            } else if ident.params_into(&mut th).is_ok() {
                xi(truth_flat, &th).unwrap_or(f64::NAN)
            } else {
                f64::NAN // least squares before the data span every direction
            };
            out.push(v);
        }
        if let Some(r) = rec.as_mut().filter(|r| r.wants(k)) {
            let diverged = failed && on_failure == OnFailure::Diverged;
            // A diverged estimate has no constants (ξ is infinite there).
            r.record(|car, est| {
                if !diverged {
                    ident.constants_into(car, est)
                }
            });
        }
    }
    Ok(Trace { xi: out, reinits: ident.reinit_count(), constants: rec.map(Recorder::finish) })
}

fn half_road(kind: ModelKind, road: f64) -> [f64; 2] {
    match kind {
        ModelKind::HalfIndependent => [road, road],
        _ => [road, 0.0],
    }
}

/// One job: `curve` of `exp` on simulator seed `seed`, ξ on `grid`; with `constants` (and an
/// identifier other than batch least squares) also the car's physical constants on a
/// decimated grid (the `constants` module).
pub(super) fn simulate(
    exp: &Experiment,
    curve: &Curve,
    grid: &[u64],
    seed: u64,
    constants: bool,
) -> crate::Result<Trace> {
    let rec = |car: Car| (constants && records_constants(curve)).then(|| Recorder::new(car, &curve.ident, grid, seed));
    match exp.model {
        ModelKind::Quarter => {
            let car = QuarterCar::<f64>::thesis();
            let rec = rec(Car::Quarter(car));
            run_job::<4, 1, 2>(car.model(), car.theta(), curve, [curve.road], grid, seed, rec)
        }
        ModelKind::HalfFront | ModelKind::HalfIndependent => {
            let car = HalfCar::<f64>::thesis();
            let rec = rec(Car::Half(car));
            run_job::<8, 2, 4>(car.model(), car.theta(), curve, half_road(exp.model, curve.road), grid, seed, rec)
        }
        ModelKind::HalfOneRoad => run_one_road(exp, curve, grid, seed, rec(Car::Half(HalfCar::thesis()))),
    }
}

/// Samples per wheelbase on one road (wheelbase 3 m, a sample every 0.3 m).
const ROAD_DELAY: usize = 10;
/// Speed on one road, m/s (0.3 m per 0.05 s).
const ROAD_SPEED: f64 = 6.0;

/// The half car on one road (Fig 6-8, 6-9): road-by-distance simulation, two-axle identifier.
fn run_one_road(
    exp: &Experiment,
    curve: &Curve,
    grid: &[u64],
    seed: u64,
    mut rec: Option<Recorder>,
) -> crate::Result<Trace> {
    let Ident::TwoAxle { method, p0_wheel, p0_body } = curve.ident else {
        return Err(crate::Error::InvalidArgument { arg: "ident", expected: "the two-axle identifier on one road" });
    };
    let car = HalfCar::<f64>::thesis();
    let model = car.model();
    let mode = if curve.label.starts_with("independent") { RoadMode::Independent } else { RoadMode::White };
    let cfg = SimConfig::<f64, 8, 2>::new(DT)
        .ic_sigma(curve.ic)
        .road_sigma(curve.road)
        .state_noise(curve.state)
        .deriv_noise(curve.deriv);
    let spacing = ROAD_SPEED * DT;
    let road = RoadConfig::new(spacing, spacing * ROAD_DELAY as f64).mode(mode);
    let mut sim = RoadSimulator::<f64, 8, 16>::new(model.clone(), cfg, road, seed)?;
    let mut idc = TwoAxleConfig::new(method, p0_wheel, curve.road, curve.deriv);
    idc.p0_body = p0_body;
    let mut id = TwoAxleIdentifier::<f64, 8, 16, 2, 16>::new(&model, ROAD_DELAY, idc)?;
    let truth = car.theta().transpose();
    let mut out = Vec::with_capacity(grid.len());
    let n = grid.last().copied().unwrap_or(0);
    let mut next = 0;
    let _ = exp;
    for k in 1..=n {
        let s = sim.next_sample(ROAD_SPEED)?;
        let _ = id.update(&s.r, &s.z);
        if grid.get(next) == Some(&k) {
            next += 1;
            let v = match id.theta::<4>() {
                Ok(th) => xi(truth.as_slice(), th.transpose().as_slice()).unwrap_or(f64::NAN),
                Err(_) => f64::NAN,
            };
            out.push(v);
        }
        if let Some(r) = rec.as_mut().filter(|r| r.wants(k)) {
            r.record(|car, est| rows_constants(&id, car, est));
        }
    }
    Ok(Trace { xi: out, reinits: 0, constants: rec.map(Recorder::finish) })
}
