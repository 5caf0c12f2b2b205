//! The sample counts of a progressive bake's passes: doubling up to the bake's count, so
//! each pass's estimate of the remaining noise is plain (see [`crate::bake::PassReport`]).
//! Its own file because the bake's entry points and the memory forecast both need it, and
//! the forecast sits below the bake's outline.

/// Sample counts of a progressive bake of `passes` passes ending at `spp`: doubling,
/// cumulative, the last one `spp`; fewer passes when `spp` runs out of halvings.
pub fn doubling_passes(spp: u32, passes: u32) -> Vec<u32> {
    let mut out: Vec<u32> = (0..passes.max(1))
        .rev()
        .map(|k| (spp >> k).max(1))
        .collect();
    out.dedup();
    out
}
