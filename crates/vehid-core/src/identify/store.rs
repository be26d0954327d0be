//! Where an identifier keeps its per-row state: fixed arrays or heap vectors.

use super::kalman::lanes::{self, RowGroup};
#[cfg(doc)]
use super::KalmanRows;
use crate::array::array_from_items;
use crate::{Error, Real, Result};
use nalgebra::{SMatrix, SVector};

/// A flat, fixed-length buffer: an array (`[X; K]`, `[[X; K]; K]`) or, with `alloc`, a `Vec`.
pub trait Flat<X>: Clone + core::fmt::Debug {
    /// A buffer of `len` copies of `x`.
    ///
    /// # Errors
    /// [`Error::Shape`] when a fixed-size buffer cannot hold exactly `len` elements.
    fn filled(arg: &'static str, len: usize, x: X) -> Result<Self>;
    /// The elements.
    fn flat(&self) -> &[X];
    /// The elements, mutably.
    fn flat_mut(&mut self) -> &mut [X];
    /// Bytes held on the heap (0 for arrays, which live inside the identifier).
    fn heap_bytes(&self) -> usize {
        0
    }
    /// A buffer of the elements `items` yields, in order (how a deserialized buffer is read
    /// back, without allocating for arrays); `Ok(None)` when their number does not fit (an
    /// array takes exactly its length, and none is empty). The first error of `items` is
    /// returned as is.
    ///
    /// # Errors
    /// The first `Err` that `items` yields.
    fn from_items<E>(items: impl Iterator<Item = core::result::Result<X, E>>) -> core::result::Result<Option<Self>, E>;
}

impl<X: Copy + core::fmt::Debug, const K: usize> Flat<X> for [X; K] {
    fn filled(arg: &'static str, len: usize, x: X) -> Result<Self> {
        if len != K {
            return Err(Error::Shape { arg, expected: K, got: len });
        }
        Ok([x; K])
    }
    fn flat(&self) -> &[X] {
        self
    }
    fn flat_mut(&mut self) -> &mut [X] {
        self
    }
    fn from_items<E>(items: impl Iterator<Item = core::result::Result<X, E>>) -> core::result::Result<Option<Self>, E> {
        array_from_items(items)
    }
}

impl<X: Copy + core::fmt::Debug, const K: usize> Flat<X> for [[X; K]; K] {
    fn filled(arg: &'static str, len: usize, x: X) -> Result<Self> {
        if len != K * K {
            return Err(Error::Shape { arg, expected: K * K, got: len });
        }
        Ok([[x; K]; K])
    }
    fn flat(&self) -> &[X] {
        self.as_flattened()
    }
    fn flat_mut(&mut self) -> &mut [X] {
        self.as_flattened_mut()
    }
    fn from_items<E>(items: impl Iterator<Item = core::result::Result<X, E>>) -> core::result::Result<Option<Self>, E> {
        let mut out: Option<Self> = None;
        let mut len = 0;
        for item in items {
            let x = item?;
            if len == K * K {
                return Ok(None);
            }
            out.get_or_insert([[x; K]; K])[len / K][len % K] = x;
            len += 1;
        }
        Ok(out.filter(|_| len == K * K))
    }
}

#[cfg(feature = "alloc")]
impl<X: Copy + core::fmt::Debug> Flat<X> for alloc::vec::Vec<X> {
    fn filled(_arg: &'static str, len: usize, x: X) -> Result<Self> {
        Ok(alloc::vec![x; len])
    }
    fn heap_bytes(&self) -> usize {
        self.capacity() * core::mem::size_of::<X>()
    }
    fn flat(&self) -> &[X] {
        self
    }
    fn flat_mut(&mut self) -> &mut [X] {
        self
    }
    fn from_items<E>(items: impl Iterator<Item = core::result::Result<X, E>>) -> core::result::Result<Option<Self>, E> {
        items.collect::<core::result::Result<Self, E>>().map(Some)
    }
}

/// No scratch: a single group of lanes ([`Fixed`] storage) plans each sample on the stack.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct NoScratch;

impl<X> Flat<X> for NoScratch {
    fn filled(_arg: &'static str, _len: usize, _x: X) -> Result<Self> {
        Ok(NoScratch)
    }
    fn flat(&self) -> &[X] {
        &[]
    }
    fn flat_mut(&mut self) -> &mut [X] {
        &mut []
    }
    fn from_items<E>(
        mut items: impl Iterator<Item = core::result::Result<X, E>>,
    ) -> core::result::Result<Option<Self>, E> {
        Ok(items.next().transpose()?.is_none().then_some(NoScratch))
    }
}

/// Where an identifier keeps its per-row state: [`Fixed<K>`] or [`Dynamic`].
pub trait Store<T: Real, const N: usize>: Clone + core::fmt::Debug {
    /// Row indices (`K`).
    type Rows: Flat<usize>;
    /// One value per row (`K`).
    type Scalars: Flat<T>;
    /// One `N`-vector per row (`K`).
    type Vecs: Flat<SVector<T, N>>;
    /// The decoupled row filters, side by side in groups of lanes (the private `lanes::RowLanes`).
    type Group: RowGroup<T, N>;
    /// The groups (`⌈K / lanes⌉`).
    type Groups: Flat<Self::Group>;
    /// One planned step per group, for the identifiers that plan through memory (several
    /// groups, or a group with too many covariance entries to keep in registers).
    type Scratches: Flat<<Self::Group as RowGroup<T, N>>::Scratch>;
    /// The square-root form's planned steps, likewise (empty unless that form is used).
    type SqrtScratches: Flat<<Self::Group as RowGroup<T, N>>::SqrtScratch>;
    /// One value per pair of rows (`K²`).
    type PairScalars: Flat<T>;
    /// One `N`-vector per pair of rows (`K²`).
    type PairVecs: Flat<SVector<T, N>>;
    /// One `N × N` block per pair of rows (`K²`).
    type Blocks: Flat<SMatrix<T, N, N>>;
}

/// Lanes per group of [`Dynamic`] row filters: one AVX2 register of `f64` on x86-64, one
/// 128-bit register elsewhere (NEON). [`Fixed<K>`] keeps all `K` rows in one group.
pub const DYNAMIC_LANES: usize = if cfg!(target_arch = "x86_64") { 4 } else { 2 };

/// Fixed storage for exactly `K` unknown rows: plain arrays, no allocation.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct Fixed<const K: usize>;

impl<T: Real, const N: usize, const K: usize> Store<T, N> for Fixed<K> {
    type Rows = [usize; K];
    type Scalars = [T; K];
    type Vecs = [SVector<T, N>; K];
    type Group = lanes::RowLanes<T, N, K>;
    type Groups = [lanes::RowLanes<T, N, K>; 1];
    type Scratches = NoScratch;
    type SqrtScratches = NoScratch;
    type PairScalars = [[T; K]; K];
    type PairVecs = [[SVector<T, N>; K]; K];
    type Blocks = [[SMatrix<T, N, N>; K]; K];
}

/// Heap storage sized at construction for any number of unknown rows (requires `alloc`).
///
/// The decoupled rows of [`KalmanRows`] are kept in groups of `L` lanes (default
/// [`DYNAMIC_LANES`]); rows are padded up to a multiple of `L`. For one or two rows `L = 2`
/// is faster (measured, quarter car f64: 22.6 ns against 37–42 ns with four lanes of which
/// two are padding); the Python bindings choose it then.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct Dynamic<const L: usize = DYNAMIC_LANES>;

#[cfg(feature = "alloc")]
impl<T: Real, const N: usize, const L: usize> Store<T, N> for Dynamic<L> {
    type Rows = alloc::vec::Vec<usize>;
    type Scalars = alloc::vec::Vec<T>;
    type Vecs = alloc::vec::Vec<SVector<T, N>>;
    type Group = lanes::RowLanes<T, N, L>;
    type Groups = alloc::vec::Vec<lanes::RowLanes<T, N, L>>;
    type Scratches = alloc::vec::Vec<lanes::LaneScratch<T, N, L>>;
    type SqrtScratches = alloc::vec::Vec<lanes::SqrtScratch<T, N, L>>;
    type PairScalars = alloc::vec::Vec<T>;
    type PairVecs = alloc::vec::Vec<SVector<T, N>>;
    type Blocks = alloc::vec::Vec<SMatrix<T, N, N>>;
}

/// Validates a row list against `N` (distinct, in range, at least one) and copies it.
pub(crate) fn rows_buffer<R: Flat<usize>, const N: usize>(rows: &[usize]) -> Result<R> {
    let set = crate::model::RowSet::<N>::new(rows)?;
    let mut out = R::filled("unknown_rows", rows.len(), 0)?;
    // Keep the caller's order: innovations and θ follow it.
    out.flat_mut().copy_from_slice(rows);
    debug_assert_eq!(set.len(), rows.len());
    Ok(out)
}

/// Expands one value or one value per row to `k` values.
pub(crate) fn per_row<T: Real>(arg: &'static str, v: &[T], k: usize, i: usize) -> Result<T> {
    match v.len() {
        1 => Ok(v[0]),
        n if n == k => Ok(v[i]),
        n => Err(Error::Shape { arg, expected: k, got: n }),
    }
}

/// Writes per-row estimates row-major (`K × N`) into `out`.
pub(crate) fn rows_into<T: Real, const N: usize>(theta: &[SVector<T, N>], out: &mut [T]) -> Result<()> {
    let k = theta.len();
    if out.len() != k * N {
        return Err(Error::Shape { arg: "out", expected: k * N, got: out.len() });
    }
    for (chunk, t) in out.chunks_exact_mut(N).zip(theta) {
        chunk.copy_from_slice(t.as_slice());
    }
    Ok(())
}
