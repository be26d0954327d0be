//! Whether a [`Structure`]'s parameters can be identified (every parameter used, no two
//! confounded) and their independent groups ([`Partition`]).

use super::*;

impl<T: Real> Structure<T> {
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
