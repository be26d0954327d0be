//! The figures beyond the thesis (Fig B-1: ξ against σ_w for every method for noisy states;
//! Fig B-2: the half car on one road with noisy states; Fig B-3: real roads; Fig B-4: the full
//! car's health monitor): selected by id, seeded and
//! reproducible, their claims computed from the runs (fed another method's results, they
//! fail), mirrored as report tables marked as not the thesis'.

use vehid_thesis::beyond::{
    self, QuarterMethod, RoadsIdent, FULL_CLAIMS, FULL_SCENARIOS, HALF_CLAIMS, NOT_THESIS, ROADS_CLAIMS,
    ROADS_CONSTANTS, ROAD_CLASSES, SWEEP_CLAIMS, SWEEP_LEVELS,
};
use vehid_thesis::{run, Report, RunOptions};

fn beyond_run(seed: u64, only: &[&str], samples: usize, seeds: usize) -> Report {
    let opts = RunOptions {
        quick: true,
        seeds: Some(seeds),
        max_iterations: Some(samples),
        base_seed: seed,
        threads: Some(2),
        only: only.iter().map(|s| s.to_string()).collect(),
        tables: false,
    };
    run(&opts, &|_| {}).unwrap()
}

#[test]
fn selected_by_id_seeded_and_reproducible() {
    let a = beyond_run(1, &["B-1", "B-2"], 400, 2);
    let a2 = beyond_run(1, &["B-1", "B-2"], 400, 2);
    let b = beyond_run(2, &["B-1", "B-2"], 400, 2);
    assert!(a.figures.is_empty(), "no thesis figure was selected");
    let (s, s2, sb) = (a.sweep.as_ref().unwrap(), a2.sweep.as_ref().unwrap(), b.sweep.as_ref().unwrap());
    assert_eq!((s.samples, s.seeds, s.full_samples), (400, 2, beyond::SWEEP_SAMPLES));
    assert_eq!(s.levels, SWEEP_LEVELS);
    assert_eq!(s.curves.len(), QuarterMethod::ALL.len());
    assert!(s.origin.contains("not a figure of Kessler"));
    for ((c, c2), cb) in s.curves.iter().zip(&s2.curves).zip(&sb.curves) {
        assert_eq!(c.xi.len(), SWEEP_LEVELS.len());
        assert!(c.xi.iter().all(|v| v.len() == 2));
        let bits = |v: &[Vec<f64>]| v.iter().flatten().map(|x| x.to_bits()).collect::<Vec<_>>();
        assert_eq!(bits(&c.xi), bits(&c2.xi), "{}: reproducible from the base seed", c.label);
        assert_ne!(bits(&c.xi), bits(&cb.xi), "{}: computed from it", c.label);
        for i in 0..SWEEP_LEVELS.len() {
            assert!(c.min[i] <= c.q25[i] && c.q25[i] <= c.median[i] && c.median[i] <= c.q75[i] && c.q75[i] <= c.max[i]);
        }
    }
    assert_eq!(s.verdicts.len(), SWEEP_CLAIMS.len());
    let h = a.half_one_road.as_ref().unwrap();
    assert_eq!(h.verdicts.len(), HALF_CLAIMS.len());
    assert!(h.rows.iter().all(|r| r.cells.len() == beyond::HALF_LEVELS.len()));
    assert!(h.not_run.iter().any(|(m, _)| m.contains("EKF")));
    // Mirrored as tables, every row marked as vehid's claim.
    assert_eq!(a.tables.len(), 2);
    assert!(a
        .tables
        .iter()
        .all(|t| t.title.contains("beyond the thesis") && t.rows.iter().all(|r| r.thesis == NOT_THESIS)));
    let json = a.to_json();
    assert!(json.contains("\"sweep\"") && json.contains("\"half_one_road\"") && !json.contains("inf"));
    // One figure alone.
    let one = beyond_run(1, &["B-2"], 300, 1);
    assert!(one.sweep.is_none() && one.half_one_road.is_some() && one.figures.is_empty());
    let thesis = beyond_run(1, &["3-5"], 50, 1);
    assert!(thesis.sweep.is_none() && thesis.half_one_road.is_none() && thesis.figures.len() == 1);
    assert!(vehid_thesis::select(&["B-4".into()]).is_err());
}

/// Fig B-3 on a small size: selected by id, one cell per identifier and class, reproducible
/// from the base seed, each class its own seeds, the claims computed, mirrored as a table.
#[test]
fn real_roads_selected_seeded_and_summarized() {
    let a = beyond_run(1, &["B-3"], 4000, 2);
    let a2 = beyond_run(1, &["B-3"], 4000, 2);
    let b = beyond_run(2, &["B-3"], 4000, 2);
    assert!(a.figures.is_empty() && a.sweep.is_none() && a.half_one_road.is_none());
    let (r, r2, rb) = (a.real_roads.as_ref().unwrap(), a2.real_roads.as_ref().unwrap(), b.real_roads.as_ref().unwrap());
    assert_eq!((r.id, r.samples, r.seeds, r.full_samples), ("B-3", 4000, 2, beyond::ROADS_SAMPLES));
    assert_eq!(r.classes, ["A", "B", "C", "D", "E"]);
    assert_eq!(
        (r.constants.as_slice(), r.truth.as_slice()),
        (&ROADS_CONSTANTS[..], &[320.0, 200_000.0, 22_000.0, 1_500.0][..])
    );
    assert_eq!(r.known.value, 40.0);
    assert!(r.origin.contains("not a figure of Kessler"));
    assert_eq!(r.rows.len(), RoadsIdent::ALL.len());
    let bits = |r: &vehid_thesis::RoadsResult| {
        r.rows
            .iter()
            .flat_map(|row| row.cells.iter().flat_map(|c| c.value.iter().flatten()))
            .map(|v| v.to_bits())
            .collect::<Vec<_>>()
    };
    assert_eq!(bits(r), bits(r2), "reproducible from the base seed");
    assert_ne!(bits(r), bits(rb), "computed from it");
    for row in &r.rows {
        assert_eq!(row.cells.len(), ROAD_CLASSES.len());
        for c in &row.cells {
            assert!(c.errors.is_empty() && c.refused == 0, "{}: {:?}", row.label, c.errors);
            for k in 0..4 {
                assert_eq!((c.value[k].len(), c.rel_err[k].len()), (2, 2));
                assert!(c.min[k] <= c.median[k] && c.median[k] <= c.max[k]);
                for s in 0..2 {
                    assert!(c.lo[k][s] < c.value[k][s] && c.value[k][s] < c.hi[k][s]);
                    let want = (c.value[k][s] / r.truth[k] - 1.0).abs();
                    assert_eq!(c.rel_err[k][s], want);
                }
                let held = (0..2).filter(|&s| c.lo[k][s] <= r.truth[k] && r.truth[k] <= c.hi[k][s]).count();
                assert_eq!(c.covered[k], held);
            }
        }
    }
    // Each class its own seeds: no two classes give the same estimates (the car is linear,
    // so on a common seed they would, up to rounding).
    let real = &r.rows[1].cells;
    for i in 0..real.len() {
        for j in i + 1..real.len() {
            assert!((real[i].value[0][0] / real[j].value[0][0] - 1.0).abs() > 1e-6, "classes {i} and {j}");
        }
    }
    assert_eq!(r.verdicts.len(), ROADS_CLAIMS.len());
    assert_eq!(a.tables.len(), 1);
    assert!(
        a.tables[0].title.starts_with("Fig B-3, beyond the thesis")
            && a.tables[0].rows.iter().all(|t| t.thesis == NOT_THESIS)
    );
    let json = a.to_json();
    assert!(json.contains("\"real_roads\"") && json.contains("\"rel_err\"") && !json.contains("inf"));
}

/// Fig B-3's claims are computed from the runs: given the thesis' identifier's results in
/// place of the real-road one's, the real-road claims fail; given the real-road one's in
/// place of the thesis', the thesis' claims fail. (On 3 seeds of 12,000 samples only the claims
/// about the thesis' identifier and the ratio are decided; the others need the report's
/// seeds: `roads_claims_agree`.)
#[test]
fn real_roads_claims_fail_when_fed_the_other_identifiers_results() {
    let r = beyond_run(4, &["B-3"], 12_000, 3).real_roads.unwrap();
    let agrees = |r: &vehid_thesis::RoadsResult| beyond::roads_verdicts(r).iter().map(|v| v.agrees).collect::<Vec<_>>();
    let v = agrees(&r);
    assert_eq!([v[2], v[3], v[5]], [true; 3], "{:#?}", r.verdicts);
    let mut swapped = r.clone();
    swapped.rows[1].cells = r.rows[0].cells.clone();
    assert_eq!(agrees(&swapped), [false, false, true, false, false, true]);
    let mut swapped = r.clone();
    swapped.rows[0].cells = r.rows[1].cells.clone();
    let v = agrees(&swapped);
    assert_eq!([v[2], v[3]], [false, false]);
    // A class missing: its claims cannot agree.
    let mut short = r.clone();
    short.rows.iter_mut().for_each(|row| row.cells.truncate(4));
    assert!(agrees(&short).iter().all(|a| !a));
}

/// The claims are computed from the runs: given the thesis' identifier's results in place of
/// IV on the physical structure (as if that identifier had run), the claims on IV fail.
#[test]
fn claims_fail_when_fed_another_methods_results() {
    let r = beyond_run(3, &["B-1", "B-2"], 3000, 3);
    let mut s = r.sweep.clone().unwrap();
    let idx = |m: QuarterMethod| QuarterMethod::ALL.iter().position(|&x| x == m).unwrap();
    let iv_ok = |s: &vehid_thesis::SweepResult| {
        beyond::sweep_verdicts(s)
            .into_iter()
            .filter(|v| {
                v.claim.contains("IV on the physical structure") || v.claim.contains("every method on the physical")
            })
            .map(|v| v.agrees)
            .collect::<Vec<_>>()
    };
    assert_eq!(iv_ok(&s), [true, true], "{:?}", beyond::sweep_verdicts(&s));
    let kalman = s.curves[idx(QuarterMethod::KalmanRows)].clone();
    let iv = idx(QuarterMethod::IvPhysical);
    s.curves[iv] = vehid_thesis::SweepCurve { label: s.curves[iv].label, setup: s.curves[iv].setup, ..kalman };
    assert_eq!(iv_ok(&s), [false, false]);
    // Fig B-2: road cancellation on the physical structure given the plain rows' results.
    let mut h = r.half_one_road.clone().unwrap();
    let before = beyond::half_verdicts(&h);
    assert!(before[1].agrees, "{:?}", before[1]);
    h.rows[2].cells = h.rows[0].cells.clone();
    assert!(!beyond::half_verdicts(&h)[1].agrees);
}

/// The claims of both figures agree in the quick mode (10,000 samples, 10 seeds, base seed
/// 1986; about 9 s of CPU in release): `cargo test --release -p vehid-thesis --test beyond
/// -- --ignored --nocapture`. `VEHID_FULL=1` runs the full mode (40,000 samples, 16 seeds).
#[test]
#[ignore]
fn claims_agree() {
    let quick = std::env::var("VEHID_FULL").is_err();
    let opts = RunOptions { quick, only: vec!["B-1".into(), "B-2".into()], tables: false, ..RunOptions::default() };
    let r = run(&opts, &|_| {}).unwrap();
    let (s, h) = (r.sweep.unwrap(), r.half_one_road.unwrap());
    eprintln!("{}\n\n{}", beyond::sweep_numbers(&s), beyond::half_numbers(&h));
    for v in s.verdicts.iter().chain(&h.verdicts) {
        eprintln!("[{}] {} -> {}", if v.agrees { "agrees" } else { "DIFFERS" }, v.claim, v.measured);
    }
    eprintln!("wall {:.1} s; B-1 {:.1} s and B-2 {:.1} s of CPU", r.seconds, s.cpu_seconds, h.cpu_seconds);
    assert!(s.verdicts.iter().chain(&h.verdicts).all(|v| v.agrees));
}

/// Fig B-3's claims agree in the quick mode (12,000 samples, 10 seeds per class, base seed
/// 1986; a few seconds of CPU): `cargo test --release -p vehid-thesis --test beyond -- --ignored
/// --nocapture roads`. `VEHID_FULL=1` runs the full mode (60,000 samples, 16 seeds).
#[test]
#[ignore]
fn roads_claims_agree() {
    let quick = std::env::var("VEHID_FULL").is_err();
    let base_seed = std::env::var("VEHID_SEED").ok().and_then(|s| s.parse().ok()).unwrap_or(1986);
    let opts = RunOptions { quick, base_seed, only: vec!["B-3".into()], tables: false, ..RunOptions::default() };
    let r = run(&opts, &|_| {}).unwrap();
    let roads = r.real_roads.unwrap();
    eprintln!("{}", beyond::roads_numbers(&roads));
    for v in &roads.verdicts {
        eprintln!("[{}] {} -> {}", if v.agrees { "agrees" } else { "DIFFERS" }, v.claim, v.measured);
    }
    eprintln!("wall {:.1} s; B-3 {:.1} s of CPU", r.seconds, roads.cpu_seconds);
    assert!(roads.verdicts.iter().all(|v| v.agrees));
}

/// Fig B-4 (the full car's health monitor): selected by id, reproducible from the base seed, a
/// row per scenario with a result per seed, its claims agreeing on the runs and mirrored as a
/// report table; fed a wrong result, each claim fails.
#[test]
fn full_car_figure_is_seeded_and_its_claims_fail_on_wrong_results() {
    // 18,000 samples: the whole 90 s drive (a cap shorter than that shortens the drives).
    let a = beyond_run(7, &["B-4"], 18_000, 4);
    let a2 = beyond_run(7, &["B-4"], 18_000, 4);
    assert!(a.figures.is_empty() && a.sweep.is_none() && a.real_roads.is_none());
    let r = a.full_car.as_ref().unwrap();
    assert_eq!((r.id, r.seeds, r.seconds, r.rows.len()), ("B-4", 4, beyond::full::FULL_SECONDS, FULL_SCENARIOS.len()));
    let bits =
        |r: &vehid_thesis::FullResult| r.rows.iter().flat_map(|w| &w.delay).map(|x| x.to_bits()).collect::<Vec<_>>();
    assert_eq!(bits(r), bits(a2.full_car.as_ref().unwrap()), "reproducible from the base seed");
    for (row, sc) in r.rows.iter().zip(&FULL_SCENARIOS) {
        assert_eq!((row.label, row.expect, row.named.len(), row.delay.len()), (sc.label, sc.expect, 4, 4));
    }
    assert_eq!(r.verdicts.len(), FULL_CLAIMS.len());
    for v in &r.verdicts {
        assert!(v.agrees, "{}: {}", v.claim, v.measured);
    }
    assert_eq!(a.tables.len(), 1);
    assert!(a.tables[0].title.starts_with("Fig B-4, beyond the thesis") && a.tables[0].rows.len() == FULL_CLAIMS.len());
    assert!(a.to_json().contains("\"full_car\""));
    assert!(a.tables[0].method.contains("damper fl −10 %: named 4/4"), "{}", a.tables[0].method);

    // Each claim against a result that breaks it (the others may break too).
    let agrees = |r: &vehid_thesis::FullResult, i: usize| beyond::full_verdicts(r)[i].agrees;
    let changed = |f: &dyn Fn(&mut vehid_thesis::FullRow)| {
        let mut w = r.clone();
        w.rows.iter_mut().filter(|row| !row.expect.is_empty()).for_each(f);
        w
    };
    // Another corner named (the front left's changes named at the front right).
    let mut wrong_corner = r.clone();
    for row in wrong_corner.rows.iter_mut() {
        row.named.iter_mut().for_each(|n| *n = n.replace("_fl", "_fr").replace('M', "b_rr"));
    }
    assert!(!agrees(&wrong_corner, 0) && !agrees(&wrong_corner, 1));
    assert!(!agrees(&changed(&|row| row.delay.iter_mut().for_each(|d| *d += 10.0)), 2));
    assert!(!agrees(&changed(&|row| row.delay[0] = f64::INFINITY), 3));
    assert!(!agrees(&changed(&|row| row.change.iter_mut().for_each(|c| *c += 3.5)), 4));
    let mut alarm = r.clone();
    alarm.rows.last_mut().unwrap().early = 1;
    assert!(!agrees(&alarm, 5));
    // The bars: named as their axle's springs, their size 9 points off.
    let mut as_springs = r.clone();
    for row in as_springs.rows.iter_mut() {
        row.named.iter_mut().for_each(|n| *n = n.replace("arb_f", "k_fl").replace("arb_r", "k_rl"));
    }
    assert!(!agrees(&as_springs, 6) && agrees(&as_springs, 0));
    let mut bar_size = r.clone();
    bar_size.rows.iter_mut().filter(|row| row.label.starts_with("anti-roll")).for_each(|row| {
        row.change.iter_mut().for_each(|c| *c += 9.0);
    });
    assert!(!agrees(&bar_size, 7) && agrees(&bar_size, 4));
    // The point load: named elsewhere (wrong_corner names it b_rr), read as a spread load.
    assert!(!agrees(&wrong_corner, 8));
    let mut spread = r.clone();
    spread.rows.iter_mut().filter(|row| row.label.starts_with("load")).for_each(|row| {
        row.change.iter_mut().for_each(|c| *c += 12.0);
    });
    assert!(!agrees(&spread, 9) && agrees(&spread, 4));
}
