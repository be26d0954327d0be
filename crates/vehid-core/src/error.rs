use core::fmt;

/// Result type of every fallible vehid operation.
pub type Result<T> = core::result::Result<T, Error>;

/// Everything that can go wrong in vehid, as data: bad input is reported, never panicked on.
///
/// Each variant names the offending argument (`arg`) so the message tells the caller what
/// to fix. A rejected per-sample update leaves the estimator exactly as it was.
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub enum Error {
    /// An argument has a value outside its domain; `expected` states the domain.
    InvalidArgument {
        /// Name of the argument.
        arg: &'static str,
        /// What a valid value looks like, e.g. "a finite value > 0".
        expected: &'static str,
    },
    /// An argument holds NaN or an infinity at position `index` (row-major).
    NonFinite {
        /// Name of the argument.
        arg: &'static str,
        /// Position of the first non-finite element.
        index: usize,
    },
    /// An argument has the wrong length or shape.
    Shape {
        /// Name of the argument.
        arg: &'static str,
        /// Expected number of elements (or rows).
        expected: usize,
        /// Number received.
        got: usize,
    },
    /// A row index is out of range or repeated.
    BadRow {
        /// Name of the argument.
        arg: &'static str,
        /// The offending row index (0-based).
        row: usize,
        /// Number of states `n`.
        n: usize,
    },
    /// The data do not excite every state direction: the regressor matrix (shared by every
    /// unknown row, since `H = I ⊗ xᵀ`) has rank `rank` < `needed`, so every unknown row
    /// lacks excitation. More (or richer) samples are required.
    RankDeficient {
        /// Numerical rank found.
        rank: usize,
        /// Rank required (the number of states).
        needed: usize,
    },
    /// One stored sample dominates a batch regression (its state is more than 1e6 times the
    /// typical one), so that the others cannot be resolved: an outlier to remove.
    Dominated {
        /// Index of the sample (0-based, in the order stored).
        sample: usize,
    },
    /// A matrix that must be invertible or positive definite is not (numerically).
    Singular {
        /// What was being factorized.
        what: &'static str,
    },
    /// The model is not asymptotically stable, so a stationary quantity does not exist.
    Unstable {
        /// The quantity that was asked for.
        what: &'static str,
    },
    /// The known quantities do not determine the physical constants.
    NotIdentifiable {
        /// Which constant cannot be recovered, and why.
        what: &'static str,
    },
    /// An option string names no known choice; `expected` lists the choices.
    UnknownOption {
        /// Name of the argument.
        arg: &'static str,
        /// The accepted values, e.g. `"rows", "shared", "full"`.
        expected: &'static str,
    },
    /// The operation does not exist for this kind of object (e.g. the covariance of an
    /// identifier that keeps none).
    Unsupported {
        /// What was asked for.
        what: &'static str,
    },
    /// A long computation was stopped on request (e.g. Ctrl-C); nothing was changed.
    Interrupted,
    /// Memory for a result sized by the caller could not be reserved.
    OutOfMemory {
        /// What was being allocated.
        what: &'static str,
        /// Bytes requested (`usize::MAX` when the size itself overflows).
        bytes: usize,
    },
    /// A fixed-capacity buffer is too small for the requested configuration.
    Capacity {
        /// Name of the argument or buffer.
        arg: &'static str,
        /// Capacity needed.
        needed: usize,
        /// Capacity available.
        capacity: usize,
    },
}

impl fmt::Display for Error {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Error::InvalidArgument { arg, expected } => {
                write!(f, "invalid `{arg}`: expected {expected}")
            }
            Error::NonFinite { arg, index } => {
                write!(f, "`{arg}` holds a non-finite value (NaN or inf) at index {index}: pass finite numbers")
            }
            Error::Shape { arg, expected, got } => {
                write!(f, "`{arg}` has {got} elements but {expected} are needed: check its shape")
            }
            Error::BadRow { arg, row, n } => {
                write!(f, "`{arg}` names row {row}, but rows must be distinct and in 0..{n} (0-based)")
            }
            Error::RankDeficient { rank, needed } => write!(
                f,
                "the data lacks excitation: the regressors so far span only {rank} of the {needed} \
                 directions the estimate needs; use more samples, a nonzero initial state, or a richer \
                 input"
            ),
            Error::Singular { what } => write!(f, "{what} is singular or not positive definite"),
            Error::Dominated { sample } => write!(
                f,
                "sample {sample} dominates the regression (its state is more than 1e6 times the typical one): an \
                 outlier; remove it (remove({sample})) and solve again"
            ),
            Error::Unstable { what } => {
                write!(f, "{what} does not exist: the model has a pole with non-negative real part")
            }
            Error::NotIdentifiable { what } => write!(f, "cannot recover {what}"),
            Error::UnknownOption { arg, expected } => {
                write!(f, "unknown `{arg}`: expected one of {expected}")
            }
            Error::Unsupported { what } => write!(f, "not available: {what}"),
            Error::Interrupted => write!(f, "interrupted; nothing was changed"),
            Error::OutOfMemory { what, bytes } => {
                if *bytes == usize::MAX {
                    write!(f, "{what} would need more memory than can be addressed")
                } else {
                    write!(f, "{what} needs {bytes} bytes, which could not be allocated")
                }
            }
            Error::Capacity { arg, needed, capacity } => {
                write!(f, "`{arg}` needs a capacity of {needed} but has {capacity}: raise the const-generic capacity")
            }
        }
    }
}

#[cfg(feature = "std")]
impl std::error::Error for Error {}

/// Checks that every value is finite; reports the first offender.
pub(crate) fn check_finite<T: crate::Real>(arg: &'static str, values: &[T]) -> Result<()> {
    match values.iter().position(|v| !v.finite()) {
        Some(index) => Err(Error::NonFinite { arg, index }),
        None => Ok(()),
    }
}

/// Checks a single value is finite and strictly positive.
pub(crate) fn check_positive<T: crate::Real>(arg: &'static str, v: T) -> Result<()> {
    if v.finite() && v > T::zero() {
        Ok(())
    } else {
        Err(Error::InvalidArgument { arg, expected: "a finite value > 0" })
    }
}

/// Checks a single value is finite and non-negative (a standard deviation or variance).
pub(crate) fn check_nonneg<T: crate::Real>(arg: &'static str, v: T) -> Result<()> {
    if v.finite() && v >= T::zero() {
        Ok(())
    } else {
        Err(Error::InvalidArgument { arg, expected: "a finite value >= 0" })
    }
}
