//! Serialization (feature `serde`): the helpers serde's derive needs for vehid's types, and
//! the checked `Serialize`/`Deserialize` of every identifier.
//!
//! The types derive their serde code, so a field added later is serialized with no change
//! here. What derive cannot write itself is done by field helpers (`#[serde(with = …)]`):
//! - [`array`], [`array2`], [`array3`]: arrays of a generic length (`[X; L]`, `[[X; L]; M]`,
//!   `[[[X; L]; M]; P]`), written as one flat tuple and read back without allocating;
//! - [`flat`]: a store buffer ([`Flat`]: an array, or a `Vec` with `alloc`), as a sequence;
//! - [`ring`]: a ring buffer ([`RingStore`]), as a sequence;
//! - [`transient`]: a scratch buffer whose content never outlives one update: written as
//!   nothing, read back empty, and sized again by its owner.
//!
//! An identifier whose update code relies on invariants it does not check (buffer lengths
//! agreeing with the number of rows, lanes holding the rows they claim, a ring as long as the
//! delay) derives with `#[serde(remote = "Self")]`: the derive then writes inherent
//! `serialize`/`deserialize` functions, and the trait implementations here ([`checked!`])
//! call them and then the type's `restored` check. So a corrupt input is a serde error,
//! never a panic later. (Deserialize through the trait: `postcard::from_bytes`,
//! `serde_json::from_str`, `<T as Deserialize>::deserialize`; the inherent function does not
//! check.)

use crate::identify::Flat;
use crate::sampler::RingStore;
use core::fmt;
use core::marker::PhantomData;
use serde::de::{self, Deserialize, Deserializer, SeqAccess, Visitor};
use serde::ser::{Serialize, SerializeTuple, Serializer};

/// Writes `v` as a tuple of `v.len()` values.
fn write_leaves<X: Serialize, S: Serializer>(v: &[X], s: S) -> Result<S::Ok, S::Error> {
    let mut t = s.serialize_tuple(v.len())?;
    for x in v {
        t.serialize_element(x)?;
    }
    t.end()
}

/// `n values`, for serde's messages.
struct Values(usize);

impl de::Expected for Values {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{} values", self.0)
    }
}

/// Reads a tuple of exactly `out.len()` values into `out`.
fn read_leaves<'de, X: Deserialize<'de>, D: Deserializer<'de>>(d: D, out: &mut [X]) -> Result<(), D::Error> {
    struct Leaves<'a, X>(&'a mut [X]);

    impl<'de, X: Deserialize<'de>> Visitor<'de> for Leaves<'_, X> {
        type Value = ();

        fn expecting(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
            write!(f, "a tuple of {} values", self.0.len())
        }

        fn visit_seq<A: SeqAccess<'de>>(self, mut seq: A) -> Result<(), A::Error> {
            let len = self.0.len();
            for (i, slot) in self.0.iter_mut().enumerate() {
                *slot = seq.next_element()?.ok_or_else(|| de::Error::invalid_length(i, &Values(len)))?;
            }
            Ok(())
        }
    }

    let len = out.len();
    d.deserialize_tuple(len, Leaves(out))
}

/// `[X; L]` as a tuple of `L` values.
pub(crate) mod array {
    use super::*;

    pub(crate) fn serialize<X: Serialize, S: Serializer, const L: usize>(v: &[X; L], s: S) -> Result<S::Ok, S::Error> {
        write_leaves(v, s)
    }

    pub(crate) fn deserialize<'de, X, D, const L: usize>(d: D) -> Result<[X; L], D::Error>
    where
        X: Deserialize<'de> + Copy + Default,
        D: Deserializer<'de>,
    {
        let mut out = [X::default(); L];
        read_leaves(d, &mut out)?;
        Ok(out)
    }
}

/// `[[X; L]; M]` as one tuple of `M·L` values (row-major).
pub(crate) mod array2 {
    use super::*;

    pub(crate) fn serialize<X: Serialize, S: Serializer, const L: usize, const M: usize>(
        v: &[[X; L]; M],
        s: S,
    ) -> Result<S::Ok, S::Error> {
        write_leaves(v.as_flattened(), s)
    }

    pub(crate) fn deserialize<'de, X, D, const L: usize, const M: usize>(d: D) -> Result<[[X; L]; M], D::Error>
    where
        X: Deserialize<'de> + Copy + Default,
        D: Deserializer<'de>,
    {
        let mut out = [[X::default(); L]; M];
        read_leaves(d, out.as_flattened_mut())?;
        Ok(out)
    }
}

/// `[[[X; L]; M]; P]` as one tuple of `P·M·L` values (row-major).
pub(crate) mod array3 {
    use super::*;

    pub(crate) fn serialize<X: Serialize, S: Serializer, const L: usize, const M: usize, const P: usize>(
        v: &[[[X; L]; M]; P],
        s: S,
    ) -> Result<S::Ok, S::Error> {
        write_leaves(v.as_flattened().as_flattened(), s)
    }

    pub(crate) fn deserialize<'de, X, D, const L: usize, const M: usize, const P: usize>(
        d: D,
    ) -> Result<[[[X; L]; M]; P], D::Error>
    where
        X: Deserialize<'de> + Copy + Default,
        D: Deserializer<'de>,
    {
        let mut out = [[[X::default(); L]; M]; P];
        read_leaves(d, out.as_flattened_mut().as_flattened_mut())?;
        Ok(out)
    }
}

/// A store buffer ([`Flat`]) as a sequence of its elements.
pub(crate) mod flat {
    use super::*;

    pub(crate) fn serialize<X: Serialize, F: Flat<X>, S: Serializer>(v: &F, s: S) -> Result<S::Ok, S::Error> {
        s.collect_seq(v.flat())
    }

    pub(crate) fn deserialize<'de, X: Deserialize<'de>, F: Flat<X>, D: Deserializer<'de>>(d: D) -> Result<F, D::Error> {
        struct Buffer<X, F>(PhantomData<(X, F)>);

        impl<'de, X: Deserialize<'de>, F: Flat<X>> Visitor<'de> for Buffer<X, F> {
            type Value = F;

            fn expecting(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
                f.write_str("a sequence of a store buffer's elements")
            }

            fn visit_seq<A: SeqAccess<'de>>(self, mut seq: A) -> Result<F, A::Error> {
                let items = core::iter::from_fn(|| seq.next_element::<X>().transpose());
                F::from_items(items)?.ok_or_else(|| {
                    de::Error::custom("a buffer whose length does not fit its fixed store (or an empty one)")
                })
            }
        }

        d.deserialize_seq(Buffer(PhantomData))
    }
}

/// A store buffer that only holds scratch copies between updates (e.g. the filters before
/// the current update): written empty when the store can be empty (a `Vec`), so that the
/// serialized state does not depend on what the last update, accepted or refused, left
/// there; its owner refills it on load. A fixed array store is written in full.
pub(crate) mod scratch {
    use super::*;

    pub(crate) fn serialize<X: Serialize, F: Flat<X>, S: Serializer>(v: &F, s: S) -> Result<S::Ok, S::Error> {
        let can_be_empty = matches!(F::from_items(core::iter::empty::<Result<X, ()>>()), Ok(Some(_)));
        if can_be_empty {
            s.collect_seq(core::iter::empty::<&X>())
        } else {
            s.collect_seq(v.flat())
        }
    }

    pub(crate) use super::flat::deserialize;
}

/// A ring buffer ([`RingStore`]) as a sequence of its slots.
pub(crate) mod ring {
    use super::*;

    pub(crate) fn serialize<X: Serialize, B: RingStore<X>, S: Serializer>(v: &B, s: S) -> Result<S::Ok, S::Error> {
        s.collect_seq(v.slots())
    }

    pub(crate) fn deserialize<'de, X, B, D>(d: D) -> Result<B, D::Error>
    where
        X: Deserialize<'de>,
        B: RingStore<X>,
        D: Deserializer<'de>,
    {
        struct Ring<X, B>(PhantomData<(X, B)>);

        impl<'de, X: Deserialize<'de>, B: RingStore<X>> Visitor<'de> for Ring<X, B> {
            type Value = B;

            fn expecting(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
                f.write_str("a sequence of a ring buffer's slots")
            }

            fn visit_seq<A: SeqAccess<'de>>(self, mut seq: A) -> Result<B, A::Error> {
                let items = core::iter::from_fn(|| seq.next_element::<X>().transpose());
                B::from_items(items)?
                    .ok_or_else(|| de::Error::custom("a ring whose length does not fit its capacity (or an empty one)"))
            }
        }

        d.deserialize_seq(Ring(PhantomData))
    }
}

/// A scratch buffer: its content never outlives one update, so it is written as nothing
/// (a unit) and read back empty; the owner's `restored` check sizes it again.
pub(crate) mod transient {
    use super::*;

    pub(crate) fn serialize<X, F: Flat<X>, S: Serializer>(_: &F, s: S) -> Result<S::Ok, S::Error> {
        s.serialize_unit()
    }

    pub(crate) fn deserialize<'de, X, F: Flat<X>, D: Deserializer<'de>>(d: D) -> Result<F, D::Error> {
        <()>::deserialize(d)?;
        F::from_items(core::iter::empty::<Result<X, D::Error>>())?
            .ok_or_else(|| de::Error::custom("a scratch buffer that cannot be empty"))
    }
}

/// A count that must not exceed `MAX` (e.g. the lanes in use of a group of `MAX` lanes).
pub(crate) fn at_most<'de, D: Deserializer<'de>, const MAX: usize>(d: D) -> Result<usize, D::Error> {
    let v = usize::deserialize(d)?;
    if v > MAX {
        return Err(de::Error::invalid_value(de::Unexpected::Unsigned(v as u64), &"a count within the capacity"));
    }
    Ok(v)
}

/// The message of a deserialized value that fails its type's check.
struct Invalid {
    what: &'static str,
    error: crate::Error,
}

impl fmt::Display for Invalid {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "not a valid {} ({}): the input is corrupt or from another version", self.what, self.error)
    }
}

/// `Serialize` and `Deserialize` for a type that derives them with `#[serde(remote = "Self")]`
/// and has `fn restored(&mut self) -> crate::Result<()>` (checks, and rebuilds what is not
/// stored): the traits call the derived inherent functions, then the check.
macro_rules! checked {
    ($what:literal, [$($g:tt)*] $ty:ty, ser: [$($sb:tt)*], de: [$($db:tt)*]) => {
        impl<$($g)*> Serialize for $ty
        where
            $($sb)*
        {
            fn serialize<Z: Serializer>(&self, s: Z) -> Result<Z::Ok, Z::Error> {
                <$ty>::serialize(self, s)
            }
        }

        impl<'de, $($g)*> Deserialize<'de> for $ty
        where
            $($db)*
        {
            fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
                let mut v = <$ty>::deserialize(d)?;
                v.restored().map_err(|error| de::Error::custom(Invalid { what: $what, error }))?;
                Ok(v)
            }
        }
    };
}

mod impls {
    use super::{de, Deserialize, Deserializer, Invalid, Serialize, Serializer};
    use crate::identify::{GradientCore, KalmanFull, KalmanRows, KalmanShared, LsAccumulator, Past, Store, TwoAxle};
    use crate::model::{LinearModel, RowSet};
    use crate::sampler::RingStore;
    use crate::Real;

    checked!("row set", [const N: usize] RowSet<N>, ser: [], de: []);

    checked!("linear model", [T: Real, const N: usize, const M: usize] LinearModel<T, N, M>,
        ser: [T: Serialize], de: [T: crate::Real]);

    checked!("KalmanRows", [T: Real, const N: usize, S: Store<T, N>] KalmanRows<T, N, S>,
        ser: [T: Serialize, S::Group: Serialize],
        de: [T: crate::Real, S::Group: Deserialize<'de>]);

    checked!("KalmanShared", [T: Real, const N: usize, S: Store<T, N>] KalmanShared<T, N, S>,
        ser: [T: Serialize], de: [T: crate::Real]);

    checked!("KalmanFull", [T: Real, const N: usize, S: Store<T, N>] KalmanFull<T, N, S>,
        ser: [T: Serialize], de: [T: crate::Real]);

    checked!("StochasticGradient", [T: Real, const N: usize, S: Store<T, N>] GradientCore<T, N, S>,
        ser: [T: Serialize], de: [T: crate::Real]);

    checked!("LsAccumulator", [T: Real, const N: usize, S: Store<T, N>] LsAccumulator<T, N, S>,
        ser: [T: Serialize], de: [T: crate::Real]);

    #[cfg(feature = "std")]
    checked!("BatchLeastSquares", [T: Real, const N: usize] crate::identify::BatchLeastSquares<T, N>,
        ser: [T: Serialize], de: [T: crate::Real]);

    checked!("Structure", [T: Real] crate::structure::Structure<T>,
        ser: [T: Serialize], de: [T: crate::Real]);

    // `Structured` keeps its filters in lanes while its fast path is live: what is written is
    // the identifier with its filters up to date (`settled`), so the format is the same.
    impl<T: Real, const P: usize, F: crate::identify::Flat<crate::identify::RowIdentifier<T, P>>> Serialize
        for crate::identify::Structured<T, P, F>
    where
        T: Serialize,
    {
        fn serialize<Z: Serializer>(&self, s: Z) -> Result<Z::Ok, Z::Error> {
            match self.settled() {
                Some(now) => Self::serialize(&now, s),
                None => Self::serialize(self, s),
            }
        }
    }

    impl<'de, T: Real, const P: usize, F: crate::identify::Flat<crate::identify::RowIdentifier<T, P>>> Deserialize<'de>
        for crate::identify::Structured<T, P, F>
    {
        fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
            let mut v = Self::deserialize(d)?;
            v.restored().map_err(|error| de::Error::custom(Invalid { what: "Structured", error }))?;
            Ok(v)
        }
    }

    checked!("StructuredGradient", [T: Real, const P: usize] crate::identify::StructuredGradient<T, P>,
        ser: [T: Serialize], de: [T: crate::Real]);

    checked!("IvFilter", [T: Real, const P: usize] crate::identify::IvFilter<T, P>,
        ser: [T: Serialize], de: [T: crate::Real]);

    checked!("IV predictor", [T: Real, const Q: usize] crate::identify::iv_predictor::Predictor<T, Q>,
        ser: [T: Serialize], de: [T: crate::Real]);

    checked!("InstrumentalVariables",
        [T: Real, const P: usize, F: crate::identify::Flat<crate::identify::IvFilter<T, P>>, const Q: usize]
        crate::identify::InstrumentalVariables<T, P, F, Q>,
        ser: [T: Serialize], de: [T: crate::Real]);

    checked!("ModelInstruments",
        [T: Real, const P: usize, F: crate::identify::Flat<crate::identify::IvFilter<T, P>>]
        crate::identify::ModelInstruments<T, P, F>,
        ser: [T: Serialize], de: [T: crate::Real]);

    checked!("BiasCompensated",
        [T: Real, const P: usize, F: crate::identify::Flat<crate::identify::BcGroup<T, P>>]
        crate::identify::BiasCompensated<T, P, F>,
        ser: [T: Serialize], de: [T: crate::Real]);

    checked!("NoiseEstimatingBcls",
        [T: Real, const P: usize, F: crate::identify::Flat<crate::identify::BcGroup<T, P>>,
         FI: crate::identify::Flat<crate::identify::IvFilter<T, P>>, const Q: usize]
        crate::identify::NoiseEstimatingBcls<T, P, F, FI, Q>,
        ser: [T: Serialize], de: [T: crate::Real]);

    checked!("HealthMonitor", [T: Real] crate::health::HealthMonitor<T>,
        ser: [T: Serialize], de: [T: crate::Real]);

    checked!("HalfHealthMonitor", [T: Real] crate::health::HalfHealthMonitor<T>,
        ser: [T: Serialize], de: [T: crate::Real]);

    checked!("FullHealthMonitor", [T: Real] crate::health::FullHealthMonitor<T>,
        ser: [T: Serialize], de: [T: crate::Real]);

    checked!("TwoAxle",
        [T: Real, const N: usize, const P: usize, S: Store<T, N>, B: RingStore<Past<T, N>>, const M: usize]
        TwoAxle<T, N, P, S, B, M>,
        ser: [T: Serialize, S::Group: Serialize],
        de: [T: crate::Real, S::Group: Deserialize<'de>]);

    checked!("JointEkf", [T: Real, const N: usize, const DIM: usize] crate::identify::JointEkf<T, N, DIM>,
        ser: [T: Serialize], de: [T: crate::Real]);

    checked!("Differenced", [T: Real, I: crate::identify::Identifier<T>] crate::identify::Differenced<T, I>,
        ser: [T: Serialize, I: Serialize], de: [T: crate::Real, I: Deserialize<'de>]);

    checked!("TwoAxleStructured",
        [T: Real, const P: usize, F: crate::identify::Flat<crate::identify::RowIdentifier<T, P>>,
         B: RingStore<crate::identify::FrontRegression<T, P>>]
        crate::identify::TwoAxleStructured<T, P, F, B>,
        ser: [T: Serialize], de: [T: crate::Real]);
}

#[cfg(test)]
mod tests;
