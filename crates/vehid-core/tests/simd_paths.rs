//! The AVX2 and the portable updates give the same bits (`crate::simd`'s promise).
//!
//! Run by `make test` twice: in the test profile with the rest, and alone in release
//! (`cargo test --release -p vehid-core --test simd_paths`), because the promise matters for
//! optimized code. The forms that take the AVX2 copy: the Dynamic store's four-lane groups
//! (quarter and half car), and for the half car in f64 the Fixed<4> rows and the shared form.

use vehid_core::identify::{Identifier, KalmanIdentifier, KalmanIdentifierVec, KalmanOptions, SharedKalmanIdentifier};
use vehid_core::model::{HalfCar, QuarterCar};
use vehid_core::sim::{SimConfig, Simulator};
use vehid_core::{simd, Real};

fn quarter_bits(n: usize) -> Vec<u64> {
    let car = QuarterCar::<f64>::thesis();
    let cfg = SimConfig::new(0.05).road_sigma(0.1).ic_sigma(0.1).deriv_noise(0.005);
    let mut sim = Simulator::new(car.model(), cfg, 21).unwrap();
    let mut q_dyn =
        KalmanIdentifierVec::<f64, 4>::from_slices(&[1, 3], &[1000.0], &[81.0, 2.5e-5], KalmanOptions::default())
            .unwrap();
    let mut q_shared = SharedKalmanIdentifier::<f64, 4, 2>::new([1, 3], 1000.0, [0.3; 2]).unwrap();
    let mut e = [0.0; 2];
    for _ in 0..n {
        let s = sim.next_sample();
        q_dyn.update_into(s.r.as_slice(), s.z.as_slice(), &[], &mut e).unwrap();
        q_shared.update(&s.r, &s.z).unwrap();
    }
    let mut bits: Vec<u64> = q_shared.theta().iter().chain(q_shared.q().iter()).map(|v| v.to_bits()).collect();
    for i in 0..2 {
        bits.extend(q_dyn.filter(i).p().iter().chain(q_dyn.theta_row(i).iter()).map(|v| v.to_bits()));
    }
    bits
}

fn half_car_bits<T: Real>(n: usize) -> Vec<u64> {
    let car = HalfCar::<T>::thesis();
    let cfg =
        SimConfig::<T, 8, 2>::new(T::of(0.05)).road_sigma(T::of(0.1)).ic_sigma(T::of(0.1)).deriv_noise(T::of(0.005));
    let mut sim = Simulator::new(car.model(), cfg, 17).unwrap();
    let rows = car.unknown_rows();
    let r = [T::of(100.0), T::of(100.0), T::of(0.01), T::of(0.01)];
    let mut fixed = KalmanIdentifier::<T, 8, 4>::new(rows, T::of(1000.0), r).unwrap();
    let mut dynamic =
        KalmanIdentifierVec::<T, 8>::from_slices(&rows[..3], &[T::of(1000.0)], &r[..3], KalmanOptions::default())
            .unwrap();
    let mut shared = SharedKalmanIdentifier::<T, 8, 4>::new(rows, T::of(1000.0), [T::of(0.3); 4]).unwrap();
    let mut e = [T::zero(); 3];
    for _ in 0..n {
        let s = sim.next_sample();
        fixed.update(&s.r, &s.z).unwrap();
        dynamic.update_into(s.r.as_slice(), s.z.as_slice(), &[], &mut e).unwrap();
        shared.update(&s.r, &s.z).unwrap();
    }
    let mut out = Vec::new();
    let mut push = |v: T| out.push(v.to_f64().to_bits());
    fixed.theta().iter().for_each(|v| push(*v));
    shared.theta().iter().for_each(|v| push(*v));
    shared.q().iter().for_each(|v| push(*v));
    for i in 0..4 {
        fixed.filter(i).p().iter().for_each(|v| push(*v));
    }
    for i in 0..3 {
        dynamic.filter(i).p().iter().chain(dynamic.theta_row(i).iter()).for_each(|v| push(*v));
    }
    out
}

#[test]
fn vector_extensions_do_not_change_a_single_bit() {
    let run = || {
        let mut bits = quarter_bits(3000);
        bits.extend(half_car_bits::<f64>(3000));
        bits.extend(half_car_bits::<f32>(3000));
        bits
    };
    simd::set_vector_extensions(false);
    assert_eq!(simd::vector_extensions(), "portable");
    let portable = run();
    simd::set_vector_extensions(true);
    let path = simd::vector_extensions();
    let vector = run();
    eprintln!("compared the portable path with: {path} ({} values)", vector.len());
    #[cfg(target_arch = "x86_64")]
    if std::is_x86_feature_detected!("avx2") {
        assert_eq!(path, "avx2", "the AVX2 path is taken on a CPU that has it");
    }
    let differ = portable.iter().zip(&vector).filter(|(a, b)| a != b).count();
    assert_eq!(differ, 0, "{differ} of {} values differ between the paths", vector.len());
}
