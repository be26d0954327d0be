//! A boxed identifier as an [`Identifier`] (requires `alloc`): what [`Differenced`] wraps
//! when the identifier is chosen at run time.

use super::*;

/// A boxed identifier as an [`Identifier`] (requires `alloc`): what [`Differenced`] wraps
/// when the identifier is chosen at run time (the Python bindings).
#[cfg(feature = "alloc")]
#[derive(Debug)]
pub struct BoxedIdentifier<T: Real>(pub alloc::boxed::Box<dyn crate::identify::DynIdentifier<T>>);

#[cfg(feature = "alloc")]
impl<T: Real> Clone for BoxedIdentifier<T> {
    fn clone(&self) -> Self {
        Self(self.0.clone_box())
    }
}

#[cfg(feature = "alloc")]
impl<T: Real> crate::identify::Persist for BoxedIdentifier<T> {
    #[cfg(feature = "persist")]
    fn save_state(&self) -> Result<alloc::vec::Vec<u8>> {
        self.0.save_state()
    }

    #[cfg(feature = "persist")]
    fn load_state(&mut self, bytes: &[u8]) -> Result<()> {
        self.0.load_state(bytes)
    }
}

#[cfg(feature = "alloc")]
impl<T: Real> Identifier<T> for BoxedIdentifier<T> {
    fn dims(&self) -> Dims {
        self.0.dims()
    }

    fn rows(&self) -> &[usize] {
        self.0.rows()
    }

    fn update_into(&mut self, x: &[T], z: &[T], u: &[T], e: &mut [T]) -> Result<()> {
        self.0.update_into(x, z, u, e)
    }

    super::super::interface::forward_estimate!(0);

    fn samples(&self) -> u64 {
        self.0.samples()
    }

    fn gated_into(&self, out: &mut [u64]) -> Result<()> {
        self.0.gated_into(out)
    }

    fn skip_sample(&mut self) {
        self.0.skip_sample()
    }
}
