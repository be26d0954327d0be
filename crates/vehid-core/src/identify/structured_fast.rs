//! The fast path of [`super::Structured`]: when every parameter group has one equation (the
//! full-row structure, the quarter car's physical structure) and every group's filter takes
//! the plain step ([`RowIdentifier::plain`]), the groups' filters are kept side by side in
//! lanes with a regressor each (`kalman::xlanes`), as [`super::KalmanRows`] keeps its rows,
//! and the regression is read from a table compiled when the identifier is made (each term's
//! lane, slot and basis), not interpreted from [`Structure::terms`] per sample.
//!
//! While the lanes hold the filters (`live`), they are the state: `Structured` reads its
//! estimate, covariance and statistics through them, and writes them back into its filters
//! ([`Fast::leave`]) before anything else touches the filters (a sample the plain step
//! refuses, a covariance reset, serialization). Entering and leaving copy every filter once;
//! a plain update copies nothing.

use super::kalman::{RowIdentifier, XLanes};
use crate::structure::{Basis, Partition, Structure, MAX_EQUATIONS, MAX_TERMS};
use crate::Real;

/// Filters per group of lanes (two `f64` in one SSE2 register).
const LANES: usize = 2;
/// Groups of lanes: the fast path takes structures of up to `LANES · LANE_GROUPS` groups.
const LANE_GROUPS: usize = 2;
/// The most parameter groups (one equation each) the fast path takes.
pub(crate) const FAST_GROUPS: usize = LANES * LANE_GROUPS;
/// The slot of a known term (it enters `y`, not the regressor).
const KNOWN: u8 = u8::MAX;

/// One term of the compiled regression: `coef · φ` into lane `lane`'s regressor entry `slot`
/// (the parameter's index in its group), or subtracted from its `y` (`slot` = `KNOWN`).
#[derive(Debug, Clone, Copy, PartialEq)]
struct Gather<T> {
    coef: T,
    basis: Basis,
    lane: u8,
    slot: u8,
}

/// The lanes and the compiled regression (see the module docs).
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Fast<T: Real, const P: usize> {
    lanes: [XLanes<T, P, LANES>; LANE_GROUPS],
    /// Whether the structure can take the fast path at all (one equation per group, at most
    /// [`FAST_GROUPS`] groups).
    able: bool,
    /// The lanes hold the filters (they are the state).
    live: bool,
    /// Groups (= equations) and groups of lanes in use.
    groups: u8,
    used: u8,
    /// Equation `i`'s lane (its group) and each lane's state (`y = z[state] − known terms`).
    lane_of_eq: [u8; FAST_GROUPS],
    state_of_lane: [u8; FAST_GROUPS],
    /// The terms, equation by equation in their order (the general path's arithmetic).
    gather: [Gather<T>; MAX_TERMS],
    n_gather: u8,
}

impl<T: Real, const P: usize> Fast<T, P> {
    /// The fast path of `s` with groups `part` (not able when a group has several equations
    /// or there are more than [`FAST_GROUPS`] groups).
    pub(crate) fn new(s: &Structure<T>, part: &Partition) -> Self {
        let mut fast = Self::none();
        let (ne, ng) = (s.equations(), part.groups as usize);
        if ne != ng || ne == 0 || ne > FAST_GROUPS {
            return fast;
        }
        let mut n = 0;
        for i in 0..ne {
            let g = part.group_of_eq[i];
            fast.lane_of_eq[i] = g;
            fast.state_of_lane[g as usize] = s.equation_state(i) as u8;
            for t in s.terms(i) {
                let slot = t.param.map_or(KNOWN, |p| part.local[p as usize]);
                fast.gather[n] = Gather { coef: t.coef, basis: t.basis, lane: g, slot };
                n += 1;
            }
        }
        fast.n_gather = n as u8;
        fast.groups = ne as u8;
        fast.used = ne.div_ceil(LANES) as u8;
        fast.able = true;
        fast
    }

    /// No fast path (and a deserialized identifier's until it is checked).
    pub(crate) fn none() -> Self {
        let none = Gather { coef: T::zero(), basis: Basis::One, lane: 0, slot: KNOWN };
        Self {
            lanes: [XLanes::padding(); LANE_GROUPS],
            able: false,
            live: false,
            groups: 0,
            used: 0,
            lane_of_eq: [0; FAST_GROUPS],
            state_of_lane: [0; FAST_GROUPS],
            gather: [none; MAX_TERMS],
            n_gather: 0,
        }
    }

    /// `true` while the lanes hold the filters.
    #[inline(always)]
    pub(crate) fn live(&self) -> bool {
        self.live
    }

    /// Moves the filters into the lanes when the fast path applies: the structure is able and
    /// every filter takes the plain step. `eq`: each equation's `(Σ w², samples)`.
    #[inline(always)]
    pub(crate) fn try_enter(&mut self, filters: &[RowIdentifier<T, P>], eq: (&[T], &[T])) {
        if self.live || !self.able || filters.len() != self.groups as usize {
            return;
        }
        if !filters.iter().fold(true, |a, f| a & f.plain()) {
            return;
        }
        self.enter(filters, eq);
    }

    #[inline(never)]
    fn enter(&mut self, filters: &[RowIdentifier<T, P>], (ssr, nobs): (&[T], &[T])) {
        self.lanes = [XLanes::padding(); LANE_GROUPS];
        for (i, &g) in self.lane_of_eq[..self.groups as usize].iter().enumerate() {
            let g = g as usize;
            self.lanes[g / LANES].set_lane(g % LANES, &filters[g], (ssr[i], nobs[i]));
        }
        self.live = true;
    }

    /// Writes the lanes back into the filters and the equations' statistics (the lanes stop
    /// being the state). Nothing when not live.
    pub(crate) fn leave(&mut self, filters: &mut [RowIdentifier<T, P>], (ssr, nobs): (&mut [T], &mut [T])) {
        if !self.live {
            return;
        }
        for (i, &g) in self.lane_of_eq[..self.groups as usize].iter().enumerate() {
            let g = g as usize;
            (ssr[i], nobs[i]) = self.lanes[g / LANES].lane_into(g % LANES, &mut filters[g]);
        }
        self.live = false;
    }

    /// Group `g`'s filter as the lanes hold it (`f`: the filter as stored, whose settings
    /// are kept), when live; else `f`.
    pub(crate) fn filter(&self, g: usize, f: &RowIdentifier<T, P>) -> RowIdentifier<T, P> {
        let mut f = *f;
        if self.live && g < self.groups as usize {
            self.lanes[g / LANES].lane_into(g % LANES, &mut f);
        }
        f
    }

    /// Equation `i`'s `(Σ w², samples)` as the lanes hold them when live, else `stored`.
    pub(crate) fn equation(&self, i: usize, stored: (T, T)) -> (T, T) {
        if !self.live || i >= self.groups as usize {
            return stored;
        }
        let g = self.lane_of_eq[i] as usize;
        self.lanes[g / LANES].equation(g % LANES)
    }

    /// The equations' statistics with the lanes' when live (for `residuals_into`).
    pub(crate) fn equations_into(&self, ssr: &mut [T; MAX_EQUATIONS], nobs: &mut [T; MAX_EQUATIONS]) {
        for i in 0..self.groups as usize {
            (ssr[i], nobs[i]) = self.equation(i, (ssr[i], nobs[i]));
        }
    }

    /// The regressors and left-hand sides of every lane at sample `(x, z, u)`, from the
    /// compiled table: per term `φ = coef · basis(x, z, u)`, added to its slot (from 0) or
    /// subtracted from `y = z[state]`, in the order of the terms (the general path's
    /// arithmetic, [`super::structured::group_regression`]; the row weight is 1 with one
    /// equation per group).
    #[inline(always)]
    #[allow(clippy::type_complexity)]
    fn regression(
        &self,
        s: &Structure<T>,
        x: &[T],
        z: &[T],
        u: &[T],
    ) -> ([[[T; LANES]; P]; LANE_GROUPS], [[T; LANES]; LANE_GROUPS]) {
        let mut h = [[[T::zero(); LANES]; P]; LANE_GROUPS];
        let mut y = [[T::zero(); LANES]; LANE_GROUPS];
        for g in 0..self.groups as usize {
            y[g / LANES][g % LANES] = z.get(self.state_of_lane[g] as usize).copied().unwrap_or_else(T::zero);
        }
        for t in &self.gather[..self.n_gather as usize] {
            let phi = t.coef * s.basis(t.basis, x, z, u);
            let g = t.lane as usize;
            if t.slot == KNOWN {
                if let Some(v) = y.get_mut(g / LANES) {
                    v[g % LANES] -= phi;
                }
            } else if let Some(v) = h.get_mut(g / LANES).and_then(|hg| hg.get_mut(t.slot as usize)) {
                v[g % LANES] += phi;
            }
        }
        (h, y)
    }

    /// One sample through the lanes (live): every group of lanes planned, then all applied,
    /// innovations into `e` (one per equation). `false` (nothing changed) when some lane must
    /// take the general update (see [`XLanes::plan`]).
    #[inline(always)]
    pub(crate) fn step(&mut self, s: &Structure<T>, x: &[T], z: &[T], u: &[T], e: &mut [T]) -> bool {
        let (h, y) = self.regression(s, x, z, u);
        let mut ek = [[T::zero(); LANES]; LANE_GROUPS];
        if self.used == 1 {
            let (ok, pl) = self.lanes[0].plan(&h[0], y[0]);
            if !ok {
                return false;
            }
            self.lanes[0].apply(&pl);
            ek[0] = pl.e;
        } else {
            let (ok0, p0) = self.lanes[0].plan(&h[0], y[0]);
            let (ok1, p1) = self.lanes[1].plan(&h[1], y[1]);
            if !(ok0 & ok1) {
                return false;
            }
            self.lanes[0].apply(&p0);
            self.lanes[1].apply(&p1);
            (ek[0], ek[1]) = (p0.e, p1.e);
        }
        for (o, &g) in e.iter_mut().zip(&self.lane_of_eq[..self.groups as usize]) {
            let g = g as usize;
            *o = ek[g / LANES][g % LANES];
        }
        true
    }
}
