//! Quick bake throughput check without the CLI: `cargo run --release --example bench_bake_quick -- SCENE [WxH] [spp]`.
use relume_engine::bake::{bench::bench_bake, BakeSettings};
use relume_engine::scene::{file::load_scene, Resolution};

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let scene = load_scene(std::path::Path::new(&args[1])).expect("scene");
    let mut settings = BakeSettings::default();
    if let Some(r) = args.get(2) {
        let (w, h) = r.split_once('x').expect("WxH");
        settings.resolution = Some(Resolution {
            width: w.parse().unwrap(),
            height: h.parse().unwrap(),
        });
    }
    if let Some(s) = args.get(3) {
        settings.spp = s.parse().unwrap();
    }
    let b = bench_bake(&scene, &settings).expect("bench");
    println!("{}", serde_json::to_string_pretty(&b).unwrap());
    let (_, r) =
        relume_engine::bake::bake(&scene, &settings, &relume_engine::progress::Progress::new())
            .unwrap();
    println!("{}", serde_json::to_string(&r).unwrap());
}
