//! [`KalmanFull`] behind the [`Identifier`] interface, and its persistence (`Persist`, and the
//! checks of a state read back).

use super::*;

#[cfg(feature = "serde")]
impl<T: Real, const N: usize, S: Store<T, N>> KalmanFull<T, N, S> {
    /// Checks a deserialized identifier: valid rows and options, every buffer sized for
    /// its rows (`θ`: `K`; `P`, `R` and the scratch: `K²`).
    pub(crate) fn restored(&mut self) -> Result<()> {
        self.opts.validate()?;
        let k = crate::model::RowSet::<N>::new(self.rows.flat())?.len();
        let lens = [
            ("theta", self.theta.flat().len(), k),
            ("ssr", self.ssr.flat().len(), k),
            ("pn", self.pn.flat().len(), k * k),
            ("p", self.p.flat().len(), k * k),
            ("r", self.r.flat().len(), k * k),
            ("c", self.c.flat().len(), k * k),
            ("w", self.w.flat().len(), k * k),
            ("s", self.s.flat().len(), k * k),
        ];
        match lens.into_iter().find(|(_, got, expected)| got != expected) {
            Some((arg, got, expected)) => Err(Error::Shape { arg, expected, got }),
            None => Ok(()),
        }
    }
}

crate::identify::persist_by_serde!([T: Real, const N: usize, S: Store<T, N>] KalmanFull<T, N, S>);

impl<T: Real, const N: usize, S: Store<T, N>> Identifier<T> for KalmanFull<T, N, S> {
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

    /// The whole `(K·N) × (K·N)` matrix.
    fn covariance_into(&self, out: &mut [T]) -> Result<()> {
        let k = self.rows.flat().len();
        let kn = k * N;
        if out.len() != kn * kn {
            return Err(Error::Shape { arg: "out", expected: kn * kn, got: out.len() });
        }
        for (idx, o) in out.iter_mut().enumerate() {
            let (i, j) = (idx / kn, idx % kn);
            *o = self.p_block(i / N, j / N)[(i % N, j % N)];
        }
        Ok(())
    }

    fn noise_into(&self, out: &mut [T]) -> Result<()> {
        let k = self.rows.flat().len();
        if out.len() != k * k {
            return Err(Error::Shape { arg: "out", expected: k * k, got: out.len() });
        }
        out.copy_from_slice(self.r.flat());
        Ok(())
    }

    fn trace(&self) -> Option<T> {
        Some(KalmanFull::trace(self))
    }

    fn reinit_count(&self) -> u32 {
        self.reinit_count
    }

    /// `P ← p0 I` (every diagonal block `p0 I`, the others 0).
    fn reset_covariance(&mut self, p0: T) -> Result<()> {
        super::super::guards::check_reset(p0, false)?;
        let k = self.rows.flat().len();
        for (ij, block) in self.p.flat_mut().iter_mut().enumerate() {
            *block = if ij / k == ij % k { SMatrix::identity() * p0 } else { SMatrix::zeros() };
        }
        Ok(())
    }

    /// The samples the gate left out, the same count for every row (see
    /// [`KalmanFull::gated`]).
    fn gated_into(&self, out: &mut [u64]) -> Result<()> {
        let k = self.rows.flat().len();
        if out.len() != k {
            return Err(Error::Shape { arg: "out", expected: k, got: out.len() });
        }
        out.fill(self.gated);
        Ok(())
    }
}
