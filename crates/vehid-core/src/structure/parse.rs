//! The text form of a [`Structure`] (std): names for states, inputs and parameters, and
//! equations such as `"a*tau - b*v - c*sign(v) - d"` or `"-k2_M*(qb - qw) - b_M*(vb - vw)"`.
//!
//! Grammar (whitespace is free):
//! ```text
//! expr    := ['+' | '-'] product (('+' | '-') product)*
//! product := factor (('*' | '/') factor)*          '/' only by a number
//! factor  := number | name | '(' expr ')' | f '(' expr ')'     f ∈ sign, pos, neg, der
//! ```
//! A name is a state, an input, or else a parameter (in order of first appearance, unless
//! the parameters are declared). Products are expanded, so `k*(x - y)` is `k*x - k*y`; every
//! resulting term must be `number × [parameter] × [basis]` with at most one parameter and one
//! basis (a state, an input, `der(state)`, or `sign`/`pos`/`neg` of a linear combination of
//! states, inputs and derivatives): the model stays linear in its parameters.
//!
//! ## Identifiability
//! A function of a combination is kept in one form however it is written (its entries in the
//! order of their variables, scaled so that the first coefficient is 1, the scale moved
//! outside: `sign(3*x)` is `sign(x)`, `neg(v - x)` is `-pos(x - v)`), and each combination is
//! stored once. Then two parameters whose terms are proportional (`a*sign(x) + b*sign(3*x)`)
//! are refused by name, and so is any set whose terms are linearly dependent as functions
//! (`a*x + b*pos(x) + c*neg(x)`: `pos(x) + neg(x) = x`), found by the rank of the regressors at
//! 64 pseudo-random points: such parameters cannot be told apart by any data, and with a prior
//! an identifier would return an arbitrary split of them.
//!
//! ## Limits
//! Every limit is checked before the work it bounds, so that no text, however written, can
//! exhaust the stack, the memory or the time of the process that parses it:
//! - a text is at most [`MAX_TEXT_BYTES`] (10,000) bytes long, checked before it is read;
//! - parentheses, function calls and unary minus signs nest at most [`MAX_DEPTH`] (64)
//!   levels deep, checked as the parser descends (the parser recurses once per level);
//! - a sum or a product has at most [`MAX_TERMS`] (96) terms once like terms are merged: a
//!   product's size is the product of its factors' sizes, checked before it is expanded
//!   (`(1+1)*(1+1)*…` is one term; `(a+b+…)*(x+y+…)` of 12 × 9 terms is refused);
//! - at most [`MAX_STATES`], [`MAX_INPUTS`] and [`MAX_PARAMS`] names, and [`MAX_EQUATIONS`]
//!   equations, counted before any name is compared; a new parameter beyond [`MAX_PARAMS`]
//!   stops the parse where it appears.
//!
//! Each is a [`StructureError`] naming the equation (or the list of names) and the limit.

use super::{
    Basis, Structure, Term, Var, MAX_COMBINATION, MAX_EQUATIONS, MAX_INPUTS, MAX_PARAMS, MAX_STATES, MAX_TERMS,
};
use crate::Real;
use std::collections::HashSet;
use std::string::{String, ToString};
use std::vec::Vec;
use std::{format, vec};

mod grammar;

/// Longest equation text, in bytes (characters, for ASCII text). At most [`MAX_TERMS`] terms
/// fit in any case; 10,000 bytes leave about 100 bytes for each.
pub const MAX_TEXT_BYTES: usize = 10_000;

/// Deepest nesting of parentheses, function calls (`sign(`, `pos(`, `neg(`) and unary minus
/// signs (`--x`) in an equation: the parser descends one level of recursion for each. At 64
/// levels it uses about 0.7 MiB of stack when vehid-core is built without optimization (10
/// KiB per level, measured), 0.1 MiB at `opt-level = 1` (1.4 KiB per level): a 2 MiB thread
/// stack, the default of a spawned Rust thread, holds it.
pub const MAX_DEPTH: usize = 64;

/// A structure's names: states, inputs, parameters, and the states whose equations are
/// identified (in order) — everything the numeric [`Structure`] leaves out.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct Names {
    /// State names, in state order.
    pub states: Vec<String>,
    /// Measured input names.
    pub inputs: Vec<String>,
    /// Parameter names, in parameter order.
    pub params: Vec<String>,
}

/// A structure that could not be built: which item (`"equation for v"`, `"states"`, …) and
/// what is wrong with it, in words that say how to fix it.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct StructureError {
    /// The item at fault.
    pub item: String,
    /// What is wrong, and the fix.
    pub message: String,
}

impl core::fmt::Display for StructureError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        write!(f, "{}: {}", self.item, self.message)
    }
}

impl std::error::Error for StructureError {}

fn err<R>(item: &str, message: impl Into<String>) -> Result<R, StructureError> {
    Err(StructureError { item: item.to_string(), message: message.into() })
}

/// Builds a [`Structure`] from names and equation texts.
///
/// # Examples
/// A mass on a rail with a measured force `tau`, viscous and Coulomb friction and an offset:
/// ```
/// use vehid_core::structure::StructureBuilder;
/// let (s, names) = StructureBuilder::new(&["q", "v"], &["tau"])
///     .equation("v", "a*tau - b*v - c*sign(v) - d")
///     .known("q", "v")
///     .build::<f64>()?;
/// assert_eq!(names.params, ["a", "b", "c", "d"]);
/// assert_eq!((s.params(), s.equations(), s.known_equations()), (4, 1, 1));
/// # Ok::<(), vehid_core::structure::StructureError>(())
/// ```
#[derive(Debug, Clone, Default)]
pub struct StructureBuilder {
    states: Vec<String>,
    inputs: Vec<String>,
    params: Option<Vec<String>>,
    equations: Vec<(String, String)>,
    known: Vec<(String, String)>,
}

impl StructureBuilder {
    /// A builder over these state and input names.
    pub fn new<S: AsRef<str>>(states: &[S], inputs: &[S]) -> Self {
        Self {
            states: states.iter().map(|s| s.as_ref().to_string()).collect(),
            inputs: inputs.iter().map(|s| s.as_ref().to_string()).collect(),
            ..Self::default()
        }
    }

    /// Declares the parameters (their order fixes the parameter vector); any other name in an
    /// equation is then an error instead of a new parameter.
    pub fn parameters<S: AsRef<str>>(mut self, names: &[S]) -> Self {
        self.params = Some(names.iter().map(|s| s.as_ref().to_string()).collect());
        self
    }

    /// An identified equation: the derivative of `state` is `text`.
    pub fn equation(mut self, state: &str, text: &str) -> Self {
        self.equations.push((state.to_string(), text.to_string()));
        self
    }

    /// A known (parameter-free) equation, used when simulating.
    pub fn known(mut self, state: &str, text: &str) -> Self {
        self.known.push((state.to_string(), text.to_string()));
        self
    }

    /// Parses everything and checks the structure ([`Structure::check_identifiable`]).
    ///
    /// # Errors
    /// [`StructureError`] naming the item: a bad or repeated name, a syntax error (with the
    /// position), a product of two parameters or two variables, an unused or confounded
    /// parameter, capacities exceeded.
    pub fn build<T: Real>(&self) -> Result<(Structure<T>, Names), StructureError> {
        // Counts first: nothing below is done on more names or equations than fit.
        check_count("states", self.states.len(), MAX_STATES)?;
        check_count("inputs", self.inputs.len(), MAX_INPUTS)?;
        if let Some(p) = &self.params {
            check_count("parameters", p.len(), MAX_PARAMS)?;
        }
        check_count("equations", self.equations.len() + self.known.len(), MAX_EQUATIONS)?;
        let states = check_names("states", &self.states)?;
        check_names("inputs", &self.inputs)?;
        if let Some(s) = self.inputs.iter().find(|s| states.contains(s.as_str())) {
            return err("inputs", format!("'{s}' is also a state: give inputs and states different names"));
        }
        if self.states.is_empty() {
            return err("states", "at least one state is needed");
        }
        if let Some(p) = &self.params {
            check_names("parameters", p)?;
            let inputs: HashSet<&str> = self.inputs.iter().map(String::as_str).collect();
            if let Some(s) = p.iter().find(|p| states.contains(p.as_str()) || inputs.contains(p.as_str())) {
                return err("parameters", format!("'{s}' is also a state or input name"));
            }
        }
        if self.equations.is_empty() {
            return err("equations", "at least one identified equation is needed");
        }
        let mut ctx = Ctx {
            states: &self.states,
            inputs: &self.inputs,
            params: self.params.clone().unwrap_or_default(),
            fixed: self.params.is_some(),
        };
        // Parse everything first (parameters get their indices in order of appearance).
        let mut parsed = Vec::new();
        for (state, text) in &self.equations {
            let item = format!("equation for {state}");
            let si = state_index(&self.states, state, &item)?;
            let poly = ctx.parse(text, &item, true)?;
            if poly.iter().all(|m| m.param.is_none()) {
                return err(&item, "no parameter in this equation: put parameter-free equations under known");
            }
            parsed.push((si, poly, item));
        }
        for (state, text) in &self.known {
            let item = format!("known equation for {state}");
            let si = state_index(&self.states, state, &item)?;
            let poly = ctx.parse(text, &item, false)?;
            parsed.push((si, poly, item));
        }
        // The parser stops at the parameter beyond MAX_PARAMS.
        debug_assert!(ctx.params.len() <= MAX_PARAMS);
        let mut s = Structure::<T>::new(self.states.len(), self.inputs.len(), ctx.params.len()).or_else(|_| {
            err(
                "structure",
                format!("at most {} states and {} inputs are supported", super::MAX_STATES, super::MAX_INPUTS),
            )
        })?;
        // Each combination is stored once, so that equal function terms have equal bases
        // (the confounded-parameter check compares bases).
        let mut stored: Vec<(&[Entry], (u8, u8))> = Vec::new();
        for (si, poly, item) in &parsed {
            let mut terms: Vec<Term<T>> = Vec::new();
            for m in poly {
                let basis = match &m.basis {
                    None => Basis::One,
                    Some(B::Var(v)) => Basis::Var(*v),
                    Some(B::Fun(f, comb)) => {
                        let (start, len) = match stored.iter().find(|(c, _)| *c == comb.as_slice()) {
                            Some(&(_, at)) => at,
                            None => {
                                let entries: Vec<(Var, T)> = comb.iter().map(|&(v, c)| (v, T::of(c))).collect();
                                let at = s.push_combination(&entries).or_else(|_| {
                                    err(
                                        item,
                                        format!(
                                            "too many entries in sign/pos/neg combinations (at most {MAX_COMBINATION})"
                                        ),
                                    )
                                })?;
                                stored.push((comb.as_slice(), at));
                                at
                            }
                        };
                        match f {
                            Fun::Sign => Basis::Sign { start, len },
                            Fun::Pos => Basis::Pos { start, len },
                            Fun::Neg => Basis::Neg { start, len },
                        }
                    }
                };
                terms.push(Term { coef: T::of(m.coef), param: m.param.map(|p| p as u8), basis });
            }
            if terms.len() > MAX_TERMS {
                return err(item, format!("too many terms (at most {MAX_TERMS} in all)"));
            }
            s.push_equation(*si, &terms).map_err(|e| StructureError { item: item.clone(), message: e.to_string() })?;
        }
        if let Some(j) = s.unused_param() {
            return err(
                "parameters",
                format!("'{}' appears in no identified equation: remove it or use it", ctx.params[j]),
            );
        }
        if let Some((a, b)) = s.confounded_pair() {
            return err(
                "parameters",
                format!(
                    "'{}' and '{}' multiply the same terms, so only a combination of them is identifiable: merge them \
                     into one parameter",
                    ctx.params[a], ctx.params[b]
                ),
            );
        }
        if let Some(set) = dependent_params(&s) {
            let names: Vec<String> = set.iter().map(|&j| format!("'{}'", ctx.params[j])).collect();
            return err(
                "parameters",
                format!(
                    "{} are not separately identifiable: their terms are linearly dependent for every value of the \
                     states and inputs (e.g. pos(e) + neg(e) = e, or one function of a combination written twice), \
                     so only combinations of them have an effect: drop a term or merge the parameters",
                    names.join(", ")
                ),
            );
        }
        Ok((s, Names { states: self.states.clone(), inputs: self.inputs.clone(), params: ctx.params }))
    }
}

/// One entry of a `sign`/`pos`/`neg` combination while parsing: a variable and its coefficient.
type Entry = (Var, f64);

/// Points at which [`dependent_params`] evaluates the regressors.
const RANK_POINTS: usize = 64;

/// The parameters of a set whose regressors are linearly dependent as functions of the
/// states, derivatives and inputs (`None`: every parameter is separately identifiable from
/// rich enough data). The regressors of every identified equation are evaluated at
/// [`RANK_POINTS`] pseudo-random points in `(−1, 1)`, stacked (one row per point and
/// equation), their columns scaled to unit length, and the smallest singular value compared
/// with the largest: below `10⁻⁹` of it (`10⁴ ε` in `f32`) the columns are dependent, and the parameters with
/// a weight over `10⁻³` in its singular vector are the set. Pairs with proportional terms
/// are found earlier, by name ([`Structure::confounded_pair`]); this finds the rest
/// (`a*x + b*pos(x) + c*neg(x)`, since `pos(x) + neg(x) = x`).
fn dependent_params<T: Real>(s: &Structure<T>) -> Option<Vec<usize>> {
    let (np, ne) = (s.params(), s.equations());
    if np == 0 || ne == 0 {
        return None;
    }
    let rows = RANK_POINTS * ne;
    let mut h = nalgebra::DMatrix::<f64>::zeros(rows, np);
    let mut seed = 0x9E37_79B9_7F4A_7C15_u64;
    let mut draw = || {
        seed = seed.wrapping_mul(6_364_136_223_846_793_005).wrapping_add(1_442_695_040_888_963_407);
        T::of(((seed >> 11) as f64 / (1u64 << 53) as f64) * 2.0 - 1.0)
    };
    let (mut x, mut z, mut u) = (vec![T::zero(); s.states()], vec![T::zero(); s.states()], vec![T::zero(); s.inputs()]);
    let mut row = vec![T::zero(); np];
    for k in 0..RANK_POINTS {
        x.iter_mut().chain(z.iter_mut()).chain(u.iter_mut()).for_each(|v| *v = draw());
        for i in 0..ne {
            s.regression(i, &x, &z, &u, &mut row);
            for (j, v) in row.iter().enumerate() {
                h[(k * ne + i, j)] = v.to_f64();
            }
        }
    }
    for mut c in h.column_iter_mut() {
        let norm = c.norm();
        if norm > 0.0 {
            c /= norm;
        }
    }
    let svd = h.svd(false, true);
    let v_t = svd.v_t.as_ref()?;
    let (mut lo, mut hi) = (0, 0);
    for (k, &sv) in svd.singular_values.iter().enumerate() {
        if sv < svd.singular_values[lo] {
            lo = k;
        }
        if sv > svd.singular_values[hi] {
            hi = k;
        }
    }
    // 10⁻⁹ in f64; in f32 the regressors' own rounding (10⁴ ε) sets the floor.
    let tol = 1e-9_f64.max(1e4 * T::default_epsilon().to_f64());
    if svd.singular_values[lo] >= tol * svd.singular_values[hi] {
        return None;
    }
    let set: Vec<usize> = (0..np).filter(|&j| v_t[(lo, j)].abs() > 1e-3).collect();
    (set.len() >= 2).then_some(set)
}

/// `count` names or equations, at most `max`.
fn check_count(item: &str, count: usize, max: usize) -> Result<(), StructureError> {
    if count > max {
        return err(item, format!("{count} given; at most {max} are supported"));
    }
    Ok(())
}

/// Each name valid and given once; the names as a set.
fn check_names<'n>(item: &str, names: &'n [String]) -> Result<HashSet<&'n str>, StructureError> {
    let mut seen = HashSet::with_capacity(names.len());
    for n in names {
        let mut chars = n.chars();
        let ok = chars.next().is_some_and(|c| c.is_ascii_alphabetic() || c == '_')
            && chars.all(|c| c.is_ascii_alphanumeric() || c == '_');
        if !ok {
            return err(item, format!("'{n}' is not a name (letters, digits, '_', not starting with a digit)"));
        }
        if matches!(n.as_str(), "sign" | "pos" | "neg" | "der") {
            return err(item, format!("'{n}' is a function name: choose another name"));
        }
        if !seen.insert(n.as_str()) {
            return err(item, format!("'{n}' is given twice"));
        }
    }
    Ok(seen)
}

fn state_index(states: &[String], name: &str, item: &str) -> Result<usize, StructureError> {
    states
        .iter()
        .position(|s| s == name)
        .map_or_else(|| err(item, format!("'{name}' is not a state (states: {})", states.join(", "))), Ok)
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Fun {
    Sign,
    Pos,
    Neg,
}

/// A basis while parsing: a variable, or a function of a linear combination.
#[derive(Debug, Clone, PartialEq)]
enum B {
    Var(Var),
    Fun(Fun, Vec<(Var, f64)>),
}

/// One monomial `coef × [param] × [basis]`.
#[derive(Debug, Clone, PartialEq)]
struct Mono {
    coef: f64,
    param: Option<usize>,
    basis: Option<B>,
}

type Poly = Vec<Mono>;

struct Ctx<'a> {
    states: &'a [String],
    inputs: &'a [String],
    params: Vec<String>,
    fixed: bool,
}

/// Why parsing stopped: a syntax error, reported with its position and the text, or a limit
/// reached, whose message says where (the text may be long: it is not repeated).
#[derive(Debug)]
enum Stop {
    Syntax(String),
    Limit(String),
}

impl From<String> for Stop {
    fn from(message: String) -> Self {
        Stop::Syntax(message)
    }
}

impl From<&str> for Stop {
    fn from(message: &str) -> Self {
        Stop::Syntax(message.to_string())
    }
}

struct Lexer<'s> {
    text: &'s str,
    pos: usize,
}

#[derive(Debug, Clone, PartialEq)]
enum Tok {
    Num(f64),
    Name(String),
    Op(char),
    End,
}

impl Lexer<'_> {
    fn skip(&mut self) {
        while self.text[self.pos..].starts_with(char::is_whitespace) {
            self.pos += self.text[self.pos..].chars().next().map_or(1, char::len_utf8);
        }
    }

    fn peek(&mut self) -> Result<Tok, String> {
        let save = self.pos;
        let t = self.next();
        self.pos = save;
        t
    }

    fn next(&mut self) -> Result<Tok, String> {
        self.skip();
        let rest = &self.text[self.pos..];
        let Some(c) = rest.chars().next() else { return Ok(Tok::End) };
        if c.is_ascii_digit() || c == '.' {
            let mut end = 0;
            let b = rest.as_bytes();
            while end < b.len() && (b[end].is_ascii_digit() || b[end] == b'.') {
                end += 1;
            }
            if end < b.len() && (b[end] == b'e' || b[end] == b'E') {
                let mut k = end + 1;
                if k < b.len() && (b[k] == b'+' || b[k] == b'-') {
                    k += 1;
                }
                if k < b.len() && b[k].is_ascii_digit() {
                    while k < b.len() && b[k].is_ascii_digit() {
                        k += 1;
                    }
                    end = k;
                }
            }
            let s = &rest[..end];
            self.pos += end;
            return s.parse::<f64>().map(Tok::Num).map_err(|_| format!("'{s}' is not a number"));
        }
        if c.is_ascii_alphabetic() || c == '_' {
            let end = rest.find(|c: char| !(c.is_ascii_alphanumeric() || c == '_')).unwrap_or(rest.len());
            self.pos += end;
            return Ok(Tok::Name(rest[..end].to_string()));
        }
        if "+-*/()".contains(c) {
            self.pos += 1;
            return Ok(Tok::Op(c));
        }
        Err(format!("unexpected '{c}'"))
    }
}

#[cfg(test)]
mod tests;
