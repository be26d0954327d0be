//! [`KalmanShared`] behind the [`Identifier`] interface, and its persistence (`Persist`, and the
//! checks of a state read back).

use super::*;

#[cfg(feature = "serde")]
impl<T: Real, const N: usize, S: Store<T, N>> KalmanShared<T, N, S> {
    /// Checks a deserialized identifier: valid rows and options, one `θ_i`, `r_i` and gate
    /// statistic per row.
    pub(crate) fn restored(&mut self) -> Result<()> {
        self.opts.validate()?;
        let k = crate::model::RowSet::<N>::new(self.rows.flat())?.len();
        for (arg, len) in
            [("theta", self.theta.flat().len()), ("r", self.r.flat().len()), ("ssr", self.ssr.flat().len())]
        {
            if len != k {
                return Err(Error::Shape { arg, expected: k, got: len });
            }
        }
        Ok(())
    }
}

crate::identify::persist_by_serde!([T: Real, const N: usize, S: Store<T, N>] KalmanShared<T, N, S>);

impl<T: Real, const N: usize, S: Store<T, N>> Identifier<T> for KalmanShared<T, N, S> {
    fn dims(&self) -> Dims {
        let k = self.rows.flat().len();
        Dims { states: N, inputs: 0, equations: k, params: k * N }
    }

    fn rows(&self) -> &[usize] {
        self.rows.flat()
    }

    #[inline]
    fn update_into(&mut self, x: &[T], z: &[T], u: &[T], e: &mut [T]) -> Result<()> {
        check_lengths(self.dims(), x, z, u, e)?;
        self.update_vec(&vector(x), &vector(z), e)
    }

    fn params_into(&self, out: &mut [T]) -> Result<()> {
        self.theta_into(out)
    }

    fn samples(&self) -> u64 {
        self.samples
    }

    /// Block diagonal: `P_i = r_i Q` per row.
    fn covariance_into(&self, out: &mut [T]) -> Result<()> {
        let k = self.rows.flat().len();
        let kn = k * N;
        if out.len() != kn * kn {
            return Err(Error::Shape { arg: "out", expected: kn * kn, got: out.len() });
        }
        out.fill(T::zero());
        for i in 0..k {
            let p = self.p(i);
            for a in 0..N {
                for b in 0..N {
                    out[(i * N + a) * kn + i * N + b] = p[(a, b)];
                }
            }
        }
        Ok(())
    }

    fn noise_into(&self, out: &mut [T]) -> Result<()> {
        crate::identify::checks::diagonal_into(out, self.rows.flat().len(), |i| self.r.flat()[i])
    }

    fn trace(&self) -> Option<T> {
        Some(KalmanShared::trace(self))
    }

    fn reinit_count(&self) -> u32 {
        self.reinit_count
    }

    /// `Q ← (p0 / r_1) I`: the first row's `P_1 = p0 I`, every row `P_i = p0 (r_i / r_1) I`
    /// (the shared form keeps one ratio `r/p0` for all rows; with equal `r`, `P_i = p0 I`).
    fn reset_covariance(&mut self, p0: T) -> Result<()> {
        super::super::guards::check_reset(p0, false)?;
        let r1 = self.r.flat().first().copied().unwrap_or(T::one());
        let scale = p0 / r1;
        if !(scale > T::zero() && scale.finite()) {
            return Err(Error::InvalidArgument {
                arg: "p0",
                expected: "a covariance whose ratio to r is finite and > 0",
            });
        }
        self.q = SMatrix::identity() * scale;
        Ok(())
    }

    /// The samples the gate left out, the same count for every row (see
    /// [`KalmanShared::gated`]).
    fn gated_into(&self, out: &mut [u64]) -> Result<()> {
        let k = self.rows.flat().len();
        if out.len() != k {
            return Err(Error::Shape { arg: "out", expected: k, got: out.len() });
        }
        out.fill(self.gated);
        Ok(())
    }
}
