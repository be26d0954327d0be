//! Criterion benches for vehid.

use vehid_core::structure::{Structure, StructureBuilder};

/// One sample of a structure with an input: measured state, measured derivative, input.
pub type InputSample = ([f64; 2], [f64; 2], [f64; 1]);

/// The mass-spring-damper rig with a measured force (`q̇ = v`, `v̇ = a F − k q − b v`, a = 1,
/// k = 8883, b = 18.8: 15 Hz, damping ratio 0.1; dt = 0.01 s) and `len` seeded samples: the
/// force an AR(1) sequence (coefficient 0.5) held over each interval, the state by 4 RK4 steps
/// per interval, 30 % white noise on the measured states and acceleration (the settings of
/// `crates/vehid-core/tests/model_instruments.rs`). For the benches of instruments from the
/// auxiliary model (`update_f64/msd/iv_model`, `count_updates msd_iv_model`).
pub fn msd_rig(len: usize) -> (Structure<f64>, Vec<InputSample>) {
    let (s, _) = StructureBuilder::new(&["q", "v"], &["F"])
        .equation("v", "a*F - k*q - b*v")
        .known("q", "v")
        .build::<f64>()
        .expect("the rig's structure");
    let p = [1.0, 8883.0, 18.8];
    let mut state = 0x2545_f491_4f6c_dd1du64;
    let mut normal = move || {
        // Sum of 12 uniforms less 6: unit variance, deterministic, no dependency.
        (0..12)
            .map(|_| {
                state ^= state << 13;
                state ^= state >> 7;
                state ^= state << 17;
                (state >> 11) as f64 / (1u64 << 53) as f64
            })
            .sum::<f64>()
            - 6.0
    };
    let (mut x, mut f) = ([0.0f64; 2], 0.0f64);
    let mut out = Vec::with_capacity(len);
    let mut both = [0.0; 4];
    let mut der = [0.0; 2];
    for _ in 0..len {
        f = 0.5 * f + normal();
        s.derivative(&p, &x, &[f], &mut der);
        let (sq, sv, sa) = (0.3 * 0.0095, 0.3 * 0.37, 0.3 * 9.0);
        out.push(([x[0] + sq * normal(), x[1] + sv * normal()], [der[0], der[1] + sa * normal()], [f]));
        s.simulate(&p, &x, &[f, f], 0.01, 4, &mut both).expect("the rig stays bounded");
        x = [both[2], both[3]];
    }
    (s, out)
}
