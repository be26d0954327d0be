//! The outlier screen of the identifiers that have none of their own ([`Screened`]): the
//! instrumental-variable, bias-compensated and stochastic-gradient identifiers and batch least
//! squares, run behind a screen with the meaning of the Kalman identifiers' gate
//! (`KalmanOptions::gate`, κ; 0: off).
//!
//! # The statistics
//! A sample `(x, z, u)` is screened — accepted (`Ok`), counted ([`Screened::screened`], and
//! on every equation by [`Identifier::gated_into`]), and not passed to the identifier, which
//! it therefore cannot change — when either test fails:
//!
//! 1. **Residual** (the Kalman gate's test; off with [`Refresh::Never`], the choice for the
//!    Kalman identifiers, which test it themselves, and the instrumental-variable ones, see
//!    there): for each identified equation `i`, the prediction
//!    error against the identifier's current estimate `p̂`, `e_i = y_i − h_iᵀ p̂`
//!    ([`Structure::residual`], in the units of the equation's measured derivative), exceeds
//!    `κ σ̂_i`, with `σ̂_i² = Σ e_i² / (n − N)` over the `n` samples since the estimate exists
//!    (`N` the parameters). Before the update this is the recursive residual of Brown, Durbin
//!    & Evans (*J. R. Stat. Soc. B* 37, 1975) up to the factor `√(1 + hᵀ P h / r)`, which tends
//!    to 1 as the estimate settles; for a least-squares estimate it is exactly the recursive
//!    residual's numerator. Active once `n ≥ N + 50` (the Kalman gate's warm-up).
//! 2. **Magnitude**: any value `v_j` of the sample (a state, a derivative, an input: also
//!    those no equation identifies, which the instruments or the regressors may still read)
//!    exceeds `κ² s_j`, with `s_j² = Σ v_j² / n` its mean square over the samples so far. By
//!    Chebyshev's inequality, `P(|v| ≥ k s) ≤ 1/k²` for any distribution with that mean square,
//!    so at `k = κ²` a good sample is screened with probability below `κ⁻⁴` (`7.7·10⁻⁴` at
//!    `κ = 6`) whatever the signal's distribution, and in practice never (36 standard
//!    deviations for a Gaussian one). It is what judges the first samples, before an estimate
//!    exists, and what an outlier in an input no equation weighs would otherwise pass. A
//!    channel with `s_j = 0` (zero so far) is not judged.
//!
//! Every sample, screened or not, enters both statistics Winsorized at the bound (`e_i²` at
//! `κ² σ̂_i²`, `v_j²` at `κ⁴ s_j²`), as the Kalman gate's: an isolated outlier moves a scale by
//! a factor `1 + (κ² − 1)/n` only, while a lasting change (a rougher road, a changed
//! dynamics), every sample of which lies beyond the bound, raises the scale by that factor
//! per sample until its samples pass (within `ln(z²/κ²) / ln(1 + (κ² − 1)/n)` samples for
//! residuals `z σ̂`): a screen does not stop the identifier from following a change.
//!
//! # The start
//! An outlier among the first samples, with no scale to judge it by, would otherwise enter
//! the exact start and make the other samples look like rounding ("lacks excitation" for
//! good). The first [`Screened::hold`] samples (16, fewer for wide samples: they fit in
//! [`START_VALUES`]) are therefore kept as well as passed on (the identifier moves, and
//! reports, as without the screen), and the identifier as built is kept beside them. When the
//! last of them arrives, each value is judged against the robust scale of its channel over
//! them, `s_j = med |v_j| / 0.6745` (the normal-consistent median absolute value: a scale no
//! single sample can move; Hampel, *J. Am. Stat. Assoc.* 69, 1974). If a sample the identifier
//! took lies beyond `κ² s_j`, the identifier restarts from its state as built and takes the
//! kept samples within the bound, in order (the others screened); otherwise nothing is redone
//! (without an outlier in the start, the screen changes nothing there). A sample the
//! identifier refuses during the start (an earlier outlier may be why) is kept and judged rather
//! than refused when another sample of the start already lies beyond the bound of those kept (at
//! least 3), else refused as without the screen. The mean squares of the magnitude test start
//! from the samples taken. The restart
//! swaps the two copies and drops the spoiled one: no allocation.
//!
//! # Transactions
//! A screened sample is skipped in the identifier's time ([`Identifier::skip_sample`]): the
//! two-axle identifiers pair the rear axle's sample with the front axle's one wheelbase
//! earlier by their place in time, and a sample left out must not shift that pairing.
//!
//! A sample is first checked (lengths; every value finite): an error changes nothing. A
//! sample passed on that the identifier refuses is refused too, and the screen's statistics
//! are left as they were. A held sample that the identifier refuses when the held samples are
//! passed on (it was accepted when it came) is counted as screened. `gate = 0` passes every
//! sample straight on: the identifier alone, bit for bit.

use super::{Dims, Identifier};
use crate::identify::iv_predictor::SAMPLE_VALUES;
use crate::structure::{Structure, MAX_EQUATIONS, MAX_PARAMS};
use crate::{Error, Real, Result};

/// Values held during the start (`hold × (2n + m)`).
pub const START_VALUES: usize = 512;

/// Samples held during the start, at most.
pub const START_SAMPLES: usize = 16;

/// Samples behind the residual scale beyond the `N` parameters before the residual test acts
/// (as the Kalman gate's).
const WARMUP: f64 = 50.0;

/// The normal-consistency factor of the median absolute value (`Φ⁻¹(3/4)`).
const MAD_NORMAL: f64 = 0.674_489_750_196_081_7;

/// When the screen re-reads the identifier's estimate for the residual test.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub enum Refresh {
    /// After every sample passed on (recursive identifiers: the estimate is a copy).
    Every,
    /// When the samples passed on have grown by a quarter since the last read (identifiers
    /// that solve on read, batch least squares: `O(log n)` solves over `n` samples).
    Geometric,
    /// Never: no residual test, the magnitude test and the held start only. For the Kalman
    /// identifiers, whose own gate tests the recursive residual, standardized by its exact
    /// variance (and cannot judge a sample of high leverage: a state far beyond the others is
    /// a new direction, its recursive residual small). For the instrumental-variable
    /// identifiers: a screen on the equation error selects samples by the very noise the
    /// instruments must be uncorrelated with, and judged against an estimate that still
    /// wanders (weak instruments, early on) it leaves out good samples and keeps the wrong
    /// estimate (measured: the quarter car with a measured input, 8 % state noise, ξ 0.2
    /// without a screen, 4·10⁷ with the residual test, the same run).
    Never,
}

/// The screen's state ([`Screened`] without its identifier and structure): what is saved
/// beside the identifier's own state.
#[derive(Debug, Clone, PartialEq)]
#[cfg_attr(
    feature = "serde",
    derive(serde::Serialize, serde::Deserialize),
    serde(bound(serialize = "T: serde::Serialize", deserialize = "T: crate::Real"))
)]
pub struct ScreenState<T> {
    gate: T,
    refresh: Refresh,
    /// Values per sample (`2n + m`), equations, parameters, samples to hold.
    width: u16,
    equations: u16,
    params: u16,
    hold: u16,
    /// Samples of the start so far (until `hold`), which of them the identifier took (bit `k`),
    /// and `open` once the start is judged.
    held: u16,
    taken: u32,
    open: bool,
    #[cfg_attr(feature = "serde", serde(with = "crate::persist::array"))]
    buf: [T; START_VALUES],
    /// Magnitude test: per value, Σ v² (Winsorized) and the samples behind it.
    #[cfg_attr(feature = "serde", serde(with = "crate::persist::array"))]
    sq: [T; SAMPLE_VALUES],
    sq_n: T,
    /// Residual test: the estimate read (when `have`), per equation Σ e² (Winsorized) and the
    /// samples behind it; the next read after `next_read` samples passed on.
    #[cfg_attr(feature = "serde", serde(with = "crate::persist::array"))]
    theta: [T; MAX_PARAMS],
    have: bool,
    #[cfg_attr(feature = "serde", serde(with = "crate::persist::array"))]
    ssr: [T; MAX_EQUATIONS],
    nobs: T,
    next_read: u64,
    /// Samples passed on, samples accepted (held and screened included), samples screened.
    passed: u64,
    seen: u64,
    screened: u64,
}

/// An identifier behind the outlier screen of the module docs: residual and magnitude tests
/// at `gate` κ (0: off), the first samples held and judged together.
///
/// # Examples
/// ```
/// use vehid_core::identify::{Identifier, IvIdentifierVec, Refresh, Screened};
/// use vehid_core::structure::Structure;
/// let s = Structure::<f64>::full_rows(4, &[1, 3])?;
/// let iv = IvIdentifierVec::<f64, 4>::exact(s, 1)?;
/// let mut id = Screened::new(iv, s, 6.0, Refresh::Every)?;
/// let mut e = [0.0; 2];
/// id.update_into(&[1e30, 0.0, 0.0, 0.0], &[0.0; 4], &[], &mut e)?; // kept, judged at the 16th
/// assert_eq!(id.samples(), 1);
/// # Ok::<(), vehid_core::Error>(())
/// ```
#[derive(Debug, Clone)]
pub struct Screened<T: Real, I> {
    inner: I,
    /// The residual test's structure; `None`: the magnitude test and the held start only
    /// ([`Screened::magnitudes_only`]).
    structure: Option<Structure<T>>,
    state: ScreenState<T>,
    /// The identifier as built, kept through the start: restarted from it, without the
    /// outliers, when the start turns out to hold one (`None` once the start is over).
    pristine: Option<I>,
}

impl<T: Real, I: Identifier<T> + Clone> Screened<T, I> {
    /// `inner` behind a screen at `gate` κ (≥ 0, 0: off; 6 in Python), the residuals those of
    /// `structure`'s identified equations at `inner`'s parameters (the same structure as the
    /// identifier's, or [`Structure::full_rows`] for a linear model's rows), the estimate
    /// re-read as `refresh` says. Build it before the first sample.
    ///
    /// # Errors
    /// [`Error::InvalidArgument`] for a `gate` not finite and ≥ 0, or a structure of other
    /// sizes than the identifier's; [`Error::Capacity`] when a sample has more than
    /// `2 MAX_STATES + MAX_INPUTS` values ([`crate::structure::MAX_STATES`],
    /// [`crate::structure::MAX_INPUTS`]) or the identifier has already taken samples.
    pub fn new(inner: I, structure: Structure<T>, gate: T, refresh: Refresh) -> Result<Self> {
        let d = inner.dims();
        if (structure.states(), structure.inputs(), structure.equations(), structure.params())
            != (d.states, d.inputs, d.equations, d.params)
        {
            return Err(Error::InvalidArgument {
                arg: "structure",
                expected: "the identifier's structure (its states, inputs, equations and parameters)",
            });
        }
        Self::build(inner, Some(structure), gate, refresh)
    }

    fn build(inner: I, structure: Option<Structure<T>>, gate: T, refresh: Refresh) -> Result<Self> {
        crate::error::check_nonneg("gate", gate)?;
        let d = inner.dims();
        if d.equations > MAX_EQUATIONS {
            return Err(Error::Capacity { arg: "equations", needed: d.equations, capacity: MAX_EQUATIONS });
        }
        if inner.samples() > 0 {
            return Err(Error::InvalidArgument { arg: "gate", expected: "a screen set before the first sample" });
        }
        let width = 2 * d.states + d.inputs;
        if width > SAMPLE_VALUES {
            return Err(Error::Capacity { arg: "states", needed: width, capacity: SAMPLE_VALUES });
        }
        let hold = (START_VALUES / width.max(1)).min(START_SAMPLES);
        let state = ScreenState {
            gate,
            refresh,
            width: width as u16,
            equations: d.equations as u16,
            // The residual test's parameters (none without a structure).
            params: structure.map_or(0, |s| s.params()) as u16,
            hold: hold as u16,
            held: 0,
            taken: 0,
            open: gate == T::zero(),
            buf: [T::zero(); START_VALUES],
            sq: [T::zero(); SAMPLE_VALUES],
            sq_n: T::zero(),
            theta: [T::zero(); MAX_PARAMS],
            have: false,
            ssr: [T::zero(); MAX_EQUATIONS],
            nobs: T::zero(),
            next_read: 0,
            passed: 0,
            seen: 0,
            screened: 0,
        };
        let pristine = (gate > T::zero()).then(|| inner.clone());
        Ok(Self { inner, structure, state, pristine })
    }

    /// `inner` behind the magnitude test and the held start only (as [`Refresh::Never`]), for an
    /// identifier whose equations no [`Structure`] holds (a linear model's rows beyond its
    /// capacity: the full car's seven rows of 14 states). The screen's state keeps no
    /// parameters.
    ///
    /// # Errors
    /// As [`Screened::new`].
    pub fn magnitudes_only(inner: I, gate: T) -> Result<Self> {
        Self::build(inner, None, gate, Refresh::Never)
    }

    /// The identifier behind the screen.
    pub fn inner(&self) -> &I {
        &self.inner
    }

    /// The identifier behind the screen, mutably (for its own settings; a sample fed to it
    /// directly bypasses the screen).
    pub fn inner_mut(&mut self) -> &mut I {
        &mut self.inner
    }

    /// The gate κ (0: off).
    pub fn gate(&self) -> T {
        self.state.gate
    }

    /// Samples screened (accepted, counted, not passed on).
    pub fn screened(&self) -> u64 {
        self.state.screened
    }

    /// Samples held at the start before any is passed on (0 with the gate off).
    pub fn hold(&self) -> usize {
        if self.state.gate == T::zero() {
            0
        } else {
            self.state.hold as usize
        }
    }

    /// The screen's state (what is saved beside the identifier's).
    pub fn state(&self) -> &ScreenState<T> {
        &self.state
    }

    /// One sample through the screen (module docs).
    fn step(&mut self, x: &[T], z: &[T], u: &[T], e: &mut [T]) -> Result<()> {
        super::checks::check_slices(self.inner.dims(), x, z, u, e)?;
        if self.state.gate == T::zero() {
            self.inner.update_into(x, z, u, e)?;
            self.state.seen += 1;
            self.state.passed += 1;
            return Ok(());
        }
        if !self.state.open {
            // The start: passed on at once (the identifier moves as without the screen), and
            // kept, to be judged together at its end.
            let k = self.state.held;
            match self.inner.update_into(x, z, u, e) {
                Ok(()) => self.state.taken |= 1 << k,
                // Refused, and the start looks sound: refused (nothing has changed).
                Err(err) if !self.start_suspect() => return Err(err),
                Err(_) => {
                    // Refused, maybe because an earlier sample of the start spoiled it: judged at
                    // the end of the start with the others; its place in time passes.
                    e.fill(T::of(f64::NAN));
                    self.inner.skip_sample();
                }
            }
            self.hold_sample(x, z, u);
            self.state.seen += 1;
            if self.state.held == self.state.hold {
                self.release(e);
            }
            return Ok(());
        }
        let (n, m) = (x.len(), u.len());
        let width = 2 * n + m;
        let mut v = [T::zero(); SAMPLE_VALUES];
        v[..n].copy_from_slice(x);
        v[n..2 * n].copy_from_slice(z);
        v[2 * n..width].copy_from_slice(u);
        let k2 = self.state.gate * self.state.gate;
        // Magnitude test, and the Winsorized mean squares it leaves.
        let mut sq = self.state.sq;
        let mut out = false;
        for (s, &vj) in sq[..width].iter_mut().zip(&v[..width]) {
            let v2 = vj * vj;
            let bound = k2 * k2 * *s / self.state.sq_n;
            if *s > T::zero() && !(v2 <= bound) {
                out = true;
                *s += bound;
            } else {
                *s += v2;
            }
        }
        // Residual test against the estimate read last (once its scale has its warm-up).
        let ne = self.state.equations as usize;
        let np = self.state.params as usize;
        let active = self.state.have && self.state.nobs >= T::of(np as f64 + WARMUP);
        let (mut res2, mut bound2) = ([T::zero(); MAX_EQUATIONS], [T::zero(); MAX_EQUATIONS]);
        if let (true, Some(structure)) = (self.state.have, &self.structure) {
            for i in 0..ne {
                let r = structure.residual(i, &self.state.theta[..np], x, z, u);
                res2[i] = r * r;
                bound2[i] = k2 * self.state.ssr[i] / (self.state.nobs - T::of(np as f64));
                if active && self.state.ssr[i] > T::zero() && !(res2[i] <= bound2[i]) {
                    out = true;
                }
            }
        }
        if out {
            e.fill(T::of(f64::NAN));
            // Keeps the identifier's time (the two-axle pairing); changes no estimate.
            self.inner.skip_sample();
        } else {
            self.inner.update_into(x, z, u, e)?;
        }
        // Nothing has failed from here on: the statistics take the sample.
        if !out {
            self.state.passed += 1;
        }
        self.state.sq = sq;
        self.state.sq_n += T::one();
        if active || (self.state.have && !out) {
            // Passed on: its residual as it is; screened (scale active): Winsorized at the gate.
            for i in 0..ne {
                let within = res2[i] <= bound2[i] || !active || self.state.ssr[i] == T::zero();
                self.state.ssr[i] += if within && res2[i].finite() { res2[i] } else { bound2[i] };
            }
            self.state.nobs += T::one();
        }
        if !out {
            self.read_estimate();
        }
        self.state.screened += u64::from(out);
        self.state.seen += 1;
        Ok(())
    }

    /// `true` when a sample the identifier took in the start so far lies beyond the robust bound
    /// of those kept (at least 3): the start is then likely spoiled, and a sample the identifier
    /// refuses is kept to be judged at its end instead of refused.
    fn start_suspect(&self) -> bool {
        let bound = self.held_bounds();
        let taken = self.state.taken;
        self.state.held >= 3
            && (0..self.state.held as usize).any(|k| taken >> k & 1 == 1 && self.held_sample(k, &bound).is_none())
    }

    /// Stores a sample of the start.
    fn hold_sample(&mut self, x: &[T], z: &[T], u: &[T]) {
        let (n, m) = (x.len(), u.len());
        let w = 2 * n + m;
        let at = self.state.held as usize * w;
        self.state.buf[at..at + n].copy_from_slice(x);
        self.state.buf[at + n..at + 2 * n].copy_from_slice(z);
        self.state.buf[at + 2 * n..at + w].copy_from_slice(u);
        self.state.held += 1;
    }

    /// The robust bound `κ² med |v_j| / 0.6745` of each value over the held samples (0: not
    /// judged, the median being 0).
    fn held_bounds(&self) -> [T; SAMPLE_VALUES] {
        let w = self.state.width as usize;
        let h = self.state.held as usize;
        let k2 = self.state.gate * self.state.gate;
        let mut bound = [T::zero(); SAMPLE_VALUES];
        if h == 0 {
            return bound;
        }
        for (j, b) in bound[..w].iter_mut().enumerate() {
            let mut col = [T::zero(); START_SAMPLES];
            for (k, c) in col[..h].iter_mut().enumerate() {
                *c = self.state.buf[k * w + j].abs();
            }
            col[..h].sort_unstable_by(|a, b| a.partial_cmp(b).unwrap_or(core::cmp::Ordering::Equal));
            let med = if h % 2 == 1 { col[h / 2] } else { (col[h / 2 - 1] + col[h / 2]) / T::of(2.0) };
            *b = k2 * med / T::of(MAD_NORMAL);
        }
        bound
    }

    /// Held sample `k` if it is within `bound` (values `x | z | u`).
    fn held_sample(&self, k: usize, bound: &[T; SAMPLE_VALUES]) -> Option<[T; SAMPLE_VALUES]> {
        let w = self.state.width as usize;
        let mut s = [T::zero(); SAMPLE_VALUES];
        s[..w].copy_from_slice(&self.state.buf[k * w..(k + 1) * w]);
        (0..w).all(|j| bound[j] == T::zero() || s[j].abs() <= bound[j]).then_some(s)
    }

    /// Judges the samples of the start against the robust bound of them all. When every sample
    /// the identifier took is within it, nothing is redone; otherwise the identifier restarts
    /// from its state as built and takes, in order, the samples within the bound (the others
    /// screened, their place in time passed); the innovations of the last sample into `e` (NaN
    /// when it was screened).
    fn release(&mut self, e: &mut [T]) {
        let d = self.inner.dims();
        let (n, m) = (d.states, d.inputs);
        let (w, h) = (2 * n + m, self.state.held as usize);
        let bound = self.held_bounds();
        let taken = self.state.taken;
        let spoiled = (0..h).any(|k| taken >> k & 1 == 1 && self.held_sample(k, &bound).is_none());
        let mut passed = [false; START_SAMPLES];
        match self.pristine.take() {
            Some(mut pristine) if spoiled => {
                // The spoiled identifier goes (no allocation: it is dropped).
                core::mem::swap(&mut self.inner, &mut pristine);
                let last = h - 1;
                for (k, ok) in passed[..h].iter_mut().enumerate() {
                    let held = self.held_sample(k, &bound);
                    let mut scratch = [T::zero(); MAX_EQUATIONS];
                    *ok = held.is_some_and(|s| {
                        let out = if k == last { &mut *e } else { &mut scratch[..d.equations] };
                        self.inner.update_into(&s[..n], &s[n..2 * n], &s[2 * n..w], out).is_ok()
                    });
                    if !*ok {
                        self.inner.skip_sample();
                        if k == last {
                            e.fill(T::of(f64::NAN));
                        }
                    }
                }
            }
            _ => {
                for (k, ok) in passed[..h].iter_mut().enumerate() {
                    *ok = taken >> k & 1 == 1;
                }
            }
        }
        for (k, &ok) in passed[..h].iter().enumerate() {
            if ok {
                self.state.passed += 1;
                for j in 0..w {
                    let v = self.state.buf[k * w + j];
                    self.state.sq[j] += v * v;
                }
                self.state.sq_n += T::one();
            } else {
                self.state.screened += 1;
            }
        }
        self.state.buf = [T::zero(); START_VALUES];
        self.state.held = 0;
        self.state.taken = 0;
        self.state.open = true;
        self.read_estimate();
    }

    /// Re-reads the estimate when due ([`Refresh`]); an estimate that does not exist yet
    /// (exact start, too few samples) turns the residual test off until it does.
    fn read_estimate(&mut self) {
        if self.state.passed < self.state.next_read || self.state.refresh == Refresh::Never || self.structure.is_none()
        {
            return;
        }
        let np = self.state.params as usize;
        let ok = self.inner.params_into(&mut self.state.theta[..np]).is_ok()
            && self.state.theta[..np].iter().all(|v| v.finite());
        if !ok && self.state.have {
            // Lost (not expected): start the residual scale again with the next estimate.
            self.state.ssr = [T::zero(); MAX_EQUATIONS];
            self.state.nobs = T::zero();
        }
        self.state.have = ok;
        self.state.next_read = match self.state.refresh {
            Refresh::Every => self.state.passed + 1,
            Refresh::Geometric => self.state.passed + (self.state.passed / 4).max(1),
            Refresh::Never => u64::MAX,
        };
    }
}

#[cfg(feature = "persist")]
/// Checks a loaded screen state: the invariants its tests rely on (counts consistent,
/// statistics finite and ≥ 0, held samples within the buffer, nothing stored beyond them).
fn check_state<T: Real>(s: &ScreenState<T>) -> Result<()> {
    let corrupt = |expected| Err(Error::InvalidArgument { arg: "state", expected });
    let (w, ne, np) = (s.width as usize, s.equations as usize, s.params as usize);
    if w > SAMPLE_VALUES || ne > MAX_EQUATIONS || np > MAX_PARAMS || s.hold as usize * w > START_VALUES {
        return corrupt("a screen's sizes within its capacity");
    }
    if !(s.gate.finite() && s.gate >= T::zero()) {
        return corrupt("a screen's gate finite and ≥ 0");
    }
    if s.held > s.hold
        || (s.open && s.held > 0)
        || (s.gate == T::zero() && !s.open)
        || (!s.open && s.held == s.hold)
        || s.taken >> s.held != 0
    {
        return corrupt("a screen's held samples within its start");
    }
    let used = s.held as usize * w;
    if !s.buf[..used].iter().all(|v| v.finite()) || s.buf[used..].iter().any(|&v| v != T::zero()) {
        return corrupt("a screen's held samples finite, nothing stored beyond them");
    }
    let nonneg = |v: &T| v.finite() && *v >= T::zero();
    let stats = s.sq[..w].iter().chain(&s.ssr[..ne]).chain([&s.sq_n, &s.nobs]);
    if !stats.into_iter().all(nonneg)
        || s.sq[w..].iter().chain(&s.ssr[ne..]).any(|&v| v != T::zero())
        || !s.theta[..np].iter().all(|v| v.finite())
        || s.theta[np..].iter().any(|&v| v != T::zero())
    {
        return corrupt("a screen's statistics finite and ≥ 0");
    }
    if s.passed.checked_add(s.screened).and_then(|v| v.checked_add(u64::from(s.held))) != Some(s.seen) {
        return corrupt("a screen's counts: samples passed on, screened and held adding up to those seen");
    }
    Ok(())
}

#[cfg(not(feature = "persist"))]
impl<T: Real, I> super::Persist for Screened<T, I> {}

/// The screen's state saved with the identifier's own; loaded only into a screen of the same
/// gate, refresh and sizes, and checked ([`Screened`]'s invariants) before it replaces
/// anything.
#[cfg(feature = "persist")]
impl<T: Real, I: Identifier<T> + super::Persist + Clone> super::Persist for Screened<T, I> {
    fn save_state(&self) -> Result<alloc::vec::Vec<u8>> {
        let pristine = match &self.pristine {
            Some(p) if !self.state.open => Some(p.save_state()?),
            _ => None,
        };
        super::persist::save(&(&self.state, self.inner.save_state()?, pristine))
    }

    fn load_state(&mut self, bytes: &[u8]) -> Result<()> {
        use super::persist::NOT_ITS_STATE;
        type Saved<T> = (ScreenState<T>, alloc::vec::Vec<u8>, Option<alloc::vec::Vec<u8>>);
        let (state, inner, saved_pristine): Saved<T> = postcard::from_bytes(bytes).map_err(|_| NOT_ITS_STATE)?;
        let (a, b) = (&self.state, &state);
        if (a.gate, a.refresh, a.width, a.equations, a.params, a.hold)
            != (b.gate, b.refresh, b.width, b.equations, b.params, b.hold)
        {
            return Err(NOT_ITS_STATE);
        }
        check_state(&state).map_err(|_| NOT_ITS_STATE)?;
        // In the start the identifier as built comes too (a restart goes back to it).
        let pristine = match (state.open, saved_pristine, &self.pristine) {
            (true, None, _) => None,
            (false, Some(b), Some(fresh)) => {
                let mut p = fresh.clone();
                p.load_state(&b)?;
                Some(p)
            }
            _ => return Err(NOT_ITS_STATE),
        };
        let mut next = Self { inner: self.inner.clone(), structure: self.structure, state, pristine };
        next.inner.load_state(&inner)?;
        *self = next;
        Ok(())
    }
}

impl<T: Real, I: Identifier<T> + Clone> Identifier<T> for Screened<T, I> {
    fn dims(&self) -> Dims {
        self.inner.dims()
    }

    fn rows(&self) -> &[usize] {
        self.inner.rows()
    }

    /// One sample through the screen (module docs): passed on, held (the start), or screened
    /// (innovations NaN). Transactional; no allocation.
    fn update_into(&mut self, x: &[T], z: &[T], u: &[T], e: &mut [T]) -> Result<()> {
        self.step(x, z, u, e)
    }

    super::interface::forward_estimate!(inner);

    /// Samples accepted: those passed on, held and screened.
    fn samples(&self) -> u64 {
        self.state.seen
    }

    /// The sample is the identifier's to skip (an outer wrapper left it out).
    fn skip_sample(&mut self) {
        self.inner.skip_sample()
    }

    /// The identifier's own count per equation plus the samples screened (each left out by
    /// every equation).
    fn gated_into(&self, out: &mut [u64]) -> Result<()> {
        self.inner.gated_into(out)?;
        for c in out.iter_mut() {
            *c += self.state.screened;
        }
        Ok(())
    }
}

#[cfg(all(test, feature = "std"))]
mod tests {
    //! One 1e30 sample (a state, a derivative identified or not, an input), after 10⁴ good
    //! ones or as the very first, changes ξ by less than 10 % behind the screen, for every
    //! identifier that has no screen of its own; seeds not tuned on.
    use super::*;
    use crate::identify::{
        BatchLeastSquares, BiasCompensatedVec, BoxedIdentifier, DynIdentifier, Gain, IvIdentifierVec,
        NoiseEstimatingBclsVec, StochasticGradientVec, StructuredGradient, StructuredPrior,
    };
    use crate::model::QuarterCar;
    use crate::sim::{SimConfig, Simulator};
    use crate::structure::StructureBuilder;
    use alloc::boxed::Box;
    use alloc::vec;
    use alloc::vec::Vec;

    const GOOD: usize = 10_000;
    const AFTER: usize = 2_000;
    const SEEDS: [u64; 3] = [41, 977, 31_337];
    /// State noise, m (8 % of the road σ: the noisy-state setting of the IV tests).
    const STATE_NOISE: f64 = 0.008;

    struct Run {
        x: Vec<[f64; 4]>,
        z: Vec<[f64; 4]>,
        u: Vec<[f64; 1]>,
    }

    fn run(seed: u64) -> Run {
        let cfg = SimConfig::new(0.05).road_sigma(0.1).ic_sigma(0.1).deriv_noise(0.005).state_noise(STATE_NOISE);
        let mut sim = Simulator::new(QuarterCar::thesis().model(), cfg, seed).unwrap();
        let mut r = Run { x: vec![], z: vec![], u: vec![] };
        for _ in 0..GOOD + AFTER {
            let s = sim.next_sample();
            r.x.push(s.r.into());
            r.z.push(s.z.into());
            r.u.push(s.u.into());
        }
        r
    }

    /// The quarter car's rows 1 and 3 with the road as a measured input (row 1: `g·w`).
    fn with_input() -> Structure<f64> {
        let (s, _) = StructureBuilder::new(&["x1", "x2", "x3", "x4"], &["w"])
            .parameters(&["a0", "a1", "a2", "a3", "g", "c0", "c1", "c2", "c3"])
            .equation("x2", "a0*x1 + a1*x2 + a2*x3 + a3*x4 + g*w")
            .equation("x4", "c0*x1 + c1*x2 + c2*x3 + c3*x4")
            .build::<f64>()
            .unwrap();
        s
    }

    /// The true parameters of `s` (the full rows, or [`with_input`]'s).
    fn truth(s: &Structure<f64>) -> Vec<f64> {
        let car = QuarterCar::<f64>::thesis();
        let th = car.theta();
        let row = |i: usize| (0..4).map(move |j| th[(i, j)]);
        if s.inputs() == 0 {
            row(0).chain(row(1)).collect()
        } else {
            row(0).chain([car.k1() / car.m_wheel()]).chain(row(1)).collect()
        }
    }

    type Build = fn(&Structure<f64>) -> (Box<dyn DynIdentifier<f64>>, Refresh);

    fn iv(s: &Structure<f64>) -> (Box<dyn DynIdentifier<f64>>, Refresh) {
        let iv = IvIdentifierVec::<f64, 8, 64>::new(*s, 1, StructuredPrior::Exact, None, &[1.0]).unwrap();
        (Box::new(iv.with_lags(6).unwrap()), Refresh::Never)
    }
    fn bc(s: &Structure<f64>) -> (Box<dyn DynIdentifier<f64>>, Refresh) {
        let sw = [STATE_NOISE * STATE_NOISE];
        (Box::new(BiasCompensatedVec::<f64, 8>::new(*s, &sw, &[], &[1.0]).unwrap()), Refresh::Geometric)
    }
    fn bc_estimate(s: &Structure<f64>) -> (Box<dyn DynIdentifier<f64>>, Refresh) {
        let iv = IvIdentifierVec::<f64, 8, 64>::new(*s, 1, StructuredPrior::Exact, None, &[1.0]).unwrap();
        let est = NoiseEstimatingBclsVec::new(iv.with_lags(6).unwrap(), &[0.005 * 0.005]).unwrap();
        (Box::new(est), Refresh::Geometric)
    }
    fn gradient(s: &Structure<f64>) -> (Box<dyn DynIdentifier<f64>>, Refresh) {
        let g = Gain::Venter { p: 0.51 };
        if s.inputs() == 0 {
            (
                Box::new(StochasticGradientVec::<f64, 4>::from_slices(&[1, 3], g, &[1.0], &[0.0], 1).unwrap()),
                Refresh::Never,
            )
        } else {
            (Box::new(StructuredGradient::<f64, 16>::new(*s, g, &[1.0], None, 1).unwrap()), Refresh::Never)
        }
    }
    fn batch(s: &Structure<f64>) -> (Box<dyn DynIdentifier<f64>>, Refresh) {
        assert_eq!(s.inputs(), 0);
        (Box::new(BatchLeastSquares::<f64, 4>::new(&[1, 3]).unwrap()), Refresh::Geometric)
    }

    fn screened(build: Build, s: &Structure<f64>, gate: f64) -> Screened<f64, BoxedIdentifier<f64>> {
        let (inner, refresh) = build(s);
        Screened::new(BoxedIdentifier(inner), *s, gate, refresh).unwrap()
    }

    /// ξ after the run with one sample inserted before sample `at`: a copy of sample `at` with
    /// value `j` of `x | z | u` set to 1e30 (`outlier = Some((j, at))`), and the samples
    /// screened.
    fn xi_with(build: Build, s: &Structure<f64>, data: &Run, outlier: Option<(usize, usize)>, gate: f64) -> (f64, u64) {
        xi_of(screened(build, s, gate), s, data, outlier)
    }

    /// [`xi_with`] on a screen built by the caller.
    fn xi_of(
        mut id: Screened<f64, BoxedIdentifier<f64>>,
        s: &Structure<f64>,
        data: &Run,
        outlier: Option<(usize, usize)>,
    ) -> (f64, u64) {
        let m = s.inputs();
        let mut e = vec![0.0; id.dims().equations];
        for k in 0..data.x.len() {
            let (mut x, mut z, mut u) = (data.x[k], data.z[k], data.u[k]);
            if let Some((j, _)) = outlier.filter(|&(_, at)| at == k) {
                match j {
                    0..=3 => x[j] = 1e30,
                    4..=7 => z[j - 4] = 1e30,
                    _ => u[0] = 1e30,
                }
                id.update_into(&x, &z, &u[..m], &mut e).unwrap();
                (x, z, u) = (data.x[k], data.z[k], data.u[k]);
            }
            id.update_into(&x, &z, &u[..m], &mut e).unwrap();
        }
        let mut p = vec![0.0; s.params()];
        id.params_into(&mut p).unwrap();
        (crate::metrics::xi(&truth(s), &p).unwrap(), id.screened())
    }

    fn check(what: &str, build: Build, inputs: bool) {
        let s = if inputs { with_input() } else { Structure::full_rows(4, &[1, 3]).unwrap() };
        // x1, x2 (states), z2 (an identified derivative), z1 (a derivative no row identifies),
        // the input.
        let mut values = vec![0, 1, 5, 4];
        if inputs {
            values.push(8);
        }
        for seed in SEEDS {
            let data = run(seed);
            let (clean, false_alarms) = xi_with(build, &s, &data, None, 6.0);
            for &j in &values {
                for at in [GOOD, 0] {
                    let (xi, screened) = xi_with(build, &s, &data, Some((j, at)), 6.0);
                    let change = (xi - clean).abs() / clean;
                    assert!(
                        change < 0.1 && screened > false_alarms,
                        "{what}, seed {seed}, value {j} at sample {at}: ξ {clean:.4} -> {xi:.4e} ({screened} screened)"
                    );
                }
            }
        }
    }

    /// The magnitude test and the held start alone (`Screened::magnitudes_only`: what guards an
    /// identifier whose rows no structure holds, the full car's) take a 1e30 state or derivative
    /// after 10⁴ samples or first: ξ within 10 %.
    #[test]
    fn the_magnitude_test_alone_takes_one_outlier() {
        let s = Structure::full_rows(4, &[1, 3]).unwrap();
        for (what, build) in [("batch", batch as Build), ("gradient", gradient)] {
            let alone = |gate: f64| Screened::magnitudes_only(BoxedIdentifier(build(&s).0), gate).unwrap();
            for seed in SEEDS {
                let data = run(seed);
                let (clean, _) = xi_of(alone(6.0), &s, &data, None);
                for j in [0, 1, 5, 4] {
                    for at in [GOOD, 0] {
                        let (xi, screened) = xi_of(alone(6.0), &s, &data, Some((j, at)));
                        let change = (xi - clean).abs() / clean;
                        assert!(
                            change < 0.1 && screened >= 1,
                            "{what}, seed {seed}, value {j} at {at}: ξ {clean:.4} -> {xi:.4e} ({screened} screened)"
                        );
                    }
                }
            }
            // Without it the outlier ruins the estimate.
            let data = run(SEEDS[0]);
            let (clean, _) = xi_of(alone(6.0), &s, &data, None);
            let (ruined, _) = xi_of(alone(0.0), &s, &data, Some((5, GOOD)));
            assert!(ruined > 10.0 * clean, "{what} without the screen: ξ {clean:.4} -> {ruined:.4e}");
        }
    }

    #[test]
    fn one_outlier_does_not_move_instrumental_variables() {
        check("IV", iv, false);
        check("IV with an input", iv, true);
    }

    #[test]
    fn one_outlier_does_not_move_bias_compensated() {
        check("BCLS", bc, false);
        check("BCLS with an input", bc, true);
    }

    #[test]
    fn one_outlier_does_not_move_noise_estimating_bias_compensated() {
        check("BCLS estimating Σ_w", bc_estimate, false);
    }

    #[test]
    fn one_outlier_does_not_move_stochastic_gradient() {
        check("stochastic gradient", gradient, false);
        check("stochastic gradient on a structure with an input", gradient, true);
    }

    #[test]
    fn one_outlier_does_not_move_batch_least_squares() {
        check("batch least squares", batch, false);
    }

    /// `gate = 0` is the identifier alone, bit for bit (the estimate after every sample, and
    /// the innovations), with nothing held and nothing counted.
    #[test]
    fn gate_zero_is_the_identifier_alone_bit_for_bit() {
        let s = Structure::full_rows(4, &[1, 3]).unwrap();
        let data = run(5);
        for build in [iv as Build, bc, bc_estimate, gradient, batch] {
            let mut a = screened(build, &s, 0.0);
            let (mut b, _) = build(&s);
            let (mut ea, mut eb) = ([0.0; 2], [0.0; 2]);
            let (mut pa, mut pb) = ([0.0; 8], [0.0; 8]);
            for k in 0..3000 {
                a.update_into(&data.x[k], &data.z[k], &[], &mut ea).unwrap();
                b.update_into(&data.x[k], &data.z[k], &[], &mut eb).unwrap();
                assert_eq!(ea.map(f64::to_bits), eb.map(f64::to_bits));
                if k % 97 == 0 {
                    let (ra, rb) = (a.params_into(&mut pa), b.params_into(&mut pb));
                    assert_eq!(ra.is_ok(), rb.is_ok());
                    assert_eq!(pa.map(f64::to_bits), pb.map(f64::to_bits));
                }
            }
            assert_eq!((a.screened(), a.hold(), a.samples()), (0, 0, 3000));
        }
    }

    /// A screened sample changes nothing but the counts: the identifier's estimate and saved
    /// state stay as they were (only the two-axle identifiers' road point moves on,
    /// `skip_sample`). A refused sample (NaN) changes nothing at all, in the start too.
    #[test]
    fn a_screened_sample_changes_the_counts_only_and_a_refused_one_nothing() {
        let s = Structure::full_rows(4, &[1, 3]).unwrap();
        let data = run(6);
        let mut id = screened(iv, &s, 6.0);
        let mut e = [0.0; 2];
        id.update_into(&data.x[0], &data.z[0], &[], &mut e).unwrap();
        let held = id.state().clone();
        assert!(id.update_into(&[f64::NAN, 0.0, 0.0, 0.0], &data.z[1], &[], &mut e).is_err());
        assert_eq!(id.state(), &held);
        for k in 1..3000 {
            id.update_into(&data.x[k], &data.z[k], &[], &mut e).unwrap();
        }
        let mut before = [0.0; 8];
        id.params_into(&mut before).unwrap();
        let inner = id.inner().0.save_state().unwrap();
        let (n, screened) = (id.samples(), id.screened());
        id.update_into(&data.x[3000], &[0.0, 1e30, 0.0, 0.0], &[], &mut e).unwrap();
        assert!(e.iter().all(|v| v.is_nan()));
        let mut after = [0.0; 8];
        id.params_into(&mut after).unwrap();
        assert_eq!(before.map(f64::to_bits), after.map(f64::to_bits));
        assert_eq!(id.inner().0.save_state().unwrap(), inner);
        assert_eq!((id.samples(), id.screened()), (n + 1, screened + 1));
        let mut g = [0; 2];
        id.gated_into(&mut g).unwrap();
        assert_eq!(g, [screened + 1; 2]);
        let state = id.state().clone();
        assert!(id.update_into(&[f64::INFINITY, 0.0, 0.0, 0.0], &data.z[3001], &[], &mut e).is_err());
        assert_eq!(id.state(), &state);
    }

    /// Saved in the start (samples held) and after it, and loaded into a fresh screen built the
    /// same way, it continues bit for bit; a state with broken invariants is refused.
    #[cfg(feature = "persist")]
    #[test]
    fn the_screen_saves_and_loads_with_its_identifier() {
        use crate::identify::Persist;
        let s = Structure::full_rows(4, &[1, 3]).unwrap();
        let data = run(7);
        for cut in [5, 2000] {
            let mut a = screened(iv, &s, 6.0);
            let mut e = [0.0; 2];
            for k in 0..cut {
                a.update_into(&data.x[k], &data.z[k], &[], &mut e).unwrap();
            }
            let bytes = a.save_state().unwrap();
            let mut b = screened(iv, &s, 6.0);
            b.load_state(&bytes).unwrap();
            assert_eq!(b.state(), a.state());
            let mut eb = [0.0; 2];
            for k in cut..cut + 500 {
                a.update_into(&data.x[k], &data.z[k], &[], &mut e).unwrap();
                b.update_into(&data.x[k], &data.z[k], &[], &mut eb).unwrap();
                assert_eq!(e.map(f64::to_bits), eb.map(f64::to_bits));
            }
            assert_eq!(b.save_state().unwrap(), a.save_state().unwrap());
            // Another gate, or broken counts, are not this screen's state.
            let mut other = screened(iv, &s, 5.0);
            assert!(other.load_state(&bytes).is_err());
            let mut bad = a.state().clone();
            bad.seen += 1;
            let inner = a.inner().0.save_state().unwrap();
            let bytes = crate::identify::persist::save(&(&bad, inner)).unwrap();
            let before = b.save_state().unwrap();
            assert!(b.load_state(&bytes).is_err());
            assert_eq!(b.save_state().unwrap(), before);
        }
    }

    /// The residual test catches what the magnitude test lets by: a body acceleration 0.5 m/s²
    /// off (tens of the body row's residual deviations, well within 36 times the channel's RMS)
    /// inserted after 10⁴ samples is screened by batch least squares and bias-compensated least
    /// squares, whose estimate is then the clean run's, bit for bit.
    #[test]
    fn the_residual_test_screens_a_moderate_outlier() {
        let s = Structure::full_rows(4, &[1, 3]).unwrap();
        for build in [batch as Build, bc] {
            for seed in [5, 6] {
                let data = run(seed);
                let fit = |bad: bool| {
                    let mut id = screened(build, &s, 6.0);
                    let mut e = [0.0; 2];
                    for k in 0..data.x.len() {
                        if bad && k == GOOD {
                            let mut z = data.z[k];
                            z[3] += 0.5;
                            id.update_into(&data.x[k], &z, &[], &mut e).unwrap();
                        }
                        id.update_into(&data.x[k], &data.z[k], &[], &mut e).unwrap();
                    }
                    let mut p = [0.0; 8];
                    id.params_into(&mut p).unwrap();
                    (p.map(f64::to_bits), id.screened())
                };
                let ((clean, n0), (with, n1)) = (fit(false), fit(true));
                assert_eq!(n1, n0 + 1, "seed {seed}: the outlier was not screened");
                assert_eq!(with, clean, "seed {seed}");
            }
        }
    }

    /// The magnitude test alone (IV: no residual test) screens a value beyond κ² = 36 times its
    /// channel's root mean square so far and passes one within it: a wheel position 40 times
    /// its RMS over the first 10⁴ samples (computed here) is screened, 30 times is not.
    #[test]
    fn the_magnitude_test_screens_beyond_kappa_squared_times_the_rms() {
        let s = Structure::full_rows(4, &[1, 3]).unwrap();
        let data = run(7);
        let rms = (data.x[..GOOD].iter().map(|x| x[0] * x[0]).sum::<f64>() / GOOD as f64).sqrt();
        for (times, screened) in [(40.0, true), (30.0, false)] {
            let mut id = screened_iv(&s);
            let mut e = [0.0; 2];
            for k in 0..GOOD {
                id.update_into(&data.x[k], &data.z[k], &[], &mut e).unwrap();
            }
            let before = id.screened();
            let mut x = data.x[GOOD];
            x[0] = times * rms;
            id.update_into(&x, &data.z[GOOD], &[], &mut e).unwrap();
            assert_eq!(id.screened() - before, u64::from(screened), "{times} × RMS");
        }
    }

    fn screened_iv(s: &Structure<f64>) -> Screened<f64, BoxedIdentifier<f64>> {
        screened(iv, s, 6.0)
    }

    /// The residual scale `σ̂² = Σe²/(nobs − p)` counts exactly the samples that had a residual,
    /// those after the estimate was first read: samples before it (or, for an identifier whose
    /// estimate the screen never reads, all of them) would add zero residuals and shrink σ̂.
    #[test]
    fn the_residual_scale_counts_only_samples_with_a_residual() {
        let s = Structure::full_rows(4, &[1, 3]).unwrap();
        let data = run(8);
        for build in [batch as Build, iv] {
            let mut id = screened(build, &s, 6.0);
            let mut e = [0.0; 2];
            let mut with_residual = 0u32;
            for k in 0..2_000 {
                with_residual += u32::from(id.state.have);
                id.update_into(&data.x[k], &data.z[k], &[], &mut e).unwrap();
            }
            assert_eq!(id.screened(), 0);
            assert_eq!(id.state.nobs, f64::from(with_residual));
        }
    }

    /// An outlier among the start's held samples is found when they are judged and the
    /// identifier restarts from the others, as they were: the estimate after the run is the
    /// clean run's, bit for bit.
    #[test]
    fn an_outlier_in_the_start_leaves_the_clean_runs_estimate() {
        let s = Structure::full_rows(4, &[1, 3]).unwrap();
        let data = run(9);
        for build in [batch as Build, bc] {
            let fit = |bad: bool| {
                let mut id = screened(build, &s, 6.0);
                let mut e = [0.0; 2];
                for k in 0..3_000 {
                    if bad && k == 5 {
                        let mut x = data.x[k];
                        x[1] = 1e6;
                        id.update_into(&x, &data.z[k], &[], &mut e).unwrap();
                    }
                    id.update_into(&data.x[k], &data.z[k], &[], &mut e).unwrap();
                }
                let mut p = [0.0; 8];
                id.params_into(&mut p).unwrap();
                (p.map(f64::to_bits), id.screened())
            };
            let ((clean, n0), (with, n1)) = (fit(false), fit(true));
            assert_eq!((n0, n1), (0, 1));
            assert_eq!(with, clean);
        }
    }
}
