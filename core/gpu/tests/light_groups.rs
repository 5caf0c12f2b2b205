//! Light-group gains on the GPU equal the CPU's (the CPU relight is the reference).

mod common;

use std::sync::Arc;

use relume_engine::bake::{bake, BakeSettings, LightGrouping};
use relume_engine::image_io::compare_rgb;
use relume_engine::progress::Progress;
use relume_engine::relight::CpuRelighter;
use relume_engine::scene::{file::load_scene, Light, Resolution};
use relume_engine::Rgb;
use relume_gpu::{DevicePreference, Relighter};

#[test]
fn gpu_light_group_gains_match_the_cpu() {
    if common::gpu_or_skip("gpu_light_group_gains_match_the_cpu").is_none() {
        return;
    }
    let path =
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../assets/cornell.scene.json");
    let mut scene = load_scene(&path).unwrap();
    scene.lights.push(Light::Point {
        position: [0.4, -0.4, 0.2],
        power: 10.0,
        color: [0.2, 0.4, 1.0],
        radius: 0.02,
    });
    let settings = BakeSettings {
        spp: 1,
        resolution: Some(Resolution {
            width: 32,
            height: 32,
        }),
        light_grouping: LightGrouping::PerLight,
        ..Default::default()
    };
    let (stack, _) = bake(&scene, &settings, &Progress::new()).unwrap();
    let (_, coefs) = common::default_coefs(&stack.header);
    let gains = [Rgb::new(0.5, 1.0, 2.0), Rgb::splat(3.0)];
    let stack = Arc::new(stack);
    let mut cpu = CpuRelighter::new(stack.clone()).unwrap();
    cpu.relight(&coefs).unwrap();
    let expect = cpu.set_light_group_gains(&gains).unwrap().to_vec();
    let mut gpu = Relighter::new(stack, DevicePreference::Gpu).unwrap();
    gpu.relight(&coefs).unwrap();
    let got = gpu.set_light_group_gains(&gains).unwrap().to_vec();
    let d = compare_rgb(&got, &expect, 4).unwrap().rel_l2;
    assert!(
        d < common::TOLERANCE,
        "GPU vs CPU with light group gains: {d}"
    );
}
