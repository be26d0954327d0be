//! [`TwoAxleStructured`] behind the [`Identifier`] interface, and its persistence (`Persist`).

use super::*;

crate::identify::persist_by_serde!([T: Real, const P: usize, F: Flat<RowIdentifier<T, P>>, B: RingStore<FrontRegression<T, P>>] TwoAxleStructured<T, P, F, B>);

impl<T: Real, const P: usize, F: Flat<RowIdentifier<T, P>>, B: RingStore<FrontRegression<T, P>>> Identifier<T>
    for TwoAxleStructured<T, P, F, B>
{
    fn dims(&self) -> crate::identify::Dims {
        structure_dims(&self.structure)
    }

    fn rows(&self) -> &[usize] {
        &self.rows[..self.structure.equations()]
    }

    /// The sample on the road point after the previous one ([`TwoAxleStructured::update_at`]
    /// with `grid = None`).
    fn update_into(&mut self, x: &[T], z: &[T], u: &[T], e: &mut [T]) -> Result<()> {
        self.update_at(x, z, u, None, e).map(|_| ())
    }

    /// The structure's parameters, in its order.
    fn params_into(&self, out: &mut [T]) -> Result<()> {
        let np = self.structure.params();
        if out.len() != np {
            return Err(Error::Shape { arg: "out", expected: np, got: out.len() });
        }
        if self.starting() {
            let rank = self.filters.flat().iter().map(|f| f.start_rank()).sum();
            return Err(Error::RankDeficient { rank, needed: np });
        }
        let mut theta = [SVector::<T, P>::zeros(); MAX_PARAMS];
        for (g, t) in theta.iter_mut().enumerate().take(self.part.groups as usize) {
            *t = self.group_estimate(g)?;
        }
        for (j, o) in out.iter_mut().enumerate() {
            *o = theta[self.part.group_of_param[j] as usize][self.part.local[j] as usize];
        }
        Ok(())
    }

    fn samples(&self) -> u64 {
        self.samples
    }

    /// The road point of the sample left out passes: the next sample is on the point after it.
    fn skip_sample(&mut self) {
        self.last_grid = Some(self.last_grid.map_or(0, |g| g.saturating_add(1)));
    }

    /// The recursive least-squares covariance; [`Error::Unsupported`] when the estimate is
    /// bias-compensated (its covariance needs fourth moments of the regressors).
    fn covariance_into(&self, out: &mut [T]) -> Result<()> {
        if self.compensating() {
            return Err(Error::Unsupported {
                what: "a covariance of the bias-compensated estimate (set compensate = false for least squares' P)",
            });
        }
        crate::identify::structured::group_covariance_into(
            &self.part,
            self.structure.params(),
            self.filters.flat(),
            out,
        )
    }

    fn noise_into(&self, out: &mut [T]) -> Result<()> {
        crate::identify::buffers::diagonal_noise_into(&self.r[..self.structure.equations()], out)
    }

    fn groups_into(&self, group_of_param: &mut [usize], group_of_eq: &mut [usize]) -> Result<()> {
        let (np, ne) = (self.structure.params(), self.structure.equations());
        partition_groups_into(&self.part, np, ne, group_of_param, group_of_eq)
    }

    fn trace(&self) -> Option<T> {
        Some(self.filters.flat().iter().fold(T::zero(), |a, f| a + f.trace()))
    }
}
