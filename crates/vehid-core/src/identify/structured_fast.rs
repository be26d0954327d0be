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

use super::kalman::{RowIdentifier, XLanes, XPlan};
use crate::structure::{Basis, Partition, Structure, Var, MAX_EQUATIONS, MAX_TERMS};
use crate::Real;

/// Filters per group of lanes (two `f64` in one SSE2 register).
const LANES: usize = 2;
/// Groups of lanes: the fast path takes structures of up to `LANES · LANE_GROUPS` groups.
const LANE_GROUPS: usize = 2;
/// The most parameter groups (one equation each) the fast path takes.
pub(crate) const FAST_GROUPS: usize = LANES * LANE_GROUPS;
/// No state (an index every state slice is shorter than): reads 0.
const NO_STATE: u8 = u8::MAX;

/// The most `sign`, `pos`, `neg` terms the fast path takes (their values are computed first,
/// into a small array, through [`Structure::basis`]).
const MAX_OTHER: usize = 7;
/// Where a term reads its basis function: `x`, `z` (a `der(·)`), `u`, or the extra values
/// (1 at index 0, then the `sign`/`pos`/`neg` values).
const FROM_X: u8 = 0;
const FROM_Z: u8 = 1;
const FROM_U: u8 = 2;
const FROM_EXTRA: u8 = 3;

/// One term of the compiled regression: `coef · φ`, `φ` entry `idx` of source `src` (one of
/// the `FROM_*`), added to lane vector `dst` of the regression buffer ([`Buffer`], flat: block,
/// slot, lane). A parameter's term goes to its lane's regressor (block: the group of lanes,
/// slot: the parameter's index in its group); a known term to its lane's `y` (block
/// `LANE_GROUPS +` the group of lanes, slot 0) with its coefficient negated (`y + (−c)φ` is
/// `y − cφ` exactly). The coefficient is a lane vector, 0 in the other lanes (which add
/// `0 · φ`, a zero: their values do not change), so that the buffer is written and read as
/// whole lane vectors (a vector load of values stored lane by lane would wait for the
/// stores).
#[derive(Debug, Clone, Copy, PartialEq)]
struct Gather<T> {
    coef: [T; LANES],
    src: u8,
    idx: u8,
    dst: u16,
    /// The last term of its entry (the terms are kept grouped by entry, in their order within
    /// it): the entry, summed in a register, is stored after this one.
    last: bool,
}

/// The regression of one sample: the lanes' regressors (blocks `0..LANE_GROUPS`) and their
/// `y` (slot 0 of blocks `LANE_GROUPS..`).
type Buffer<T, const P: usize> = [[[T; LANES]; P]; 2 * LANE_GROUPS];

/// [`Buffer`] aligned to 16 bytes (its lane vectors never straddle a cache line).
#[repr(align(16))]
struct Aligned<T, const P: usize>(Buffer<T, P>);

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
    /// When every term is `1 · x_j` with a parameter, one per regressor entry, and there are
    /// no known terms (the full-row structure and its sparse forms): each entry's state
    /// ([`NO_STATE`] for none), read directly instead of through `gather`.
    direct: Option<[[[u8; LANES]; P]; LANE_GROUPS]>,
    /// Of a direct regression: entry `a` of every lane's regressor is `x_a` (the full-row
    /// structure), so each is read once for all lanes.
    identity: bool,
    /// The `sign`, `pos`, `neg` terms' basis functions (in the order their values are kept).
    others: [Basis; MAX_OTHER],
    n_others: u8,
    /// Equation `i` is in lane `i` (the innovations are the lanes in order).
    in_order: bool,
}

impl<T: Real, const P: usize> Fast<T, P> {
    /// The fast path of `s` with groups `part` (not able when a group has several equations
    /// or there are more than [`FAST_GROUPS`] groups).
    /// Whether equation `i` is lane `i` (tests: both arrangements are exercised).
    #[cfg(test)]
    pub(crate) fn in_order(&self) -> bool {
        self.in_order
    }

    pub(crate) fn new(s: &Structure<T>, part: &Partition) -> Self {
        let mut fast = Self::none();
        let (ne, ng) = (s.equations(), part.groups as usize);
        if ne != ng || ne == 0 || ne > FAST_GROUPS {
            return fast;
        }
        let mut n = 0;
        let mut direct = [[[NO_STATE; LANES]; P]; LANE_GROUPS];
        let mut is_direct = true;
        for i in 0..ne {
            let g = part.group_of_eq[i];
            fast.lane_of_eq[i] = g;
            fast.state_of_lane[g as usize] = s.equation_state(i) as u8;
            let (lg, k) = (g as usize / LANES, g as usize % LANES);
            for t in s.terms(i) {
                let (src, idx) = match t.basis {
                    Basis::Var(Var::State(j)) => (FROM_X, j),
                    Basis::Var(Var::Deriv(j)) => (FROM_Z, j),
                    Basis::Var(Var::Input(j)) => (FROM_U, j),
                    Basis::One => (FROM_EXTRA, 0),
                    b => {
                        let Some(slot) = fast.others.get_mut(fast.n_others as usize) else {
                            return Self::none();
                        };
                        *slot = b;
                        fast.n_others += 1;
                        (FROM_EXTRA, fast.n_others)
                    }
                };
                let (dst, c) = match t.param {
                    Some(p) => (lg * P + part.local[p as usize] as usize, t.coef),
                    None => ((LANE_GROUPS + lg) * P, -t.coef),
                };
                let mut coef = [T::zero(); LANES];
                coef[k] = c;
                fast.gather[n] = Gather { coef, src, idx, dst: dst as u16, last: true };
                n += 1;
                match (t.param, src) {
                    (Some(p), FROM_X) if t.coef == T::one() => {
                        let j = idx;
                        let e = &mut direct[lg][part.local[p as usize] as usize][k];
                        is_direct &= *e == NO_STATE;
                        *e = j;
                    }
                    _ => is_direct = false,
                }
            }
        }
        // Grouped by entry (a stable insertion sort: each entry's terms keep their order, so
        // its sum is the same), each group's last term marked.
        let terms = &mut fast.gather[..n];
        for i in 1..terms.len() {
            let mut j = i;
            while j > 0 && terms[j - 1].dst > terms[j].dst {
                terms.swap(j - 1, j);
                j -= 1;
            }
        }
        for i in 0..n {
            terms[i].last = i + 1 == n || terms[i + 1].dst != terms[i].dst;
        }
        fast.n_gather = n as u8;
        fast.direct = is_direct.then_some(direct);
        fast.identity = is_direct
            && (0..ne).all(|g| (0..P).all(|a| direct[g / LANES][a][g % LANES] as usize == a))
            && P <= s.states();
        fast.in_order = (0..ne).all(|i| fast.lane_of_eq[i] as usize == i);
        fast.groups = ne as u8;
        fast.used = ne.div_ceil(LANES) as u8;
        fast.able = true;
        fast
    }

    /// No fast path (and a deserialized identifier's until it is checked).
    pub(crate) fn none() -> Self {
        let none = Gather { coef: [T::zero(); LANES], src: FROM_EXTRA, idx: 0, dst: 0, last: true };
        Self {
            lanes: [XLanes::padding(); LANE_GROUPS],
            able: false,
            live: false,
            groups: 0,
            used: 0,
            lane_of_eq: [0; FAST_GROUPS],
            state_of_lane: [NO_STATE; FAST_GROUPS],
            gather: [none; MAX_TERMS],
            n_gather: 0,
            direct: None,
            identity: false,
            others: [Basis::One; MAX_OTHER],
            n_others: 0,
            in_order: false,
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

    /// The regressors and left-hand sides of every lane at sample `(x, z, u)` into `buf`
    /// (zero), from the compiled table: `y = z[state]`, then per term `φ = coef · basis(x, z, u)`
    /// added to its regressor entry (from 0) or subtracted from `y`, in the order of the
    /// terms (the general path's arithmetic, [`super::structured::group_regression`]; the row
    /// weight is 1 with one equation per group).
    #[inline(always)]
    fn regression(&self, s: &Structure<T>, x: &[T], z: &[T], u: &[T], buf: &mut Buffer<T, P>) {
        // Whole lane vectors (lanes that hold no filter read no state: 0).
        for lg in 0..self.used as usize {
            let mut y = [T::zero(); LANES];
            for (k, v) in y.iter_mut().enumerate() {
                let st = self.state_of_lane.get(lg * LANES + k).copied().unwrap_or(NO_STATE);
                *v = z.get(st as usize).copied().unwrap_or_else(T::zero);
            }
            buf[LANE_GROUPS + lg][0] = y;
        }
        if self.identity {
            if let Some(xs) = x.get(..P) {
                // Every lane's regressor is x (`0 + x_a`, as the general path adds the term
                // to a zero entry); lanes that hold no filter read it too, with P = 0 they
                // never move.
                for block in buf.iter_mut().take(self.used as usize) {
                    for a in 0..P {
                        block[a] = [T::zero() + xs[a]; LANES];
                    }
                }
                return;
            }
        }
        if let Some(direct) = &self.direct {
            // `0 + x_j`, as the general path adds the term to a zero entry.
            for (lg, d) in direct.iter().enumerate().take(self.used as usize) {
                for a in 0..P {
                    let mut v = [T::zero(); LANES];
                    for k in 0..LANES {
                        v[k] = T::zero() + x.get(d[a][k] as usize).copied().unwrap_or_else(T::zero);
                    }
                    buf[lg][a] = v;
                }
            }
            return;
        }
        let mut extra = [T::one(); 1 + MAX_OTHER];
        if self.n_others > 0 {
            for (v, b) in extra[1..].iter_mut().zip(&self.others[..self.n_others as usize]) {
                *v = s.basis(*b, x, z, u);
            }
        }
        let at = |v: &[T], j: u8| v.get(j as usize).copied().unwrap_or_else(T::zero);
        let flat = buf.as_flattened_mut();
        // Each entry summed in a register from its value before (0, or y = z[state]), then
        // stored once.
        let mut acc = [T::zero(); LANES];
        let mut first = true;
        for t in &self.gather[..self.n_gather as usize] {
            if first {
                acc = flat.get(t.dst as usize).copied().unwrap_or([T::zero(); LANES]);
            }
            let v = match t.src {
                FROM_X => at(x, t.idx),
                FROM_Z => at(z, t.idx),
                FROM_U => at(u, t.idx),
                _ => at(&extra, t.idx),
            };
            for k in 0..LANES {
                acc[k] += t.coef[k] * v;
            }
            if t.last {
                if let Some(d) = flat.get_mut(t.dst as usize) {
                    *d = acc;
                }
            }
            first = t.last;
        }
    }

    /// One sample through the lanes (live): every group of lanes planned, then all applied,
    /// innovations into `e` (one per equation). `false` (nothing changed) when some lane must
    /// take the general update (see [`XLanes::plan`]).
    #[inline(always)]
    pub(crate) fn step(&mut self, s: &Structure<T>, x: &[T], z: &[T], u: &[T], e: &mut [T]) -> bool {
        let mut aligned = Aligned([[[T::zero(); LANES]; P]; 2 * LANE_GROUPS]);
        let buf = &mut aligned.0;
        self.regression(s, x, z, u, buf);
        let mut ek = [[T::zero(); LANES]; LANE_GROUPS];
        if self.used == 1 {
            let mut pl = XPlan::empty();
            if !self.lanes[0].plan(&buf[0], buf[LANE_GROUPS][0], &mut pl) {
                return false;
            }
            self.lanes[0].apply(&pl);
            ek[0] = pl.e;
        } else {
            let (mut p0, mut p1) = (XPlan::empty(), XPlan::empty());
            let ok0 = self.lanes[0].plan(&buf[0], buf[LANE_GROUPS][0], &mut p0);
            let ok1 = self.lanes[1].plan(&buf[1], buf[LANE_GROUPS + 1][0], &mut p1);
            if !(ok0 & ok1) {
                return false;
            }
            self.lanes[0].apply(&p0);
            self.lanes[1].apply(&p1);
            (ek[0], ek[1]) = (p0.e, p1.e);
        }
        if self.in_order {
            // Lane by lane (a copy of a run-time length would call `memcpy`).
            let flat = ek.as_flattened();
            for i in 0..FAST_GROUPS {
                if let Some(o) = e.get_mut(i) {
                    *o = flat[i];
                }
            }
        } else {
            for (o, &g) in e.iter_mut().zip(&self.lane_of_eq[..self.groups as usize]) {
                let g = g as usize;
                *o = ek[g / LANES][g % LANES];
            }
        }
        true
    }
}
