//! Ray tracing and sampling: BVH, camera rays, light and hemisphere sampling.
