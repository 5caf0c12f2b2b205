//! The bake split over a farm's machines by eye-sample ranges.
//!
//! - [`partition`]: a partition traces its range of eye samples exactly as a one-machine
//!   bake traces them, and the merge sums the partitions into one stack, bit-identical to
//!   that bake.
//! - [`partial`]: what a partition hands to the merge, the sums of its samples per tile,
//!   per layer reached there and per aligned block of the canonical summation tree.
//! - [`guide_file`]: the guide pass run once for all partitions, as a file.
//! - [`farm_file`]: the container both files are written in (magic, JSON header, payload,
//!   checksum), so a file damaged between machines is refused by name.
//!
//! Apart from the stages because it is another way of driving them, across processes: it
//! runs the preparation, the path, the tile tracing and the streaming finish unchanged, and
//! adds only the files and the checks that a bake on one machine never needs.

pub mod farm_file;
pub mod guide_file;
pub mod partial;
pub mod partition;
