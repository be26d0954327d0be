//! Two axles on one road (Ch. VI.D, thesis-notes §3): identifying the wheel rows when the
//! rear wheel meets the front wheel's road one wheelbase later.
//!
//! Samples are taken every `spacing` metres (`Δ`, see [`crate::sampler::AxleSampler`]), and
//! `d = L / Δ` (`L = l1 + l2`), so the rear input at sample `k` is the front input at sample
//! `k − d`: `u2(k) = u1(k − d)` (Eq 6.9). With `ρ = b42 / b21` (rear over front entry of `B`)
//! the wheel rows can be identified three ways ([`WheelMethod`]):
//!
//! - **`None`**: the plain decoupled rows (Eq 6.16–6.18) with `r = σ_v² + b² σ_u²` (Eq 4.7).
//!   The rear input is correlated with the state, so the rear row is biased (Fig 6-8).
//! - **`Thesis`** (Eq 6.12–6.14): the front row's innovation `e1(k) = z2 − xᵀθ̂_2 ≈ b21 u1(k)`
//!   estimates the road, and the rear row's innovation becomes
//!   `e2(k) = z4(k) − x(k)ᵀθ̂_4 − ρ·e1(k − d)`. The rear row keeps the variance of Eq 4.7
//!   (as the thesis did: the subtracted innovation carries the front row's own estimation
//!   error). The rear row is not updated before its first pair.
//! - **`Cancel`** (road cancellation): `z4(k) − ρ z2(k − d) = a4ᵀ x(k) − ρ a2ᵀ x(k − d)
//!   + v4(k) − ρ v2(k − d)`: the road input cancels exactly. One recursive least squares on
//!   the regressor `[x(k); −ρ x(k − d)]` estimates both wheel rows jointly (`2N` parameters,
//!   `[a4; a2]`) with the noise variance `σ_v² (1 + ρ²)` and no road term. The direct
//!   front-row equation `z2(k) = a2ᵀ x(k) + b21 u1(k) + v2(k)` is added as a second source,
//!   weighted by its own variance `σ_v² + b21² σ_u²` (optional, [`TwoAxleConfig::direct_front`]).
//!
//! The other unknown rows (the half car's body rows) are the plain Kalman rows
//! ([`KalmanRows`]); rows without an input have `r = σ_v²`.
//!
//! **Tracks.** A model with `M = 2t` inputs, the `t` front wheels' roads first and the rear
//! wheels' in the same order (`M = 2`: the half car's front and rear; `M = 4`: the full car's
//! `fl, fr, rl, rr`), has `t` tracks (wheel paths): rear wheel `j` rolls on front wheel `j`'s
//! track one wheelbase later (`u_{t+j}(k) = u_j(k − d)`). Each track's pair of wheel rows is
//! identified as above on its own (its own `ρ_j`, variances and joint filter); a road input
//! enters only its own wheel row, so the tracks' roads need not be independent (the full
//! car's left and right tracks are coherent: `sim/two_track.rs`). At most [`MAX_TRACKS`].
//!
//! Each sample is identified by its road-point (grid) index; [`TwoAxle::update_at`] with
//! `grid = None` takes the next one. A ring of the last `d` samples (a fixed array `[_; C]`,
//! or a `Vec`) holds what the pairing needs. Nothing here uses the time between samples.

use super::{
    check_lengths, check_sample, vector, CovarianceForm, Dims, Identifier, KalmanOptions, KalmanRows, RowIdentifier,
    Store,
};
use crate::error::{check_nonneg, check_positive};
use crate::model::{LinearModel, RowSet};
use crate::sampler::{RingStore, Trigger};
use crate::{Error, Real, Result};
use nalgebra::{SMatrix, SVector};

#[cfg(feature = "alloc")]
use super::Dynamic;
use super::Fixed;

mod identifier;

/// How the wheel rows are identified.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub enum WheelMethod {
    /// Plain decoupled rows (Eq 6.16–6.18): biased on the rear row by the correlated input.
    None,
    /// The thesis' innovation subtraction (Eq 6.12–6.14).
    Thesis,
    /// Road cancellation: the joint regression in which the shared road input cancels.
    #[default]
    Cancel,
}

option_names!(WheelMethod, "method", { None => "none", Thesis => "thesis", Cancel => "cancel" });

/// Settings of a [`TwoAxle`] identifier: method, prior and noise levels (each equation's
/// variance is derived from the noise levels).
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct TwoAxleConfig<T> {
    /// How the wheel rows are identified.
    pub method: WheelMethod,
    /// `P(0)` on the wheel rows (`p0 I`; the thesis: 1000).
    pub p0_wheel: T,
    /// `P(0)` on the other unknown rows (the thesis' 8-state study used 8).
    pub p0_body: T,
    /// Road standard deviation σ_u, m.
    pub road_sigma: T,
    /// Derivative measurement noise σ_v (every component), state units per second.
    pub deriv_noise: T,
    /// `Cancel` only: also use the direct front-row equation, weighted by its variance.
    pub direct_front: bool,
    /// The exact start on every filter ([`RowIdentifier::exact`], [`KalmanRows::exact`]):
    /// least squares on every sample once each filter's parameters are determined, no prior
    /// (`p0_wheel`, `p0_body` unused). Methods `None` and `Cancel` (the thesis' method reads the
    /// front row's innovation, which a filter in its start does not have); every equation's
    /// variance must be positive.
    pub exact: bool,
    /// Each filter's own outlier gate κ (0: off; [`KalmanOptions::gate`]): a sample whose
    /// recursive residual on a filter exceeds κ σ̂ leaves that filter unchanged (the wheel
    /// rows' filters, and every body row), counted in that filter's rows' `gated`. For models
    /// whose rows the outer screen's structure cannot hold (the full car's seven rows of 14):
    /// put the identifier behind [`super::Screened::magnitudes_only`] for the magnitude test
    /// (a screened sample's road point passes, [`Identifier::skip_sample`]).
    pub gate: T,
}

impl<T: Real> TwoAxleConfig<T> {
    /// `p0` on every row, the direct front equation on, no exact start.
    pub fn new(method: WheelMethod, p0: T, road_sigma: T, deriv_noise: T) -> Self {
        Self {
            method,
            p0_wheel: p0,
            p0_body: p0,
            road_sigma,
            deriv_noise,
            direct_front: true,
            exact: false,
            gate: T::zero(),
        }
    }

    fn validate(&self) -> Result<()> {
        check_positive("p0", self.p0_wheel)?;
        check_positive("p0", self.p0_body)?;
        check_nonneg("road_sigma", self.road_sigma)?;
        check_nonneg("deriv_noise", self.deriv_noise)?;
        check_nonneg("gate", self.gate)?;
        if self.exact && self.method == WheelMethod::Thesis {
            return Err(Error::InvalidArgument {
                arg: "exact",
                expected: "methods none or cancel with the exact start (the thesis' method subtracts the front row's \
                           innovation, which a filter in its exact start does not have)",
            });
        }
        Ok(())
    }
}

/// Most tracks (wheel paths) of a [`TwoAxle`]: the full car's left and right.
pub const MAX_TRACKS: usize = 2;

/// One remembered sample of the ring: its grid index, measured state `r(k)`, and per track
/// the front-row derivative `z2(k)` and front-row innovation `e1(k)`.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(
    feature = "serde",
    derive(serde::Serialize, serde::Deserialize),
    serde(bound(deserialize = "T: crate::Real"))
)]
pub struct Past<T: Real, const N: usize> {
    /// Grid (road-point) index.
    pub grid: u64,
    /// Measured state `r(k)`.
    pub x: SVector<T, N>,
    /// Measured derivative of each track's front wheel row, `z2(k)`.
    pub z_front: [T; MAX_TRACKS],
    /// Each track's front-row innovation `e1(k) = z2(k) − r(k)ᵀ θ̂_2(k−1)` (Eq 6.13).
    pub e_front: [T; MAX_TRACKS],
    /// `false` for an empty slot.
    pub valid: bool,
}

/// The two-axle identifier over a body-row [`Store`] `S` and a ring storage `B`, for a model
/// of `M` road inputs (2 for the half car, 4 for the full car: `M / 2` tracks); see
/// [`TwoAxleIdentifier`] (no allocation) and `TwoAxleIdentifierVec` (heap).
///
/// `P` must be `2 N` (the joint regression of the `Cancel` method; checked at construction).
#[derive(Debug, Clone)]
#[cfg_attr(
    feature = "serde",
    derive(serde::Serialize, serde::Deserialize),
    serde(
        remote = "Self",
        bound(
            serialize = "T: serde::Serialize, S::Group: serde::Serialize",
            deserialize = "T: crate::Real, S::Group: serde::Deserialize<'de>"
        )
    )
)]
pub struct TwoAxle<
    T: Real,
    const N: usize,
    const P: usize,
    S: Store<T, N>,
    B: RingStore<Past<T, N>>,
    const M: usize = 2,
> {
    model: LinearModel<T, N, M>,
    rows: RowSet<N>,
    cfg: TwoAxleConfig<T>,
    front_row: [usize; MAX_TRACKS],
    rear_row: [usize; MAX_TRACKS],
    ratio: [T; MAX_TRACKS],
    d: usize,
    r_front: [T; MAX_TRACKS],
    r_rear: [T; MAX_TRACKS],
    r_cancel: [T; MAX_TRACKS],
    direct_scale: [T; MAX_TRACKS],
    front: [RowIdentifier<T, N>; MAX_TRACKS],
    rear: [RowIdentifier<T, N>; MAX_TRACKS],
    joint: [RowIdentifier<T, P>; MAX_TRACKS],
    body: Option<KalmanRows<T, N, S>>,
    #[cfg_attr(feature = "serde", serde(with = "crate::persist::ring"))]
    ring: B,
    last_grid: Option<u64>,
    samples: u64,
    paired: u64,
}

/// The two-axle identifier with fixed storage: `N` states, `P = 2N` joint parameters, `KB`
/// body rows (unknown rows other than the wheel rows), a ring of `C ≥ d` samples, `M` road
/// inputs (default 2). No allocation. The thesis' half car: `TwoAxleIdentifier<f64, 8, 16,
/// 2, C>`; the full car: `TwoAxleIdentifier<f64, 14, 28, 3, C, 4>`.
///
/// # Examples
/// ```
/// use vehid_core::identify::{TwoAxleConfig, TwoAxleIdentifier, WheelMethod};
/// use vehid_core::model::HalfCar;
/// use vehid_core::sim::{RoadConfig, RoadSimulator, SimConfig};
/// let car = HalfCar::<f64>::thesis();
/// let road = RoadConfig::new(0.3, car.wheelbase());         // d = 3 m / 0.3 m = 10
/// let cfg = SimConfig::new(0.05).road_sigma(0.1).deriv_noise(0.005);
/// let mut sim = RoadSimulator::<f64, 8, 16>::new(car.model(), cfg, road, 1)?;
/// let id_cfg = TwoAxleConfig::new(WheelMethod::Cancel, 1000.0, 0.1, 0.005);
/// let mut id = TwoAxleIdentifier::<f64, 8, 16, 2, 16>::new(&car.model(), 10, id_cfg)?;
/// for _ in 0..2000 {
///     let s = sim.next_sample(6.0)?;                        // 6 m/s: one sample per 0.3 m
///     id.update(&s.r, &s.z)?;
/// }
/// let theta = id.theta::<4>()?;                             // rows 1, 3, 5, 7 of A
/// assert!((theta[(0, 0)] / car.theta()[(0, 0)] - 1.0).abs() < 0.1);
/// # Ok::<(), vehid_core::Error>(())
/// ```
pub type TwoAxleIdentifier<T, const N: usize, const P: usize, const KB: usize, const C: usize, const M: usize = 2> =
    TwoAxle<T, N, P, Fixed<KB>, [Past<T, N>; C], M>;

/// [`TwoAxle`] with heap storage (any number of body rows, any `d`).
#[cfg(feature = "alloc")]
pub type TwoAxleIdentifierVec<T, const N: usize, const P: usize, const M: usize = 2> =
    TwoAxle<T, N, P, Dynamic, alloc::vec::Vec<Past<T, N>>, M>;

/// The wheel rows `(fronts, rears)` of the `M / 2` tracks: the unknown row each input enters (exactly one
/// each, all different), the first `M / 2` inputs the front wheels', the rest the rear wheels'
/// in the same order.
pub(crate) fn wheel_rows<T: Real, const N: usize, const M: usize>(
    model: &LinearModel<T, N, M>,
) -> Result<([usize; MAX_TRACKS], [usize; MAX_TRACKS])> {
    const BAD: Error = Error::InvalidArgument {
        arg: "b",
        expected: "2 or 4 road inputs, the front wheels' then the rear wheels' in the same order (half car: front, \
                   rear; full car: fl, fr, rl, rr), each entering exactly one unknown row of its own (its wheel row)",
    };
    if M != 2 && M != 2 * MAX_TRACKS {
        return Err(BAD);
    }
    let b = model.b();
    let only = |col: usize| -> Result<usize> {
        let mut found = None;
        for i in 0..N {
            if b[(i, col)] != T::zero() {
                if found.is_some() {
                    return Err(BAD);
                }
                found = Some(i);
            }
        }
        found.ok_or(BAD)
    };
    let tracks = M / 2;
    let (mut fronts, mut rears) = ([0; MAX_TRACKS], [0; MAX_TRACKS]);
    let rows = model.unknown_rows();
    for j in 0..tracks {
        (fronts[j], rears[j]) = (only(j)?, only(tracks + j)?);
    }
    let all = fronts[..tracks].iter().chain(&rears[..tracks]);
    for (i, &r) in all.clone().enumerate() {
        if !rows.contains(r) || all.clone().skip(i + 1).any(|&o| o == r) {
            return Err(BAD);
        }
    }
    Ok((fronts, rears))
}

impl<T: Real, const N: usize, const P: usize, S: Store<T, N>, B: RingStore<Past<T, N>>, const M: usize>
    TwoAxle<T, N, P, S, B, M>
{
    /// Builds the identifier for a model of `M = 2` or `4` road inputs (the front wheels'
    /// then the rear wheels', each entering one unknown row), with `d` road points (samples)
    /// between the axles.
    ///
    /// Variances (per equation, from the noise levels): front and rear rows
    /// `σ_v² + b² σ_u²` (Eq 4.7); each track's cancelled equation `σ_v² (1 + ρ²)`; the other
    /// rows `σ_v² + Σ_j (B_ij σ_u)²`.
    ///
    /// # Errors
    /// [`Error::InvalidArgument`] for `p0 ≤ 0`, negative noise levels, `d = 0`, or a `B` that
    /// is not 2 or 4 wheel inputs; [`Error::Shape`] when `P ≠ 2N` or when a fixed body store
    /// does not hold exactly the other unknown rows; [`Error::Capacity`] when the ring holds
    /// fewer than `d` samples.
    pub fn new(model: &LinearModel<T, N, M>, d: usize, cfg: TwoAxleConfig<T>) -> Result<Self> {
        cfg.validate()?;
        if P != 2 * N {
            return Err(Error::Shape { arg: "P (joint parameters, must be 2N)", expected: 2 * N, got: P });
        }
        if d == 0 {
            return Err(Error::InvalidArgument { arg: "d", expected: "at least 1 road point between the axles" });
        }
        let (front_row, rear_row) = wheel_rows(model)?;
        let tracks = Self::TRACKS;
        let b = model.b();
        let sv2 = cfg.deriv_noise * cfg.deriv_noise;
        let su2 = cfg.road_sigma * cfg.road_sigma;
        let zero = [T::zero(); MAX_TRACKS];
        let (mut ratio, mut r_front, mut r_rear, mut r_cancel, mut direct_scale) = (zero, zero, zero, zero, zero);
        for j in 0..tracks {
            let (b21, b42) = (b[(front_row[j], j)], b[(rear_row[j], tracks + j)]);
            ratio[j] = b42 / b21;
            r_front[j] = sv2 + b21 * b21 * su2;
            r_rear[j] = sv2 + b42 * b42 * su2;
            r_cancel[j] = sv2 * (T::one() + ratio[j] * ratio[j]);
            direct_scale[j] = if r_front[j] > T::zero() { (r_cancel[j] / r_front[j]).sqrt() } else { T::one() };
        }
        let wheel = |row: usize| front_row[..tracks].contains(&row) || rear_row[..tracks].contains(&row);
        let mut body_rows = [0usize; N];
        let mut body_r = [T::zero(); N];
        let mut nb = 0;
        for &row in model.unknown_rows().as_slice() {
            if !wheel(row) {
                body_rows[nb] = row;
                let mut v = sv2;
                for j in 0..M {
                    v += b[(row, j)] * b[(row, j)] * su2;
                }
                body_r[nb] = v;
                nb += 1;
            }
        }
        let opts = KalmanOptions { gate: cfg.gate, ..KalmanOptions::default() };
        let body = match (nb, cfg.exact) {
            (0, _) => None,
            (_, true) => Some(KalmanRows::exact(&body_rows[..nb], &body_r[..nb], opts)?),
            (_, false) => Some(KalmanRows::from_slices(&body_rows[..nb], &[cfg.p0_body], &body_r[..nb], opts)?),
        };
        let empty = Past { grid: 0, x: SVector::zeros(), z_front: zero, e_front: zero, valid: false };
        let ring = B::with_len("TwoAxle ring capacity C (samples between the axles, d)", d, empty)?;
        // Unused track slots (the half car's second) repeat the first.
        fn filters<T: Real, const K: usize>(
            cfg: &TwoAxleConfig<T>,
            r: [T; MAX_TRACKS],
            tracks: usize,
        ) -> Result<[RowIdentifier<T, K>; MAX_TRACKS]> {
            let opts = KalmanOptions { gate: cfg.gate, ..KalmanOptions::default() };
            let one = |r: T| {
                let f = if cfg.exact { RowIdentifier::exact(r) } else { RowIdentifier::new(cfg.p0_wheel, r) }?;
                if cfg.gate > T::zero() {
                    f.configured(CovarianceForm::Standard, &opts)
                } else {
                    Ok(f)
                }
            };
            let mut out = [one(r[0])?; MAX_TRACKS];
            for j in 1..tracks {
                out[j] = one(r[j])?;
            }
            Ok(out)
        }
        // The filters that run: a method's own (the others are kept at their start).
        // (The exact start needs r > 0, which an unused filter's variance need not be.)
        let used = |r: [T; MAX_TRACKS], by: bool| if by || !cfg.exact { r } else { [T::one(); MAX_TRACKS] };
        let rows_method = cfg.method != WheelMethod::Cancel;
        Ok(Self {
            model: model.clone(),
            rows: model.unknown_rows(),
            cfg,
            front_row,
            rear_row,
            ratio,
            d,
            r_front,
            r_rear,
            r_cancel,
            direct_scale,
            front: filters(&cfg, used(r_front, rows_method), tracks)?,
            rear: filters(&cfg, used(r_rear, rows_method), tracks)?,
            joint: filters(&cfg, used(r_cancel, !rows_method), tracks)?,
            body,
            ring,
            last_grid: None,
            samples: 0,
            paired: 0,
        })
    }

    /// Tracks (wheel paths): `M / 2`.
    const TRACKS: usize = M / 2;

    /// With the exact start, the first filter in use still in its start: `(rank, needed)`.
    fn start_rank(&self) -> Option<(usize, usize)> {
        if !self.cfg.exact {
            return None;
        }
        let t = Self::TRACKS;
        let wheels = match self.cfg.method {
            WheelMethod::Cancel => self.joint[..t].iter().find(|f| f.starting()).map(|f| (f.start_rank(), P)),
            _ => self.front[..t].iter().chain(&self.rear[..t]).find(|f| f.starting()).map(|f| (f.start_rank(), N)),
        };
        let body = self.body.as_ref().filter(|b| b.starting()).map(|b| (b.filter(0).start_rank(), N));
        wheels.or(body)
    }

    /// Whether `row` is a wheel row: `Some((track, front))`.
    fn wheel_of(&self, row: usize) -> Option<(usize, bool)> {
        (0..Self::TRACKS).find_map(|j| {
            if row == self.front_row[j] {
                Some((j, true))
            } else if row == self.rear_row[j] {
                Some((j, false))
            } else {
                None
            }
        })
    }

    /// Checks a deserialized identifier: `P = 2N`, valid settings, the wheel rows the
    /// model's, the body rows the other unknown rows, a ring of at least `d ≥ 1` samples.
    #[cfg(feature = "serde")]
    pub(crate) fn restored(&mut self) -> Result<()> {
        if P != 2 * N {
            return Err(Error::Shape { arg: "P (joint parameters, must be 2N)", expected: 2 * N, got: P });
        }
        self.cfg.validate()?;
        if self.rows != self.model.unknown_rows() || wheel_rows(&self.model)? != (self.front_row, self.rear_row) {
            return Err(Error::InvalidArgument { arg: "rows", expected: "the model's unknown rows and wheel rows" });
        }
        let body = self.body.as_ref().map_or(&[][..], |b| b.rows());
        let others = self.rows.as_slice().iter().filter(|&&r| self.wheel_of(r).is_none());
        if !others.eq(body.iter()) {
            return Err(Error::InvalidArgument { arg: "body", expected: "the unknown rows other than the wheel rows" });
        }
        if self.d == 0 {
            return Err(Error::InvalidArgument { arg: "d", expected: "at least 1 road point between the axles" });
        }
        if self.ring.slots().len() < self.d {
            return Err(Error::Capacity { arg: "ring", needed: self.d, capacity: self.ring.slots().len() });
        }
        Ok(())
    }

    /// The settings.
    pub fn config(&self) -> &TwoAxleConfig<T> {
        &self.cfg
    }

    /// The first track's wheel rows `(front, rear)` (0-based rows of `A`; the half car's 1
    /// and 3; the full car's left wheels, 1 and 5).
    pub fn wheel_rows(&self) -> (usize, usize) {
        (self.front_row[0], self.rear_row[0])
    }

    /// Tracks (wheel paths): `M / 2`.
    pub fn tracks(&self) -> usize {
        Self::TRACKS
    }

    /// Track `j`'s wheel rows `(front, rear)`.
    ///
    /// # Panics
    /// For `j ≥ tracks()`.
    pub fn track_rows(&self, j: usize) -> (usize, usize) {
        assert!(j < Self::TRACKS, "track_rows: track {j} of {}", Self::TRACKS);
        (self.front_row[j], self.rear_row[j])
    }

    /// The first track's `ρ = b42 / b21`.
    pub fn ratio(&self) -> T {
        self.ratio[0]
    }

    /// Road points between the axles, `d`.
    pub fn delay(&self) -> usize {
        self.d
    }

    /// Variances `(front, rear, cancelled)` of the first track's wheel equations.
    pub fn wheel_variances(&self) -> (T, T, T) {
        (self.r_front[0], self.r_rear[0], self.r_cancel[0])
    }

    /// Samples accepted.
    pub fn samples(&self) -> u64 {
        self.samples
    }

    /// Samples that found their partner `d` road points earlier.
    pub fn paired(&self) -> u64 {
        self.paired
    }

    /// The first track's joint filter of the `Cancel` method (parameters `[a_rear; a_front]`).
    pub fn joint(&self) -> &RowIdentifier<T, P> {
        &self.joint[0]
    }

    /// The unknown rows (0-based), in the order of θ and of the innovations.
    pub fn rows(&self) -> &[usize] {
        self.rows.as_slice()
    }

    /// The current estimate of row `row` of `A` (a 0-based row index of `A`); the known
    /// row itself for a row that is not unknown.
    ///
    /// # Panics
    /// For `row ≥ N`, as indexing past `A`'s last row would (it used to read row `N − 1`).
    pub fn theta_row(&self, row: usize) -> SVector<T, N> {
        assert!(row < N, "theta_row: row {row} of a model with {N} states");
        if let Some((t, front)) = self.wheel_of(row) {
            return match self.cfg.method {
                WheelMethod::Cancel => {
                    let off = if front { N } else { 0 };
                    SVector::from_fn(|j, _| self.joint[t].theta()[off + j])
                }
                _ => {
                    if front {
                        self.front[t].theta()
                    } else {
                        self.rear[t].theta()
                    }
                }
            };
        }
        if let Some(body) = &self.body {
            if let Some(i) = body.rows().iter().position(|&r| r == row) {
                return body.theta_row(i);
            }
        }
        self.model.a().row(row).transpose()
    }

    /// Writes θ̂ (the unknown rows, `K × N` row-major, in the model's order) into `out`.
    ///
    /// # Errors
    /// [`Error::Shape`] for a wrong length; [`Error::RankDeficient`] while a filter in use is
    /// in its exact start ([`TwoAxleConfig::exact`]: no estimate yet).
    pub fn theta_into(&self, out: &mut [T]) -> Result<()> {
        let rows = self.rows;
        let k = rows.len();
        if out.len() != k * N {
            return Err(Error::Shape { arg: "out", expected: k * N, got: out.len() });
        }
        if let Some((rank, needed)) = self.start_rank() {
            return Err(Error::RankDeficient { rank, needed });
        }
        for (i, &row) in rows.as_slice().iter().enumerate() {
            out[i * N..(i + 1) * N].copy_from_slice(self.theta_row(row).as_slice());
        }
        Ok(())
    }

    /// θ̂ as a `K × N` matrix (the half car: `K = 4`, rows 1, 3, 5, 7).
    ///
    /// # Errors
    /// [`Error::Shape`] when `K` is not the number of unknown rows.
    pub fn theta<const K: usize>(&self) -> Result<SMatrix<T, K, N>> {
        let rows = self.rows;
        if rows.len() != K {
            return Err(Error::Shape { arg: "K", expected: rows.len(), got: K });
        }
        let mut m = SMatrix::<T, K, N>::zeros();
        for (i, &row) in rows.as_slice().iter().enumerate() {
            m.set_row(i, &self.theta_row(row).transpose());
        }
        Ok(m)
    }

    /// `Â`: the model's `A` with the unknown rows replaced by their estimates.
    pub fn a_hat(&self) -> SMatrix<T, N, N> {
        let mut a = *self.model.a();
        for &row in self.rows.as_slice() {
            a.set_row(row, &self.theta_row(row).transpose());
        }
        a
    }

    /// The next sample, on the road point after the previous one. See
    /// [`TwoAxle::update_at`].
    ///
    /// # Errors
    /// As [`TwoAxle::update_at`].
    pub fn update_next(&mut self, r: &SVector<T, N>, z: &SVector<T, N>, e: &mut [T]) -> Result<bool> {
        self.update_at(r, z, None, e)
    }

    /// One sample: measured state `r(k)` and derivative `z(k)` taken on road point `grid`
    /// (`None`: the point after the previous sample's; from [`crate::sampler::Trigger::grid`]
    /// when odometry jumped). Writes one innovation per unknown row into `e` (model order;
    /// for the wheel rows the innovation of the equation used, 0 when a row took no step) and
    /// returns whether the sample was paired with the one `d` road points earlier. No
    /// allocation.
    ///
    /// # Errors
    /// [`Error::NonFinite`] for NaN/inf; [`Error::InvalidArgument`] (argument `grid`) for a
    /// grid index not after the previous one; [`Error::Shape`] for a wrong `e` length;
    /// [`Error::Singular`] / overflow as [`RowIdentifier::update`]. The identifier is
    /// unchanged after any error.
    pub fn update_at(&mut self, r: &SVector<T, N>, z: &SVector<T, N>, grid: Option<u64>, e: &mut [T]) -> Result<bool> {
        self.step(r, z, grid, true, e)
    }

    /// One sample taken on a [`Trigger`] of an [`crate::sampler::AxleSampler`]: its grid
    /// index is used, and the sample is paired only when the sampler paired it (its road
    /// points within the sampler's tolerance). Otherwise as [`TwoAxle::update_at`].
    ///
    /// # Errors
    /// As [`TwoAxle::update_at`].
    pub fn update_trigger(
        &mut self,
        r: &SVector<T, N>,
        z: &SVector<T, N>,
        trigger: &Trigger<T>,
        e: &mut [T],
    ) -> Result<bool> {
        self.step(r, z, Some(trigger.grid), trigger.pair.is_some(), e)
    }

    fn step(
        &mut self,
        r: &SVector<T, N>,
        z: &SVector<T, N>,
        grid: Option<u64>,
        allow_pair: bool,
        e: &mut [T],
    ) -> Result<bool> {
        check_sample(r, z)?;
        let rows = self.rows;
        if e.len() != rows.len() {
            return Err(Error::Shape { arg: "e", expected: rows.len(), got: e.len() });
        }
        let grid = match (grid, self.last_grid) {
            (None, None) => 0,
            (None, Some(g)) => {
                g.checked_add(1).ok_or(Error::InvalidArgument { arg: "grid", expected: "a grid index < 2^64 − 1" })?
            }
            (Some(g), Some(last)) if g <= last => {
                return Err(Error::InvalidArgument {
                    arg: "grid",
                    expected: "road-point indices increasing from sample to sample",
                })
            }
            (Some(g), _) => g,
        };
        let d = self.d as u64;
        let cap = self.ring.slots().len() as u64;
        let past = if allow_pair && grid >= d {
            let p = self.ring.slots()[((grid - d) % cap) as usize];
            (p.valid && p.grid == grid - d).then_some(p)
        } else {
            None
        };
        // Plan on copies, one track at a time; commit only when every step succeeded.
        let zero = [T::zero(); MAX_TRACKS];
        let (mut zf, mut e_front, mut e_rear) = (zero, zero, zero);
        let mut planned: [Option<(RowIdentifier<T, N>, RowIdentifier<T, N>)>; MAX_TRACKS] = [None; MAX_TRACKS];
        let mut joint: [Option<RowIdentifier<T, P>>; MAX_TRACKS] = [None; MAX_TRACKS];
        for t in 0..Self::TRACKS {
            zf[t] = z[self.front_row[t]];
            let zr = z[self.rear_row[t]];
            let ratio = self.ratio[t];
            match self.cfg.method {
                WheelMethod::None | WheelMethod::Thesis => {
                    let (mut front, mut rear) = (self.front[t], self.rear[t]);
                    e_front[t] = front.update(r, zf[t])?;
                    e_rear[t] = match (self.cfg.method, past) {
                        (WheelMethod::None, _) => rear.update(r, zr)?,
                        (_, Some(p)) => rear.update(r, zr - ratio * p.e_front[t])?,
                        (_, None) => T::zero(),
                    };
                    planned[t] = Some((front, rear));
                }
                WheelMethod::Cancel => {
                    let mut j = self.joint[t];
                    let th = j.theta();
                    e_front[t] = zf[t] - (0..N).fold(T::zero(), |a, i| a + th[N + i] * r[i]);
                    e_rear[t] = match past {
                        Some(p) => {
                            let h = SVector::<T, P>::from_fn(|i, _| if i < N { r[i] } else { -ratio * p.x[i - N] });
                            j.update(&h, zr - ratio * p.z_front[t])?
                        }
                        None => T::zero(),
                    };
                    let scale = self.direct_scale[t];
                    if self.cfg.direct_front && scale > T::zero() {
                        let h = SVector::<T, P>::from_fn(|i, _| if i < N { T::zero() } else { r[i - N] * scale });
                        j.update(&h, zf[t] * scale)?;
                    }
                    joint[t] = Some(j);
                }
            }
        }
        let mut eb = [T::zero(); N];
        if let Some(body) = &mut self.body {
            let k = body.rows().len();
            body.update_vec(r, z, &mut eb[..k])?;
        }
        // Commit.
        for t in 0..Self::TRACKS {
            if let Some(j) = joint[t] {
                self.joint[t] = j;
            }
            if let Some((front, rear)) = planned[t] {
                (self.front[t], self.rear[t]) = (front, rear);
            }
        }
        let mut ib = 0;
        for (i, &row) in rows.as_slice().iter().enumerate() {
            e[i] = match self.wheel_of(row) {
                Some((t, true)) => e_front[t],
                Some((t, false)) => e_rear[t],
                None => {
                    ib += 1;
                    eb[ib - 1]
                }
            };
        }
        self.ring.slots_mut()[(grid % cap) as usize] = Past { grid, x: *r, z_front: zf, e_front, valid: true };
        self.last_grid = Some(grid);
        self.samples += 1;
        if past.is_some() {
            self.paired += 1;
        }
        Ok(past.is_some())
    }
}

impl<T: Real, const N: usize, const P: usize, const KB: usize, const C: usize, const M: usize>
    TwoAxle<T, N, P, Fixed<KB>, [Past<T, N>; C], M>
{
    /// One sample on the next road point; returns whether it was paired. See
    /// [`TwoAxle::update_at`].
    ///
    /// # Errors
    /// As [`TwoAxle::update_at`].
    pub fn update(&mut self, r: &SVector<T, N>, z: &SVector<T, N>) -> Result<bool> {
        let mut e = [T::zero(); N];
        let k = self.rows.len();
        self.update_at(r, z, None, &mut e[..k])
    }
}
