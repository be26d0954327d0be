//! What one sample update of an identifier costs: its arithmetic and its size.

/// The arithmetic of one sample update and the identifier's size, for comparison with the
/// thesis' Table I (4-state identifier: 3.6 ms on a 1986 microprocessor, 352 bytes; 8-state
/// decoupled: 14.5 ms, 2800 bytes). Counts are of the estimator's formulas, not of the
/// input checks; an addition counts subtractions too.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Cost {
    /// Multiplications per update.
    pub multiplications: usize,
    /// Additions and subtractions per update.
    pub additions: usize,
    /// Divisions per update.
    pub divisions: usize,
    /// Square roots per update.
    pub square_roots: usize,
    /// Size of the identifier's state, bytes (`size_of_val`; for the `Vec` forms the heap
    /// buffers are added).
    pub bytes: usize,
}

impl Cost {
    /// All floating-point operations.
    pub fn flops(&self) -> usize {
        self.multiplications + self.additions + self.divisions + self.square_roots
    }
}
