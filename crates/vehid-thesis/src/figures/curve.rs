//! One curve of a figure and its identifier.

use vehid_core::identify::WheelMethod;

/// The identifier of a curve and its settings.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Ident {
    /// Batch least squares over every sample so far (Eq 2.14), Ch. III.
    BatchLs,
    /// The Kalman-filter identifier, decoupled rows (Eq 4.3–4.7, 6.16–6.18).
    Kalman {
        /// `P(0)` diagonal on the wheel rows (quarter car: both rows).
        p0_wheel: f64,
        /// `P(0)` diagonal on the body rows (half car rows 5 and 7; quarter car: ignored).
        p0_body: f64,
        /// The filter's `R` as a multiple of the correct `R_v + B R_u Bᵀ` (Fig 4-8: < 1).
        r_scale: f64,
        /// Eq 4.36 reinitialization.
        reinit: bool,
    },
    /// The stochastic gradient (Eq 5.2–5.18) with the wheel-row gains one tenth of the
    /// body-row gains (Eq 5.10); `Σ_N = σ_w² I` bias elimination when the curve has state noise.
    Gradient {
        /// The gain sequence.
        gain: GainKind,
        /// Body-row gain `h` (wheel row `h / 10`).
        h: f64,
    },
    /// vehid's extension: the quarter car identified in its physical structure with the wheel
    /// mass `m` known (4 parameters k2/M, b/M, M, k1 instead of 8 free entries; exact start,
    /// no prior), read back as rows of A for ξ.
    Physical,
    /// The two-axle identifier on one road (Ch. VI.D): `None` = plain decoupled rows,
    /// `Thesis` = Eq 6.12–6.14, `Cancel` = vehid's road cancellation (an extension).
    TwoAxle {
        /// Wheel-row method.
        method: WheelMethod,
        /// `P(0)` on the wheel rows.
        p0_wheel: f64,
        /// `P(0)` on the body rows.
        p0_body: f64,
    },
}

/// The gain sequence of a stochastic-gradient curve.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum GainKind {
    /// Venter, `k^(−p)` (Eq 5.8).
    Venter(f64),
    /// Lyapunov / normalized (Eq 5.9).
    Lyapunov,
    /// Ljung's sequence with forgetting (Eq 5.15–5.18), λ₀ = 0.99, λ(0) = 0.95.
    Ljung,
}

/// One curve of a figure: the caption's four σ, an optional pulse, and the identifier.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Curve {
    /// Legend text (besides the σ values).
    pub label: &'static str,
    /// Initial-condition σ_ic.
    pub ic: f64,
    /// Road σ_u.
    pub road: f64,
    /// State measurement σ_w.
    pub state: f64,
    /// State derivative measurement σ_v.
    pub deriv: f64,
    /// Pulse width in sample intervals (0 = no pulse).
    pub pulse_width: u64,
    /// The identifier.
    pub ident: Ident,
}

/// A curve's legend name: its label, or its index.
pub fn curve_name(c: &Curve, i: usize) -> String {
    if c.label.is_empty() {
        format!("curve {}", i + 1)
    } else {
        c.label.to_string()
    }
}
