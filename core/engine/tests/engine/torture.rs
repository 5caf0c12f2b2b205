//! The numerical torture test: generated scenes that are valid but extreme — albedos 0 and
//! 1, both ends of roughness, metals, lights from 1e-30 to 1e30 W in one scene, tiny and
//! huge lights and scenes, a grazing camera, sliver and coplanar triangles, an emitter
//! touching a wall, many lights, many editable regions — each baked to a file at every
//! preset and both precisions, read back and relit at the extreme edits of every editable
//! material. Every bake must complete, every stored value and every relit pixel must be
//! finite; the counts of what the stages kept finite are printed (one JSON line).
//!
//! The bounded run (in the test command) bakes each case at 12×12 with at most 4 eye
//! samples, one seed; the presets' other values (light and indirect samples, sampling,
//! basis tolerance, denoiser, compression, bounce budget) are theirs. The full run,
//! `RELUME_TORTURE=full cargo test --release -p relume-engine --test engine torture -- --ignored
//! --nocapture` (`scripts/torture.sh`), uses each preset's own sample counts at 24×24 and
//! three seeds.
use crate::common;

use std::sync::Arc;

use common::{bp, quad, region, sphere};
use relume_engine::bake::presets::Preset;
use relume_engine::bake::to_file::bake_to_file;
use relume_engine::bake::BakeSettings;
use relume_engine::brdf::MaterialSpec;
use relume_engine::options::Precision;
use relume_engine::progress::Progress;
use relume_engine::relight::CpuRelighter;
use relume_engine::scene::{AreaShape, Light, Resolution, Scene};
use relume_engine::stack::bases::StackBases;
use relume_engine::stack::tiled::file::read_tiled;
use relume_engine::stack::tiled::TileValues;

fn principled(base: f32, metallic: f32, roughness: f32) -> MaterialSpec {
    serde_json::from_value(serde_json::json!({
        "model": "principled",
        "base_color": [base, base, base],
        "metallic": metallic,
        "roughness": roughness,
    }))
    .unwrap()
}

fn area(position: [f32; 3], size: f32, power: f32) -> Light {
    Light::Area {
        position,
        axis_u: [1.0, 0.0, 0.0],
        axis_v: [0.0, 1.0, 0.0],
        shape: AreaShape::Square,
        size_x: size,
        size_y: None,
        power,
        color: [1.0, 0.9, 0.8],
        visible_camera: true,
    }
}

fn point(position: [f32; 3], power: f32) -> Light {
    Light::Point {
        position,
        power,
        color: [1.0, 1.0, 1.0],
        radius: 0.0,
    }
}

/// The Cornell box scaled by `s`, its clip range too.
fn box_scaled(s: f32) -> Scene {
    let mut scene = common::cornell_scaled(12, s);
    scene.camera.clip_end *= s;
    scene
}

/// The generated cases: a name and a scene.
fn cases() -> Vec<(&'static str, Scene)> {
    let mut out = Vec::new();

    let mut s = common::cornell(12);
    s.regions[0].material = bp(1.0, 0.0, 1.0);
    s.regions[1].material = bp(0.0, 1.0, 1e4);
    out.push(("albedo 1 walls, mirror-like object", s));

    let mut s = common::cornell(12);
    s.regions[0].material = bp(0.0, 0.0, 1.0);
    s.regions[1].material = bp(0.0, 0.0, 1.0);
    out.push(("black editable regions", s));

    let mut s = common::cornell(12);
    s.regions[0].material = principled(1.0, 1.0, 0.0);
    s.regions[1].material = principled(0.8, 1.0, 1.0);
    out.push(("metals at both roughness ends", s));

    let mut s = common::cornell(12);
    s.lights = vec![
        area([0.0, 0.0, 0.98], 0.5, 1e30),
        point([0.5, 0.0, 0.5], 1e-30),
    ];
    out.push(("lights of 1e30 and 1e-30 W together", s));

    let mut s = common::cornell(12);
    s.lights = vec![area([0.0, 0.0, 0.98], 0.5, 1e-30)];
    out.push(("only a 1e-30 W light", s));

    let mut s = common::cornell(12);
    s.lights = vec![area([0.0, 0.0, 0.98], 1e-6, 40.0)];
    out.push(("a light of side 1 µm", s));

    let mut s = common::cornell(12);
    s.lights = vec![area([0.0, 0.0, 0.0], 1.9, 40.0)];
    out.push(("a light almost as wide as the box", s));

    let mut s = common::cornell(12);
    // On the ceiling itself, facing down: the emitter touches the surface.
    s.lights = vec![area([0.0, 0.0, 1.0], 0.5, 40.0)];
    out.push(("an emitter touching the ceiling", s));

    out.push(("a box 1e-4 m wide", box_scaled(1e-4)));
    out.push(("a box 1e4 m wide", box_scaled(1e4)));

    let mut s = common::cornell(12);
    s.camera = common::look_at([0.0, -3.9, -0.999], [0.0, 3.0, -0.999], 35.0);
    out.push(("a camera grazing the floor", s));

    let mut s = common::cornell(12);
    // A sliver (one side 1e-7 of the others) and a quad coplanar with the back wall.
    s.meshes.push(quad(
        "sliver",
        [-0.5, 0.0, -0.5],
        [0.5, 0.0, -0.5],
        [0.5, 0.0, -0.4999999],
        [-0.5, 0.0, -0.4999999],
        1,
    ));
    s.meshes.push(quad(
        "coplanar",
        [-0.5, 1.0, -0.5],
        [0.5, 1.0, -0.5],
        [0.5, 1.0, 0.5],
        [-0.5, 1.0, 0.5],
        1,
    ));
    out.push(("sliver and coplanar triangles", s));

    let mut s = common::cornell(12);
    s.lights = (0..64)
        .map(|i| {
            let a = i as f32 * 0.7;
            point([0.8 * a.cos(), 0.8 * a.sin(), 0.5], 1.0)
        })
        .collect();
    out.push(("64 point lights", s));

    let mut s = common::cornell(12);
    for k in 0..8u32 {
        let r = s.regions.len() as u32;
        s.regions.push(region(
            &format!("Ball {k}"),
            true,
            bp(0.1 * k as f32, 0.1, 50.0),
        ));
        let x = -0.8 + 0.22 * k as f32;
        s.meshes
            .push(sphere(&format!("ball {k}"), [x, -0.3, -0.85], 0.1, 6, 8, r));
    }
    out.push(("ten editable regions", s));
    out
}

/// The extreme edits every editable material is relit at.
fn extreme_edits() -> Vec<MaterialSpec> {
    vec![
        bp(0.0, 0.0, 1.0),
        bp(1.0, 0.0, 1.0),
        bp(0.0, 1.0, 1e6),
        bp(0.0, 1.0, 1e-3),
        principled(1.0, 1.0, 0.0),
        principled(1.0, 0.0, 1.0),
        principled(0.0, 0.0, 0.0),
    ]
}

struct Tally {
    bakes: usize,
    relights: usize,
    lost: Vec<String>,
    non_finite_stack: usize,
    non_finite_pixels: usize,
    discarded: u64,
    layer_values: u64,
    lattice_fits: u64,
    stored_values: u64,
}

fn run(size: u32, spp_cap: Option<u32>, seeds: &[u64], precisions: &[Precision]) -> Tally {
    let mut t = Tally {
        bakes: 0,
        relights: 0,
        lost: Vec::new(),
        non_finite_stack: 0,
        non_finite_pixels: 0,
        discarded: 0,
        layer_values: 0,
        lattice_fits: 0,
        stored_values: 0,
    };
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("s.exr");
    let edits = extreme_edits();
    for (name, scene) in cases() {
        for preset in Preset::ALL {
            for &precision in precisions {
                for &seed in seeds {
                    let mut s = BakeSettings {
                        seed,
                        threads: 2,
                        precision,
                        bounces: 4,
                        resolution: Some(Resolution {
                            width: size,
                            height: size,
                        }),
                        ..BakeSettings::default()
                    };
                    preset.apply(&mut s);
                    if let Some(cap) = spp_cap {
                        s.spp = s.spp.min(cap);
                    }
                    let what = format!("{name}, {}, {precision:?}, seed {seed}", preset.name());
                    t.bakes += 1;
                    let report =
                        match bake_to_file(&scene, &s, 1, &path, &Progress::new(), |_, _| {}) {
                            Ok(b) => b.report,
                            Err(e) => {
                                t.lost.push(format!("{what}: {e}"));
                                continue;
                            }
                        };
                    t.discarded += report.non_finite.path_contributions;
                    t.layer_values += report.non_finite.layer_values;
                    t.lattice_fits += report.non_finite.lattice_fits;
                    t.stored_values += report.non_finite.stored_values;
                    let stack = match read_tiled(&path) {
                        Ok(s) => s,
                        Err(e) => {
                            t.lost.push(format!("{what}: written but unreadable: {e}"));
                            continue;
                        }
                    };
                    t.non_finite_stack += stack
                        .tiles
                        .iter()
                        .map(|tile| match &tile.values {
                            TileValues::F16(v) => v.iter().filter(|x| !x.is_finite()).count(),
                            TileValues::F32(v) => v.iter().filter(|x| !x.is_finite()).count(),
                        })
                        .sum::<usize>();
                    let bases = StackBases::from_header(&stack.header).unwrap();
                    let editable = scene.regions.iter().filter(|r| r.editable).count();
                    let mut relighter = CpuRelighter::from_tiled(Arc::new(stack)).unwrap();
                    for edit in &edits {
                        let specs = vec![edit.clone(); editable];
                        let coefs = bases.coefficients(&specs).unwrap();
                        let image = relighter.relight(&coefs).unwrap();
                        t.relights += 1;
                        let bad = image.iter().filter(|v| !v.is_finite()).count();
                        if bad > 0 {
                            eprintln!("{what}: {bad} non-finite values relit at {edit:?}");
                        }
                        t.non_finite_pixels += bad;
                    }
                }
            }
        }
    }
    println!(
        "{{\"cases\": {}, \"bakes\": {}, \"relights\": {}, \"lost_bakes\": {}, \
         \"non_finite_stack_values\": {}, \"non_finite_relit_values\": {}, \
         \"discarded_path_contributions\": {}, \"layer_values_zeroed\": {}, \
         \"lattice_fits_kept_exact\": {}, \"builder_values_zeroed\": {}}}",
        cases().len(),
        t.bakes,
        t.relights,
        t.lost.len(),
        t.non_finite_stack,
        t.non_finite_pixels,
        t.discarded,
        t.layer_values,
        t.lattice_fits,
        t.stored_values
    );
    t
}

fn assert_clean(t: &Tally) {
    assert!(t.lost.is_empty(), "lost bakes:\n{}", t.lost.join("\n"));
    assert_eq!(t.non_finite_stack, 0, "non-finite values in written stacks");
    assert_eq!(t.non_finite_pixels, 0, "non-finite relit values");
    assert_eq!(
        t.stored_values, 0,
        "the builder had to zero values the stages before it let through"
    );
}

// The bounded run, one test per precision: a run spends most of its time on one core
// (each bake is small), so the test harness runs the two side by side.
#[test]
fn every_extreme_case_bakes_at_every_preset_and_relights_finite_in_f16() {
    let t = run(12, Some(4), &[0], &[Precision::F16]);
    assert_eq!(t.bakes, cases().len() * Preset::ALL.len());
    assert_clean(&t);
}

#[test]
fn every_extreme_case_bakes_at_every_preset_and_relights_finite_in_f32() {
    let t = run(12, Some(4), &[0], &[Precision::F32]);
    assert_eq!(t.bakes, cases().len() * Preset::ALL.len());
    assert_clean(&t);
}

#[test]
#[ignore = "the full matrix: scripts/torture.sh"]
fn full_torture_matrix() {
    if std::env::var("RELUME_TORTURE").as_deref() != Ok("full") {
        eprintln!("set RELUME_TORTURE=full to run the full matrix (scripts/torture.sh)");
        return;
    }
    let t = run(24, None, &[0, 1, 2], &[Precision::F16, Precision::F32]);
    assert_clean(&t);
}
