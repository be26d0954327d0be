//! Two axles on one road on a physical structure (Ch. VI.D with Eq 6.1–6.8's parameters):
//! road cancellation ([`super::WheelMethod::Cancel`]) on a [`Structure`] instead of the full
//! rows.
//!
//! Samples are taken every `Δ` metres and `d = L / Δ`, so the rear road input at sample `k`
//! is the front one at `k − d`: `u2(k) = u1(k − d)` (Eq 6.9). Each identified equation of
//! the structure is the scalar regression `y_i(k) = h_i(k)ᵀ p + ε_i(k)`
//! ([`Structure::regression`]). The front and rear wheel equations carry the road,
//! `ε_front(k) = b21 u1(k) + v2(k)` and `ε_rear(k) = b42 u2(k) + v4(k)` (`b21`, `b42` the wheel
//! entries of `B`, 1/s²; `v` the derivative noise, m/s²), so with `ρ = b42 / b21` the
//! cancelled equation
//!
//! ```text
//! y_rear(k) − ρ y_front(k − d) = (h_rear(k) − ρ h_front(k − d))ᵀ p + v4(k) − ρ v2(k − d)
//! ```
//!
//! is linear in the same parameters `p`, with no road term and the variance
//! `σ_v² (1 + ρ²)`. It replaces the rear wheel equation (whose road input is correlated with
//! the state one wheelbase after the front wheel met it: the bias of Fig 6-8). The other
//! equations are used as they are (the half car's heave and pitch equations: no road,
//! variance `σ_v²`), and the direct front equation `y_front(k) = h_front(k)ᵀ p + b21 u1(k) +
//! v2(k)` is unbiased for a white road (`u1(k)` is independent of the state at `k`) and is
//! added with its variance `σ_v² + b21² σ_u²` when [`TwoAxleStructuredConfig::direct_front`]
//! is set.
//!
//! On the half car's physical structure ([`crate::model::HalfCar::structure`] with `m1`,
//! `m2`, `l1`, `l2` known) the wheel equations share `M` and `J`, so the cancelled equation
//! estimates `M`, `J`, `k11`, `k21` in one group; the heave and pitch equations each form
//! their own group. The 28 non-zero entries of the four unknown rows of `A` follow from the
//! 12 parameters ([`TwoAxleStructured::a_rows_into`]).
//!
//! # Derivative noise
//! The half car's wheel equations read the body's measured accelerations (`der(vb)`,
//! `der(om)`), whose noise `σ_v` enters the regressor multiplied by `M` and `J`. In the
//! cancelled equation, whose own noise is only `σ_v √(1 + ρ²)`, that regressor noise is about
//! as large as the signal left once the road cancels, and least squares attenuates the wheel
//! group towards zero (on the thesis' half car: `M`, `J`, `k11`, `k21` all about 12 % low,
//! whatever the number of samples). With [`TwoAxleStructuredConfig::compensate`] the estimate
//! is the bias-compensated least squares of [`super::BiasCompensated`] (Söderström 2007,
//! §4.3), computed from the recursive filter on read:
//!
//! ```text
//! θ̂ = (XᵀX − C)⁻¹ (Xᵀy − c) = (I − (P/r_g) C)⁻¹ (θ̂_LS − (P/r_g) c)
//! ```
//!
//! with `XᵀX = r_g P⁻¹` (the exact start's `P`; with a prior, nearly), `C = σ_v² Σ_i n_i w_i²
//! J_h,i J_h,iᵀ` and `c = σ_v² Σ_i n_i w_i² J_h,i J_y,iᵀ` over the group's equations (`n_i`
//! updates, weight `w_i`, `J_h,i`, `J_y,i` the regressor's and the output's dependence on the
//! measured derivatives; for the cancelled equation the rear one's at `k` and `ρ` times the
//! front one's at `k − d`, independent samples). It is consistent when `σ_v` is right (a
//! `σ_v` 10 % off leaves about a fifth of the bias: on the thesis' half car the worst of the
//! 28 entries is then 3–5 % off instead of under 2 %); measured states are taken as exact, and
//! `der(·)` must enter linearly (not inside `sign`/`pos`/`neg`). The innovations are the
//! recursive filter's.
//!
//! # Groups and storage
//! The parameters split into groups as [`Structure::partition`] splits them, except that the
//! front and rear wheel equations' groups are one (the cancelled equation holds both); each
//! group is one [`RowIdentifier`] (exact start or `P(0) = p0 I`), its equations weighted by
//! `√(r_g / r_i)` (`r_g` the group's reference variance: the cancelled equation's in the
//! wheel group, the first equation's elsewhere). A ring of the last `d` front-wheel
//! regressions (a fixed array or a `Vec`, sized at construction) holds what the pairing
//! needs. An update allocates nothing and is transactional.

use super::buffers::{partition_groups_into, structure_dims};
use super::checks::check_slices;
use super::deriv_noise::{add_deriv_noise, compensated, nonlinear_deriv, reads_noisy_deriv};
use super::two_axle::wheel_rows;
use super::{Flat, Identifier, RowIdentifier, OVERFLOW};
use crate::error::{check_nonneg, check_positive};
use crate::model::LinearModel;
use crate::sampler::{RingStore, Trigger};
use crate::structure::{Partition, Structure, MAX_EQUATIONS, MAX_PARAMS};
use crate::{Error, Real, Result};
use nalgebra::{SMatrix, SVector};

mod config;
mod identifier;

pub use config::TwoAxleStructuredConfig;

/// One remembered front-wheel regression of the ring: its grid index, `y_front(k)` and
/// `h_front(k)` (in the wheel group's local parameter order, unweighted).
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(
    feature = "serde",
    derive(serde::Serialize, serde::Deserialize),
    serde(bound(deserialize = "T: crate::Real"))
)]
pub struct FrontRegression<T: Real, const P: usize> {
    /// Grid (road-point) index.
    pub grid: u64,
    /// `y_front(k)`: the front wheel's measured acceleration minus its known terms, m/s².
    pub y: T,
    /// `h_front(k)`, the regressor of the wheel group's parameters.
    pub h: SVector<T, P>,
    /// `false` for an empty slot.
    pub valid: bool,
}

/// Road cancellation on a [`Structure`] (see the module docs), with `P` parameters per group
/// filter, the filters in `F` and the ring in `B`; see [`TwoAxleStructuredKalman`] (no
/// allocation) and `TwoAxleStructuredVec` (heap).
#[derive(Debug, Clone)]
#[cfg_attr(
    feature = "serde",
    derive(serde::Serialize, serde::Deserialize),
    serde(remote = "Self", bound(serialize = "T: serde::Serialize", deserialize = "T: crate::Real"))
)]
pub struct TwoAxleStructured<T: Real, const P: usize, F: Flat<RowIdentifier<T, P>>, B: RingStore<FrontRegression<T, P>>>
{
    structure: Structure<T>,
    /// The structure's partition with the two wheel equations' groups merged.
    part: Partition,
    cfg: TwoAxleStructuredConfig<T>,
    /// Equation indices of the front and rear wheel equations.
    front_eq: u8,
    rear_eq: u8,
    rows: [usize; MAX_EQUATIONS],
    ratio: T,
    d: usize,
    /// Each equation's variance `r_i` (front: the direct equation's; rear: the cancelled
    /// one's) and row weight `√(r_g / r_i)`.
    r: [T; MAX_EQUATIONS],
    scale: [T; MAX_EQUATIONS],
    #[cfg_attr(feature = "serde", serde(with = "crate::persist::flat"))]
    filters: F,
    /// The filters before the current update: scratch, not state.
    #[cfg_attr(feature = "serde", serde(with = "crate::persist::scratch"))]
    backup: F,
    #[cfg_attr(feature = "serde", serde(with = "crate::persist::ring"))]
    ring: B,
    /// Updates each equation's filter took (the rear wheel: cancelled updates).
    eq_count: [u64; MAX_EQUATIONS],
    last_grid: Option<u64>,
    samples: u64,
    paired: u64,
}

/// [`TwoAxleStructured`] with fixed storage: `G` group filters of `P` parameters, a ring of
/// `C ≥ d` samples. No allocation. The thesis' half car on its physical structure (`m1`, `m2`,
/// `l1`, `l2` known): `TwoAxleStructuredKalman<f64, 4, 3, C>`.
///
/// # Examples
/// ```
/// use vehid_core::identify::{Identifier, TwoAxleStructuredConfig, TwoAxleStructuredKalman};
/// use vehid_core::model::HalfCar;
/// use vehid_core::sim::{RoadConfig, RoadSimulator, SimConfig};
/// let car = HalfCar::<f64>::thesis();
/// let c = car.constants();
/// let mut known = [None; 12];
/// for i in 8..12 {
///     known[i] = Some(c[i]);                                 // m1, m2, l1, l2
/// }
/// let ps = HalfCar::structure(known)?;
/// let road = RoadConfig::new(0.3, car.wheelbase());          // d = 3 m / 0.3 m = 10
/// let cfg = SimConfig::new(0.05).road_sigma(0.1).deriv_noise(0.005);
/// let mut sim = RoadSimulator::<f64, 8, 16>::new(car.model(), cfg, road, 1)?;
/// let id_cfg = TwoAxleStructuredConfig::new(0.1, 0.005);
/// let mut id = TwoAxleStructuredKalman::<f64, 4, 3, 16>::new(*ps.structure(), &car.model(), 10, id_cfg)?;
/// let mut e = [0.0; 4];
/// for _ in 0..2000 {
///     let s = sim.next_sample(6.0)?;                         // 6 m/s: one sample per 0.3 m
///     id.update_into(s.r.as_slice(), s.z.as_slice(), &[], &mut e)?;
/// }
/// let mut rows = [0.0; 32];                                  // rows 5, 7, 1, 3 of A
/// id.a_rows_into(&mut rows)?;
/// let truth = car.model().a()[(1, 0)];                       // −(k11 + k12)/m1
/// assert!((rows[16] / truth - 1.0).abs() < 0.05);
/// # Ok::<(), vehid_core::Error>(())
/// ```
pub type TwoAxleStructuredKalman<T, const P: usize, const G: usize, const C: usize> =
    TwoAxleStructured<T, P, [RowIdentifier<T, P>; G], [FrontRegression<T, P>; C]>;

/// [`TwoAxleStructured`] with heap storage (any number of groups, any `d`).
#[cfg(feature = "alloc")]
pub type TwoAxleStructuredVec<T, const P: usize> =
    TwoAxleStructured<T, P, alloc::vec::Vec<RowIdentifier<T, P>>, alloc::vec::Vec<FrontRegression<T, P>>>;

/// `part` with the groups `a` and `b` made one (parameters renumbered in order).
fn merged(part: &Partition, np: usize, ne: usize, a: u8, b: u8) -> Partition {
    let (keep, gone) = (a.min(b), a.max(b));
    let old = |g: u8| if g == gone { keep } else { g };
    let mut out = Partition {
        groups: 0,
        group_of_param: [0; MAX_PARAMS],
        local: [0; MAX_PARAMS],
        size: [0; MAX_PARAMS],
        group_of_eq: [0; MAX_EQUATIONS],
    };
    let mut id = [u8::MAX; MAX_PARAMS];
    let mut new = |g: u8, out: &mut Partition| {
        let g = old(g) as usize;
        if id[g] == u8::MAX {
            id[g] = out.groups;
            out.groups += 1;
        }
        id[g]
    };
    for j in 0..np {
        let g = new(part.group_of_param[j], &mut out);
        out.group_of_param[j] = g;
        out.local[j] = out.size[g as usize];
        out.size[g as usize] += 1;
    }
    for i in 0..ne {
        out.group_of_eq[i] = new(part.group_of_eq[i], &mut out);
    }
    out
}

impl<T: Real, const P: usize, F: Flat<RowIdentifier<T, P>>, B: RingStore<FrontRegression<T, P>>>
    TwoAxleStructured<T, P, F, B>
{
    /// Builds the identifier of `structure`'s parameters for a 2-input `model` (front and
    /// rear road, each entering one unknown row: the wheel rows, and `ρ = b42 / b21`, are
    /// read from its `B`), with `d` road points (samples) between the axles. The structure
    /// must have `N` states and an identified equation for each wheel row.
    ///
    /// Variances (per equation, from the noise levels): the cancelled equation
    /// `σ_v² (1 + ρ²)`, the direct front equation `σ_v² + b21² σ_u²`, the others
    /// `σ_v² + Σ_j (B_ij σ_u)²`. They weigh equations of one group against each other; with
    /// a prior they also set the gain.
    ///
    /// # Errors
    /// [`Error::InvalidArgument`] for `p0 ≤ 0`, negative noise levels, `d = 0`, a `B` that is
    /// not two wheel inputs, a structure without an identified equation for each wheel row, or
    /// a group whose equations are not all noisy or all noise-free;
    /// [`Error::Shape`] when the structure's states are not `N` or `F` cannot hold exactly
    /// the groups; [`Error::NotIdentifiable`] for an unused or confounded parameter;
    /// [`Error::Capacity`] when a group has more than `P` parameters or the ring holds fewer
    /// than `d` samples.
    pub fn new<const N: usize>(
        structure: Structure<T>,
        model: &LinearModel<T, N, 2>,
        d: usize,
        cfg: TwoAxleStructuredConfig<T>,
    ) -> Result<Self> {
        cfg.validate()?;
        structure.check_identifiable()?;
        if structure.states() != N {
            return Err(Error::Shape { arg: "structure (states)", expected: N, got: structure.states() });
        }
        if d == 0 {
            return Err(Error::InvalidArgument { arg: "d", expected: "at least 1 road point between the axles" });
        }
        if cfg.compensate && cfg.deriv_noise > T::zero() && nonlinear_deriv(&structure) {
            return Err(Error::Unsupported {
                what: "compensating the derivative noise of der(·) inside sign/pos/neg (set compensate = false)",
            });
        }
        let (fronts, rears) = wheel_rows(model)?;
        let (front_row, rear_row) = (fronts[0], rears[0]);
        let eq_of = |row: usize| {
            structure.equation_states().position(|s| s == row).ok_or(Error::InvalidArgument {
                arg: "structure",
                expected: "an identified equation for each wheel row (the rows the front and rear road inputs enter: \
                           the half car's 1 and 3), as in HalfCar::structure",
            })
        };
        let (front_eq, rear_eq) = (eq_of(front_row)?, eq_of(rear_row)?);
        let (np, ne) = (structure.params(), structure.equations());
        let p0 = structure.partition();
        let part = merged(&p0, np, ne, p0.group_of_eq[front_eq], p0.group_of_eq[rear_eq]);
        if part.largest() > P {
            return Err(Error::Capacity { arg: "P", needed: part.largest(), capacity: P });
        }
        let b = model.b();
        let (b21, b42) = (b[(front_row, 0)], b[(rear_row, 1)]);
        let ratio = b42 / b21;
        let (sv2, su2) = (cfg.deriv_noise * cfg.deriv_noise, cfg.road_sigma * cfg.road_sigma);
        let mut r = [T::zero(); MAX_EQUATIONS];
        for (i, s) in structure.equation_states().enumerate() {
            r[i] = if i == rear_eq {
                sv2 * (T::one() + ratio * ratio)
            } else {
                sv2 + (0..2).fold(T::zero(), |a, j| a + b[(s, j)] * b[(s, j)] * su2)
            };
        }
        // Each group's reference variance: the cancelled equation's in the wheel group, the
        // first equation's elsewhere.
        let wheel = part.group_of_eq[rear_eq] as usize;
        let mut r_group = [None; MAX_EQUATIONS];
        r_group[wheel] = Some(r[rear_eq]);
        let mut scale = [T::one(); MAX_EQUATIONS];
        for i in 0..ne {
            let g = part.group_of_eq[i] as usize;
            let rg = *r_group[g].get_or_insert(r[i]);
            scale[i] = match (rg > T::zero(), r[i] > T::zero()) {
                (_, true) => (rg / r[i]).sqrt(),
                (false, false) => T::one(),
                (true, false) => {
                    return Err(Error::InvalidArgument {
                        arg: "deriv_noise",
                        expected: "equations that share parameters all noisy or all noise-free (a noise-free \
                                   equation beside a noisy one of its group: give deriv_noise > 0)",
                    })
                }
            };
        }
        let zero = RowIdentifier::<T, P>::new(T::one(), T::one())?;
        let mut filters = F::filled("groups", part.groups as usize, zero)?;
        for (g, slot) in filters.flat_mut().iter_mut().enumerate() {
            let rg = r_group[g].unwrap_or_else(T::one);
            let f = match cfg.p0 {
                // The exact start's r only scales P: any positive value.
                None => RowIdentifier::exact(if rg > T::zero() { rg } else { T::one() })?,
                Some(p0) => RowIdentifier::new(p0, rg)?,
            };
            *slot = f.restricted(part.size[g] as usize)?;
        }
        let empty = FrontRegression { grid: 0, y: T::zero(), h: SVector::zeros(), valid: false };
        let ring = B::with_len("TwoAxleStructured ring capacity C (samples between the axles, d)", d, empty)?;
        let mut rows = [0usize; MAX_EQUATIONS];
        for (i, s) in structure.equation_states().enumerate() {
            rows[i] = s;
        }
        Ok(Self {
            structure,
            part,
            cfg,
            front_eq: front_eq as u8,
            rear_eq: rear_eq as u8,
            rows,
            ratio,
            d,
            r,
            scale,
            backup: filters.clone(),
            filters,
            ring,
            eq_count: [0; MAX_EQUATIONS],
            last_grid: None,
            samples: 0,
            paired: 0,
        })
    }

    /// Checks a deserialized identifier (feature `serde`; its structure checked itself): the
    /// merged partition, one filter (and backup) per group, the wheel equations, the
    /// equations' states, a ring of at least `d ≥ 1` samples.
    #[cfg(feature = "serde")]
    pub(crate) fn restored(&mut self) -> Result<()> {
        let corrupt =
            Error::InvalidArgument { arg: "state", expected: "a two-axle structured identifier's saved state" };
        self.cfg.validate()?;
        if self.backup.flat().is_empty() {
            self.backup = self.filters.clone();
        }
        let (np, ne) = (self.structure.params(), self.structure.equations());
        let (f, r) = (self.front_eq as usize, self.rear_eq as usize);
        if f >= ne || r >= ne || f == r {
            return Err(corrupt);
        }
        let p0 = self.structure.partition();
        let part = merged(&p0, np, ne, p0.group_of_eq[f], p0.group_of_eq[r]);
        let ng = part.groups as usize;
        if part != self.part || part.largest() > P || self.filters.flat().len() != ng || self.backup.flat().len() != ng
        {
            return Err(corrupt);
        }
        if self.structure.equation_states().enumerate().any(|(i, s)| self.rows[i] != s)
            || self.rows[ne..].iter().any(|&r| r != 0)
        {
            return Err(corrupt);
        }
        if self.d == 0 || self.ring.slots().len() < self.d {
            return Err(corrupt);
        }
        crate::error::check_finite("scale", &self.scale[..ne])?;
        Ok(())
    }

    /// The settings.
    pub fn config(&self) -> &TwoAxleStructuredConfig<T> {
        &self.cfg
    }

    /// The structure identified.
    pub fn structure(&self) -> &Structure<T> {
        &self.structure
    }

    /// The parameter groups (the structure's, with the wheel equations' groups merged).
    pub fn partition(&self) -> &Partition {
        &self.part
    }

    /// The filter of group `g`.
    pub fn filter(&self, g: usize) -> &RowIdentifier<T, P> {
        &self.filters.flat()[g]
    }

    /// The equation indices `(front, rear)` of the wheel equations.
    pub fn wheel_equations(&self) -> (usize, usize) {
        (self.front_eq as usize, self.rear_eq as usize)
    }

    /// Equation `i`'s variance `r_i` (front: the direct equation's; rear: the cancelled
    /// equation's).
    pub fn equation_r(&self, i: usize) -> T {
        self.r[i]
    }

    /// Variances `(front, rear, cancelled)` of the wheel equations, as
    /// [`super::TwoAxleIdentifier::wheel_variances`]: the direct front equation's
    /// `σ_v² + b21² σ_u²`, the plain rear one's `σ_v² + b42² σ_u²` (not used: the cancelled
    /// equation replaces it; `b42 = ρ b21`) and the cancelled one's `σ_v² (1 + ρ²)`.
    pub fn wheel_variances(&self) -> (T, T, T) {
        let sv2 = self.cfg.deriv_noise * self.cfg.deriv_noise;
        let front = self.r[self.front_eq as usize];
        (front, sv2 + self.ratio * self.ratio * (front - sv2), self.r[self.rear_eq as usize])
    }

    /// `ρ = b42 / b21`.
    pub fn ratio(&self) -> T {
        self.ratio
    }

    /// Road points between the axles, `d`.
    pub fn delay(&self) -> usize {
        self.d
    }

    /// Samples that found their partner `d` road points earlier.
    pub fn paired(&self) -> u64 {
        self.paired
    }

    /// `true` while some group is still in its exact start.
    pub fn starting(&self) -> bool {
        self.filters.flat().iter().any(|f| f.starting())
    }

    /// The unknown rows of `A` the estimate gives (`equations × states`, row-major, in the
    /// order of the structure's identified equations; the half car's physical structure:
    /// rows 5, 7, 1, 3): [`Structure::linear_rows_into`] at the estimated parameters.
    ///
    /// # Errors
    /// [`Error::RankDeficient`] during the exact start; [`Error::Shape`] for a wrong length.
    pub fn a_rows_into(&self, out: &mut [T]) -> Result<()> {
        let mut p = [T::zero(); MAX_PARAMS];
        let np = self.structure.params();
        self.params_into(&mut p[..np])?;
        self.structure.linear_rows_into(&p[..np], out)
    }

    /// One sample: measured state `x(k)`, derivative `z(k)`, inputs `u(k)`, taken on road
    /// point `grid` (`None`: the point after the previous sample's). Writes one innovation per
    /// identified equation into `e` (the rear wheel: the cancelled equation's, 0 when the
    /// sample is not paired; the front wheel: the direct equation's, whether it is used or
    /// not; NaN during an exact start) and returns whether the sample was paired with the one
    /// `d` road points earlier. No allocation.
    ///
    /// # Errors
    /// [`Error::Shape`] for wrong lengths; [`Error::NonFinite`] for NaN/inf;
    /// [`Error::InvalidArgument`] (argument `grid`) for a grid index not after the previous
    /// one, or (argument `r_k`) when the update would overflow; [`Error::Singular`] as
    /// [`RowIdentifier::update`]. The identifier is unchanged after any error.
    pub fn update_at(&mut self, x: &[T], z: &[T], u: &[T], grid: Option<u64>, e: &mut [T]) -> Result<bool> {
        self.step(x, z, u, grid, true, e)
    }

    /// One sample taken on a [`Trigger`] of an [`crate::sampler::AxleSampler`]: its grid
    /// index is used, and the sample is paired only when the sampler paired it. Otherwise as
    /// [`TwoAxleStructured::update_at`].
    ///
    /// # Errors
    /// As [`TwoAxleStructured::update_at`].
    pub fn update_trigger(&mut self, x: &[T], z: &[T], u: &[T], trigger: &Trigger<T>, e: &mut [T]) -> Result<bool> {
        self.step(x, z, u, Some(trigger.grid), trigger.pair.is_some(), e)
    }

    /// Equation `i`'s regression `(y, h)`, `h` in its group's local order (unweighted).
    fn local_regression(&self, i: usize, x: &[T], z: &[T], u: &[T]) -> (T, SVector<T, P>) {
        super::structured::group_regression(&self.structure, &self.part, self.rows[i], i, x, z, u)
    }

    fn step(&mut self, x: &[T], z: &[T], u: &[T], grid: Option<u64>, allow_pair: bool, e: &mut [T]) -> Result<bool> {
        check_slices(self.dims(), x, z, u, e)?;
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
        let (d, cap) = (self.d as u64, self.ring.slots().len() as u64);
        let past = if allow_pair && grid >= d {
            let p = self.ring.slots()[((grid - d) % cap) as usize];
            (p.valid && p.grid == grid - d).then_some(p)
        } else {
            None
        };
        let (fe, re) = (self.front_eq as usize, self.rear_eq as usize);
        let (y_front, h_front) = self.local_regression(fe, x, z, u);
        let ne = self.structure.equations();
        let (mut touched, mut stepped) = (0u32, 0u32);
        for i in 0..ne {
            let g = self.part.group_of_eq[i] as usize;
            if touched & (1 << g) == 0 {
                touched |= 1 << g;
                self.backup.flat_mut()[g] = self.filters.flat()[g];
            }
            let w = self.scale[i];
            let step = if i == re {
                match past {
                    // The cancelled equation (the wheel group's reference: weight 1).
                    Some(p) => {
                        let (y, h) = self.local_regression(re, x, z, u);
                        self.update_group(g, &(h - p.h * self.ratio), y - self.ratio * p.y)
                    }
                    None => Ok(T::zero()),
                }
            } else if i == fe && !self.cfg.direct_front {
                let f = &self.filters.flat()[g];
                Ok(if f.starting() { T::of(f64::NAN) } else { y_front - h_front.dot(&f.theta()) })
            } else {
                let (y, h) = if i == fe { (y_front, h_front) } else { self.local_regression(i, x, z, u) };
                self.update_group(g, &(h * w), y * w).map(|inn| inn / w)
            };
            match step {
                Ok(v) => {
                    e[i] = v;
                    stepped |= u32::from(if i == re { past.is_some() } else { i != fe || self.cfg.direct_front }) << i;
                }
                Err(err) => {
                    super::structured::restore_groups(self.filters.flat_mut(), self.backup.flat(), touched);
                    return Err(match err {
                        Error::NonFinite { .. } => OVERFLOW,
                        other => other,
                    });
                }
            }
        }
        for (i, n) in self.eq_count[..ne].iter_mut().enumerate() {
            *n += u64::from(stepped >> i & 1);
        }
        self.ring.slots_mut()[(grid % cap) as usize] = FrontRegression { grid, y: y_front, h: h_front, valid: true };
        self.last_grid = Some(grid);
        self.samples += 1;
        if past.is_some() {
            self.paired += 1;
        }
        Ok(past.is_some())
    }

    /// `true` when the estimate is bias-compensated: set, `σ_v > 0`, and some parameter
    /// multiplies a measured derivative.
    fn compensating(&self) -> bool {
        self.cfg.compensate && self.cfg.deriv_noise > T::zero() && reads_noisy_deriv(&self.structure)
    }

    /// Group `g`'s estimate: the filter's, bias-compensated when set (module docs).
    fn group_estimate(&self, g: usize) -> Result<SVector<T, P>> {
        let f = &self.filters.flat()[g];
        if !self.compensating() {
            return Ok(f.theta());
        }
        let (mut c_mat, mut c_vec) = (SMatrix::<T, P, P>::zeros(), SVector::<T, P>::zeros());
        let sv2 = self.cfg.deriv_noise * self.cfg.deriv_noise;
        let (fe, re) = (self.front_eq as usize, self.rear_eq as usize);
        let (s, part) = (&self.structure, &self.part);
        for i in 0..s.equations() {
            if part.group_of_eq[i] as usize != g || self.eq_count[i] == 0 {
                continue;
            }
            let n = T::of(self.eq_count[i] as f64) * sv2 * self.scale[i] * self.scale[i];
            if i == re {
                // h_rear(k) − ρ h_front(k − d): two independent samples' noise.
                add_deriv_noise(s, part, re, n, &mut c_mat, &mut c_vec);
                add_deriv_noise(s, part, fe, n * self.ratio * self.ratio, &mut c_mat, &mut c_vec);
            } else {
                add_deriv_noise(s, part, i, n, &mut c_mat, &mut c_vec);
            }
        }
        compensated(f, &c_mat, &c_vec)
    }

    /// One step of group `g`'s filter on `(h, y)`; an overflow of the regression is an error.
    fn update_group(&mut self, g: usize, h: &SVector<T, P>, y: T) -> Result<T> {
        if !(y.finite() && h.iter().all(|v| v.finite())) {
            return Err(OVERFLOW);
        }
        self.filters.flat_mut()[g].update(h, y)
    }
}
