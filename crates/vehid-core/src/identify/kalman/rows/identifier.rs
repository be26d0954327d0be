//! [`KalmanRows`] behind the [`Identifier`] interface, and its persistence (`Persist`, and the
//! checks of a state read back).

use super::*;

#[cfg(feature = "serde")]
impl<T: Real, const N: usize, S: Store<T, N>> KalmanRows<T, N, S> {
    /// Checks a deserialized identifier (valid rows and options, one group of lanes per
    /// `LANES` rows holding exactly those rows, one phase) and sizes its scratch again.
    pub(crate) fn restored(&mut self) -> Result<()> {
        self.opts.validate()?;
        let rows = self.rows.flat();
        crate::model::RowSet::<N>::new(rows)?;
        let lanes = <S::Group as RowGroup<T, N>>::LANES;
        let groups = self.groups.flat();
        if groups.len() != rows.len().div_ceil(lanes) {
            return Err(Error::Shape { arg: "groups", expected: rows.len().div_ceil(lanes), got: groups.len() });
        }
        let start = self.starting();
        if groups.iter().zip(rows.chunks(lanes)).any(|(g, chunk)| !g.lanes_are(chunk) || g.starting() != start) {
            return Err(Error::InvalidArgument { arg: "groups", expected: "lanes holding the unknown rows, in order" });
        }
        for g in self.groups.flat_mut() {
            g.refresh();
        }
        let groups = self.groups.flat();
        self.scratch = S::Scratches::filled("unknown_rows", groups.len(), S::Group::scratch())?;
        let sqrt_groups = if self.opts.form == CovarianceForm::Sqrt { groups.len() } else { 0 };
        self.sqrt_scratch = S::SqrtScratches::filled("unknown_rows", sqrt_groups, S::Group::sqrt_scratch())?;
        Ok(())
    }
}

crate::identify::persist_by_serde!([T: Real, const N: usize, S: Store<T, N>] KalmanRows<T, N, S>);

impl<T: Real, const N: usize, S: Store<T, N>> Identifier<T> for KalmanRows<T, N, S> {
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

    /// Block diagonal: one `N × N` block `P_i` per row.
    fn covariance_into(&self, out: &mut [T]) -> Result<()> {
        let k = self.rows.flat().len();
        let kn = k * N;
        if out.len() != kn * kn {
            return Err(Error::Shape { arg: "out", expected: kn * kn, got: out.len() });
        }
        out.fill(T::zero());
        for i in 0..k {
            let p = self.filter(i).p();
            for a in 0..N {
                for b in 0..N {
                    out[(i * N + a) * kn + i * N + b] = p[(a, b)];
                }
            }
        }
        Ok(())
    }

    fn residuals_into(&self, ssr: &mut [T], nobs: &mut [T]) -> Result<()> {
        let k = self.rows.flat().len();
        if ssr.len() != k || nobs.len() != k {
            return Err(Error::Shape { arg: "ssr", expected: k, got: ssr.len().min(nobs.len()) });
        }
        for i in 0..k {
            let f = self.filter(i);
            (ssr[i], nobs[i]) = (f.ssr(), f.nobs());
        }
        Ok(())
    }

    fn noise_into(&self, out: &mut [T]) -> Result<()> {
        crate::identify::checks::diagonal_into(out, self.rows.flat().len(), |i| self.filter(i).r())
    }

    fn trace(&self) -> Option<T> {
        Some(KalmanRows::trace(self))
    }

    fn reinit_count(&self) -> u32 {
        self.reinit_count
    }

    fn reset_covariance(&mut self, p0: T) -> Result<()> {
        super::super::guards::check_reset(p0, self.starting())?;
        for g in self.groups.flat_mut() {
            g.reset_covariance(p0);
        }
        Ok(())
    }

    fn gated_into(&self, out: &mut [u64]) -> Result<()> {
        let k = self.rows.flat().len();
        if out.len() != k {
            return Err(Error::Shape { arg: "out", expected: k, got: out.len() });
        }
        for (i, o) in out.iter_mut().enumerate() {
            *o = self.filter(i).gated();
        }
        Ok(())
    }
}
