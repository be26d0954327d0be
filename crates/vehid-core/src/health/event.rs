//! What the monitor reports: [`Event`], [`Status`] with its [`Reason`], [`Estimate`], and
//! the [`Constant`] an event names.

/// A constant the monitor can name in an [`Event`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub enum Constant {
    /// Body (sprung) mass `M`, kg: `k2/M` and `b/M` changed by the same factor.
    BodyMass,
    /// Suspension spring stiffness `k2`, N/m: `k2/M` alone changed.
    Spring,
    /// Damping `b`, N·s/m: `b/M` alone changed.
    Damper,
}

impl Constant {
    /// The thesis' name: `"M"`, `"k2"` or `"b"`.
    pub fn as_str(&self) -> &'static str {
        match self {
            Constant::BodyMass => "M",
            Constant::Spring => "k2",
            Constant::Damper => "b",
        }
    }
}

impl core::fmt::Display for Constant {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(self.as_str())
    }
}

/// Why the monitor cannot judge at the moment (it then never raises an event).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub enum Reason {
    /// The road excites too little: a tracked ratio's relative standard error exceeds
    /// `judge_error` (a smooth road, a slow car, the car standing).
    LowExcitation,
    /// The last sample had a missing channel (NaN), e.g. a gap in the log.
    Missing,
    /// A channel has repeated the same value for `stuck_samples` samples.
    Stuck,
    /// The deflection jumped away from the integrated accelerations by more than 8
    /// standard deviations of the kinematic filter's innovation (a seam or glitch in the data).
    Jump,
    /// Restarting the kinematic filter after missing or stuck data (`reacquire` seconds).
    Reacquiring,
    /// The deflection sensor and the accelerometers disagree: the deflection's second
    /// derivative no longer matches `a_body − a_wheel` with the warm-up's gain (a sensor whose
    /// gain changed, an inverted or swapped channel; `consistency.rs`). Nothing about the
    /// car is judged until they agree again for one `window`.
    Sensors,
}

/// What the monitor is doing.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Status {
    /// Learning the reference (the first `warmup` seconds of usable data).
    Warmup,
    /// Comparing the tracked ratios with the reference.
    Monitoring,
    /// A change was detected; measuring its new value for `settle` seconds.
    Settling,
    /// No judgement possible now; the reason.
    CannotJudge(Reason),
}

/// A detected change of one constant: of the quarter car ([`Constant`]) or of the half car
/// (`C = HalfConstant`).
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct Event<T, C = Constant> {
    /// When the event was reported, s (sample index × dt).
    pub t: T,
    /// Estimated onset, s: the last time the alarming CUSUM was zero.
    pub t_change: T,
    /// The constant that changed.
    pub parameter: C,
    /// Its value before, in its unit (kg, N/m, N·s/m): the nominal car's, or the previous
    /// event's `after`.
    pub before: T,
    /// Its value after.
    pub after: T,
    /// Lower end of the `confidence` interval of `after`.
    pub low: T,
    /// Upper end of the interval.
    pub high: T,
    /// The relative change `after / before − 1`.
    pub change: T,
    /// Where a load was set down, for a body-mass event of the full car whose changes fit a
    /// point mass better than a load spread like the body's own mass: `[x, y]`, m from the
    /// nominal car's centre of mass (`x` forward, `y` to the left: the frame of
    /// [`crate::model::FullCar::corner_position`]); `None` otherwise.
    pub position: Option<[T; 2]>,
}

/// The tracked ratios with their intervals.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Estimate<T> {
    /// `[k2/M (1/s²), b/M (1/s), c (m/s²)]`.
    pub value: [T; 3],
    /// Lower ends of the `confidence` intervals.
    pub low: [T; 3],
    /// Upper ends.
    pub high: [T; 3],
}
