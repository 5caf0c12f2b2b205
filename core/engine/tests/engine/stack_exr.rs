//! The stack file: round trips, validation errors, atomic writes, generic readability.

use crate::common;

use std::path::{Path, PathBuf};

use exr::prelude::{self as x, ReadChannels as _, ReadLayers as _, WritableImage as _};
use relume_engine::layer_key::{LayerKey, PathVertex};
use relume_engine::scene::{Camera, Light, Projection, SensorFit};
use relume_engine::stack::exr_file::{
    check_scene_hash, read_stack, read_stack_header, write_stack,
};
use relume_engine::stack::{
    Layer, LayerSamples, Precision, StackHeader, TransferStack, STACK_FORMAT_VERSION,
};
use relume_engine::RelumeError;

use common::stack_header::{blinn_phong_region, stack_header};

fn header(width: u32, height: u32, precision: Precision) -> StackHeader {
    let regions = vec![
        // Non-ASCII survives (texts are UTF-8).
        blinn_phong_region("Wand – grün", true, [0.7, 0.1, 0.1], [0.04; 3], 120.0),
        blinn_phong_region("Floor", false, [0.5; 3], [0.0; 3], 1.0),
    ];
    StackHeader {
        camera: Camera {
            projection: Projection::Perspective,
            matrix_world: [
                [1.0, 0.0, 0.0, 0.25],
                [0.0, 0.0, -1.0, -3.5],
                [0.0, 1.0, 0.0, 1.1],
                [0.0, 0.0, 0.0, 1.0],
            ],
            lens_mm: 35.0,
            sensor_width_mm: 36.0,
            sensor_height_mm: 24.0,
            sensor_fit: SensorFit::Auto,
            shift_x: 0.0,
            shift_y: 0.0,
            ortho_scale: 6.0,
            clip_start: 0.1,
            clip_end: 100.0,
        },
        spp: 64,
        bounces: 2,
        seed: 0xDEAD_BEEF_1234,
        lights: vec![Light::Point {
            position: [0.0, 0.0, 1.9],
            power: 1000.0,
            color: [1.0, 0.9, 0.8],
            radius: 0.1,
        }],
        scene_hash: "3f2a9c0e1b7d4455".into(),
        precision,
        ..stack_header(width, height, regions)
    }
}

/// Deterministic values with a wide range: 1e-6 … 1e4 magnitudes, a few negatives, zeros.
fn values(n: usize, seed: u64) -> Vec<f32> {
    let mut s = seed
        .wrapping_mul(6364136223846793005)
        .wrapping_add(1442695040888963407);
    (0..n)
        .map(|i| {
            s = s
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            let u = (s >> 40) as f32 / (1u64 << 24) as f32; // [0, 1)
            match i % 7 {
                0 => 0.0,
                1 => -u,
                _ => 10f32.powf(u * 10.0 - 6.0),
            }
        })
        .collect()
}

fn keys() -> Vec<(LayerKey, u32)> {
    let e = |region, basis| PathVertex::Editable { region, basis };
    vec![
        (LayerKey::new(vec![]), 3), // World
        (
            LayerKey {
                path: vec![],
                light_group: 2,
            },
            3,
        ), // G2_World
        (LayerKey::new(vec![PathVertex::Fixed]), 3), // F
        (LayerKey::new(vec![e(0, 0)]), 3), // E0b0
        (LayerKey::new(vec![e(0, 2)]), 1), // E0b2: grey
        (LayerKey::new(vec![e(0, 2), e(1, 0)]), 1), // E0b2_E1b0
        (LayerKey::new(vec![e(1, 3), PathVertex::Fixed]), 3), // E1b3_F
        (
            LayerKey {
                path: vec![e(0, 1)],
                light_group: 1,
            },
            1,
        ), // G1_E0b1
        (
            LayerKey {
                path: vec![PathVertex::Fixed, e(12, 5)],
                light_group: 65535,
            },
            3,
        ),
    ]
}

fn stack(width: u32, height: u32, precision: Precision) -> TransferStack {
    let n = (width * height) as usize;
    let scales = [
        1.0f32,
        3.051_757_8e-5,
        0.123_456_79,
        7.1e4,
        1.0e-30,
        2.5,
        0.333_333_34,
        9.9e-3,
        42.0,
    ];
    let layers = keys()
        .into_iter()
        .enumerate()
        .map(|(i, (key, channels))| {
            let v = values(n * channels as usize, i as u64);
            let samples = match precision {
                Precision::F16 => {
                    LayerSamples::F16(v.iter().map(|&s| half::f16::from_f32(s)).collect())
                }
                Precision::F32 => LayerSamples::F32(v),
            };
            Layer {
                key,
                channels,
                scale: scales[i % scales.len()],
                samples,
            }
        })
        .collect();
    TransferStack {
        header: header(width, height, precision),
        layers,
    }
}

fn tmp() -> tempfile::TempDir {
    tempfile::tempdir().expect("temp dir")
}

/// Files in `dir` other than `keep` (temp files left behind would show here).
fn others(dir: &Path, keep: &[&str]) -> Vec<String> {
    std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| !keep.contains(&n.as_str()))
        .collect()
}

#[test]
fn round_trip_f16_and_f32_exactly() {
    let dir = tmp();
    for precision in [Precision::F16, Precision::F32] {
        // 7×5: odd sizes catch interleaving mistakes; 5 rows < one 16-line ZIP block.
        for (w, h) in [(7u32, 5u32), (3, 37)] {
            let s = stack(w, h, precision);
            let path = dir.path().join(format!("s_{precision:?}_{w}x{h}.exr"));
            let bytes = write_stack(&path, &s).unwrap();
            assert_eq!(bytes, std::fs::metadata(&path).unwrap().len());
            let back = read_stack(&path).unwrap();
            assert_eq!(back, s, "{precision:?} {w}×{h}");
            // Bit-exact scales (PartialEq on f32 would accept 0.0 == -0.0).
            for (a, b) in back.layers.iter().zip(&s.layers) {
                assert_eq!(a.scale.to_bits(), b.scale.to_bits());
            }
            assert_eq!(read_stack_header(&path).unwrap(), s.header);
        }
    }
    assert_eq!(
        others(
            dir.path(),
            &[
                "s_F16_7x5.exr",
                "s_F16_3x37.exr",
                "s_F32_7x5.exr",
                "s_F32_3x37.exr"
            ]
        ),
        Vec::<String>::new()
    );
}

#[test]
fn overwrite_replaces_the_file() {
    let dir = tmp();
    let path = dir.path().join("s.exr");
    write_stack(&path, &stack(4, 4, Precision::F32)).unwrap();
    let s2 = stack(6, 2, Precision::F16);
    write_stack(&path, &s2).unwrap();
    assert_eq!(read_stack(&path).unwrap(), s2);
}

#[test]
fn generic_exr_reader_sees_blender_style_channels() {
    let dir = tmp();
    let path = dir.path().join("s.exr");
    let s = stack(5, 3, Precision::F16);
    write_stack(&path, &s).unwrap();
    let image = x::read_all_data_from_file(&path).unwrap();
    assert_eq!(image.layer_data.len(), 1, "one part");
    let layer = &image.layer_data[0];
    let names: Vec<String> = layer
        .channel_data
        .list
        .iter()
        .map(|c| c.name.to_string())
        .collect();
    let mut expected: Vec<String> = keys()
        .iter()
        .flat_map(|(k, c)| {
            let sfx: &[&str] = if *c == 1 { &["Y"] } else { &["R", "G", "B"] };
            sfx.iter()
                .map(move |s| format!("{}.Transfer.{s}", k.layer_name()))
        })
        .collect();
    expected.sort();
    assert_eq!(names, expected);
    assert!(names.contains(&"World.Transfer.R".to_string()));
    assert!(names.contains(&"G1_E0b1.Transfer.Y".to_string()));
    assert!(names.contains(&"E0b2_E1b0.Transfer.Y".to_string()));
    assert_eq!(layer.encoding.compression, x::Compression::ZIP16);
    assert_eq!(layer.encoding.blocks, x::Blocks::ScanLines);
    assert_eq!((layer.size.width(), layer.size.height()), (5, 3));
    let dw = image.attributes.display_window;
    assert_eq!(
        (
            dw.position.x(),
            dw.position.y(),
            dw.size.width(),
            dw.size.height()
        ),
        (0, 0, 5, 3)
    );
    for c in &layer.channel_data.list {
        assert!(
            matches!(c.sample_data, x::Levels::Singular(x::FlatSamples::F16(_))),
            "{}",
            c.name
        );
    }
    for a in [
        "relume/header",
        "relume/format_version",
        "relume/scene_hash",
        "relume/layers",
    ] {
        assert!(
            layer.attributes.other.contains_key(&x::Text::from(a)),
            "{a}"
        );
    }
    assert_eq!(
        layer.attributes.other[&x::Text::from("relume/format_version")],
        x::AttributeValue::I32(STACK_FORMAT_VERSION as i32)
    );
    // Raw samples are stored (before scale): pixel 1 of World's G channel.
    let g = layer
        .channel_data
        .list
        .iter()
        .find(|c| c.name.to_string() == "World.Transfer.G")
        .unwrap();
    let x::Levels::Singular(x::FlatSamples::F16(gv)) = &g.sample_data else {
        unreachable!()
    };
    let LayerSamples::F16(world) = &s.layers[0].samples else {
        unreachable!()
    };
    assert_eq!(gv[1], world[3 + 1]);
}

#[test]
fn missing_file_is_io() {
    let p = Path::new("/nonexistent-relume-dir/stack.exr");
    assert!(matches!(read_stack(p), Err(RelumeError::Io { .. })));
    assert!(matches!(read_stack_header(p), Err(RelumeError::Io { .. })));
}

#[test]
fn truncated_files_are_stack_truncated() {
    let dir = tmp();
    let path = dir.path().join("s.exr");
    write_stack(&path, &stack(16, 40, Precision::F32)).unwrap();
    let full = std::fs::read(&path).unwrap();
    let cut = dir.path().join("cut.exr");
    for len in [0, 3, 10, full.len() / 2, full.len() - 100, full.len() - 1] {
        std::fs::write(&cut, &full[..len]).unwrap();
        let r = read_stack(&cut);
        assert!(
            matches!(r, Err(RelumeError::StackTruncated { .. })),
            "cut at {len}: {r:?}"
        );
    }
    // Meta data that is there but wrong (not missing): StackFormat. Byte 4 is the OpenEXR
    // file version (2); 99 is no version at all.
    let mut bad = full.clone();
    bad[4] = 99;
    std::fs::write(&cut, &bad).unwrap();
    for r in [
        read_stack(&cut).map(|_| ()),
        read_stack_header(&cut).map(|_| ()),
    ] {
        assert!(
            matches!(r, Err(RelumeError::StackFormat { .. })),
            "version byte 99: {r:?}"
        );
    }
    // Damaged compressed pixel data (zlib checks it): StackTruncated, "truncated or damaged".
    let mut bad = full.clone();
    let at = full.len() * 3 / 4;
    bad[at..at + 32].iter_mut().for_each(|b| *b ^= 0x5a);
    std::fs::write(&cut, &bad).unwrap();
    let r = read_stack(&cut);
    assert!(
        matches!(r, Err(RelumeError::StackTruncated { .. })),
        "damaged: {r:?}"
    );
    // The meta data is in the first few KiB: cut inside it, the header read fails too.
    for len in [0, 10, 200] {
        std::fs::write(&cut, &full[..len]).unwrap();
        let r = read_stack_header(&cut);
        assert!(
            matches!(r, Err(RelumeError::StackTruncated { .. })),
            "cut at {len}: {r:?}"
        );
    }
}

#[test]
fn foreign_files_are_refused() {
    let dir = tmp();
    let text = dir.path().join("notes.exr");
    std::fs::write(&text, "just some text, not an image at all").unwrap();
    for r in [
        read_stack(&text).map(|_| ()),
        read_stack_header(&text).map(|_| ()),
    ] {
        assert!(matches!(r, Err(RelumeError::StackForeign { .. })), "{r:?}");
    }
    let plain = dir.path().join("plain.exr");
    relume_engine::image_io::write_rgba_exr(&plain, 2, 2, &[0.5; 16]).unwrap();
    for r in [
        read_stack(&plain).map(|_| ()),
        read_stack_header(&plain).map(|_| ()),
    ] {
        let err = r.unwrap_err();
        assert!(matches!(err, RelumeError::StackForeign { .. }), "{err:?}");
        assert!(err.to_string().contains("relume/header"), "{err}");
    }
}

#[test]
fn check_scene_hash_detects_stale_stacks() {
    let h = header(2, 2, Precision::F16);
    check_scene_hash(&h, "3f2a9c0e1b7d4455").unwrap();
    match check_scene_hash(&h, "0000") {
        Err(RelumeError::StackStale {
            stack_hash,
            scene_hash,
        }) => {
            assert_eq!(stack_hash, "3f2a9c0e1b7d4455");
            assert_eq!(scene_hash, "0000");
        }
        other => panic!("{other:?}"),
    }
}

type FlatLayer = x::Layer<x::AnyChannels<x::FlatSamples>>;

/// Writes a valid stack, lets `edit` change its part (attributes, channels) with the exr API
/// and writes it back: the way to make files that are wrong in one precise respect.
fn tampered(
    dir: &Path,
    name: &str,
    precision: Precision,
    edit: impl FnOnce(&mut FlatLayer),
) -> PathBuf {
    let path = dir.join(name);
    write_stack(&path, &stack(4, 3, precision)).unwrap();
    let mut image = x::read()
        .no_deep_data()
        .largest_resolution_level()
        .all_channels()
        .all_layers()
        .all_attributes()
        .from_file(&path)
        .unwrap();
    edit(&mut image.layer_data[0]);
    image.layer_data[0]
        .channel_data
        .list
        .sort_by_key(|c| c.name.clone());
    image.write().to_file(&path).unwrap();
    path
}

fn set_text(l: &mut FlatLayer, attr: &str, value: &str) {
    l.attributes.other.insert(
        x::Text::from(attr),
        x::AttributeValue::Text(x::Text::from_slice_unchecked(value.as_bytes())),
    );
}

fn get_text(l: &FlatLayer, attr: &str) -> String {
    match &l.attributes.other[&x::Text::from(attr)] {
        x::AttributeValue::Text(t) => String::from_utf8(t.as_slice().to_vec()).unwrap(),
        other => panic!("{other:?}"),
    }
}

/// Asserts a StackFormat error whose message contains `needle`.
fn assert_format(r: relume_engine::Result<impl std::fmt::Debug>, needle: &str) {
    match r {
        Err(e @ RelumeError::StackFormat { .. }) => {
            assert!(e.to_string().contains(needle), "{e} lacks {needle:?}")
        }
        other => panic!("expected StackFormat containing {needle:?}, got {other:?}"),
    }
}

#[test]
fn the_untampered_helper_file_reads() {
    let dir = tmp();
    let p = tampered(dir.path(), "ok.exr", Precision::F16, |_| {});
    assert_eq!(read_stack(&p).unwrap(), stack(4, 3, Precision::F16));
}

#[test]
fn other_format_version_is_stack_version() {
    let dir = tmp();
    let p = tampered(dir.path(), "v.exr", Precision::F16, |l| {
        l.attributes.other.insert(
            x::Text::from("relume/format_version"),
            x::AttributeValue::I32(2),
        );
        // A future version may lay the header out differently: not even parsed.
        set_text(l, "relume/header", "{\"future\": true}");
    });
    for r in [
        read_stack(&p).map(|_| ()),
        read_stack_header(&p).map(|_| ()),
    ] {
        match r {
            Err(RelumeError::StackVersion {
                found: 2,
                supported,
                ..
            }) => assert_eq!(supported, STACK_FORMAT_VERSION),
            other => panic!("{other:?}"),
        }
    }
}

#[test]
fn missing_header_attribute_is_foreign() {
    let dir = tmp();
    let p = tampered(dir.path(), "f.exr", Precision::F16, |l| {
        l.attributes.other.remove(&x::Text::from("relume/header"));
    });
    assert!(matches!(
        read_stack_header(&p),
        Err(RelumeError::StackForeign { .. })
    ));
}

#[test]
fn damaged_header_and_attributes_are_stack_format() {
    let dir = tmp();
    let p = tampered(dir.path(), "a.exr", Precision::F16, |l| {
        set_text(l, "relume/header", "{not json")
    });
    assert_format(read_stack_header(&p), "not a stack header");

    let p = tampered(dir.path(), "b.exr", Precision::F16, |l| {
        set_text(l, "relume/scene_hash", "ffff")
    });
    assert_format(read_stack(&p), "relume/scene_hash");

    let p = tampered(dir.path(), "c.exr", Precision::F16, |l| {
        let h = get_text(l, "relume/header").replace("\"width\":4", "\"width\":5");
        set_text(l, "relume/header", &h);
    });
    assert_format(read_stack_header(&p), "4×3 but the header says 5×3");

    let p = tampered(dir.path(), "d.exr", Precision::F16, |l| {
        l.attributes.other.remove(&x::Text::from("relume/layers"));
    });
    assert_format(read_stack(&p), "relume/layers is missing");

    let p = tampered(dir.path(), "e.exr", Precision::F16, |l| {
        l.attributes.other.insert(
            x::Text::from("relume/format_version"),
            x::AttributeValue::F32(1.0),
        );
    });
    assert_format(read_stack_header(&p), "not an i32");
}

#[test]
fn bad_layer_names_are_stack_format() {
    let dir = tmp();
    let p = tampered(dir.path(), "n.exr", Precision::F16, |l| {
        let layers = get_text(l, "relume/layers").replace("\"E0b2_E1b0\"", "\"Bogus\"");
        set_text(l, "relume/layers", &layers);
        for c in l.channel_data.list.iter_mut() {
            if c.name.to_string() == "E0b2_E1b0.Transfer.Y" {
                c.name = x::Text::from("Bogus.Transfer.Y");
            }
        }
    });
    assert_format(read_stack(&p), "\"Bogus\" is not a path signature");
}

#[test]
fn layer_list_and_channels_must_match() {
    let dir = tmp();
    // A channel gone.
    let p = tampered(dir.path(), "m.exr", Precision::F16, |l| {
        l.channel_data
            .list
            .retain(|c| c.name.to_string() != "F.Transfer.G");
    });
    assert_format(read_stack(&p), "F.Transfer.G");
    // An extra channel.
    let p = tampered(dir.path(), "x.exr", Precision::F16, |l| {
        let mut extra = l.channel_data.list[0].clone();
        extra.name = x::Text::from("Extra.Transfer.Y");
        l.channel_data.list.push(extra);
    });
    assert_format(read_stack(&p), "Extra.Transfer.Y");
    // A grey layer listed as RGB: its Y channel belongs to no listed layer.
    let p = tampered(dir.path(), "g.exr", Precision::F16, |l| {
        let layers = get_text(l, "relume/layers").replace(
            "{\"name\":\"E0b2\",\"channels\":1",
            "{\"name\":\"E0b2\",\"channels\":3",
        );
        set_text(l, "relume/layers", &layers);
    });
    assert_format(
        read_stack(&p),
        "E0b2.Transfer.Y is in the file but no layer",
    );
    // An impossible channel count.
    let p = tampered(dir.path(), "k.exr", Precision::F16, |l| {
        let layers = get_text(l, "relume/layers").replace(
            "{\"name\":\"E0b2\",\"channels\":1",
            "{\"name\":\"E0b2\",\"channels\":2",
        );
        set_text(l, "relume/layers", &layers);
    });
    assert_format(read_stack(&p), "E0b2 has 2 channels");
}

#[test]
fn wrong_sample_type_is_stack_format() {
    let dir = tmp();
    let p = tampered(dir.path(), "t.exr", Precision::F16, |l| {
        for c in l.channel_data.list.iter_mut() {
            if c.name.to_string() == "World.Transfer.B" {
                c.sample_data = x::FlatSamples::F32(c.sample_data.values_as_f32().collect());
            }
        }
    });
    assert_format(read_stack(&p), "World.Transfer.B holds f32 samples");
}

#[test]
fn non_finite_samples_name_their_layer() {
    let dir = tmp();
    for (precision, nan) in [(Precision::F16, 0u8), (Precision::F32, 1u8)] {
        let p = tampered(dir.path(), &format!("nan{nan}.exr"), precision, |l| {
            for c in l.channel_data.list.iter_mut() {
                if c.name.to_string() == "E1b3_F.Transfer.G" {
                    match &mut c.sample_data {
                        x::FlatSamples::F16(v) => v[5] = half::f16::NAN,
                        x::FlatSamples::F32(v) => v[5] = f32::INFINITY,
                        _ => unreachable!(),
                    }
                }
            }
        });
        assert_format(read_stack(&p), "layer E1b3_F has a non-finite sample");
        assert_format(read_stack(&p), "pixel 5, channel G");
    }
}

#[test]
fn write_validates_and_touches_no_file_on_error() {
    let dir = tmp();
    let path = dir.path().join("good.exr");
    let good = stack(4, 3, Precision::F16);
    write_stack(&path, &good).unwrap();
    let before = std::fs::read(&path).unwrap();

    let mut bad = Vec::new();
    let mut s = good.clone();
    s.layers[2].scale = f32::NAN;
    bad.push((s, "scale NaN"));
    let mut s = good.clone();
    s.layers[1].scale = 0.0;
    bad.push((s, "scale 0"));
    let mut s = good.clone();
    if let LayerSamples::F16(v) = &mut s.layers[3].samples {
        v[7] = half::f16::INFINITY;
    }
    bad.push((s, "layer E0b0 has a non-finite sample"));
    let mut s = good.clone();
    s.layers[0].samples = LayerSamples::F16(vec![half::f16::ZERO; 5]);
    bad.push((s, "layer World has 5 samples"));
    let mut s = good.clone();
    s.layers[4].samples = LayerSamples::F32(vec![0.0; 12]);
    bad.push((s, "F32 samples in a stack of precision F16"));
    let mut s = good.clone();
    s.layers[4].channels = 2;
    bad.push((s, "2 channels"));
    let mut s = good.clone();
    s.layers[5].key = s.layers[4].key.clone();
    bad.push((s, "appears twice"));
    let mut s = good.clone();
    s.layers.clear();
    bad.push((s, "no layer"));
    let mut s = good.clone();
    s.header.camera.lens_mm = f32::NAN;
    bad.push((s, "round-trip"));
    let mut s = good.clone();
    s.header.format_version = 7;
    bad.push((s, "format version 7"));

    for (s, needle) in bad {
        assert_format(write_stack(&path, &s), needle);
        assert_eq!(
            std::fs::read(&path).unwrap(),
            before,
            "{needle}: the good file changed"
        );
    }
    assert_eq!(
        others(dir.path(), &["good.exr"]),
        Vec::<String>::new(),
        "temp files left"
    );
}

#[test]
fn unwritable_places_give_io_and_keep_the_old_file() {
    let dir = tmp();
    let s = stack(3, 2, Precision::F32);
    // A directory that does not exist.
    let r = write_stack(&dir.path().join("missing/s.exr"), &s);
    assert!(matches!(r, Err(RelumeError::Io { .. })), "{r:?}");
    // A "directory" that is a file (works as root too, where permissions do not bite).
    let file = dir.path().join("plain");
    std::fs::write(&file, "x").unwrap();
    let r = write_stack(&file.join("s.exr"), &s);
    assert!(matches!(r, Err(RelumeError::Io { .. })), "{r:?}");
    // Target is a directory: refused before anything is written (the rename would fail,
    // or replace an empty one), nothing inside it touched, no temp file left.
    let target = dir.path().join("taken.exr");
    std::fs::create_dir(&target).unwrap();
    std::fs::write(target.join("inside"), "keep").unwrap();
    let r = write_stack(&target, &s);
    assert!(
        matches!(&r, Err(RelumeError::OutputNotAFile { kind, .. }) if kind == "a directory"),
        "{r:?}"
    );
    assert_eq!(
        std::fs::read_to_string(target.join("inside")).unwrap(),
        "keep"
    );
    assert_eq!(
        others(dir.path(), &["plain", "taken.exr"]),
        Vec::<String>::new(),
        "temp files left"
    );

    // A read-only directory, where permissions are enforced (not as root).
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt;
        let ro = dir.path().join("ro");
        std::fs::create_dir(&ro).unwrap();
        let old = ro.join("s.exr");
        write_stack(&old, &s).unwrap();
        let before = std::fs::read(&old).unwrap();
        std::fs::set_permissions(&ro, std::fs::Permissions::from_mode(0o555)).unwrap();
        let enforced = std::fs::write(ro.join("probe"), "x").is_err();
        if enforced {
            let r = write_stack(&old, &stack(3, 2, Precision::F16));
            assert!(matches!(r, Err(RelumeError::Io { .. })), "{r:?}");
            assert_eq!(std::fs::read(&old).unwrap(), before);
        } else {
            eprintln!("running as root: read-only directory not enforced, case skipped");
        }
        std::fs::set_permissions(&ro, std::fs::Permissions::from_mode(0o755)).unwrap();
    }
}

/// 100 RGB layers of 512×512 f16 (150 MiB of samples): the size of a real bake.
/// Prints write/read times and file size; asserts only the round trip.
/// `cargo test -p relume-engine --test engine stack_exr -- --ignored --nocapture` to run it.
#[test]
#[ignore = "150 MiB stack, several seconds: run on demand for the timing figures"]
fn timing_100_layers_512_f16() {
    let (w, h) = (512u32, 512u32);
    let n = (w * h) as usize;
    let mut layers = Vec::new();
    for i in 0..100u16 {
        // Smooth, bake-like data plus a little deterministic noise (pure noise does not
        // compress; a noise-free gradient compresses unrealistically well).
        let noise = values(n * 3, i as u64);
        let v: Vec<f32> = (0..n * 3)
            .map(|j| {
                let p = j / 3;
                let (px, py) = ((p % 512) as f32 / 512.0, (p / 512) as f32 / 512.0);
                (0.2 + px * py + 0.05 * (i as f32 * 0.1 + px * 6.0).sin())
                    * (1.0 + 0.02 * noise[j].clamp(-1.0, 1.0))
            })
            .collect();
        let key = LayerKey::new(vec![
            PathVertex::Editable {
                region: i / 10,
                basis: i % 10,
            },
            PathVertex::Fixed,
        ]);
        layers.push(Layer::from_f32(key, 3, &v, Precision::F16));
    }
    let s = TransferStack {
        header: header(w, h, Precision::F16),
        layers,
    };
    let dir = tmp();
    let path = dir.path().join("big.exr");
    let t = std::time::Instant::now();
    let bytes = write_stack(&path, &s).unwrap();
    let tw = t.elapsed();
    let t = std::time::Instant::now();
    let back = read_stack(&path).unwrap();
    let tr = t.elapsed();
    let t = std::time::Instant::now();
    read_stack_header(&path).unwrap();
    let th = t.elapsed();
    eprintln!(
        "100 layers × 512² × RGB f16: {:.1} MiB samples, file {:.1} MiB; write {:.2} s, read {:.2} s, header {:.2} ms",
        s.sample_bytes() as f64 / 1048576.0,
        bytes as f64 / 1048576.0,
        tw.as_secs_f64(),
        tr.as_secs_f64(),
        th.as_secs_f64() * 1e3
    );
    assert!(back == s);
}
