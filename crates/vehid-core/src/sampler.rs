//! Distance-triggered ("asynchronous") sampling for two axles on one road (Ch. VI.D,
//! thesis-notes §3, Eq 6.9 and 6.12–6.14).
//!
//! The rear wheel meets the front wheel's road one wheelbase `L = l1 + l2` later
//! (`u2(t) = u1(t − L/v)`, Eq 6.9). If samples are taken every `spacing` metres of travel
//! (`Δ`), and `L = d·Δ`, then at sample `k` the rear axle is over the road point where the
//! front axle was at sample `k − d`, whatever the speed profile. [`AxleSampler`] turns
//! odometry into those sampling decisions and pairs each sample with the earlier front-axle
//! sample whose road point the rear axle is now over.
//!
//! # Semantics
//! - Grid points lie at odometry `s0 + g·Δ`, `g = 0, 1, 2, …`, with `s0 = 0` m until a
//!   [`AxleSampler::reset`].
//! - Feeding odometry `s` (m, non-decreasing) triggers a sample as soon as `s` reaches the
//!   next grid point; the sample is taken *at `s`* (the caller samples now), so the point
//!   actually sampled overshoots the grid point by what the vehicle travelled since the
//!   previous odometry reading. Feed often enough (travel per reading ≤ tolerance / 2), or
//!   use [`AxleSampler::time_to_next`] to schedule the sample exactly.
//! - A sample at `s_k` is paired with the earlier sample `k'` taken on grid point `g − d`
//!   when `|(s_k − L) − s_k'| ≤ tolerance`; otherwise it is reported unpaired. So *no pair
//!   ever differs by more than the tolerance*, by construction.
//! - A stopped vehicle (odometry not advancing, speed 0) produces no samples; nothing is
//!   divided by the speed.
//! - Odometry that jumps over one or more grid points triggers one sample (on the last grid
//!   point passed); the skipped points are simply missing, and the samples that would have
//!   paired with them come out unpaired.
//! - Odometry that runs backwards is an error ([`Error::InvalidArgument`], argument `s`) and
//!   leaves the sampler unchanged; [`AxleSampler::reset`] starts a new grid (e.g. after the
//!   vehicle reversed), forgetting every earlier sample.
//!
//! Capacity: the sampler remembers the last `d` samples in a ring of `C` slots, so `C ≥ d`
//! (the constructor reports the capacity needed otherwise). No allocation anywhere.

use crate::error::{check_nonneg, check_positive};
use crate::{Error, Real, Result};

/// A fixed-capacity ring buffer's storage: an array `[X; C]` (no allocation) or, with
/// `alloc`, a `Vec<X>` sized at construction. Used by [`AxleSampler`] and by
/// [`crate::identify::TwoAxle`] to remember the last `d` samples.
pub trait RingStore<X>: Clone + core::fmt::Debug {
    /// A buffer with (at least) `len` slots, each `x`.
    ///
    /// # Errors
    /// [`Error::Capacity`] naming `arg` when a fixed array has fewer than `len` slots.
    fn with_len(arg: &'static str, len: usize, x: X) -> Result<Self>;
    /// The slots in use.
    fn slots(&self) -> &[X];
    /// The slots in use, mutably.
    fn slots_mut(&mut self) -> &mut [X];
    /// A buffer of the slots `items` yields, in order (how a deserialized ring is read back,
    /// without allocating for arrays); `Ok(None)` when their number does not fit (an array
    /// takes exactly its length, and a ring is never empty).
    ///
    /// # Errors
    /// The first `Err` that `items` yields.
    fn from_items<E>(items: impl Iterator<Item = core::result::Result<X, E>>) -> core::result::Result<Option<Self>, E>;
}

impl<X: Copy + core::fmt::Debug, const C: usize> RingStore<X> for [X; C] {
    fn with_len(arg: &'static str, len: usize, x: X) -> Result<Self> {
        if len > C {
            return Err(Error::Capacity { arg, needed: len, capacity: C });
        }
        Ok([x; C])
    }
    fn slots(&self) -> &[X] {
        self
    }
    fn slots_mut(&mut self) -> &mut [X] {
        self
    }
    fn from_items<E>(items: impl Iterator<Item = core::result::Result<X, E>>) -> core::result::Result<Option<Self>, E> {
        crate::array::array_from_items(items)
    }
}

#[cfg(feature = "alloc")]
impl<X: Copy + core::fmt::Debug> RingStore<X> for alloc::vec::Vec<X> {
    fn with_len(arg: &'static str, len: usize, x: X) -> Result<Self> {
        // The length comes from the caller (e.g. wheelbase / spacing): allocate fallibly.
        let len = len.max(1);
        let mut v = alloc::vec::Vec::new();
        v.try_reserve_exact(len)
            .map_err(|_| Error::OutOfMemory { what: arg, bytes: len.saturating_mul(core::mem::size_of::<X>()) })?;
        v.resize(len, x);
        Ok(v)
    }
    fn slots(&self) -> &[X] {
        self
    }
    fn slots_mut(&mut self) -> &mut [X] {
        self
    }
    fn from_items<E>(items: impl Iterator<Item = core::result::Result<X, E>>) -> core::result::Result<Option<Self>, E> {
        let v = items.collect::<core::result::Result<Self, E>>()?;
        Ok((!v.is_empty()).then_some(v))
    }
}

/// The number of road points `d` between the axles: `L / Δ` rounded to the nearest integer,
/// with `|d·Δ − L|` (m) the geometric pairing residual.
///
/// # Errors
/// [`Error::InvalidArgument`] for a wheelbase or spacing that is not finite and > 0, or a
/// spacing longer than twice the wheelbase (`d` would be 0).
pub fn axle_delay<T: Real>(wheelbase: T, spacing: T) -> Result<(usize, T)> {
    check_positive("wheelbase", wheelbase)?;
    check_positive("spacing", spacing)?;
    let ratio = (wheelbase / spacing).to_f64();
    let d = libm::round(ratio);
    if !(1.0..1e9).contains(&d) {
        return Err(Error::InvalidArgument {
            arg: "spacing",
            expected: "a spacing between 1e-9 and 2 times the wheelbase (d = wheelbase/spacing road points ≥ 1)",
        });
    }
    let residual = T::of(libm::fabs(d * spacing.to_f64() - wheelbase.to_f64()));
    Ok((d as usize, residual))
}

/// One remembered sample.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Slot<T> {
    /// Grid point index `g`.
    pub grid: u64,
    /// Sample number (0, 1, 2, … in the order emitted).
    pub sample: u64,
    /// Odometry at which it was taken, m.
    pub position: T,
    /// `false` for an empty slot.
    pub valid: bool,
}

/// The earlier front-axle sample a rear-axle sample is paired with.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Pair<T> {
    /// Sample number of the earlier sample.
    pub sample: u64,
    /// Its grid point index (`g − d`).
    pub grid: u64,
    /// `|(s_k − L) − s_k'|`, m: how far the rear axle now is from the road point the front
    /// axle was sampled on (≤ the tolerance).
    pub error: T,
}

/// A decision to sample now.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Trigger<T> {
    /// Sample number (0, 1, 2, …).
    pub sample: u64,
    /// Grid point index `g` (road point `g·Δ` m from the start); consecutive unless odometry
    /// jumped.
    pub grid: u64,
    /// Odometry at the sample, m (≥ `g·Δ`).
    pub position: T,
    /// The earlier sample the rear axle is now over, within the tolerance; `None` for the
    /// first `d` samples, after a reset, or when a jump made the match worse than the
    /// tolerance.
    pub pair: Option<Pair<T>>,
}

/// The asynchronous sampler of Ch. VI.D with a ring of `C` slots (`C ≥ d = L/Δ`); see the
/// [module documentation](self) for the exact semantics.
///
/// # Examples
/// ```
/// use vehid_core::sampler::AxleSampler;
/// // Wheelbase 3 m, a sample every 0.3 m (d = 10), pairs within 1 cm.
/// let mut s = AxleSampler::<f64, 16>::new(3.0, 0.3, 0.01)?;
/// let mut pairs = 0;
/// for step in 0..10_000 {
///     // 6 m/s, odometry read every millisecond.
///     if let Some(t) = s.advance(6.0, 0.001)? {
///         if let Some(p) = t.pair {
///             assert!(p.error <= 0.01);
///             pairs += 1;
///         }
///     }
/// #   let _ = step;
/// }
/// assert!(pairs > 150);
/// # Ok::<(), vehid_core::Error>(())
/// ```
#[derive(Debug, Clone)]
pub struct AxleSampler<T: Real, const C: usize> {
    wheelbase: T,
    spacing: T,
    tolerance: T,
    d: usize,
    origin: T,
    s: T,
    next_grid: u64,
    samples: u64,
    ring: [Slot<T>; C],
}

impl<T: Real, const C: usize> AxleSampler<T, C> {
    /// A sampler for axles `wheelbase` m apart, sampling every `spacing` m, pairing within
    /// `tolerance` m. Odometry starts at 0 m; the first sample is at 0 m.
    ///
    /// # Errors
    /// [`Error::InvalidArgument`] for a wheelbase or spacing not finite and > 0, a negative
    /// or non-finite tolerance, or a spacing that does not divide the wheelbase to within the
    /// tolerance (`|d·Δ − L| > tolerance`: no sample could ever be paired);
    /// [`Error::Capacity`] when `C < d` (the error names `d`, the capacity needed).
    pub fn new(wheelbase: T, spacing: T, tolerance: T) -> Result<Self> {
        check_nonneg("tolerance", tolerance)?;
        let (d, residual) = axle_delay(wheelbase, spacing)?;
        if residual > tolerance {
            return Err(Error::InvalidArgument {
                arg: "spacing",
                expected:
                    "a spacing that divides the wheelbase to within the tolerance (|d·spacing − wheelbase| ≤ tolerance)",
            });
        }
        if d > C {
            return Err(Error::Capacity { arg: "AxleSampler capacity C", needed: d, capacity: C });
        }
        let empty = Slot { grid: 0, sample: 0, position: T::zero(), valid: false };
        Ok(Self {
            wheelbase,
            spacing,
            tolerance,
            d,
            origin: T::zero(),
            s: T::zero(),
            next_grid: 0,
            samples: 0,
            ring: [empty; C],
        })
    }

    /// Road points between the axles, `d = round(L / Δ)`.
    pub fn delay(&self) -> usize {
        self.d
    }

    /// Sample spacing `Δ`, m.
    pub fn spacing(&self) -> T {
        self.spacing
    }

    /// Wheelbase `L`, m.
    pub fn wheelbase(&self) -> T {
        self.wheelbase
    }

    /// Pairing tolerance, m.
    pub fn tolerance(&self) -> T {
        self.tolerance
    }

    /// Last odometry reading, m.
    pub fn position(&self) -> T {
        self.s
    }

    /// Samples emitted so far.
    pub fn samples(&self) -> u64 {
        self.samples
    }

    /// Distance (m) still to travel to the next grid point (0 when a reading at the current
    /// position would already trigger).
    pub fn distance_to_next(&self) -> T {
        let target = self.origin + T::of(self.next_grid as f64) * self.spacing;
        let d = target - self.s;
        if d > T::zero() {
            d
        } else {
            T::zero()
        }
    }

    /// Time (s) until the next grid point at a constant `speed` (m/s): schedule the next
    /// reading then and the sample lands exactly on the grid. `None` for a stopped vehicle
    /// (or an invalid speed): it will never get there.
    pub fn time_to_next(&self, speed: T) -> Option<T> {
        if speed.finite() && speed > T::zero() {
            Some(self.distance_to_next() / speed)
        } else {
            None
        }
    }

    /// Feeds an odometry reading `s` (m, from the start); returns `Some` when a sample is to
    /// be taken now.
    ///
    /// # Errors
    /// [`Error::NonFinite`] for NaN/inf; [`Error::InvalidArgument`] (argument `s`) when `s` is
    /// smaller than the previous reading (odometry running backwards: call
    /// [`AxleSampler::reset`]). The sampler is unchanged after an error.
    pub fn feed_distance(&mut self, s: T) -> Result<Option<Trigger<T>>> {
        if !s.finite() {
            return Err(Error::NonFinite { arg: "s", index: 0 });
        }
        if s < self.s {
            return Err(Error::InvalidArgument {
                arg: "s",
                expected: "non-decreasing odometry (it ran backwards: call reset() to start a new grid)",
            });
        }
        let target = self.origin + T::of(self.next_grid as f64) * self.spacing;
        if s < target {
            self.s = s;
            return Ok(None);
        }
        // The last grid point passed (≥ the next one due): the sample is at `s`.
        let passed = libm::floor(((s - self.origin) / self.spacing).to_f64());
        let g = if passed.is_finite() && passed > self.next_grid as f64 && passed < 9.0e15 {
            passed as u64
        } else {
            self.next_grid
        };
        let pair = if g >= self.d as u64 {
            let want = g - self.d as u64;
            let slot = self.ring[(want % C as u64) as usize];
            let error = (s - self.wheelbase - slot.position).abs();
            if slot.valid && slot.grid == want && error <= self.tolerance {
                Some(Pair { sample: slot.sample, grid: want, error })
            } else {
                None
            }
        } else {
            None
        };
        if C > 0 {
            self.ring[(g % C as u64) as usize] = Slot { grid: g, sample: self.samples, position: s, valid: true };
        }
        let t = Trigger { sample: self.samples, grid: g, position: s, pair };
        self.samples += 1;
        self.next_grid = g + 1;
        self.s = s;
        Ok(Some(t))
    }

    /// Feeds motion instead of distance: the vehicle moved at `speed` (m/s, ≥ 0) for `dt`
    /// seconds (≥ 0) since the previous reading. A stopped vehicle (`speed = 0`) never
    /// triggers.
    ///
    /// # Errors
    /// [`Error::InvalidArgument`] for a negative or non-finite speed or time step (the
    /// sampler is then unchanged).
    pub fn advance(&mut self, speed: T, dt: T) -> Result<Option<Trigger<T>>> {
        check_nonneg("speed", speed)?;
        check_nonneg("dt", dt)?;
        let s = self.s + speed * dt;
        if !s.finite() {
            return Err(Error::InvalidArgument { arg: "dt", expected: "speed·dt small enough to stay finite" });
        }
        self.feed_distance(s)
    }

    /// Starts a new grid at odometry `s` (m): the next reading ≥ `s` triggers grid point 0
    /// again at `s`, every earlier sample is forgotten (so the next `d` samples are unpaired),
    /// sample numbers continue. Use after the vehicle reversed or the odometer was reset.
    ///
    /// # Errors
    /// [`Error::NonFinite`] for NaN/inf (the sampler is then unchanged).
    pub fn reset(&mut self, s: T) -> Result<()> {
        if !s.finite() {
            return Err(Error::NonFinite { arg: "s", index: 0 });
        }
        for slot in self.ring.iter_mut() {
            slot.valid = false;
        }
        self.origin = s;
        self.s = s;
        self.next_grid = 0;
        Ok(())
    }
}
