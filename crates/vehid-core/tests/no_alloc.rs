//! "No allocation per sample" (ARCHITECTURE.md's first invariant), for every identifier:
//! a counting global allocator counts the allocations of this test's thread while each
//! identifier takes `N` samples after a warm-up, and the count must be zero.
//!
//! `BatchLeastSquares` stores its samples (it allocates as its store grows, by design) and
//! is left out.

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;

use nalgebra::SVector;
use vehid_core::identify::{
    BiasCompensatedVec, CovarianceForm, FullKalmanIdentifier, FullKalmanIdentifierVec, Gain, Identifier,
    IvIdentifierVec, KalmanIdentifier, KalmanIdentifierVec, KalmanOptions, NoiseEstimatingBclsVec,
    SharedKalmanIdentifier, SharedKalmanIdentifierVec, StochasticGradient, StochasticGradientVec, StructuredGradient,
    StructuredKalman, StructuredKalmanVec, StructuredPrior, TwoAxleConfig, TwoAxleIdentifierVec,
    TwoAxleStructuredConfig, TwoAxleStructuredKalman, TwoAxleStructuredVec, WheelMethod,
};
use vehid_core::model::{HalfCar, QuarterCar};
use vehid_core::sim::{SimConfig, Simulator};
use vehid_core::structure::Structure;

struct Counting;

thread_local! {
    static ALLOCATIONS: Cell<u64> = const { Cell::new(0) };
}

// SAFETY: forwards to the system allocator; only counts.
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        let _ = ALLOCATIONS.try_with(|c| c.set(c.get() + 1));
        unsafe { System.alloc(layout) }
    }
    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        let _ = ALLOCATIONS.try_with(|c| c.set(c.get() + 1));
        unsafe { System.alloc_zeroed(layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        let _ = ALLOCATIONS.try_with(|c| c.set(c.get() + 1));
        unsafe { System.realloc(ptr, layout, new_size) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        unsafe { System.dealloc(ptr, layout) }
    }
}

#[global_allocator]
static GLOBAL: Counting = Counting;

fn allocations() -> u64 {
    ALLOCATIONS.with(|c| c.get())
}

const WARM: usize = 50;
const N: usize = 200;

/// Allocations of this thread during `N` updates after `WARM` (the samples are made before).
fn count<const S: usize, I: Identifier<f64>>(name: &str, id: &mut I, data: &[(SVector<f64, S>, SVector<f64, S>)]) {
    let d = id.dims();
    let mut e = vec![0.0; d.equations];
    for (x, z) in &data[..WARM] {
        id.update_into(x.as_slice(), z.as_slice(), &[], &mut e).unwrap();
    }
    let before = allocations();
    for (x, z) in &data[WARM..WARM + N] {
        id.update_into(x.as_slice(), z.as_slice(), &[], &mut e).unwrap();
    }
    let n = allocations() - before;
    assert_eq!(n, 0, "{name}: {n} allocations in {N} updates");
}

fn quarter(seed: u64) -> Vec<(SVector<f64, 4>, SVector<f64, 4>)> {
    let cfg = SimConfig::new(0.05).road_sigma(0.1).ic_sigma(0.1).deriv_noise(0.005);
    let mut sim = Simulator::new(QuarterCar::<f64>::thesis().model(), cfg, seed).unwrap();
    (0..WARM + N).map(|_| sim.next_sample()).map(|s| (s.r, s.z)).collect()
}

#[test]
fn no_identifier_allocates_per_sample() {
    let data = quarter(3);
    let rows = [1usize, 3];
    let r = [81.0, 2.5e-5];
    // The counter sees allocations: the test would not pass vacuously.
    let before = allocations();
    let v = std::hint::black_box(vec![1u8; 3]);
    assert!(allocations() > before && v.len() == 3);

    for form in [CovarianceForm::Standard, CovarianceForm::Joseph, CovarianceForm::Sqrt] {
        let o = KalmanOptions { form, ..Default::default() };
        let t = KalmanOptions { forgetting: 0.995, drift: 1e-7, directional: false, gate: 4.0, ..o };
        let name = |what: &str| format!("{what} {form:?}");
        count(&name("rows"), &mut KalmanIdentifier::<f64, 4, 2>::from_slices(&rows, &[1000.0], &r, o).unwrap(), &data);
        count(
            &name("rows Vec"),
            &mut KalmanIdentifierVec::<f64, 4>::from_slices(&rows, &[1000.0], &r, o).unwrap(),
            &data,
        );
        let four = [1.0, 81.0, 1.0, 2.5e-5];
        let mut id = KalmanIdentifierVec::<f64, 4>::from_slices(&[0, 1, 2, 3], &[1000.0], &four, o).unwrap();
        count(&name("rows Vec, four rows"), &mut id, &data);
        count(
            &name("rows tracking"),
            &mut KalmanIdentifier::<f64, 4, 2>::from_slices(&rows, &[1000.0], &r, t).unwrap(),
            &data,
        );
        count(
            &name("rows Vec tracking"),
            &mut KalmanIdentifierVec::<f64, 4>::from_slices(&rows, &[1000.0], &r, t).unwrap(),
            &data,
        );
        let dir = KalmanOptions { forgetting: 0.995, directional: true, ..o };
        count(
            &name("rows directional"),
            &mut KalmanIdentifierVec::<f64, 4>::from_slices(&rows, &[1000.0], &r, dir).unwrap(),
            &data,
        );
        // The exact start after it has started (the warm-up absorbs the first samples).
        count(&name("rows exact"), &mut KalmanIdentifier::<f64, 4, 2>::exact(&rows, &r, o).unwrap(), &data);
        count(&name("rows Vec exact"), &mut KalmanIdentifierVec::<f64, 4>::exact(&rows, &r, o).unwrap(), &data);
        if form != CovarianceForm::Sqrt {
            let s = SharedKalmanIdentifier::<f64, 4, 2>::from_slices(&rows, &[1000.0], &[0.3], o).unwrap();
            count(&name("shared"), &mut { s }, &data);
            let s = SharedKalmanIdentifierVec::<f64, 4>::from_slices(&rows, &[1000.0], &[0.3], o).unwrap();
            count(&name("shared Vec"), &mut { s }, &data);
        }
        if form == CovarianceForm::Standard {
            let f = FullKalmanIdentifier::<f64, 4, 2>::from_slices(&rows, &[1000.0], &r, o).unwrap();
            count(&name("full"), &mut { f }, &data);
            let f = FullKalmanIdentifierVec::<f64, 4>::from_slices(&rows, &[1000.0], &r, o).unwrap();
            count(&name("full Vec"), &mut { f }, &data);
        }
        let st = Structure::full_rows(4, &rows).unwrap();
        let sk = StructuredKalman::<f64, 4, 2>::new(st, StructuredPrior::Scalar(1000.0), None, &r, o).unwrap();
        count(&name("structured"), &mut { sk }, &data);
        let sk = StructuredKalmanVec::<f64, 8>::new(st, StructuredPrior::Exact, None, &r, t).unwrap();
        count(&name("structured Vec exact tracking"), &mut { sk }, &data);
    }
    for g in [Gain::Venter { p: 0.51 }, Gain::Lyapunov, Gain::Ljung { lambda0: 0.99, lambda_init: 0.95 }] {
        let sg = StochasticGradient::<f64, 4, 2>::from_slices(&rows, g, &[0.04, 0.4], &[1e-4], 2).unwrap();
        count(&format!("SG {g:?}"), &mut { sg }, &data);
        let sg = StochasticGradientVec::<f64, 4>::from_slices(&rows, g, &[0.04, 0.4], &[1e-4], 1).unwrap();
        count(&format!("SG Vec {g:?}"), &mut { sg }, &data);
        let st = Structure::full_rows(4, &rows).unwrap();
        let sg = StructuredGradient::<f64, 8>::new(st, g, &[0.04], None, 1).unwrap();
        count(&format!("structured SG {g:?}"), &mut { sg }, &data);
    }
    let iv = IvIdentifierVec::<f64, 8>::full_rows(4, &rows, 1, StructuredPrior::Exact, &[1.0]).unwrap();
    count("IV", &mut { iv }, &data);
    let st = Structure::full_rows(4, &rows).unwrap();
    let bc = BiasCompensatedVec::<f64, 8>::new(st, &[1e-6], &[], &[1.0]).unwrap();
    count("bias compensated", &mut { bc }, &data);
    let ne = NoiseEstimatingBclsVec::<f64, 8, 17>::full_rows(4, &rows, 1, 2).unwrap();
    count("bias compensated, noise estimated", &mut { ne }, &data);
    model_instruments();

    // The half car: six unknown rows (two lane groups of the heap store), and its two axles
    // on one road, each wheel method.
    let half = HalfCar::<f64>::thesis();
    let cfg = SimConfig::new(0.05).road_sigma(0.1).ic_sigma(0.1).deriv_noise(0.005);
    let mut sim = Simulator::new(half.model(), cfg, 5).unwrap();
    let hdata: Vec<_> = (0..WARM + N).map(|_| sim.next_sample()).map(|s| (s.r, s.z)).collect();
    for form in [CovarianceForm::Standard, CovarianceForm::Joseph, CovarianceForm::Sqrt] {
        let o = KalmanOptions { form, ..Default::default() };
        let r = [1.0, 81.0, 1.0, 2.5e-5, 1.0, 1.0];
        let mut id = KalmanIdentifierVec::<f64, 8>::from_slices(&[0, 1, 2, 3, 5, 7], &[1000.0], &r, o).unwrap();
        count(&format!("half car six rows {form:?}"), &mut id, &hdata);
    }
    for method in [WheelMethod::None, WheelMethod::Thesis, WheelMethod::Cancel] {
        let cfg = TwoAxleConfig::new(method, 1000.0, 0.1, 0.005);
        let mut two = TwoAxleIdentifierVec::<f64, 8, 16>::new(&half.model(), 10, cfg).unwrap();
        count(&format!("two axles {method:?}"), &mut two, &hdata);
    }
    // Road cancellation on the half car's physical structure (m1, m2, l1, l2 known), both
    // stores.
    let c = half.constants();
    let known = core::array::from_fn(|i| (i >= 8).then_some(c[i]));
    let ps = *HalfCar::structure(known).unwrap().structure();
    let cfg = TwoAxleStructuredConfig::new(0.1, 0.005);
    let mut fixed = TwoAxleStructuredKalman::<f64, 4, 3, 16>::new(ps, &half.model(), 10, cfg).unwrap();
    count("two axles, physical structure", &mut fixed, &hdata);
    let mut heap = TwoAxleStructuredVec::<f64, 4>::new(ps, &half.model(), 10, cfg).unwrap();
    count("two axles, physical structure Vec", &mut heap, &hdata);
}

/// Instruments from the auxiliary model (a structure with a measured input: a mass-spring-damper
/// driven by a measured force), past its first refresh and through several more (the
/// stability test), in both stores.
fn model_instruments() {
    use vehid_core::identify::{IvIdentifier, ModelIvIdentifierVec};
    use vehid_core::structure::StructureBuilder;
    let (s, _) = StructureBuilder::new(&["q", "v"], &["F"])
        .equation("v", "a*F - k*q - b*v")
        .known("q", "v")
        .build::<f64>()
        .unwrap();
    let p = [1.0, 40.0, 2.5];
    let (mut x, mut f, mut k) = ([0.0f64; 2], 0.0f64, 0u64);
    let mut data = vec![];
    for _ in 0..600 {
        k = k.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        f = 0.5 * f + ((k >> 11) as f64 / (1u64 << 53) as f64 - 0.5);
        let mut der = [0.0; 2];
        s.derivative(&p, &x, &[f], &mut der);
        data.push((x, der, [f]));
        let mut both = [0.0; 4];
        s.simulate(&p, &x, &[f, f], 0.01, 2, &mut both).unwrap();
        x = [both[2], both[3]];
    }
    let mut fixed = IvIdentifier::<f64, 3, 1>::exact(s, 1).unwrap().with_model_instruments(0.01, 2, 20, None).unwrap();
    let mut heap: ModelIvIdentifierVec<f64, 3> = vehid_core::identify::IvIdentifierVec::<f64, 3>::exact(s, 1)
        .unwrap()
        .with_model_instruments(0.01, 2, 20, None)
        .unwrap();
    let mut e = [0.0];
    for (x, z, u) in &data[..300] {
        fixed.update_into(x, z, u, &mut e).unwrap();
        heap.update_into(x, z, u, &mut e).unwrap();
    }
    assert!(fixed.adopted() > 0 && heap.adopted() > 0);
    let before = allocations();
    for (x, z, u) in &data[300..] {
        fixed.update_into(x, z, u, &mut e).unwrap();
        heap.update_into(x, z, u, &mut e).unwrap();
    }
    let n = allocations() - before;
    assert_eq!(n, 0, "model instruments: {n} allocations in 300 updates");
    assert!(fixed.adopted() > 10);
}

/// The realistic sensors' state-variable-filter fit takes samples, and closes blocks (every
/// 0.35 s here), without allocating.
#[test]
fn the_state_filter_fit_does_not_allocate_per_sample() {
    use vehid_core::identify::StateFilterFit;
    use vehid_core::model::QuarterCar;
    let ps = QuarterCar::<f64>::realistic_structure([Some(320.0), None, None, None, None]).unwrap();
    let dt = 0.005;
    let mut fit = StateFilterFit::new(*ps.structure(), dt, 60.0, 0.35).unwrap();
    let sample = |k: usize| {
        let t = k as f64 * dt;
        [-(t * 7.0).sin(), 0.3 * (t * 60.0).sin(), 0.01 * (t * 7.0).sin() + 0.001 * (t * 3.1).cos()]
    };
    for k in 0..300 {
        fit.update(&sample(k)).unwrap();
    }
    let before = allocations();
    for k in 300..2300 {
        fit.update(&sample(k)).unwrap();
    }
    fit.restart();
    let n = allocations() - before;
    assert_eq!(n, 0, "state filter fit: {n} allocations in 2000 updates (28 blocks)");
    assert!(fit.stats(0.05).is_ok());
}
