//! A whole simulation in memory (requires `alloc`).

use super::{RoadSample, Sample};
use crate::Real;

/// A whole simulation, row-major per sample (requires `alloc`).
#[cfg(feature = "alloc")]
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Run<T> {
    /// Number of states `n`.
    pub n_states: usize,
    /// Number of inputs `m`.
    pub n_inputs: usize,
    /// Sample times, s (`len`).
    pub t: alloc::vec::Vec<T>,
    /// True states (`len × n`).
    pub x: alloc::vec::Vec<T>,
    /// True derivatives (`len × n`).
    pub xdot: alloc::vec::Vec<T>,
    /// Road inputs (`len × m`).
    pub u: alloc::vec::Vec<T>,
    /// Measured states (`len × n`).
    pub r: alloc::vec::Vec<T>,
    /// Measured derivatives (`len × n`).
    pub z: alloc::vec::Vec<T>,
    /// Distance travelled, m (`len`), for road simulations; empty otherwise.
    pub s: alloc::vec::Vec<T>,
}

#[cfg(feature = "alloc")]
impl<T: Real> Run<T> {
    /// An empty run with room for `len` samples.
    pub fn with_capacity(n: usize, m: usize, len: usize) -> Self {
        use alloc::vec::Vec;
        Self {
            n_states: n,
            n_inputs: m,
            t: Vec::with_capacity(len),
            x: Vec::with_capacity(len * n),
            xdot: Vec::with_capacity(len * n),
            u: Vec::with_capacity(len * m),
            r: Vec::with_capacity(len * n),
            z: Vec::with_capacity(len * n),
            s: Vec::new(),
        }
    }

    /// Appends one road sample (with its distance `s`).
    pub fn push_road<const N: usize>(&mut self, s: &RoadSample<T, N>) {
        self.push(&s.sample());
        self.s.push(s.s);
    }

    /// Appends one sample.
    pub fn push<const N: usize, const M: usize>(&mut self, s: &Sample<T, N, M>) {
        self.t.push(s.t);
        self.x.extend_from_slice(s.x.as_slice());
        self.xdot.extend_from_slice(s.xdot.as_slice());
        self.u.extend_from_slice(s.u.as_slice());
        self.r.extend_from_slice(s.r.as_slice());
        self.z.extend_from_slice(s.z.as_slice());
    }

    /// Number of samples.
    pub fn len(&self) -> usize {
        self.t.len()
    }

    /// `true` when the run holds no sample.
    pub fn is_empty(&self) -> bool {
        self.t.is_empty()
    }
}
