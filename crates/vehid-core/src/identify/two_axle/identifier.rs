//! [`TwoAxle`] behind the [`Identifier`] interface, and its persistence (`Persist`).

use super::*;

crate::identify::persist_by_serde!([T: Real, const N: usize, const P: usize, S: Store<T, N>, B: RingStore<Past<T, N>>, const M: usize] TwoAxle<T, N, P, S, B, M>);

impl<T: Real, const N: usize, const P: usize, S: Store<T, N>, B: RingStore<Past<T, N>>, const M: usize> Identifier<T>
    for TwoAxle<T, N, P, S, B, M>
{
    fn dims(&self) -> Dims {
        let k = self.rows.len();
        Dims { states: N, inputs: 0, equations: k, params: k * N }
    }

    fn rows(&self) -> &[usize] {
        self.rows.as_slice()
    }

    /// The sample on the road point after the previous one ([`TwoAxle::update_next`]).
    fn update_into(&mut self, x: &[T], z: &[T], u: &[T], e: &mut [T]) -> Result<()> {
        check_lengths(self.dims(), x, z, u, e)?;
        self.update_at(&vector(x), &vector(z), None, e).map(|_| ())
    }

    fn params_into(&self, out: &mut [T]) -> Result<()> {
        self.theta_into(out)
    }

    fn samples(&self) -> u64 {
        self.samples
    }

    /// The road point of the sample left out passes: the next sample is on the point after it.
    fn skip_sample(&mut self) {
        self.last_grid = Some(self.last_grid.map_or(0, |g| g.saturating_add(1)));
    }
}
