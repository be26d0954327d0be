use nalgebra::RealField;

/// The scalar types vehid computes in: `f32` and `f64`.
///
/// A thin extension of [`nalgebra::RealField`] with exact conversions from and to `f64`, so
/// that constants and seeded noise (always drawn in `f64`) are the same numbers in both
/// precisions.
pub trait Real: RealField + Copy + Default + core::fmt::Debug + Send + Sync + Stored + 'static {
    /// Converts an `f64` constant (rounding to nearest for `f32`).
    fn of(x: f64) -> Self;
    /// Converts to `f64` (exact for both implementations).
    fn to_f64(self) -> f64;
    /// `true` when the value is neither NaN nor infinite.
    fn finite(self) -> bool {
        self.to_f64().is_finite()
    }
    /// The largest finite value.
    fn biggest() -> Self;
}

impl Real for f64 {
    #[inline(always)]
    fn biggest() -> Self {
        f64::MAX
    }
    #[inline(always)]
    fn of(x: f64) -> Self {
        x
    }
    #[inline(always)]
    fn to_f64(self) -> f64 {
        self
    }
}

impl Real for f32 {
    #[inline(always)]
    fn biggest() -> Self {
        f32::MAX
    }
    #[inline(always)]
    fn of(x: f64) -> Self {
        x as f32
    }
    #[inline(always)]
    fn to_f64(self) -> f64 {
        self as f64
    }
}

/// What a scalar needs for the serialized states (feature `serde`): serde both ways, so that
/// every type generic over [`Real`] serializes and every identifier is `Persist` without a
/// bound of its own; nothing without the feature. Implemented for every type that qualifies.
#[cfg(feature = "serde")]
pub trait Stored: serde::Serialize + serde::de::DeserializeOwned {}
#[cfg(feature = "serde")]
impl<X: serde::Serialize + serde::de::DeserializeOwned> Stored for X {}

/// What a scalar needs for the serialized states (nothing without the `serde` feature).
#[cfg(not(feature = "serde"))]
pub trait Stored {}
#[cfg(not(feature = "serde"))]
impl<X> Stored for X {}
