//! A bake split over a farm by eye-sample ranges, and the merge that makes it one stack.
//!
//! A bake is a sum over eye samples, and every eye sample draws its random numbers from a
//! counter-based stream indexed by (seed, pixel, sample) ([`crate::geometry::sampling`]), so
//! partition `i` of `N` traces samples `[i·spp/N, (i+1)·spp/N)` exactly as a one-machine bake
//! traces them. It streams a partial stack ([`crate::bake::farm::partial`]) tile by tile: per
//! tile and per layer reached there the sums of its samples in the aligned blocks of the
//! canonical summation tree ([`crate::bake::schedule::blocks`]). Work that needs the whole frame
//! runs once: the guide pass before the partitions ([`super::guide_file`]), and in
//! [`merge_files`] the sum, the average, grey detection, the denoiser, layer dropping and the
//! header — the one-machine bake's streaming finish ([`crate::bake::schedule::stream`]) fed
//! with the parts' tiles instead of traced ones, on the same bits, so the merged file is the
//! one-machine bake's, byte for byte (`core/cli/tests/farm.rs`, `tests/engine/farm.rs`).

use std::ops::Range;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::Instant;

use rayon::prelude::*;

use super::guide_file::GuideFile;
use crate::bake::farm::partial::{
    PartialHeader, PartialReader, PartialWriter, TileSums, PARTIAL_FORMAT_VERSION,
};
use crate::bake::path::vertex_brdf::BasisBrdf;
use crate::bake::prepare::context::BakeContext;
use crate::bake::schedule::blocks::dyadic_blocks;
use crate::bake::schedule::summed_finish::finish_summed_tiles;
use crate::bake::schedule::tile_sums::TileBlocks;
use crate::bake::schedule::{band, tiles};
use crate::bake::settings::{BakeSettings, IndirectSampling};
use crate::bake::{prepare::estimate, BakeReport};
use crate::progress::{Progress, Stage};
use crate::scene::{hash::scene_hash, Scene};
use crate::stack::tiled::{tiles_along, TiledStack};
use crate::{RelumeError, Result};

/// Partition `index` of `count` (`--partition index/count`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Partition {
    pub index: u32,
    pub count: u32,
}

impl Partition {
    /// Parses `i/N` with 0 ≤ i < N.
    pub fn parse(text: &str) -> Result<Partition> {
        let bad = || {
            RelumeError::invalid(
                "--partition",
                format!("\"{text}\" (expected i/N with 0 ≤ i < N, e.g. 0/4)"),
            )
        };
        let (i, n) = text.split_once('/').ok_or_else(bad)?;
        let p = Partition {
            index: i.trim().parse().map_err(|_| bad())?,
            count: n.trim().parse().map_err(|_| bad())?,
        };
        if p.count == 0 || p.index >= p.count {
            return Err(bad());
        }
        Ok(p)
    }

    /// The eye samples of this partition of a bake of `spp`: `[i·spp/N, (i+1)·spp/N)`.
    pub fn samples(&self, spp: u32) -> Range<u32> {
        let at = |i: u32| (i as u64 * spp as u64 / self.count as u64) as u32;
        at(self.index)..at(self.index + 1)
    }
}

pub use crate::bake::settings::{normalized, settings_fingerprint};

/// Bakes partition `partition` of `scene` into the partial stack `output`: its eye samples,
/// summed in the canonical tree, traced in bands of tile rows and written tile by tile, so
/// the partition holds the tiles in flight, not a frame per layer. `guide` is the guide file
/// of a guided bake (checked against the scene and settings); without one a guided partition
/// runs the guide pass itself (deterministic: the same trees, at the cost of repeating it on
/// every machine). `scene_path` is recorded for the merge. Returns the file's header, the
/// warnings and the bytes written.
pub fn bake_partition(
    scene: &Scene,
    scene_path: Option<&Path>,
    settings: &BakeSettings,
    partition: Partition,
    guide: Option<GuideFile>,
    output: &Path,
    progress: &Progress,
) -> Result<(PartialHeader, Vec<String>, u64)> {
    let start = Instant::now();
    settings.validate()?;
    if !settings.adaptive.is_off() {
        return Err(RelumeError::invalid(
            "adaptive_threshold",
            format!(
                "a farm splits the bake by eye-sample ranges, and adaptive sampling decides per tile from all the samples before its range whether to take it, so partition {}/{} cannot know its tiles' samples: bake it with an adaptive threshold of 0, or on one machine",
                partition.index, partition.count
            ),
        ));
    }
    let samples = partition.samples(settings.spp);
    if samples.is_empty() {
        return Err(RelumeError::invalid(
            "--partition",
            format!(
                "{}/{} of {} samples is empty: use at most {} partitions",
                partition.index, partition.count, settings.spp, settings.spp
            ),
        ));
    }
    let hash = scene_hash(scene);
    let fingerprint = settings_fingerprint(settings);
    progress.set_stage(Stage::Setup);
    let (mut ctx, validation, prepared) = estimate::prepare_measured(scene, settings, progress)?;
    // The one-machine bake's streaming forecast: a partition holds what its trace holds
    // (bands of sparse tiles), without the stack, so this errs towards refusing.
    let forecast = estimate::estimate(&mut ctx, scene, 1, prepared, progress)?;
    crate::memory::check_budget(
        &format!(
            "this partition ({}×{}, {} of {} possible layers reached by a probe)",
            forecast.width, forecast.height, forecast.layers_reached, forecast.layers_possible
        ),
        forecast.peak_bytes,
        settings.memory_budget,
    )?;
    let mut warnings = validation.warnings;
    let guided = settings.sampling == IndirectSampling::Guided && settings.bounces >= 1;
    let guide_hash = match guide {
        Some(g) => {
            if g.header.scene_hash != hash {
                return Err(RelumeError::invalid(
                    "--guide",
                    format!(
                        "the guide was made for another scene (hash {}, this scene {hash})",
                        g.header.scene_hash
                    ),
                ));
            }
            if g.header.settings_hash != fingerprint {
                return Err(RelumeError::invalid(
                    "--guide",
                    "the guide was made with other bake settings (spp, samples, seed, preset…): make it with the partitions' options",
                ));
            }
            ctx.guide = g.field;
            Some(g.hash)
        }
        None if guided => {
            warnings.push(
                "no --guide given: this partition ran the guide pass itself (the same trees; a farm saves the repeats with --guide-only first)".into(),
            );
            ctx.build_guide(scene, progress)?;
            None
        }
        None => None,
    };
    if guided != ctx.guide.is_some() && guide_hash.is_some() {
        return Err(RelumeError::invalid(
            "--guide",
            "the guide file does not match the settings' sampling",
        ));
    }
    let rays = AtomicU64::new(0);
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(settings.threads)
        .build()
        .map_err(|e| RelumeError::invalid("threads", e.to_string()))?;
    let all = tiles::tiles(ctx.resolution);
    let tx = tiles_along(ctx.resolution.width) as usize;
    let rows = pool.install(|| band::default_band_rows(ctx.resolution.width, settings.threads, 0));
    let blocks = dyadic_blocks(samples.start, samples.end);
    let layer_count = ctx.layer_count();
    let brdf = BasisBrdf { ctx: &ctx };
    let mut writer = PartialWriter::create(output, layer_count)?;
    progress.set_stage(Stage::Tracing);
    progress.start(all.len() as u64 * samples.len() as u64);
    for band in all.chunks(rows * tx) {
        progress.check()?;
        let done: Vec<Result<Vec<TileSums>>> = pool.install(|| {
            band.par_iter()
                .map(|tile| {
                    progress.check()?;
                    let sums = TileSums::traced(
                        &ctx,
                        &brdf,
                        blocks.len(),
                        tile,
                        samples.clone(),
                        progress,
                        &rays,
                    )?;
                    progress.advance(samples.len() as u64);
                    Ok(sums)
                })
                .collect()
        });
        for tile in done {
            writer.tile(&tile?)?;
        }
    }
    progress.check()?;
    let header = PartialHeader {
        format_version: PARTIAL_FORMAT_VERSION,
        engine_version: env!("CARGO_PKG_VERSION").into(),
        scene_hash: hash,
        scene_path: scene_path.map(|p| std::path::absolute(p).unwrap_or_else(|_| p.to_path_buf())),
        settings: normalized(settings),
        settings_hash: fingerprint,
        spp: settings.spp,
        samples: [samples.start, samples.end],
        partition: [partition.index, partition.count],
        guide_hash,
        width: ctx.resolution.width,
        height: ctx.resolution.height,
        layer_count: layer_count as u32,
        blocks: blocks.iter().map(|r| [r.start, r.end]).collect(),
        layers_reached: 0,
        tile_entries: 0,
        largest_tile_bytes: 0,
        bake_peak_bytes: forecast.peak_bytes,
        rays: rays.load(Ordering::Relaxed),
        seconds: 0.0,
    };
    progress.set_stage(Stage::Writing);
    let (mut header, bytes) = writer.finish(header)?;
    header.seconds = start.elapsed().as_secs_f64();
    progress.set_stage(Stage::Done);
    Ok((header, warnings, bytes))
}

fn name(part: &(PathBuf, PartialHeader)) -> String {
    format!(
        "{} (partition {}/{}, samples [{}, {}))",
        part.0.display(),
        part.1.partition[0],
        part.1.partition[1],
        part.1.samples[0],
        part.1.samples[1]
    )
}

/// Checks that `parts` (each with the path it was read from) belong to one bake — the same
/// scene hash, settings, seed, guide and engine — and cover its samples `[0, spp)` exactly
/// once. Returns the parts' order by first sample. Errors name the missing samples (and the
/// partitions that hold them), the duplicated or overlapping parts, or the foreign part.
pub fn check_parts(parts: &[(PathBuf, PartialHeader)]) -> Result<Vec<usize>> {
    let refuse = |m: String| Err(RelumeError::invalid("partial stacks", m));
    let Some(first) = parts.first() else {
        return refuse("no partial stack given".into());
    };
    let h0 = &first.1;
    for p in &parts[1..] {
        let h = &p.1;
        let differs = if h.scene_hash != h0.scene_hash {
            Some(format!(
                "scene hash {} (the first part: {})",
                h.scene_hash, h0.scene_hash
            ))
        } else if h.settings.seed != h0.settings.seed {
            Some(format!(
                "seed {} (the first part: {})",
                h.settings.seed, h0.settings.seed
            ))
        } else if h.spp != h0.spp {
            Some(format!("{} spp (the first part: {})", h.spp, h0.spp))
        } else if h.settings_hash != h0.settings_hash {
            Some("other bake settings".into())
        } else if h.engine_version != h0.engine_version {
            Some(format!(
                "engine {} (the first part: {})",
                h.engine_version, h0.engine_version
            ))
        } else if h.guide_hash != h0.guide_hash && h.guide_hash.is_some() && h0.guide_hash.is_some()
        {
            Some("another guide file".into())
        } else if (h.width, h.height, h.layer_count) != (h0.width, h0.height, h0.layer_count) {
            Some("another resolution or layer layout".into())
        } else {
            None
        };
        if let Some(d) = differs {
            return refuse(format!(
                "{} is foreign: it belongs to another bake than {} — {d}",
                name(p),
                first.0.display()
            ));
        }
    }
    let mut order: Vec<usize> = (0..parts.len()).collect();
    order.sort_by_key(|&i| (parts[i].1.samples[0], parts[i].1.samples[1]));
    let spp = h0.spp;
    let holders = |gap: Range<u32>| -> String {
        let n = h0.partition[1].max(1);
        let list: Vec<String> = (0..n)
            .filter(|&i| {
                let r = Partition { index: i, count: n }.samples(spp);
                r.start < gap.end && gap.start < r.end
            })
            .map(|i| format!("{i}/{n}"))
            .collect();
        if list.len() == 1 {
            format!("partition {}", list[0])
        } else {
            format!("partitions {}", list.join(", "))
        }
    };
    let mut next = 0u32;
    let mut prev: Option<usize> = None;
    for &i in &order {
        let [a, b] = parts[i].1.samples;
        if a > next {
            return refuse(format!(
                "samples [{next}, {a}) of {spp} are missing: {} was not given",
                holders(next..a)
            ));
        }
        if a < next {
            let other = &parts[prev.expect("a part before")];
            let what = if other.1.samples == parts[i].1.samples {
                "duplicated"
            } else {
                "overlapping"
            };
            return refuse(format!(
                "{} and {} are {what}: samples [{a}, {}) would count twice",
                name(other),
                name(&parts[i]),
                next.min(b)
            ));
        }
        next = b;
        prev = Some(i);
    }
    if next < spp {
        return refuse(format!(
            "samples [{next}, {spp}) of {spp} are missing: {} was not given",
            holders(next..spp)
        ));
    }
    Ok(order)
}

/// The merge's peak memory, forecast from the parts' headers alone (nothing of their bodies
/// is read): the one-machine bake's forecast peak, which the parts record (the merge
/// finalises as that bake does, its tiles summed from the parts instead of traced), plus
/// per part its read buffer and, twice (read, then summed), its largest tile widened to RGB.
pub fn merge_peak_bytes(headers: &[(PathBuf, PartialHeader)]) -> u64 {
    let bake = headers
        .iter()
        .map(|(_, h)| h.bake_peak_bytes)
        .max()
        .unwrap_or(0);
    let per_part =
        |h: &PartialHeader| (1u64 << 20).saturating_add(h.largest_tile_bytes.saturating_mul(6));
    headers
        .iter()
        .map(|(_, h)| per_part(h))
        .fold(bake, u64::saturating_add)
}

/// Merges the partial stack files `paths` of one bake of `scene` into the stack a
/// one-machine bake with the same settings makes, bit for bit: checks every header
/// ([`check_parts`], the scene's hash, the settings), forecasts the peak
/// ([`merge_peak_bytes`]) and refuses a merge over `memory_budget` (`None`: the default
/// budget, [`crate::memory::budget_bytes`]) before any part's body is read, then streams:
/// the parts are read side by side tile by tile, each tile's blocks summed in the canonical
/// tree and handed to the one-machine bake's streaming finish, which denoises, finalises and
/// drops as that bake does. A part damaged on its way (its checksum) fails the merge before
/// the stack is returned. `threads` (0: all cores) are the merge machine's.
pub fn merge_files(
    scene: &Scene,
    paths: &[PathBuf],
    threads: usize,
    memory_budget: Option<u64>,
    progress: &Progress,
) -> Result<(TiledStack, BakeReport)> {
    let start = Instant::now();
    let headers = paths
        .iter()
        .map(|p| {
            Ok((
                p.clone(),
                crate::bake::farm::partial::read_partial_header(p)?,
            ))
        })
        .collect::<Result<Vec<_>>>()?;
    let order = check_parts(&headers)?;
    let h0 = &headers[0].1;
    let hash = scene_hash(scene);
    if hash != h0.scene_hash {
        return Err(RelumeError::invalid(
            "partial stacks",
            format!(
                "the parts were baked from another scene (hash {}; the scene given has {hash})",
                h0.scene_hash
            ),
        ));
    }
    let settings = BakeSettings {
        threads,
        ..h0.settings.clone()
    };
    if settings_fingerprint(&settings) != h0.settings_hash {
        return Err(RelumeError::invalid(
            "partial stacks",
            "their settings do not match their own fingerprint (damaged header, or another engine build)",
        ));
    }
    let reached = headers
        .iter()
        .map(|(_, h)| h.layers_reached)
        .max()
        .unwrap_or(0);
    crate::memory::check_budget(
        &format!(
            "this merge ({} parts of {}×{}, {} of {} possible layers reached)",
            headers.len(),
            h0.width,
            h0.height,
            reached,
            h0.layer_count
        ),
        merge_peak_bytes(&headers),
        memory_budget,
    )?;
    progress.set_stage(Stage::Setup);
    let (ctx, validation) = BakeContext::prepare(scene, &settings, progress)?;
    if ctx.layer_count() as u32 != h0.layer_count
        || (ctx.resolution.width, ctx.resolution.height) != (h0.width, h0.height)
    {
        return Err(RelumeError::invalid(
            "partial stacks",
            "their layer layout differs from what this engine makes of the scene and settings",
        ));
    }
    let rays: u64 = headers.iter().map(|(_, h)| h.rays).sum();
    let trace_seconds: f64 = headers.iter().map(|(_, h)| h.seconds).sum();
    let mut readers = Vec::with_capacity(order.len());
    for &i in &order {
        let r = PartialReader::open(&paths[i])?;
        if r.header.samples != headers[i].1.samples || r.header.settings_hash != h0.settings_hash {
            return Err(RelumeError::invalid(
                "partial stacks",
                format!("{} changed while the merge read it", headers[i].0.display()),
            ));
        }
        readers.push(r);
    }
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .map_err(|e| RelumeError::invalid("threads", e.to_string()))?;
    let spp = settings.spp;
    progress.set_stage(Stage::Tracing);
    progress.start(tiles::tiles(ctx.resolution).len() as u64 * spp as u64);
    let summed = finish_summed_tiles(&ctx, scene, &settings, &pool, progress, false, |tile| {
        let mut blocks = TileBlocks::default();
        for r in readers.iter_mut() {
            let ranges: Vec<[u32; 2]> = r.header.blocks.clone();
            for (range, sums) in ranges.into_iter().zip(r.tile(tile.pixels())?) {
                blocks.push(range[0]..range[1], sums);
            }
        }
        progress.advance(spp as u64);
        Ok(blocks.fold())
    })?;
    for r in readers {
        r.finish()?;
    }
    let mut report = summed.report;
    let stack = summed.stack;
    report.seconds = start.elapsed().as_secs_f64();
    report.setup_seconds = report.seconds - report.assembly_seconds;
    report.trace_seconds = trace_seconds;
    report.rays = rays;
    report.rays_per_second = rays as f64 / trace_seconds.max(1e-9);
    report.triangles = validation.triangles;
    report.degenerate_triangles = validation.degenerate_triangles;
    let own = std::mem::take(&mut report.warnings);
    report.warnings = validation.warnings.into_iter().chain(own).collect();
    progress.set_stage(Stage::Done);
    Ok((stack, report))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn partitions_tile_the_samples() {
        for spp in [1u32, 7, 16, 128, 1000] {
            for n in 1..=spp.min(9) {
                let mut next = 0;
                for i in 0..n {
                    let r = Partition { index: i, count: n }.samples(spp);
                    assert_eq!(r.start, next);
                    assert!(!r.is_empty());
                    next = r.end;
                }
                assert_eq!(next, spp);
            }
        }
        assert_eq!(
            Partition::parse("2/7").unwrap(),
            Partition { index: 2, count: 7 }
        );
        for bad in ["7/7", "1", "a/2", "0/0", "-1/3"] {
            assert!(Partition::parse(bad).is_err(), "{bad}");
        }
    }
}
