//! Round trips: every identifier, in every form and store, serialized after `N` samples and
//! deserialized continues bit for bit with the original for `M` more; corrupt input is an
//! error, never a panic (also after loading).

use crate::identify::*;
use crate::model::{HalfCar, LinearModel, QuarterCar, RowSet};
use crate::sim::{RoadConfig, RoadSimulator, SimConfig, Simulator};
use nalgebra::{SMatrix, SVector};
use serde::de::DeserializeOwned;
use serde::Serialize;

type V4 = SVector<f64, 4>;
type V8 = SVector<f64, 8>;

fn quarter(n: usize) -> Vec<(V4, V4)> {
    let cfg = SimConfig::new(0.05).road_sigma(0.1).ic_sigma(0.1).deriv_noise(0.005);
    let mut sim = Simulator::new(QuarterCar::thesis().model(), cfg, 7).unwrap();
    (0..n).map(|_| sim.next_sample()).map(|s| (s.r, s.z)).collect()
}

/// Half-car samples taken every 0.3 m at 6 m/s on one road (d = 10).
fn half_road(n: usize) -> Vec<(V8, V8)> {
    let car = HalfCar::<f64>::thesis();
    let cfg = SimConfig::new(0.05).road_sigma(0.1).ic_sigma(0.1).deriv_noise(0.005);
    let mut sim = RoadSimulator::<f64, 8, 16>::new(car.model(), cfg, RoadConfig::new(0.3, car.wheelbase()), 3).unwrap();
    (0..n).map(|_| sim.next_sample(6.0).unwrap()).map(|s| (s.r, s.z)).collect()
}

fn to_bytes<I: Serialize>(id: &I) -> Vec<u8> {
    postcard::to_allocvec(id).unwrap()
}

/// Bits of a reported quantity, or why there is none.
type Bits = Result<Vec<u64>, crate::Error>;

/// Everything an identifier reports, as bits (`Err` where it has no such quantity yet).
fn report<I: Identifier<f64>>(id: &I) -> (Bits, Bits, Vec<u64>) {
    let d = id.dims();
    let bits = |v: Vec<f64>| v.into_iter().map(f64::to_bits).collect::<Vec<_>>();
    let mut th = vec![0.0; d.params];
    let th = id.params_into(&mut th).map(|()| bits(th));
    let mut p = vec![0.0; d.params * d.params];
    let p = id.covariance_into(&mut p).map(|()| bits(p));
    let counters =
        vec![id.samples(), u64::from(id.reinit_count()), id.trace().map_or(0, f64::to_bits), d.params as u64];
    (th, p, counters)
}

/// Runs `data[..split]`, restores a copy through postcard, runs the rest on both, comparing
/// innovations and reports after every sample and the serialized states at the end.
fn continues<I>(mut id: I, data: &[(&[f64], &[f64])], split: usize) -> I
where
    I: Identifier<f64> + Serialize + DeserializeOwned,
{
    let k = id.dims().equations;
    let (mut e1, mut e2) = (vec![0.0; k], vec![0.0; k]);
    for (x, z) in &data[..split] {
        id.update_into(x, z, &[], &mut e1).unwrap();
    }
    let bytes = to_bytes(&id);
    let mut back: I = postcard::from_bytes(&bytes).unwrap();
    assert_eq!(to_bytes(&back), bytes, "serialize ∘ deserialize is the identity");
    assert_eq!(report(&back), report(&id));
    for (x, z) in &data[split..] {
        let a = id.update_into(x, z, &[], &mut e1);
        let b = back.update_into(x, z, &[], &mut e2);
        assert_eq!(a, b);
        assert_eq!(
            e1.iter().map(|v| v.to_bits()).collect::<Vec<_>>(),
            e2.iter().map(|v| v.to_bits()).collect::<Vec<_>>()
        );
        assert_eq!(report(&back), report(&id));
    }
    assert_eq!(to_bytes(&back), to_bytes(&id), "the same state after the continuation");
    id
}

fn slices<const N: usize>(data: &[(SVector<f64, N>, SVector<f64, N>)]) -> Vec<(&[f64], &[f64])> {
    data.iter().map(|(x, z)| (x.as_slice(), z.as_slice())).collect()
}

const R_Q: [f64; 2] = [81.0, 2.5e-5];

fn opts(form: CovarianceForm) -> KalmanOptions<f64> {
    KalmanOptions { form, ..KalmanOptions::default() }
}

#[test]
fn kalman_rows_every_form_and_store() {
    let data = quarter(400);
    let d = slices(&data);
    for form in [CovarianceForm::Standard, CovarianceForm::Joseph, CovarianceForm::Sqrt] {
        let o = opts(form);
        continues(KalmanIdentifier::<f64, 4, 2>::from_slices(&[1, 3], &[1000.0], &R_Q, o).unwrap(), &d, 150);
        continues(KalmanIdentifierVec2::<f64, 4>::from_slices(&[1, 3], &[1000.0], &R_Q, o).unwrap(), &d, 150);
        continues(KalmanIdentifierVec::<f64, 4>::from_slices(&[3, 1], &[1000.0], &R_Q, o).unwrap(), &d, 150);
        // Reinitialization (Eq 4.36) and retirement.
        let o = KalmanOptions { reinit: true, retire_below: 1e-9, ..o };
        continues(KalmanIdentifier::<f64, 4, 2>::from_slices(&[1, 3], &[1.0], &R_Q, o).unwrap(), &d, 20);
    }
}

#[test]
fn kalman_rows_exact_start_before_and_after_it_ends() {
    let data = quarter(300);
    let d = slices(&data);
    for form in [CovarianceForm::Standard, CovarianceForm::Sqrt] {
        let o = opts(form);
        for split in [2, 100] {
            let id = KalmanIdentifier::<f64, 4, 2>::exact(&[1, 3], &R_Q, o).unwrap();
            let id = continues(id, &d, split);
            assert!(!id.starting());
            let id = KalmanIdentifierVec2::<f64, 4>::exact(&[1, 3], &R_Q, o).unwrap();
            continues(id, &d, split);
        }
    }
    // Still starting when saved: the restored one is still starting too.
    let mut id = KalmanIdentifier::<f64, 4, 2>::exact(&[1, 3], &R_Q, KalmanOptions::default()).unwrap();
    id.update(&data[0].0, &data[0].1).unwrap();
    let back: KalmanIdentifier<f64, 4, 2> = postcard::from_bytes(&to_bytes(&id)).unwrap();
    assert!(back.starting() && id.starting());
}

#[test]
fn kalman_rows_tracking() {
    let data = quarter(400);
    let d = slices(&data);
    for form in [CovarianceForm::Standard, CovarianceForm::Joseph, CovarianceForm::Sqrt] {
        for directional in [false, true] {
            let o = KalmanOptions { form, forgetting: 0.98, directional, drift: 1e-6, ..KalmanOptions::default() };
            continues(KalmanIdentifier::<f64, 4, 2>::from_slices(&[1, 3], &[1000.0], &R_Q, o).unwrap(), &d, 200);
            continues(KalmanIdentifierVec::<f64, 4>::exact(&[1, 3], &R_Q, o).unwrap(), &d, 200);
        }
    }
}

#[test]
fn kalman_rows_outlier_gate_and_huber() {
    // Outliers after the gate's warm-up (N + 50 samples), split before and after the first.
    let mut data = quarter(400);
    for k in [120, 260, 261, 330] {
        data[k].1[1] += 1e3;
        data[k].1[3] -= 50.0;
    }
    let d = slices(&data);
    for form in [CovarianceForm::Standard, CovarianceForm::Joseph, CovarianceForm::Sqrt] {
        for (gate, huber) in [(6.0, 0.0), (0.0, 1.345), (6.0, 1.345)] {
            let o = KalmanOptions { form, gate, huber, ..KalmanOptions::default() };
            for split in [100, 200] {
                let id = continues(
                    KalmanIdentifier::<f64, 4, 2>::from_slices(&[1, 3], &[1000.0], &R_Q, o).unwrap(),
                    &d,
                    split,
                );
                if gate > 0.0 {
                    assert!((0..2).any(|i| id.filter(i).gated() > 0), "the gate acted");
                }
                continues(KalmanIdentifierVec::<f64, 4>::exact(&[1, 3], &R_Q, o).unwrap(), &d, split);
            }
        }
    }
}

#[test]
fn kalman_rows_several_groups_and_f32() {
    // Six rows of the half car: Fixed<6> in one group, Dynamic<2> in three (with scratch).
    let data = half_road(600);
    let d = slices(&data);
    let rows = [0, 1, 3, 5, 6, 7];
    let r = [0.01, 100.0, 100.0, 2.5e-3, 0.02, 2.5e-3];
    let o = KalmanOptions::default();
    continues(KalmanIdentifier::<f64, 8, 6>::from_slices(&rows, &[1000.0], &r, o).unwrap(), &d, 250);
    continues(KalmanIdentifierVec2::<f64, 8>::from_slices(&rows, &[1000.0], &r, o).unwrap(), &d, 250);
    continues(KalmanIdentifierVec::<f64, 8>::from_slices(&rows, &[1000.0], &r, o).unwrap(), &d, 250);
    // The square-root form plans several groups through its own scratch.
    let o = opts(CovarianceForm::Sqrt);
    continues(KalmanIdentifierVec2::<f64, 8>::from_slices(&rows, &[1000.0], &r, o).unwrap(), &d, 250);
    continues(KalmanIdentifierVec2::<f64, 8>::exact(&rows, &r, o).unwrap(), &d, 250);
    // f32: the same continuation, read through the fixed-size API.
    let mut a = KalmanIdentifier::<f32, 4, 2>::new([1, 3], 1000.0, [81.0, 2.5e-5]).unwrap();
    let q: Vec<_> = quarter(200).iter().map(|(x, z)| (x.cast::<f32>(), z.cast::<f32>())).collect();
    for (x, z) in &q[..100] {
        a.update(x, z).unwrap();
    }
    let mut b: KalmanIdentifier<f32, 4, 2> = postcard::from_bytes(&to_bytes(&a)).unwrap();
    for (x, z) in &q[100..] {
        assert_eq!(a.update(x, z).unwrap(), b.update(x, z).unwrap());
    }
    assert_eq!(a.theta(), b.theta());
    assert!((0..2).all(|i| a.filter(i) == b.filter(i)));
}

#[test]
fn kalman_shared_and_full() {
    let data = quarter(400);
    let d = slices(&data);
    for form in [CovarianceForm::Standard, CovarianceForm::Joseph] {
        for reinit in [false, true] {
            let o = KalmanOptions { form, reinit, ..KalmanOptions::default() };
            let r = [2.5e-5, 2.5e-5];
            continues(SharedKalmanIdentifier::<f64, 4, 2>::from_slices(&[1, 3], &[1000.0], &r, o).unwrap(), &d, 150);
            continues(SharedKalmanIdentifierVec::<f64, 4>::from_slices(&[1, 3], &[1000.0], &r, o).unwrap(), &d, 150);
        }
    }
    let r = [81.0, 0.01, 0.01, 2.5e-5];
    for reinit in [false, true] {
        let o = KalmanOptions { reinit, ..KalmanOptions::default() };
        continues(FullKalmanIdentifier::<f64, 4, 2>::from_slices(&[1, 3], &[1000.0], &r, o).unwrap(), &d, 150);
        continues(FullKalmanIdentifierVec::<f64, 4>::from_slices(&[1, 3], &[1000.0], &r, o).unwrap(), &d, 150);
    }
}

#[test]
fn gradient_accumulator_and_batch() {
    let data = quarter(400);
    let d = slices(&data);
    let gains = [Gain::Venter { p: 0.51 }, Gain::Lyapunov, Gain::Ljung { lambda0: 0.99, lambda_init: 0.95 }];
    for gain in gains {
        for spacing in [1, 3] {
            let h = [0.4, 0.4, 0.4, 0.4, 0.04, 0.04, 0.04, 0.04];
            let id = StochasticGradient::<f64, 4, 2>::from_slices(&[1, 3], gain, &h, &[1e-4], spacing).unwrap();
            continues(id, &d, 151);
            let id = StochasticGradientVec::<f64, 4>::from_slices(&[1, 3], gain, &h, &[1e-4], spacing).unwrap();
            continues(id, &d, 151);
        }
    }
    continues(LsAccumulator::<f64, 4, Fixed<2>>::from_rows(&[1, 3]).unwrap(), &d, 150);
    continues(LsAccumulator::<f64, 4, Dynamic>::from_rows(&[1, 3]).unwrap(), &d, 150);
    continues(BatchLeastSquares::<f64, 4>::new(&[1, 3]).unwrap(), &d, 150);
}

#[test]
fn two_axle_with_its_ring() {
    let car = HalfCar::<f64>::thesis();
    let data = half_road(500);
    let d = slices(&data);
    for method in [WheelMethod::None, WheelMethod::Thesis, WheelMethod::Cancel] {
        let cfg = TwoAxleConfig::new(method, 1000.0, 0.1, 0.005);
        for split in [5, 200] {
            // Split inside the first d = 10 samples (ring partly filled) and after.
            let id = TwoAxleIdentifier::<f64, 8, 16, 2, 16>::new(&car.model(), 10, cfg).unwrap();
            let id = continues(id, &d, split);
            assert!(id.paired() > 0);
            let id = TwoAxleIdentifierVec::<f64, 8, 16>::new(&car.model(), 10, cfg).unwrap();
            continues(id, &d, split);
        }
    }
}

/// The half car's physical structure on one road (road cancellation), in the fixed store with a
/// parameter capacity `P` equal to its largest group's (4) and above it (6), and in the heap
/// store, split inside the first `d = 10` samples and after.
#[test]
fn two_axle_structured_with_its_ring() {
    let car = HalfCar::<f64>::thesis();
    let data = half_road(500);
    let d = slices(&data);
    let c = car.constants();
    let mut known = [None; 12];
    for i in 8..12 {
        known[i] = Some(c[i]);
    }
    let st = *HalfCar::structure(known).unwrap().structure();
    let cfg = TwoAxleStructuredConfig::new(0.1, 0.005);
    for split in [5, 200] {
        continues(TwoAxleStructuredKalman::<f64, 4, 3, 16>::new(st, &car.model(), 10, cfg).unwrap(), &d, split);
        continues(TwoAxleStructuredKalman::<f64, 6, 3, 16>::new(st, &car.model(), 10, cfg).unwrap(), &d, split);
        continues(TwoAxleStructuredVec::<f64, 4>::new(st, &car.model(), 10, cfg).unwrap(), &d, split);
    }
}

#[test]
fn options_models_and_sets_round_trip() {
    let model = HalfCar::<f64>::thesis().model();
    let back: LinearModel<f64, 8, 2> = postcard::from_bytes(&to_bytes(&model)).unwrap();
    assert_eq!(back, model);
    let rows = RowSet::<8>::new(&[7, 1, 3]).unwrap();
    assert_eq!(postcard::from_bytes::<RowSet<8>>(&to_bytes(&rows)).unwrap(), rows);
    let o = KalmanOptions { form: CovarianceForm::Sqrt, forgetting: 0.99, ..KalmanOptions::<f64>::default() };
    assert_eq!(postcard::from_bytes::<KalmanOptions<f64>>(&to_bytes(&o)).unwrap(), o);
    let spec = KalmanSpec { rows: vec![1, 3], p0: Prior::Exact, theta0: None, r: vec![1.0], mode: Mode::Rows, opts: o };
    assert_eq!(postcard::from_bytes::<KalmanSpec<f64>>(&to_bytes(&spec)).unwrap(), spec);
    // A self-describing format names the choices.
    let json = serde_json::to_string(&(CovarianceForm::Sqrt, GainKind::Ljung, WheelMethod::Cancel)).unwrap();
    assert_eq!(json, r#"["Sqrt","Ljung","Cancel"]"#);
}

#[test]
fn json_round_trip_of_a_fixed_identifier() {
    // A self-describing format (maps, fixed arrays as arrays) works too (to the precision of
    // serde_json's float parsing, which is bit-exact only with its `float_roundtrip` feature).
    let data = quarter(100);
    let mut id = KalmanIdentifier::<f64, 4, 2>::new([1, 3], 1000.0, R_Q).unwrap();
    for (x, z) in &data[..50] {
        id.update(x, z).unwrap();
    }
    let text = serde_json::to_string(&id).unwrap();
    let mut back: KalmanIdentifier<f64, 4, 2> = serde_json::from_str(&text).unwrap();
    for (x, z) in &data[50..] {
        id.update(x, z).unwrap();
        back.update(x, z).unwrap();
    }
    let (a, b) = (id.theta(), back.theta());
    assert!((a - b).abs().max() <= 1e-12 * a.abs().max(), "{a} {b}");
}

/// Deserializing `value` as `I` is an error mentioning `needle`.
fn rejects<I: DeserializeOwned>(value: &serde_json::Value, needle: &str) {
    match serde_json::from_value::<I>(value.clone()) {
        Ok(_) => panic!("accepted a corrupt {needle}"),
        Err(e) => assert!(e.to_string().contains(needle), "{e}"),
    }
}

#[test]
fn inconsistent_input_is_an_error() {
    use serde_json::json;
    let id = KalmanIdentifierVec2::<f64, 8>::from_slices(&[0, 1, 3, 5, 6], &[1000.0], &[1.0], KalmanOptions::default())
        .unwrap();
    let good = serde_json::to_value(&id).unwrap();
    type Rows = KalmanIdentifierVec2<f64, 8>;
    let with = |path: &[&str], v: serde_json::Value| {
        let mut out = good.clone();
        let mut at = &mut out;
        for p in &path[..path.len() - 1] {
            at = if let Ok(i) = p.parse::<usize>() { &mut at[i] } else { &mut at[*p] };
        }
        at[path[path.len() - 1]] = v;
        out
    };
    rejects::<Rows>(&with(&["rows"], json!([0, 1, 3, 5, 5])), "unknown_rows");
    rejects::<Rows>(&with(&["rows"], json!([0, 1, 3, 5, 9])), "unknown_rows");
    rejects::<Rows>(&with(&["rows"], json!([0, 1, 3, 5])), "not a valid KalmanRows");
    rejects::<Rows>(&with(&["groups", "0", "used"], json!(3)), "capacity");
    rejects::<Rows>(&with(&["groups", "2", "used"], json!(2)), "not a valid KalmanRows");
    rejects::<Rows>(&with(&["groups", "1", "zrow"], json!([5, 3])), "not a valid KalmanRows");
    rejects::<Rows>(&with(&["opts", "forgetting"], json!(1.5)), "forgetting");
    let mut short = good.clone();
    short["groups"].as_array_mut().unwrap().pop();
    rejects::<Rows>(&short, "groups");

    let full = FullKalmanIdentifierVec::<f64, 4>::from_slices(&[1, 3], &[1.0], &[1.0], KalmanOptions::default());
    let mut v = serde_json::to_value(full.unwrap()).unwrap();
    v["p"].as_array_mut().unwrap().pop();
    rejects::<FullKalmanIdentifierVec<f64, 4>>(&v, "`p`");

    let mut ls = BatchLeastSquares::<f64, 4>::new(&[1, 3]).unwrap();
    for _ in 0..3 {
        ls.push(&V4::repeat(1.0), &V4::repeat(2.0)).unwrap();
    }
    let mut v = serde_json::to_value(&ls).unwrap();
    v["z"].as_array_mut().unwrap().pop();
    // 3 samples of 2 rows: 6 derivatives needed.
    rejects::<BatchLeastSquares<f64, 4>>(&v, "`z` has 5 elements but 6 are needed");
    let mut v = serde_json::to_value(&ls).unwrap();
    v["x"].as_array_mut().unwrap().pop();
    rejects::<BatchLeastSquares<f64, 4>>(&v, "`x` has 11 elements but 12 are needed");

    let car = HalfCar::<f64>::thesis();
    let cfg = TwoAxleConfig::new(WheelMethod::Cancel, 1000.0, 0.1, 0.005);
    let two = TwoAxleIdentifierVec::<f64, 8, 16>::new(&car.model(), 10, cfg).unwrap();
    let good = serde_json::to_value(&two).unwrap();
    let mut v = good.clone();
    v["d"] = json!(11);
    rejects::<TwoAxleIdentifierVec<f64, 8, 16>>(&v, "ring");
    let mut v = good.clone();
    v["ring"] = json!([]);
    rejects::<TwoAxleIdentifierVec<f64, 8, 16>>(&v, "ring");
    let mut v = good.clone();
    v["front_row"][0] = json!(9);
    rejects::<TwoAxleIdentifierVec<f64, 8, 16>>(&v, "wheel rows");
    let mut v = good.clone();
    v["body"]["rows"] = json!([5]);
    rejects::<TwoAxleIdentifierVec<f64, 8, 16>>(&v, "not a valid KalmanRows");
    let mut v = good;
    v["body"] = json!(null);
    rejects::<TwoAxleIdentifierVec<f64, 8, 16>>(&v, "`body`");

    // The two-axle structured identifier's equation states: each identified equation's, and
    // zero past them; either kind of corruption alone is refused.
    let c = car.constants();
    let mut known = [None; 12];
    for i in 8..12 {
        known[i] = Some(c[i]);
    }
    let st = *HalfCar::structure(known).unwrap().structure();
    let ts = TwoAxleStructuredVec::<f64, 4>::new(st, &car.model(), 10, TwoAxleStructuredConfig::new(0.1, 0.005));
    let good = serde_json::to_value(ts.unwrap()).unwrap();
    let ne = st.equations();
    assert!(serde_json::from_value::<TwoAxleStructuredVec<f64, 4>>(good.clone()).is_ok());
    for (at, value) in [(0, 6), (ne, 1)] {
        let mut v = good.clone();
        v["rows"][at] = json!(value);
        rejects::<TwoAxleStructuredVec<f64, 4>>(&v, "saved state");
    }

    // A fixed store takes exactly its length.
    let fixed = serde_json::to_value(KalmanIdentifier::<f64, 4, 2>::new([1, 3], 1.0, [1.0, 1.0]).unwrap()).unwrap();
    let mut v = fixed.clone();
    v["rows"] = json!([1, 3, 0]);
    rejects::<KalmanIdentifier<f64, 4, 2>>(&v, "fixed store");
    let mut v = fixed;
    v["rows"] = json!([1]);
    rejects::<KalmanIdentifier<f64, 4, 2>>(&v, "fixed store");
    let mut set = serde_json::to_value(RowSet::<4>::new(&[1, 3]).unwrap()).unwrap();
    set["len"] = json!(5);
    rejects::<RowSet<4>>(&set, "unknown_rows");
}

/// Every single-byte change of a serialized identifier either fails to load or loads into
/// an identifier that updates and reports without panicking.
fn survives_corruption<I>(id: &I, data: &[(&[f64], &[f64])], flips: &[u8])
where
    I: Identifier<f64> + Serialize + DeserializeOwned,
{
    let bytes = to_bytes(id);
    let k = id.dims().equations;
    let mut e = vec![0.0; k];
    for i in 0..bytes.len() {
        for &flip in flips {
            let mut b = bytes.clone();
            b[i] ^= flip;
            if let Ok(mut back) = postcard::from_bytes::<I>(&b) {
                for (x, z) in data {
                    let _ = back.update_into(x, z, &[], &mut e);
                }
                let _ = report(&back);
            }
        }
    }
}

#[test]
fn corrupt_bytes_never_panic() {
    let q = quarter(60);
    let dq = slices(&q);
    let h = half_road(40);
    let dh = slices(&h);
    // Three rows in two groups of two lanes (one of them half padding).
    let mut rows =
        KalmanIdentifierVec2::<f64, 4>::from_slices(&[1, 2, 3], &[1000.0], &[1.0], KalmanOptions::default()).unwrap();
    let mut e = [0.0; 3];
    for (x, z) in &q[..20] {
        rows.update_vec(x, z, &mut e).unwrap();
    }
    survives_corruption(&rows, &dq[20..23], &[0x01, 0xff]);
    survives_corruption(
        &KalmanIdentifierVec2::<f64, 4>::exact(&[1, 3], &R_Q, KalmanOptions::default()).unwrap(),
        &dq[..6],
        &[0x01, 0xff],
    );
    let r = SMatrix::<f64, 2, 2>::new(81.0, 0.01, 0.01, 2.5e-5);
    survives_corruption(&FullKalmanIdentifier::<f64, 4, 2>::new([1, 3], 1000.0, r).unwrap(), &dq[..3], &[0x01, 0xff]);
    survives_corruption(
        &SharedKalmanIdentifierVec::<f64, 4>::from_slices(&[1, 3], &[1.0], &[1.0], KalmanOptions::default()).unwrap(),
        &dq[..3],
        &[0x01, 0xff],
    );
    survives_corruption(
        &StochasticGradientVec::<f64, 4>::from_slices(&[1, 3], Gain::Lyapunov, &[1.0], &[0.0], 2).unwrap(),
        &dq[..3],
        &[0x01, 0xff],
    );
    survives_corruption(&LsAccumulator::<f64, 4, Dynamic>::from_rows(&[1, 3]).unwrap(), &dq[..3], &[0x01, 0xff]);
    let mut ls = BatchLeastSquares::<f64, 4>::new(&[1, 3]).unwrap();
    for (x, z) in &q[..8] {
        ls.push(x, z).unwrap();
    }
    survives_corruption(&ls, &dq[..4], &[0x01, 0xff]);
    let car = HalfCar::<f64>::thesis();
    let cfg = TwoAxleConfig::new(WheelMethod::Thesis, 1000.0, 0.1, 0.005);
    let mut two = TwoAxleIdentifierVec::<f64, 8, 16>::new(&car.model(), 3, cfg).unwrap();
    let mut e = [0.0; 4];
    for (x, z) in &h[..5] {
        two.update_next(x, z, &mut e).unwrap();
    }
    // (7 kB, most of it floats: one update per variant keeps the debug-build test short.)
    survives_corruption(&two, &dh[5..6], &[0xff]);
}

#[test]
fn identifiers_on_a_structure_continue_bit_for_bit() {
    // The full-row structure (8 parameters, two groups) with a prior and the exact start,
    // and the physical structure (m known: 4 parameters, one of them shared), in array and
    // heap storage; the structured stochastic gradient with a sample spacing of 3.
    let data = quarter(300);
    let d = slices(&data);
    let q = QuarterCar::<f64>::thesis();
    let full = crate::structure::Structure::<f64>::full_rows(4, &[1, 3]).unwrap();
    let physical = *QuarterCar::<f64>::structure([None, Some(1.0), None, None, None]).unwrap().structure();
    let r: [f64; 2] = q.model().row_noise_var(0.1, 0.005).unwrap();
    for form in [CovarianceForm::Standard, CovarianceForm::Sqrt] {
        let o = opts(form);
        let id = StructuredKalman::<f64, 4, 2>::new(full, StructuredPrior::Scalar(1000.0), None, &r, o).unwrap();
        continues(id, &d, 120);
        let id = StructuredKalmanVec::<f64, 4>::new(full, StructuredPrior::Exact, None, &r, o).unwrap();
        for split in [2, 150] {
            continues(id.clone(), &d, split);
        }
        let id =
            StructuredKalman::<f64, 2, 2>::new(physical, StructuredPrior::Scalar(1000.0), None, &[1.0], o).unwrap();
        continues(id, &d, 100);
    }
    let sg = StructuredGradient::<f64, 8>::new(full, Gain::Venter { p: 0.51 }, &[0.4], None, 3).unwrap();
    for split in [1, 101] {
        continues(sg.clone(), &d, split);
    }
}

#[test]
fn a_corrupt_structure_is_refused_and_corrupt_bytes_never_panic() {
    use serde_json::json;
    let full = crate::structure::Structure::<f64>::full_rows(4, &[1, 3]).unwrap();
    let text = serde_json::to_value(full).unwrap();
    let back: crate::structure::Structure<f64> = serde_json::from_value(text.clone()).unwrap();
    assert_eq!(back, full);
    // A term reading a state the structure does not have, a parameter beyond its count, an
    // equation past the stored terms, a second equation for a state: each refused.
    for (path, value) in [
        ("/terms/0/basis", json!({"Var": {"State": 9}})),
        ("/terms/0/param", json!(40)),
        ("/eqs/1/len", json!(90)),
        ("/eqs/1/state", json!(1)),
    ] {
        let mut v = text.clone();
        *v.pointer_mut(path).unwrap() = value;
        assert!(serde_json::from_value::<crate::structure::Structure<f64>>(v).is_err(), "{path}");
    }
    let q = quarter(40);
    let dq = slices(&q);
    let r = [81.0, 2.5e-5];
    let id =
        StructuredKalman::<f64, 4, 2>::new(full, StructuredPrior::Scalar(1000.0), None, &r, KalmanOptions::default())
            .unwrap();
    survives_corruption(&id, &dq[..3], &[0xff]);
    let sg = StructuredGradient::<f64, 8>::new(full, Gain::Lyapunov, &[1.0], None, 2).unwrap();
    survives_corruption(&sg, &dq[..3], &[0x01, 0xff]);
}

#[test]
fn instrumental_variables_continue_bit_for_bit() {
    // The full rows (two groups of four) with the delayed regressors (lags 0) and with the
    // refined instruments (lags 6, the Python default: the predictor's 49 regressors start
    // after 49 samples), saved while the ring fills, while the exact start or the predictor
    // is starting, and after; a prior; the fixed store; the physical structure.
    let data = quarter(400);
    let d = slices(&data);
    let full = crate::structure::Structure::<f64>::full_rows(4, &[1, 3]).unwrap();
    for delay in [1, 2] {
        let id = IvIdentifierVec::<f64, 4>::exact(full, delay).unwrap().with_lags(0).unwrap();
        for split in [0, 1, 3, 150] {
            continues(id.clone(), &d, split);
        }
        let id = IvIdentifierVec::<f64, 4, 64>::exact(full, delay).unwrap().with_lags(6).unwrap();
        for split in [3, 20, 60, 150] {
            let back = continues(id.clone(), &d, split);
            assert!(!back.starting());
        }
    }
    let r = [81.0, 2.5e-5];
    let prior = IvIdentifier::<f64, 4, 2>::new(full, 2, StructuredPrior::Scalar(1000.0), None, &r).unwrap();
    continues(prior, &d, 100);
    let fixed = IvIdentifier::<f64, 4, 2, 64>::exact(full, 1).unwrap().with_lags(3).unwrap();
    continues(fixed, &d, 100);
    // Groups smaller than P (the filters' unused entries stay 0 through the round trip).
    continues(IvIdentifierVec::<f64, 8, 64>::exact(full, 1).unwrap().with_lags(2).unwrap(), &d, 120);
    let physical = *QuarterCar::<f64>::structure([None, Some(1.0), None, None, None]).unwrap().structure();
    continues(IvIdentifierVec::<f64, 4, 64>::exact(physical, 1).unwrap().with_lags(2).unwrap(), &d, 120);
}

#[test]
fn bias_compensated_continues_bit_for_bit() {
    let data = quarter(300);
    let d = slices(&data);
    for split in [0, 1, 150] {
        continues(BiasCompensatedVec::<f64, 4>::full_rows(4, &[1, 3], &[1e-6]).unwrap(), &d, split);
        continues(BiasCompensatedLs::<f64, 8, 2>::full_rows(4, &[1, 3], &[1e-6, 2e-6, 1e-6, 3e-6]).unwrap(), &d, split);
    }
    // The physical structure reads der(·): its derivative noise enters the correction.
    let physical = *QuarterCar::<f64>::structure([None, Some(1.0), None, None, None]).unwrap().structure();
    let id = BiasCompensatedVec::<f64, 4>::new(physical, &[1e-6], &[1e-6], &[1.0, 0.5]).unwrap();
    continues(id, &d, 100);
}

/// `bytes` with the first occurrence of `old`'s eight bytes replaced by `new`'s.
fn patch_f64(bytes: &[u8], old: f64, new: f64) -> Vec<u8> {
    let (o, n) = (old.to_le_bytes(), new.to_le_bytes());
    let at = bytes.windows(8).position(|w| w == o).expect("the value is in the bytes");
    let mut out = bytes.to_vec();
    out[at..at + 8].copy_from_slice(&n);
    out
}

/// Why the check refuses `bytes` as `$ty`: postcard drops a custom error's message, so the
/// bytes are decoded without the check (the derived inherent `deserialize`) and checked
/// (`restored`) here, after asserting that the checked `Deserialize` refuses them too.
macro_rules! refusal {
    ($ty:ty, $bytes:expr) => {{
        let bytes: &[u8] = $bytes;
        assert!(postcard::from_bytes::<$ty>(bytes).is_err(), "the checked Deserialize accepted it");
        let mut de = postcard::Deserializer::from_bytes(bytes);
        let mut v = <$ty>::deserialize(&mut de).expect("decodes unchecked");
        v.restored().expect_err("refused").to_string()
    }};
}

#[test]
fn a_corrupt_iv_filter_or_predictor_is_refused() {
    use crate::identify::iv_predictor::Predictor;
    // IvFilter<f64, 2> of one parameter: θ (2 values), P, M (4 each), r, start, dim, count.
    let f = IvFilter::<f64, 2>::exact(1, 1.0).unwrap();
    let good = to_bytes(&f);
    assert_eq!((&good[80..88], good[88], good[89]), (&1.0f64.to_le_bytes()[..], 1, 1));
    let put = |at: usize, v: &[u8]| {
        let mut b = good.clone();
        b[at..at + v.len()].copy_from_slice(v);
        b
    };
    type F = IvFilter<f64, 2>;
    for (bytes, needle) in [
        (put(89, &[0]), "1 to P parameters"),
        (put(89, &[3]), "1 to P parameters"),
        (put(80, &0.0f64.to_le_bytes()), "weight r finite"),
        (put(80, &f64::NAN.to_le_bytes()), "weight r finite"),
        (put(0, &f64::INFINITY.to_le_bytes()), "θ, P and M finite"),
        (put(8, &1.0f64.to_le_bytes()), "zero beyond its dim"),
        // P and M are column-major: entry (0, 1), coupling the used parameter to an unused
        // one, is value 2 of each.
        (put(16 + 2 * 8, &1.0f64.to_le_bytes()), "zero beyond its dim"),
        (put(48 + 2 * 8, &1.0f64.to_le_bytes()), "zero beyond its dim"),
        (put(48, &(-1.0f64).to_le_bytes()), "diagonal ≥ 0"),
    ] {
        let why = refusal!(F, &bytes);
        assert!(why.contains(needle), "{needle}: {why}");
    }
    // After the start r = 0 is a valid weight.
    let mut b = put(80, &0.0f64.to_le_bytes());
    b[88] = 0;
    assert!(postcard::from_bytes::<F>(&b).is_ok());

    // Predictor<f64, 2> of one regressor and one output: P (4 values), Π̂ (2 × 40), dim,
    // outputs, start, count, big (the last 8 bytes).
    let p = Predictor::<f64, 2>::new(1, 1);
    let good = to_bytes(&p);
    let (dim_at, big_at) = (84 * 8, good.len() - 8);
    assert_eq!((good[dim_at], good[dim_at + 1]), (1, 1));
    let put = |edits: &[(usize, &[u8])]| {
        let mut b = good.clone();
        for (at, v) in edits {
            b[*at..*at + v.len()].copy_from_slice(v);
        }
        b
    };
    type Pr = Predictor<f64, 2>;
    let (four, nan) = (4.0f64.to_le_bytes(), f64::NAN.to_le_bytes());
    for (bytes, needle) in [
        (put(&[(dim_at, &[3])]), "at most Q regressors"),
        (put(&[(dim_at + 1, &[41])]), "at most Q regressors"),
        (put(&[(0, &nan)]), "P and Π̂ finite"),
        (put(&[(4 * 8 + 40 * 8, &f64::INFINITY.to_le_bytes())]), "P and Π̂ finite"),
        (put(&[(3 * 8, &four), (big_at, &four)]), "zero beyond its regressors"),
        (put(&[(4 * 8 + 8, &four), (big_at, &four)]), "zero beyond its regressors"),
        (put(&[(0, &four)]), "entry bound"),
        (put(&[(big_at, &nan)]), "entry bound"),
    ] {
        let why = refusal!(Pr, &bytes);
        assert!(why.contains(needle), "{needle}: {why}");
    }
    assert!(postcard::from_bytes::<Pr>(&put(&[(0, &four), (big_at, &2.0f64.to_le_bytes())])).is_ok());
}

#[test]
fn a_corrupt_iv_identifier_is_refused() {
    use serde_json::json;
    let data = quarter(120);
    let full = crate::structure::Structure::<f64>::full_rows(4, &[1, 3]).unwrap();
    let mut e = [0.0; 2];
    let mut run = |mut id: IvIdentifierVec<f64, 8, 64>| {
        for (x, z) in &data {
            id.update_into(x.as_slice(), z.as_slice(), &[], &mut e).unwrap();
        }
        serde_json::to_value(&id).unwrap()
    };
    type Iv = IvIdentifierVec<f64, 8, 64>;
    let refined = run(Iv::exact(full, 1).unwrap().with_lags(2).unwrap());
    let plain = run(Iv::exact(full, 1).unwrap().with_lags(0).unwrap());
    assert!(
        serde_json::from_value::<Iv>(refined.clone()).is_ok() && serde_json::from_value::<Iv>(plain.clone()).is_ok()
    );
    let with = |good: &serde_json::Value, path: &str, v: serde_json::Value| {
        let mut out = good.clone();
        *out.pointer_mut(path).unwrap_or_else(|| panic!("{path}")) = v;
        out
    };
    // The ring's bound, `√(largest float) / 256` (its message): just below it is taken.
    let ring_limit = f64::MAX.sqrt() / 256.0;
    assert!(serde_json::from_value::<Iv>(with(&refined, "/ring/buf/0", json!(0.5 * ring_limit))).is_ok());
    let mut one_filter = refined.clone();
    one_filter["filters"].as_array_mut().unwrap().pop();
    let cases = [
        (with(&refined, "/part/groups", json!(3)), "parameter groups"),
        (one_filter, "one filter per parameter group"),
        (with(&refined, "/rows/1", json!(2)), "equation rows"),
        (with(&refined, "/r/0", json!(-1.0)), "variances r finite and > 0"),
        (with(&refined, "/scale/1", json!(0.5)), "row weights"),
        (with(&refined, "/filters/0/r", json!(2.0)), "filters of their groups' sizes"),
        (with(&refined, "/filters/1/dim", json!(5)), "filters of their groups' sizes"),
        (with(&refined, "/delay", json!(0)), "delay of at least 1"),
        (with(&refined, "/lags", json!(8)), "capacity Q"),
        (with(&refined, "/delay", json!(2)), "ring of delay + lags"),
        (with(&refined, "/ring/head", json!(2)), "ring of delay + lags"),
        (with(&refined, "/samples", json!(1)), "ring filled by the samples"),
        (with(&refined, "/ring/buf/0", json!(1e200)), "past samples below"),
        (with(&refined, "/ring/buf/0", json!(2.0 * ring_limit)), "past samples below"),
        (with(&refined, "/ring/buf/500", json!(1.0)), "past samples below"),
        (with(&plain, "/pred/outputs", json!(3)), "predictor of lags"),
        (with(&refined, "/eq_ssr/1", json!(-1.0)), "residual sums"),
        (with(&refined, "/eq_nobs/0", json!(-1.0)), "residual sums"),
    ];
    for (v, needle) in &cases {
        rejects::<Iv>(v, needle);
    }
}

#[test]
fn a_corrupt_bias_compensated_identifier_is_refused() {
    use serde_json::json;
    let data = quarter(60);
    let mut id = BiasCompensatedVec::<f64, 8>::full_rows(4, &[1, 3], &[3.7e-4]).unwrap();
    let mut e = [0.0; 2];
    for (x, z) in &data {
        id.update_into(x.as_slice(), z.as_slice(), &[], &mut e).unwrap();
    }
    type Bc = BiasCompensatedVec<f64, 8>;
    let good = serde_json::to_value(&id).unwrap();
    assert!(serde_json::from_value::<Bc>(good.clone()).is_ok());
    let with = |path: &str, v: serde_json::Value| {
        let mut out = good.clone();
        *out.pointer_mut(path).unwrap_or_else(|| panic!("{path}")) = v;
        out
    };
    let mut one_group = good.clone();
    one_group["groups"].as_array_mut().unwrap().pop();
    let cases = [
        (with("/part/groups", json!(3)), "parameter groups"),
        (one_group, "one set of sums per parameter group"),
        (with("/rows/0", json!(3)), "equation rows"),
        (with("/r/1", json!(0.0)), "variances r finite and > 0"),
        (with("/scale/0", json!(2.0)), "row weights"),
        (with("/groups/0/dim", json!(3)), "each counting every sample"),
        (with("/groups/1/count", json!(59)), "each counting every sample"),
        (with("/groups/0/a/0", json!(-1.0)), "diagonal ≥ 0"),
        (with("/groups/0/b/7", json!(1.0)), "zero beyond each group's"),
        (with("/groups/1/c/63", json!(1.0)), "zero beyond each group's"),
    ];
    for (v, needle) in &cases {
        rejects::<Bc>(v, needle);
    }
    // A non-finite sum (postcard, which writes every float): the correction's 3.7e-4.
    assert_eq!(id.correction(0).0[(0, 0)], 3.7e-4);
    let why = refusal!(Bc, &patch_f64(&to_bytes(&id), 3.7e-4, f64::NAN));
    assert!(why.contains("sums and correction finite"), "{why}");
}

#[test]
fn corrupt_noisy_state_identifier_bytes_never_panic() {
    let q = quarter(40);
    let dq = slices(&q);
    let full = crate::structure::Structure::<f64>::full_rows(4, &[1, 3]).unwrap();
    let mut iv = IvIdentifierVec::<f64, 4>::exact(full, 2).unwrap();
    let mut bc = BiasCompensatedVec::<f64, 4>::full_rows(4, &[1, 3], &[1e-6]).unwrap();
    let mut e = [0.0; 2];
    for (x, z) in &dq[..12] {
        iv.update_into(x, z, &[], &mut e).unwrap();
        bc.update_into(x, z, &[], &mut e).unwrap();
    }
    // (The ring alone is 4 kB of floats: one flip and one update per variant.)
    survives_corruption(&iv, &dq[12..13], &[0xff]);
    survives_corruption(&bc, &dq[12..13], &[0x01, 0xff]);
}

#[test]
fn instrumental_variables_with_a_measured_input_continue_bit_for_bit() {
    // A rig with a measured force: the ring of past samples holds 2n + m = 5 values per
    // sample (a check of that width on load must count the input). With 3 lags the
    // predictor's 3·5 + 1 = 16 regressors fill its capacity Q = 16 exactly.
    use crate::structure::StructureBuilder;
    let (st, _) = StructureBuilder::new(&["q", "v"], &["tau"])
        .equation("v", "a*tau - b*v")
        .known("q", "v")
        .build::<f64>()
        .unwrap();
    let (mut q, mut v) = (0.0f64, 0.0f64);
    let mut rows = Vec::new();
    for k in 0..300 {
        let tau = (0.37 * k as f64).sin() + 0.5 * (0.11 * k as f64).cos();
        let dv = 2.0 * tau - 0.8 * v + 0.01 * (1.3 * k as f64).sin();
        rows.push(([q, v], [v, dv], [tau]));
        q += 0.05 * v;
        v += 0.05 * dv;
    }
    for lags in [0, 2, 3] {
        let mut id = IvIdentifierVec::<f64, 2, 16>::exact(st, 1).unwrap().with_lags(lags).unwrap();
        let mut e = [0.0; 1];
        for (x, z, u) in &rows[..150] {
            id.update_into(x, z, u, &mut e).unwrap();
        }
        let mut back: IvIdentifierVec<f64, 2, 16> = postcard::from_bytes(&to_bytes(&id)).unwrap();
        let mut e2 = [0.0; 1];
        for (x, z, u) in &rows[150..] {
            id.update_into(x, z, u, &mut e).unwrap();
            back.update_into(x, z, u, &mut e2).unwrap();
            assert_eq!(e[0].to_bits(), e2[0].to_bits());
        }
        assert_eq!(to_bytes(&back), to_bytes(&id), "lags {lags}");
    }
}

/// The joint EKF on the quarter car's physical structure (m known), the prior of
/// `tests/joint_ekf.rs` (half or 1.5 times the truth, 100 % standard deviation).
fn joint_ekf() -> JointEkf<f64, 4, 9> {
    let physical = *QuarterCar::<f64>::structure([None, Some(1.0), None, None, None]).unwrap().structure();
    let noise = EkfNoise::from_sigmas(0.01, 0.005, V4::from([0.0, 90.0, 0.0, 0.0]), 0.1);
    let guess = [2.5, 6.0, 5.0, 135.0];
    JointEkf::new(physical, &guess, &guess.map(|g| g * g), 1.0, noise, 0.05, 5).unwrap()
}

#[test]
fn joint_ekf_continues_bit_for_bit() {
    let data = quarter(200);
    let d = slices(&data);
    for split in [0, 1, 120] {
        continues(joint_ekf(), &d, split);
    }
}

#[test]
fn a_corrupt_joint_ekf_is_refused() {
    use serde_json::json;
    type Ekf = JointEkf<f64, 4, 9>;
    let fresh = joint_ekf();
    let mut id = fresh;
    let mut e = [0.0; 2];
    for (x, z) in &quarter(30) {
        id.update_into(x.as_slice(), z.as_slice(), &[], &mut e).unwrap();
    }
    let good = serde_json::to_value(id).unwrap();
    assert_eq!(serde_json::from_value::<Ekf>(good.clone()).unwrap(), id);
    let with = |path: &str, v: serde_json::Value| {
        let mut out = good.clone();
        *out.pointer_mut(path).unwrap_or_else(|| panic!("{path}")) = v;
        out
    };
    let cases = [
        (with("/substeps", json!(0)), "joint EKF's saved state"),
        (with("/rows/0", json!(2)), "joint EKF's saved state"),
        (with("/rows/5", json!(1)), "joint EKF's saved state"),
        (with("/order/0", json!(1)), "joint EKF's saved state"),
        (with("/dt", json!(-0.05)), "dt"),
        (with("/noise/state_var/2", json!(0.0)), "state_var"),
        (with("/noise/road_var", json!(-1.0)), "road_var"),
        // The road slot (index 8 of 9; P column-major): estimate, variance, covariances.
        (with("/s/8", json!(1e-3)), "joint EKF's saved state"),
        (with("/p/80", json!(0.5 * good["noise"]["road_var"].as_f64().unwrap())), "joint EKF's saved state"),
        (with("/p/8", json!(1e-6)), "joint EKF's saved state"),
        (with("/p/77", json!(1e-6)), "joint EKF's saved state"),
    ];
    for (v, needle) in &cases {
        rejects::<Ekf>(v, needle);
    }
    // A non-finite estimate (postcard writes every float): the prior's 135 on k1.
    let why = refusal!(Ekf, &patch_f64(&to_bytes(&fresh), 135.0, f64::NAN));
    assert!(why.contains("state"), "{why}");
    survives_corruption(&id, &slices(&quarter(2)), &[0x01, 0xff]);
}
