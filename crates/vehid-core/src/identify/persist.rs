//! Saving and restoring an identifier through its boxed interface: [`Persist`].
//!
//! With the `persist` feature, every identifier of this crate writes its whole state as bytes
//! ([`Persist::save_state`]: postcard, the `serde` feature's encoding of the concrete type)
//! and reads such bytes back into an identifier of its own type
//! ([`Persist::load_state`]), so that code holding a `Box<dyn DynIdentifier<T>>` saves and
//! restores it without knowing, or recovering, its type: restoring is "build the identifier
//! from its settings, then load the state". The bytes hold no type tag; what was saved from
//! one type is read by the same type (a caller that keeps its settings beside the bytes, as
//! the Python bindings do, guarantees it). Loading is all or nothing: bytes that do not
//! decode, fail the type's own checks (the `restored` checks of `crate::persist`), or
//! describe an identifier of other sizes or rows are an error, and the identifier is
//! unchanged.
//!
//! A new identifier type gets both methods from one line, `persist_by_serde!` below, beside
//! its `impl Identifier`. An identifier written outside this crate implements [`Persist`] with
//! an empty block (`impl Persist for MyId {}`): it can then be boxed, and saving it is
//! [`Error::Unsupported`].

#[cfg(feature = "persist")]
use crate::{Error, Result};

/// Saving and restoring the state of an identifier held as a [`super::DynIdentifier`]
/// (methods with the `persist` feature; see the module documentation).
pub trait Persist {
    /// The whole state as bytes (postcard of the concrete type).
    ///
    /// # Errors
    /// [`Error::Unsupported`] for an identifier that does not implement it (the default);
    /// [`Error::OutOfMemory`] when the bytes cannot be written.
    #[cfg(feature = "persist")]
    fn save_state(&self) -> Result<alloc::vec::Vec<u8>> {
        Err(Error::Unsupported { what: "saving the state (this identifier does not implement Persist)" })
    }

    /// Replaces the state by one saved by [`Persist::save_state`] from an identifier of the
    /// same type, sizes and rows. All or nothing.
    ///
    /// # Errors
    /// [`Error::InvalidArgument`] (`arg` "state") when the bytes do not decode, fail the
    /// type's checks, or are of an identifier of other sizes or rows;
    /// [`Error::Unsupported`] for an identifier that does not implement it (the default).
    #[cfg(feature = "persist")]
    fn load_state(&mut self, bytes: &[u8]) -> Result<()> {
        let _ = bytes;
        Err(Error::Unsupported { what: "restoring the state (this identifier does not implement Persist)" })
    }
}

/// `value` as postcard bytes.
#[cfg(feature = "persist")]
pub(crate) fn save<V: serde::Serialize>(value: &V) -> Result<alloc::vec::Vec<u8>> {
    postcard::to_allocvec(value).map_err(|_| Error::OutOfMemory { what: "the saved state", bytes: usize::MAX })
}

/// The error of bytes that are not a state this identifier can take.
#[cfg(feature = "persist")]
pub(crate) const NOT_ITS_STATE: Error = Error::InvalidArgument {
    arg: "state",
    expected: "bytes saved by save_state from an identifier of the same type, sizes and rows (these do not \
               decode, fail its checks, or describe another identifier)",
};

/// Replaces `this` by the identifier `bytes` decode to, when that has the same sizes and rows.
#[cfg(feature = "persist")]
pub(crate) fn load<T, I>(this: &mut I, bytes: &[u8]) -> Result<()>
where
    T: crate::Real,
    I: super::Identifier<T> + serde::de::DeserializeOwned,
{
    let back: I = postcard::from_bytes(bytes).map_err(|_| NOT_ITS_STATE)?;
    if back.dims() != this.dims() || back.rows() != this.rows() {
        return Err(NOT_ITS_STATE);
    }
    *this = back;
    Ok(())
}

/// [`Persist`] for an identifier type through its serde implementation:
/// `persist_by_serde!([generics] Type)`, the generics as in its `impl Identifier<T>` (which
/// must name the scalar `T`). Without the `persist` feature, an empty implementation.
macro_rules! persist_by_serde {
    ([$($g:tt)*] $ty:ty) => {
        #[cfg(not(feature = "persist"))]
        impl<$($g)*> $crate::identify::Persist for $ty {}

        #[cfg(feature = "persist")]
        impl<$($g)*> $crate::identify::Persist for $ty
        where
            Self: $crate::identify::Identifier<T> + serde::Serialize + serde::de::DeserializeOwned,
        {
            fn save_state(&self) -> $crate::Result<alloc::vec::Vec<u8>> {
                $crate::identify::persist::save(self)
            }

            fn load_state(&mut self, bytes: &[u8]) -> $crate::Result<()> {
                $crate::identify::persist::load(self, bytes)
            }
        }
    };
}
pub(crate) use persist_by_serde;

#[cfg(all(test, feature = "persist"))]
mod tests {
    use crate::identify::*;
    use crate::model::QuarterCar;
    use crate::sim::{SimConfig, Simulator};
    use crate::structure::Structure;
    use alloc::boxed::Box;
    use alloc::vec;
    use alloc::vec::Vec;

    /// Quarter-car samples: (state, derivative), thesis car, white road.
    fn samples(n: usize, seed: u64) -> Vec<(Vec<f64>, Vec<f64>)> {
        let cfg = SimConfig::new(0.05).road_sigma(0.1).ic_sigma(0.1).deriv_noise(0.005);
        let mut sim = Simulator::new(QuarterCar::thesis().model(), cfg, seed).unwrap();
        (0..n).map(|_| sim.next_sample()).map(|s| (s.r.as_slice().to_vec(), s.z.as_slice().to_vec())).collect()
    }

    fn kalman(rows: &[usize], mode: Mode, exact: bool) -> Box<dyn DynIdentifier<f64>> {
        let spec = KalmanSpec {
            rows: rows.to_vec(),
            p0: if exact { Prior::Exact } else { Prior::PerRow(vec![30.0]) },
            theta0: None,
            r: vec![1e-4],
            mode,
            opts: KalmanOptions::default(),
        };
        boxed_kalman::<f64, 4>(&spec).unwrap()
    }

    fn iv() -> Box<dyn DynIdentifier<f64>> {
        let s = Structure::full_rows(4, &[1, 3]).unwrap();
        Box::new(IvIdentifierVec::<f64, 4>::new(s, 3, StructuredPrior::Exact, None, &[1e-4]).unwrap())
    }

    type Build = fn() -> Box<dyn DynIdentifier<f64>>;

    /// What the identifier reports, as bits.
    fn state_bits(id: &dyn DynIdentifier<f64>) -> (Vec<u64>, u64) {
        let mut th = vec![0.0; id.dims().params];
        id.params_into(&mut th).unwrap();
        (th.iter().map(|v| v.to_bits()).collect(), id.samples())
    }

    fn feed(id: &mut dyn DynIdentifier<f64>, data: &[(Vec<f64>, Vec<f64>)]) {
        let mut e = vec![0.0; id.dims().equations];
        for (x, z) in data {
            id.update_into(x, z, &[], &mut e).unwrap();
        }
    }

    /// Saved after 300 samples through the boxed interface and loaded into a fresh identifier
    /// built the same way, it continues bit for bit.
    #[test]
    fn a_boxed_identifier_saves_and_loads_without_its_type() {
        let data = samples(600, 11);
        let builds: [(&str, Build); 5] = [
            ("rows, two lanes", || kalman(&[1, 3], Mode::Rows, true)),
            ("rows, four lanes", || kalman(&[0, 1, 2, 3], Mode::Rows, true)),
            ("shared", || kalman(&[1, 3], Mode::Shared, false)),
            ("full", || kalman(&[1, 3], Mode::Full, false)),
            ("instrumental variables", iv),
        ];
        for (what, build) in builds {
            let mut a = build();
            feed(a.as_mut(), &data[..300]);
            let bytes = a.save_state().unwrap();
            let mut b = build();
            b.load_state(&bytes).unwrap();
            assert_eq!(state_bits(b.as_ref()), state_bits(a.as_ref()), "{what}");
            feed(a.as_mut(), &data[300..]);
            feed(b.as_mut(), &data[300..]);
            assert_eq!(state_bits(b.as_ref()), state_bits(a.as_ref()), "{what}");
            assert_eq!(b.save_state().unwrap(), a.save_state().unwrap(), "{what}");
        }
    }

    /// The state of another type, of other rows, or cut short is refused and changes nothing.
    #[test]
    fn a_foreign_or_cut_state_is_refused_and_changes_nothing() {
        let data = samples(200, 12);
        let mut two = kalman(&[1, 3], Mode::Rows, true);
        feed(two.as_mut(), &data);
        let before = two.save_state().unwrap();
        let mut other_rows = kalman(&[0, 2], Mode::Rows, true);
        feed(other_rows.as_mut(), &data);
        let mut shared = kalman(&[1, 3], Mode::Shared, false);
        feed(shared.as_mut(), &data);
        let foreign = [
            other_rows.save_state().unwrap(),
            shared.save_state().unwrap(),
            iv().save_state().unwrap(),
            before[..before.len() - 1].to_vec(),
            Vec::new(),
        ];
        for bytes in &foreign {
            assert!(two.load_state(bytes).is_err());
            assert_eq!(two.save_state().unwrap(), before);
        }
    }

    /// The coloured-road wrapper saves its road state with the inner identifier's, and takes
    /// back only a state of the same road model.
    #[test]
    fn the_road_wrapper_saves_its_state_and_its_inner_identifiers() {
        let data = samples(400, 13);
        let s = Structure::full_rows(4, &[1, 3]).unwrap();
        let wrap = |road| Differenced::new(BoxedIdentifier(iv()), &s, road, Travel::PerSample(0.5)).unwrap();
        let mut a = wrap(RoadModel::RandomWalk);
        let mut e = vec![0.0; 2];
        for (x, z) in &data[..200] {
            a.update_into(x, z, &[], &mut e).unwrap();
        }
        let bytes = a.save_state().unwrap();
        let mut b = wrap(RoadModel::RandomWalk);
        b.load_state(&bytes).unwrap();
        assert_eq!(b.state(), a.state());
        let mut shaped = wrap(RoadModel::Shaped { cutoff: 0.01 });
        let fresh = shaped.save_state().unwrap();
        assert!(shaped.load_state(&bytes).is_err());
        assert_eq!(shaped.save_state().unwrap(), fresh);
        let (mut ea, mut eb) = (vec![0.0; 2], vec![0.0; 2]);
        for (x, z) in &data[200..] {
            a.update_into(x, z, &[], &mut ea).unwrap();
            b.update_into(x, z, &[], &mut eb).unwrap();
            assert_eq!(ea, eb);
        }
    }
}
