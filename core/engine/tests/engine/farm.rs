//! A bake split into sample-range partitions and merged is bit-identical to one bake with the
//! same settings (every sample of every layer, the header, the file read back); parts that are
//! missing, duplicated or foreign are refused by name.
use crate::common;

use std::path::{Path, PathBuf};

use relume_engine::bake::farm::guide_file::{build_guide, read_guide, write_guide};
use relume_engine::bake::farm::partial::verify_partial;
use relume_engine::bake::farm::partition::{bake_partition, merge_files, Partition};
use relume_engine::bake::presets::Preset;
use relume_engine::bake::{bake, bake_progressive, BakeSettings, LightGrouping};
use relume_engine::progress::Progress;
use relume_engine::scene::{Scene, World};
use relume_engine::stack::exr_file::{read_stack, write_stack};
use relume_engine::stack::{LayerSamples, TransferStack};

/// The Cornell box with a second (coloured point) light and a dim world, at `size`² — not a
/// multiple of the 16-px bake tiles or the 8-px guide tiles.
fn two_lights(size: u32) -> Scene {
    common::cornell_two_lights(size)
}

/// The preview preset (guided sampling, denoised bounce layers) with one group per light.
fn preview_per_light() -> BakeSettings {
    let mut s = BakeSettings {
        seed: 7,
        light_grouping: LightGrouping::PerLight,
        ..BakeSettings::default()
    };
    Preset::Preview.apply(&mut s);
    s
}

fn assert_identical(a: &TransferStack, b: &TransferStack, what: &str) {
    assert_eq!(a.header, b.header, "{what}: headers differ");
    assert_eq!(
        a.layers.len(),
        b.layers.len(),
        "{what}: layer counts differ"
    );
    for (x, y) in a.layers.iter().zip(&b.layers) {
        let name = x.key.layer_name();
        assert_eq!(x.key, y.key, "{what}: layer keys differ");
        assert_eq!(x.channels, y.channels, "{what}: {name}");
        assert_eq!(x.scale.to_bits(), y.scale.to_bits(), "{what}: {name} scale");
        let bits = |l: &LayerSamples| -> Vec<u32> {
            match l {
                LayerSamples::F16(v) => v.iter().map(|h| h.to_bits() as u32).collect(),
                LayerSamples::F32(v) => v.iter().map(|f| f.to_bits()).collect(),
            }
        };
        let (bx, by) = (bits(&x.samples), bits(&y.samples));
        let differing = bx.iter().zip(&by).filter(|(p, q)| p != q).count();
        assert_eq!(
            differing,
            0,
            "{what}: {name}: {differing} of {} samples differ",
            bx.len()
        );
    }
}

/// Bakes every partition of a split in `n` into the files a farm would copy; returns their
/// paths.
fn bake_parts(
    scene: &Scene,
    settings: &BakeSettings,
    n: u32,
    guide: Option<&Path>,
    dir: &Path,
) -> Vec<PathBuf> {
    (0..n)
        .map(|i| {
            // Thread counts differ between machines: the result must not care.
            let settings = BakeSettings {
                threads: 1 + (i as usize % 2),
                ..settings.clone()
            };
            let g = guide.map(|g| read_guide(g).unwrap());
            let path = dir.join(format!("part_{n}_{i}.rpart"));
            bake_partition(
                scene,
                None,
                &settings,
                Partition { index: i, count: n },
                g,
                &path,
                &Progress::new(),
            )
            .unwrap();
            path
        })
        .collect()
}

/// Merges the parts `paths` (any order) into a dense stack for the comparisons.
fn merge(scene: &Scene, paths: &[PathBuf]) -> relume_engine::Result<TransferStack> {
    let (stack, _) = merge_files(scene, paths, 0, None, &Progress::new())?;
    stack.to_dense()
}

#[test]
fn split_in_1_2_3_and_7_partitions_merges_to_the_bits_of_one_bake() {
    let dir = tempfile::tempdir().unwrap();
    let scene = two_lights(20);
    let settings = preview_per_light();
    let (single, _) = bake(&scene, &settings, &Progress::new()).unwrap();
    assert!(single.header.denoise.bounce_iterations > 0 && single.header.sampling == "guided");
    assert_eq!(
        single.header.light_groups.len(),
        3,
        "two lights and the world"
    );
    let single_file = dir.path().join("single.exr");
    write_stack(&single_file, &single).unwrap();

    let guide = dir.path().join("guide.rguide");
    let field = build_guide(&scene, &settings, &Progress::new()).unwrap();
    assert!(field.is_some());
    write_guide(&guide, &scene, &settings, field.as_ref()).unwrap();

    for n in [1u32, 2, 3, 7] {
        // One split lets the partitions run the guide pass themselves: the same trees.
        let g = (n != 2).then_some(guide.as_path());
        let parts = bake_parts(&scene, &settings, n, g, dir.path());
        let merged = merge(&scene, &parts).unwrap();
        assert_identical(&single, &merged, &format!("{n} partitions"));
        // The files too (their bytes are not compared: the OpenEXR encoder writes chunks in
        // the order its threads finish them, so two writes of one stack differ in layout).
        let merged_file = dir.path().join(format!("merged_{n}.exr"));
        write_stack(&merged_file, &merged).unwrap();
        assert_identical(
            &read_stack(&single_file).unwrap(),
            &read_stack(&merged_file).unwrap(),
            &format!("{n} partitions, read back"),
        );
    }
}

#[test]
fn a_progressive_bake_ends_on_the_bits_of_a_one_shot_bake() {
    // Passes 3 and 6 are not aligned to the summation tree's blocks; the result still is.
    let scene = common::cornell(20);
    let settings = BakeSettings {
        spp: 6,
        ..BakeSettings::default()
    };
    let (one, _) = bake(&scene, &settings, &Progress::new()).unwrap();
    let (last, _, _) = bake_progressive(
        &scene,
        &settings,
        &[1, 3, 6],
        &Progress::new(),
        |_, _, _| Ok(()),
    )
    .unwrap();
    assert_identical(&one, &last, "passes 1, 3, 6");
}

#[test]
fn a_denoised_compressed_progressive_bake_ends_on_the_bits_of_a_one_shot_bake() {
    // Guided sampling, the denoiser on both layer kinds, lattice-compressed bounce layers
    // and layer dropping: every step of the finish a pass runs from its kept tile sums.
    let scene = two_lights(37);
    let mut settings = preview_per_light();
    settings.spp = 6;
    settings.compression = settings.compression.with_step(4);
    settings.drop_budget = 0.01;
    settings.denoise.direct_iterations = settings.denoise.direct_iterations.max(1);
    settings.denoise.bounce_iterations = settings.denoise.bounce_iterations.max(2);
    let (one, one_report) = bake(&scene, &settings, &Progress::new()).unwrap();
    let mut spp_seen = Vec::new();
    let (last, last_report, reports) = bake_progressive(
        &scene,
        &settings,
        &[2, 5, 6],
        &Progress::new(),
        |stack, _, pass| {
            assert_eq!(stack.header.spp, pass.spp);
            spp_seen.push(pass.spp);
            Ok(())
        },
    )
    .unwrap();
    assert_eq!(spp_seen, vec![2, 5, 6]);
    assert!(reports[0].estimated_rel_error.is_none());
    assert!(reports[1..].iter().all(|r| r
        .estimated_rel_error
        .is_some_and(|e| e.is_finite() && e > 0.0)));
    assert_identical(&one, &last, "denoised, compressed, passes 2, 5, 6");
    assert_eq!(one_report.layers_grey, last_report.layers_grey);
    assert_eq!(one_report.layers_rgb, last_report.layers_rgb);
    assert_eq!(one_report.tile_entries, last_report.tile_entries);
    assert_eq!(
        one_report.compression_error.to_bits(),
        last_report.compression_error.to_bits()
    );
}

#[test]
fn missing_duplicated_and_foreign_parts_are_refused_by_name() {
    let dir = tempfile::tempdir().unwrap();
    let scene = common::cornell(16);
    let settings = BakeSettings {
        spp: 6,
        ..BakeSettings::default()
    };
    let parts = |seed: u64| {
        bake_parts(
            &scene,
            &BakeSettings {
                seed,
                ..settings.clone()
            },
            3,
            None,
            &dir.path().join(format!("seed{seed}")),
        )
    };
    std::fs::create_dir_all(dir.path().join("seed0")).unwrap();
    std::fs::create_dir_all(dir.path().join("seed1")).unwrap();
    let good: Vec<PathBuf> = parts(0);
    let foreign: Vec<PathBuf> = parts(1);
    let err = |list: Vec<&PathBuf>| {
        let list: Vec<PathBuf> = list.into_iter().cloned().collect();
        merge(&scene, &list).unwrap_err().to_string()
    };

    let e = err(vec![&good[0], &good[2]]);
    assert!(
        e.contains("samples [2, 4) of 6 are missing") && e.contains("1/3"),
        "{e}"
    );
    let e = err(vec![&good[0], &good[1]]);
    assert!(
        e.contains("samples [4, 6) of 6 are missing") && e.contains("2/3"),
        "{e}"
    );
    let e = err(vec![&good[0], &good[1], &good[1], &good[2]]);
    assert!(
        e.contains("duplicated") && e.contains("part_3_1.rpart"),
        "{e}"
    );
    let e = err(vec![&good[0], &foreign[1], &good[2]]);
    assert!(
        e.contains("foreign") && e.contains("seed1") && e.contains("seed 1 (the first part: 0)"),
        "{e}"
    );
    // A scene other than the parts'.
    let mut other = scene.clone();
    other.lights.clear();
    other.world = World::Color {
        color: [1.0; 3],
        strength: 1.0,
    };
    let e = merge(&other, &good).unwrap_err().to_string();
    assert!(e.contains("another scene"), "{e}");
    // A part damaged in a copy.
    let mut bytes = std::fs::read(&good[1]).unwrap();
    let k = bytes.len() / 2;
    bytes[k] ^= 1;
    let damaged = dir.path().join("damaged.rpart");
    std::fs::write(&damaged, &bytes).unwrap();
    let e = verify_partial(&damaged).err().unwrap().to_string();
    assert!(e.contains("checksum"), "{e}");
    // The merge reads it through too, and refuses it before returning a stack.
    let e = merge(&scene, &[good[0].clone(), damaged.clone(), good[2].clone()])
        .unwrap_err()
        .to_string();
    assert!(e.contains("checksum"), "{e}");
    std::fs::write(&damaged, &bytes[..k]).unwrap();
    let e = verify_partial(&damaged).err().unwrap().to_string();
    assert!(e.contains("truncated"), "{e}");
    // A part of the old dense format (version 1) is refused by its version.
    let text = std::fs::read(&good[1]).unwrap();
    let at = text
        .windows(18)
        .position(|w| w == b"\"format_version\":2")
        .expect("the header names its version");
    let mut old = text.clone();
    old[at + 17] = b'1';
    let old_part = dir.path().join("old.rpart");
    std::fs::write(&old_part, &old).unwrap();
    let e = verify_partial(&old_part).err().unwrap().to_string();
    assert!(
        e.contains("format version 1") && e.contains("reads version 2"),
        "{e}"
    );
    // And the good parts, in any order, merge.
    merge(&scene, &[good[2].clone(), good[0].clone(), good[1].clone()]).unwrap();
}
