//! [`InstrumentalVariables`] behind the [`Identifier`] interface, and its persistence (`Persist`).

use super::*;

crate::identify::persist_by_serde!([T: Real, const P: usize, F: Flat<IvFilter<T, P>>, const Q: usize] InstrumentalVariables<T, P, F, Q>);

impl<T: Real, const P: usize, F: Flat<IvFilter<T, P>>, const Q: usize> Identifier<T>
    for InstrumentalVariables<T, P, F, Q>
{
    fn dims(&self) -> Dims {
        crate::identify::buffers::structure_dims(&self.structure)
    }

    fn rows(&self) -> &[usize] {
        &self.rows[..self.structure.equations()]
    }

    /// One sample (see [`Identifier::update_into`]). For the first `delay` samples there is
    /// no instrument yet: they are stored and their innovations reported, nothing else.
    fn update_into(&mut self, x: &[T], z: &[T], u: &[T], e: &mut [T]) -> Result<()> {
        if self.lags == 0 && self.ring.full() && self.shared_ready() == Some(SharedRegressor::States) {
            if let Some(done) = self.update_states(x, z, u, e) {
                return done;
            }
        }
        self.check_sample(x, z, u, e)?;
        if !self.ring.full() {
            self.innovations(x, z, u, e)?;
            self.ring.push(x, z, u);
            self.samples += 1;
            return Ok(());
        }
        let (n, m) = (self.structure.states(), self.structure.inputs());
        let d = self.delay as usize;
        if self.lags == 0 {
            // The instruments' sample: the one `d` steps back.
            if let Some(kind) = self.shared_ready() {
                let (h, zeta) = self.shared_regressors(kind, x, z, u, split(self.ring.ago(d), n), e)?;
                self.update_shared(&h, &zeta, e)?;
            } else {
                let mut at = [T::zero(); SAMPLE_VALUES];
                at[..2 * n + m].copy_from_slice(self.ring.ago(d));
                self.update_groups(x, z, u, split(&at[..2 * n + m], n), e)?;
            }
        } else {
            self.update_refined(x, z, u, e)?;
        }
        self.ring.push(x, z, u);
        self.samples += 1;
        Ok(())
    }

    fn params_into(&self, out: &mut [T]) -> Result<()> {
        let np = self.structure.params();
        if out.len() != np {
            return Err(Error::Shape { arg: "out", expected: np, got: out.len() });
        }
        if self.starting() {
            let rank = self.filters.flat().iter().filter(|f| !f.starting()).map(|f| f.dim()).sum();
            return Err(Error::RankDeficient { rank, needed: np });
        }
        for (j, o) in out.iter_mut().enumerate() {
            let g = self.part.group_of_param[j] as usize;
            *o = self.filters.flat()[g].theta()[self.part.local[j] as usize];
        }
        Ok(())
    }

    fn samples(&self) -> u64 {
        self.samples
    }

    /// The sandwich covariance `P M Pᵀ / r_g` per group (see [`IvFilter::covariance`]): times
    /// the residual scale `σ²/r` (what [`crate::identify::estimate_stats`] multiplies by) it is the
    /// asymptotic covariance of the IV estimate, `σ² (Σζhᵀ)⁻¹ (Σζζᵀ) (Σhζᵀ)⁻¹` (Söderström &
    /// Stoica Eq 8.26, white equation errors).
    fn covariance_into(&self, out: &mut [T]) -> Result<()> {
        let np = self.structure.params();
        if out.len() != np * np {
            return Err(Error::Shape { arg: "out", expected: np * np, got: out.len() });
        }
        if self.starting() {
            let rank = self.filters.flat().iter().filter(|f| !f.starting()).map(|f| f.dim()).sum();
            return Err(Error::RankDeficient { rank, needed: np });
        }
        out.fill(T::zero());
        for (g, f) in self.filters.flat().iter().enumerate() {
            let cov = f.covariance();
            let members = (0..np).filter(|&j| self.part.group_of_param[j] as usize == g);
            for a in members.clone() {
                for b in members.clone() {
                    out[a * np + b] = cov[(self.part.local[a] as usize, self.part.local[b] as usize)];
                }
            }
        }
        Ok(())
    }

    fn noise_into(&self, out: &mut [T]) -> Result<()> {
        crate::identify::buffers::diagonal_noise_into(&self.r[..self.structure.equations()], out)
    }

    /// Each equation's sum of squared a-posteriori residuals `y − hᵀθ̂(k)` (own units) over the
    /// samples filtered after the start, and their number.
    fn residuals_into(&self, ssr: &mut [T], nobs: &mut [T]) -> Result<()> {
        crate::identify::buffers::copy_residuals(self.structure.equations(), &self.eq_ssr, &self.eq_nobs, ssr, nobs)
    }

    fn groups_into(&self, group_of_param: &mut [usize], group_of_eq: &mut [usize]) -> Result<()> {
        let (np, ne) = (self.structure.params(), self.structure.equations());
        crate::identify::buffers::partition_groups_into(&self.part, np, ne, group_of_param, group_of_eq)
    }
}
