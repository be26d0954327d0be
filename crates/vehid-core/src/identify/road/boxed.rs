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

    fn params_into(&self, out: &mut [T]) -> Result<()> {
        self.0.params_into(out)
    }

    fn samples(&self) -> u64 {
        self.0.samples()
    }

    fn covariance_into(&self, out: &mut [T]) -> Result<()> {
        self.0.covariance_into(out)
    }

    fn noise_into(&self, out: &mut [T]) -> Result<()> {
        self.0.noise_into(out)
    }

    fn residuals_into(&self, ssr: &mut [T], nobs: &mut [T]) -> Result<()> {
        self.0.residuals_into(ssr, nobs)
    }

    fn groups_into(&self, group_of_param: &mut [usize], group_of_eq: &mut [usize]) -> Result<()> {
        self.0.groups_into(group_of_param, group_of_eq)
    }

    fn trace(&self) -> Option<T> {
        self.0.trace()
    }

    fn reinit_count(&self) -> u32 {
        self.0.reinit_count()
    }

    fn reset_covariance(&mut self, p0: T) -> Result<()> {
        self.0.reset_covariance(p0)
    }

    fn gated_into(&self, out: &mut [u64]) -> Result<()> {
        self.0.gated_into(out)
    }

    fn skip_sample(&mut self) {
        self.0.skip_sample()
    }
}
