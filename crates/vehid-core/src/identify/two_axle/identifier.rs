//! [`TwoAxle`] behind the [`Identifier`] interface, and its persistence (`Persist`).

use super::MAX_TRACKS;
use super::*;

crate::identify::persist_by_serde!([T: Real, const N: usize, const P: usize, S: Store<T, N>, B: RingStore<Past<T, N>>, const M: usize] TwoAxle<T, N, P, S, B, M>);

impl<T: Real, const N: usize, const P: usize, S: Store<T, N>, B: RingStore<Past<T, N>>, const M: usize> Identifier<T>
    for TwoAxle<T, N, P, S, B, M>
{
    fn dims(&self) -> Dims {
        let k = self.rows.len();
        Dims { states: N, inputs: 0, equations: k, params: k * N }
    }

    fn rows(&self) -> &[usize] {
        self.rows.as_slice()
    }

    /// The sample on the road point after the previous one ([`TwoAxle::update_next`]).
    fn update_into(&mut self, x: &[T], z: &[T], u: &[T], e: &mut [T]) -> Result<()> {
        check_lengths(self.dims(), x, z, u, e)?;
        self.update_at(&vector(x), &vector(z), None, e).map(|_| ())
    }

    fn params_into(&self, out: &mut [T]) -> Result<()> {
        self.theta_into(out)
    }

    fn samples(&self) -> u64 {
        self.samples
    }

    /// Block diagonal by group ([`Identifier::groups_into`]): each body row's `P`; with
    /// [`WheelMethod::Cancel`] each track's joint `P` over its rear and front rows (their
    /// cross-covariance included); otherwise each wheel row's own `P`.
    fn covariance_into(&self, out: &mut [T]) -> Result<()> {
        let k = self.rows.len();
        let kn = k * N;
        if out.len() != kn * kn {
            return Err(Error::Shape { arg: "out", expected: kn * kn, got: out.len() });
        }
        out.fill(T::zero());
        let rows = self.rows.as_slice();
        for (i, &ri) in rows.iter().enumerate() {
            for (j, &rj) in rows.iter().enumerate() {
                let mut put = |p: &dyn Fn(usize, usize) -> T| {
                    for a in 0..N {
                        for b in 0..N {
                            out[(i * N + a) * kn + j * N + b] = p(a, b);
                        }
                    }
                };
                match (self.source(ri), self.source(rj)) {
                    (Source::Body(a), Source::Body(b)) if a == b => {
                        if let Some(body) = &self.body {
                            let p = body.filter(a).p();
                            put(&|x, y| p[(x, y)]);
                        }
                    }
                    (Source::Joint(t, oi), Source::Joint(u, oj)) if t == u => {
                        let p = self.joint[t].p();
                        put(&|x, y| p[(oi + x, oj + y)]);
                    }
                    (Source::Row(t, f), Source::Row(u, g)) if t == u && f == g => {
                        let p = if f { self.front[t].p() } else { self.rear[t].p() };
                        put(&|x, y| p[(x, y)]);
                    }
                    _ => {}
                }
            }
        }
        Ok(())
    }

    /// Each row's filter's `r`: a track's two rows under [`WheelMethod::Cancel`] both the
    /// cancelled equation's `σ_v² (1 + ρ²)` (the joint filter's unit).
    fn noise_into(&self, out: &mut [T]) -> Result<()> {
        crate::identify::checks::diagonal_into(out, self.rows.len(), |i| self.filter_stats(self.rows.as_slice()[i]).0)
    }

    /// Each row's filter's residual sums; under [`WheelMethod::Cancel`] a track's joint filter
    /// (its cancelled and direct front equations, in the cancelled equation's unit) is reported
    /// on the rear row, the front row adding none.
    fn residuals_into(&self, ssr: &mut [T], nobs: &mut [T]) -> Result<()> {
        let k = self.rows.len();
        if ssr.len() != k || nobs.len() != k {
            return Err(Error::Shape { arg: "ssr", expected: k, got: ssr.len().min(nobs.len()) });
        }
        for (i, &row) in self.rows.as_slice().iter().enumerate() {
            (_, ssr[i], nobs[i]) = self.filter_stats(row);
        }
        Ok(())
    }

    /// Each row's samples left out by its filter's own residual gate
    /// ([`TwoAxleConfig::gate`]; a track's joint filter counts on both its rows).
    fn gated_into(&self, out: &mut [u64]) -> Result<()> {
        let k = self.rows.len();
        if out.len() != k {
            return Err(Error::Shape { arg: "out", expected: k, got: out.len() });
        }
        for (o, &row) in out.iter_mut().zip(self.rows.as_slice()) {
            let own = match self.source(row) {
                Source::Body(i) => self.body.as_ref().map_or(0, |b| b.filter(i).gated()),
                Source::Joint(t, _) => self.joint[t].gated(),
                Source::Row(t, true) => self.front[t].gated(),
                Source::Row(t, false) => self.rear[t].gated(),
            };
            *o = own;
        }
        Ok(())
    }

    /// One group per body row, per wheel row (methods none and thesis) or per track (its two
    /// rows, method cancel).
    fn groups_into(&self, group_of_param: &mut [usize], group_of_eq: &mut [usize]) -> Result<()> {
        let k = self.rows.len();
        if group_of_param.len() != k * N {
            return Err(Error::Shape { arg: "group_of_param", expected: k * N, got: group_of_param.len() });
        }
        if group_of_eq.len() != k {
            return Err(Error::Shape { arg: "group_of_eq", expected: k, got: group_of_eq.len() });
        }
        // Numbered in the order the rows first meet them; a track's rows share one.
        let (mut tracks, mut next) = ([None; MAX_TRACKS], 0);
        for (i, &row) in self.rows.as_slice().iter().enumerate() {
            let g = match self.source(row) {
                Source::Joint(t, _) => *tracks[t].get_or_insert_with(|| {
                    next += 1;
                    next - 1
                }),
                _ => {
                    next += 1;
                    next - 1
                }
            };
            group_of_eq[i] = g;
            group_of_param[i * N..(i + 1) * N].fill(g);
        }
        Ok(())
    }

    /// The road point of the sample left out passes: the next sample is on the point after it.
    fn skip_sample(&mut self) {
        self.last_grid = Some(self.last_grid.map_or(0, |g| g.saturating_add(1)));
    }
}

/// Which filter holds a row's estimate.
#[derive(Clone, Copy, PartialEq)]
enum Source {
    /// Body row `i` of the body rows' filter.
    Body(usize),
    /// Track `t`'s joint filter, the row's parameters from offset `o` (0 rear, `N` front).
    Joint(usize, usize),
    /// Track `t`'s own front (`true`) or rear row filter.
    Row(usize, bool),
}

impl<T: Real, const N: usize, const P: usize, S: Store<T, N>, B: RingStore<Past<T, N>>, const M: usize>
    TwoAxle<T, N, P, S, B, M>
{
    fn source(&self, row: usize) -> Source {
        match (self.wheel_of(row), self.cfg.method) {
            (Some((t, front)), WheelMethod::Cancel) => Source::Joint(t, if front { N } else { 0 }),
            (Some((t, front)), _) => Source::Row(t, front),
            (None, _) => {
                let body = self.body.as_ref().map_or(&[][..], |b| b.rows());
                Source::Body(body.iter().position(|&r| r == row).unwrap_or(0))
            }
        }
    }

    /// `(r, ssr, nobs)` of the filter behind `row` (see `residuals_into`).
    fn filter_stats(&self, row: usize) -> (T, T, T) {
        let of = |f: &RowIdentifier<T, N>| (f.r(), f.ssr(), f.nobs());
        match self.source(row) {
            Source::Body(i) => self.body.as_ref().map_or((T::zero(), T::zero(), T::zero()), |b| of(&b.filter(i))),
            Source::Joint(t, o) => {
                let j = &self.joint[t];
                if o == 0 {
                    (j.r(), j.ssr(), j.nobs())
                } else {
                    (j.r(), T::zero(), T::zero())
                }
            }
            Source::Row(t, true) => of(&self.front[t]),
            Source::Row(t, false) => of(&self.rear[t]),
        }
    }
}
