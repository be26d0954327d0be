//! A batch of samples as the interface takes it (row-major slices), and its iterator.

use super::Dims;
use crate::{Error, Result};

/// A batch of samples, each stored row-major: sample `k` is `x[k n .. (k+1) n]`,
/// `z[k n .. (k+1) n]` and `u[k m .. (k+1) m]`.
#[derive(Debug, Clone, Copy)]
pub struct Samples<'a, T> {
    x: &'a [T],
    z: &'a [T],
    u: &'a [T],
    states: usize,
    inputs: usize,
    len: usize,
}

impl<'a, T> Samples<'a, T> {
    /// Checks the layout: `x` and `z` hold the same whole number of samples of `states`
    /// values, `u` holds `inputs` values per sample (nothing when `inputs` is 0).
    ///
    /// # Errors
    /// [`Error::Shape`] naming `r` (the measured states), `z` or `u`; [`Error::InvalidArgument`]
    /// for `states == 0`.
    pub fn new(states: usize, inputs: usize, x: &'a [T], z: &'a [T], u: &'a [T]) -> Result<Self> {
        if states == 0 {
            return Err(Error::InvalidArgument { arg: "states", expected: "at least one state" });
        }
        if x.len() % states != 0 {
            return Err(Error::Shape { arg: "r", expected: (x.len() / states + 1) * states, got: x.len() });
        }
        let len = x.len() / states;
        if z.len() != x.len() {
            return Err(Error::Shape { arg: "z", expected: x.len(), got: z.len() });
        }
        let need_u = len.checked_mul(inputs).ok_or(Error::Shape { arg: "u", expected: usize::MAX, got: u.len() })?;
        if u.len() != need_u {
            return Err(Error::Shape { arg: "u", expected: need_u, got: u.len() });
        }
        Ok(Self { x, z, u, states, inputs, len })
    }

    /// Number of samples.
    pub fn len(&self) -> usize {
        self.len
    }

    /// `true` when there is no sample.
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// States per sample.
    pub fn states(&self) -> usize {
        self.states
    }

    /// Inputs per sample.
    pub fn inputs(&self) -> usize {
        self.inputs
    }

    /// The samples in order, as `(x, z, u)` slices.
    pub fn iter(&self) -> SampleIter<'a, T> {
        SampleIter { x: self.x, z: self.z, u: self.u, n: self.states, m: self.inputs }
    }

    /// The samples from index `start` on.
    pub fn skip_to(&self, start: usize) -> Samples<'a, T> {
        let start = start.min(self.len);
        let (n, m) = (self.states, self.inputs);
        Samples {
            x: &self.x[start * n..],
            z: &self.z[start * n..],
            u: &self.u[start * m..],
            states: n,
            inputs: m,
            len: self.len - start,
        }
    }

    /// Checks that these samples fit an identifier of the given dimensions.
    ///
    /// # Errors
    /// [`Error::Shape`] naming `r` (states per sample) or `u` (inputs per sample).
    pub fn check(&self, dims: Dims) -> Result<()> {
        if self.states != dims.states {
            return Err(Error::Shape { arg: "r", expected: dims.states, got: self.states });
        }
        if self.inputs != dims.inputs {
            return Err(Error::Shape { arg: "u", expected: dims.inputs, got: self.inputs });
        }
        Ok(())
    }
}

/// Iterator over the samples of [`Samples`]: `(x, z, u)` per sample.
#[derive(Debug, Clone)]
pub struct SampleIter<'a, T> {
    x: &'a [T],
    z: &'a [T],
    u: &'a [T],
    n: usize,
    m: usize,
}

impl<'a, T> Iterator for SampleIter<'a, T> {
    type Item = (&'a [T], &'a [T], &'a [T]);

    #[inline(always)]
    fn next(&mut self) -> Option<Self::Item> {
        if self.x.len() < self.n || self.z.len() < self.n || self.u.len() < self.m {
            return None;
        }
        let (x, xr) = self.x.split_at(self.n);
        let (z, zr) = self.z.split_at(self.n);
        let (u, ur) = self.u.split_at(self.m);
        (self.x, self.z, self.u) = (xr, zr, ur);
        Some((x, z, u))
    }

    fn size_hint(&self) -> (usize, Option<usize>) {
        let left = self.x.len() / self.n.max(1);
        (left, Some(left))
    }
}
