//! [`Structured`] behind the [`Identifier`] interface, and its persistence (`Persist`).

use super::*;

crate::identify::persist_by_serde!([T: Real, const P: usize, F: Flat<RowIdentifier<T, P>>] Structured<T, P, F>);

impl<T: Real, const P: usize, F: Flat<RowIdentifier<T, P>>> Identifier<T> for Structured<T, P, F> {
    fn dims(&self) -> Dims {
        crate::identify::buffers::structure_dims(&self.structure)
    }

    fn rows(&self) -> &[usize] {
        &self.rows[..self.structure.equations()]
    }

    fn update_into(&mut self, x: &[T], z: &[T], u: &[T], e: &mut [T]) -> Result<()> {
        check_lengths(self.dims(), x, z, u, e)?;
        if !(all_finite(x) & all_finite(z) & all_finite(u)) {
            check_slices(self.dims(), x, z, u, e)?;
        }
        let ne = self.structure.equations();
        if !self.fast.live() {
            self.fast.try_enter(self.filters.flat(), (&self.eq_ssr[..ne], &self.eq_nobs[..ne]));
        }
        if self.fast.live() {
            if self.fast.step(&self.structure, x, z, u, e) {
                self.samples += 1;
                return Ok(());
            }
            self.leave_lanes();
        }
        self.update_general(x, z, u, e)
    }

    fn params_into(&self, out: &mut [T]) -> Result<()> {
        let np = self.structure.params();
        if out.len() != np {
            return Err(Error::Shape { arg: "out", expected: np, got: out.len() });
        }
        if self.starting() {
            let rank = self.filters.flat().iter().map(|f| f.start_rank()).sum();
            return Err(Error::RankDeficient { rank, needed: np });
        }
        let mut theta = [SVector::<T, P>::zeros(); crate::identify::structured_fast::FAST_GROUPS];
        for (g, t) in theta.iter_mut().enumerate().take(self.part.groups as usize) {
            *t = self.filter(g).theta();
        }
        for (j, o) in out.iter_mut().enumerate() {
            let g = self.part.group_of_param[j] as usize;
            let l = self.part.local[j] as usize;
            *o = match theta.get(g) {
                Some(t) => t[l],
                None => self.filters.flat()[g].theta()[l],
            };
        }
        Ok(())
    }

    fn samples(&self) -> u64 {
        self.samples
    }

    fn residuals_into(&self, ssr: &mut [T], nobs: &mut [T]) -> Result<()> {
        let (mut s, mut n) = (self.eq_ssr, self.eq_nobs);
        self.fast.equations_into(&mut s, &mut n);
        crate::identify::buffers::copy_residuals(self.structure.equations(), &s, &n, ssr, nobs)
    }

    fn groups_into(&self, group_of_param: &mut [usize], group_of_eq: &mut [usize]) -> Result<()> {
        let (np, ne) = (self.structure.params(), self.structure.equations());
        crate::identify::buffers::partition_groups_into(&self.part, np, ne, group_of_param, group_of_eq)
    }

    fn covariance_into(&self, out: &mut [T]) -> Result<()> {
        if !self.fast.live() {
            return group_covariance_into(&self.part, self.structure.params(), self.filters.flat(), out);
        }
        // Live lanes: at most FAST_GROUPS groups.
        let filters = self.filters.flat();
        let mut now = [filters[0]; crate::identify::structured_fast::FAST_GROUPS];
        for (g, f) in now.iter_mut().enumerate().take(filters.len()) {
            *f = self.filter(g);
        }
        group_covariance_into(&self.part, self.structure.params(), &now[..filters.len()], out)
    }

    fn noise_into(&self, out: &mut [T]) -> Result<()> {
        crate::identify::buffers::diagonal_noise_into(&self.r[..self.structure.equations()], out)
    }

    fn trace(&self) -> Option<T> {
        Some((0..self.filters.flat().len()).fold(T::zero(), |a, g| a + self.filter(g).trace()))
    }

    /// Every group's filter restarts at `P = p0 I` ([`RowIdentifier::reset_covariance`]).
    fn reset_covariance(&mut self, p0: T) -> Result<()> {
        let starting = self.filters.flat().iter().any(|f| f.starting());
        crate::identify::kalman::check_reset(p0, starting)?;
        self.leave_lanes();
        for f in self.filters.flat_mut() {
            f.reset_covariance(p0)?;
        }
        Ok(())
    }

    fn gated_into(&self, out: &mut [u64]) -> Result<()> {
        let ne = self.structure.equations();
        if out.len() != ne {
            return Err(Error::Shape { arg: "out", expected: ne, got: out.len() });
        }
        out.copy_from_slice(&self.eq_gated[..ne]);
        Ok(())
    }
}
