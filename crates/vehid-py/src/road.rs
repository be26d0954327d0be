//! The `road=` setting of the identifiers that take one (`IVIdentifier`): argument parsing and
//! wrapping the core identifier in `identify::Differenced` (which saves its road state with
//! the inner identifier's: `Persist`).

use crate::{core_err, VehidError};
use pyo3::prelude::*;
use vehid_core::identify::{BoxedIdentifier, Contact, Differenced, DynIdentifier, RoadModel, Travel};
use vehid_core::structure::Structure;

/// The cutoff of `road="iso8608"` unless `road_cutoff=` says otherwise: vehid's ISO 8608
/// drives' shaping filter, cycles/m.
pub const DEFAULT_CUTOFF: f64 = vehid_core::sim::DEFAULT_CUTOFF;

/// The least distance between differenced samples unless `min_spacing=` says otherwise, m.
pub const DEFAULT_MIN_SPACING: f64 = vehid_core::identify::DEFAULT_MIN_SPACING;

/// The distance per sample at which a sample has weight 1 with `spacing="odometer"`, m.
pub const ODOMETER_REFERENCE: f64 = 1.0;

/// A coloured-road setting: the model and how the distance per sample is known.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Road {
    pub model: RoadModel<f64>,
    pub travel: Travel<f64>,
    /// The least distance between differenced samples, m.
    pub min_spacing: f64,
    /// The lift-off check's body and wheel masses `(M, m)`, kg (the quarter car).
    pub lift_off: Option<(f64, f64)>,
}

impl Road {
    /// `road` as the Python getter gives it.
    pub fn name(&self) -> &'static str {
        match self.model {
            RoadModel::RandomWalk => "random-walk",
            RoadModel::Shaped { .. } => "iso8608",
        }
    }

    /// `road_cutoff` (None for the random walk).
    pub fn cutoff(&self) -> Option<f64> {
        match self.model {
            RoadModel::RandomWalk => None,
            RoadModel::Shaped { cutoff } => Some(cutoff),
        }
    }

    /// `spacing`: metres per sample, or "odometer".
    pub fn spacing<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        match self.travel {
            Travel::PerSample(ds) => Ok(ds.into_pyobject(py)?.into_any()),
            Travel::Odometer { .. } => Ok("odometer".into_pyobject(py)?.into_any()),
        }
    }
}

/// Parses `road`, `road_cutoff`, `spacing` and `min_spacing` (None: the white road of the
/// thesis).
pub fn road_args(
    road: &str,
    cutoff: Option<f64>,
    spacing: Option<&Bound<'_, PyAny>>,
    min_spacing: Option<f64>,
    lift_off: Option<(f64, f64)>,
) -> PyResult<Option<Road>> {
    let model = match road {
        "white" => {
            if cutoff.is_some() || spacing.is_some() || min_spacing.is_some() || lift_off.is_some() {
                return Err(VehidError::new_err(
                    "`road_cutoff`, `spacing`, `min_spacing` and `lift_off` describe a coloured road: give them \
                     with road=\"random-walk\" or road=\"iso8608\"",
                ));
            }
            return Ok(None);
        }
        "random-walk" => {
            if cutoff.is_some() {
                return Err(VehidError::new_err("`road_cutoff` is for road=\"iso8608\" (a random walk has none)"));
            }
            RoadModel::RandomWalk
        }
        "iso8608" => {
            let c = cutoff.unwrap_or(DEFAULT_CUTOFF);
            if !(c.is_finite() && c >= 0.0) {
                return Err(VehidError::new_err(format!(
                    "`road_cutoff` must be finite and >= 0 cycles/m (the shaping filter's n_c; 0 is a random walk), \
                     got {c}"
                )));
            }
            RoadModel::Shaped { cutoff: c }
        }
        other => {
            return Err(VehidError::new_err(format!(
                "unknown `road` {other:?}: expected \"white\" (the thesis' road noise), \"random-walk\" or \
                 \"iso8608\" (a road whose height is a random walk / ISO 8608 shaping filter in distance)"
            )))
        }
    };
    let need = || {
        VehidError::new_err(format!(
            "road={road:?} needs `spacing`: the distance travelled per sample in metres (speed × sample interval, \
             e.g. 15 m/s × 0.005 s = 0.075), or \"odometer\" with the odometer reading (m) as the last column of `u`"
        ))
    };
    let travel = match spacing {
        None => return Err(need()),
        Some(v) => match v.extract::<String>() {
            Ok(t) if t == "odometer" => Travel::Odometer { reference: ODOMETER_REFERENCE },
            Ok(_) => return Err(need()),
            Err(_) => {
                let ds: f64 = v.extract().map_err(|_| need())?;
                if !(ds.is_finite() && ds > 0.0) {
                    return Err(VehidError::new_err(format!(
                        "`spacing` must be finite and > 0 metres per sample, got {ds}"
                    )));
                }
                Travel::PerSample(ds)
            }
        },
    };
    let min_spacing = min_spacing.unwrap_or(DEFAULT_MIN_SPACING);
    if !(min_spacing.is_finite() && min_spacing >= 0.0) {
        return Err(VehidError::new_err(format!(
            "`min_spacing` must be finite and >= 0 metres (0: every sample is differenced), got {min_spacing}"
        )));
    }
    if let Some((big_m, m)) = lift_off {
        if !(big_m.is_finite() && big_m > 0.0 && m.is_finite() && m > 0.0) {
            return Err(VehidError::new_err(format!(
                "`lift_off` must be (M, m): the body and wheel masses in kg, finite and > 0, got ({big_m}, {m})"
            )));
        }
    }
    Ok(Some(Road { model, travel, min_spacing, lift_off }))
}

/// `inner` (an identifier on `s`) fed the samples differenced for `road`.
pub fn wrap(
    inner: Box<dyn DynIdentifier<f64>>,
    s: &Structure<f64>,
    road: Road,
) -> PyResult<Box<dyn DynIdentifier<f64>>> {
    let mut d = Differenced::new(BoxedIdentifier(inner), s, road.model, road.travel)
        .and_then(|d| d.with_min_spacing(road.min_spacing))
        .map_err(core_err)?;
    if let Some((big_m, m)) = road.lift_off {
        if s.states() != 4 {
            return Err(VehidError::new_err(format!(
                "`lift_off` checks the quarter car (states wheel_pos, wheel_vel, body_pos, body_vel); this model has \
                 {} states",
                s.states()
            )));
        }
        d = d.with_contact(Contact { wheel: 1, body: 3, m_wheel: m, m_body: big_m }).map_err(core_err)?;
    }
    Ok(Box::new(d))
}

type Wrapped = Differenced<f64, BoxedIdentifier<f64>>;

/// Samples a coloured-road wrapper found lifted off (None: no wrapper).
pub fn lifted(inner: &dyn DynIdentifier<f64>) -> Option<u64> {
    inner.as_any().downcast_ref::<Wrapped>().map(|d| d.lifted())
}
