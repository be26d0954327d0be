//! [`RowGroup`] for [`RowLanes`]: the lanes as one group of row filters (set and read a
//! lane, plan a sample, check it, apply it).

use super::super::guards::overflow_culprit;
use super::super::sums::{is_fin, lane_dot, lane_sum, tree_sum};
use super::super::{CovarianceForm, RowIdentifier};
use super::{put_lanes, LaneScratch, RowGroup, RowLanes, SqrtScratch, FORGET, GENERAL, PLAIN};
use crate::identify::OVERFLOW;
use crate::{Error, Real};
use nalgebra::SVector;

impl<T: Real, const N: usize, const L: usize> RowGroup<T, N> for RowLanes<T, N, L> {
    const LANES: usize = L;
    type Scratch = LaneScratch<T, N, L>;
    type SqrtScratch = SqrtScratch<T, N, L>;

    fn padding() -> Self {
        let mut p = [[[T::zero(); L]; N]; N];
        for (a, row) in p.iter_mut().enumerate() {
            row[a] = [T::one(); L];
        }
        Self {
            theta: [[T::zero(); L]; N],
            p,
            r: [T::one(); L],
            zrow: [0; L],
            active: [T::zero(); L],
            ssr: [T::zero(); L],
            nobs: [T::zero(); L],
            s: [T::zero(); L],
            cap: [T::zero(); L],
            lambda: T::one(),
            drift: T::zero(),
            directional: false,
            gate: T::zero(),
            huber: T::zero(),
            gated: [0; L],
            used: 0,
            form: CovarianceForm::Standard,
            start: false,
            any_r_zero: false,
            mode: PLAIN,
            forget: [T::one(); L],
        }
    }

    fn scratch() -> Self::Scratch {
        LaneScratch {
            px: [[T::zero(); L]; N],
            c: [T::zero(); L],
            w: [T::zero(); L],
            s: [T::zero(); L],
            xth: [T::zero(); L],
            step: [T::zero(); L],
            go: [T::zero(); L],
            e: [T::zero(); L],
            fc: [T::zero(); L],
            scale: [T::one(); L],
            add: [T::zero(); L],
            gated: [T::zero(); L],
            reff: [T::zero(); L],
            ssr: [T::zero(); L],
            nobs: [T::zero(); L],
            s_last: [T::zero(); L],
        }
    }

    fn set_lane(&mut self, k: usize, zrow: usize, f: &RowIdentifier<T, N>) {
        for a in 0..N {
            self.theta[a][k] = f.theta[a];
            for b in a..N {
                self.p[a][b][k] = f.m[(a, b)];
            }
        }
        self.r[k] = f.r;
        self.zrow[k] = zrow;
        self.active[k] = if f.retired { T::zero() } else { T::one() };
        (self.ssr[k], self.nobs[k], self.s[k], self.cap[k], self.gated[k]) = (f.ssr, f.nobs, f.s, f.cap, f.gated);
        (self.lambda, self.drift, self.directional) = (f.lambda, f.drift, f.directional);
        (self.form, self.start, self.gate, self.huber) = (f.form, f.start, f.gate, f.huber);
        self.used = self.used.max(k + 1);
        self.any_r_zero = (0..self.used).any(|i| self.r[i] == T::zero());
        self.refresh();
    }

    #[inline(always)]
    fn mode(&self) -> u8 {
        self.mode
    }

    fn refresh(&mut self) {
        // The outlier gate alone keeps the plain mode: its plan tests the gate and sends a
        // sample beyond it to the general path (`plan`, `beyond_gate`).
        let standard =
            self.form == CovarianceForm::Standard && !self.start && !self.any_r_zero && self.huber == T::zero();
        let exponential = !self.directional && self.drift == T::zero();
        self.mode = match (standard, self.tracks(), exponential) {
            (true, false, _) => PLAIN,
            (true, true, true) if self.gate == T::zero() => FORGET,
            _ => GENERAL,
        };
        let inv = T::one() / self.lambda;
        for k in 0..L {
            self.forget[k] = if self.active[k] != T::zero() { inv } else { T::one() };
        }
    }

    fn lane(&self, k: usize) -> RowIdentifier<T, N> {
        let mut theta = SVector::<T, N>::zeros();
        for a in 0..N {
            theta[a] = self.theta[a][k];
        }
        RowIdentifier {
            theta,
            m: self.p_lane(k),
            r: self.r[k],
            form: self.form,
            start: self.start,
            retired: self.active[k] == T::zero(),
            lambda: self.lambda,
            directional: self.directional,
            drift: self.drift,
            cap: self.cap[k],
            gate: self.gate,
            huber: self.huber,
            gated: self.gated[k],
            ssr: self.ssr[k],
            nobs: self.nobs[k],
            s: self.s[k],
            dim: N as u8,
        }
    }

    fn theta_lane(&self, k: usize) -> SVector<T, N> {
        if self.start {
            return SVector::repeat(T::of(f64::NAN));
        }
        SVector::from_fn(|a, _| self.theta[a][k])
    }

    fn trace_lane(&self, k: usize) -> T {
        if self.start || self.form == CovarianceForm::Sqrt {
            return self.lane(k).trace();
        }
        let mut d = [T::zero(); N];
        for (a, v) in d.iter_mut().enumerate() {
            *v = self.p[a][a][k];
        }
        tree_sum(d)
    }

    fn retire_lane(&mut self, k: usize) {
        self.active[k] = T::zero();
        self.refresh();
    }

    fn reinitialize(&mut self) {
        if self.start {
            return;
        }
        for k in 0..self.used {
            if self.form == CovarianceForm::Sqrt {
                let mut f = self.lane(k);
                f.reinitialize();
                let zrow = self.zrow[k];
                self.set_lane(k, zrow, &f);
                continue;
            }
            for a in 0..N {
                self.p[a][a][k] *= T::of(10.0);
            }
            self.r[k] *= T::of(2.0);
            self.active[k] = T::one();
        }
        self.refresh();
    }

    fn reset_covariance(&mut self, p0: T) {
        for k in 0..self.used {
            let mut f = self.lane(k);
            if f.reset_covariance(p0).is_ok() {
                let zrow = self.zrow[k];
                self.set_lane(k, zrow, &f);
            }
        }
        self.refresh();
    }

    fn starting(&self) -> bool {
        self.start
    }

    fn lanes_are(&self, rows: &[usize]) -> bool {
        self.used == rows.len() && self.zrow.get(..self.used) == Some(rows)
    }

    fn gates(sc: &Self::Scratch) -> bool {
        // Padding is never gated.
        sc.gated.iter().any(|g| *g != T::zero())
    }

    fn gates_sqrt(sc: &Self::SqrtScratch) -> bool {
        Self::gates(&sc.base)
    }

    #[cold]
    fn absorb(&mut self, x: &SVector<T, N>, z: &SVector<T, N>, e: &mut [T]) -> crate::Result<()> {
        let mut next = *self;
        for k in 0..self.used {
            let mut f = self.lane(k);
            let zk = z.as_slice().get(self.zrow[k]).copied().unwrap_or_else(T::zero);
            e[k] = f.update(x, zk)?;
            next.set_lane(k, self.zrow[k], &f);
        }
        *self = next;
        Ok(())
    }

    #[inline(always)]
    fn plan<const MODE: u8>(&self, x: &SVector<T, N>, z: &SVector<T, N>, e: &mut [T], sc: &mut Self::Scratch) -> bool {
        // Everything is computed into locals and the plan written once at the end: the
        // compiler then keeps it in registers (no initialization, no stores it cannot drop).
        let xth = lane_dot(&self.theta, x);
        let ek = self.innovations(z, xth);
        put_lanes(e, ek);
        // P x from the upper triangle, lane by lane, each sum pairwise.
        let mut px = [[T::zero(); L]; N];
        for a in 0..N {
            let mut col = [[T::zero(); L]; N];
            for b in 0..N {
                col[b] = if a <= b { self.p[a][b] } else { self.p[b][a] };
            }
            px[a] = lane_dot(&col, x);
        }
        // Exponential forgetting needs tr P before the update: summed while the diagonal is
        // loaded anyway.
        let trace = if const { MODE == FORGET } { self.diag_traces() } else { [T::zero(); L] };
        let mut s = lane_dot(&px, x);
        for k in 0..L {
            s[k] += self.r[k];
        }
        let mut go = self.active;
        if const { MODE == GENERAL } && self.any_r_zero {
            go = self.collapsed_lanes(x, px, s, go);
        }
        let (mut gated, mut reff) = ([T::zero(); L], self.r);
        if const { MODE == GENERAL } && (self.gate > T::zero() || self.huber > T::zero()) {
            (gated, reff) = self.screen_lanes(ek, s);
            for k in 0..L {
                go[k] = if gated[k] != T::zero() { T::zero() } else { go[k] };
                s[k] += reff[k] - self.r[k];
            }
        }
        // Per lane, as whole-lane arithmetic and selects (so that it stays vectorized). A lane
        // that steps needs 0 < s < inf; r/s below √ε makes its downdate risky. Either marks
        // the lane's step check with a NaN, so that one test of the steps refuses the plan:
        // `check` then names the cause, or finds only risky downdates that stay definite.
        let rk = super::super::guards::risky::<T>();
        let mut w = [T::zero(); L];
        let mut c = [T::zero(); L];
        let mut flag = [T::zero(); L];
        for k in 0..L {
            let inv = T::one() / s[k];
            let step = go[k] != T::zero();
            let fine = (s[k] > T::zero()) & (s[k] <= T::biggest());
            let risky = (reff[k] > T::zero()) & (reff[k] < rk * s[k]);
            flag[k] = if step & (risky | !fine) { T::of(f64::NAN) } else { T::zero() };
            w[k] = if step { inv } else { T::zero() };
            c[k] = if step { ek[k] * inv } else { T::zero() };
        }
        // The plain mode under the outlier gate: a lane beyond it marks the plan like a risky
        // step, so that `settle` plans the sample again in the general mode, which leaves it
        // out (the same test, `guards::screen`, on the same values). Apart from the loop
        // above, so that without a gate that loop is what it was.
        if const { MODE == PLAIN } && self.gate > T::zero() {
            let beyond = self.beyond_gate(ek, s);
            for k in 0..L {
                flag[k] = if beyond[k] & (go[k] != T::zero()) { T::of(f64::NAN) } else { flag[k] };
            }
        }
        let mut st = [[T::zero(); L]; N];
        for a in 0..N {
            for k in 0..L {
                st[a][k] = px[a][k] * c[k];
            }
        }
        let step = lane_sum(st);
        let mut ok = true;
        for k in 0..L {
            ok &= is_fin(step[k] + flag[k]);
        }
        let (fc, scale, add) = match MODE {
            PLAIN => ([T::zero(); L], [T::one(); L], [T::zero(); L]),
            FORGET => ([T::zero(); L], self.forgetting(trace), [T::zero(); L]),
            _ if self.tracks() => self.tracking(self.diag_traces(), s, reff, go),
            _ => ([T::zero(); L], [T::one(); L], [T::zero(); L]),
        };
        let (ssr, nobs, s_last) = self.statistics(go, ek, c, s);
        *sc = LaneScratch { px, c, w, s, xth, step, go, e: ek, fc, scale, add, gated, reff, ssr, nobs, s_last };
        ok
    }

    #[cold]
    fn accepts(&self, x: &SVector<T, N>, sc: &Self::Scratch) -> bool {
        let rk = super::super::guards::risky::<T>();
        let mut risky = false;
        for k in 0..L {
            let go = sc.go[k] != T::zero();
            if !sc.step[k].finite() || (go && !(sc.s[k] > T::zero() && sc.s[k] <= T::biggest())) {
                return false;
            }
            risky |= go && sc.reff[k] > T::zero() && sc.reff[k] < rk * sc.s[k];
        }
        !risky || self.downdates_stay_definite(x, *sc)
    }

    #[cold]
    fn check(&self, x: &SVector<T, N>, sc: &Self::Scratch) -> crate::Result<()> {
        for k in 0..self.used {
            if sc.go[k] == T::zero() {
                continue;
            }
            // s overflows through the state; a finite s with an infinite step, through the
            // innovation.
            if !sc.s[k].finite() {
                return Err(OVERFLOW);
            }
            if !sc.step[k].finite() {
                return Err(overflow_culprit(sc.e[k], sc.xth[k]));
            }
            if !(sc.s[k] > T::zero()) {
                return Err(Error::Singular {
                    what: "the innovation variance xᵀPx + r (P lost positive definiteness: reset_covariance(p0) restarts the identifier from its \
                           estimate; form='sqrt' cannot lose it)",
                });
            }
        }
        if !self.downdates_stay_definite(x, *sc) {
            return Err(super::super::guards::LOST_DEFINITENESS);
        }
        Ok(())
    }

    fn sqrt_scratch() -> Self::SqrtScratch {
        SqrtScratch { base: Self::scratch(), v: [[T::zero(); L]; N], p: [[T::zero(); L]; N], ratio: [[T::one(); L]; N] }
    }

    #[cold]
    fn check_sqrt(&self, ss: &Self::SqrtScratch) -> crate::Result<()> {
        let sc = &ss.base;
        for k in 0..self.used {
            if !sc.s[k].finite() {
                return Err(OVERFLOW);
            }
            if !sc.step[k].finite() {
                return Err(overflow_culprit(sc.e[k], sc.xth[k]));
            }
        }
        Err(Error::Singular { what: "the innovation variance xᵀPx + r (the square-root factors are not positive)" })
    }

    #[inline(always)]
    fn plan_sqrt(&self, x: &SVector<T, N>, z: &SVector<T, N>, e: &mut [T], ss: &mut Self::SqrtScratch) -> bool {
        let xth = lane_dot(&self.theta, x);
        let ek = self.innovations(z, xth);
        put_lanes(e, ek);
        self.plan_ud(x, xth, ek, ss)
    }

    #[inline(always)]
    fn apply_sqrt(&mut self, ss: &Self::SqrtScratch) {
        core::sync::atomic::compiler_fence(core::sync::atomic::Ordering::SeqCst);
        self.record::<GENERAL>(&ss.base);
        self.apply_ud(ss);
    }

    #[inline(always)]
    fn apply<const MODE: u8>(&mut self, x: &SVector<T, N>, sc: &Self::Scratch) {
        core::sync::atomic::compiler_fence(core::sync::atomic::Ordering::SeqCst);
        self.record::<MODE>(sc);
        if const { MODE == PLAIN } {
            self.step_theta(sc);
            self.downdate(sc);
            return;
        }
        if const { MODE == FORGET } {
            self.step_theta(sc);
            self.downdate_forget(sc);
            return;
        }
        match self.form {
            CovarianceForm::Standard => {
                self.step_theta(sc);
                if self.tracks() {
                    self.downdate_tracking(sc);
                } else {
                    self.downdate(sc);
                }
            }
            CovarianceForm::Joseph => {
                self.step_theta(sc);
                self.joseph(x, *sc);
            }
            // Planned and applied by `plan_sqrt` / `apply_sqrt`.
            CovarianceForm::Sqrt => {}
        }
    }
}
