//! Every WGSL file in shaders/ parses and validates with naga (the compiler wgpu uses), composed
//! exactly as the renderer composes it, and none is left out of the renderer's list.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use std::path::Path;

use omnicave::render::shaders::{COMMON, FEATURES, SHARED, compose};

fn validate(name: &str, source: &str) {
    let module = naga::front::wgsl::parse_str(source)
        .unwrap_or_else(|e| panic!("{name}: {}", e.emit_to_string(source)));
    naga::valid::Validator::new(
        naga::valid::ValidationFlags::all(),
        naga::valid::Capabilities::default(),
    )
    .validate(&module)
    .unwrap_or_else(|e| panic!("{name}: {}", e.emit_to_string(source)));
}

#[test]
fn every_wgsl_file_validates() {
    validate("common.wgsl", COMMON);
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("shaders");
    let mut seen = 0;
    for entry in std::fs::read_dir(&dir).unwrap() {
        let path = entry.unwrap().path();
        if path.extension().and_then(|e| e.to_str()) != Some("wgsl") {
            continue;
        }
        let stem = path.file_stem().unwrap().to_str().unwrap().to_owned();
        let text = std::fs::read_to_string(&path).unwrap();
        if let Some((_, shared)) = SHARED.iter().find(|(name, _)| *name == stem) {
            assert_eq!(
                text, *shared,
                "{stem}.wgsl differs from the compiled-in copy"
            );
            continue;
        }
        let feature = FEATURES
            .iter()
            .find(|f| f.stem == stem)
            .unwrap_or_else(|| panic!("shaders/{stem}.wgsl is not in render::shaders::FEATURES"));
        assert_eq!(
            feature.source, text,
            "{stem}.wgsl differs from the compiled-in copy"
        );
        validate(&format!("{stem}.wgsl"), &compose(*feature));
        seen += 1;
    }
    assert_eq!(
        seen,
        FEATURES.len(),
        "a feature shader listed in FEATURES has no file"
    );
}
