//! The shown image when OIDN is not asked for or cannot run: the relit image bit for bit,
//! and a report saying which ran and why.
mod common;

use std::path::PathBuf;

use relume_denoise::oidn::{DeviceChoice, LibrarySearch, OidnApi};
use relume_denoise::{DenoiseMode, FeatureImages, ShownImage};

/// A small RGBA image with values of every kind the relight gives: zero, negative, large.
fn image(w: u32, h: u32) -> Vec<f32> {
    (0..w * h)
        .flat_map(|i| {
            let v = (i as f32 * 0.37).sin() * 3.0;
            [v, v.abs() * 100.0, 0.0, 1.0]
        })
        .collect()
}

fn nowhere() -> LibrarySearch {
    LibrarySearch {
        dirs: vec![PathBuf::from("/nonexistent/relume-oidn-test")],
        system: false,
    }
}

#[test]
fn none_and_linear_are_the_relit_image_bit_for_bit() {
    let img = image(7, 5);
    let mut shown = ShownImage::new(nowhere(), DeviceChoice::Default);
    for mode in [DenoiseMode::None, DenoiseMode::Linear] {
        let (out, report) = shown
            .show(&img, 7, 5, mode, FeatureImages::Missing("none".into()))
            .unwrap();
        assert_eq!(out.as_ref(), img.as_slice(), "{mode}");
        assert_eq!(
            (report.asked, report.ran, report.note.clone()),
            (mode, mode, None)
        );
        assert_eq!(report.summary(), mode.to_string());
    }
}

#[test]
fn a_missing_library_falls_back_to_the_linear_image_and_says_where_it_looked() {
    if std::env::var_os(relume_denoise::oidn::ENV_VAR).is_some() {
        eprintln!(
            "SKIPPED: {} is set in this environment",
            relume_denoise::oidn::ENV_VAR
        );
        return;
    }
    let img = image(8, 8);
    let mut shown = ShownImage::new(nowhere(), DeviceChoice::Default);
    let (out, report) = shown
        .show(
            &img,
            8,
            8,
            DenoiseMode::Oidn,
            FeatureImages::Missing("none".into()),
        )
        .unwrap();
    assert_eq!(out.as_ref(), img.as_slice());
    assert_eq!(report.asked, DenoiseMode::Oidn);
    assert_eq!(report.ran, DenoiseMode::Linear);
    let note = report.note.unwrap();
    assert!(note.contains("OpenImageDenoise did not run"), "{note}");
    assert!(note.contains("OpenImageDenoise 2 was not found"), "{note}");
    assert!(note.contains("/nonexistent/relume-oidn-test/"), "{note}");
    assert!(note.contains("no such file"), "{note}");
}

#[test]
fn a_library_that_is_not_oidn_2_is_named_as_such() {
    // The bpy wheel's TBB: a real shared library without OIDN's functions.
    let Some(dir) = common::bpy_lib_dir() else {
        eprintln!("SKIPPED: no bpy wheel (its lib folder holds the library this test opens)");
        return;
    };
    let Some(tbb) = std::fs::read_dir(&dir)
        .unwrap()
        .filter_map(|e| e.ok().map(|e| e.path()))
        .find(|p| {
            p.file_name()
                .unwrap()
                .to_string_lossy()
                .starts_with("libtbb.so")
        })
    else {
        eprintln!("SKIPPED: no libtbb in {}", dir.display());
        return;
    };
    let err = OidnApi::open(&tbb).err().expect("TBB is not OIDN");
    assert!(
        err.contains("no function oidnNewDevice") && err.contains("not an OpenImageDenoise 2"),
        "{err}"
    );
}

#[test]
fn a_value_that_is_not_finite_is_refused_before_oidn() {
    let mut img = image(4, 4);
    img[9] = f32::NAN;
    let mut shown = ShownImage::new(nowhere(), DeviceChoice::Default);
    let err = shown
        .show(
            &img,
            4,
            4,
            DenoiseMode::Oidn,
            FeatureImages::Missing("none".into()),
        )
        .expect_err("NaN refused");
    assert!(err.to_string().contains("(2, 0)"), "{err}");
    let err = shown
        .show(
            &img[..12],
            4,
            4,
            DenoiseMode::None,
            FeatureImages::Missing("none".into()),
        )
        .expect_err("wrong size refused");
    assert!(err.to_string().contains("4×4"), "{err}");
}

#[test]
fn negative_colour_enters_oidn_as_zero_and_is_counted() {
    let Some(search) = common::oidn_search("negative_colour") else {
        return;
    };
    let img = image(16, 16);
    let negatives = img
        .chunks_exact(4)
        .flat_map(|p| &p[..3])
        .filter(|v| **v < 0.0)
        .count();
    assert!(negatives > 0);
    let mut shown = ShownImage::new(search, DeviceChoice::Default);
    let (out, report) = shown
        .show(
            &img,
            16,
            16,
            DenoiseMode::Oidn,
            FeatureImages::Missing("test".into()),
        )
        .unwrap();
    assert_eq!(report.ran, DenoiseMode::Oidn, "{:?}", report.note);
    assert_eq!(report.negative_values, negatives);
    assert_eq!(report.features, "none");
    assert!(report.note.unwrap().contains("no features: test"));
    assert!(out.iter().all(|v| v.is_finite()));
    // Alpha is the input's.
    assert!(out.chunks_exact(4).all(|p| p[3] == 1.0));
}
