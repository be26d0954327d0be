//! A fixed number of updates of one key identifier on seeded data, for instruction counting
//! under callgrind (`benches/callgrind_check.py`, `make bench-check`).
//!
//! Run: `cargo run -q --release -p vehid-benches --bin count_updates -- BENCH N`
//! with `BENCH` one of the names printed by `count_updates --list`. The input (4096 seeded
//! samples of the thesis quarter or half car, the same settings as the criterion benches) is
//! generated whatever `N` is, so the instructions of `N` updates are the count with `N` minus
//! the count with `N = 0`. The bench's state is printed at the end so that nothing is
//! optimized away.

use std::hint::black_box;
use std::process::ExitCode;
use vehid_core::identify::{
    BiasCompensatedLs, CovarianceForm, EkfNoise, Gain, Identifier, IvIdentifier, JointEkf, KalmanIdentifier,
    KalmanIdentifierVec, KalmanIdentifierVec2, KalmanOptions, NoiseEstimatingBclsLs, Refresh, Screened,
    SharedKalmanIdentifier, StochasticGradient, StructuredGradient, StructuredKalman, StructuredPrior,
    TwoAxleStructuredConfig, TwoAxleStructuredKalman,
};
use vehid_core::model::{HalfCar, LinearModel, QuarterCar};
use vehid_core::nalgebra::SVector;
use vehid_core::sim::{Method, RoadConfig, RoadSimulator, SimConfig, Simulator};
use vehid_core::structure::Structure;

const LEN: usize = 4096;

/// The benches: name and what one update is.
const BENCHES: [(&str, &str); 25] = [
    ("quarter_rows", "KalmanIdentifier<f64, 4, 2> (rows) update"),
    ("half_rows", "KalmanIdentifier<f64, 8, 4> (rows) update"),
    ("quarter_rows_sqrt", "KalmanIdentifier<f64, 4, 2> square-root form update"),
    ("half_rows_sqrt", "KalmanIdentifier<f64, 8, 4> square-root form update"),
    ("quarter_rows_forget", "KalmanIdentifier<f64, 4, 2> with forgetting 0.999 update"),
    ("half_rows_forget", "KalmanIdentifier<f64, 8, 4> with forgetting 0.999 update"),
    ("quarter_rows_exact", "KalmanIdentifier<f64, 4, 2> after an exact start, update"),
    ("half_rows_exact", "KalmanIdentifier<f64, 8, 4> after an exact start, update"),
    (
        "quarter_rows_vec",
        "KalmanIdentifierVec2<f64, 4> (rows, heap, two lanes: Python's quarter car) Identifier::update_into (slices)",
    ),
    ("half_rows_vec", "KalmanIdentifierVec<f64, 8> (rows, heap: Python's half car) Identifier::update_into (slices)"),
    ("quarter_shared", "SharedKalmanIdentifier<f64, 4, 2> update"),
    ("half_shared", "SharedKalmanIdentifier<f64, 8, 4> update"),
    ("quarter_sg_venter", "StochasticGradient<f64, 4, 2> (Venter, p = 0.51) update"),
    ("quarter_sim_exact", "Simulator<f64, 4, 1> (exact discretization) next_sample"),
    ("quarter_structured_rows", "StructuredKalman<f64, 4, 2> on the full-row structure (8 parameters) update_into"),
    ("quarter_structured_physical", "StructuredKalman<f64, 2, 2> on the physical structure, m known, update_into"),
    ("quarter_structured_sg", "StructuredGradient<f64, 8> (Venter, p = 0.51) on the full-row structure update_into"),
    ("quarter_iv_rows", "IvIdentifier<f64, 4, 2> (delay 1) on the full-row structure update_into"),
    ("quarter_iv_physical", "IvIdentifier<f64, 2, 2> (delay 1, exact start) on the physical structure update_into"),
    ("quarter_bcls_rows", "BiasCompensatedLs<f64, 4, 2> on the full-row structure update_into"),
    ("quarter_bcls_screened", "Screened(BiasCompensatedLs<f64, 4, 2>, gate 6, refresh as the samples grow by a quarter, as Python builds it) update_into"),
    ("quarter_ekf_physical", "JointEkf<f64, 4, 9> (physical structure, m known, 5 RK4 sub-steps) update_into"),
    ("quarter_nebcls_rows", "NoiseEstimatingBclsLs<f64, 4, 2> (delayed IV inside, full rows) update_into"),
    (
        "half_two_axle_physical",
        "TwoAxleStructuredKalman<f64, 4, 3, 16> (half car, one road, 12 parameters) update_into",
    ),
    (
        "msd_iv_model",
        "ModelIvIdentifier<f64, 3, 1> (instruments from the auxiliary model, 1 RK4 step, refresh 100) on the \
         mass-spring-damper update_into",
    ),
];

type Data<const N: usize> = Vec<(SVector<f64, N>, SVector<f64, N>)>;

fn samples<const N: usize, const M: usize>(model: LinearModel<f64, N, M>) -> vehid_core::Result<Data<N>> {
    let cfg = SimConfig::new(0.05).road_sigma(0.1).ic_sigma(0.1).deriv_noise(0.005);
    let mut sim = Simulator::new(model, cfg, 42)?;
    Ok((0..LEN).map(|_| sim.next_sample()).map(|s| (s.r, s.z)).collect())
}

/// The online-form variants of the rows identifier (square-root form, forgetting, exact
/// start), by bench name suffix.
fn variant<const N: usize, const K: usize>(
    bench: &str,
    rows: &[usize],
    r: &[f64],
) -> vehid_core::Result<KalmanIdentifier<f64, N, K>> {
    let opts = match bench.rsplit('_').next() {
        Some("sqrt") => KalmanOptions { form: CovarianceForm::Sqrt, ..KalmanOptions::default() },
        Some("forget") => KalmanOptions { forgetting: 0.999, ..KalmanOptions::default() },
        _ => KalmanOptions::default(),
    };
    if bench.ends_with("_exact") {
        KalmanIdentifier::exact(rows, r, opts)
    } else {
        KalmanIdentifier::from_slices(rows, &[1000.0], r, opts)
    }
}

/// Runs `n` updates cycling through `data`; returns a checksum of the results.
fn cycle<const N: usize, O>(
    data: &Data<N>,
    n: usize,
    mut update: impl FnMut(&SVector<f64, N>, &SVector<f64, N>) -> O,
) -> usize {
    let mut done = 0usize;
    for k in 0..n {
        let (x, z) = &data[k & (LEN - 1)];
        black_box(update(black_box(x), black_box(z)));
        done += 1;
    }
    done
}

fn run(bench: &str, n: usize) -> vehid_core::Result<String> {
    let q = QuarterCar::<f64>::thesis();
    let h = HalfCar::<f64>::thesis();
    Ok(match bench {
        "quarter_rows" => {
            let data = samples(q.model())?;
            let r: [f64; 2] = q.model().row_noise_var(0.1, 0.005)?;
            let mut id = KalmanIdentifier::<f64, 4, 2>::new(q.unknown_rows(), 1000.0, r)?;
            cycle(&data, n, |x, z| id.update(x, z).is_ok());
            format!("{:?}", id.theta())
        }
        "half_rows" => {
            let data = samples(h.model())?;
            let r: [f64; 4] = h.model().row_noise_var(0.1, 0.005)?;
            let mut id = KalmanIdentifier::<f64, 8, 4>::new(h.unknown_rows(), 1000.0, r)?;
            cycle(&data, n, |x, z| id.update(x, z).is_ok());
            format!("{:?}", id.theta())
        }
        "quarter_rows_sqrt" | "quarter_rows_forget" | "quarter_rows_exact" => {
            let data = samples(q.model())?;
            let r: [f64; 2] = q.model().row_noise_var(0.1, 0.005)?;
            let mut id = variant::<4, 2>(bench, &q.unknown_rows(), &r)?;
            cycle(&data, n, |x, z| id.update(x, z).is_ok());
            format!("{:?}", id.theta())
        }
        "half_rows_sqrt" | "half_rows_forget" | "half_rows_exact" => {
            let data = samples(h.model())?;
            let r: [f64; 4] = h.model().row_noise_var(0.1, 0.005)?;
            let mut id = variant::<8, 4>(bench, &h.unknown_rows(), &r)?;
            cycle(&data, n, |x, z| id.update(x, z).is_ok());
            format!("{:?}", id.theta())
        }
        "quarter_rows_vec" => {
            let data = samples(q.model())?;
            let r: [f64; 2] = q.model().row_noise_var(0.1, 0.005)?;
            let mut id = KalmanIdentifierVec2::<f64, 4>::from_slices(
                &q.unknown_rows(),
                &[1000.0],
                &r,
                KalmanOptions::default(),
            )?;
            let mut e = [0.0; 2];
            cycle(&data, n, |x, z| id.update_into(x.as_slice(), z.as_slice(), &[], &mut e).is_ok());
            format!("{:?}", id.theta_row(0))
        }
        "half_rows_vec" => {
            let data = samples(h.model())?;
            let r: [f64; 4] = h.model().row_noise_var(0.1, 0.005)?;
            let mut id =
                KalmanIdentifierVec::<f64, 8>::from_slices(&h.unknown_rows(), &[1000.0], &r, KalmanOptions::default())?;
            let mut e = [0.0; 4];
            cycle(&data, n, |x, z| id.update_into(x.as_slice(), z.as_slice(), &[], &mut e).is_ok());
            format!("{:?}", id.theta_row(0))
        }
        "quarter_shared" => {
            let data = samples(q.model())?;
            let mut id = SharedKalmanIdentifier::<f64, 4, 2>::new(q.unknown_rows(), 1000.0, [1.0; 2])?;
            cycle(&data, n, |x, z| id.update(x, z).is_ok());
            format!("{:?}", id.theta())
        }
        "half_shared" => {
            let data = samples(h.model())?;
            let mut id = SharedKalmanIdentifier::<f64, 8, 4>::new(h.unknown_rows(), 1000.0, [1.0; 4])?;
            cycle(&data, n, |x, z| id.update(x, z).is_ok());
            format!("{:?}", id.theta())
        }
        "quarter_sg_venter" => {
            let data = samples(q.model())?;
            let mut id = StochasticGradient::<f64, 4, 2>::new(q.unknown_rows(), Gain::Venter { p: 0.51 }, 0.4)?;
            cycle(&data, n, |x, z| id.update(x, z).is_ok());
            format!("{:?}", id.theta())
        }
        "quarter_sim_exact" => sim_exact(n)?,
        "quarter_structured_rows"
        | "quarter_structured_physical"
        | "quarter_structured_sg"
        | "quarter_iv_rows"
        | "quarter_iv_physical"
        | "quarter_bcls_rows"
        | "quarter_bcls_screened"
        | "quarter_ekf_physical"
        | "quarter_nebcls_rows" => structured(bench, n)?,
        "half_two_axle_physical" => two_axle_physical(n)?,
        "msd_iv_model" => msd_iv_model(n)?,
        _ => unreachable!("main checks the name against BENCHES"),
    })
}

/// The simulator bench, a function of its own (as [`structured`]).
#[inline(never)]
fn sim_exact(n: usize) -> vehid_core::Result<String> {
    let q = QuarterCar::<f64>::thesis();
    // Same settings as the criterion bench simulate_f64/quarter/exact; the data set is
    // generated anyway so that the N = 0 run has the same setup.
    let _data = black_box(samples(q.model())?);
    let mut cfg = SimConfig::<f64, 4, 1>::new(0.05).road_sigma(0.1).deriv_noise(0.005);
    cfg.method = Method::Exact;
    let mut sim = Simulator::new(q.model(), cfg, 1)?;
    let mut last = SVector::<f64, 4>::zeros();
    for _ in 0..n {
        last = black_box(sim.next_sample()).r;
    }
    Ok(format!("{last:?}"))
}

/// The identifiers on a [`Structure`] (Kalman, gradient, IV, bias-compensated, joint EKF), a
/// function of their own so that their code does not change how the other benches' loops are
/// compiled in [`run`] (with them inlined there, quarter_sim_exact grew from 605 to 676
/// instructions per sample).
#[inline(never)]
fn structured(bench: &str, n: usize) -> vehid_core::Result<String> {
    let q = QuarterCar::<f64>::thesis();
    // The same settings as the criterion benches update_f64/quarter/structured_* and
    // iv_* / bcls_rows (benches/benches/identify.rs).
    let data = samples(q.model())?;
    let r: [f64; 2] = q.model().row_noise_var(0.1, 0.005)?;
    let full = Structure::<f64>::full_rows(4, &q.unknown_rows())?;
    let physical = *QuarterCar::<f64>::structure([None, Some(1.0), None, None, None])?.structure();
    let mut id: Box<dyn Identifier<f64>> = match bench {
        "quarter_structured_rows" => Box::new(StructuredKalman::<f64, 4, 2>::new(
            full,
            StructuredPrior::Scalar(1000.0),
            None,
            &r,
            KalmanOptions::default(),
        )?),
        "quarter_structured_physical" => Box::new(StructuredKalman::<f64, 2, 2>::new(
            physical,
            StructuredPrior::Scalar(1000.0),
            None,
            &[1.0],
            KalmanOptions::default(),
        )?),
        "quarter_structured_sg" => {
            Box::new(StructuredGradient::<f64, 8>::new(full, Gain::Venter { p: 0.51 }, &[0.4], None, 1)?)
        }
        "quarter_iv_rows" => Box::new(IvIdentifier::<f64, 4, 2>::full_rows(
            4,
            &q.unknown_rows(),
            1,
            StructuredPrior::Scalar(1000.0),
            &[1.0],
        )?),
        "quarter_iv_physical" => Box::new(IvIdentifier::<f64, 2, 2>::exact(physical, 1)?),
        "quarter_bcls_rows" => Box::new(BiasCompensatedLs::<f64, 4, 2>::full_rows(4, &q.unknown_rows(), &[6.4e-5])?),
        "quarter_bcls_screened" => Box::new(Screened::new(
            BiasCompensatedLs::<f64, 4, 2>::full_rows(4, &q.unknown_rows(), &[6.4e-5])?,
            full,
            6.0,
            Refresh::Geometric,
        )?),
        "quarter_nebcls_rows" => Box::new(NoiseEstimatingBclsLs::<f64, 4, 2>::full_rows(4, &q.unknown_rows(), 1, 0)?),
        _ => Box::new(ekf_physical(&q)?),
    };
    let mut e = [0.0; 2];
    cycle(&data, n, |x, z| id.update_into(x.as_slice(), z.as_slice(), &[], &mut e).is_ok());
    // The estimate may not exist yet (the exact start before enough samples, or the
    // bias compensation on data without state noise): then the error is the state.
    let mut theta = [0.0; 8];
    let np = id.dims().params;
    Ok(match id.params_into(&mut theta[..np]) {
        Ok(()) => format!("{:?}", &theta[..np]),
        Err(e) => format!("({e})"),
    })
}

/// Instruments from the auxiliary model (SRIVC/RIVC) on the mass-spring-damper rig with a
/// measured force, as the criterion bench update_f64/msd/iv_model: exact start, delay 1, one
/// RK4 step per sample, refresh every 100 samples (stability test included).
#[inline(never)]
fn msd_iv_model(n: usize) -> vehid_core::Result<String> {
    let (s, data) = vehid_benches::msd_rig(LEN);
    let mut id = IvIdentifier::<f64, 3, 1>::exact(s, 1)?.with_model_instruments(0.01, 1, 100, None)?;
    let mut e = [0.0];
    // Past the exact start and the first refresh, so that the model's instruments run.
    for (x, z, u) in &data[..400] {
        id.update_into(x, z, u, &mut e)?;
    }
    let mut k = 400;
    for _ in 0..n {
        let (x, z, u) = &data[k];
        black_box(id.update_into(x, z, u, &mut e).is_ok());
        k = if k + 1 == LEN { 400 } else { k + 1 };
    }
    let mut theta = [0.0; 3];
    id.params_into(&mut theta)?;
    Ok(format!("{theta:?} adopted {}", id.adopted()))
}

/// The joint EKF on the quarter car's physical structure (m known) as the criterion bench
/// update_f64/quarter/ekf_physical builds it: a prior 10 % off the truth with a standard
/// deviation of half the guess, Σ_w for 8 % state noise, the simulator's 5 RK4 sub-steps.
fn ekf_physical(q: &QuarterCar<f64>) -> vehid_core::Result<JointEkf<f64, 4, 9>> {
    let ps = QuarterCar::<f64>::structure([None, Some(1.0), None, None, None])?;
    let mut guess = [0.0; 4];
    ps.params_of(&q.constants(), &mut guess)?;
    guess.iter_mut().for_each(|g| *g *= 1.1);
    let var = guess.map(|g| 0.25 * g * g);
    let b = SVector::<f64, 4>::from_column_slice(q.model().b().as_slice());
    JointEkf::new(*ps.structure(), &guess, &var, 1.0, EkfNoise::from_sigmas(0.008, 0.005, b, 0.1), 0.05, 5)
}

/// Road cancellation on the half car's physical structure, as the criterion bench
/// update_f64/half/two_axle_physical: the thesis' half car sampled every 0.3 m at 6 m/s, the
/// rear axle 10 samples behind, m1, m2, l1, l2 known (12 parameters), the exact start.
#[inline(never)]
fn two_axle_physical(n: usize) -> vehid_core::Result<String> {
    let car = HalfCar::<f64>::thesis();
    let cfg = SimConfig::new(0.05).road_sigma(0.1).deriv_noise(0.005);
    let mut sim = RoadSimulator::<f64, 8, 16>::new(car.model(), cfg, RoadConfig::new(0.3, car.wheelbase()), 42)?;
    let data = (0..LEN).map(|_| sim.next_sample(6.0).map(|s| (s.r, s.z))).collect::<vehid_core::Result<Data<8>>>()?;
    let c = car.constants();
    let mut known = [None; 12];
    for i in 8..12 {
        known[i] = Some(c[i]);
    }
    let ps = HalfCar::structure(known)?;
    let mut id = TwoAxleStructuredKalman::<f64, 4, 3, 16>::new(
        *ps.structure(),
        &car.model(),
        10,
        TwoAxleStructuredConfig::new(0.1, 0.005),
    )?;
    let mut e = [0.0; 4];
    cycle(&data, n, |x, z| id.update_into(x.as_slice(), z.as_slice(), &[], &mut e).is_ok());
    let mut rows = [0.0; 32];
    Ok(match id.a_rows_into(&mut rows) {
        Ok(()) => format!("{rows:?}"),
        Err(e) => format!("({e})"),
    })
}

fn main() -> ExitCode {
    let args: Vec<String> = std::env::args().skip(1).collect();
    if args.first().map(String::as_str) == Some("--list") {
        for (name, what) in BENCHES {
            println!("{name}\t{what}");
        }
        return ExitCode::SUCCESS;
    }
    let (bench, n) = match (args.first(), args.get(1).map(|s| s.parse::<usize>())) {
        (Some(b), Some(Ok(n))) if args.len() == 2 => (b.clone(), n),
        _ => {
            eprintln!("usage: count_updates BENCH N   (or --list)");
            return ExitCode::from(2);
        }
    };
    if !BENCHES.iter().any(|(name, _)| *name == bench) {
        eprintln!("count_updates: unknown bench {bench:?} (see --list)");
        return ExitCode::from(2);
    }
    match run(&bench, n) {
        Ok(state) => {
            println!("{bench} {n} {state}");
            ExitCode::SUCCESS
        }
        Err(e) => {
            eprintln!("count_updates: {e}");
            ExitCode::from(2)
        }
    }
}
