//! vehid-core's integration tests that need no global allocator of their own, as one test
//! binary: each file is a module of it, so `cargo test -p vehid-core --test integration
//! noisy_states::` runs one file's tests. (The files with a counting allocator are binaries of
//! their own, listed in Cargo.toml.)

mod common;

#[path = "claims.rs"]
mod claims;
#[path = "contract.rs"]
mod contract;
#[path = "half_one_road.rs"]
mod half_one_road;
#[path = "health_behaviour.rs"]
mod health_behaviour;
#[path = "identify_noise.rs"]
mod identify_noise;
#[path = "model_instruments.rs"]
mod model_instruments;
#[path = "noise_estimating.rs"]
mod noise_estimating;
#[path = "noisy_states.rs"]
mod noisy_states;
#[path = "parser_property.rs"]
mod parser_property;
#[path = "physical_structure.rs"]
mod physical_structure;
#[path = "road.rs"]
mod road;
#[path = "sensor_faults.rs"]
mod sensor_faults;

/// With `autotests = false`, a new file in `tests/` would silently never run: each one must be
/// a module above or a `[[test]]` of Cargo.toml (read here as text: every `name = "…"` line of
/// a `[[test]]` table).
#[test]
fn every_test_file_is_built() {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
    let manifest = std::fs::read_to_string(dir.join("Cargo.toml")).unwrap();
    let targets: Vec<&str> = manifest
        .split("[[test]]")
        .skip(1)
        .filter_map(|t| t.lines().find_map(|l| l.trim().strip_prefix("name = \"")?.strip_suffix('"')))
        .collect();
    let this = std::fs::read_to_string(dir.join("tests/integration.rs")).unwrap();
    let mut unbuilt = Vec::new();
    for entry in std::fs::read_dir(dir.join("tests")).unwrap() {
        let name = entry.unwrap().file_name().into_string().unwrap();
        let Some(stem) = name.strip_suffix(".rs") else { continue };
        if !targets.contains(&stem) && !this.contains(&format!("#[path = \"{name}\"]")) {
            unbuilt.push(name);
        }
    }
    assert!(
        unbuilt.is_empty(),
        "{unbuilt:?} in tests/ belong to no test target: add each as a module of tests/integration.rs or as a \
         [[test]] of Cargo.toml"
    );
}
