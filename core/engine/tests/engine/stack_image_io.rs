//! Plain image files and the shared atomic-write helper (tests named `stack_*` because the
//! stack writer shares the helper).

use std::path::Path;

use exr::prelude::{self as x, WritableImage as _};
use relume_engine::image_io::{
    compare_rgb, read_rgb_exr, srgb_oetf, write_atomic, write_png_srgb, write_rgba_exr, ImageDiff,
};
use relume_engine::RelumeError;

fn files(dir: &Path) -> Vec<String> {
    let mut v: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    v.sort();
    v
}

#[test]
fn write_atomic_keeps_the_old_file_when_the_writer_fails() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("f.bin");
    let n = write_atomic(&path, |w| {
        use std::io::Write;
        w.write_all(b"good")
            .map_err(|e| RelumeError::io("f.bin", e))
    })
    .unwrap();
    assert_eq!(n, 4);
    // The writer has written half a file when it fails: the temp is removed, the old stays.
    let r = write_atomic(&path, |w| {
        use std::io::Write;
        w.write_all(&[0u8; 3 << 20]).unwrap(); // more than the 1 MiB buffer: hits the disk
        Err(RelumeError::invalid("test", "fails half-way"))
    });
    assert!(matches!(r, Err(RelumeError::InvalidValue { .. })), "{r:?}");
    assert_eq!(std::fs::read(&path).unwrap(), b"good");
    assert_eq!(files(dir.path()), vec!["f.bin".to_string()]);
}

fn rgba(w: u32, h: u32) -> Vec<f32> {
    (0..w * h)
        .flat_map(|p| {
            let f = p as f32;
            [
                f * 0.25,
                1e-4 * f,
                1000.0 - f,
                if p % 2 == 0 { 1.0 } else { 0.5 },
            ]
        })
        .collect()
}

#[test]
fn rgba_exr_round_trips_as_rgb() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("img.exr");
    let (w, h) = (5, 3);
    let src = rgba(w, h);
    write_rgba_exr(&path, w, h, &src).unwrap();
    let (rw, rh, rgb) = read_rgb_exr(&path).unwrap();
    assert_eq!((rw, rh), (w, h));
    let expected: Vec<f32> = src.chunks(4).flat_map(|p| [p[0], p[1], p[2]]).collect();
    assert_eq!(rgb, expected); // f32 + ZIP: exact
                               // Generic reader: f32 RGBA, ZIP.
    let image = x::read_all_data_from_file(&path).unwrap();
    let l = &image.layer_data[0];
    let names: Vec<String> = l
        .channel_data
        .list
        .iter()
        .map(|c| c.name.to_string())
        .collect();
    assert_eq!(names, ["A", "B", "G", "R"]);
    assert_eq!(l.encoding.compression, x::Compression::ZIP16);
    assert_eq!(files(dir.path()), vec!["img.exr".to_string()]);
}

#[test]
fn rgba_exr_rejects_wrong_sizes() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("img.exr");
    let r = write_rgba_exr(&path, 4, 4, &[0.0; 15]);
    assert!(matches!(r, Err(RelumeError::Image { .. })), "{r:?}");
    let r = write_rgba_exr(&path, 0, 4, &[]);
    assert!(matches!(r, Err(RelumeError::Image { .. })), "{r:?}");
    assert!(!path.exists());
    let r = write_rgba_exr(&dir.path().join("no/such/dir.exr"), 1, 1, &[0.0; 4]);
    assert!(matches!(r, Err(RelumeError::Io { .. })), "{r:?}");
}

/// Writes one part with the given channels (each a list of f32 values) at w×h.
fn write_channels(path: &Path, w: usize, h: usize, chans: &[(&str, Vec<f32>)]) {
    let list = chans
        .iter()
        .map(|(n, v)| x::AnyChannel::new(*n, x::FlatSamples::F32(v.clone())))
        .collect();
    let layer = x::Layer::new(
        (w, h),
        x::LayerAttributes::default(),
        x::Encoding::FAST_LOSSLESS,
        x::AnyChannels::sort(list),
    );
    x::Image::from_layer(layer).write().to_file(path).unwrap();
}

#[test]
fn read_rgb_exr_picks_blender_layers_and_grey() {
    let dir = tempfile::tempdir().unwrap();
    // Blender multilayer: the first (sorted) group with R, G, B wins; Depth.Z is ignored.
    let p = dir.path().join("multi.exr");
    write_channels(
        &p,
        2,
        1,
        &[
            ("Depth.Z", vec![9.0, 9.0]),
            ("ViewLayer.Combined.R", vec![1.0, 2.0]),
            ("ViewLayer.Combined.G", vec![3.0, 4.0]),
            ("ViewLayer.Combined.B", vec![5.0, 6.0]),
            ("ViewLayer.Combined.A", vec![1.0, 1.0]),
            ("ZLayer.Combined.R", vec![7.0, 7.0]),
            ("ZLayer.Combined.G", vec![7.0, 7.0]),
            ("ZLayer.Combined.B", vec![7.0, 7.0]),
        ],
    );
    assert_eq!(
        read_rgb_exr(&p).unwrap(),
        (2, 1, vec![1.0, 3.0, 5.0, 2.0, 4.0, 6.0])
    );
    // Unprefixed R, G, B win over prefixed ones.
    let p = dir.path().join("plain_first.exr");
    write_channels(
        &p,
        1,
        1,
        &[
            ("A.Combined.R", vec![7.0]),
            ("A.Combined.G", vec![7.0]),
            ("A.Combined.B", vec![7.0]),
            ("R", vec![1.0]),
            ("G", vec![2.0]),
            ("B", vec![3.0]),
        ],
    );
    assert_eq!(read_rgb_exr(&p).unwrap(), (1, 1, vec![1.0, 2.0, 3.0]));
    // Grey: Y is copied to R, G, B.
    let p = dir.path().join("grey.exr");
    write_channels(&p, 1, 2, &[("Y", vec![0.5, 2.0])]);
    assert_eq!(
        read_rgb_exr(&p).unwrap(),
        (1, 2, vec![0.5, 0.5, 0.5, 2.0, 2.0, 2.0])
    );
    // Nothing usable: an Image error listing the channels.
    let p = dir.path().join("depth.exr");
    write_channels(&p, 1, 1, &[("Z", vec![1.0]), ("R", vec![1.0])]);
    match read_rgb_exr(&p) {
        Err(e @ RelumeError::Image { .. }) => assert!(e.to_string().contains("R, Z"), "{e}"),
        other => panic!("{other:?}"),
    }
}

#[test]
fn read_rgb_exr_errors() {
    let dir = tempfile::tempdir().unwrap();
    assert!(matches!(
        read_rgb_exr(&dir.path().join("none.exr")),
        Err(RelumeError::Io { .. })
    ));
    let p = dir.path().join("text.exr");
    std::fs::write(&p, "hello").unwrap();
    match read_rgb_exr(&p) {
        Err(RelumeError::Image { path, .. }) => assert_eq!(path, p),
        other => panic!("{other:?}"),
    }
    // Truncated.
    let full = dir.path().join("full.exr");
    write_rgba_exr(&full, 8, 40, &rgba(8, 40)).unwrap();
    let bytes = std::fs::read(&full).unwrap();
    std::fs::write(&p, &bytes[..bytes.len() - 100]).unwrap();
    assert!(matches!(read_rgb_exr(&p), Err(RelumeError::Image { .. })));
}

#[test]
fn srgb_oetf_known_values() {
    assert_eq!(srgb_oetf(0.0), 0.0);
    assert_eq!(srgb_oetf(1.0), 1.0);
    assert_eq!(srgb_oetf(2.0), 1.0);
    assert_eq!(srgb_oetf(-1.0), 0.0);
    assert_eq!(srgb_oetf(f32::NAN), 0.0);
    assert!((srgb_oetf(0.002) - 0.025_84).abs() < 1e-6); // linear segment: 12.92 × 0.002
    assert!((srgb_oetf(0.18) - 0.461_356).abs() < 1e-5); // mid grey → 46 %
    assert!((srgb_oetf(0.5) - 0.735_357).abs() < 1e-5);
    // Continuous at the knee (0.0031308).
    assert!((srgb_oetf(0.003_130_8) - srgb_oetf(0.003_130_9)).abs() < 1e-5);
}

#[test]
fn png_srgb_encodes_exposure_and_clamps() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("out.png");
    #[rustfmt::skip]
    let px = [
        0.18, 0.5, 1.0, 1.0,     // mid grey, 0.5, white
        0.09, 0.25, 0.5, 0.5,    // the same one stop down; alpha 0.5
        4.0, -1.0, f32::NAN, 2.0, // clamps; NaN → 0; alpha clamps
        f32::INFINITY, 0.0, 0.002, 0.0,
    ];
    write_png_srgb(&path, 2, 2, &px, 0.0).unwrap();
    let decoder = png::Decoder::new(std::io::BufReader::new(std::fs::File::open(&path).unwrap()));
    let mut reader = decoder.read_info().unwrap();
    assert!(reader.info().srgb.is_some(), "sRGB chunk");
    let mut buf = vec![0; reader.output_buffer_size().unwrap()];
    let info = reader.next_frame(&mut buf).unwrap();
    assert_eq!(
        (info.width, info.height, info.color_type, info.bit_depth),
        (2, 2, png::ColorType::Rgba, png::BitDepth::Eight)
    );
    let b = &buf[..info.buffer_size()];
    assert_eq!(&b[0..4], &[118, 188, 255, 255]); // 0.4614·255 = 117.6, 0.7354·255 = 187.5
    assert_eq!(&b[8..12], &[255, 0, 0, 255]);
    assert_eq!(&b[12..16], &[255, 0, 7, 0]); // 12.92 × 0.002 × 255 = 6.6
    assert_eq!(b[7], 128); // alpha stored linearly: 0.5 × 255 + 0.5
                           // Exposure +1: the second pixel equals the first.
    write_png_srgb(&path, 2, 2, &px, 1.0).unwrap();
    let mut reader =
        png::Decoder::new(std::io::BufReader::new(std::fs::File::open(&path).unwrap()))
            .read_info()
            .unwrap();
    let mut buf2 = vec![0; reader.output_buffer_size().unwrap()];
    reader.next_frame(&mut buf2).unwrap();
    assert_eq!(&buf2[4..7], &b[0..3]);
    // Errors.
    assert!(matches!(
        write_png_srgb(&path, 3, 2, &px, 0.0),
        Err(RelumeError::Image { .. })
    ));
    assert!(matches!(
        write_png_srgb(&path, 2, 2, &px, f32::NAN),
        Err(RelumeError::InvalidValue { .. })
    ));
    assert_eq!(files(dir.path()), vec!["out.png".to_string()]);
}

#[test]
fn compare_rgb_on_known_arrays() {
    // Reference b = (3, 4, 0) per pixel (‖b‖ = 5 per pixel); a differs by (0, 0, 1) on one of
    // two pixels: ‖a − b‖ = 1, ‖b‖ = √50 → rel_l2 = 1/√50; rmse = √(1/6); max_abs = 1.
    let b = [3.0, 4.0, 0.0, 3.0, 4.0, 0.0];
    let a = [3.0, 4.0, 1.0, 3.0, 4.0, 0.0];
    let d = compare_rgb(&a, &b, 3).unwrap();
    assert!((d.rel_l2 - 1.0 / 50f64.sqrt()).abs() < 1e-12, "{d:?}");
    assert!((d.rmse - (1.0f64 / 6.0).sqrt()).abs() < 1e-12);
    assert_eq!(d.max_abs, 1.0);
    assert_eq!(d.pixels, 2);
    // RGBA: alpha ignored, even when it differs wildly.
    let b4 = [3.0, 4.0, 0.0, 1.0, 3.0, 4.0, 0.0, 1.0];
    let a4 = [3.0, 4.0, 1.0, -7.0, 3.0, 4.0, 0.0, 100.0];
    assert_eq!(compare_rgb(&a4, &b4, 4).unwrap(), d);
    // Identical → zero; a zero reference: 0 if equal, +∞ otherwise.
    assert_eq!(compare_rgb(&b, &b, 3).unwrap().rel_l2, 0.0);
    let z = [0.0; 3];
    assert_eq!(
        compare_rgb(&z, &z, 3).unwrap(),
        ImageDiff {
            rel_l2: 0.0,
            rmse: 0.0,
            max_abs: 0.0,
            pixels: 1
        }
    );
    assert_eq!(
        compare_rgb(&[0.0, 0.0, 2.0], &z, 3).unwrap().rel_l2,
        f64::INFINITY
    );
}

#[test]
fn compare_rgb_errors() {
    let b = [1.0f32; 6];
    let e = compare_rgb(&[1.0; 9], &b, 3).unwrap_err();
    assert!(
        e.to_string().contains("sizes differ: 9 values against 6"),
        "{e}"
    );
    let e = compare_rgb(&[1.0; 6], &b, 4).unwrap_err();
    assert!(e.to_string().contains("whole number"), "{e}");
    let e = compare_rgb(&b, &b, 2).unwrap_err();
    assert!(e.to_string().contains("2 channels"), "{e}");
    let mut a = b;
    a[4] = f32::NAN;
    match compare_rgb(&a, &b, 3) {
        Err(e @ RelumeError::NonFinite { .. }) => assert!(
            e.to_string()
                .contains("image being compared, pixel 1, channel 1"),
            "{e}"
        ),
        other => panic!("{other:?}"),
    }
    match compare_rgb(&b, &a, 3) {
        Err(e @ RelumeError::NonFinite { .. }) => {
            assert!(e.to_string().contains("reference"), "{e}")
        }
        other => panic!("{other:?}"),
    }
    // A NaN alpha is ignored like any alpha.
    let mut a4 = [1.0f32; 8];
    a4[3] = f32::NAN;
    assert_eq!(compare_rgb(&a4, &[1.0; 8], 4).unwrap().rel_l2, 0.0);
}
