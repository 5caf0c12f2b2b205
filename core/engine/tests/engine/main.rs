//! The engine's integration tests, one module per concept, in one test binary (a binary per
//! file compiled its helpers and linked the engine once per file). Run one module with its
//! name as the filter, e.g.
//! `cargo test --release -p relume-engine --test engine tail_refinement`.

mod common;

mod adaptive_sampling;
mod area_sampling;
mod assets_scenes;
mod bake_physics;
mod bounce_kinds;
mod denoise;
mod emitters;
mod env_sampling;
mod extremes;
mod farm;
mod forecast_bounds;
mod frozen_tail;
mod hostile_inputs;
mod lattice_stack;
mod layer_dropping;
mod light_groups;
mod linearity;
mod mis;
mod non_finite;
mod pixel_features;
mod principled_basis;
mod progressive;
mod reliability;
mod relight_cpu;
mod relight_perf;
mod relight_tiled;
mod sampling_comparison;
mod scene_errors;
mod settings_fields;
mod stack_exr;
mod stack_image_io;
mod stack_write;
mod streaming_bake;
mod subsurface;
mod subsurface_basis;
mod tail_refinement;
mod tiled_stack;
mod torture;
