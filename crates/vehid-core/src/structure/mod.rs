//! Models linear in their parameters ("grey box"): which states' derivatives are identified,
//! from which terms of the state and the measured inputs, with which parameters.
//!
//! Each identified equation reads
//! `ẋ_i = Σ_k c_k p_{j(k)} φ_k(x, u) + Σ_m c_m φ_m(x, u)`: parameter terms (a coefficient
//! `c`, a parameter `p_j`, a basis function `φ`) and known terms (no parameter). A basis
//! function is 1 (an offset), a state or a measured input, or `sign`, `pos` or `neg` of a linear
//! combination of states and inputs (Coulomb friction `sign(v)`, an asymmetric damper
//! `pos(v2 − v4)` / `neg(v2 − v4)`; `pos(e) = max(e, 0)`, `neg(e) = min(e, 0)`,
//! `sign(0) = 0`). A parameter may appear in several equations. With the measured derivative
//! `z_i`, equation `i` is the scalar regression `y_i = z_i − known_i(x, u) = h_i(x, u)ᵀ p + ε_i`
//! (Eq 2.2–2.4 generalized: for the full unknown rows of `A`, `h_i = x` on row `i`'s block).
//!
//! [`Structure`] is plain data of fixed capacity (no allocation; `no_std`); `parse.rs` (std)
//! reads the text form (`"a*tau - b*v - c*sign(v) - d"`). Known equations (parameter-free,
//! e.g. `q̇ = v`) are kept for simulation.

#[cfg(feature = "std")]
mod parse;

#[cfg(feature = "std")]
pub use parse::{Names, StructureBuilder, StructureError, MAX_DEPTH, MAX_TEXT_BYTES};

use crate::{Error, Real, Result};

/// Most states a structure may have.
pub const MAX_STATES: usize = 16;
/// Most measured inputs.
pub const MAX_INPUTS: usize = 8;
/// Most parameters.
pub const MAX_PARAMS: usize = 32;
/// Most equations (identified and known together).
pub const MAX_EQUATIONS: usize = 16;
/// Most terms over all equations.
pub const MAX_TERMS: usize = 96;
/// Most (variable, coefficient) pairs over all the linear combinations inside `sign`, `pos`,
/// `neg`.
pub const MAX_COMBINATION: usize = 64;

/// A state, a measured input, or the measured derivative of a state.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub enum Var {
    /// State `i` (0-based).
    State(u8),
    /// Measured input `j` (0-based).
    Input(u8),
    /// The derivative of state `i` (`der(v)` in the text form): the measured `z_i` when
    /// identifying, the simulated `ẋ_i` when simulating. It lets an equation use another
    /// state's acceleration, e.g. a momentum balance `m v̇_w = −M v̇_b − k1 q_w` in which a
    /// second body's force is read from its measured acceleration. Its measurement noise
    /// enters the regressor (errors in variables): use it where that noise is small against
    /// the equation's own.
    Deriv(u8),
}

/// The basis function of a term.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub enum Basis {
    /// 1: an offset.
    One,
    /// A state or input.
    Var(Var),
    /// `sign(e)` of the linear combination stored at `start..start + len` (`sign(0) = 0`).
    Sign {
        /// First entry of the combination.
        start: u8,
        /// Entries.
        len: u8,
    },
    /// `pos(e) = max(e, 0)`.
    Pos {
        /// First entry of the combination.
        start: u8,
        /// Entries.
        len: u8,
    },
    /// `neg(e) = min(e, 0)`.
    Neg {
        /// First entry of the combination.
        start: u8,
        /// Entries.
        len: u8,
    },
}

/// One term: `coef × p_param × φ`, or `coef × φ` when `param` is `None` (a known term).
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct Term<T> {
    /// The numeric coefficient.
    pub coef: T,
    /// The parameter (0-based), `None` for a known term.
    pub param: Option<u8>,
    /// The basis function.
    pub basis: Basis,
}

/// An equation: the derivative of `state` as the terms `start..start + len`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
struct Eq {
    state: u8,
    start: u8,
    len: u8,
}

/// A model linear in its parameters, as fixed-capacity data (see the module docs).
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(
    feature = "serde",
    derive(serde::Serialize, serde::Deserialize),
    serde(remote = "Self", bound(serialize = "T: serde::Serialize", deserialize = "T: crate::Real"))
)]
pub struct Structure<T> {
    states: u8,
    inputs: u8,
    params: u8,
    /// Identified equations first (`identified` of them), then the known ones.
    eqs: [Eq; MAX_EQUATIONS],
    identified: u8,
    known: u8,
    /// The equations in an order in which every `der(·)` a term reads is computed before it
    /// (for simulation).
    order: [u8; MAX_EQUATIONS],
    #[cfg_attr(feature = "serde", serde(with = "crate::persist::array"))]
    terms: [Term<T>; MAX_TERMS],
    n_terms: u8,
    #[cfg_attr(feature = "serde", serde(with = "crate::persist::array"))]
    comb: [(Var, T); MAX_COMBINATION],
    n_comb: u8,
}

const INVALID: Error = Error::InvalidArgument {
    arg: "structure",
    expected: "equations within the structure's capacity (16 states, 8 inputs, 32 parameters, 16 equations, \
               96 terms, 64 entries in sign/pos/neg combinations)",
};

impl Default for Var {
    /// State 0 (the filler of unused slots).
    fn default() -> Self {
        Var::State(0)
    }
}

impl Default for Basis {
    /// 1 (the filler of unused slots).
    fn default() -> Self {
        Basis::One
    }
}

impl<T: Real> Default for Term<T> {
    /// `0 × 1`, a known term (the filler of unused slots).
    fn default() -> Self {
        Term { coef: T::zero(), param: None, basis: Basis::One }
    }
}

impl<T: Real> Structure<T> {
    /// Checks a deserialized structure (feature `serde`): it is rebuilt from its parts through
    /// [`Structure::new`], [`Structure::push_combination`] and [`Structure::push_equation`],
    /// with every check they make, and must come out equal, so that a corrupt input is an
    /// error, never a panic later.
    #[cfg(feature = "serde")]
    pub(crate) fn restored(&mut self) -> Result<()> {
        let n_eq = self.identified as usize + self.known as usize;
        let (nt, nc) = (self.n_terms as usize, self.n_comb as usize);
        if n_eq > MAX_EQUATIONS || nt > MAX_TERMS || nc > MAX_COMBINATION {
            return Err(INVALID);
        }
        let mut rebuilt = Self::new(self.states as usize, self.inputs as usize, self.params as usize)?;
        if nc > 0 {
            rebuilt.push_combination(&self.comb[..nc])?;
        }
        for e in &self.eqs[..n_eq] {
            let (s, l) = (e.start as usize, e.len as usize);
            if s + l > nt {
                return Err(INVALID);
            }
            rebuilt.push_equation(e.state as usize, &self.terms[s..s + l])?;
        }
        if rebuilt != *self {
            return Err(INVALID);
        }
        Ok(())
    }

    /// An empty structure with `states` states, `inputs` measured inputs and `params`
    /// parameters (equations are added with [`Structure::push_equation`]).
    ///
    /// # Errors
    /// [`Error::InvalidArgument`] beyond the capacities ([`MAX_STATES`], …) or for no state.
    pub fn new(states: usize, inputs: usize, params: usize) -> Result<Self> {
        if states == 0 || states > MAX_STATES || inputs > MAX_INPUTS || params > MAX_PARAMS {
            return Err(INVALID);
        }
        let eq = Eq { state: 0, start: 0, len: 0 };
        let term = Term { coef: T::zero(), param: None, basis: Basis::One };
        Ok(Self {
            states: states as u8,
            inputs: inputs as u8,
            params: params as u8,
            eqs: [eq; MAX_EQUATIONS],
            identified: 0,
            known: 0,
            order: [0; MAX_EQUATIONS],
            terms: [term; MAX_TERMS],
            n_terms: 0,
            comb: [(Var::State(0), T::zero()); MAX_COMBINATION],
            n_comb: 0,
        })
    }

    /// The full-row structure of a linear model (the thesis' setting): for each unknown row
    /// `i` (0-based, in order), `ẋ_i = Σ_j p_{i n + j} x_j` with every entry a parameter, named
    /// row-major as the identifiers' `θ`. `n` states, no measured input.
    ///
    /// # Errors
    /// [`Error::InvalidArgument`] for rows out of range or repeated, or beyond the capacities.
    pub fn full_rows(n: usize, rows: &[usize]) -> Result<Self> {
        let mut s = Self::new(n, 0, rows.len() * n)?;
        let mut terms = [Term { coef: T::one(), param: None, basis: Basis::One }; MAX_STATES];
        for (i, &row) in rows.iter().enumerate() {
            for (j, t) in terms.iter_mut().enumerate().take(n) {
                *t = Term { coef: T::one(), param: Some((i * n + j) as u8), basis: Basis::Var(Var::State(j as u8)) };
            }
            s.push_equation(row, &terms[..n])?;
        }
        Ok(s)
    }

    /// Stores a linear combination for a `sign`/`pos`/`neg` basis; returns `(start, len)`.
    ///
    /// # Errors
    /// [`Error::InvalidArgument`] beyond [`MAX_COMBINATION`], or for a variable out of range.
    pub fn push_combination(&mut self, entries: &[(Var, T)]) -> Result<(u8, u8)> {
        let start = self.n_comb as usize;
        if start + entries.len() > MAX_COMBINATION || entries.is_empty() {
            return Err(INVALID);
        }
        for &(v, c) in entries {
            self.check_var(v)?;
            crate::error::check_finite("structure", &[c])?;
        }
        self.comb[start..start + entries.len()].copy_from_slice(entries);
        self.n_comb += entries.len() as u8;
        Ok((start as u8, entries.len() as u8))
    }

    fn check_var(&self, v: Var) -> Result<()> {
        let ok = match v {
            Var::State(i) | Var::Deriv(i) => i < self.states,
            Var::Input(j) => j < self.inputs,
        };
        if ok {
            Ok(())
        } else {
            Err(Error::InvalidArgument {
                arg: "structure",
                expected: "variables among the structure's states and inputs",
            })
        }
    }

    /// The derivatives (`der(·)`) a basis function reads, as a bit set over the states.
    fn derivs_of(&self, b: Basis) -> u32 {
        let bit = |v: Var| match v {
            Var::Deriv(i) => 1u32 << i,
            _ => 0,
        };
        match b {
            Basis::One => 0,
            Basis::Var(v) => bit(v),
            Basis::Sign { start, len } | Basis::Pos { start, len } | Basis::Neg { start, len } => {
                self.comb[start as usize..(start + len) as usize].iter().fold(0, |a, &(v, _)| a | bit(v))
            }
        }
    }

    /// Adds an equation for the derivative of `state`: identified when a term has a
    /// parameter, known (used in simulation only) when none has. Identified equations must
    /// come before known ones.
    ///
    /// # Errors
    /// [`Error::InvalidArgument`] for a state or parameter out of range, a second equation
    /// for the same state, an identified equation after a known one, an equation that reads
    /// its own derivative, derivatives that read each other in a loop, capacities exceeded.
    pub fn push_equation(&mut self, state: usize, terms: &[Term<T>]) -> Result<()> {
        if state >= self.states as usize {
            return Err(INVALID);
        }
        let n_eq = (self.identified + self.known) as usize;
        if n_eq >= MAX_EQUATIONS || self.n_terms as usize + terms.len() > MAX_TERMS {
            return Err(INVALID);
        }
        if self.eqs[..n_eq].iter().any(|e| e.state as usize == state) {
            return Err(Error::InvalidArgument {
                arg: "equations",
                expected: "one equation per state (this state's derivative is given twice)",
            });
        }
        for t in terms {
            crate::error::check_finite("structure", &[t.coef])?;
            if let Some(p) = t.param {
                if p >= self.params {
                    return Err(INVALID);
                }
            }
            match t.basis {
                Basis::One => {}
                Basis::Var(v) => self.check_var(v)?,
                Basis::Sign { start, len } | Basis::Pos { start, len } | Basis::Neg { start, len } => {
                    if start as usize + len as usize > self.n_comb as usize || len == 0 {
                        return Err(INVALID);
                    }
                }
            }
            if self.derivs_of(t.basis) & (1 << state) != 0 {
                return Err(Error::InvalidArgument {
                    arg: "equations",
                    expected: "an equation that does not read its own state's derivative (move der(x) to the left: \
                               divide the equation by its coefficient)",
                });
            }
        }
        let identified = terms.iter().any(|t| t.param.is_some());
        if identified && self.known > 0 {
            return Err(Error::InvalidArgument {
                arg: "equations",
                expected: "the identified equations before the known ones",
            });
        }
        let mut next = *self;
        let start = next.n_terms as usize;
        next.terms[start..start + terms.len()].copy_from_slice(terms);
        next.n_terms += terms.len() as u8;
        next.eqs[n_eq] = Eq { state: state as u8, start: start as u8, len: terms.len() as u8 };
        if identified {
            next.identified += 1;
        } else {
            next.known += 1;
        }
        next.sort_equations()?;
        *self = next;
        Ok(())
    }

    /// The derivatives equation `i` reads (bit set over states).
    fn reads(&self, i: usize) -> u32 {
        self.terms(i).iter().fold(0, |a, t| a | self.derivs_of(t.basis))
    }

    /// Orders the equations so that every derivative an equation reads is computed first
    /// (Kahn's algorithm over at most 16 equations).
    fn sort_equations(&mut self) -> Result<()> {
        let n_eq = (self.identified + self.known) as usize;
        let mut done = 0u32; // states whose derivative is computed
        let mut with_eq = 0u32;
        for e in &self.eqs[..n_eq] {
            with_eq |= 1 << e.state;
        }
        let mut placed = [false; MAX_EQUATIONS];
        for slot in 0..n_eq {
            // Derivatives of states without an equation are 0 in simulation: not waited for.
            let next = (0..n_eq).find(|&i| !placed[i] && self.reads(i) & with_eq & !done == 0);
            let Some(i) = next else {
                return Err(Error::InvalidArgument {
                    arg: "equations",
                    expected: "derivatives that do not depend on each other in a loop (an algebraic loop through \
                               der(·) terms)",
                });
            };
            placed[i] = true;
            self.order[slot] = i as u8;
            done |= 1 << self.eqs[i].state;
        }
        Ok(())
    }

    /// States `n`.
    pub fn states(&self) -> usize {
        self.states as usize
    }

    /// Measured inputs `m`.
    pub fn inputs(&self) -> usize {
        self.inputs as usize
    }

    /// Parameters.
    pub fn params(&self) -> usize {
        self.params as usize
    }

    /// Identified equations.
    pub fn equations(&self) -> usize {
        self.identified as usize
    }

    /// Known (parameter-free) equations.
    pub fn known_equations(&self) -> usize {
        self.known as usize
    }

    /// The state whose derivative equation `i` gives (identified equations first, then known).
    pub fn equation_state(&self, i: usize) -> usize {
        self.eqs[i].state as usize
    }

    /// The states of the identified equations, in order.
    pub fn equation_states(&self) -> impl Iterator<Item = usize> + '_ {
        self.eqs[..self.identified as usize].iter().map(|e| e.state as usize)
    }

    /// The terms of equation `i` (identified equations first, then known).
    pub fn terms(&self, i: usize) -> &[Term<T>] {
        let e = self.eqs[i];
        &self.terms[e.start as usize..(e.start + e.len) as usize]
    }

    /// The entries `(variable, coefficient)` of a `sign`/`pos`/`neg` combination.
    pub fn combination(&self, start: u8, len: u8) -> &[(Var, T)] {
        &self.comb[start as usize..(start + len) as usize]
    }

    /// `true` when some term reads a derivative (`der(·)`).
    pub fn reads_derivatives(&self) -> bool {
        (0..(self.identified + self.known) as usize).any(|i| self.reads(i) != 0)
    }

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

    /// `true` when every state has an equation (identified or known): the structure can then
    /// be simulated.
    pub fn complete(&self) -> bool {
        let eqs = &self.eqs[..(self.identified + self.known) as usize];
        (0..self.states as usize).all(|s| eqs.iter().any(|e| e.state as usize == s))
    }

    /// The first parameter that appears in no identified equation.
    pub fn unused_param(&self) -> Option<usize> {
        (0..self.params as usize)
            .find(|&j| !(0..self.identified as usize).any(|i| self.terms(i).iter().any(|t| t.param == Some(j as u8))))
    }

    /// The first pair of parameters that multiply the same terms in every equation (then only
    /// a combination of them could be identified, never each).
    pub fn confounded_pair(&self) -> Option<(usize, usize)> {
        let np = self.params as usize;
        (0..np).flat_map(|a| ((a + 1)..np).map(move |b| (a, b))).find(|&(a, b)| self.confounded(a as u8, b as u8))
    }

    /// Checks that every parameter appears in some identified equation and that no two
    /// parameters are confounded ([`Structure::confounded_pair`]). The data can still fail to
    /// identify a structure (a term that never varies); the identifiers report that as a rank
    /// deficiency.
    ///
    /// # Errors
    /// [`Error::NotIdentifiable`] naming the problem.
    pub fn check_identifiable(&self) -> Result<()> {
        if self.identified == 0 {
            return Err(Error::NotIdentifiable { what: "anything: the structure has no equation with a parameter" });
        }
        if self.unused_param().is_some() {
            return Err(Error::NotIdentifiable { what: "a parameter that appears in no identified equation" });
        }
        if self.confounded_pair().is_some() {
            return Err(Error::NotIdentifiable {
                what: "two parameters that multiply the same terms (only their combination is identifiable)",
            });
        }
        Ok(())
    }

    /// `true` when parameters `a` and `b` appear with the same basis functions, in the same
    /// equations, with coefficients in one fixed ratio.
    fn confounded(&self, a: u8, b: u8) -> bool {
        let mut ratio: Option<T> = None;
        for i in 0..self.identified as usize {
            let ta: heapless_terms::Terms<T> = heapless_terms::collect(self.terms(i), a);
            let tb: heapless_terms::Terms<T> = heapless_terms::collect(self.terms(i), b);
            if ta.len != tb.len {
                return false;
            }
            for k in 0..ta.len {
                let (ba, ca) = ta.items[k];
                let Some(&(_, cb)) = tb.items[..tb.len].iter().find(|(bb, _)| *bb == ba) else { return false };
                let r = ca / cb;
                match ratio {
                    None => ratio = Some(r),
                    Some(q) if (q - r).abs() <= T::default_epsilon() * T::of(16.0) * q.abs() => {}
                    Some(_) => return false,
                }
            }
        }
        ratio.is_some()
    }

    /// The parameters split into independent groups: two parameters are in one group when an
    /// identified equation contains both (transitively). Each group is its own least-squares
    /// problem; the identifiers run one filter per group.
    pub fn partition(&self) -> Partition {
        let np = self.params as usize;
        let mut root = [0u8; MAX_PARAMS];
        for (j, r) in root.iter_mut().enumerate() {
            *r = j as u8;
        }
        fn find(root: &mut [u8; MAX_PARAMS], mut j: u8) -> u8 {
            while root[j as usize] != j {
                root[j as usize] = root[root[j as usize] as usize];
                j = root[j as usize];
            }
            j
        }
        for i in 0..self.identified as usize {
            let mut first: Option<u8> = None;
            for t in self.terms(i) {
                if let Some(p) = t.param {
                    match first {
                        None => first = Some(p),
                        Some(f) => {
                            let (ra, rb) = (find(&mut root, f), find(&mut root, p));
                            if ra != rb {
                                root[ra.max(rb) as usize] = ra.min(rb);
                            }
                        }
                    }
                }
            }
        }
        let mut part = Partition {
            groups: 0,
            group_of_param: [0; MAX_PARAMS],
            local: [0; MAX_PARAMS],
            size: [0; MAX_PARAMS],
            group_of_eq: [0; MAX_EQUATIONS],
        };
        let mut group_of_root = [u8::MAX; MAX_PARAMS];
        for j in 0..np {
            let r = find(&mut root, j as u8) as usize;
            if group_of_root[r] == u8::MAX {
                group_of_root[r] = part.groups;
                part.groups += 1;
            }
            let g = group_of_root[r];
            part.group_of_param[j] = g;
            part.local[j] = part.size[g as usize];
            part.size[g as usize] += 1;
        }
        for i in 0..self.identified as usize {
            let p = self.terms(i).iter().find_map(|t| t.param).unwrap_or(0);
            part.group_of_eq[i] = part.group_of_param[p as usize];
        }
        part
    }
}

/// The parameters of a [`Structure`] in independent groups ([`Structure::partition`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct Partition {
    /// Number of groups.
    pub groups: u8,
    /// The group of each parameter.
    pub group_of_param: [u8; MAX_PARAMS],
    /// Each parameter's index within its group.
    pub local: [u8; MAX_PARAMS],
    /// Parameters per group.
    pub size: [u8; MAX_PARAMS],
    /// The group of each identified equation.
    pub group_of_eq: [u8; MAX_EQUATIONS],
}

impl Partition {
    /// Parameters in the largest group (the `P` an identifier needs).
    pub fn largest(&self) -> usize {
        self.size[..self.groups as usize].iter().copied().max().unwrap_or(0) as usize
    }
}

/// A small fixed-capacity list of `(basis, coefficient)` pairs of one parameter in one
/// equation (no allocation).
mod heapless_terms {
    use super::{Basis, Term, MAX_TERMS};
    use crate::Real;

    pub(super) struct Terms<T> {
        pub(super) items: [(Basis, T); MAX_TERMS],
        pub(super) len: usize,
    }

    /// The terms of parameter `p` in `terms`, coefficients of equal bases summed.
    pub(super) fn collect<T: Real>(terms: &[Term<T>], p: u8) -> Terms<T> {
        let mut out = Terms { items: [(Basis::One, T::zero()); MAX_TERMS], len: 0 };
        for t in terms.iter().filter(|t| t.param == Some(p)) {
            match out.items[..out.len].iter_mut().find(|(b, _)| *b == t.basis) {
                Some(item) => item.1 += t.coef,
                None => {
                    out.items[out.len] = (t.basis, t.coef);
                    out.len += 1;
                }
            }
        }
        out
    }
}
