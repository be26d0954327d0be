//! A [`StructuredPrior`] as the blocks of the instrumental normal equations it adds to.

use super::*;

/// Per-group prior covariances (`None` for the exact start).
pub(super) struct PriorBlocks<T: Real, const P: usize> {
    diag: [T; MAX_PARAMS],
    matrix: Option<[T; MAX_PARAMS * MAX_PARAMS]>,
    part: Partition,
    params: usize,
}

impl<T: Real, const P: usize> PriorBlocks<T, P> {
    pub(super) fn block(&self, g: usize) -> SMatrix<T, P, P> {
        let np = self.params;
        let mut pm = SMatrix::<T, P, P>::zeros();
        let member = |j: usize| self.part.group_of_param[j] as usize == g && (self.part.local[j] as usize) < P;
        for a in (0..np).filter(|&a| member(a)) {
            let la = self.part.local[a] as usize;
            match &self.matrix {
                Some(m) => {
                    for b in (0..np).filter(|&b| member(b)) {
                        pm[(la, self.part.local[b] as usize)] = m[a * np + b];
                    }
                }
                None => pm[(la, la)] = self.diag[a],
            }
        }
        pm
    }
}

pub(super) fn prior_blocks<T: Real, const P: usize>(
    s: &Structure<T>,
    part: &Partition,
    p0: StructuredPrior<'_, T>,
) -> Result<Option<PriorBlocks<T, P>>> {
    let (np, ne) = (s.params(), s.equations());
    let mut out = PriorBlocks { diag: [T::zero(); MAX_PARAMS], matrix: None, part: *part, params: np };
    match p0 {
        StructuredPrior::Exact => return Ok(None),
        StructuredPrior::Scalar(v) => {
            crate::error::check_positive("p0", v)?;
            out.diag[..np].fill(v);
        }
        StructuredPrior::PerEquation(v) => {
            if v.len() != ne {
                return Err(Error::Shape { arg: "p0", expected: ne, got: v.len() });
            }
            for &x in v {
                crate::error::check_positive("p0", x)?;
            }
            for i in (0..ne).rev() {
                for t in s.terms(i) {
                    if let Some(j) = t.param {
                        out.diag[j as usize] = v[i];
                    }
                }
            }
        }
        StructuredPrior::Matrix(m) => {
            if m.len() != np * np {
                return Err(Error::Shape { arg: "p0", expected: np * np, got: m.len() });
            }
            crate::error::check_finite("p0", m)?;
            let mut a = [T::zero(); MAX_PARAMS * MAX_PARAMS];
            for x in 0..np {
                for y in 0..np {
                    if part.group_of_param[x] != part.group_of_param[y] && m[x * np + y] != T::zero() {
                        return Err(Error::InvalidArgument {
                            arg: "p0",
                            expected: "no prior covariance between parameters of independent groups (no equation \
                                       links them)",
                        });
                    }
                    a[x * np + y] = m[x * np + y];
                }
            }
            out.matrix = Some(a);
        }
    }
    Ok(Some(out))
}
