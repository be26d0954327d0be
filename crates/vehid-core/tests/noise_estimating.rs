//! Bias-compensated least squares with the state-noise variances estimated from the data:
//! `NoiseEstimatingBcls` on the quarter car in the setting of
//! `noisy_states.rs` (rows 1 and 3, white road σ_u 0.1, dt 0.05 s, derivative noise σ_v 0.1,
//! white state noise σ_w a percentage of σ_u on every state).
//!
//! Seeds 500–509 were used while developing (choosing the fit's weighting, trying iteration);
//! the must-show figures use seeds 2000–2011, run once. The fast tests use seeds 60–69.

use vehid_core::identify::{
    BiasCompensatedLs, Identifier, IvIdentifier, KalmanIdentifier, NoiseEstimatingBcls, NoiseEstimatingBclsLs,
    StructuredPrior,
};
use vehid_core::model::QuarterCar;
use vehid_core::Error;

use crate::common;
use common::{
    close, feed, median, params, physical, quarter, time_updates, xi_physical, xi_rows, DERIV, LAGS, Q, ROAD,
};

/// Estimated σ_w per state (NaN where not estimated).
fn sigmas<F, FI, const P: usize, const QQ: usize>(id: &NoiseEstimatingBcls<f64, P, F, FI, QQ>) -> [f64; 4]
where
    F: vehid_core::identify::Flat<vehid_core::identify::BcGroup<f64, P>>,
    FI: vehid_core::identify::Flat<vehid_core::identify::IvFilter<f64, P>>,
{
    let mut v = [0.0; 4];
    id.state_noise_var_into(&mut v).unwrap();
    v.map(f64::sqrt)
}

fn rows_ne(lags: usize) -> NoiseEstimatingBclsLs<f64, 4, 2, Q> {
    NoiseEstimatingBclsLs::<f64, 4, 2, Q>::full_rows(4, &[1, 3], 1, lags).unwrap()
}

fn physical_ne(lags: usize) -> NoiseEstimatingBclsLs<f64, 2, 2, Q> {
    let iv = IvIdentifier::<f64, 2, 2, Q>::exact(*physical().structure(), 1).unwrap().with_lags(lags).unwrap();
    NoiseEstimatingBclsLs::new(iv, &[DERIV * DERIV]).unwrap()
}

fn rows_kalman(x: &[f64], z: &[f64]) -> f64 {
    let r = QuarterCar::<f64>::thesis().model().row_noise_var::<2>(ROAD, DERIV).unwrap();
    let mut id = KalmanIdentifier::<f64, 4, 2>::new([1, 3], 1000.0, r).unwrap();
    feed(&mut id, x, z);
    xi_rows(&params(&id))
}

fn rows_bcls(x: &[f64], z: &[f64], pct: f64) -> f64 {
    let var = (pct / 100.0 * ROAD).powi(2);
    let mut id = BiasCompensatedLs::<f64, 4, 2>::full_rows(4, &[1, 3], &[var]).unwrap();
    feed(&mut id, x, z);
    xi_rows(&params(&id))
}

fn physical_bcls(x: &[f64], z: &[f64], pct: f64) -> f64 {
    let var = (pct / 100.0 * ROAD).powi(2);
    let mut id =
        BiasCompensatedLs::<f64, 2, 2>::new(*physical().structure(), &[var], &[DERIV * DERIV], &[1.0]).unwrap();
    feed(&mut id, x, z);
    xi_physical(&params(&id))
}

fn worst(v: &[f64]) -> f64 {
    v.iter().fold(0.0f64, |a, &b| a.max(if b.is_nan() { f64::INFINITY } else { b }))
}

/// Named lists of values, in insertion order.
#[derive(Default)]
struct Table(Vec<(String, Vec<f64>)>);

impl Table {
    fn add(&mut self, name: String, v: f64) {
        match self.0.iter_mut().find(|e| e.0 == name) {
            Some(e) => e.1.push(v),
            None => self.0.push((name, vec![v])),
        }
    }
    fn get(&self, name: &str) -> &[f64] {
        &self.0.iter().find(|e| e.0 == name).unwrap().1
    }
    fn print(&self) {
        for (name, v) in &self.0 {
            let bad = v.iter().filter(|x| !x.is_finite()).count();
            eprintln!("| {name} | {:.4} | {:.4} | {bad}/{} |", median(v), worst(v), v.len());
        }
    }
}

/// Every method of the comparison on `seeds` at `pcts` (40,000 samples): ξ of the rows (full
/// rows and physical structure) and the relative error of each estimated σ_w.
fn compare(seeds: impl Iterator<Item = u64> + Clone, pcts: &[f64], physical_too: bool) -> Table {
    let mut t = Table::default();
    for &pct in pcts {
        let truth = pct / 100.0 * ROAD;
        for seed in seeds.clone() {
            let (x, z) = quarter(40_000, pct, seed);
            for (lags, kind) in [(0, "delayed"), (LAGS, "refined")] {
                let mut id = rows_ne(lags);
                feed(&mut id, &x, &z);
                t.add(format!("{pct} % rows NE-BCLS ({kind} IV inside)"), xi_rows(&params(&id)));
                t.add(format!("{pct} % rows IV {kind}"), xi_rows(&params(id.instrumental())));
                let s = sigmas(&id);
                for (j, sj) in s.iter().enumerate() {
                    t.add(format!("{pct} % rows σ̂_{j} rel. error ({kind})"), (sj / truth - 1.0).abs());
                }
            }
            t.add(format!("{pct} % rows BCLS (Σ_w known)"), rows_bcls(&x, &z, pct));
            t.add(format!("{pct} % rows Kalman (thesis)"), rows_kalman(&x, &z));
            if physical_too {
                for (lags, kind) in [(0, "delayed"), (LAGS, "refined")] {
                    let mut id = physical_ne(lags);
                    feed(&mut id, &x, &z);
                    t.add(format!("{pct} % physical NE-BCLS ({kind} IV inside)"), xi_physical(&params(&id)));
                    t.add(format!("{pct} % physical IV {kind}"), xi_physical(&params(id.instrumental())));
                    let mut v = [0.0; 4];
                    id.state_noise_var_into(&mut v).unwrap();
                    let t2 = truth * truth;
                    t.add(format!("{pct} % physical σ̂_0 rel. error ({kind})"), (v[0].sqrt() / truth - 1.0).abs());
                    t.add(format!("{pct} % physical σ̂_2 rel. error ({kind})"), (v[2].sqrt() / truth - 1.0).abs());
                    t.add(
                        format!("{pct} % physical √((σ̂_1²+σ̂_3²)/2) rel. error ({kind})"),
                        (((v[1] + v[3]) / 2.0).sqrt() / t2.sqrt() - 1.0).abs(),
                    );
                }
                t.add(format!("{pct} % physical BCLS (Σ_w, Σ_v known)"), physical_bcls(&x, &z, pct));
            }
        }
    }
    t
}

/// Development comparison (seeds 500–509; `VEHID_PCTS`, e.g. `2,8,32`, default 8).
///
/// Run: `cargo test -p vehid-core --release --test integration -- --ignored --nocapture noise_estimating::dev_compare`
#[test]
#[ignore]
fn dev_compare() {
    let pcts: Vec<f64> = std::env::var("VEHID_PCTS")
        .ok()
        .map(|v| v.split(',').map(|p| p.parse().unwrap()).collect())
        .unwrap_or(vec![8.0]);
    compare(500..510, &pcts, true).print();
}

/// At 8 % state noise (seeds 60–62, 40,000 samples, refined instruments inside): every
/// state's σ̂_w within 10 % of the truth on the full rows (development seeds: worst 4.5 %),
/// the physical structure's within 15 % for the positions and 10 % for the velocities'
/// combination √((σ̂_1² + σ̂_3²)/2) (the only one it determines; development worst 6.6 %,
/// 2.0 %); ξ of the full rows ≤ 0.3 and of the physical structure ≤ 0.005 (development
/// median 0.099 and 0.0002), both far below least squares (the thesis' Kalman rows, ξ > 4).
#[test]
fn estimates_sigma_w_at_8_percent() {
    let truth = 0.08 * ROAD;
    for seed in 60..63 {
        let (x, z) = quarter(40_000, 8.0, seed);
        let mut rows = rows_ne(LAGS);
        feed(&mut rows, &x, &z);
        let s = sigmas(&rows);
        let (xr, kalman) = (xi_rows(&params(&rows)), rows_kalman(&x, &z));
        eprintln!("seed {seed}: σ̂/σ {:.4?}, ξ {xr:.4}, Kalman ξ {kalman:.3}", s.map(|v| v / truth));
        for (j, v) in s.iter().enumerate() {
            assert!((v / truth - 1.0).abs() < 0.10, "seed {seed}: σ̂_{j} = {v} against {truth}");
        }
        assert!(xr <= 0.3 && kalman > 4.0, "seed {seed}: ξ {xr}, Kalman {kalman}");
        let mut phys = physical_ne(LAGS);
        feed(&mut phys, &x, &z);
        let mut v = [0.0; 4];
        phys.state_noise_var_into(&mut v).unwrap();
        let (p0, p2, pv) = (v[0].sqrt() / truth, v[2].sqrt() / truth, ((v[1] + v[3]) / 2.0).sqrt() / truth);
        let xp = xi_physical(&params(&phys));
        eprintln!("seed {seed}: physical σ̂/σ {p0:.4} {p2:.4} {pv:.4}, ξ {xp:.5}");
        assert!((p0 - 1.0).abs() < 0.15 && (p2 - 1.0).abs() < 0.15 && (pv - 1.0).abs() < 0.10, "seed {seed}");
        assert!(xp <= 0.005, "seed {seed}: physical ξ {xp}");
    }
}

/// Two-sided: with no state noise the estimated σ̂_w is near 0 (below 2 % of σ_u on every
/// state, a quarter of the 8 % that `estimates_sigma_w_at_8_percent` finds; measured at most
/// 0.8 %: a variance estimated near 0 scatters like the square root of its noise) and the
/// compensated estimate stays as good as least squares on clean data (ξ ≤ 0.1; development
/// median 0.015).
#[test]
fn no_state_noise_gives_sigma_near_zero() {
    for seed in 63..65 {
        let (x, z) = quarter(40_000, 0.0, seed);
        let mut id = rows_ne(LAGS);
        feed(&mut id, &x, &z);
        let s = sigmas(&id);
        let xr = xi_rows(&params(&id));
        eprintln!("seed {seed}: σ̂/σ_u {:.5?}, ξ {xr:.4}", s.map(|v| v / ROAD));
        assert!(s.iter().all(|&v| v < 0.02 * ROAD), "seed {seed}: σ̂ {s:?}");
        assert!(xr <= 0.1, "seed {seed}: ξ {xr}");
    }
}

/// Transactional: a NaN sample, and a value the instruments' ring refuses after the
/// least-squares sums took it (the rollback path), return errors and change nothing: the
/// identifier then continues bit for bit as a twin that never saw them.
#[test]
fn rejected_samples_change_nothing() {
    let (x, z) = quarter(1_000, 8.0, 66);
    let mut id = rows_ne(1);
    let mut e = [0.0; 2];
    feed(&mut id, &x[..2000], &z[..2000]);
    let mut twin = id.clone();
    let err = id.update_into(&[0.1, f64::NAN, 0.0, 0.0], &z[..4], &[], &mut e).unwrap_err();
    assert!(matches!(err, Error::NonFinite { arg: "r_k", index: 1 }), "{err:?}");
    let big = f64::MAX.sqrt();
    let err = id.update_into(&x[..4], &[0.0, big, 0.0, 0.0], &[], &mut e).unwrap_err();
    assert!(matches!(err, Error::InvalidArgument { arg: "z_k", .. }), "{err:?}");
    assert!(matches!(id.update_into(&x[..3], &z[..4], &[], &mut e), Err(Error::Shape { arg: "r_k", .. })));
    assert_eq!(id.samples(), 500);
    feed(&mut id, &x[2000..], &z[2000..]);
    feed(&mut twin, &x[2000..], &z[2000..]);
    let bits = |v: Vec<f64>| v.into_iter().map(f64::to_bits).collect::<Vec<_>>();
    assert_eq!(bits(params(&id)), bits(params(&twin)));
    assert_eq!(sigmas(&id).map(f64::to_bits), sigmas(&twin).map(f64::to_bits));
    assert_eq!(id.samples(), 1_000);
}

/// Bad arguments are typed errors naming the argument.
#[test]
fn bad_arguments_are_typed_errors() {
    use vehid_core::structure::{Basis, Structure, Term, Var};
    // An IV identifier that has seen a sample.
    let mut iv = IvIdentifier::<f64, 4, 2>::full_rows(4, &[1, 3], 1, StructuredPrior::Exact, &[1.0]).unwrap();
    iv.update_into(&[0.1; 4], &[0.2; 4], &[], &mut [0.0; 2]).unwrap();
    assert!(matches!(NoiseEstimatingBclsLs::new(iv, &[]), Err(Error::InvalidArgument { arg: "iv", .. })));
    let fresh = || IvIdentifier::<f64, 2, 2>::exact(*physical().structure(), 1).unwrap();
    assert!(matches!(
        NoiseEstimatingBclsLs::new(fresh(), &[0.1, 0.2]),
        Err(Error::Shape { arg: "deriv_noise_var", .. })
    ));
    assert!(matches!(
        NoiseEstimatingBclsLs::new(fresh(), &[-0.01]),
        Err(Error::InvalidArgument { arg: "deriv_noise_var", .. })
    ));
    assert!(matches!(
        NoiseEstimatingBclsLs::new(fresh(), &[f64::NAN]),
        Err(Error::NonFinite { arg: "deriv_noise_var", .. })
    ));
    // Refined instruments beyond the predictor's capacity; delay 0.
    assert!(matches!(
        NoiseEstimatingBclsLs::<f64, 4, 2, 9>::full_rows(4, &[1, 3], 1, 2),
        Err(Error::Capacity { arg: "lags", .. })
    ));
    assert!(matches!(
        NoiseEstimatingBclsLs::<f64, 4, 2>::full_rows(4, &[1, 3], 0, 0),
        Err(Error::InvalidArgument { arg: "delay", .. })
    ));
    // A sign term of a state: its noise bias depends on the unknown true state.
    let mut s = Structure::<f64>::new(1, 0, 1).unwrap();
    let (start, len) = s.push_combination(&[(Var::State(0), 1.0)]).unwrap();
    s.push_equation(0, &[Term { coef: 1.0, param: Some(0), basis: Basis::Sign { start, len } }]).unwrap();
    let iv = IvIdentifier::<f64, 1, 1>::exact(s, 1).unwrap();
    assert!(matches!(NoiseEstimatingBclsLs::new(iv, &[]), Err(Error::Unsupported { .. })));
    // Reading: before any sample, wrong lengths.
    let id = rows_ne(0);
    assert!(matches!(id.params_into(&mut [0.0; 8]), Err(Error::RankDeficient { .. })));
    assert!(matches!(id.state_noise_var_into(&mut [0.0; 4]), Err(Error::RankDeficient { .. })));
    assert!(matches!(id.params_into(&mut [0.0; 7]), Err(Error::Shape { arg: "out", .. })));
    assert!(matches!(id.state_noise_var_into(&mut [0.0; 3]), Err(Error::Shape { arg: "out", .. })));
    assert!(matches!(id.covariance_into(&mut [0.0; 64]), Err(Error::Unsupported { .. })));
}

/// A state that no parameterized term reads is not estimated (NaN), the others are; f32
/// runs the same code (full rows, refined instruments of one lag: with six, the predictor of
/// 49 regressors in single precision makes an IV step singular on this seed, which the
/// identifier refuses).
#[test]
fn unread_states_are_nan_and_f32_works() {
    use vehid_core::structure::{Basis, Structure, Term, Var};
    // v̇w = a zw + b vw only: zb, vb are read by no term.
    let mut s = Structure::<f32>::new(4, 0, 2).unwrap();
    let t = |p, j| Term { coef: 1.0, param: Some(p), basis: Basis::Var(Var::State(j)) };
    s.push_equation(1, &[t(0, 0), t(1, 1)]).unwrap();
    let iv = IvIdentifier::<f32, 2, 1>::exact(s, 1).unwrap();
    let mut id = NoiseEstimatingBclsLs::new(iv, &[]).unwrap();
    assert!(id.estimates_state(0) && id.estimates_state(1) && !id.estimates_state(2) && !id.estimates_state(3));
    assert!(!id.estimates_state(4));
    let (x, z) = quarter(20_000, 8.0, 67);
    let mut id32 = NoiseEstimatingBclsLs::<f32, 4, 2, Q>::full_rows(4, &[1, 3], 1, 1).unwrap();
    let mut e = [0.0f32; 2];
    for (xk, zk) in x.chunks(4).zip(z.chunks(4)) {
        let (xf, zf): (Vec<f32>, Vec<f32>) =
            (xk.iter().map(|&v| v as f32).collect(), zk.iter().map(|&v| v as f32).collect());
        id32.update_into(&xf, &zf, &[], &mut e).unwrap();
        id.update_into(&xf, &zf, &[], &mut e[..1]).unwrap();
    }
    let mut w = [0.0f32; 4];
    id.state_noise_var_into(&mut w).unwrap();
    assert!(w[0] >= 0.0 && w[1] >= 0.0 && w[2].is_nan() && w[3].is_nan(), "{w:?}");
    let mut v = [0.0f32; 4];
    id32.state_noise_var_into(&mut v).unwrap();
    let mut th = [0.0f32; 8];
    id32.params_into(&mut th).unwrap();
    let th64: Vec<f64> = th.iter().map(|&v| v as f64).collect();
    eprintln!("f32: σ̂/σ {:?}, ξ {}", v.map(|v| v.sqrt() / 0.008), xi_rows(&th64));
    assert!(v.iter().all(|v| (v.sqrt() / 0.008 - 1.0).abs() < 0.2), "{v:?}");
    assert!(xi_rows(&th64) < 0.5);
}

/// A saved identifier (serde, postcard) continues bit for bit; one whose parts disagree is
/// refused.
#[test]
fn a_saved_identifier_continues_bit_for_bit() {
    let (x, z) = quarter(2_000, 8.0, 68);
    let mut id = rows_ne(LAGS);
    feed(&mut id, &x[..4000], &z[..4000]);
    let bytes = postcard::to_allocvec(&id).unwrap();
    let mut back: NoiseEstimatingBclsLs<f64, 4, 2, Q> = postcard::from_bytes(&bytes).unwrap();
    feed(&mut id, &x[4000..], &z[4000..]);
    feed(&mut back, &x[4000..], &z[4000..]);
    let bits = |v: Vec<f64>| v.into_iter().map(f64::to_bits).collect::<Vec<_>>();
    assert_eq!(bits(params(&id)), bits(params(&back)));
    // The sums of one identifier with the instruments of another that saw more samples.
    let json = serde_json::to_value(&id).unwrap();
    let mut other = rows_ne(LAGS);
    feed(&mut other, &x[..400], &z[..400]);
    let mut mixed = json.clone();
    mixed["bc"] = serde_json::to_value(&other).unwrap()["bc"].clone();
    let err = serde_json::from_value::<NoiseEstimatingBclsLs<f64, 4, 2, Q>>(mixed).unwrap_err();
    assert!(err.to_string().contains("share structure and samples"), "{err}");
}

/// Must-show: seeds 2000–2011 (not used while developing), 40,000
/// samples, σ_w 2, 8, 32 % of σ_u on every state; "NE-BCLS" = this identifier, its
/// instruments refined (6 lags) unless said. Measured (release; median / worst over 12):
///
/// | σ_w | σ̂_w rel. error per state zw, vw, zb, vb (full rows, median) | ξ rows NE-BCLS | BCLS Σ_w known | IV refined | Kalman | ξ physical NE-BCLS | BCLS known | IV refined |
/// |---|---|---|---|---|---|---|---|---|
/// | 2 % | 3.0, 9.6, 1.3, 3.1 % | 0.036 / 0.28 | 0.042 / 0.24 | 0.022 / 0.14 | 0.89 / 1.28 | 0.0002 / 0.0007 | 0.0002 / 0.0007 | 0.0002 / 0.0006 |
/// | 8 % | 0.55, 1.1, 0.44, 0.65 % | 0.090 / 1.27 | 0.19 / 1.30 | 0.018 / 0.14 | 4.87 / 5.36 | 0.0002 / 0.0007 | 0.0002 / 0.0012 | 0.0002 / 0.0007 |
/// | 32 % | 0.50, 0.40, 0.16, 0.34 % | 3.47 / inf (1/12 Singular) | 2.66 / 583 | 0.16 / 1.63 | 5.81 / 5.97 | 0.0007 / 0.0027 | 0.0021 / 0.023 | 0.0007 / 0.0028 |
///
/// With the delayed-regressor instruments inside, the full rows' σ̂ of the wheel velocity is
/// clamped at 0 on most seeds (median relative error 100 % at 8 %) and ξ is 0.70 / 25 at
/// 8 %; on the physical structure it does well (ξ 0.0004 / 0.0014 at 8 %, 0.0026 / 0.94 at
/// 32 %, against IV delayed 0.0025 / 0.017 and 0.0050 / 0.025).
///
/// Run: `cargo test -p vehid-core --release --test integration -- --ignored --nocapture noise_estimating::must_show`
#[test]
#[ignore]
fn must_show_sigma_w_and_xi() {
    let t = compare(2000..2012, &[2.0, 8.0, 32.0], true);
    eprintln!("| what | median | worst | no estimate (ξ inf: Singular) |\n|---|---|---|---|");
    t.print();
    for pct in [2.0, 8.0, 32.0] {
        for j in 0..4 {
            let v = t.get(&format!("{pct} % rows σ̂_{j} rel. error (refined)"));
            let limit = if pct == 2.0 { 0.3 } else { 0.1 };
            assert!(median(v) < limit, "{pct} % σ̂_{j}: median relative error {}", median(v));
        }
    }
}

/// Wall-clock ns per update (release, indicative).
///
/// Run: `cargo test -p vehid-core --release --test integration -- --ignored --nocapture noise_estimating::timing`
#[test]
#[ignore]
fn timing() {
    use std::time::Instant;
    let (x, z) = quarter(4096, 8.0, 1);
    let reps = 50;
    let time = |name: &str, id: &mut dyn Identifier<f64>| time_updates(name, id, &x, &z, reps);
    let read = |name: &str, id: &dyn Identifier<f64>| {
        let mut th = vec![0.0; id.dims().params];
        let t = Instant::now();
        for _ in 0..1000 {
            let _ = std::hint::black_box(id.params_into(&mut th));
        }
        eprintln!("{name}: {:.0} ns/read", t.elapsed().as_nanos() as f64 / 1000.0);
    };
    let mut bc = BiasCompensatedLs::<f64, 4, 2>::full_rows(4, &[1, 3], &[6.4e-5]).unwrap();
    time("bcls rows (Σ_w known)", &mut bc);
    read("bcls rows (Σ_w known)", &bc);
    let mut iv = IvIdentifier::<f64, 4, 2>::full_rows(4, &[1, 3], 1, StructuredPrior::Exact, &[1.0]).unwrap();
    time("iv rows delayed", &mut iv);
    let mut ne = rows_ne(0);
    time("NE-BCLS rows, delayed IV inside", &mut ne);
    read("NE-BCLS rows, delayed IV inside", &ne);
    let mut ne = rows_ne(LAGS);
    time("NE-BCLS rows, refined IV inside", &mut ne);
    read("NE-BCLS rows, refined IV inside", &ne);
    let mut ne = physical_ne(LAGS);
    time("NE-BCLS physical, refined IV inside", &mut ne);
    read("NE-BCLS physical, refined IV inside", &ne);
}

/// The estimate is bias-compensated least squares at the estimated variances (its docs:
/// `θ̂ = (A − N C(Σ̂))⁻¹ (b − N d(Σ̂))`): fed the same samples, `BiasCompensatedLs` built
/// with `Σ_w = Σ̂_w` (read back) and the same `Σ_v` gives the same parameters to rounding.
/// On the velocity row with a known term beside `x₂`'s parameter (`c x₂ + 2 x₂`: `c` is
/// `A₁₂ − 2`), so that the output `y = ẋ₁ − 2 x₂` carries the noise of a regressor whose
/// variance is estimated and its correction `d(Σ̂)` is not 0 (the physical structure and the
/// full rows have none: `d = 0` there), and on the full rows.
#[test]
fn the_estimate_is_bcls_at_the_estimated_variances() {
    use vehid_core::structure::StructureBuilder;
    let (x, z) = quarter(3_000, 8.0, 69);
    let (st, _) = StructureBuilder::new(&["x0", "x1", "x2", "x3"], &[])
        .equation("x1", "a*x0 + b*x1 + c*x2 + d*x3 + 2*x2")
        .build::<f64>()
        .unwrap();
    let iv = IvIdentifier::<f64, 4, 1, Q>::exact(st, 1).unwrap().with_lags(LAGS).unwrap();
    let mut known = NoiseEstimatingBclsLs::new(iv, &[DERIV * DERIV]).unwrap();
    feed(&mut known, &x, &z);
    let mut v = [0.0; 4];
    known.state_noise_var_into(&mut v).unwrap();
    assert!(v[2] > 0.0, "{v:?}");
    let mut bc = BiasCompensatedLs::<f64, 4, 1>::new(st, &v, &[DERIV * DERIV], &[1.0]).unwrap();
    feed(&mut bc, &x, &z);
    close("known 2·x₂ term", "θ against BCLS", &params(&known), &params(&bc), 1e-9);
    // x₂'s noise matters here: compensated without it, the estimate moves far beyond rounding.
    let mut plain =
        BiasCompensatedLs::<f64, 4, 1>::new(st, &[v[0], v[1], 0.0, v[3]], &[DERIV * DERIV], &[1.0]).unwrap();
    feed(&mut plain, &x, &z);
    let gap = params(&plain).iter().zip(params(&bc)).fold(0.0f64, |m, (p, q)| m.max((p - q).abs()));
    assert!(gap > 1e-6 * params(&bc).iter().fold(0.0f64, |m, q| m.max(q.abs())), "{gap}");
    let mut rows = rows_ne(LAGS);
    feed(&mut rows, &x, &z);
    rows.state_noise_var_into(&mut v).unwrap();
    let mut bc = BiasCompensatedLs::<f64, 4, 2>::full_rows(4, &[1, 3], &v).unwrap();
    feed(&mut bc, &x, &z);
    close("full rows", "θ against BCLS", &params(&rows), &params(&bc), 1e-9);
}
