//! Evaluating a [`Structure`]: its bases, regressors and residuals on a sample, the
//! derivative it gives and its simulation (RK4, the inputs held over a sample).

use super::*;

impl<T: Real> Structure<T> {
    /// The value of a variable.
    #[inline(always)]
    fn var(v: Var, x: &[T], z: &[T], u: &[T]) -> T {
        let at = |s: &[T], i: u8| s.get(i as usize).copied().unwrap_or_else(T::zero);
        match v {
            Var::State(i) => at(x, i),
            Var::Input(j) => at(u, j),
            Var::Deriv(i) => at(z, i),
        }
    }

    /// `φ(x, ż, u)` of a basis function (`z`: the derivatives `der(·)` reads).
    #[inline(always)]
    pub fn basis(&self, b: Basis, x: &[T], z: &[T], u: &[T]) -> T {
        let comb = |start: u8, len: u8| {
            self.comb[start as usize..(start + len) as usize]
                .iter()
                .fold(T::zero(), |a, &(v, c)| a + c * Self::var(v, x, z, u))
        };
        match b {
            Basis::One => T::one(),
            Basis::Var(v) => Self::var(v, x, z, u),
            Basis::Sign { start, len } => {
                let e = comb(start, len);
                if e > T::zero() {
                    T::one()
                } else if e < T::zero() {
                    -T::one()
                } else {
                    T::zero()
                }
            }
            Basis::Pos { start, len } => comb(start, len).max(T::zero()),
            Basis::Neg { start, len } => comb(start, len).min(T::zero()),
        }
    }

    /// The regression of identified equation `i` at one sample (measured state `x`,
    /// derivative `z`, inputs `u`): `y = z_state − Σ known terms` is returned and the regressor
    /// `h` (one value per parameter) written, so that `y = hᵀ p + ε`. No allocation.
    #[inline]
    pub fn regression(&self, i: usize, x: &[T], z: &[T], u: &[T], h: &mut [T]) -> T {
        h.iter_mut().for_each(|v| *v = T::zero());
        let mut y = Self::var(Var::Deriv(self.eqs[i].state), x, z, u);
        for t in self.terms(i) {
            let phi = t.coef * self.basis(t.basis, x, z, u);
            match t.param {
                Some(p) => {
                    if let Some(hp) = h.get_mut(p as usize) {
                        *hp += phi;
                    }
                }
                None => y -= phi,
            }
        }
        y
    }

    /// The residual of identified equation `i` at one sample and parameters `p`:
    /// `z_state − Σ known terms − hᵀ p` (the regression of [`Structure::regression`] at `p`).
    /// No allocation.
    pub fn residual(&self, i: usize, p: &[T], x: &[T], z: &[T], u: &[T]) -> T {
        let mut h = [T::zero(); MAX_PARAMS];
        let np = self.params();
        let y = self.regression(i, x, z, u, &mut h[..np]);
        h[..np].iter().zip(p).fold(y, |acc, (&hj, &pj)| acc - hj * pj)
    }

    /// `ẋ` at `(x, u)` and parameters `p` into `out` (`n` values), every equation evaluated
    /// in dependency order so that `der(·)` terms read the derivatives just computed. States
    /// without an equation get 0 (see [`Structure::complete`]).
    pub fn derivative(&self, p: &[T], x: &[T], u: &[T], out: &mut [T]) {
        out.iter_mut().for_each(|v| *v = T::zero());
        for &i in &self.order[..(self.identified + self.known) as usize] {
            let i = i as usize;
            let mut v = T::zero();
            for t in self.terms(i) {
                let w = match t.param {
                    Some(j) => p.get(j as usize).copied().unwrap_or_else(T::zero),
                    None => T::one(),
                };
                v += t.coef * w * self.basis(t.basis, x, out, u);
            }
            if let Some(o) = out.get_mut(self.eqs[i].state as usize) {
                *o = v;
            }
        }
    }

    /// Free-run simulation with parameters `p` from `x0`: `out` (`samples × n`, row-major)
    /// receives the state at each sample, `out[0] = x0`; the inputs `u` (`samples × m`) are
    /// held over each interval (zero-order hold) and each interval of `dt` seconds is
    /// integrated by `substeps` classical Runge–Kutta (RK4) steps of [`Structure::derivative`].
    /// No allocation.
    ///
    /// # Errors
    /// [`Error::InvalidArgument`] for an incomplete structure (a state without an equation:
    /// add a known equation), `dt ≤ 0` or `substeps = 0`; [`Error::Shape`] for lengths;
    /// [`Error::NonFinite`] naming `params`, `x0` or `u`; [`Error::InvalidArgument`] naming
    /// `params` when the state overflows (the model diverges on these inputs).
    pub fn simulate(&self, p: &[T], x0: &[T], u: &[T], dt: T, substeps: u32, out: &mut [T]) -> Result<()> {
        let (n, m) = (self.states as usize, self.inputs as usize);
        if !self.complete() {
            return Err(Error::InvalidArgument {
                arg: "structure",
                expected: "an equation for every state to simulate (add known equations, e.g. q = v)",
            });
        }
        if !(dt > T::zero()) || !dt.finite() {
            return Err(Error::InvalidArgument { arg: "dt", expected: "a finite sample interval > 0 s" });
        }
        if substeps == 0 {
            return Err(Error::InvalidArgument { arg: "substeps", expected: "at least 1 integration step per sample" });
        }
        if p.len() != self.params() {
            return Err(Error::Shape { arg: "params", expected: self.params(), got: p.len() });
        }
        if x0.len() != n {
            return Err(Error::Shape { arg: "x0", expected: n, got: x0.len() });
        }
        let samples = out.len() / n.max(1);
        if out.len() != samples * n || u.len() != samples * m {
            return Err(Error::Shape { arg: "u", expected: samples * m, got: u.len() });
        }
        for (arg, v) in [("params", p), ("x0", x0), ("u", u)] {
            if let Some(index) = v.iter().position(|a| !a.finite()) {
                return Err(Error::NonFinite { arg, index });
            }
        }
        if samples == 0 {
            return Ok(());
        }
        let h = dt / T::of(f64::from(substeps));
        let half = h / T::of(2.0);
        let mut x = [T::zero(); MAX_STATES];
        x[..n].copy_from_slice(x0);
        let (mut k1, mut k2, mut k3, mut k4, mut tmp) = (
            [T::zero(); MAX_STATES],
            [T::zero(); MAX_STATES],
            [T::zero(); MAX_STATES],
            [T::zero(); MAX_STATES],
            [T::zero(); MAX_STATES],
        );
        for k in 0..samples {
            out[k * n..(k + 1) * n].copy_from_slice(&x[..n]);
            if k + 1 == samples {
                break;
            }
            let uk = &u[k * m..(k + 1) * m];
            for _ in 0..substeps {
                self.derivative(p, &x[..n], uk, &mut k1[..n]);
                for j in 0..n {
                    tmp[j] = x[j] + half * k1[j];
                }
                self.derivative(p, &tmp[..n], uk, &mut k2[..n]);
                for j in 0..n {
                    tmp[j] = x[j] + half * k2[j];
                }
                self.derivative(p, &tmp[..n], uk, &mut k3[..n]);
                for j in 0..n {
                    tmp[j] = x[j] + h * k3[j];
                }
                self.derivative(p, &tmp[..n], uk, &mut k4[..n]);
                for j in 0..n {
                    x[j] += h / T::of(6.0) * (k1[j] + T::of(2.0) * (k2[j] + k3[j]) + k4[j]);
                }
            }
            if x[..n].iter().any(|v| !v.finite()) {
                return Err(Error::InvalidArgument {
                    arg: "params",
                    expected: "a model that stays bounded on these inputs (the simulated state overflowed: the \
                               model diverges; check the estimate's stability and the input's units)",
                });
            }
        }
        Ok(())
    }

    /// The rows of `A` that parameters `p` give: `out` (`equations × states`, row-major, in
    /// the order of the identified equations) receives `∂ẋ_i/∂x_j` of each identified
    /// equation's state `i`, as `derivative(p, e_j, 0) − derivative(p, 0, 0)` (every `der(·)`
    /// term resolved through the equation it reads, so a wheel row that reads the body's
    /// accelerations gets the body rows' entries times its parameters). Exact for a structure
    /// linear in the state (no `sign`/`pos`/`neg` of states; an offset cancels); the inputs
    /// are held at 0 (their columns are `B`'s, not `A`'s). No allocation.
    ///
    /// # Errors
    /// [`Error::Shape`] for `p` not of [`Structure::params`] values or `out` not of
    /// `equations × states`; [`Error::NonFinite`] for NaN/inf in `p`.
    pub fn linear_rows_into(&self, p: &[T], out: &mut [T]) -> Result<()> {
        let (n, ne) = (self.states(), self.equations());
        if p.len() != self.params() {
            return Err(Error::Shape { arg: "params", expected: self.params(), got: p.len() });
        }
        if out.len() != ne * n {
            return Err(Error::Shape { arg: "out", expected: ne * n, got: out.len() });
        }
        crate::error::check_finite("params", p)?;
        let mut x = [T::zero(); MAX_STATES];
        let (mut base, mut d) = ([T::zero(); MAX_STATES], [T::zero(); MAX_STATES]);
        self.derivative(p, &x[..n], &[], &mut base[..n]);
        for j in 0..n {
            x[j] = T::one();
            self.derivative(p, &x[..n], &[], &mut d[..n]);
            x[j] = T::zero();
            for (i, s) in self.equation_states().enumerate() {
                out[i * n + j] = d[s] - base[s];
            }
        }
        Ok(())
    }
}
