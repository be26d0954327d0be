//! [`Differenced`] behind the [`Identifier`] interface, and its persistence (`Persist`: the
//! road state saved with the inner identifier's own).

use super::*;

/// The wrapper's [`RoadState`] and the inner identifier's own saved state, together; loaded
/// only into a wrapper with the same road model, travel, least spacing and contact check.
#[cfg(not(feature = "persist"))]
impl<T: Real, I> crate::identify::Persist for Differenced<T, I> {}

#[cfg(feature = "persist")]
impl<T: Real, I: Identifier<T> + crate::identify::Persist + Clone> crate::identify::Persist for Differenced<T, I> {
    fn save_state(&self) -> Result<alloc::vec::Vec<u8>> {
        crate::identify::persist::save(&(&self.state, self.inner.save_state()?))
    }

    fn load_state(&mut self, bytes: &[u8]) -> Result<()> {
        use crate::identify::persist::NOT_ITS_STATE;
        let (state, inner): (RoadState<T>, alloc::vec::Vec<u8>) =
            postcard::from_bytes(bytes).map_err(|_| NOT_ITS_STATE)?;
        let (a, b) = (&self.state, &state);
        if (a.road, a.travel, a.min_spacing, a.contact) != (b.road, b.travel, b.min_spacing, b.contact) {
            return Err(NOT_ITS_STATE);
        }
        let mut next = Self::with_state(self.inner.clone(), state).map_err(|_| NOT_ITS_STATE)?;
        next.inner.load_state(&inner)?;
        *self = next;
        Ok(())
    }
}

impl<T: Real, I: Identifier<T>> Identifier<T> for Differenced<T, I> {
    fn dims(&self) -> Dims {
        let mut d = self.inner.dims();
        d.inputs += self.odometer() as usize;
        d
    }

    fn rows(&self) -> &[usize] {
        self.inner.rows()
    }

    fn update_into(&mut self, x: &[T], z: &[T], u: &[T], e: &mut [T]) -> Result<()> {
        let dims = self.dims();
        check_lengths(dims, x, z, u, e)?;
        let lifted = self.state.contact.is_some_and(|c| {
            let (aw, ab) = (z[c.wheel as usize], z[c.body as usize]);
            c.m_wheel * aw + c.m_body * ab < -(c.m_wheel + c.m_body) * T::of(G * (1.0 - LIFT_OFF_LOAD))
        });
        self.step(dims, x, z, u, e)?;
        // Counted once the sample is taken, so that a refused one changes nothing.
        self.state.lifted += u64::from(lifted);
        Ok(())
    }

    super::super::interface::forward_estimate!(inner);

    fn samples(&self) -> u64 {
        self.state.seen
    }

    fn gated_into(&self, out: &mut [u64]) -> Result<()> {
        self.inner.gated_into(out)
    }
}
