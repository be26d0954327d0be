//! Diagnosis of the health monitor with the thesis' state sensors: the bias and the
//! spread of the tracked `k2/M`, `b/M` on one no-change drive (passenger quarter car, class C
//! at 15 m/s, 200 Hz), for the tracker `Rls3` (window 6 s) fed by different regressors:
//!
//! - `filter`: the deflection-only kinematic filter (`DeflectionFilter`, the monitor before);
//! - `filter_nb`: the same without the bias state's random walk (1e-4);
//! - `true d`: the true deflection with the filter's rate;
//! - `d^,vb-vw`: the filter's deflection with the raw measured rate `vb − vw`;
//! - `true both`: the true deflection and rate (only the acceleration's noise left);
//! - `kf2`: the filter with the rate measured too (`RateGain`, the monitor now).
//!
//! Per ratio: the batch least-squares estimate over the drive, the tracked estimate's mean,
//! its spread (standard deviation over the drive, sampled every second after 30 s), the
//! nominal standard error `√(σ² P_jj/(1 + λ))` the CUSUM assumes (σ² from the batch
//! residuals), and the ratio spread / nominal. Also the filter's errors and their
//! autocorrelation.
//!
//! Usage: `health_diag [noise fraction, default 0.08] [seconds, default 3600] [seed, default 7500000]`.
use vehid_core::health::{DeflectionFilter, RateGain, Rls3};
use vehid_core::model::QuarterCar;
use vehid_core::nalgebra::{SMatrix, SVector};
use vehid_core::sim::{DriveConfig, QuarterDrive, SensorNoise, SensorSet};

const DT: f64 = 0.005;

struct Track {
    name: &'static str,
    fast: Rls3<f64>,
    batch: Rls3<f64>,
    e2: f64,
    n: f64,
    th: Vec<[f64; 2]>,
    pd: Vec<[f64; 2]>,
}

impl Track {
    fn new(name: &'static str) -> Self {
        let p0 = SMatrix::<f64, 3, 3>::identity() * 1e6;
        Self {
            name,
            fast: Rls3::new(SVector::zeros(), p0, 1.0 - DT / 6.0),
            batch: Rls3::new(SVector::zeros(), p0, 1.0),
            e2: 0.0,
            n: 0.0,
            th: vec![],
            pd: vec![],
        }
    }
    fn feed(&mut self, k: usize, d: f64, v: f64, a: f64) {
        let phi = SVector::<f64, 3>::new(-d, -v, 1.0);
        self.fast.update(&phi, a);
        if let Some(e) = self.batch.update(&phi, a) {
            if k > 2000 {
                self.e2 += e * e;
                self.n += 1.0;
            }
        }
        if k > 6000 && k % 200 == 0 {
            let t = self.fast.theta();
            let p = self.fast.p();
            self.th.push([t[0], t[1]]);
            self.pd.push([p[(0, 0)], p[(1, 1)]]);
        }
    }
    fn report(&self, truth: [f64; 2]) {
        let s2 = self.e2 / self.n;
        let lam = 1.0 - DT / 6.0;
        let b = self.batch.theta();
        for j in 0..2 {
            let m = self.th.iter().map(|t| t[j]).sum::<f64>() / self.th.len() as f64;
            let sd = (self.th.iter().map(|t| (t[j] - m).powi(2)).sum::<f64>() / self.th.len() as f64).sqrt();
            let nom = (self.pd.iter().map(|p| s2 * p[j] / (1.0 + lam)).sum::<f64>() / self.pd.len() as f64).sqrt();
            println!(
                "{:>10} {}: truth {:.4} batch {:.4} ({:+.2} %), tracked mean {:.4} ({:+.2} %), spread {:.4} ({:.2} %), nominal s {:.4} ({:.2} %), ratio {:.2}",
                self.name, ["k2/M", "b/M"][j], truth[j], b[j], 100.0 * (b[j] / truth[j] - 1.0), m, 100.0 * (m / truth[j] - 1.0), sd, 100.0 * sd / truth[j], nom, 100.0 * nom / truth[j], sd / nom
            );
        }
        println!("{:>10} sigma {:.4}", self.name, s2.sqrt());
    }
}

fn main() {
    let argv: Vec<String> = std::env::args().collect();
    let f: f64 = argv.get(1).map(|s| s.parse().unwrap()).unwrap_or(0.08);
    let secs: f64 = argv.get(2).map(|s| s.parse().unwrap()).unwrap_or(3600.0);
    let seed: u64 = argv.get(3).map(|s| s.parse().unwrap()).unwrap_or(7_500_000);
    let car = QuarterCar::<f64>::passenger();
    let base = DriveConfig::new(DT).sensors(SensorSet::State);
    let mut pilot = QuarterDrive::new(car, base.clone(), 9_000_000).unwrap();
    let n = (600.0 / DT) as usize;
    let (mut s, mut s2) = ([0.0f64; 2], [0.0f64; 2]);
    for _ in 0..n {
        let y = pilot.next_sample();
        let y = y.y();
        for (j, v) in [y[2], y[7]].into_iter().enumerate() {
            s[j] += v;
            s2[j] += v * v;
        }
    }
    let sd = |j: usize| (s2[j] / n as f64 - (s[j] / n as f64).powi(2)).sqrt();
    let noise = SensorNoise { state: f * sd(0), deriv: f * sd(1), ..SensorNoise::default() };
    println!("sigma_w {:.3e} sigma_v {:.3e}", noise.state, noise.deriv);
    let mut drive = QuarterDrive::new(car, base.noise(noise), seed).unwrap();
    let sa = (2.0f64).sqrt() * noise.deriv;
    let sdn = (2.0f64).sqrt() * noise.state;
    let mut kf = DeflectionFilter::new(DT, sa, sdn, 0.01).unwrap();
    let mut kf0 = DeflectionFilter::new(DT, sa, sdn, 1e-4).unwrap();
    let gain = RateGain::new(DT, sa, sdn, sdn, 0.01).unwrap();
    let mut kf2 = DeflectionFilter::new(DT, sa, sdn, 0.01).unwrap();
    let (mut e2d, mut e2v) = (0.0, 0.0);
    let truth = [car.k2() / car.m_body(), car.b() / car.m_body()];
    let mut tr = [
        Track::new("filter"),
        Track::new("filter_nb"),
        Track::new("true d"),
        Track::new("d^,vb-vw"),
        Track::new("true both"),
        Track::new("kf2"),
    ];
    let (mut ed2, mut ev2, mut dd2, mut vv2) = (0.0, 0.0, 0.0, 0.0);
    let steps = (secs / DT) as usize;
    let mut errs: Vec<[f64; 2]> = Vec::with_capacity(steps);
    for k in 0..steps {
        let smp = drive.next_sample();
        let y = smp.y();
        let x = smp.x;
        let (dt_, vt) = (x[2] - x[0], x[3] - x[1]);
        let (d, v) = kf.update(y[2] - y[0], y[7] - y[5]);
        let (d0, v0) = kf0.update(y[2] - y[0], y[7] - y[5]);
        if k > 2000 {
            ed2 += (d - dt_).powi(2);
            ev2 += (v - vt).powi(2);
            dd2 += dt_ * dt_;
            vv2 += vt * vt;
            errs.push([d - dt_, v - vt]);
        }
        let (d2, v2) = kf2.update_rate_gated(y[2] - y[0], y[3] - y[1], y[7] - y[5], &gain, f64::MAX).unwrap();
        if k > 2000 {
            e2d += (d2 - dt_).powi(2);
            e2v += (v2 - vt).powi(2);
        }
        let a = y[7];
        tr[5].feed(k, d2, v2, a);
        tr[0].feed(k, d, v, a);
        tr[1].feed(k, d0, v0, a);
        tr[2].feed(k, dt_, v, a);
        tr[3].feed(k, d, y[3] - y[1], a);
        tr[4].feed(k, dt_, vt, a);
    }
    let m = errs.len() as f64;
    println!(
        "filter error rms: d {:.3e} ({:.1} % of std d), dv {:.3e} ({:.1} % of std dv)",
        (ed2 / m).sqrt(),
        100.0 * (ed2 / dd2).sqrt(),
        (ev2 / m).sqrt(),
        100.0 * (ev2 / vv2).sqrt()
    );
    println!("kf2 error rms: d {:.1} %, dv {:.1} %", 100.0 * (e2d / dd2).sqrt(), 100.0 * (e2v / vv2).sqrt());
    for lag in [1usize, 10, 50, 100, 200, 400] {
        let mut c = [0.0; 2];
        for i in lag..errs.len() {
            c[0] += errs[i][0] * errs[i - lag][0];
            c[1] += errs[i][1] * errs[i - lag][1];
        }
        println!("  autocorr lag {lag}: d {:.3} dv {:.3}", c[0] / ed2, c[1] / ev2);
    }
    for t in &tr {
        t.report(truth);
    }
}
