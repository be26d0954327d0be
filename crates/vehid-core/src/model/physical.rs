//! A vehicle's physical structure: its equations as a [`Structure`] whose parameters are
//! ratios of physical constants (or the constants themselves), and the map back to the
//! constants with intervals.
//!
//! Mechanics fixes most entries of `A`: the quarter car's body row is
//! `[k2/M, b/M, −k2/M, −b/M]`, two numbers, not four. A vehicle is described here by its
//! constants (`M`, `m`, `k1`, …) and by equations whose coefficients are products of
//! numbers (lever arms, known masses) and *edges*: ratios `a/b` of two constants. Given the
//! constants the user knows, every edge becomes
//! - a number, when both constants are known;
//! - the parameter `a` (times `1/b`), when only `b` is known: e.g. `M/m` with `m` known is the
//!   parameter `M`. Edges that reduce to the same constant share one parameter, which couples
//!   the equations that hold them;
//! - the parameter `a/b`, otherwise.
//!
//! Each unknown constant is then a monomial `c = f Π θ_j^{e_j}` of the parameters, found by
//! walking the edges from a known constant (equations are homogeneous in the constants, so
//! one known constant — a mass — fixes the scale; without one only ratios are identifiable).
//! Its interval is first order (the delta method): `se² = gᵀ Σ g`, `g_j = c e_j / θ_j`. It is
//! exact when the constant is one parameter times a known number (then `c` is linear in
//! `θ`); otherwise first order in the parameters' relative errors.

use crate::structure::{Basis, Structure, Term, Var, MAX_PARAMS};
use crate::{Error, Real, Result};

/// Most constants of a vehicle.
pub const MAX_CONSTANTS: usize = 12;
/// Most edges (ratio slots) of a vehicle's equations.
pub(crate) const MAX_EDGES: usize = 16;

/// The edge index of a template term whose parameter is a free offset (named `"offset"`, in
/// the unit of its equation): a sensor's bias or zero error, not a ratio of constants. It
/// determines no constant, and its true value for a vehicle ([`PhysicalStructure::params_of`])
/// is 0 (unbiased sensors).
pub(crate) const OFFSET: u8 = u8::MAX;

/// One term of a vehicle's equation template: `coef × edge × basis`, or `coef × basis`
/// when `edge` is `None`.
#[derive(Debug, Clone, Copy)]
pub(crate) struct TemplateTerm<T> {
    pub coef: T,
    pub edge: Option<u8>,
    pub basis: Basis,
}

/// How an edge entered the structure.
#[derive(Debug, Clone, Copy, PartialEq)]
enum EdgeValue<T> {
    /// Both constants known: the number `a/b`.
    Fixed(T),
    /// Parameter `j`, times the number `mult` (`1/b` when it stands for `a` itself).
    Param { j: u8, mult: T },
}

/// A vehicle's physical structure with some constants known (see the module docs).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PhysicalStructure<T> {
    structure: Structure<T>,
    names: [&'static str; MAX_PARAMS],
    param_edges: [(u8, Option<u8>); MAX_PARAMS],
    constants: [&'static str; MAX_CONSTANTS],
    n_constants: u8,
    known: [Option<T>; MAX_CONSTANTS],
    /// Each constant as `factor × Π θ_j^{exp_j}` (`None`: not determined).
    mono: [Option<(T, [i8; MAX_PARAMS])>; MAX_CONSTANTS],
    /// Whether each constant appears in an identified equation.
    appears: [bool; MAX_CONSTANTS],
    /// What a constant in no equation needs (see [`PhysicalStructure::needs`]).
    absent: &'static str,
}

/// Builds a [`PhysicalStructure`] from a vehicle description.
pub(crate) struct Builder<'a, T> {
    pub states: usize,
    pub constants: &'a [&'static str],
    /// The constants' names joined pairwise: `ratio_names[e]` is the name of edge `e` as a
    /// parameter (`"k2/M"`).
    pub edges: &'a [(u8, u8, &'static str)],
    pub known: &'a [Option<T>],
    /// What a constant that appears in no equation would need to be determined (a sensor
    /// these equations do not read), for [`PhysicalStructure::needs`].
    pub absent: &'static str,
}

impl<T: Real> Builder<'_, T> {
    /// The structure of `equations` (`(state, terms)`, identified ones) and `known_eqs`
    /// (parameter-free, for simulation).
    pub fn build(
        &self,
        equations: &[(usize, &[TemplateTerm<T>])],
        known_eqs: &[(usize, &[TemplateTerm<T>])],
    ) -> Result<PhysicalStructure<T>> {
        let nc = self.constants.len();
        for (c, v) in self.known.iter().enumerate() {
            if let Some(v) = v {
                crate::error::check_positive(self.constants[c], *v)?;
            }
        }
        // Parameters of the edges that appear.
        let mut used = [false; MAX_EDGES];
        for (_, terms) in equations {
            for t in terms.iter() {
                if let Some(e) = t.edge.filter(|&e| e != OFFSET) {
                    used[e as usize] = true;
                }
            }
        }
        let mut appears = [false; MAX_CONSTANTS];
        for (e, &(a, b, _)) in self.edges.iter().enumerate() {
            if used[e] {
                (appears[a as usize], appears[b as usize]) = (true, true);
            }
        }
        let mut names = [""; MAX_PARAMS];
        let mut param_edges = [(0u8, None); MAX_PARAMS];
        let mut np = 0usize;
        let mut value = [EdgeValue::Fixed(T::zero()); MAX_EDGES];
        for (e, &(a, b, ratio)) in self.edges.iter().enumerate() {
            if !used[e] {
                continue;
            }
            let (ka, kb) = (self.known[a as usize], self.known[b as usize]);
            // Key: (a, Some(b)) for the ratio, (a, None) for the constant a itself.
            let (key, name, mult) = match (ka, kb) {
                (Some(va), Some(vb)) => {
                    value[e] = EdgeValue::Fixed(va / vb);
                    continue;
                }
                (None, Some(vb)) => ((a, None), self.constants[a as usize], T::one() / vb),
                _ => ((a, Some(b)), ratio, T::one()),
            };
            let j = match param_edges[..np].iter().position(|k| *k == key) {
                Some(j) => j,
                None => {
                    param_edges[np] = key;
                    names[np] = name;
                    np += 1;
                    np - 1
                }
            };
            value[e] = EdgeValue::Param { j: j as u8, mult };
        }
        let offset = equations.iter().any(|(_, terms)| terms.iter().any(|t| t.edge == Some(OFFSET)));
        let offset_j = np as u8;
        if offset {
            param_edges[np] = (OFFSET, None);
            names[np] = "offset";
            np += 1;
        }
        let mut s = Structure::new(self.states, 0, np)?;
        // Every equation's terms with the edges resolved; equations left without a parameter
        // (every edge known) join the known ones, after the identified.
        let mut eqs = [(0usize, [Term { coef: T::zero(), param: None, basis: Basis::One }; 32], 0usize); 16];
        let all = equations.iter().chain(known_eqs);
        let mut n_eq = 0;
        for (state, tmpl) in all {
            let (_, terms, n) = &mut eqs[n_eq];
            for t in tmpl.iter() {
                let resolve = |e: u8| match e {
                    OFFSET => EdgeValue::Param { j: offset_j, mult: T::one() },
                    e => value[e as usize],
                };
                let (coef, param) = match t.edge.map(resolve) {
                    None => (t.coef, None),
                    Some(EdgeValue::Fixed(v)) => (t.coef * v, None),
                    Some(EdgeValue::Param { j, mult }) => (t.coef * mult, Some(j)),
                };
                // Merge with an earlier term of the same parameter and basis.
                match terms[..*n].iter_mut().find(|o| o.param == param && o.basis == t.basis) {
                    Some(o) => o.coef += coef,
                    None => {
                        terms[*n] = Term { coef, param, basis: t.basis };
                        *n += 1;
                    }
                }
            }
            eqs[n_eq].0 = *state;
            n_eq += 1;
        }
        for pass in [true, false] {
            for (state, terms, n) in &eqs[..n_eq] {
                if terms[..*n].iter().any(|t| t.param.is_some()) == pass {
                    s.push_equation(*state, &terms[..*n])?;
                }
            }
        }
        s.check_identifiable()?;
        // Monomials: known constants, constants that are parameters, then walk the edges.
        let mut mono: [Option<(T, [i8; MAX_PARAMS])>; MAX_CONSTANTS] = [None; MAX_CONSTANTS];
        for c in 0..nc {
            if let Some(v) = self.known[c] {
                mono[c] = Some((v, [0; MAX_PARAMS]));
            }
        }
        for (j, &(a, b)) in param_edges[..np].iter().enumerate() {
            if b.is_none() && a != OFFSET {
                let mut e = [0i8; MAX_PARAMS];
                e[j] = 1;
                mono[a as usize] = Some((T::one(), e));
            }
        }
        loop {
            let mut changed = false;
            for (j, &(a, b)) in param_edges[..np].iter().enumerate() {
                let Some(b) = b else { continue };
                let (a, b) = (a as usize, b as usize);
                match (mono[a], mono[b]) {
                    (Some((f, mut e)), None) => {
                        e[j] -= 1;
                        mono[b] = Some((f, e));
                        changed = true;
                    }
                    (None, Some((f, mut e))) => {
                        e[j] += 1;
                        mono[a] = Some((f, e));
                        changed = true;
                    }
                    _ => {}
                }
            }
            if !changed {
                break;
            }
        }
        let mut constants = [""; MAX_CONSTANTS];
        constants[..nc].copy_from_slice(self.constants);
        let mut known = [None; MAX_CONSTANTS];
        known[..nc].copy_from_slice(self.known);
        Ok(PhysicalStructure {
            structure: s,
            names,
            param_edges,
            constants,
            n_constants: nc as u8,
            known,
            mono,
            appears,
            absent: self.absent,
        })
    }
}

impl<T: Real> PhysicalStructure<T> {
    /// The structure (to give to an identifier).
    pub fn structure(&self) -> &Structure<T> {
        &self.structure
    }

    /// The parameters' names: a constant (`"M"`) or a ratio of two (`"k2/M"`).
    pub fn param_names(&self) -> &[&'static str] {
        &self.names[..self.structure.params()]
    }

    /// Every constant's name.
    pub fn constant_names(&self) -> &[&'static str] {
        &self.constants[..self.n_constants as usize]
    }

    /// The value of a known constant.
    pub fn known(&self, c: usize) -> Option<T> {
        self.known[c]
    }

    /// `true` when constant `c` follows from the parameters (or is known).
    pub fn determined(&self, c: usize) -> bool {
        self.mono[c].is_some()
    }

    /// Why constant `c` is not determined, in words that say what would determine it, or
    /// `None` when it is (or is known): a constant that appears in the equations only in ratios
    /// needs one constant of its ratios known (a mass: the equations are homogeneous in the
    /// constants, so data fix only ratios); one that appears in no equation needs the signals
    /// these equations do not read (the structure's own reason, e.g. for the body equation of
    /// the realistic sensors: the tyre force).
    pub fn needs(&self, c: usize) -> Option<&'static str> {
        if c >= self.n_constants as usize || self.mono[c].is_some() {
            return None;
        }
        Some(if self.appears[c] {
            "a known mass: these equations fix only ratios of the constants (give one mass as known)"
        } else {
            self.absent
        })
    }

    /// The true parameter values of the structure for a vehicle with these constants (in the
    /// order of [`PhysicalStructure::constant_names`]) into `out`.
    ///
    /// # Errors
    /// [`Error::Shape`] for wrong lengths.
    pub fn params_of(&self, constants: &[T], out: &mut [T]) -> Result<()> {
        let np = self.structure.params();
        if constants.len() != self.n_constants as usize || out.len() != np {
            return Err(Error::Shape { arg: "out", expected: np, got: out.len() });
        }
        for (j, o) in out.iter_mut().enumerate() {
            let (a, b) = self.param_edges[j];
            *o = match b {
                None if a == OFFSET => T::zero(),
                None => constants[a as usize],
                Some(b) => constants[a as usize] / constants[b as usize],
            };
        }
        Ok(())
    }

    /// Constant `c` from parameters `theta` with covariance `cov` (`params × params`,
    /// row-major): `(value, standard error)` by the delta method (module docs). Known
    /// constants have standard error 0.
    ///
    /// # Errors
    /// [`Error::NotIdentifiable`] when the constant does not follow from the parameters (no
    /// known constant anchors it: give a mass); [`Error::Shape`] for wrong lengths.
    pub fn constant(&self, c: usize, theta: &[T], cov: &[T]) -> Result<(T, T)> {
        let np = self.structure.params();
        if theta.len() != np {
            return Err(Error::Shape { arg: "params", expected: np, got: theta.len() });
        }
        if cov.len() != np * np {
            return Err(Error::Shape { arg: "cov", expected: np * np, got: cov.len() });
        }
        let Some((f, e)) = self.mono.get(c).copied().flatten() else {
            return Err(Error::NotIdentifiable {
                what: "this constant: the equations fix only ratios of the constants; give one of them as known \
                       (a mass)",
            });
        };
        let mut v = f;
        for j in 0..np {
            for _ in 0..e[j].unsigned_abs() {
                v = if e[j] > 0 { v * theta[j] } else { v / theta[j] };
            }
        }
        let mut g = [T::zero(); MAX_PARAMS];
        for j in 0..np {
            if e[j] != 0 {
                g[j] = v * T::of(e[j] as f64) / theta[j];
            }
        }
        let mut var = T::zero();
        for a in 0..np {
            for b in 0..np {
                var += g[a] * cov[a * np + b] * g[b];
            }
        }
        Ok((v, var.max(T::zero()).sqrt()))
    }
}

/// A template term with an edge.
pub(crate) fn tt<T: Real>(coef: T, edge: u8, basis: Basis) -> TemplateTerm<T> {
    TemplateTerm { coef, edge: Some(edge), basis }
}

/// A template term without an edge (a known coefficient).
pub(crate) fn tk<T: Real>(coef: T, basis: Basis) -> TemplateTerm<T> {
    TemplateTerm { coef, edge: None, basis }
}

/// Basis helpers: state `i`, derivative of state `i`.
pub(crate) fn st(i: u8) -> Basis {
    Basis::Var(Var::State(i))
}

pub(crate) fn der(i: u8) -> Basis {
    Basis::Var(Var::Deriv(i))
}
