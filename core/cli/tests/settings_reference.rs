//! docs/cli.md's "Bake settings" list is generated from the engine's field documentation
//! (`relume_engine::bake::fields`), so the reference says what the code says. A field added
//! or reworded makes this test fail until the list is regenerated:
//! `RELUME_WRITE_DOCS=1 cargo test -p relume-cli --test settings_reference`.

use relume_engine::bake::fields::{BakeFields, FIELDS};

const BEGIN: &str = "<!-- bake settings: generated from core/engine/src/bake/fields.rs -->\n";
const END: &str = "<!-- end of bake settings -->\n";

/// The list: one item per field, with its flag, Python keyword and default.
fn generated() -> String {
    let defaults = BakeFields::default().to_map();
    let mut text = String::new();
    for field in FIELDS {
        let default = defaults
            .get(field.key)
            .map(|v| v.to_string())
            .unwrap_or_default();
        text += &format!(
            "- `--{}` (`{}=`, default `{default}`): {}\n",
            field.flag(),
            field.key,
            field.doc()
        );
    }
    text
}

#[test]
fn the_cli_reference_lists_every_bake_setting_with_its_documentation() {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../docs/cli.md");
    let doc = std::fs::read_to_string(&path).unwrap();
    let start = doc
        .find(BEGIN)
        .expect("docs/cli.md has the generated-list marker")
        + BEGIN.len();
    let end = start
        + doc[start..]
            .find(END)
            .expect("docs/cli.md has the end marker");
    let want = generated();
    if doc[start..end] == want {
        return;
    }
    if std::env::var_os("RELUME_WRITE_DOCS").is_some() {
        std::fs::write(&path, format!("{}{want}{}", &doc[..start], &doc[end..])).unwrap();
        return;
    }
    panic!(
        "docs/cli.md's bake settings differ from the engine's fields; regenerate with \
         RELUME_WRITE_DOCS=1 cargo test -p relume-cli --test settings_reference"
    );
}
