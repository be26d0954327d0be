use super::*;
use crate::model::QuarterCar;

/// `reset_covariance` (its docs): the parameters' block `p0 I`, the state–parameter
/// covariance 0, the state's own block and the road slot (neither a state nor a
/// parameter; restarted uncorrelated at every step) kept; after a sample.
#[test]
fn reset_covariance_touches_the_parameters_block_only() {
    let st = *QuarterCar::<f64>::structure([None, Some(1.0), None, None, None]).unwrap().structure();
    let g = SVector::<f64, 4>::from_column_slice(QuarterCar::<f64>::thesis().model().b().as_slice());
    let noise = EkfNoise::from_sigmas(0.008, 0.1, g, 0.1);
    let mut ekf = JointEkf::<f64, 4, 9>::new(st, &[5.0, 4.0, 10.0, 90.0], &[1.0; 4], 1.0, noise, 0.05, 5).unwrap();
    let mut e = [0.0; 2];
    ekf.update_into(&[0.01, -0.2, 0.03, 0.5], &[-0.2, 1.0, 0.5, -3.0], &[], &mut e).unwrap();
    let before = ekf.p;
    ekf.reset_covariance(2.5).unwrap();
    for a in 0..9 {
        for b in 0..9 {
            let (pa, pb) = ((4..8).contains(&a), (4..8).contains(&b));
            let want = match (pa, pb) {
                (true, true) => {
                    if a == b {
                        2.5
                    } else {
                        0.0
                    }
                }
                (true, false) | (false, true) => 0.0,
                (false, false) => before[(a, b)],
            };
            assert_eq!(ekf.p[(a, b)], want, "P[{a},{b}]");
        }
    }
}

/// `predict`'s tangent `∂x_{k+1}/∂s` (`D × N`) is the derivative of its own map: central
/// differences of `predict` in every component of `s` (the states, the parameters, the
/// road), on the quarter car's physical structure.
#[test]
fn predict_tangent_is_the_derivative_of_the_map() {
    let st = *QuarterCar::<f64>::structure([None, Some(1.0), None, None, None]).unwrap().structure();
    let g = SVector::<f64, 4>::from_column_slice(QuarterCar::<f64>::thesis().model().b().as_slice());
    let noise = EkfNoise::from_sigmas(0.008, 0.1, g, 0.1);
    let ekf = JointEkf::<f64, 4, 9>::new(st, &[5.0, 4.0, 10.0, 90.0], &[1.0; 4], 1.0, noise, 0.05, 5).unwrap();
    let s = SVector::<f64, 9>::from_column_slice(&[0.01, -0.2, 0.03, 0.5, 5.0, 4.0, 10.0, 90.0, 0.02]);
    let (_, tx) = ekf.predict(&s, &[]);
    for j in 0..9 {
        let h = 1e-6 * s[j].abs().max(1.0);
        let (mut a, mut b) = (s, s);
        a[j] += h;
        b[j] -= h;
        let d = (ekf.predict(&a, &[]).0 - ekf.predict(&b, &[]).0) / (2.0 * h);
        for i in 0..4 {
            assert!(
                (tx[(j, i)] - d[i]).abs() <= 1e-6 * (1.0 + d[i].abs()),
                "∂x_{i}/∂s_{j}: tangent {} against the difference {}",
                tx[(j, i)],
                d[i]
            );
        }
    }
}
