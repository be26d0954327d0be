//! Pickling and copying of identifiers.
//!
//! An identifier pickles as `copyreg.__newobj_ex__(cls, args, kwargs)` plus a state:
//! `args`/`kwargs` build a fresh object of the same class and settings (the model, and for
//! `KalmanIdentifier` its mode and form, for `StochasticGradient` its gain, for
//! `TwoAxleIdentifier` its spacing, method and wheelbase (on a Structure also its `car` and
//! `compensate`), for `IVIdentifier` its delay and lags; `BiasCompensated` is built with a
//! zero noise covariance (or, estimating it, with its instruments) and `JointEKF` as a placeholder filter of the same sizes, which the
//! saved core replaces), and `__setstate__` then replaces its core by the saved one. That works with
//! every pickle protocol (0–5).
//!
//! The state is the tuple `(FORMAT, "vehid <version>", payload)`: the payload is postcard
//! (vehid-core's `serde` feature) of [`Saved`]: which concrete core type the identifier holds
//! (the binding chose it at construction), the model, and the core's own postcard bytes,
//! sealed with a CRC-32 (`seal.rs`: a changed, cut or appended byte is refused).
//! Loading checks the format version first, then decodes (the core validates itself: a
//! corrupt payload is an error, never a later panic), then checks that the core fits the
//! class and the model of the object it goes into.

use crate::dispatch::{dispatch_n, ModelData};
use crate::guard::{borrow, borrow_mut};
use crate::identify::{PyBatchLeastSquares, PyIdentifier, PyKalmanIdentifier, PyStochasticGradient};
use crate::joint_ekf::{PyJointEKF, EKF_STATES};
use crate::model::{Kind, PyLinearModel};
use crate::noisy::{PyBiasCompensated, PyIVIdentifier, PREDICTOR};
use crate::two_axle::PyTwoAxleIdentifier;
use crate::VehidError;
use pyo3::prelude::*;
use pyo3::types::{PyBytes, PyDict, PyTuple};
use serde::{Deserialize, Serialize};
use vehid_core::identify::{
    BatchLeastSquares, BiasCompensatedVec, DynIdentifier, Dynamic, IvIdentifierVec, JointEkf, KalmanFull, KalmanRows,
    KalmanShared, ModelIvIdentifierVec, NoiseEstimatingBclsVec, StochasticGradientVec, StructuredGradient,
    StructuredKalmanVec, TwoAxleIdentifierVec, TwoAxleStructuredVec,
};
use vehid_core::Error;

/// Version of the pickled state's layout. Raise it when the payload or any serialized core
/// type changes in a way older readers (or this reader, for older payloads) cannot follow.
/// 2: modes `shared` and `full` keep the outlier gate's statistics.
/// (`Core::Iv`, `Core::BiasCompensated`, `Core::JointEkf`, `Core::TwoAxleStructured`,
/// `Core::NoiseEstimating` and `Core::IvModel` were added within format 2: new variants at the end of [`Core`]
/// leave every older payload's encoding unchanged, so it still loads.)
/// 3: the payload and the road state carry a CRC-32 (`seal.rs`).
pub const FORMAT: u32 = 3;

/// The concrete core type behind a Python identifier. Serialized by variant index: a new
/// variant goes at the end (older payloads keep their meaning).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
enum Core {
    /// `KalmanRows` in groups of two lanes.
    Rows2,
    /// `KalmanRows` in groups of four lanes.
    Rows4,
    Shared,
    Full,
    Gradient,
    Batch,
    /// `TwoAxleIdentifierVec<f64, 8, 16>`.
    TwoAxle,
    /// `StructuredKalmanVec<f64, P>` (a `KalmanIdentifier` on a Structure), `P` its largest group.
    Structured(u8),
    /// `StructuredGradient<f64, P>` (a `StochasticGradient` on a Structure).
    StructuredGradient(u8),
    /// `IvIdentifierVec<f64, P, Q>` (an `IVIdentifier`, on a linear model's full rows or a
    /// Structure), `P` its largest group's bucket, `Q` its predictor's capacity (0 with
    /// `lags=0`, else `noisy::PREDICTOR`).
    Iv(u8, u8),
    /// `BiasCompensatedVec<f64, P>` (a `BiasCompensated`), `P` its largest group's bucket.
    BiasCompensated(u8),
    /// `JointEkf<f64, N, D>` (a `JointEKF`).
    JointEkf(u8, u8),
    /// `TwoAxleStructuredVec<f64, P>` (a `TwoAxleIdentifier` on a Structure).
    TwoAxleStructured(u8),
    /// `NoiseEstimatingBclsVec<f64, P, Q>` (a `BiasCompensated` with
    /// `state_noise_var="estimate"`), `P` and `Q` as for `Iv`.
    NoiseEstimating(u8, u8),
    /// `ModelIvIdentifierVec<f64, P>` (an `IVIdentifier` with `instruments="model"`), `P` as
    /// for `Iv`.
    IvModel(u8),
}

impl Core {
    fn mode(self) -> Option<&'static str> {
        match self {
            Core::Rows2 | Core::Rows4 => Some("rows"),
            Core::Shared => Some("shared"),
            Core::Full => Some("full"),
            _ => None,
        }
    }
}

/// What the state's payload holds.
#[derive(Serialize, Deserialize)]
struct Saved {
    core: Core,
    model: ModelData,
    state: Vec<u8>,
}

type TwoAxleCore = TwoAxleIdentifierVec<f64, 8, 16>;

fn encode<I: Serialize>(core: Core, id: &I) -> vehid_core::Result<Option<(Core, Vec<u8>)>> {
    postcard::to_allocvec(id)
        .map(|bytes| Some((core, bytes)))
        .map_err(|_| Error::OutOfMemory { what: "the pickled state", bytes: usize::MAX })
}

/// The core type and its bytes, for an `N`-state identifier (`None`: not a type this binding
/// builds).
fn save_n<const N: usize>(id: &dyn DynIdentifier<f64>) -> vehid_core::Result<Option<(Core, Vec<u8>)>> {
    let any = id.as_any();
    if let Some(x) = any.downcast_ref::<KalmanRows<f64, N, Dynamic<2>>>() {
        return encode(Core::Rows2, x);
    }
    if let Some(x) = any.downcast_ref::<KalmanRows<f64, N, Dynamic<4>>>() {
        return encode(Core::Rows4, x);
    }
    if let Some(x) = any.downcast_ref::<KalmanShared<f64, N, Dynamic>>() {
        return encode(Core::Shared, x);
    }
    if let Some(x) = any.downcast_ref::<KalmanFull<f64, N, Dynamic>>() {
        return encode(Core::Full, x);
    }
    if let Some(x) = any.downcast_ref::<StochasticGradientVec<f64, N>>() {
        return encode(Core::Gradient, x);
    }
    if let Some(x) = any.downcast_ref::<BatchLeastSquares<f64, N>>() {
        return encode(Core::Batch, x);
    }
    if let Some(x) = any.downcast_ref::<TwoAxleCore>() {
        return encode(Core::TwoAxle, x);
    }
    Ok(None)
}

/// The core type and its bytes of an identifier on a Structure (the sizes `P` the binding
/// builds: `structure.rs`).
fn save_structured(id: &dyn DynIdentifier<f64>) -> vehid_core::Result<Option<(Core, Vec<u8>)>> {
    let any = id.as_any();
    macro_rules! try_p {
        ($($p:literal),*) => {$(
            if let Some(x) = any.downcast_ref::<StructuredKalmanVec<f64, $p>>() {
                return encode(Core::Structured($p), x);
            }
            if let Some(x) = any.downcast_ref::<StructuredGradient<f64, $p>>() {
                return encode(Core::StructuredGradient($p), x);
            }
        )*};
    }
    try_p!(2, 4, 8, 16, 32);
    Ok(None)
}

/// The core type and its bytes of an `IVIdentifier` or a `BiasCompensated` (on a model or a
/// Structure; the sizes `P`, `Q` the binding builds: `noisy.rs`).
fn save_noisy(id: &dyn DynIdentifier<f64>) -> vehid_core::Result<Option<(Core, Vec<u8>)>> {
    let any = id.as_any();
    macro_rules! try_p {
        ($($p:literal),*) => {$(
            if let Some(x) = any.downcast_ref::<IvIdentifierVec<f64, $p, 0>>() {
                return encode(Core::Iv($p, 0), x);
            }
            if let Some(x) = any.downcast_ref::<IvIdentifierVec<f64, $p, PREDICTOR>>() {
                return encode(Core::Iv($p, PREDICTOR as u8), x);
            }
            if let Some(x) = any.downcast_ref::<BiasCompensatedVec<f64, $p>>() {
                return encode(Core::BiasCompensated($p), x);
            }
            if let Some(x) = any.downcast_ref::<NoiseEstimatingBclsVec<f64, $p, 0>>() {
                return encode(Core::NoiseEstimating($p, 0), x);
            }
            if let Some(x) = any.downcast_ref::<NoiseEstimatingBclsVec<f64, $p, PREDICTOR>>() {
                return encode(Core::NoiseEstimating($p, PREDICTOR as u8), x);
            }
            if let Some(x) = any.downcast_ref::<ModelIvIdentifierVec<f64, $p>>() {
                return encode(Core::IvModel($p), x);
            }
        )*};
    }
    try_p!(2, 4, 8, 16, 32);
    Ok(None)
}

/// The core type and its bytes of a `JointEKF` or of a `TwoAxleIdentifier` on a Structure
/// (the sizes the binding builds: `joint_ekf.rs`, `two_axle.rs`).
fn save_newer(id: &dyn DynIdentifier<f64>) -> vehid_core::Result<Option<(Core, Vec<u8>)>> {
    let any = id.as_any();
    const N: u8 = EKF_STATES as u8;
    macro_rules! try_d {
        ($($d:literal),*) => {$(
            if let Some(x) = any.downcast_ref::<JointEkf<f64, EKF_STATES, $d>>() {
                return encode(Core::JointEkf(N, $d), x);
            }
        )*};
    }
    try_d!(8, 9, 13);
    macro_rules! try_p {
        ($($p:literal),*) => {$(
            if let Some(x) = any.downcast_ref::<TwoAxleStructuredVec<f64, $p>>() {
                return encode(Core::TwoAxleStructured($p), x);
            }
        )*};
    }
    try_p!(4, 8, 16);
    Ok(None)
}

/// Decodes the core of a `JointEKF` or of a `TwoAxleIdentifier` on a Structure (`None`:
/// another kind, or sizes the binding does not build).
fn load_newer(core: Core, bytes: &[u8]) -> Option<Loaded> {
    const N: u8 = EKF_STATES as u8;
    Some(match core {
        Core::JointEkf(N, 8) => decode::<JointEkf<f64, EKF_STATES, 8>>(bytes),
        Core::JointEkf(N, 9) => decode::<JointEkf<f64, EKF_STATES, 9>>(bytes),
        Core::JointEkf(N, 13) => decode::<JointEkf<f64, EKF_STATES, 13>>(bytes),
        Core::TwoAxleStructured(4) => decode::<TwoAxleStructuredVec<f64, 4>>(bytes),
        Core::TwoAxleStructured(8) => decode::<TwoAxleStructuredVec<f64, 8>>(bytes),
        Core::TwoAxleStructured(16) => decode::<TwoAxleStructuredVec<f64, 16>>(bytes),
        _ => return None,
    })
}

/// Decodes the core of an `IVIdentifier` or a `BiasCompensated` (`None`: another kind, or
/// sizes the binding does not build).
fn load_noisy(core: Core, bytes: &[u8]) -> Option<Loaded> {
    const Q: u8 = PREDICTOR as u8;
    Some(match core {
        Core::Iv(2, 0) => decode::<IvIdentifierVec<f64, 2, 0>>(bytes),
        Core::Iv(4, 0) => decode::<IvIdentifierVec<f64, 4, 0>>(bytes),
        Core::Iv(8, 0) => decode::<IvIdentifierVec<f64, 8, 0>>(bytes),
        Core::Iv(16, 0) => decode::<IvIdentifierVec<f64, 16, 0>>(bytes),
        Core::Iv(32, 0) => decode::<IvIdentifierVec<f64, 32, 0>>(bytes),
        Core::Iv(2, Q) => decode::<IvIdentifierVec<f64, 2, PREDICTOR>>(bytes),
        Core::Iv(4, Q) => decode::<IvIdentifierVec<f64, 4, PREDICTOR>>(bytes),
        Core::Iv(8, Q) => decode::<IvIdentifierVec<f64, 8, PREDICTOR>>(bytes),
        Core::Iv(16, Q) => decode::<IvIdentifierVec<f64, 16, PREDICTOR>>(bytes),
        Core::Iv(32, Q) => decode::<IvIdentifierVec<f64, 32, PREDICTOR>>(bytes),
        Core::BiasCompensated(2) => decode::<BiasCompensatedVec<f64, 2>>(bytes),
        Core::BiasCompensated(4) => decode::<BiasCompensatedVec<f64, 4>>(bytes),
        Core::BiasCompensated(8) => decode::<BiasCompensatedVec<f64, 8>>(bytes),
        Core::BiasCompensated(16) => decode::<BiasCompensatedVec<f64, 16>>(bytes),
        Core::BiasCompensated(32) => decode::<BiasCompensatedVec<f64, 32>>(bytes),
        Core::NoiseEstimating(2, 0) => decode::<NoiseEstimatingBclsVec<f64, 2, 0>>(bytes),
        Core::NoiseEstimating(4, 0) => decode::<NoiseEstimatingBclsVec<f64, 4, 0>>(bytes),
        Core::NoiseEstimating(8, 0) => decode::<NoiseEstimatingBclsVec<f64, 8, 0>>(bytes),
        Core::NoiseEstimating(16, 0) => decode::<NoiseEstimatingBclsVec<f64, 16, 0>>(bytes),
        Core::NoiseEstimating(32, 0) => decode::<NoiseEstimatingBclsVec<f64, 32, 0>>(bytes),
        Core::NoiseEstimating(2, Q) => decode::<NoiseEstimatingBclsVec<f64, 2, PREDICTOR>>(bytes),
        Core::NoiseEstimating(4, Q) => decode::<NoiseEstimatingBclsVec<f64, 4, PREDICTOR>>(bytes),
        Core::NoiseEstimating(8, Q) => decode::<NoiseEstimatingBclsVec<f64, 8, PREDICTOR>>(bytes),
        Core::NoiseEstimating(16, Q) => decode::<NoiseEstimatingBclsVec<f64, 16, PREDICTOR>>(bytes),
        Core::NoiseEstimating(32, Q) => decode::<NoiseEstimatingBclsVec<f64, 32, PREDICTOR>>(bytes),
        Core::IvModel(2) => decode::<ModelIvIdentifierVec<f64, 2>>(bytes),
        Core::IvModel(4) => decode::<ModelIvIdentifierVec<f64, 4>>(bytes),
        Core::IvModel(8) => decode::<ModelIvIdentifierVec<f64, 8>>(bytes),
        Core::IvModel(16) => decode::<ModelIvIdentifierVec<f64, 16>>(bytes),
        Core::IvModel(32) => decode::<ModelIvIdentifierVec<f64, 32>>(bytes),
        _ => return None,
    })
}

/// The auxiliary model's `(dt, substeps, refresh)` of an `IVIdentifier`'s core with
/// `instruments="model"` (`None`: not one).
fn model_settings(id: &dyn DynIdentifier<f64>) -> Option<(f64, u32, usize)> {
    let any = id.as_any();
    macro_rules! try_p {
        ($($p:literal),*) => {$(
            if let Some(x) = any.downcast_ref::<ModelIvIdentifierVec<f64, $p>>() {
                return Some(x.settings());
            }
        )*};
    }
    try_p!(2, 4, 8, 16, 32);
    None
}

/// The instruments' `(delay, lags)` of an `IVIdentifier`'s core (`None`: not one).
fn iv_settings(id: &dyn DynIdentifier<f64>) -> Option<(usize, usize)> {
    let any = id.as_any();
    macro_rules! try_p {
        ($($p:literal),*) => {$(
            if let Some(x) = any.downcast_ref::<IvIdentifierVec<f64, $p, 0>>() {
                return Some((x.delay(), x.lags()));
            }
            if let Some(x) = any.downcast_ref::<IvIdentifierVec<f64, $p, PREDICTOR>>() {
                return Some((x.delay(), x.lags()));
            }
            if let Some(x) = any.downcast_ref::<ModelIvIdentifierVec<f64, $p>>() {
                return Some((x.inner().delay(), x.inner().lags()));
            }
        )*};
    }
    try_p!(2, 4, 8, 16, 32);
    None
}

/// Decodes a core on a Structure.
fn load_structured(core: Core, bytes: &[u8]) -> Option<Loaded> {
    Some(match core {
        Core::Structured(2) => decode::<StructuredKalmanVec<f64, 2>>(bytes),
        Core::Structured(4) => decode::<StructuredKalmanVec<f64, 4>>(bytes),
        Core::Structured(8) => decode::<StructuredKalmanVec<f64, 8>>(bytes),
        Core::Structured(16) => decode::<StructuredKalmanVec<f64, 16>>(bytes),
        Core::Structured(32) => decode::<StructuredKalmanVec<f64, 32>>(bytes),
        Core::StructuredGradient(4) => decode::<StructuredGradient<f64, 4>>(bytes),
        Core::StructuredGradient(8) => decode::<StructuredGradient<f64, 8>>(bytes),
        Core::StructuredGradient(16) => decode::<StructuredGradient<f64, 16>>(bytes),
        Core::StructuredGradient(32) => decode::<StructuredGradient<f64, 32>>(bytes),
        _ => return None,
    })
}

type Loaded = Result<Box<dyn DynIdentifier<f64>>, postcard::Error>;

fn decode<I: DynIdentifier<f64> + for<'de> Deserialize<'de> + 'static>(bytes: &[u8]) -> Loaded {
    Ok(Box::new(postcard::from_bytes::<I>(bytes)?))
}

/// Decodes an `N`-state core of type `core`.
fn load_n<const N: usize>(core: Core, bytes: &[u8]) -> vehid_core::Result<Loaded> {
    Ok(match core {
        Core::Rows2 => decode::<KalmanRows<f64, N, Dynamic<2>>>(bytes),
        Core::Rows4 => decode::<KalmanRows<f64, N, Dynamic<4>>>(bytes),
        Core::Shared => decode::<KalmanShared<f64, N, Dynamic>>(bytes),
        Core::Full => decode::<KalmanFull<f64, N, Dynamic>>(bytes),
        Core::Gradient => decode::<StochasticGradientVec<f64, N>>(bytes),
        Core::Batch => decode::<BatchLeastSquares<f64, N>>(bytes),
        Core::TwoAxle if N == 8 => decode::<TwoAxleCore>(bytes),
        Core::TwoAxle
        | Core::Structured(_)
        | Core::StructuredGradient(_)
        | Core::Iv(..)
        | Core::IvModel(_)
        | Core::BiasCompensated(_)
        | Core::NoiseEstimating(..)
        | Core::JointEkf(..)
        | Core::TwoAxleStructured(_) => return Err(crate::dispatch::bad_dims()),
    })
}

/// The identifier's state: `(FORMAT, "vehid <version>", payload)`.
fn state<'py>(py: Python<'py>, base: &PyIdentifier) -> PyResult<Bound<'py, PyTuple>> {
    let n = base.model.n;
    // A coloured-road wrapper: its inner identifier saved as any other, its own state beside.
    let (inner, road) = crate::road::split(base.inner.as_ref());
    let found = match save_noisy(inner).map_err(crate::identify::raise)? {
        Some(saved) => Some(saved),
        None => save_newer(inner).map_err(crate::identify::raise)?,
    };
    let saved = match found {
        Some(saved) => Ok(Some(saved)),
        None if base.structure.is_some() => save_structured(inner),
        None => dispatch_n!(n, save_n(inner)),
    }
    .map_err(crate::identify::raise)?;
    let Some((core, bytes)) = saved else {
        return Err(VehidError::new_err("this identifier cannot be pickled (its core type is not one vehid builds)"));
    };
    let payload = crate::seal::seal(&Saved { core, model: base.model.clone(), state: bytes })
        .map_err(|e| VehidError::new_err(format!("cannot pickle the identifier: {e}")))?;
    let version = concat!("vehid ", env!("CARGO_PKG_VERSION"));
    match road {
        None => (FORMAT, version, PyBytes::new(py, &payload)).into_pyobject(py),
        Some(road) => {
            let extra = crate::seal::seal(road)
                .map_err(|e| VehidError::new_err(format!("cannot pickle the identifier: {e}")))?;
            (FORMAT, version, PyBytes::new(py, &payload), PyBytes::new(py, &extra)).into_pyobject(py)
        }
    }
}

/// The arguments that build a fresh identifier of `obj`'s class and settings.
fn blank_args<'py>(obj: &Bound<'py, PyIdentifier>) -> PyResult<(Bound<'py, PyTuple>, Bound<'py, PyDict>)> {
    let py = obj.py();
    let kwargs = PyDict::new(py);
    let model = if obj.is_instance_of::<PyTwoAxleIdentifier>() {
        for key in ["spacing", "method", "wheelbase"] {
            kwargs.set_item(key, obj.getattr(key)?)?;
        }
        match &borrow(obj)?.structure {
            // On a Structure: the car gives B; `compensate` decides what the structure may hold.
            Some(st) => {
                kwargs.set_item("car", obj.getattr("model")?)?;
                kwargs.set_item("compensate", obj.getattr("compensate")?)?;
                st.bind(py).clone().into_any()
            }
            None => obj.getattr("model")?,
        }
    } else {
        if obj.is_instance_of::<PyKalmanIdentifier>() {
            kwargs.set_item("p0", 1.0)?;
            kwargs.set_item("r", 1.0)?;
            kwargs.set_item("mode", obj.getattr("mode")?)?;
            kwargs.set_item("form", obj.getattr("form")?)?;
        } else if obj.is_instance_of::<PyStochasticGradient>() {
            kwargs.set_item("gain", obj.getattr("gain")?)?;
        } else if let Ok(ls) = obj.as_any().cast::<PyBatchLeastSquares>() {
            kwargs.set_item("keep_samples", borrow(ls)?.keeps_samples())?;
        } else if obj.is_instance_of::<PyIVIdentifier>() {
            kwargs.set_item("delay", obj.getattr("delay")?)?;
            kwargs.set_item("lags", obj.getattr("lags")?)?;
            for key in ["road", "road_cutoff", "spacing", "min_spacing", "lift_off"] {
                kwargs.set_item(key, obj.getattr(key)?)?;
            }
            let instruments: String = obj.getattr("instruments")?.extract()?;
            if instruments == "model" {
                // Any valid auxiliary model's settings: the saved core (and its settings) replace it.
                kwargs.set_item("instruments", instruments)?;
                kwargs.set_item("dt", obj.getattr("dt")?)?;
                kwargs.set_item("refresh", obj.getattr("refresh")?)?;
                kwargs.set_item("substeps", obj.getattr("substeps")?)?;
            }
        } else if obj.is_instance_of::<PyBiasCompensated>() {
            match obj.getattr("instruments")?.extract::<Option<(usize, usize)>>()? {
                Some((delay, lags)) => {
                    kwargs.set_item("state_noise_var", "estimate")?;
                    kwargs.set_item("delay", delay)?;
                    kwargs.set_item("lags", lags)?;
                }
                None => kwargs.set_item("state_noise_var", 0.0)?,
            }
        } else if obj.is_instance_of::<PyJointEKF>() {
            // Any valid filter of the same sizes: the saved core replaces it.
            let (n, np) = {
                let b = borrow(obj)?;
                (b.model.n, b.inner.dims().params)
            };
            kwargs.set_item("theta0", vec![0.0; np])?;
            kwargs.set_item("p0", 1.0)?;
            kwargs.set_item("state_noise", 1.0)?;
            kwargs.set_item("road_gain", vec![0.0; n])?;
            kwargs.set_item("substeps", 1)?;
        } else {
            return Err(VehidError::new_err(format!(
                "{} cannot be pickled or copied: only vehid's identifier classes can",
                obj.get_type().name()?
            )));
        }
        let guard = borrow(obj)?;
        if let Some(st) = &guard.structure {
            if kwargs.contains("r")? {
                kwargs.del_item("r")?;
            }
            st.bind(py).clone().into_any()
        } else {
            let data = guard.model.clone();
            Bound::new(py, PyLinearModel::new_core(data, Kind::Generic))?.into_any()
        }
    };
    Ok((PyTuple::new(py, [model])?, kwargs))
}

/// `__reduce__`: `(copyreg.__newobj_ex__, (cls, args, kwargs), state)`.
pub fn reduce<'py>(obj: &Bound<'py, PyIdentifier>) -> PyResult<Bound<'py, PyTuple>> {
    let py = obj.py();
    let (args, kwargs) = blank_args(obj)?;
    let newobj = py.import("copyreg")?.getattr("__newobj_ex__")?;
    let this = borrow(obj)?;
    let state = state(py, &this)?;
    (newobj, (obj.get_type(), args, kwargs), state).into_pyobject(py)
}

/// `__copy__` / `__deepcopy__`: a fresh object of the same class with a copy of the core (the
/// models are immutable and shared).
pub fn copy<'py>(obj: &Bound<'py, PyIdentifier>) -> PyResult<Bound<'py, PyAny>> {
    let (args, kwargs) = blank_args(obj)?;
    let new = obj.get_type().call(args, Some(&kwargs))?;
    let new = new.cast::<PyIdentifier>()?;
    let core = borrow(obj)?.inner.clone_box();
    borrow_mut(new)?.inner = core;
    Ok(new.clone().into_any())
}

fn corrupt(what: &str) -> PyErr {
    VehidError::new_err(format!(
        "cannot restore the identifier: {what} (the pickle is corrupt, or was not made by vehid)"
    ))
}

/// `__setstate__`: checks the format version, decodes, checks that the core fits this
/// object's class and model, then replaces the core.
pub fn set_state(obj: &Bound<'_, PyIdentifier>, state: &Bound<'_, PyAny>) -> PyResult<()> {
    // (format, version, payload), and for a coloured-road identifier its wrapper's state.
    let (format, version, payload, road) = match state.extract::<(u32, String, Vec<u8>)>() {
        Ok((f, v, p)) => (f, v, p, None),
        Err(_) => match state.extract::<(u32, String, Vec<u8>, Vec<u8>)>() {
            Ok((f, v, p, r)) => (f, v, p, Some(r)),
            Err(_) => return Err(corrupt("its state is not a (format, version, bytes) tuple")),
        },
    };
    if format != FORMAT {
        return Err(VehidError::new_err(format!(
            "cannot restore the identifier: it was pickled by {version} in state format {format}, and this vehid \
             ({}) reads format {FORMAT} only; refit it, or load it with the version that saved it",
            env!("CARGO_PKG_VERSION")
        )));
    }
    let saved: Saved = crate::seal::open(&payload)
        .map_err(|e| corrupt(&format!("its payload does not decode or fails its checksum ({e})")))?;
    let model = borrow(obj)?.model.clone();
    if saved.model != model {
        return Err(VehidError::new_err(
            "cannot restore the identifier: the state is of an identifier of another model than this object's",
        ));
    }
    let on_structure = borrow(obj)?.structure.is_some();
    let class_fits = if obj.is_instance_of::<PyIVIdentifier>() {
        let model: bool = obj.getattr("instruments")?.extract::<String>()? == "model";
        matches!((saved.core, model), (Core::Iv(..), false) | (Core::IvModel(_), true))
    } else if obj.is_instance_of::<PyBiasCompensated>() {
        let estimates: bool = obj.getattr("estimates_noise")?.extract()?;
        matches!((saved.core, estimates), (Core::BiasCompensated(_), false) | (Core::NoiseEstimating(..), true))
    } else if obj.is_instance_of::<PyJointEKF>() {
        matches!(saved.core, Core::JointEkf(..))
    } else if obj.is_instance_of::<PyTwoAxleIdentifier>() {
        if on_structure {
            matches!(saved.core, Core::TwoAxleStructured(_))
        } else {
            saved.core == Core::TwoAxle
        }
    } else if on_structure {
        // BatchLeastSquares on a structure is the exact-start structured Kalman identifier.
        let kalman = obj.is_instance_of::<PyKalmanIdentifier>() || obj.is_instance_of::<PyBatchLeastSquares>();
        matches!(
            (saved.core, kalman, obj.is_instance_of::<PyStochasticGradient>()),
            (Core::Structured(_), true, _) | (Core::StructuredGradient(_), _, true)
        )
    } else if obj.is_instance_of::<PyKalmanIdentifier>() {
        let mode: String = obj.getattr("mode")?.extract()?;
        saved.core.mode() == Some(mode.as_str())
    } else if obj.is_instance_of::<PyStochasticGradient>() {
        saved.core == Core::Gradient
    } else if let Ok(ls) = obj.as_any().cast::<PyBatchLeastSquares>() {
        // The memory-bounded form holds the exact-start rows filter.
        if borrow(ls)?.keeps_samples() {
            saved.core == Core::Batch
        } else {
            matches!(saved.core, Core::Rows2 | Core::Rows4)
        }
    } else {
        false
    };
    if !class_fits {
        return Err(VehidError::new_err(format!(
            "cannot restore a {} from the state of another kind of identifier ({:?})",
            obj.get_type().name()?,
            saved.core
        )));
    }
    let loaded = match load_noisy(saved.core, &saved.state)
        .or_else(|| load_structured(saved.core, &saved.state))
        .or_else(|| load_newer(saved.core, &saved.state))
    {
        Some(loaded) => loaded,
        None => dispatch_n!(model.n, load_n(saved.core, &saved.state)).map_err(crate::core_err)?,
    };
    let core = loaded.map_err(|e| corrupt(&format!("its {:?} core does not decode ({e})", saved.core)))?;
    let d = core.dims();
    // Identifiers on a Structure read its measured inputs; on a linear model, none.
    let inputs = if on_structure { model.m } else { 0 };
    let params_fit = match &borrow(obj)?.structure {
        Some(st) => d.params == st.get().core.params(),
        None => true,
    };
    if d.states != model.n || d.inputs != inputs || core.rows() != model.rows.as_slice() || !params_fit {
        return Err(corrupt("its core does not fit the model (states or unknown rows differ)"));
    }
    // An IVIdentifier's delay and lags are also the Python object's (its getters and repr).
    if obj.is_instance_of::<PyIVIdentifier>() {
        let settings: (usize, usize) = (obj.getattr("delay")?.extract()?, obj.getattr("lags")?.extract()?);
        if iv_settings(core.as_ref()) != Some(settings) {
            return Err(corrupt("its instruments' delay or lags differ from this object's"));
        }
        if obj.getattr("instruments")?.extract::<String>()? == "model" {
            let mine: (Option<f64>, usize, u32) = (
                obj.getattr("dt")?.extract()?,
                obj.getattr("refresh")?.extract()?,
                obj.getattr("substeps")?.extract()?,
            );
            if model_settings(core.as_ref()).map(|(dt, sub, refresh)| (Some(dt), refresh, sub)) != Some(mine) {
                return Err(corrupt("its auxiliary model's dt, refresh or substeps differ from this object's"));
            }
        }
    }
    let mine = crate::road::of(borrow(obj)?.inner.as_ref());
    let core = match road {
        None if mine.is_none() => core,
        Some(bytes) if mine.is_some() => {
            let st: vehid_core::identify::RoadState<f64> = crate::seal::open(&bytes)
                .map_err(|e| corrupt(&format!("its road state does not decode or fails its checksum ({e})")))?;
            let wrapped = crate::road::rewrap(core, st).map_err(|e| corrupt(&e.to_string()))?;
            if crate::road::of(wrapped.as_ref()) != mine {
                return Err(corrupt("its road model or spacing differ from this object's"));
            }
            wrapped
        }
        _ => return Err(corrupt("it was saved with another road model (white or coloured) than this object's")),
    };
    borrow_mut(obj)?.inner = core;
    Ok(())
}
