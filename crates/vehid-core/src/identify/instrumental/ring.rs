//! The ring of the last `delay` samples that the instruments are read from (fixed capacity,
//! no allocation).

use super::*;

/// Values the ring of past samples holds: `delay × (2 n + m) ≤ RING_VALUES`.
pub const RING_VALUES: usize = 512;

/// The last `delay` samples `(x, z, u)` (fixed capacity, no allocation). Serialized as is
/// (feature `serde`); its owner checks it on load ([`InstrumentalVariables`]'s `restored`).
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(
    feature = "serde",
    derive(serde::Serialize, serde::Deserialize),
    serde(bound(serialize = "T: serde::Serialize", deserialize = "T: crate::Real"))
)]
pub(crate) struct Ring<T> {
    #[cfg_attr(feature = "serde", serde(with = "crate::persist::array"))]
    pub(super) buf: [T; RING_VALUES],
    /// Values per sample (`2 n + m`), slots (`delay`), the next slot, slots filled.
    pub(super) width: u16,
    pub(super) slots: u16,
    pub(super) head: u16,
    pub(super) filled: u16,
}

impl<T: Real> Ring<T> {
    /// A ring of `slots` samples of `n` states and `m` inputs (`arg` names the setting).
    pub(crate) fn new(n: usize, m: usize, delay: usize, slots: usize) -> Result<Self> {
        if delay == 0 {
            return Err(Error::InvalidArgument {
                arg: "delay",
                expected: "at least 1 sample (delay 0 makes the instruments the noisy regressors: least squares)",
            });
        }
        let width = 2 * n + m;
        let need = slots.saturating_mul(width);
        if need > RING_VALUES {
            return Err(Error::Capacity { arg: "delay", needed: need, capacity: RING_VALUES });
        }
        Ok(Self { buf: [T::zero(); RING_VALUES], width: width as u16, slots: slots as u16, head: 0, filled: 0 })
    }

    /// `true` once every slot holds a sample.
    #[inline(always)]
    pub(crate) fn full(&self) -> bool {
        self.filled == self.slots
    }

    /// The sample `age` steps back (`1 ≤ age ≤ slots`, the ring full).
    #[inline(always)]
    pub(crate) fn ago(&self, age: usize) -> &[T] {
        let w = self.width as usize;
        let slots = self.slots as usize;
        // head < slots and 1 ≤ age ≤ slots: one conditional subtraction wraps it.
        let i = self.head as usize + slots - age;
        let at = if i >= slots { i - slots } else { i } * w;
        &self.buf[at..at + w]
    }

    /// [`Ring::push`] of a sample of `N` states and no input, on compile-time lengths.
    #[inline(always)]
    pub(crate) fn push_states<const N: usize>(&mut self, x: &[T], z: &[T]) {
        let at = self.head as usize * 2 * N;
        let slot = &mut self.buf[at..at + 2 * N];
        let (sx, sz) = slot.split_at_mut(N);
        sx.copy_from_slice(&x[..N]);
        sz.copy_from_slice(&z[..N]);
        self.head = if self.head + 1 == self.slots { 0 } else { self.head + 1 };
        self.filled = (self.filled + 1).min(self.slots);
    }

    /// Stores a sample (over the oldest).
    #[inline(always)]
    pub(crate) fn push(&mut self, x: &[T], z: &[T], u: &[T]) {
        let w = self.width as usize;
        let at = self.head as usize * w;
        let slot = &mut self.buf[at..at + w];
        let (n, m) = (x.len(), u.len());
        slot[..n].copy_from_slice(x);
        slot[n..2 * n].copy_from_slice(z);
        slot[2 * n..2 * n + m].copy_from_slice(u);
        self.head = if self.head + 1 == self.slots { 0 } else { self.head + 1 };
        self.filled = (self.filled + 1).min(self.slots);
    }
}
