//! Identification when the unmeasured road input is not white: the equations quasi-differenced
//! by the road's own shaping filter in distance, then identified by any identifier.
//!
//! **Why.** The thesis drives the wheel with white road noise (Eq 4.25), and least squares
//! (every Kalman form, batch least squares) needs the unmeasured input to be uncorrelated with
//! the regressors. A real road is not white: ISO 8608 gives its height a displacement PSD
//! `G_d(n) = G_d(n0) (n/n0)⁻²` by distance, the spectrum of a random walk. The wheel
//! equation `ẍ_w = θᵀφ + c·h(s)` (`c = k1/m`, `h` the road height at the distance `s`
//! travelled) then has a slow, large error term that follows the wheel's own position, and
//! least squares on it is biased without bound (on a passenger car the body mass comes out at
//! a sixth of its value, with a tight interval).
//!
//! **What this does.** The road is modelled as the first-order shaping filter of ISO 8608
//! road generation (an Ornstein–Uhlenbeck process in distance, cutoff `n_c` cycles/m; `n_c =
//! 0` is the pure random walk): over the distance `Δs_k` travelled between two samples,
//! `h_k = ρ_k h_{k−1} + η_k` with `ρ_k = exp(−2π n_c Δs_k)` and `η_k` independent of
//! everything up to sample `k − 1`, variance proportional to `1 − ρ_k²` (to `Δs_k` for the
//! random walk). Every sample is replaced by its quasi-difference
//! `x̃_k = x_k − ρ_k x_{k−1}` (the same for the measured derivative `z` and the measured
//! inputs `u`), scaled by `w_k = √(Δs_ref / Δs_k)` when the distance varies, so that its road
//! term `w_k c η_k` has one variance throughout. An equation linear in the samples,
//! `z_i = θᵀφ(x, z, u) + c h`, becomes `z̃_i = θᵀφ(x̃, z̃, ũ) + c w η`: the same parameters
//! with a white error (Cochrane & Orcutt 1949 for a regression with AR(1) errors; first
//! differences are the GLS transformation for random-walk errors).
//!
//! **Which identifier inside.** The error `η_k` is white, but not independent of the current
//! regressors: a road is a continuous profile, so the states at sample `k` have already felt
//! the road between the two samples, which is part of `η_k`. Least squares on the differenced
//! samples is therefore still biased (on the passenger car on class C: body mass −5 kg for
//! 320). Instruments from the past are not: the regressors of sample `k − d` (`d ≥ 1`) are
//! independent of `η_k`. So the identifier to wrap is
//! [`InstrumentalVariables`](super::InstrumentalVariables) (`delay = 1` for clean states,
//! `≥ 2` with white sensor noise, whose difference is correlated over two samples). This is
//! the estimator of Anderson & Hsiao (1981, "Estimation of dynamic models with error
//! components", *JASA* 76: first differences, instruments from before the differenced
//! error). A Kalman identifier or batch least squares may be wrapped too (consistent only when
//! the road is held constant between samples, as in the thesis' simulation).
//!
//! **What it needs.** Equations linear in the states, derivatives and measured inputs (no
//! offsets, `sign`, `pos` or `neg`: their differences are not the terms of differences; an
//! offset vanishes and is not identifiable): [`Differenced::new`] checks the structure. The
//! distance travelled per sample: constant ([`Travel::PerSample`], speed × sample interval)
//! or read from an odometer given as the last measured input ([`Travel::Odometer`], metres,
//! never decreasing). The cutoff: the shaping filter's `n_c` ([`RoadModel::Shaped`]; vehid's
//! ISO 8608 drives use 0.01 cycles/m) or none ([`RoadModel::RandomWalk`]). With a random
//! walk assumed on a road whose long wavelengths are flatter, the leftover `(ρ − 1) h` term
//! biases the wheel equation by about `2π n_c v dt` relative to the road's increment (on the
//! passenger car at 30 m/s: +1.5 % on k1, −1.1 % on M); the estimates stay within a few
//! percent but their intervals no longer cover.
//!
//! **Smooth roads: samples far enough apart.** The argument above needs the road's increments
//! between two differenced samples to be independent of the earlier ones. In vehid's ISO 8608
//! drives they are (the road is an AR(1) in distance with independent steps), but a real road
//! as a tyre feels it is smooth at short distances: ISO 8608 defines the spectrum up to 2.83
//! cycles/m, and the contact patch filters shorter wavelengths out. Its increments over
//! neighbouring stretches are then correlated over about `1/(2 n_max) ≈ 0.18` m, and at
//! 200 Hz and 15 m/s (7.5 cm per sample) instruments from one sample back are correlated with
//! the error: on such a road (generated independently of vehid, by random-phase harmonics,
//! integrated by scipy) the body mass came out 32 % low. So only samples at least
//! `min_spacing` apart are differenced ([`DEFAULT_MIN_SPACING`] = 0.25 m; the samples between
//! are skipped), which restores the estimate (within 2 % there, the intervals covering);
//! [`Differenced::with_min_spacing`]`(0)` uses every sample, for data whose road increments
//! are independent from sample to sample (vehid's own drives).
//!
//! **Tyre lift-off.** On a rough road at speed the tyre leaves the ground, where the linear
//! model does not hold (the road pushes, never pulls), and the constants come out biased.
//! [`Differenced::with_contact`] counts the samples whose tyre force, from the measured
//! accelerations, is (nearly) zero ([`Contact`]), so that such a run is flagged. Leaving them
//! out does not help: it selects samples on the road height, the error (see [`Contact`]).
//!
//! **Not covered.** A road with another spectrum (its increments not white after the
//! filter) and sensor noise that is not white.

use super::checks::check_lengths;
use super::interface::{Dims, Identifier};
use crate::error::{check_finite, check_nonneg, check_positive};
use crate::structure::{Basis, Structure, MAX_INPUTS, MAX_STATES};
use crate::{Error, Real, Result};

#[cfg(feature = "alloc")]
mod boxed;
mod identifier;

#[cfg(feature = "alloc")]
pub use boxed::BoxedIdentifier;

/// Values of one stored sample: `x` and `z` (`n` each), the inputs `u` and the odometer.
const SAMPLE_VALUES: usize = 2 * MAX_STATES + MAX_INPUTS + 1;

/// Default least distance between two differenced samples, m: ISO 8608's spectrum ends at
/// 2.83 cycles/m (and a tyre envelopes shorter wavelengths), so the road's increments over
/// stretches longer than `1/(2 × 2.83) ≈ 0.18` m are nearly independent (module docs,
/// "Smooth roads").
pub const DEFAULT_MIN_SPACING: f64 = 0.25;

/// Largest weight `w_k = √(Δs_ref / Δs_k)` given to one sample (a vehicle standing still
/// travels no distance: its sample is weighted as one that travelled `Δs_ref / 100`).
pub const MAX_ROAD_WEIGHT: f64 = 10.0;

/// The tyre's contact with the road, checked on every sample's measured accelerations. The
/// tyre force of a wheel and the body it carries is `F = (m_w + m_b) g + m_w a_w + m_b a_b`
/// (accelerations of the states: deviations from the static equilibrium, as vehid's quarter car
/// has them); in flight it is 0, the centre of mass falling at exactly `g`. A sample whose `F`
/// is below [`LIFT_OFF_LOAD`] of the static load `(m_w + m_b) g` is counted as off the ground
/// or about to leave it ([`Differenced::lifted`]); the margin covers rounding (in flight `F` is
/// 0 only to rounding) and a nominal body mass up to 10 % off (`m_b a_b` then moves by up to 5 %
/// of the load).
///
/// The samples are counted, not left out: the linear model does not hold in flight, but leaving
/// the flight samples out selects samples on the tyre force, which depends on the road height,
/// the equations' error; on class E at 25 m/s (off the ground a fifth of the time) that made the
/// body mass 46 % high where keeping them gave 18 %. A run with lifted samples is to be flagged,
/// its constants not trusted (module docs, "Tyre lift-off").
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct Contact<T> {
    /// Index in `z` of the wheel's vertical acceleration (the quarter car: 1).
    pub wheel: u8,
    /// Index in `z` of the body's vertical acceleration (the quarter car: 3).
    pub body: u8,
    /// The wheel (unsprung) mass, kg (> 0).
    pub m_wheel: T,
    /// The body (sprung) mass the wheel carries, kg (> 0; a nominal value serves: the test
    /// moves by `Δm_b (a_b + g)`).
    pub m_body: T,
}

/// Standard gravity, m/s² (the contact check's `g`).
const G: f64 = 9.80665;

/// The share of the static tyre load below which a sample is counted as off the ground
/// ([`Contact`]). On class E at 25 m/s (a tyre that lifts off a fifth of the time; seeds
/// 8810–8814, not those it was chosen on) it missed at most 2 of about 6,200 flight samples
/// with the nominal body mass 10 % high, none with it exact or 10 % low, and counted 18–33 %
/// more samples about to lift.
pub const LIFT_OFF_LOAD: f64 = 0.2;

/// What the identifier assumes about the unmeasured road input.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub enum RoadModel<T> {
    /// A random walk in distance (ISO 8608's `n⁻²` spectrum at every wavelength): `ρ = 1`,
    /// the equations differenced.
    RandomWalk,
    /// ISO 8608's first-order shaping filter with cutoff `cutoff` (cycles/m, ≥ 0; 0 is the
    /// random walk): `ρ_k = exp(−2π n_c Δs_k)`.
    Shaped {
        /// The cutoff `n_c`, cycles/m.
        cutoff: T,
    },
}

impl<T: Real> RoadModel<T> {
    /// `2π n_c`, rad/m (0 for the random walk).
    fn rate(&self) -> T {
        match *self {
            RoadModel::RandomWalk => T::zero(),
            RoadModel::Shaped { cutoff } => T::of(2.0 * core::f64::consts::PI) * cutoff,
        }
    }
}

/// How far the vehicle travels between two samples.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub enum Travel<T> {
    /// The same distance every sample, metres (> 0): speed × sample interval.
    PerSample(T),
    /// The last measured input of every sample is an odometer reading, metres (never
    /// decreasing); `reference` (m, > 0) is the distance per sample at which a sample has
    /// weight 1 (the typical one: any value gives the same estimate up to the scale of the
    /// equations' noise variance).
    Odometer {
        /// `Δs_ref`, m.
        reference: T,
    },
}

/// An identifier fed the quasi-differenced samples `w_k (s_k − ρ_k s_{k−1})` (module
/// documentation): consistent on a road whose height is a random walk or an ISO 8608
/// shaping filter in distance, when the inner identifier uses instruments from the past.
///
/// Transactional like every identifier: a rejected sample (by this wrapper or the inner
/// identifier) changes nothing, and the next one is differenced against the last accepted.
/// The first sample (and the first after [`Differenced::restart`]) only starts a difference:
/// its innovations are 0 and the inner identifier does not see it. Per sample: one pass over
/// the sample (`2n + m` multiply-adds) and the inner update; no allocation.
///
/// # Examples
/// ```
/// use vehid_core::identify::{Differenced, Identifier, IvIdentifier, RoadModel, StructuredPrior, Travel};
/// use vehid_core::model::QuarterCar;
/// use vehid_core::sim::{DriveConfig, QuarterDrive, SensorSet};
///
/// let car = QuarterCar::<f64>::passenger();                 // 320 kg body, 40 kg wheel
/// let dt = 0.005;                                            // class C road at 15 m/s
/// let cfg = DriveConfig::new(dt).sensors(SensorSet::State);  // true states, no sensor noise
/// let mut drive = QuarterDrive::new(car, cfg, 3)?;
/// let known = [None, Some(40.0), None, None, None];         // the wheel mass m known
/// let phys = QuarterCar::<f64>::structure(known)?;          // parameters k2/M, b/M, M, k1
/// let s = *phys.structure();
/// // instruments: the (differenced) regressors one sample back; 2 groups of 2 parameters
/// let iv = IvIdentifier::<f64, 2, 2>::new(s, 1, StructuredPrior::Exact, None, &[1.0])?;
/// let road = RoadModel::Shaped { cutoff: 0.01 };             // the drive's road
/// let mut id = Differenced::new(iv, &s, road, Travel::PerSample(15.0 * dt))?;
/// let mut e = [0.0; 2];
/// for _ in 0..40_000 {
///     let y = drive.next_sample();
///     id.update_into(&y.y()[..4], &y.y()[4..], &[], &mut e)?;
/// }
/// let mut p = [0.0; 4];
/// id.params_into(&mut p)?;
/// assert!((p[2] / 320.0 - 1.0).abs() < 0.05);                // M within 5 %
/// assert!((p[3] / 200_000.0 - 1.0).abs() < 0.05);            // k1 within 5 %
/// # Ok::<(), vehid_core::Error>(())
/// ```
#[derive(Debug, Clone)]
#[cfg_attr(
    feature = "serde",
    derive(serde::Serialize, serde::Deserialize),
    serde(
        remote = "Self",
        bound(
            serialize = "T: serde::Serialize, I: serde::Serialize",
            deserialize = "T: crate::Real, I: serde::Deserialize<'de>"
        )
    )
)]
pub struct Differenced<T: Real, I> {
    inner: I,
    state: RoadState<T>,
    /// Derived from `state` once, not per sample (rebuilt on load).
    #[cfg_attr(feature = "serde", serde(skip, default = "Gap::unset"))]
    gap: Gap<T>,
}

/// At a constant distance per sample: the samples from one differenced sample to the next
/// (the least whole number whose distance reaches `min_spacing`, at least 1) and `ρ` over
/// them. With an odometer: 1 and 1 (both are worked out per sample there).
#[derive(Debug, Clone, Copy)]
struct Gap<T> {
    samples: u32,
    rho: T,
}

impl<T: Real> Gap<T> {
    fn unset() -> Self {
        Self { samples: 1, rho: T::one() }
    }

    fn of(state: &RoadState<T>) -> Self {
        match state.travel {
            Travel::PerSample(ds) => {
                let g = libm::ceil(state.min_spacing.to_f64() / ds.to_f64());
                let samples = if g.is_finite() && g >= 1.0 { g.min(f64::from(u32::MAX)) as u32 } else { 1 };
                Self { samples, rho: gap_rho(state, samples) }
            }
            Travel::Odometer { .. } => Self::unset(),
        }
    }
}

/// What [`Differenced`] keeps besides its inner identifier: the road model, the travel, and
/// the last accepted sample (to save beside an inner identifier saved another way, and to
/// rebuild with [`Differenced::with_state`]).
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(
    feature = "serde",
    derive(serde::Serialize, serde::Deserialize),
    serde(bound(serialize = "T: serde::Serialize", deserialize = "T: Real"))
)]
pub struct RoadState<T: Real> {
    road: RoadModel<T>,
    travel: Travel<T>,
    /// The last accepted sample: `x`, `z`, `u` (without the odometer), then the odometer.
    #[cfg_attr(feature = "serde", serde(with = "crate::persist::array"))]
    prev: [T; SAMPLE_VALUES],
    /// `prev` holds a sample.
    primed: bool,
    /// Samples accepted, the first of each difference and the skipped ones included.
    seen: u64,
    /// The least distance between two samples that are differenced, m (≥ 0): closer samples
    /// are skipped (module docs, "Smooth roads").
    min_spacing: T,
    /// Samples since the stored one ([`Travel::PerSample`]: the distance is this times the
    /// distance per sample).
    since: u32,
    /// The tyre contact check (None: every sample is taken as on the road).
    contact: Option<Contact<T>>,
    /// Samples counted off the ground (or about to leave it).
    lifted: u64,
}

impl<T: Real, I: Identifier<T>> Differenced<T, I> {
    /// Wraps `inner`, an identifier on `structure` (the one it was built on: for a linear
    /// model's rows, [`Structure::full_rows`]).
    ///
    /// # Errors
    /// [`Error::NotIdentifiable`] when an identified equation has an offset or a `sign`,
    /// `pos` or `neg` term (its difference is not a term of the differences);
    /// [`Error::Shape`] when `inner` does not have the structure's sizes (with
    /// [`Travel::Odometer`]: one more input, the odometer); [`Error::InvalidArgument`] for a
    /// cutoff not finite and ≥ 0 or a distance not finite and > 0.
    pub fn new(inner: I, structure: &Structure<T>, road: RoadModel<T>, travel: Travel<T>) -> Result<Self> {
        Self::check_structure(structure)?;
        if let RoadModel::Shaped { cutoff } = road {
            check_nonneg("road cutoff", cutoff)?;
        }
        match travel {
            Travel::PerSample(ds) => check_positive("distance per sample", ds)?,
            Travel::Odometer { reference } => check_positive("reference distance per sample", reference)?,
        }
        let d = inner.dims();
        if d.states != structure.states() {
            return Err(Error::Shape { arg: "states", expected: structure.states(), got: d.states });
        }
        if d.inputs != structure.inputs() {
            return Err(Error::Shape { arg: "inputs", expected: structure.inputs(), got: d.inputs });
        }
        if d.equations != structure.equations() {
            return Err(Error::Shape { arg: "equations", expected: structure.equations(), got: d.equations });
        }
        let state = RoadState {
            road,
            travel,
            prev: [T::zero(); SAMPLE_VALUES],
            primed: false,
            seen: 0,
            min_spacing: T::of(DEFAULT_MIN_SPACING),
            since: 0,
            contact: None,
            lifted: 0,
        };
        Ok(Self { inner, gap: Gap::of(&state), state })
    }

    /// Differences only samples at least `min_spacing` metres apart (≥ 0; 0: every sample;
    /// default [`DEFAULT_MIN_SPACING`]): the samples in between are checked and counted but
    /// not used (module docs, "Smooth roads").
    ///
    /// # Errors
    /// [`Error::InvalidArgument`] for a spacing not finite and ≥ 0.
    pub fn with_min_spacing(mut self, min_spacing: T) -> Result<Self> {
        check_nonneg("min_spacing", min_spacing)?;
        self.state.min_spacing = min_spacing;
        self.gap = Gap::of(&self.state);
        Ok(self)
    }

    /// Checks every sample for tyre contact ([`Contact`]) and counts the lifted ones
    /// ([`Differenced::lifted`]); they are used as any other (see [`Contact`] for why).
    ///
    /// # Errors
    /// [`Error::InvalidArgument`] for masses not finite and > 0, or an index beyond the states.
    pub fn with_contact(mut self, contact: Contact<T>) -> Result<Self> {
        check_positive("m_wheel", contact.m_wheel)?;
        check_positive("m_body", contact.m_body)?;
        let n = self.inner.dims().states;
        if contact.wheel as usize >= n || contact.body as usize >= n {
            return Err(Error::InvalidArgument { arg: "contact", expected: "acceleration indices below the states" });
        }
        self.state.contact = Some(contact);
        Ok(self)
    }

    /// The contact check in use.
    pub fn contact(&self) -> Option<Contact<T>> {
        self.state.contact
    }

    /// Samples found off the ground (or about to leave it) so far.
    pub fn lifted(&self) -> u64 {
        self.state.lifted
    }

    /// The least distance between two differenced samples, m.
    pub fn min_spacing(&self) -> T {
        self.state.min_spacing
    }

    /// Checks that every identified equation of `structure` is linear in the states,
    /// derivatives and inputs, so that differencing the samples differences the equation.
    ///
    /// # Errors
    /// [`Error::NotIdentifiable`] naming the term kind that does not difference.
    pub fn check_structure(structure: &Structure<T>) -> Result<()> {
        for i in 0..structure.equations() {
            for t in structure.terms(i) {
                match t.basis {
                    Basis::Var(_) => {}
                    Basis::One => {
                        return Err(Error::NotIdentifiable {
                            what: "an offset under a coloured-road model: differencing removes it (identify on a \
                                   white road model, or remove the offset)",
                        })
                    }
                    Basis::Sign { .. } | Basis::Pos { .. } | Basis::Neg { .. } => {
                        return Err(Error::NotIdentifiable {
                            what: "a sign/pos/neg term under a coloured-road model: the difference of a nonlinear \
                                   term is not a term of the differenced samples",
                        })
                    }
                }
            }
        }
        Ok(())
    }

    /// The identifier fed the differenced samples.
    pub fn inner(&self) -> &I {
        &self.inner
    }

    /// The road model.
    pub fn road(&self) -> RoadModel<T> {
        self.state.road
    }

    /// How the distance between samples is known.
    pub fn travel(&self) -> Travel<T> {
        self.state.travel
    }

    /// The wrapper's own state (road model, travel, last sample), e.g. to save it beside an
    /// inner identifier saved another way.
    pub fn state(&self) -> &RoadState<T> {
        &self.state
    }

    /// Rebuilds a wrapper from an inner identifier and a saved [`RoadState`] (with every check
    /// of a deserialized one).
    ///
    /// # Errors
    /// [`Error::InvalidArgument`] (`arg` "state") naming what does not fit.
    pub fn with_state(inner: I, state: RoadState<T>) -> Result<Self> {
        let v = Self { inner, gap: Gap::of(&state), state };
        v.check_state()?;
        Ok(v)
    }

    /// Forgets the last sample, so that the next one starts a new difference (after a gap in
    /// the data, or when the vehicle was lifted off the road). The estimate is kept.
    pub fn restart(&mut self) {
        self.state.primed = false;
    }

    fn odometer(&self) -> bool {
        matches!(self.state.travel, Travel::Odometer { .. })
    }
}

impl<T: Real, I: Identifier<T>> Differenced<T, I> {
    /// One sample of checked lengths: stored to start a difference, skipped (closer than
    /// `min_spacing`), or differenced and given to the inner identifier.
    fn step(&mut self, dims: Dims, x: &[T], z: &[T], u: &[T], e: &mut [T]) -> Result<()> {
        let (n, m) = (dims.states, dims.inputs - self.odometer() as usize);
        let s_now = if self.odometer() { u[m] } else { T::zero() };
        if !self.state.primed {
            // Nothing checks this sample but here: it is only stored.
            check_sample(x, z, u)?;
            self.store(x, z, &u[..m], s_now);
            self.state.primed = true;
            self.state.seen += 1;
            self.state.since = 0;
            e.fill(T::zero());
            return Ok(());
        }
        let prev = &self.state.prev;
        let (rho, w) = match self.state.travel {
            Travel::PerSample(_) => {
                let since = self.state.since.saturating_add(1);
                if since < self.gap.samples {
                    return self.skip(x, z, u, e, since);
                }
                // `since` exceeds the gap only for a state saved with another spacing.
                let rho = if since == self.gap.samples { self.gap.rho } else { gap_rho(&self.state, since) };
                (rho, T::one())
            }
            Travel::Odometer { reference } => {
                let ds = s_now - prev[2 * n + m];
                if !(ds >= T::zero() && ds.finite()) {
                    return Err(Error::InvalidArgument {
                        arg: "u_k",
                        expected: "an odometer reading (the last input, m) that is finite and never decreases",
                    });
                }
                if ds < self.state.min_spacing {
                    return self.skip(x, z, u, e, 0);
                }
                let floor = reference / T::of(MAX_ROAD_WEIGHT * MAX_ROAD_WEIGHT);
                let rate = self.state.road.rate();
                let rho = if rate == T::zero() { T::one() } else { (-(rate * ds)).exp() };
                (rho, (reference / if ds > floor { ds } else { floor }).sqrt())
            }
        };
        let mut dx = [T::zero(); MAX_STATES];
        let mut dz = [T::zero(); MAX_STATES];
        let mut du = [T::zero(); MAX_INPUTS];
        for j in 0..n {
            dx[j] = w * (x[j] - rho * prev[j]);
            dz[j] = w * (z[j] - rho * prev[n + j]);
        }
        for j in 0..m {
            du[j] = w * (u[j] - rho * prev[2 * n + j]);
        }
        // A NaN or infinity in the sample, or a difference that overflows, makes a difference
        // non-finite, which the inner identifier refuses (naming r_k, z_k or u_k), changing
        // nothing; the stored sample is replaced only after it took the sample.
        self.inner.update_into(&dx[..n], &dz[..n], &du[..m], e)?;
        self.store(x, z, &u[..m], s_now);
        self.state.seen += 1;
        self.state.since = 0;
        Ok(())
    }

    /// A sample closer than `min_spacing` to the stored one: checked, counted, not used.
    fn skip(&mut self, x: &[T], z: &[T], u: &[T], e: &mut [T], since: u32) -> Result<()> {
        check_sample(x, z, u)?;
        self.state.since = since;
        self.state.seen += 1;
        e.fill(T::zero());
        Ok(())
    }

    fn store(&mut self, x: &[T], z: &[T], u: &[T], s: T) {
        let n = x.len();
        let prev = &mut self.state.prev;
        prev[..n].copy_from_slice(x);
        prev[n..2 * n].copy_from_slice(z);
        prev[2 * n..2 * n + u.len()].copy_from_slice(u);
        prev[2 * n + u.len()] = s;
    }

    /// Checks a deserialized wrapper (feature `serde`): as [`Differenced::with_state`].
    #[cfg(feature = "serde")]
    pub(crate) fn restored(&mut self) -> Result<()> {
        self.check_state()?;
        self.gap = Gap::of(&self.state);
        Ok(())
    }

    /// The state's settings valid, the stored sample finite and 0 beyond the inner
    /// identifier's sizes, and `seen` at least the inner identifier's count.
    fn check_state(&self) -> Result<()> {
        let corrupt = |expected| Err(Error::InvalidArgument { arg: "state", expected });
        let st = &self.state;
        let ok_road = match st.road {
            RoadModel::RandomWalk => true,
            RoadModel::Shaped { cutoff } => cutoff.finite() && cutoff >= T::zero(),
        };
        let ok_travel = match st.travel {
            Travel::PerSample(v) | Travel::Odometer { reference: v } => v.finite() && v > T::zero(),
        };
        if !(ok_road && ok_travel) {
            return corrupt("a differenced identifier's cutoff ≥ 0 and distance > 0");
        }
        let d = self.inner.dims();
        let used = 2 * d.states + d.inputs + 1;
        if used > SAMPLE_VALUES || d.states > MAX_STATES || d.inputs > MAX_INPUTS {
            return corrupt("a differenced identifier within the sample capacity");
        }
        if !st.prev.iter().all(|v| v.finite()) || st.prev[used..].iter().any(|v| *v != T::zero()) {
            return corrupt("a differenced identifier's last sample finite (and 0 beyond its size)");
        }
        if let Some(c) = st.contact {
            let ok = c.m_wheel.finite() && c.m_wheel > T::zero() && c.m_body.finite() && c.m_body > T::zero();
            if !ok || c.wheel as usize >= d.states || c.body as usize >= d.states {
                return corrupt("a differenced identifier's contact check with masses > 0 and state indices");
            }
        }
        if st.lifted > st.seen {
            return corrupt("a differenced identifier counting its lifted samples among those it saw");
        }
        if !(st.min_spacing.finite() && st.min_spacing >= T::zero()) {
            return corrupt("a differenced identifier's min_spacing finite and ≥ 0");
        }
        if st.seen < self.inner.samples() || (st.primed && st.seen == 0) || u64::from(st.since) > st.seen {
            return corrupt("a differenced identifier counting at least the samples its inner one took");
        }
        Ok(())
    }
}

/// `ρ = exp(−2π n_c Δs)` over `since` samples at a constant distance per sample.
fn gap_rho<T: Real>(state: &RoadState<T>, since: u32) -> T {
    match state.travel {
        Travel::PerSample(ds) => (-(state.road.rate() * ds * T::of(f64::from(since)))).exp(),
        Travel::Odometer { .. } => T::one(),
    }
}

/// Every value of a sample that is stored or skipped (not handed to the inner identifier,
/// which checks its own) finite.
fn check_sample<T: Real>(x: &[T], z: &[T], u: &[T]) -> Result<()> {
    check_finite("r_k", x)?;
    check_finite("z_k", z)?;
    check_finite("u_k", u)
}
