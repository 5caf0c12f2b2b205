//! The flat bake fields ([`relume_engine::bake::fields`]) against the engine's
//! `BakeSettings`: every value a bake reads is set by some field, every field reaches the
//! settings, and overrides keep the rules (one owner, errors naming the key, nothing changed
//! on an error).

use std::collections::BTreeSet;

use relume_engine::bake::fields::{BakeFields, FIELDS};
use relume_engine::bake::presets::Preset;
use relume_engine::bake::BakeSettings;
use relume_engine::scene::Resolution;
use serde_json::{json, Map, Value};

const SCENE: Resolution = Resolution {
    width: 512,
    height: 384,
};

/// A valid value other than the default for each field.
fn other_value(key: &str) -> Value {
    match key {
        "spp"
        | "light_samples"
        | "bounce_light_samples"
        | "diffuse_bounces"
        | "glossy_bounces"
        | "indirect_samples"
        | "bounces"
        | "threads" => json!(3),
        "bounce_budget" | "drop_budget" => json!(0.01),
        "sampling" => json!("guided"),
        "seed" => json!(7),
        "resolution" => json!("64x32"),
        "resolution_scale" => json!(0.5),
        "precision" => json!("f32"),
        "bases" => json!(4),
        "basis_tolerance" => json!(0.05),
        "ns_min" => json!(2.0),
        "ns_max" => json!(500.0),
        "lobe" => json!("principled"),
        "principled_bases" => json!(5),
        "light_grouping" => json!("per-light"),
        "subsurface_samples" => json!(1000),
        "subsurface_theta" => json!(0.3),
        "denoise_direct" | "denoise_bounce" => json!(2),
        "memory_budget_mb" => json!(256.0),
        "compression_step" => json!(4),
        "compression_tolerance" => json!(0.01),
        "adaptive_threshold" => json!(0.02),
        "adaptive_min_spp" => json!(8),
        other => panic!("no test value for the new field {other}: add one here"),
    }
}

/// Values of the settings no front sets, with why.
const NOT_A_FRONTS: &[&str] = &[
    // The PCA's lobe count, measuring grid, spacing and measure: the basis's own
    // configuration, fixed by the engine (a stack records it; no user chooses it).
    "basis.lobes",
    "basis.grid",
    "basis.spacing",
    "basis.weighting",
    "basis.measure",
    "basis.constant_in_fit",
];

/// Leaf paths (`basis.ns_min`) of a JSON value, with their values.
fn leaves(prefix: &str, v: &Value, out: &mut Vec<(String, Value)>) {
    match v {
        Value::Object(m) => {
            for (k, v) in m {
                let path = if prefix.is_empty() {
                    k.clone()
                } else {
                    format!("{prefix}.{k}")
                };
                leaves(&path, v, out);
            }
        }
        other => out.push((prefix.to_string(), other.clone())),
    }
}

fn one(key: &str, value: Value) -> Map<String, Value> {
    Map::from_iter([(key.to_string(), value)])
}

#[test]
fn every_value_of_the_settings_is_set_by_a_field_and_every_field_reaches_the_settings() {
    let default = serde_json::to_value(BakeSettings::default()).unwrap();
    let mut required = Vec::new();
    leaves("", &default, &mut required);
    let mut reached = BTreeSet::new();
    for field in FIELDS {
        // A field that means something only with another starts from that other set.
        let mut start = BakeFields::default();
        if field.key == "compression_tolerance" {
            start.apply(&one("compression_step", json!(4))).unwrap();
        }
        if field.key == "principled_bases" {
            start.apply(&one("lobe", json!("principled"))).unwrap();
        }
        if field.key == "adaptive_min_spp" {
            start
                .apply(&one("adaptive_threshold", json!(0.02)))
                .unwrap();
        }
        let mut base = Vec::new();
        leaves(
            "",
            &serde_json::to_value(start.settings(SCENE).unwrap()).unwrap(),
            &mut base,
        );
        let mut fields = start.clone();
        fields
            .apply(&one(field.key, other_value(field.key)))
            .unwrap_or_else(|e| panic!("{}: {e}", field.key));
        let changed = serde_json::to_value(fields.settings(SCENE).unwrap()).unwrap();
        let mut after = Vec::new();
        leaves("", &changed, &mut after);
        let before: Vec<_> = base.iter().map(|(p, _)| p.clone()).collect();
        let mut moved = false;
        for (path, value) in &base {
            let now = after.iter().find(|(p, _)| p == path).map(|(_, v)| v);
            // A null that became an object (the resolution) is a change of that path.
            let grew = after
                .iter()
                .any(|(p, _)| p.starts_with(&format!("{path}.")) && !before.contains(p));
            if now != Some(value) || grew {
                reached.insert(path.clone());
                moved = true;
            }
        }
        // `lobe` adds the principled basis's configuration, absent by default.
        moved |= after.iter().any(|(p, _)| !before.contains(p));
        assert!(moved, "{} changes nothing in BakeSettings", field.key);
    }
    let missing: Vec<_> = required
        .iter()
        .map(|(p, _)| p.as_str())
        .filter(|p| {
            let exempt = NOT_A_FRONTS
                .iter()
                .any(|n| p == n || p.starts_with(&format!("{n}.")));
            !reached.contains(*p) && !exempt
        })
        .collect();
    assert!(
        missing.is_empty(),
        "BakeSettings values no front sets: {missing:?}; add them to BakeFields (bake/fields.rs) \
         or, if no user chooses them, to NOT_A_FRONTS with why"
    );
}

#[test]
fn the_defaults_and_the_presets_round_trip_to_the_engines_settings() {
    let same = |a: &BakeSettings, b: &BakeSettings| {
        serde_json::to_value(a).unwrap() == serde_json::to_value(b).unwrap()
    };
    let fields = BakeFields::default();
    assert!(same(
        &fields.settings(SCENE).unwrap(),
        &BakeSettings::default()
    ));
    for preset in Preset::ALL {
        let fields = BakeFields::preset(preset);
        let mut expected = BakeSettings::default();
        let scale = preset.apply(&mut expected);
        expected.bounces = relume_engine::bake::settings::DEFAULT_BOUNCES;
        if scale != 1.0 {
            expected.resolution = Some(SCENE.scaled(scale).unwrap());
        }
        assert!(
            same(&fields.settings(SCENE).unwrap(), &expected),
            "{}",
            preset.name()
        );
    }
}

#[test]
fn a_bad_value_is_refused_naming_its_key_and_changes_nothing() {
    let start = BakeFields::preset(Preset::Preview);
    for (key, value, words) in [
        ("spp", json!(0), "≥ 1"),
        ("spp", json!("many"), "expected u32"),
        ("sampling", json!("best"), "uniform"),
        ("resolution", json!("wide"), "WIDTHxHEIGHT"),
        ("resolution_scale", json!(0.0), "(0, 16]"),
        ("threads", json!(100_000), "at most"),
        ("drop_budget", json!(1.5), "[0, 1)"),
        ("memory_budget_mb", json!(0.0), "> 0"),
        ("compression_step", json!(17), "at most"),
        ("ns_min", json!(-1.0), "ns_min"),
        ("principled_bases", json!(1), "to 31"),
        ("principled_bases", json!(40), "to 31"),
        ("no_such_thing", json!(1), "no such bake setting"),
    ] {
        let mut fields = start.clone();
        let e = fields.apply(&one(key, value)).unwrap_err().to_string();
        let named = key.split('_').next().unwrap();
        assert!(e.contains(named) && e.contains(words), "{key}: {e}");
        assert_eq!(fields, start, "{key}: a refused value changed the fields");
    }
}

#[test]
fn overrides_keep_the_pairs_that_name_one_value_consistent() {
    let mut fields = BakeFields::preset(Preset::Final);
    assert!(fields.basis_tolerance.is_some() && fields.bases.is_none());
    fields.apply(&one("bases", json!(7))).unwrap();
    assert_eq!((fields.bases, fields.basis_tolerance), (Some(7), None));
    let both = Map::from_iter([
        ("bases".to_string(), json!(7)),
        ("basis_tolerance".to_string(), json!(0.1)),
    ]);
    let e = fields.apply(&both).unwrap_err().to_string();
    assert!(e.contains("not both"), "{e}");
    // A resolution given alone is baked as given: the preset's scale no longer applies.
    let mut draft = BakeFields::preset(Preset::Draft);
    draft.apply(&one("resolution", json!([100, 50]))).unwrap();
    let r = draft.settings(SCENE).unwrap().resolution;
    assert_eq!(
        r,
        Some(Resolution {
            width: 100,
            height: 50
        })
    );
    // A step turning compression on reads back with the tolerance it bakes with.
    let mut fields = BakeFields::default();
    fields.apply(&one("compression_step", json!(8))).unwrap();
    assert!(fields.compression_tolerance > 0.0);
    // Off again: the tolerance goes with it rather than being silently kept.
    fields.apply(&one("compression_step", json!(0))).unwrap();
    assert_eq!(fields.compression_tolerance, 0.0);
}
