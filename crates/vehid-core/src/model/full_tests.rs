//! Tests of the full car against independent checks: the energy functions' Hessians, the half
//! car as the limit of equal sides, the static loads, and the closed-form modes of a
//! symmetric car.

use super::*;
use crate::model::{HalfCar, HalfCarParams};

/// An asymmetric car with anti-roll bars: every constant different, so that a swapped index
/// or sign shows.
fn odd_car() -> FullCar<f64> {
    FullCar::new(FullCarParams {
        m_body: 1340.0,
        jx: 510.0,
        jy: 1950.0,
        kt: [185e3, 192e3, 205e3, 198e3],
        k: [31e3, 29e3, 36e3, 34e3],
        b: [1450.0, 1380.0, 1210.0, 1290.0],
        m: [42.0, 44.0, 37.0, 36.0],
        l_f: 1.25,
        l_r: 1.55,
        track_f: 1.52,
        track_r: 1.48,
        arb_f: 21e3,
        arb_r: 9e3,
    })
    .unwrap()
}

/// Suspension extensions of the generalized coordinates `q = (z_fl, z_fr, z_rl, z_rr, zb, θ,
/// φ)`, written from the geometry directly (front +l_f, rear −l_r, left +t/2).
fn extensions(p: &FullCarParams<f64>, q: &[f64; 7]) -> [f64; 4] {
    let (zb, th, ph) = (q[4], q[5], q[6]);
    [
        zb + p.l_f * th + p.track_f / 2.0 * ph - q[0],
        zb + p.l_f * th - p.track_f / 2.0 * ph - q[1],
        zb - p.l_r * th + p.track_r / 2.0 * ph - q[2],
        zb - p.l_r * th - p.track_r / 2.0 * ph - q[3],
    ]
}

/// Potential energy (springs, tyres on a flat road, anti-roll bars), J.
fn potential(p: &FullCarParams<f64>, q: &[f64; 7]) -> f64 {
    let d = extensions(p, q);
    let mut v = 0.0;
    for i in 0..4 {
        v += 0.5 * p.k[i] * d[i] * d[i] + 0.5 * p.kt[i] * q[i] * q[i];
    }
    v += 0.5 * p.arb_f * ((d[0] - d[1]) / p.track_f).powi(2);
    v += 0.5 * p.arb_r * ((d[2] - d[3]) / p.track_r).powi(2);
    v
}

/// Rayleigh dissipation function of the generalized velocities, W.
fn dissipation(p: &FullCarParams<f64>, qd: &[f64; 7]) -> f64 {
    let d = extensions(p, qd);
    (0..4).map(|i| 0.5 * p.b[i] * d[i] * d[i]).sum()
}

/// Hessian of a quadratic form by central differences (exact up to rounding for a quadratic).
fn hessian(f: impl Fn(&[f64; 7]) -> f64) -> [[f64; 7]; 7] {
    let h = 1e-3;
    let mut out = [[0.0; 7]; 7];
    for r in 0..7 {
        for c in 0..7 {
            let at = |sr: f64, sc: f64| {
                let mut q = [0.0; 7];
                q[r] += sr * h;
                q[c] += sc * h;
                f(&q)
            };
            out[r][c] = (at(1.0, 1.0) - at(1.0, -1.0) - at(-1.0, 1.0) + at(-1.0, -1.0)) / (4.0 * h * h);
        }
    }
    out
}

#[test]
fn full_car_rows_are_the_energy_hessians() {
    // Lagrange: mass_r q̈_r = −∂V/∂q_r − ∂D/∂q̇_r, so mass_r · A[acc_r, pos_c] = −∂²V/∂q_r∂q_c
    // and mass_r · A[acc_r, vel_c] = −∂²D/∂q̇_r∂q̇_c.
    let car = odd_car();
    let p = car.params();
    let a = *car.model().a();
    let kv = hessian(|q| potential(&p, q));
    let cv = hessian(|q| dissipation(&p, q));
    let mass = car.masses();
    for r in 0..7 {
        for c in 0..7 {
            let (k, b) = (mass[r] * a[(2 * r + 1, 2 * c)], mass[r] * a[(2 * r + 1, 2 * c + 1)]);
            let tol = 1e-6 * kv[r][c].abs().max(1.0);
            assert!((k + kv[r][c]).abs() <= tol, "stiffness ({r},{c}): {k} vs {}", -kv[r][c]);
            assert!((b + cv[r][c]).abs() <= 1e-6 * cv[r][c].abs().max(1.0), "damping ({r},{c}): {b} vs {}", -cv[r][c]);
        }
    }
    // Kinematic rows and B.
    let bm = *car.model().b();
    for i in 0..7 {
        assert_eq!(a[(2 * i, 2 * i + 1)], 1.0);
    }
    for i in 0..4 {
        assert!((bm[(2 * i + 1, i)] - p.kt[i] / p.m[i]).abs() < 1e-9);
        assert_eq!(bm.column(i).iter().filter(|v| **v != 0.0).count(), 1);
    }
}

#[test]
fn full_car_is_the_half_car_when_left_equals_right() {
    // Equal corners on each axle and equal roads under both sides: the motion stays in the
    // subspace z_fl = z_fr, z_rl = z_rr, φ = 0, where the full car with body M, Jy is the half
    // car with M/2, Jy/2 (one side): A_full E = E A_half, B_full E_u = E B_half.
    let h = HalfCar::<f64>::new(HalfCarParams {
        k11: 205e3,
        k21: 190e3,
        k12: 27e3,
        k22: 23e3,
        b1: 1700.0,
        b2: 1350.0,
        m1: 41.0,
        m2: 36.0,
        m_body: 655.0,
        j: 990.0,
        l1: 1.15,
        l2: 1.6,
    })
    .unwrap();
    let hp = h.params();
    let full = FullCar::new(FullCarParams {
        m_body: 2.0 * hp.m_body,
        jx: 480.0,
        jy: 2.0 * hp.j,
        kt: [hp.k11, hp.k11, hp.k21, hp.k21],
        k: [hp.k12, hp.k12, hp.k22, hp.k22],
        b: [hp.b1, hp.b1, hp.b2, hp.b2],
        m: [hp.m1, hp.m1, hp.m2, hp.m2],
        l_f: hp.l1,
        l_r: hp.l2,
        track_f: 1.45,
        track_r: 1.55,
        arb_f: 15e3,
        arb_r: 8e3,
    })
    .unwrap();
    // Half state [z1, v1, z2, v2, zb, vb, ph, om] into the full state.
    let mut e = SMatrix::<f64, 14, 8>::zeros();
    for (full_i, half_i) in
        [(0, 0), (1, 1), (2, 0), (3, 1), (4, 2), (5, 3), (6, 2), (7, 3), (8, 4), (9, 5), (10, 6), (11, 7)]
    {
        e[(full_i, half_i)] = 1.0;
    }
    let mut eu = SMatrix::<f64, 4, 2>::zeros();
    for (i, j) in [(0, 0), (1, 0), (2, 1), (3, 1)] {
        eu[(i, j)] = 1.0;
    }
    let (fm, hm) = (full.model(), h.model());
    let lhs = fm.a() * e;
    let rhs = e * hm.a();
    for (x, y) in lhs.iter().zip(rhs.iter()) {
        assert!((x - y).abs() <= 1e-9 * y.abs().max(1.0), "A: {x} vs {y}");
    }
    let (lb, rb) = (fm.b() * eu, e * hm.b());
    for (x, y) in lb.iter().zip(rb.iter()) {
        assert!((x - y).abs() <= 1e-9 * y.abs().max(1.0), "B: {x} vs {y}");
    }
}

#[test]
fn full_car_static_equilibrium_carries_each_corners_share() {
    // Left and right springs equal, centre of mass on the centreline: each front corner
    // carries M g l_r / (2L), each rear corner M g l_f / (2L) (statics of a beam on two
    // supports); the tyre carries that plus its wheel's weight.
    let g = 9.81;
    for car in [FullCar::<f64>::passenger(), FullCar::default()] {
        let mut p = car.params();
        p.arb_f = 12e3; // a bar carries nothing when both sides deflect alike
        let car = FullCar::new(p).unwrap();
        let q = car.static_equilibrium(g).unwrap();
        let d = extensions(&p, &q);
        let l = p.l_f + p.l_r;
        for i in 0..4 {
            let load = p.m_body * g * if i < 2 { p.l_r } else { p.l_f } / (2.0 * l);
            assert!((-p.k[i] * d[i] - load).abs() < 1e-6 * load, "corner {i}: spring {} vs {load}", -p.k[i] * d[i]);
            let tyre = -p.kt[i] * q[i];
            assert!((tyre - load - p.m[i] * g).abs() < 1e-6 * load, "corner {i}: tyre {tyre}");
        }
        assert!(q[6].abs() < 1e-12, "no roll under a centred load");
    }
}

/// Real polynomial helpers (coefficients lowest degree first).
fn pmul(a: &[f64], b: &[f64]) -> [f64; 5] {
    let mut out = [0.0; 5];
    for (i, x) in a.iter().enumerate() {
        for (j, y) in b.iter().enumerate() {
            out[i + j] += x * y;
        }
    }
    out
}

/// Newton step `|P(s)/P'(s)|` at a complex point: small when `s` is a root of `P`.
fn newton_step(p: &[f64; 5], s: nalgebra::Complex<f64>) -> f64 {
    let (mut v, mut d) = (nalgebra::Complex::new(0.0, 0.0), nalgebra::Complex::new(0.0, 0.0));
    for c in p.iter().rev() {
        d = d * s + v;
        v = v * s + c;
    }
    if d.norm() == 0.0 {
        return f64::INFINITY;
    }
    (v / d).norm()
}

#[cfg(feature = "alloc")]
#[test]
fn full_symmetric_car_poles_are_the_closed_form_modes() {
    // A symmetric car (equal corners, l_f = l_r = l, equal tracks t = 2w, equal bars K)
    // decouples into four modes; with c(s) = b s + k, k_r = k + 2K/t², the wheel factor
    // W(s, k) = m s² + b s + k + kt:
    //   heave  (M s² + 4 c)(W) − 4 c²         pitch  (Jy s² + 4 l² c)(W) − 4 l² c²
    //   roll   (Jx s² + 4 w² c_r)(W_r) − 4 w² c_r²   (c_r = b s + k_r)
    //   warp   W_r (the wheels against each other, the body still)
    // so the 14 poles are 4 + 4 + 4 + 2 roots of these polynomials.
    let mut p = FullCar::<f64>::default().params();
    p.arb_f = 6e3;
    p.arb_r = 6e3;
    let car = FullCar::new(p).unwrap();
    let (k, b, m, kt) = (p.k[0], p.b[0], p.m[0], p.kt[0]);
    let (l, w) = (p.l_f, p.track_f / 2.0);
    let kr = k + 2.0 * p.arb_f / (p.track_f * p.track_f);
    let two_dof = |inertia: f64, arm2: f64, ks: f64| {
        let c = [ks, b];
        let body = [4.0 * arm2 * ks, 4.0 * arm2 * b, inertia];
        let wheel = [ks + kt, b, m];
        let mut poly = pmul(&body, &wheel);
        let cc = pmul(&c, &c);
        for i in 0..5 {
            poly[i] -= 4.0 * arm2 * cc[i];
        }
        poly
    };
    let polys =
        [two_dof(p.m_body, 1.0, k), two_dof(p.jy, l * l, k), two_dof(p.jx, w * w, kr), [kr + kt, b, m, 0.0, 0.0]];
    let poles = car.model().poles().unwrap();
    let mut count = [0usize; 4];
    for s in poles.iter() {
        let steps: Vec<f64> = polys.iter().map(|q| newton_step(q, *s) / s.norm()).collect();
        let hits: Vec<usize> = (0..4).filter(|&i| steps[i] < 1e-7).collect();
        assert_eq!(hits.len(), 1, "pole {s} is a root of one mode polynomial: steps {steps:?}");
        count[hits[0]] += 1;
    }
    assert_eq!(count, [4, 4, 4, 2], "heave, pitch, roll, warp");
}

#[cfg(feature = "alloc")]
#[test]
fn full_car_roll_frequencies_match_the_two_dof_closed_form() {
    // The undamped roll mode of the symmetric car (b → 0): det([[4w²k_r − ω²Jx, −4w k_r],
    // [−k_r, k_r + kt − ω² m]]) = 0, solved as a quadratic in ω²; the full car's poles, with
    // tiny dampers, include ±jω for both roots.
    let mut p = FullCar::<f64>::default().params();
    p.b = [1e-6; 4];
    p.arb_f = 9e3;
    p.arb_r = 9e3;
    p.jx = 380.0;
    let car = FullCar::new(p).unwrap();
    let (k, m, kt, w) = (p.k[0], p.m[0], p.kt[0], p.track_f / 2.0);
    let kr = k + 2.0 * p.arb_f / (p.track_f * p.track_f);
    // (4w²kr − xJx)(kr + kt − x m) − 4w²kr² = 0 in x = ω².
    let (qa, qb, qc) = (p.jx * m, -(4.0 * w * w * kr * m + p.jx * (kr + kt)), 4.0 * w * w * kr * kt);
    let disc = (qb * qb - 4.0 * qa * qc).sqrt();
    let roots = [(-qb - disc) / (2.0 * qa), (-qb + disc) / (2.0 * qa)];
    let poles = car.model().poles().unwrap();
    for x in roots {
        let om = x.sqrt();
        let near = poles.iter().map(|s| (s.im.abs() - om).abs()).fold(f64::INFINITY, f64::min);
        assert!(near < 1e-6 * om, "roll frequency {om} rad/s not among the poles (nearest off by {near})");
    }
}

#[test]
fn full_car_constants_round_trip_and_validate() {
    let car = odd_car();
    let back = FullCar::from_constants(car.constants()).unwrap();
    assert_eq!(back, car);
    for (i, (name, v)) in car.params().named().iter().enumerate() {
        assert_eq!(*name, FullCar::<f64>::CONSTANTS[i]);
        assert_eq!(*v, car.constants()[i]);
    }
    // Every constant refused at zero (the bars only below zero), named in the error.
    for (i, name) in FullCar::<f64>::CONSTANTS.iter().enumerate() {
        let mut c = car.constants();
        c[i] = if name.starts_with("arb") { -1.0 } else { 0.0 };
        match FullCar::from_constants(c) {
            Err(Error::InvalidArgument { arg, .. }) => assert_eq!(arg, *name),
            other => panic!("{name}: {other:?}"),
        }
        c[i] = f64::NAN;
        assert!(FullCar::from_constants(c).is_err(), "{name} NaN");
    }
    let mut c = car.constants();
    c[23] = 0.0;
    assert!(FullCar::from_constants(c).is_ok(), "no front bar is fine");
}

#[test]
fn full_car_structural_zeros_follow_the_bars() {
    let mut p = odd_car().params();
    p.arb_r = 0.0;
    let m = FullCar::new(p).unwrap().model();
    // Front left wheel row (1): bar on the front axle couples z_fr (2) but not v_fr (3).
    assert!(!m.is_structural_zero(1, 2) && m.a()[(1, 2)] != 0.0);
    assert!(m.is_structural_zero(1, 3) && m.a()[(1, 3)] == 0.0);
    // Rear left wheel row (5): no rear bar, so z_rr (6) is a structural zero.
    assert!(m.is_structural_zero(5, 6) && m.a()[(5, 6)] == 0.0);
    // Other axle always zero.
    for c in [4, 5, 6, 7] {
        assert!(m.is_structural_zero(1, c) && m.a()[(1, c)] == 0.0);
    }
    // Every structural zero is a zero of A.
    for r in m.unknown_rows().as_slice() {
        for c in 0..14 {
            if m.is_structural_zero(*r, c) {
                assert_eq!(m.a()[(*r, c)], 0.0, "({r},{c})");
            }
        }
    }
}

#[test]
fn full_car_in_f32_matches_f64() {
    let a64 = *FullCar::<f64>::passenger().model().a();
    let a32 = *FullCar::<f32>::passenger().model().a();
    for (x, y) in a64.iter().zip(a32.iter()) {
        assert!((x - *y as f64).abs() <= 1e-5 * x.abs().max(1.0), "{x} vs {y}");
    }
}
