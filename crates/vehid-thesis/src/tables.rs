//! The report's tables: Eq 4.28, Eq 4.32, Eq 4.34 and Table I (with the update timing).

use crate::figures::DT;
use crate::report::{fmt_num, Table, TableRow};
use crate::seeds::mix;
use crate::stats::median;
use vehid_core::analysis::output_std;
use vehid_core::identify::{BatchLeastSquares, Cost, KalmanIdentifier, KalmanOptions};
use vehid_core::metrics::{snr_db, xi};
use vehid_core::model::{HalfCar, LinearModel, QuarterCar};
use vehid_core::nalgebra::SVector;
use vehid_core::sim::{SimConfig, Simulator};

/// Eq 4.28 thesis values, σ_x / σ_u.
pub const EQ_4_28: [f64; 4] = [0.386, 1.84, 0.402, 1.03];
/// Eq 4.32 thesis values, dB at σ_u = 25 σ_w.
pub const EQ_4_32: [f64; 4] = [19.7, 33.3, 20.0, 28.2];
/// Eq 4.34 thesis values, e_i(8000).
pub const EQ_4_34: [f64; 4] = [0.605, 0.001, 0.705, 0.032];

/// The report's tables: Eq 4.28, Eq 4.32, Eq 4.34 (measured over `seeds` seeds) and Table I
/// (bytes from `size_of`, ns per update from a short timing).
///
/// # Errors
/// A core error (a bug).
pub fn tables(base_seed: u64, seeds: usize, quick: bool) -> crate::Result<Vec<Table>> {
    let car = QuarterCar::<f64>::thesis();
    let model = car.model();
    let names = ["x1 (wheel position)", "ẋ1 (wheel velocity)", "x2 (body position)", "ẋ2 (body velocity)"];
    // Eq 4.28: analytic, and the sample standard deviation over 10,000 simulated samples.
    let sd = output_std(&model, &[1.0], DT)?;
    let mut sim = Simulator::new(model.clone(), SimConfig::new(DT).road_sigma(1.0), mix(base_seed ^ 428))?;
    let mut acc = [0.0f64; 4];
    let nsamp = 10_000;
    for _ in 0..1000 {
        sim.next_sample(); // settle from x(0) = 0
    }
    for _ in 0..nsamp {
        let s = sim.next_sample();
        for i in 0..4 {
            acc[i] += s.x[i] * s.x[i];
        }
    }
    let mut t428 = Table {
        title: "Eq 4.28: output standard deviation σ_x / σ_u".into(),
        method: format!("vehid: Eq 4.27 evaluated in closed form (analysis::output_std); in brackets the sample value of one simulated run of {nsamp} samples (the thesis' Eq 4.29 check)"),
        rows: vec![],
    };
    for i in 0..4 {
        let v = sd[i];
        let simv = (acc[i] / nsamp as f64).sqrt();
        let rel = (v - EQ_4_28[i]).abs() / EQ_4_28[i];
        t428.rows.push(TableRow {
            label: names[i].into(),
            thesis: fmt_num(EQ_4_28[i]),
            vehid: format!("{:.3} [{:.3}]", v, simv),
            agrees: rel < 0.01,
            note: if rel < 0.01 { String::new() } else { format!("{:.1} % off", rel * 100.0) },
        });
    }
    // Eq 4.32: SNR at σ_u = 25 σ_w.
    let mut t432 = Table {
        title: "Eq 4.32: sensor SNR with σ_u = 25 σ_w".into(),
        method: "vehid: metrics::snr_db(σ_i, σ_u / 25) with σ_i from Eq 4.27".into(),
        rows: vec![],
    };
    for i in 0..4 {
        let db = snr_db(sd[i], 1.0 / 25.0)?;
        let ok = (db - EQ_4_32[i]).abs() < 0.15;
        t432.rows.push(TableRow {
            label: names[i].into(),
            thesis: format!("{} dB", EQ_4_32[i]),
            vehid: format!("{db:.1} dB"),
            agrees: ok,
            note: if ok { String::new() } else { "more than 0.15 dB off".into() },
        });
    }
    // Eq 4.34: state noise on one element at a time.
    let t434 = sensitivity(base_seed, seeds, quick)?;
    Ok(vec![t428, t432, t434, table_one(quick)?])
}

/// Eq 4.33–4.34: `e_i(8000) = ξ_w(8000) − ξ_0(8000)` with σ_w = σ_u / 25 on element `i` only
/// (Fig 4-2's noise otherwise), same seeds with and without.
fn sensitivity(base_seed: u64, seeds: usize, quick: bool) -> crate::Result<Table> {
    let car = QuarterCar::<f64>::thesis();
    let truth = car.theta().transpose();
    let (road, deriv, sw) = (0.1, 0.005, 0.1 / 25.0);
    let n = 8000;
    let run1 = |elem: Option<usize>, seed: u64| -> crate::Result<f64> {
        let mut cfg = SimConfig::<f64, 4, 1>::new(DT).road_sigma(road).deriv_noise(deriv);
        if let Some(i) = elem {
            cfg.state_noise[i] = sw;
        }
        let r = car.model().row_noise_var::<2>(road, deriv)?;
        let mut id = KalmanIdentifier::<f64, 4, 2>::new([1, 3], 1000.0, r)?;
        let mut sim = Simulator::new(car.model(), cfg, seed)?;
        for _ in 0..n {
            let s = sim.next_sample();
            let _ = id.update(&s.r, &s.z);
        }
        let th = id.theta().transpose();
        xi(truth.as_slice(), th.as_slice())
    };
    let mut e = [[0.0f64; 4]; 0].to_vec();
    for s in 0..seeds {
        let seed = mix(base_seed ^ 434 ^ mix(s as u64));
        let x0 = run1(None, seed)?;
        let mut row = [0.0; 4];
        for (i, v) in row.iter_mut().enumerate() {
            *v = run1(Some(i), seed)? - x0;
        }
        e.push(row);
    }
    let mut t = Table {
        title: "Eq 4.34: per-element state-noise sensitivity e_i(8000) = ξ_w − ξ_0".into(),
        method: format!(
            "vehid: Fig 4-2's noise (σ_ic 0, σ_u 0.1, σ_v 0.005), σ_w = σ_u/25 = 0.004 on element i only, Kalman P(0) = 1000, \
             same seed with and without; mean [median] over {seeds} seeds (the thesis: mean of 3){}",
            if quick { " — quick mode" } else { "" }
        ),
        rows: vec![],
    };
    let names = ["x1", "ẋ1", "x2", "ẋ2"];
    let means: Vec<f64> = (0..4).map(|i| e.iter().map(|r| r[i]).sum::<f64>() / e.len() as f64).collect();
    let rank = |v: &[f64]| {
        let mut idx: Vec<usize> = (0..v.len()).collect();
        idx.sort_by(|&a, &b| v[a].total_cmp(&v[b]));
        idx
    };
    let same_order = rank(&means) == rank(&EQ_4_34);
    for i in 0..4 {
        let col: Vec<f64> = e.iter().map(|r| r[i]).collect();
        let m = means[i];
        // Agreement: within a factor 2 (the thesis' figure is a mean of 3 runs, so its own
        // spread is large); a value printed as ≈ 0 agrees with anything below 0.01.
        let ok = if EQ_4_34[i] < 0.01 { m.abs() < 0.01 } else { m > EQ_4_34[i] / 2.0 && m < EQ_4_34[i] * 2.0 };
        t.rows.push(TableRow {
            label: names[i].into(),
            thesis: fmt_num(EQ_4_34[i]),
            vehid: format!("{} [{}]", fmt_num(m), fmt_num(median(&col))),
            agrees: ok,
            note: if ok {
                String::new()
            } else {
                format!(
                    "outside a factor 2 of the thesis. The thesis averaged only 3 runs and the per-seed \
                     spread of ξ at 8000 iterations is large; what holds is the conclusion it drew: \
                     position sensors (about 20 dB SNR) bias far more than the wheel-velocity sensor \
                     (33 dB){}",
                    if same_order { "; the ranking of the four elements matches" } else { "" }
                )
            },
        });
    }
    t.rows.push(TableRow {
        label: "ranking of the four elements".into(),
        thesis: "ẋ1 < ẋ2 < x1 < x2".into(),
        vehid: rank(&means).iter().map(|&i| names[i]).collect::<Vec<_>>().join(" < "),
        agrees: same_order,
        note: if same_order { String::new() } else { "different order".into() },
    });
    Ok(t)
}

/// Measured ns per update of one identifier over pre-generated samples.
fn time_updates<const N: usize, const M: usize>(
    model: LinearModel<f64, N, M>,
    road: [f64; M],
    n: usize,
    mut update: impl FnMut(&SVector<f64, N>, &SVector<f64, N>),
) -> crate::Result<f64> {
    let mut cfg = SimConfig::<f64, N, M>::new(DT).deriv_noise(0.005);
    cfg.road_sigma = SVector::from(road);
    let mut sim = Simulator::new(model, cfg, 7)?;
    let samples: Vec<(SVector<f64, N>, SVector<f64, N>)> = (0..n)
        .map(|_| {
            let s = sim.next_sample();
            (s.r, s.z)
        })
        .collect();
    let t0 = std::time::Instant::now();
    for (r, z) in &samples {
        update(core::hint::black_box(r), core::hint::black_box(z));
    }
    Ok(t0.elapsed().as_nanos() as f64 / n as f64)
}

fn table_one(quick: bool) -> crate::Result<Table> {
    let n = if quick { 50_000 } else { 200_000 };
    let q = QuarterCar::<f64>::thesis();
    let h = HalfCar::<f64>::thesis();
    let rq = q.model().row_noise_var::<2>(0.1, 0.005)?;
    let mut k4 = KalmanIdentifier::<f64, 4, 2>::new([1, 3], 1000.0, rq)?;
    let ns4 = time_updates(q.model(), [0.1], n, |r, z| {
        let _ = k4.update(r, z);
    })?;
    let mut rh = [0.0; 4];
    h.model().row_noise_var_into(&[0.1, 0.0], &[0.005], &mut rh)?;
    let mut k8 = KalmanIdentifier::<f64, 8, 4>::from_slices(
        &[1, 3, 5, 7],
        &[1000.0, 1000.0, 8.0, 8.0],
        &rh,
        KalmanOptions::default(),
    )?;
    let ns8 = time_updates(h.model(), [0.1, 0.0], n / 2, |r, z| {
        let _ = k8.update(r, z);
    })?;
    let (c4, c8) = (k4.cost(), k8.cost());
    let ops = |c: &Cost| format!("{} / {} / {} (+ {} √)", c.multiplications, c.additions, c.divisions, c.square_roots);
    // Thesis: Table I (4-state, 6 measurements) and Ch. VI.E (8-state, 4 × per row).
    let (t4, t8) = ((256usize, 178usize, 2usize), (4 * 270usize, 4 * 255usize, 4 * 8usize));
    let within3 = |a: usize, b: usize| a * 3 >= b && b * 3 >= a;
    let b4_32 = core::mem::size_of::<KalmanIdentifier<f32, 4, 2>>();
    let b4_64 = core::mem::size_of::<KalmanIdentifier<f64, 4, 2>>();
    let b8_32 = core::mem::size_of::<KalmanIdentifier<f32, 8, 4>>();
    let b8_64 = core::mem::size_of::<KalmanIdentifier<f64, 8, 4>>();
    // Batch LS: the stored samples of a 40,000-sample run (the thesis' 1 MB for l > 40,000).
    let mut ls = BatchLeastSquares::<f32, 4>::new(&[1, 3])?;
    let zero = SVector::<f32, 4>::zeros();
    for _ in 0..40_000 {
        ls.push(&zero, &zero)?;
    }
    let ls_bytes = ls.storage_bytes();
    let budget_ns = DT * 1e9;
    Ok(Table {
        title: "Table I: cost per update and memory".into(),
        method: format!(
            "vehid: arithmetic from the identifiers' cost(); bytes = size_of of the identifier (f32 like the thesis' 4-byte floats, f64 in brackets); ns per update = \
             wall time of {n} (4-state) / {} (8-state) updates in this run's build on this machine; batch LS = storage_bytes() after 40,000 f32 samples",
            n / 2
        ),
        rows: vec![
            TableRow {
                label: "4-state Kalman identifier, time per update".into(),
                thesis: "3.6 ms (1986 microprocessor)".into(),
                vehid: format!("{ns4:.0} ns"),
                agrees: ns4 < budget_ns,
                note: "the thesis' point is that an update fits in the 0.05 s sample interval: it does, by orders of magnitude".into(),
            },
            TableRow {
                label: "4-state Kalman identifier, arithmetic per update (mult / add / div)".into(),
                thesis: format!("{} / {} / {}", t4.0, t4.1, t4.2),
                vehid: ops(&c4),
                agrees: within3(c4.multiplications + c4.additions, t4.0 + t4.1),
                note: "vehid runs the decoupled rows (Eq 6.16–6.18, exactly equal to the full filter here); the thesis \
                       counted the stacked filter with loads and index increments on top"
                    .into(),
            },
            TableRow {
                label: "8-state decoupled Kalman identifier, arithmetic per update (mult / add / div)".into(),
                thesis: format!("{} / {} / {}", t8.0, t8.1, t8.2),
                vehid: ops(&c8),
                agrees: within3(c8.multiplications + c8.additions, t8.0 + t8.1),
                note: "thesis: 270 / 255 / 8 per row, four rows".into(),
            },
            TableRow {
                label: "4-state Kalman identifier, memory".into(),
                thesis: "352 bytes".into(),
                vehid: format!("{b4_32} bytes [{b4_64}]"),
                agrees: b4_32 <= 352,
                note: if b4_32 <= 352 { String::new() } else { "vehid keeps each row's full P (and scratch) rather than the thesis' packed storage".into() },
            },
            TableRow {
                label: "8-state decoupled Kalman identifier, time per update".into(),
                thesis: "14.5 ms".into(),
                vehid: format!("{ns8:.0} ns"),
                agrees: ns8 < budget_ns,
                note: "fits the sample interval".into(),
            },
            TableRow {
                label: "8-state decoupled Kalman identifier, memory".into(),
                thesis: "2800 bytes".into(),
                vehid: format!("{b8_32} bytes [{b8_64}]"),
                agrees: b8_32 <= 2800,
                note: if b8_32 <= 2800 { String::new() } else { "vehid keeps each row's full 8×8 P plus scratch".into() },
            },
            TableRow {
                label: "batch least squares, memory for 40,000 samples".into(),
                thesis: "≈ 1 MB".into(),
                vehid: format!("{:.2} MB", ls_bytes as f64 / 1e6),
                agrees: ls_bytes as f64 > 2.5e5 && (ls_bytes as f64) < 4e6,
                note: "same order: the data must be stored".into(),
            },
        ],
    })
}
