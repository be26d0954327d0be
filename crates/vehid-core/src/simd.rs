//! Run-time choice of vector instructions for the per-sample Kalman updates.
//!
//! On x86-64 with the `std` feature, [`crate::identify::KalmanRows`] and
//! [`crate::identify::KalmanShared`] run their update in a copy compiled for AVX2 when the
//! CPU has it (checked once, then cached by the standard library) and the model is wide
//! enough for it to pay, as measured: row groups that fill a 256-bit register (four `f64`
//! rows: the half car, the heap forms with four lanes) and the shared form for more than four
//! `f64` states. Otherwise (narrower models, other architectures, `no_std`, or after
//! [`set_vector_extensions`]`(false)`) they run the portable build, which uses whatever the
//! compile target enables (SSE2 on plain x86-64, NEON on aarch64; `-C target-cpu=native`
//! gives more).
//!
//! The choice never changes a result: the kernels use no fused multiply-add and sum in a
//! fixed order, so every path computes bit-identical estimates (tested).

#[cfg(all(feature = "std", target_arch = "x86_64"))]
static DISABLED: core::sync::atomic::AtomicBool = core::sync::atomic::AtomicBool::new(false);

/// Allows (`true`, the default) or forbids (`false`) the AVX2 path for the whole process;
/// useful to compare the two builds. A no-op where there is no run-time choice.
pub fn set_vector_extensions(enabled: bool) {
    #[cfg(all(feature = "std", target_arch = "x86_64"))]
    DISABLED.store(!enabled, core::sync::atomic::Ordering::Relaxed);
    #[cfg(not(all(feature = "std", target_arch = "x86_64")))]
    let _ = enabled;
}

/// The path the updates take now: `"avx2"` or `"portable"`.
pub fn vector_extensions() -> &'static str {
    if avx2() {
        "avx2"
    } else {
        "portable"
    }
}

/// `true` when the AVX2 copy of the updates is to be used.
#[inline(always)]
pub(crate) fn avx2() -> bool {
    #[cfg(all(feature = "std", target_arch = "x86_64"))]
    {
        !DISABLED.load(core::sync::atomic::Ordering::Relaxed) && std::is_x86_feature_detected!("avx2")
    }
    #[cfg(not(all(feature = "std", target_arch = "x86_64")))]
    {
        false
    }
}
