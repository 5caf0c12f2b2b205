//! A bake split over a farm by eye-sample ranges, and the merge that makes it one stack.
//!
//! A bake is a sum over eye samples, and every eye sample draws its random numbers from a
//! counter-based stream indexed by (seed, pixel, sample) ([`crate::geometry::sampling`]), so
//! partition `i` of `N` traces samples `[i·spp/N, (i+1)·spp/N)` exactly as a one-machine bake
//! traces them. It writes a partial stack ([`crate::bake::farm::partial`]): per layer the sums of
//! its samples in the aligned blocks of the canonical summation tree
//! ([`crate::bake::schedule::blocks`]). Work that needs the whole frame runs once: the guide pass
//! before the partitions ([`super::guide_file`]), and in [`merge`] the sum, the average, grey
//! detection, the denoiser, layer dropping and the header — the same code as a one-machine bake, on
//! the same bits, so the merged stack is bit-identical to it (`tests/farm.rs` checks every sample
//! of every layer and the header, for 1, 2, 3 and 7 partitions).

use std::ops::Range;
use std::path::{Path, PathBuf};
use std::time::Instant;

use super::guide_file::GuideFile;
use crate::bake::farm::partial::{BlockInfo, PartialHeader, PartialStack, PARTIAL_FORMAT_VERSION};
use crate::bake::finish::assemble::assemble;
use crate::bake::prepare::context::BakeContext;
use crate::bake::schedule::blocks::BlockStore;
use crate::bake::schedule::trace::trace_range;
use crate::bake::settings::{BakeSettings, IndirectSampling};
use crate::bake::{finish::denoise, prepare::estimate, schedule::tiles, BakeReport};
use crate::progress::{Progress, Stage};
use crate::scene::{hash::scene_hash, Scene};
use crate::stack::tiled::TiledStack;
use crate::stack::TransferStack;
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

/// Bakes partition `partition` of `scene`: its eye samples, summed in the canonical tree.
/// `guide` is the guide file of a guided bake (checked against the scene and settings);
/// without one a guided partition runs the guide pass itself (deterministic: the same trees,
/// at the cost of repeating it on every machine). `scene_path` is recorded for the merge.
pub fn bake_partition(
    scene: &Scene,
    scene_path: Option<&Path>,
    settings: &BakeSettings,
    partition: Partition,
    guide: Option<GuideFile>,
    progress: &Progress,
) -> Result<(PartialStack, Vec<String>)> {
    let start = Instant::now();
    settings.validate()?;
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
    let forecast = estimate::estimate_dense(&mut ctx, scene, 1, prepared, progress)?;
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
    let rays = std::sync::atomic::AtomicU64::new(0);
    let mut store = BlockStore::default();
    progress.set_stage(Stage::Tracing);
    progress.start(tiles::tiles(ctx.resolution).len() as u64 * samples.len() as u64);
    trace_range(
        &ctx,
        &mut store,
        samples.start,
        samples.end,
        false,
        progress,
        &rays,
    )?;
    progress.check()?;
    let blocks = store
        .blocks
        .iter()
        .map(|b| BlockInfo {
            samples: [b.range.start, b.range.end],
            layers: b
                .layers
                .iter()
                .enumerate()
                .filter(|(_, l)| l.lock().is_ok_and(|l| l.is_some()))
                .map(|(i, _)| i as u32)
                .collect(),
        })
        .collect();
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
        layer_count: ctx.layer_count() as u32,
        blocks,
        rays: rays.load(std::sync::atomic::Ordering::Relaxed),
        seconds: start.elapsed().as_secs_f64(),
    };
    progress.set_stage(Stage::Done);
    Ok((
        PartialStack {
            header,
            blocks: store.blocks,
        },
        warnings,
    ))
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

/// [`merge_tiled`], expanded to the dense stack ([`TiledStack::to_dense`]).
pub fn merge(
    scene: &Scene,
    parts: Vec<(PathBuf, PartialStack)>,
    threads: usize,
    progress: &Progress,
) -> Result<(TransferStack, BakeReport)> {
    let (stack, report) = merge_tiled(scene, parts, threads, progress)?;
    Ok((stack.to_dense()?, report))
}

/// Merges the partial stacks of one bake of `scene` (read from the paths beside them) into
/// the stack a one-machine bake with the same settings makes, bit for bit: checks
/// ([`check_parts`], and the scene's hash), sums in the canonical tree, finalises (as
/// full frames: a merge's memory stays dense). `threads` (0: all cores) are the merge
/// machine's. All parts in memory: see [`merge_files_tiled`] for the streaming form.
pub fn merge_tiled(
    scene: &Scene,
    parts: Vec<(PathBuf, PartialStack)>,
    threads: usize,
    progress: &Progress,
) -> Result<(TiledStack, BakeReport)> {
    let headers: Vec<(PathBuf, PartialHeader)> = parts
        .iter()
        .map(|(p, s)| (p.clone(), s.header.clone()))
        .collect();
    let mut slots: Vec<Option<PartialStack>> = parts.into_iter().map(|(_, s)| Some(s)).collect();
    merge_with(
        scene,
        headers,
        |i| Ok(slots[i].take().expect("each part once")),
        threads,
        None,
        progress,
    )
}

/// [`merge_files_tiled`], expanded to the dense stack ([`TiledStack::to_dense`]).
pub fn merge_files(
    scene: &Scene,
    paths: &[PathBuf],
    threads: usize,
    progress: &Progress,
) -> Result<(TransferStack, BakeReport)> {
    let (stack, report) = merge_files_tiled(scene, paths, threads, progress)?;
    Ok((stack.to_dense()?, report))
}

/// [`merge_tiled`] of partial stack files: every header is checked first, then the parts
/// are read one at a time in sample order and folded in as they come, so the merge holds
/// at most ≈ log2(parts) + 1 blocks of sums (one, two… full-frame stacks of f32), not
/// every part.
pub fn merge_files_tiled(
    scene: &Scene,
    paths: &[PathBuf],
    threads: usize,
    progress: &Progress,
) -> Result<(TiledStack, BakeReport)> {
    merge_files_tiled_within(scene, paths, threads, None, progress)
}

/// [`merge_files_tiled`] within `memory_budget` bytes (`None`: the default budget,
/// [`crate::memory::budget_bytes`]): the merge's peak is forecast from the parts' headers
/// ([`merge_peak_bytes`]) and a merge over the budget is refused before any part's body is
/// read.
pub fn merge_files_tiled_within(
    scene: &Scene,
    paths: &[PathBuf],
    threads: usize,
    memory_budget: Option<u64>,
    progress: &Progress,
) -> Result<(TiledStack, BakeReport)> {
    let headers = paths
        .iter()
        .map(|p| {
            Ok((
                p.clone(),
                crate::bake::farm::partial::read_partial_header(p)?,
            ))
        })
        .collect::<Result<Vec<_>>>()?;
    merge_with(
        scene,
        headers,
        |i| crate::bake::farm::partial::read_partial(&paths[i]),
        threads,
        memory_budget,
        progress,
    )
}

/// The merge's peak memory, forecast from the parts' headers alone (nothing of their
/// bodies is read): the scene and its geometry (with the BVH build), then the larger of
/// loading — the sums the store holds (at most ⌊log2 blocks⌋ + 1 blocks of every layer any
/// part reached, in f32 RGB, with their features) and the part being read — and assembling
/// — the folded sums, their averages and the stack at its precision, and the denoiser's
/// weights and per-worker copies. Every layer counts three channels, so the forecast errs
/// towards refusing.
pub fn merge_peak_bytes(
    scene: &Scene,
    headers: &[(PathBuf, PartialHeader)],
    threads: usize,
) -> u64 {
    let Some(h0) = headers.first().map(|(_, h)| h) else {
        return 0;
    };
    let px = h0.width as u64 * h0.height as u64;
    let feature = denoise::FEATURE_STRIDE as u64;
    let layers = layers_in_parts(headers) as u64;
    let block_bytes = |l: u64| px.saturating_mul(4 * (feature + 3 * l));
    let largest_part = headers
        .iter()
        .map(|(_, h)| {
            h.blocks
                .iter()
                .map(|b| block_bytes(b.layers.len() as u64))
                .fold(0u64, u64::saturating_add)
        })
        .max()
        .unwrap_or(0);
    let blocks: u64 = headers.iter().map(|(_, h)| h.blocks.len() as u64).sum();
    let held = (blocks.max(1).ilog2() as u64 + 1).saturating_mul(block_bytes(layers));
    let loading = held.saturating_add(largest_part);
    let sample = match h0.settings.precision {
        crate::options::Precision::F16 => 2,
        crate::options::Precision::F32 => 4,
    };
    let threads = if threads == 0 {
        std::thread::available_parallelism().map_or(1, |n| n.get())
    } else {
        threads
    } as u64;
    let averaged = px.saturating_mul(layers).saturating_mul(12 + 3 * sample);
    let denoise = px.saturating_mul(25 * 4 + threads * 12);
    let assembling = block_bytes(layers)
        .saturating_add(averaged)
        .saturating_add(denoise);
    let triangles = scene.triangle_count() as u64;
    let geometry =
        triangles * (estimate::BYTES_PER_TRIANGLE + estimate::BVH_BUILD_BYTES_PER_TRIANGLE);
    estimate::scene_bytes(scene)
        .saturating_add(geometry)
        .saturating_add(loading.max(assembling))
}

/// Layers any block of any part reached.
fn layers_in_parts(headers: &[(PathBuf, PartialHeader)]) -> usize {
    let mut all: Vec<u32> = headers
        .iter()
        .flat_map(|(_, h)| h.blocks.iter().flat_map(|b| b.layers.iter().copied()))
        .collect();
    all.sort_unstable();
    all.dedup();
    all.len()
}

fn merge_with(
    scene: &Scene,
    headers: Vec<(PathBuf, PartialHeader)>,
    mut load: impl FnMut(usize) -> Result<PartialStack>,
    threads: usize,
    memory_budget: Option<u64>,
    progress: &Progress,
) -> Result<(TiledStack, BakeReport)> {
    let start = Instant::now();
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
    let h = &headers[0].1;
    crate::memory::check_budget(
        &format!(
            "this merge ({} parts of {}×{}, {} of {} possible layers reached)",
            headers.len(),
            h.width,
            h.height,
            layers_in_parts(&headers),
            h.layer_count
        ),
        merge_peak_bytes(scene, &headers, threads),
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
    let mut store = BlockStore::default();
    for i in order {
        progress.check()?;
        let part = load(i)?;
        if part.header.samples != headers[i].1.samples
            || part.header.settings_hash != h0.settings_hash
        {
            return Err(RelumeError::invalid(
                "partial stacks",
                format!("{} changed while the merge read it", headers[i].0.display()),
            ));
        }
        for block in part.blocks {
            store.push(block);
        }
    }
    progress.check()?;
    let (sums, feature_sums) = store.fold();
    let eye_features = denoise::EyeFeatures::from_sums(&ctx, &feature_sums, settings.spp);
    drop(feature_sums);
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .map_err(|e| RelumeError::invalid("threads", e.to_string()))?;
    let (stack, mut report, _) = assemble(
        &ctx,
        scene,
        &settings,
        &sums,
        &eye_features,
        settings.spp,
        &pool,
        progress,
        true,
        false,
    )?;
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
