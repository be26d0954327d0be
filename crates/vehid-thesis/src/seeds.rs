//! The seed of every realization, derived from the run's base seed.
//!
//! A job's seed depends only on (base seed, figure id, curve, seed index), never on the
//! order in which the threads pick the jobs, so a report is reproducible from its base seed.

use crate::figures::Experiment;

/// SplitMix64: seeds from (base, figure, curve, seed index).
pub(crate) fn mix(mut z: u64) -> u64 {
    z = z.wrapping_add(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

fn fig_hash(id: &str) -> u64 {
    id.bytes().fold(0xcbf2_9ce4_8422_2325u64, |h, b| (h ^ b as u64).wrapping_mul(0x100_0000_01b3))
}

/// The seed of one realization.
pub fn job_seed(base: u64, exp: &Experiment, curve: usize, seed_index: usize) -> u64 {
    let c = if exp.distinct_ensembles { curve as u64 + 1 } else { 0 };
    mix(mix(base ^ fig_hash(exp.id)) ^ mix(c.wrapping_mul(1_000_003) ^ seed_index as u64))
}

/// The seed of realization `seed_index` of a figure beyond the thesis (`id`, e.g. `"B-1"`):
/// every level and method of that figure shares it (common random numbers).
pub fn beyond_seed(base: u64, id: &str, seed_index: usize) -> u64 {
    mix(mix(base ^ fig_hash(id)) ^ mix(0xB_E70D ^ seed_index as u64))
}

/// The seed of realization `seed_index` of curve `curve` of a figure beyond the thesis whose
/// curves are independent ensembles (Fig B-3's road classes): distinct from
/// [`beyond_seed`]'s and from every other curve's.
pub fn beyond_class_seed(base: u64, id: &str, curve: usize, seed_index: usize) -> u64 {
    mix(beyond_seed(base, id, seed_index) ^ mix(0xC1A5_5000 ^ (curve as u64 + 1)))
}
