//! [`JointEkf`] behind the [`Identifier`] interface, and its persistence (`Persist`).

use super::*;

crate::identify::persist_by_serde!([T: Real, const N: usize, const D: usize] JointEkf<T, N, D>);

impl<T: Real, const N: usize, const D: usize> Identifier<T> for JointEkf<T, N, D> {
    fn dims(&self) -> Dims {
        crate::identify::buffers::structure_dims(&self.structure)
    }

    fn rows(&self) -> &[usize] {
        &self.rows[..self.structure.equations()]
    }

    /// One sample: the update with `r_k` (`x`) and `z_k`, then the prediction to `k + 1`
    /// (module docs). `e`: each identified equation's `z_i − f_i(x̂, p̂)` at the prior.
    ///
    /// # Errors
    /// [`Error::Shape`], [`Error::NonFinite`] naming `r_k`, `z_k` or `u_k`;
    /// [`Error::Singular`] when the covariance lost definiteness; an overflow error. The
    /// filter is unchanged after any error.
    fn update_into(&mut self, x: &[T], z: &[T], u: &[T], e: &mut [T]) -> Result<()> {
        check_slices(self.dims(), x, z, u, e)?;
        let (s, p, innov) = self.step(x, z, u)?;
        self.s = s;
        self.p = p;
        e.copy_from_slice(&innov[..e.len()]);
        self.samples += 1;
        Ok(())
    }

    fn params_into(&self, out: &mut [T]) -> Result<()> {
        let np = self.structure.params();
        if out.len() != np {
            return Err(Error::Shape { arg: "out", expected: np, got: out.len() });
        }
        out.copy_from_slice(&self.s.as_slice()[N..N + np]);
        Ok(())
    }

    fn samples(&self) -> u64 {
        self.samples
    }

    /// The parameters' block of `P` (posterior given the samples so far, under the filter's
    /// linearization and noise model).
    fn covariance_into(&self, out: &mut [T]) -> Result<()> {
        let np = self.structure.params();
        if out.len() != np * np {
            return Err(Error::Shape { arg: "out", expected: np * np, got: out.len() });
        }
        for a in 0..np {
            for b in 0..np {
                out[a * np + b] = self.p[(N + a, N + b)];
            }
        }
        Ok(())
    }

    /// The identified equations' noise covariance: `Σ_v,ii δ_ij + g_i g_j σ_u²` (their
    /// measured derivatives' noise, road included).
    fn noise_into(&self, out: &mut [T]) -> Result<()> {
        let ne = self.structure.equations();
        if out.len() != ne * ne {
            return Err(Error::Shape { arg: "out", expected: ne * ne, got: out.len() });
        }
        let g = &self.noise.road_gain;
        for (a, &ra) in self.rows[..ne].iter().enumerate() {
            for (b, &rb) in self.rows[..ne].iter().enumerate() {
                let v = if a == b { self.noise.deriv_var[ra] } else { T::zero() };
                out[a * ne + b] = v + g[ra] * g[rb] * self.noise.road_var;
            }
        }
        Ok(())
    }

    /// One group: the filter couples every parameter and equation.
    fn groups_into(&self, group_of_param: &mut [usize], group_of_eq: &mut [usize]) -> Result<()> {
        let d = self.dims();
        if group_of_param.len() != d.params {
            return Err(Error::Shape { arg: "group_of_param", expected: d.params, got: group_of_param.len() });
        }
        if group_of_eq.len() != d.equations {
            return Err(Error::Shape { arg: "group_of_eq", expected: d.equations, got: group_of_eq.len() });
        }
        group_of_param.fill(0);
        group_of_eq.fill(0);
        Ok(())
    }

    /// `tr P` of the parameters' block.
    fn trace(&self) -> Option<T> {
        Some((N..D - 1).fold(T::zero(), |a, i| a + self.p[(i, i)]))
    }

    /// `P_pp ← p0 I` and the state–parameter covariance to 0 (the state's own block is kept).
    fn reset_covariance(&mut self, p0: T) -> Result<()> {
        check_positive("p0", p0)?;
        for a in N..D - 1 {
            for b in 0..D - 1 {
                let v = if a == b { p0 } else { T::zero() };
                self.p[(a, b)] = v;
                self.p[(b, a)] = v;
            }
        }
        Ok(())
    }
}
