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
//! [`Structure`] is plain data of fixed capacity (no allocation; `no_std`); `eval.rs` evaluates
//! it (bases, regressors, derivative, simulation), `identifiability.rs` checks its parameters
//! and groups them ([`Partition`]); `parse.rs` (std) reads the text form (its grammar in
//! `parse/grammar.rs`) (`"a*tau - b*v - c*sign(v) - d"`). Known equations (parameter-free,
//! e.g. `q̇ = v`) are kept for simulation.

#[cfg(feature = "std")]
mod parse;

#[cfg(feature = "std")]
pub use parse::{Names, StructureBuilder, StructureError, MAX_DEPTH, MAX_TEXT_BYTES};

use crate::{Error, Real, Result};

mod eval;
mod identifiability;

pub use identifiability::Partition;

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
}
