//! The AVX2 copy of an identifier's update and its run-time dispatch (`avx2_step!`, used by
//! the rows and shared forms).

/// Gives an identifier with an `#[inline(always)] fn step(&mut self, x, z, e) -> Result<()>`
/// its AVX2 copy `step_avx2` and `dispatch`, which runs that copy when `$wide` (a constant
/// expression of the identifier's parameters: where it measured faster) and the CPU has AVX2
/// (x86-64 with `std`), else the portable `step`. Both copies compute the same bits (no FMA,
/// fixed summation order; tested). `$wide` is tested in a `const` block, so that the AVX2
/// copy is not even compiled for the identifiers that never take it.
macro_rules! avx2_step {
    ($wide:expr) => {
        /// [`Self::step`] compiled for AVX2 (same arithmetic, wider registers).
        #[cfg(all(feature = "std", target_arch = "x86_64"))]
        #[target_feature(enable = "avx2")]
        fn step_avx2(&mut self, x: &SVector<T, N>, z: &SVector<T, N>, e: &mut [T]) -> Result<()> {
            self.step(x, z, e)
        }

        /// Runs [`Self::step`] in its AVX2 copy when wide and the CPU has AVX2, else portable.
        #[inline(always)]
        fn dispatch(&mut self, x: &SVector<T, N>, z: &SVector<T, N>, e: &mut [T]) -> Result<()> {
            #[cfg(all(feature = "std", target_arch = "x86_64"))]
            if const { $wide } && crate::simd::avx2() {
                // SAFETY: the CPU supports AVX2 (checked at run time by `simd::avx2`).
                return unsafe { self.step_avx2(x, z, e) };
            }
            self.step(x, z, e)
        }
    };
}
