//! Two parallel ISO 8608 tracks (the left and right wheel paths) with a left/right coherence.
//!
//! **Each track** has the displacement PSD of the quarter car's road (`drive.rs`,
//! `iso8608.rs`): `G(n) = G_d(n0) n0² / (n² + n_c²)` (cycles/m), the ISO 8608 line `∝ n⁻²`
//! above the small cutoff `n_c`, with the stationary variance `σ_r² = π n0² G_d(n0) / (2 n_c)`.
//!
//! **Coherence.** The two tracks are `l = s + d`, `r = s − d`: a common profile `s` and half
//! their difference `d`, independent of each other. Their spectra are chosen so that each
//! track keeps `G(n)` and the normalized cross-spectrum is
//!
//! ```text
//! γ(n) = G_lr(n) / G(n) = 1 / (1 + (n / n_a)²),      n_a = 1.2572 / (2π B)
//! ```
//!
//! (real: the tracks are in phase; the magnitude-squared coherence is `γ²`), `B` the distance
//! between the wheel paths (the track width). This is a rational fit of the coherence of an
//! *isotropic* road surface (Dodds & Robson, "The description of road surface roughness",
//! *J. Sound Vib.* 31 (1973) 175–183; Kamash & Robson, "The application of isotropy in road
//! surface modelling", *J. Sound Vib.* 57 (1978) 89–100): for a profile spectrum `∝ n⁻²`,
//! the isotropic surface's two-dimensional spectrum `∝ |κ|⁻³` gives
//! `γ_iso(n) = 2π n B · K₁(2π n B)` (`K₁` the modified Bessel function); the rational form
//! equals it where it is ½ (`2π n B = 1.2572`) and stays within 0.041 of it at every `n`. Long
//! waves are common to both tracks (coherence → 1), short ones independent (→ 0); a car with
//! a 1.5 m track sees half coherence at 0.13 cycles/m (7.5 m waves).
//!
//! **Realization.** With `ω_c = 2π n_c`, `ω_a = 2π n_a` (rad/m) and `C = 2 ω_c σ_r²`, the
//! spectra `G_s = G (n²/2 + n_a²)/(n² + n_a²)` and `G_d = G (n²/2)/(n² + n_a²)` are those of
//! `s = α_s x₁ + β_s y₁` and `d = α_d x₂ + β_d y₂`, where each pair `(x, y)` is two
//! Ornstein–Uhlenbeck processes in distance with rates `ω_c`, `ω_a` driven by one white noise
//! (`dx = −ω_c x ds + dW`, `dy = −ω_a y ds + dW`), the pairs independent, and
//!
//! ```text
//! α_d = √(C/2) ω_c / (ω_c − ω_a)      β_d = −√(C/2) ω_a / (ω_c − ω_a)
//! α_s = √C (ω_a − ω_c/√2) / (ω_a − ω_c)      β_s = √(C/2) − α_s
//! ```
//!
//! (partial fractions of `√(C/2) iω / ((iω + ω_c)(iω + ω_a))` and of
//! `√(C/2) (iω + √2 ω_a) / (…)`). Over a step `Δs` each pair is advanced exactly: `x ← e^{−ω_c
//! Δs} x + w₁`, `y ← e^{−ω_a Δs} y + w₂` with the joint Gaussian increment of covariance
//! `[(1 − e^{−2ω_cΔs})/(2ω_c), (1 − e^{−(ω_c+ω_a)Δs})/(ω_c+ω_a); ·, (1 − e^{−2ω_aΔs})/(2ω_a)]`
//! (times `σ_r²` of the current class). So, as for the single track, the sampled tracks have
//! the model's spectra at any spacing and speed.

use super::iso8608::{RoadClass, N0};
use crate::error::check_positive;
use crate::{Error, Result};
use core::f64::consts::PI;
use rand::rngs::Xoshiro256PlusPlus;
use rand_distr::{Distribution, StandardNormal};

/// `2π n B` where the isotropic road's coherence `2π n B K₁(2π n B)` is ½.
pub const HALF_COHERENCE: f64 = 1.257_151_390_677_57;

/// Two parallel ISO 8608 tracks with the isotropic-road coherence (module documentation).
#[derive(Debug, Clone)]
pub struct TwoTrackRoad {
    sigma: f64,
    cutoff: f64,
    wc: f64,
    wa: f64,
    /// `[α_s, β_s, α_d, β_d]` for `σ_r = 1`.
    coef: [f64; 4],
    /// `[x₁, y₁]` (common) and `[x₂, y₂]` (difference), in metres per `σ_r` of the noise.
    s: [f64; 2],
    d: [f64; 2],
    rng: Xoshiro256PlusPlus,
}

impl TwoTrackRoad {
    /// Two tracks of `class` with shaping cutoff `cutoff` (cycles/m) whose wheel paths are
    /// `track` metres apart, started from their stationary distribution.
    ///
    /// # Errors
    /// [`Error::InvalidArgument`] for a `cutoff` or `track` not finite and > 0, or a track so
    /// wide that the coherence's corner `n_a` is not above twice the cutoff
    /// (`track < 1.2572 / (4π n_c)`, 10 m at the default cutoff).
    pub fn new(class: RoadClass, cutoff: f64, track: f64, rng: Xoshiro256PlusPlus) -> Result<Self> {
        check_positive("cutoff", cutoff)?;
        check_positive("track", track)?;
        let na = HALF_COHERENCE / (2.0 * PI * track);
        if na <= 2.0 * cutoff {
            return Err(Error::InvalidArgument {
                arg: "track",
                expected: "a track width below 1.2572 / (4π cutoff) (10 m at the default cutoff)",
            });
        }
        let (wc, wa) = (2.0 * PI * cutoff, 2.0 * PI * na);
        let c = 2.0 * wc;
        let h = libm::sqrt(c / 2.0);
        let alpha_s = libm::sqrt(c) * (wa - wc / core::f64::consts::SQRT_2) / (wa - wc);
        let coef = [alpha_s, h - alpha_s, h * wc / (wc - wa), -h * wa / (wc - wa)];
        let sigma = Self::sigma_of(class, cutoff);
        let mut road = Self { sigma, cutoff, wc, wa, coef, s: [0.0; 2], d: [0.0; 2], rng };
        // Stationary start: each pair's covariance is the step's covariance for Δs → ∞.
        let [e1, e2, e3, e4] = road.normals();
        road.s = road.increment(f64::INFINITY, e1, e2);
        road.d = road.increment(f64::INFINITY, e3, e4);
        Ok(road)
    }

    fn sigma_of(class: RoadClass, cutoff: f64) -> f64 {
        libm::sqrt(PI * N0 * N0 * class.gd0() / (2.0 * cutoff))
    }

    fn normals(&mut self) -> [f64; 4] {
        let mut e = [0.0; 4];
        for v in e.iter_mut() {
            *v = StandardNormal.sample(&mut self.rng);
        }
        e
    }

    /// The Gaussian increment of one pair over `ds` (times `σ_r`) from two standard normals:
    /// the Cholesky factor of the covariance in the module documentation.
    fn increment(&self, ds: f64, e1: f64, e2: f64) -> [f64; 2] {
        let (wc, wa) = (self.wc, self.wa);
        // 1 − e^{−w ds}, accurate for small ds.
        let one_minus = |w: f64| if ds.is_infinite() { 1.0 } else { -libm::expm1(-w * ds) };
        let q11 = one_minus(2.0 * wc) / (2.0 * wc);
        let q12 = one_minus(wc + wa) / (wc + wa);
        let q22 = one_minus(2.0 * wa) / (2.0 * wa);
        let l11 = libm::sqrt(q11);
        let l21 = if l11 > 0.0 { q12 / l11 } else { 0.0 };
        let l22 = libm::sqrt((q22 - l21 * l21).max(0.0));
        [self.sigma * l11 * e1, self.sigma * (l21 * e1 + l22 * e2)]
    }

    /// The current heights `[left, right]`, m.
    pub fn heights(&self) -> [f64; 2] {
        let [as_, bs, ad, bd] = self.coef;
        let s = as_ * self.s[0] + bs * self.s[1];
        let d = ad * self.d[0] + bd * self.d[1];
        [s + d, s - d]
    }

    /// The stationary standard deviation of each track's height, `σ_r`, m.
    pub fn sigma(&self) -> f64 {
        self.sigma
    }

    /// The coherence corner `n_a`, cycles/m: `γ(n) = 1 / (1 + (n/n_a)²)`.
    pub fn coherence_corner(&self) -> f64 {
        self.wa / (2.0 * PI)
    }

    /// The model's normalized cross-spectrum `γ(n) = G_lr(n) / G(n)` at `n` cycles/m.
    pub fn coherence(&self, n: f64) -> f64 {
        let r = n / self.coherence_corner();
        1.0 / (1.0 + r * r)
    }

    /// Continues on a road of another class from the current heights (the spread relaxes to
    /// the new class over a few `1/(2π n_c)` metres, as for the single track).
    pub fn set_class(&mut self, class: RoadClass) {
        self.sigma = Self::sigma_of(class, self.cutoff);
    }

    /// Moves `ds ≥ 0` metres along both tracks (nothing moves for `ds = 0`).
    pub fn advance(&mut self, ds: f64) {
        if ds > 0.0 {
            let (pc, pa) = (libm::exp(-self.wc * ds), libm::exp(-self.wa * ds));
            let [e1, e2, e3, e4] = self.normals();
            let ws = self.increment(ds, e1, e2);
            let wd = self.increment(ds, e3, e4);
            self.s = [pc * self.s[0] + ws[0], pa * self.s[1] + ws[1]];
            self.d = [pc * self.d[0] + wd[0], pa * self.d[1] + wd[1]];
        }
    }
}
