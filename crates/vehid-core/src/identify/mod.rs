//! Identifiers of the unknown rows of `A` (Ch. II–V): batch least squares (Eq 2.14), the
//! Kalman-filter identifier (Eq 4.3–4.7), and stochastic gradient (Eq 2.56, 5.2–5.18).
