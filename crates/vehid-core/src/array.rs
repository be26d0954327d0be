//! Fixed-size arrays read back from a sequence of items without allocating (how the
//! array stores of the identifiers and of the axle sampler are deserialized).

/// `[x; K]` filled from `items` (exactly `K` of them; `K ≥ 1`), without allocating.
pub(crate) fn array_from_items<X: Copy, E, const K: usize>(
    items: impl Iterator<Item = core::result::Result<X, E>>,
) -> core::result::Result<Option<[X; K]>, E> {
    let mut out: Option<[X; K]> = None;
    let mut len = 0;
    for item in items {
        let x = item?;
        if len == K {
            return Ok(None);
        }
        out.get_or_insert([x; K])[len] = x;
        len += 1;
    }
    Ok(out.filter(|_| len == K))
}
