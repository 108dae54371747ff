//! Real models the project did not generate (Khronos sample models in `../shared/corpus`):
//! each loads with what its exporter put in it and renders as a model, not a flat or black
//! shape, on the walls and through the tessellated omnistereo path. Skips, saying so, where
//! the corpus is absent (a newcomer's clone); CI has it and must not skip.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::print_stdout)]

mod common;

use std::collections::HashSet;
use std::path::Path;

use common::*;
use glam::Vec3;
use omnicave::cave::omni::OmniSettings;
use omnicave::cave::{Head, RenderMode};
use omnicave::render::Renderer;
use omnicave::scene::{AlphaMode, Scene, SceneFit, load_gltf};
use omnicave::tess::{Criterion, TessSettings};

fn model(corpus: &Path, name: &str) -> Scene {
    let dir = corpus.join(name);
    let file = ["gltf", "glb"]
        .iter()
        .map(|ext| dir.join(format!("{name}.{ext}")))
        .find(|p| p.is_file())
        .unwrap_or_else(|| panic!("{name}: no .gltf or .glb"));
    let mut scene = load_gltf(&file).unwrap_or_else(|e| panic!("{e}"));
    // As a user would: fitted on the floor, 0.8 m across; then lifted onto a 0.6 m table
    // 1 m ahead, in front of the front wall.
    let fit = scene.fit_transform(SceneFit::Floor, 0.8);
    scene.transform(glam::Mat4::from_translation(Vec3::new(0.0, 0.6, -1.0)) * fit);
    scene
}

#[test]
fn every_corpus_model_loads_with_what_its_exporter_wrote() {
    let Some(corpus) = corpus() else { return };
    let helmet = model(&corpus, "DamagedHelmet");
    let m = &helmet.materials[helmet.draws[0].material];
    assert!(
        m.base_color_texture.is_some()
            && m.metallic_roughness_texture.is_some()
            && m.normal_texture.is_some()
            && m.occlusion_texture.is_some()
            && m.emissive_texture.is_some(),
        "DamagedHelmet: every map read: {m:?}"
    );
    // No tangents in the file: generated for its normal map.
    let with_tangents = helmet
        .vertices
        .iter()
        .filter(|v| v.tangent[3] != 0.0)
        .count();
    // One vertex that no triangle uses gets none (MikkTSpace works per face corner).
    assert!(with_tangents + 1 >= helmet.vertices.len());

    let flight = model(&corpus, "FlightHelmet");
    assert!(flight.materials.len() >= 6);
    assert!(
        flight
            .materials
            .iter()
            .any(|m| m.alpha_mode == AlphaMode::Blend),
        "FlightHelmet's lenses are alpha-blended"
    );

    let colours = model(&corpus, "BoxVertexColors");
    let distinct: HashSet<[u8; 4]> = colours
        .vertices
        .iter()
        .map(|v| v.color.map(|c| (c * 255.0) as u8))
        .collect();
    assert!(distinct.len() >= 4, "BoxVertexColors: {distinct:?}");

    let duck = model(&corpus, "Duck");
    assert_eq!(duck.cameras.len(), 1, "Duck's camera node");
    assert_eq!(duck.textures.len(), 1);

    // SimpleSparseAccessor: a 2×? grid whose sparse values raise three vertices to y = 4
    // (before fitting, 6 units wide): the raised vertices lift the bounds' top.
    let dir = corpus.join("SimpleSparseAccessor");
    let sparse = load_gltf(&dir.join("SimpleSparseAccessor.gltf")).unwrap();
    let (lo, hi) = sparse.bounds().unwrap();
    assert_eq!(hi.y, 4.0, "the sparse substitution lifts vertices to y = 4");
    assert_eq!(lo.y, 0.0);
}

#[test]
fn every_corpus_model_renders_as_a_model_in_stereo_and_tessellated_omnistereo() {
    let Some(corpus) = corpus() else { return };
    let cave = cave_at(256, 224);
    let front = cave.wall_index("front").unwrap();
    // Looking at the model on its table, seen on the front wall.
    let head = Head::at(Vec3::new(0.0, 1.3, 0.5));
    // Each model and the colours it shows at least: textured and lit models many; the sparse
    // model is one flat, untextured, evenly lit surface.
    for (name, min_buckets) in [
        ("BoxTextured", 8),
        ("BoxVertexColors", 8),
        ("Duck", 8),
        ("DamagedHelmet", 8),
        ("FlightHelmet", 8),
        ("SimpleSparseAccessor", 1),
    ] {
        let scene = model(&corpus, name);
        let mut renderer = Renderer::new(gpu(), &cave, NO_MSAA).expect("renderer");
        renderer.set_scene(&scene).expect("scene upload");
        for (mode, tess) in [
            (RenderMode::Stereo, TessSettings::default()),
            (
                RenderMode::OmniOffAxis,
                TessSettings {
                    criterion: Some(Criterion::Error(0.5)),
                    ..TessSettings::default()
                },
            ),
        ] {
            let frame = test_frame(&cave, head, mode, OmniSettings::default(), tess);
            renderer.render(&frame).expect("render");
            let images = renderer.read_images().expect("read back");
            let image = &images[front].left;
            // The model's pixels (the background is black) and how varied they are: a flat or
            // black rendering has one or two colours; a model lit and textured has many.
            let model_pixels: Vec<[u8; 3]> = image
                .pixels()
                .map(|p| [p[0], p[1], p[2]])
                .filter(|c| c.iter().any(|&v| v > 8))
                .collect();
            let buckets: HashSet<[u8; 3]> =
                model_pixels.iter().map(|c| c.map(|v| v / 16)).collect();
            let mean = model_pixels
                .iter()
                .map(|c| c.iter().map(|&v| f32::from(v)).sum::<f32>() / 3.0)
                .sum::<f32>()
                / model_pixels.len().max(1) as f32;
            keep(&format!("{name}-{}", mode.name()), image);
            assert!(
                model_pixels.len() > 2000,
                "{name} {mode:?}: too few pixels drawn"
            );
            assert!(
                buckets.len() >= min_buckets,
                "{name} {mode:?}: degenerate (flat) rendering"
            );
            assert!(mean > 30.0, "{name} {mode:?}: nearly black");
        }
    }
}

/// Keeps an image for a person to look at: target/test-out/corpus/<name>.png.
fn keep(name: &str, image: &image::RgbaImage) {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("target/test-out/corpus");
    std::fs::create_dir_all(&dir).unwrap();
    image.save(dir.join(format!("{name}.png"))).unwrap();
}
