//! Sensor faults must never look like a changed car: over drives of the passenger quarter car
//! with nothing changed, a sensor fault from 60 s on (a bias step of 1, 5 and 100 deflection
//! standard deviations, a drifting deflection zero, the deflection's gain ×0.9 and ×1.1, an
//! inverted deflection, the two accelerometers swapped, a stuck channel, an accelerometer
//! bias step) gives no event, and the monitor says it cannot judge at some point after the
//! fault where the fault is visible in the data (module documentation of `health`,
//! `consistency.rs`). A real change is still found with the check in place
//! (`health_behaviour.rs`, `health::tests`).
//!
//! The half car and the full car likewise (their front (left) corner's channels; the full car
//! also its rear right corner's).
//!
//! Seeds 61_000 onwards, not used while the check's constants were chosen (58_000–58_099).

use vehid_core::health::{FullHealthMonitor, HalfHealthMonitor, HealthConfig, HealthMonitor, Reason, Status};
use vehid_core::model::{FullCar, HalfCar, QuarterCar};
use vehid_core::sim::{DriveConfig, FullDrive, FullDriveConfig, HalfDrive, HalfDriveConfig, QuarterDrive};

const DT: f64 = 0.005;
const FAULT_AT: f64 = 60.0;
const SECONDS: f64 = 120.0;

/// A sensor fault applied to the samples from `FAULT_AT` on; `sd` is the deflection's standard
/// deviation over the drive's first 20 s, m.
#[derive(Debug, Clone, Copy)]
pub enum Fault {
    /// The deflection's zero steps by this many standard deviations.
    BiasStep(f64),
    /// The deflection's zero drifts by one standard deviation per this many seconds.
    Drift(f64),
    /// The deflection is read with this gain.
    Gain(f64),
    /// The deflection's sign is flipped.
    Inverted,
    /// `a_body` and `a_wheel` are swapped.
    Swapped,
    /// The wheel accelerometer repeats its last value.
    Stuck,
    /// The body accelerometer's zero steps by this much, m/s².
    AccelBias(f64),
}

impl Fault {
    /// Applies the fault to the channels `[a_body, a_wheel, deflection]` at indices `at` of `y`.
    fn apply(self, y: &mut [f64], at: [usize; 3], t: f64, sd: f64, held: &mut Option<f64>) {
        let dt = t - FAULT_AT;
        let [ab, aw, d] = at;
        match self {
            Fault::BiasStep(n) => y[d] += n * sd,
            Fault::Drift(per) => y[d] += sd * dt / per,
            Fault::Gain(g) => y[d] *= g,
            Fault::Inverted => y[d] = -y[d],
            Fault::Swapped => y.swap(ab, aw),
            Fault::Stuck => y[aw] = *held.get_or_insert(y[aw]),
            Fault::AccelBias(b) => y[ab] += b,
        }
    }

    /// Whether the data show the fault to a kinematic check (an accelerometer's bias step
    /// does not: the kinematic filter's bias state and the offset `c` absorb it, correctly).
    fn visible(self) -> bool {
        !matches!(self, Fault::AccelBias(_) | Fault::Drift(_))
    }
}

/// A monitor of either car behind one interface, for the drives below.
trait Monitor {
    fn feed(&mut self, y: &[f64]) -> bool;
    fn status(&self) -> Status;
}

impl Monitor for HealthMonitor<f64> {
    fn feed(&mut self, y: &[f64]) -> bool {
        self.update(y).unwrap().is_some()
    }
    fn status(&self) -> Status {
        HealthMonitor::status(self)
    }
}

impl Monitor for HalfHealthMonitor<f64> {
    fn feed(&mut self, y: &[f64]) -> bool {
        self.update(y).unwrap().is_some()
    }
    fn status(&self) -> Status {
        HalfHealthMonitor::status(self)
    }
}

impl Monitor for FullHealthMonitor<f64> {
    fn feed(&mut self, y: &[f64]) -> bool {
        self.update(y).unwrap().is_some()
    }
    fn status(&self) -> Status {
        FullHealthMonitor::status(self)
    }
}

/// One drive with `fault` on the channels `at` (`[a_body, a_wheel, deflection]`; the half
/// car's front corner): (events, whether the status was "cannot judge" for a reason other
/// than low excitation at some sample after the fault, the share of the samples from 10 s
/// after the fault on whose status is "cannot judge: sensors disagree").
fn outcome_with(
    mut next: impl FnMut() -> Vec<f64>,
    mon: &mut dyn Monitor,
    fault: Fault,
    at: [usize; 3],
) -> (usize, bool, f64) {
    let n = (SECONDS / DT) as usize;
    let (mut s1, mut s2, mut m) = (0.0, 0.0, 0.0);
    let (mut events, mut flagged, mut held) = (0, false, None);
    let (mut late, mut disagree) = (0usize, 0usize);
    for k in 0..n {
        let t = k as f64 * DT;
        let mut y = next();
        if t < 20.0 {
            s1 += y[at[2]];
            s2 += y[at[2]] * y[at[2]];
            m += 1.0;
        }
        if t >= FAULT_AT {
            let sd = (s2 / m - (s1 / m) * (s1 / m)).sqrt();
            fault.apply(&mut y, at, t, sd, &mut held);
        }
        events += usize::from(mon.feed(&y));
        if t >= FAULT_AT {
            flagged |= matches!(mon.status(), Status::CannotJudge(r) if r != Reason::LowExcitation);
        }
        if t >= FAULT_AT + 10.0 {
            late += 1;
            disagree += usize::from(mon.status() == Status::CannotJudge(Reason::Sensors));
        }
    }
    (events, flagged, disagree as f64 / late as f64)
}

/// The passenger quarter car (class C, 15 m/s, 200 Hz, realistic sensors) with `fault`.
pub fn run(seed: u64, fault: Fault) -> (usize, bool) {
    let (events, flagged, _) = quarter_outcome(seed, fault);
    (events, flagged)
}

/// [`run`] with the share of "sensors disagree" ([`outcome_with`]).
fn quarter_outcome(seed: u64, fault: Fault) -> (usize, bool, f64) {
    let car = QuarterCar::<f64>::passenger();
    let mut drive = QuarterDrive::new(car, DriveConfig::new(DT), seed).unwrap();
    let mut mon = HealthMonitor::new(HealthConfig::new(DT, car)).unwrap();
    outcome_with(|| drive.next_sample().y().to_vec(), &mut mon, fault, [0, 1, 2])
}

/// The passenger half car with `fault` on its front corner (channels `a_body_f`, `a_wheel_f`,
/// `deflection_f` at 0, 2, 4).
pub fn run_half(seed: u64, fault: Fault) -> (usize, bool) {
    let (events, flagged, _) = half_outcome(seed, fault);
    (events, flagged)
}

/// [`run_half`] with the share of "sensors disagree" ([`outcome_with`]).
fn half_outcome(seed: u64, fault: Fault) -> (usize, bool, f64) {
    let car = HalfCar::<f64>::passenger();
    let mut drive = HalfDrive::new(car, HalfDriveConfig::new(DriveConfig::new(DT)), seed).unwrap();
    let mut mon = HalfHealthMonitor::new(HealthConfig::new(DT, car)).unwrap();
    outcome_with(|| drive.next_sample().y().to_vec(), &mut mon, fault, [0, 2, 4])
}

/// The passenger full car with `fault` on its front left corner (channels `a_body_fl`,
/// `a_wheel_fl`, `deflection_fl` at 0, 4, 8).
pub fn run_full(seed: u64, fault: Fault) -> (usize, bool) {
    run_full_at(seed, fault, [0, 4, 8])
}

/// The same on the rear right corner (channels 3, 7, 11).
pub fn run_full_rr(seed: u64, fault: Fault) -> (usize, bool) {
    run_full_at(seed, fault, [3, 7, 11])
}

fn run_full_at(seed: u64, fault: Fault, at: [usize; 3]) -> (usize, bool) {
    let (events, flagged, _) = full_outcome(seed, fault, at);
    (events, flagged)
}

/// [`run_full_at`] with the share of "sensors disagree" ([`outcome_with`]).
fn full_outcome(seed: u64, fault: Fault, at: [usize; 3]) -> (usize, bool, f64) {
    let car = FullCar::<f64>::passenger();
    let mut drive = FullDrive::new(car, FullDriveConfig::new(DriveConfig::new(DT)), seed).unwrap();
    let mut mon = FullHealthMonitor::new(HealthConfig::new(DT, car)).unwrap();
    outcome_with(|| drive.next_sample().y().to_vec(), &mut mon, fault, at)
}

fn check(fault: Fault, seeds: core::ops::Range<u64>) {
    check_with(run, fault, seeds.clone());
    check_with(run_half, fault, seeds.start..seeds.start + HALF_SEEDS);
    check_with(run_full, fault, seeds.start..seeds.start + FULL_SEEDS);
    check_with(run_full_rr, fault, seeds.start + FULL_SEEDS..seeds.start + 2 * FULL_SEEDS);
}

fn check_with(run: fn(u64, Fault) -> (usize, bool), fault: Fault, seeds: core::ops::Range<u64>) {
    let mut with_events = Vec::new();
    let mut unflagged = 0;
    for seed in seeds {
        let (events, flagged) = run(seed, fault);
        if events > 0 {
            with_events.push(seed);
        }
        unflagged += usize::from(!flagged);
    }
    assert!(with_events.is_empty(), "{fault:?}: events on seeds {with_events:?}");
    if fault.visible() {
        assert_eq!(unflagged, 0, "{fault:?}: never 'cannot judge' after the fault on {unflagged} drives");
    }
}

const SEEDS: core::ops::Range<u64> = 61_000..61_012;
/// The half car's drives per fault (each costs about three quarter-car drives).
const HALF_SEEDS: u64 = 4;
/// The full car's drives per fault and corner.
const FULL_SEEDS: u64 = 2;

#[test]
fn a_bias_step_of_the_deflection_is_no_event() {
    for n in [1.0, 5.0, 100.0] {
        check(Fault::BiasStep(n), SEEDS);
    }
}

#[test]
fn a_drifting_deflection_zero_is_no_event() {
    check(Fault::Drift(10.0), SEEDS);
}

#[test]
fn a_deflection_gain_off_by_ten_percent_is_no_event() {
    check(Fault::Gain(0.9), SEEDS);
    check(Fault::Gain(1.1), SEEDS);
}

/// A deflection gain off by 2 %: under the check's tolerance (2 % of the defaults), yet it
/// moves `k2/M` by about 3 %, past the CUSUM's allowance, and looks like a spring change
/// (`health::GAIN_LEVERAGE`). An event is held back when a gain has moved by a third of the
/// event's size, so such a drive mostly reports nothing (it need not say "cannot judge": the
/// gain's move is within the tolerance). ×0.98 and ×1.02 on 20 quarter-car drives each (seeds
/// 61_100–61_119, not used while the rule was made): at most 6 of the 40 with an event; on 10
/// half-car drives each (the front deflection): at most 7 of the 20. Without the rule 36 and
/// 44 of 50 quarter-car drives gave one (`check_gain --fault-gain`, seeds 67_000–67_049, the
/// fault at 120 s of 180), with it 2 and 2; on seeds 61_200–61_209 (×0.98 and ×1.02 together)
/// the quarter car 17 of 20 before and 1 after, the half car 14 and 3, the full car (front
/// left) 2 and 0.
#[test]
fn a_deflection_gain_off_by_two_percent_is_seldom_an_event() {
    for (car, run, seeds, most) in
        [("quarter", run as fn(u64, Fault) -> (usize, bool), 61_100..61_120, 6), ("half", run_half, 61_100..61_110, 7)]
    {
        let mut with_events = Vec::new();
        for gain in [0.98, 1.02] {
            for seed in seeds.clone() {
                if run(seed, Fault::Gain(gain)).0 > 0 {
                    with_events.push((gain, seed));
                }
            }
        }
        let n = 2 * seeds.count();
        assert!(with_events.len() <= most, "{car}: events on {} of {n} drives: {with_events:?}", with_events.len());
    }
}

#[test]
fn inverted_swapped_and_stuck_channels_are_no_event() {
    check(Fault::Inverted, SEEDS);
    check(Fault::Swapped, SEEDS);
    check(Fault::Stuck, SEEDS);
}

#[test]
fn an_accelerometer_bias_step_is_no_event() {
    check(Fault::AccelBias(0.5), SEEDS);
}

/// The issue-sized figure: 100 drives of each car per fault kind, fresh seeds 65_000–65_099 (62_000–62_099 were used while the pre-report look at the gain was added, 64_000–64_099 for the figure before the check ran at 100 Hz).
/// `cargo test --release -p vehid-core --test integration sensor_faults::hundred -- --ignored
/// --nocapture` (about a minute per fault kind on one core).
#[test]
#[ignore]
fn hundred_drives_per_fault_kind() {
    let kinds = [
        Fault::BiasStep(1.0),
        Fault::BiasStep(5.0),
        Fault::BiasStep(100.0),
        Fault::Drift(10.0),
        Fault::Gain(0.9),
        Fault::Gain(1.1),
        Fault::Inverted,
        Fault::Swapped,
        Fault::Stuck,
        Fault::AccelBias(0.5),
    ];
    let mut bad = Vec::new();
    for fault in kinds {
        for (name, run) in [
            ("quarter", run as fn(u64, Fault) -> (usize, bool)),
            ("half", run_half),
            ("full, front left", run_full),
            ("full, rear right", run_full_rr),
        ] {
            let (mut ev, mut flagged) = (Vec::new(), 0);
            for seed in 65_000..65_100 {
                let (e, f) = run(seed, fault);
                if e > 0 {
                    ev.push(seed);
                }
                flagged += usize::from(f);
            }
            println!(
                "{fault:?} {name}: drives with an event {}/100 {ev:?}, 'cannot judge' after the fault {flagged}/100",
                ev.len()
            );
            if !ev.is_empty() {
                bad.push((fault, name, ev));
            }
        }
    }
    assert!(bad.is_empty(), "{bad:?}");
}

/// While a deflection gain fault lasts, the status says so: "cannot judge: sensors disagree"
/// for most of the time from 10 s after the fault (docs/capabilities/health.md, "Sensor
/// faults"), not "monitoring" with events held back one at a time. Gain ×0.9 and ×1.1 on
/// the quarter car, the half car's front and the full car's front left corner, seeds
/// 61_310–61_312: at least half of those samples on every drive (0.87–1.0 on seeds
/// 61_300–61_302; about 0.01 when the full car's monitor judged on while the sensors
/// disagreed).
#[test]
fn a_gain_fault_is_said_while_it_lasts() {
    for fault in [Fault::Gain(0.9), Fault::Gain(1.1)] {
        for seed in 61_310..61_313 {
            for (car, share) in [
                ("quarter", quarter_outcome(seed, fault).2),
                ("half", half_outcome(seed, fault).2),
                ("full", full_outcome(seed, fault, [0, 4, 8]).2),
            ] {
                assert!(share >= 0.5, "{fault:?}, seed {seed}, {car}: 'sensors disagree' {share:.3} of the time");
            }
        }
    }
}
