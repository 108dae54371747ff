//! Every WGSL file in shaders/ parses and validates with naga (the compiler wgpu uses), composed
//! exactly as the renderer composes it, and none is left out of the renderer's list; and every
//! Rust struct and constant shared with WGSL matches its WGSL twin: the same size and every
//! WGSL member at the offset the Rust struct puts it, as naga lays them out. A field added,
//! dropped, reordered or retyped on one side only fails here.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use std::mem::{offset_of, size_of};
use std::path::Path;

use omnicave::render::panorama::ResolveUniforms;
use omnicave::render::pose_pass::{PoseDeformer, PoseRestVertex, PoseUniforms};
use omnicave::render::present::PresentUniforms;
use omnicave::render::scene_gpu::GpuVertex;
use omnicave::render::shaders::{self, COMMON, FEATURES, SHARED, compose};
use omnicave::render::shadow_pass::ShadowLayerUniforms;
use omnicave::render::sky_pass::SkyUniforms;
use omnicave::render::tessellator::{GpuTessEntry, TessUniforms};
use omnicave::render::uniforms::{FrameUniforms, GpuLight, MaterialUniforms, ViewUniforms};

/// Parses and validates one WGSL source with naga, panicking with its diagnostics.
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

/// A Rust struct's size and, for each WGSL member by name, the Rust offset of its data.
struct RustLayout {
    name: &'static str,
    size: usize,
    members: Vec<(&'static str, usize)>,
}

/// `layout!(Type, "wgsl_member" => rust_field, …)`: offsets of the named Rust fields;
/// `"wgsl_member" => rust_field + N` for a WGSL member inside a Rust array field.
macro_rules! layout {
    ($ty:ty, $($member:literal => $field:ident $(+ $extra:literal)?),+ $(,)?) => {
        RustLayout {
            name: stringify!($ty),
            size: size_of::<$ty>(),
            members: vec![$(($member, offset_of!($ty, $field) $(+ $extra)?)),+],
        }
    };
}

/// Compares a Rust layout with the WGSL struct `wgsl_name` of `source`; the differences.
fn differences(source: &str, wgsl_name: &str, rust: &RustLayout) -> Vec<String> {
    let module = naga::front::wgsl::parse_str(source).expect("WGSL parses");
    let Some((members, span)) = module.types.iter().find_map(|(_, ty)| match &ty.inner {
        naga::TypeInner::Struct { members, span } if ty.name.as_deref() == Some(wgsl_name) => {
            Some((members.clone(), *span))
        }
        _ => None,
    }) else {
        return vec![format!("no WGSL struct {wgsl_name}")];
    };
    let mut out = Vec::new();
    if span as usize != rust.size {
        out.push(format!(
            "{wgsl_name} is {span} bytes in WGSL, {} is {} in Rust",
            rust.name, rust.size
        ));
    }
    for m in &members {
        let name = m.name.as_deref().unwrap_or("?");
        match rust.members.iter().find(|(n, _)| *n == name) {
            None => out.push(format!("{wgsl_name}.{name} has no Rust counterpart listed")),
            Some((_, offset)) if *offset != m.offset as usize => out.push(format!(
                "{wgsl_name}.{name} is at byte {} in WGSL, {} in {}",
                m.offset, offset, rust.name
            )),
            Some(_) => {}
        }
    }
    for (name, _) in &rust.members {
        if !members.iter().any(|m| m.name.as_deref() == Some(name)) {
            out.push(format!("{wgsl_name} has no member {name}"));
        }
    }
    out
}

fn cases() -> Vec<(shaders::Feature, &'static str, RustLayout)> {
    vec![
        (
            shaders::SCENE,
            "FrameUniforms",
            layout!(FrameUniforms,
                "cave_from_world" => cave_from_world,
                "normal_from_world" => normal_from_world,
                "ambient" => ambient,
                "wire_color" => wire_color,
                "omni" => omni,
                "light_count" => light_count,
                "shading" => shading,
                "shadow_tiles" => shadow_tiles,
                "frame_pad" => frame_pad,
                "shadow_params" => shadow_params,
                "sky_params" => sky_params,
                "sky_from_cave" => sky_from_cave,
                "sky_sh" => sky_sh,
                "lights" => lights,
                "shadow_from_cave" => shadow_from_cave,
            ),
        ),
        (
            shaders::SCENE,
            "Light",
            layout!(GpuLight,
                "position" => position,
                "direction" => direction,
                "color" => color,
                "cone" => cone,
                "shadow" => shadow,
            ),
        ),
        (
            shaders::SHADOW,
            "ShadowLayerUniforms",
            layout!(ShadowLayerUniforms,
                "shadow_from_world" => shadow_from_world,
            ),
        ),
        (
            shaders::SCENE,
            "ViewUniforms",
            layout!(ViewUniforms,
                "clip_from_cave" => clip_from_cave,
                "eye_position" => eye_position,
                "wall_plane" => wall_plane,
                "omni_head" => omni_head,
                "pano_projection" => pano_projection,
                "pano_near" => pano_near,
                "pano_far" => pano_far,
                "pano_stereo" => pano_stereo,
                "pano_window" => pano_window,
                "pano_size" => pano_size,
                "volume_half_ioid" => volume_half_ioid,
                "volume_distance" => volume_distance,
                "volume_zero_parallax" => volume_zero_parallax,
                "pano_msaa" => pano_msaa,
                "pano_pad" => pano_pad,
            ),
        ),
        (
            shaders::SCENE,
            "MaterialUniforms",
            layout!(MaterialUniforms,
                "base_color" => base_color,
                "emissive" => emissive,
                "texture_flags" => texture_flags,
                "metallic" => metallic,
                "roughness" => roughness,
                "normal_scale" => normal_scale,
                "occlusion_strength" => occlusion_strength,
                "alpha_cutoff" => alpha_cutoff,
                "alpha_blend" => alpha_blend,
                "unlit" => unlit,
                "material_pad" => material_pad,
                "uv_transforms" => uv_transforms,
            ),
        ),
        (
            shaders::POSE,
            "PoseUniforms",
            layout!(PoseUniforms,
                "vertex_count" => vertex_count,
                "groups_x" => groups_x,
                "pad0" => pad0,
                "pad1" => pad1,
            ),
        ),
        (
            shaders::POSE,
            "PoseDeformer",
            layout!(PoseDeformer,
                "first_vertex" => first_vertex,
                "rest_offset" => rest_offset,
                "first_matrix" => first_matrix,
                "influences_per_vertex" => influences_per_vertex,
                "influence_offset" => influence_offset,
                "target_count" => target_count,
                "delta_offset" => delta_offset,
                "first_weight" => first_weight,
            ),
        ),
        (
            shaders::POSE,
            "PoseRestVertex",
            layout!(PoseRestVertex,
                "position" => position,
                "deformer" => deformer,
                "normal" => normal,
                "tangent" => tangent,
            ),
        ),
        (
            shaders::TESSELLATE,
            "TessEntry",
            layout!(GpuTessEntry,
                "source" => source,
                "depth" => depth,
                "c0" => corners,
                "c1" => corners + 8,
                "c2" => corners + 16,
            ),
        ),
        (
            shaders::TESSELLATE,
            "TessUniforms",
            layout!(TessUniforms,
                "criterion" => criterion,
                "criterion_value" => criterion_value,
                "rounds" => rounds,
                "x_length_only" => x_length_only,
                "target_width" => target_width,
                "target_height" => target_height,
                "pixels_per_unit" => pixels_per_unit,
                "eye_wall_distance" => eye_wall_distance,
                "near" => near,
                "backface_cull" => backface_cull,
                "frustum_cull" => frustum_cull,
                "eye_ball_radius" => eye_ball_radius,
                "eye_ball_centre" => eye_ball_centre,
                "eye_ball_pad" => eye_ball_pad,
                "source_triangles" => source_triangles,
                "live_capacity" => live_capacity,
                "output_capacity" => output_capacity,
                "draws" => draws,
                "cluster_mode" => cluster_mode,
                "needy_offset" => needy_offset,
                "needy_count" => needy_count,
                "root_bound" => root_bound,
                "partner" => partner,
                "partner_eye_wall_distance" => partner_eye_wall_distance,
                "partner_near" => partner_near,
                "partner_pad" => partner_pad,
            ),
        ),
        (
            shaders::SKY,
            "SkyUniforms",
            layout!(SkyUniforms,
                "cube_from_cave" => cube_from_cave,
                "wall_origin" => wall_origin,
                "wall_right" => wall_right,
                "wall_up" => wall_up,
                "eye" => eye,
                "head" => head,
                "pole" => pole,
                "params" => params,
            ),
        ),
        (
            shaders::PRESENT,
            "PresentUniforms",
            layout!(PresentUniforms,
                "params" => params,
                "size" => size,
                "viewport" => viewport,
                "shift" => shift,
                "crop" => crop,
            ),
        ),
        (
            shaders::PANORAMA,
            "ResolveUniforms",
            layout!(ResolveUniforms,
                "cave_from_view" => cave_from_view,
                "cube_from_cave" => cube_from_cave,
                "window" => window,
                "params" => params,
                "background" => background,
            ),
        ),
    ]
}

#[test]
fn every_shared_struct_matches_its_wgsl_twin() {
    let mut problems = Vec::new();
    for (feature, wgsl_name, rust) in cases() {
        problems.extend(differences(&compose(feature), wgsl_name, &rust));
    }
    assert!(
        problems.is_empty(),
        "layouts differ:\n{}",
        problems.join("\n")
    );
}

#[test]
fn a_mismatch_is_caught() {
    // The checker itself must fail on structs that differ: TessUniforms laid against
    // FrameUniforms (other size, other members), and a member moved by 16 bytes.
    let source = compose(shaders::SCENE);
    let wrong = layout!(TessUniforms, "criterion" => criterion_value);
    assert!(!differences(&source, "FrameUniforms", &wrong).is_empty());
    let moved = layout!(MaterialUniforms,
        "base_color" => base_color,
        "emissive" => metallic,
        "texture_flags" => texture_flags,
        "metallic" => metallic,
        "roughness" => roughness,
        "normal_scale" => normal_scale,
        "occlusion_strength" => occlusion_strength,
        "alpha_cutoff" => alpha_cutoff,
        "alpha_blend" => alpha_blend,
        "unlit" => unlit,
        "material_pad" => material_pad,
        "uv_transforms" => uv_transforms,
    );
    let found = differences(&source, "MaterialUniforms", &moved);
    assert_eq!(found.len(), 1, "{found:?}");
    assert!(
        found[0].contains("MaterialUniforms.emissive is at byte 16 in WGSL, 32 in"),
        "{found:?}"
    );
}

/// The value of the WGSL `const NAME: u32` in `source`, as naga evaluates it.
fn wgsl_u32_constant(source: &str, name: &str) -> Option<u32> {
    let module = naga::front::wgsl::parse_str(source).expect("WGSL parses");
    let (_, constant) = module
        .constants
        .iter()
        .find(|(_, c)| c.name.as_deref() == Some(name))?;
    match module.global_expressions[constant.init] {
        naga::Expression::Literal(naga::Literal::U32(v)) => Some(v),
        _ => None,
    }
}

#[test]
fn the_vertex_stride_and_light_count_match() {
    // The tessellator and the tessellated draws read scene vertices as f32 storage with the
    // stride VERTEX_FLOATS; the vertex buffer is written as GpuVertex.
    let source = compose(shaders::SCENE);
    let constant = |name| wgsl_u32_constant(&source, name).map(|v| v as usize);
    assert_eq!(
        constant("VERTEX_FLOATS").map(|floats| 4 * floats),
        Some(size_of::<GpuVertex>())
    );
    assert_eq!(
        constant("MAX_LIGHTS"),
        Some(omnicave::render::uniforms::MAX_LIGHTS)
    );
    assert_eq!(
        constant("MAX_SHADOW_LAYERS"),
        Some(omnicave::scene::shadows::MAX_SHADOW_LAYERS)
    );
    // Each attribute where the storage reads expect it (offsets in floats).
    let floats = |bytes: usize| bytes / 4;
    assert_eq!(floats(offset_of!(GpuVertex, normal)), 3);
    assert_eq!(floats(offset_of!(GpuVertex, uv)), 6);
    assert_eq!(floats(offset_of!(GpuVertex, uv1)), 8);
    assert_eq!(floats(offset_of!(GpuVertex, color)), 10);
    assert_eq!(floats(offset_of!(GpuVertex, tangent)), 14);
    // The pose pass writes the posed normal and tangent at these offsets.
    let pose = compose(shaders::POSE);
    let pose_constant = |name| wgsl_u32_constant(&pose, name).map(|v| v as usize);
    assert_eq!(
        pose_constant("NORMAL_FLOAT"),
        Some(floats(offset_of!(GpuVertex, normal)))
    );
    assert_eq!(
        pose_constant("TANGENT_FLOAT"),
        Some(floats(offset_of!(GpuVertex, tangent)))
    );
}

#[test]
fn shared_constants_match_their_wgsl_twins() {
    use omnicave::render::tessellator::SPLIT_LEVELS;
    let source = compose(shaders::TESSELLATE);
    assert_eq!(
        wgsl_u32_constant(&source, "SPLIT_LEVELS"),
        Some(SPLIT_LEVELS),
        "split levels per dispatch: shaders/tessellate.wgsl and src/render/tessellator.rs"
    );
    // The counter and argument slots the GPU writes and the renderer reads back, and the
    // deepest fallback refinement (the CPU twin must fall back to the same depth).
    use omnicave::render::tessellator as t;
    for (name, rust) in [
        ("C_OUT", t::C_OUT),
        ("C_BACK", t::C_BACK),
        ("C_FRUSTUM", t::C_FRUSTUM),
        ("C_OVERFLOW", t::C_OVERFLOW),
        ("C_FALLBACK", t::C_FALLBACK),
        ("C_DRAWS", t::C_DRAWS),
        ("ARGS_FALLBACK", t::ARGS_FALLBACK),
        ("ARGS_DRAWS", t::ARGS_DRAWS),
        (
            "FALLBACK_DEPTH_LIMIT",
            omnicave::tess::FALLBACK_DEPTH_LIMIT as usize,
        ),
    ] {
        assert_eq!(
            wgsl_u32_constant(&source, name).map(|v| v as usize),
            Some(rust),
            "{name}: shaders/tessellate.wgsl and src/render/tessellator.rs or src/tess/mod.rs"
        );
    }
    // The checker itself reads constants: one that is not there is not found.
    assert_eq!(wgsl_u32_constant(&source, "NO_SUCH_CONSTANT"), None);
    let module = naga::front::wgsl::parse_str(&source).expect("WGSL parses");
    // The windows the scene's vertices are bound in, and the storage buffers the tessellator
    // binds in its compute stage: what the renderer asks the device for.
    assert_eq!(
        wgsl_u32_constant(&source, "VERTEX_WINDOWS").map(|v| v as usize),
        Some(omnicave::render::vertex_windows::VERTEX_WINDOWS),
        "vertex windows: shaders/common.wgsl and src/render/vertex_windows.rs"
    );
    let storage = module
        .global_variables
        .iter()
        .filter(|(_, g)| matches!(g.space, naga::AddressSpace::Storage { .. }))
        .count();
    assert_eq!(
        storage as u32,
        omnicave::render::gpu::TESSELLATOR_STORAGE_BUFFERS,
        "storage buffers: shaders/tessellate.wgsl and src/render/gpu.rs"
    );
    // The margin by which a two-edge split's other diagonal must be shorter: the GPU and the
    // CPU twin must cut every quadrilateral alike.
    let (_, margin) = module
        .constants
        .iter()
        .find(|(_, c)| c.name.as_deref() == Some("DIAGONAL_MARGIN"))
        .expect("DIAGONAL_MARGIN in shaders/tessellate.wgsl");
    assert_eq!(
        module.global_expressions[margin.init],
        naga::Expression::Literal(naga::Literal::F32(omnicave::tess::DIAGONAL_MARGIN)),
        "diagonal margin: shaders/tessellate.wgsl and src/tess/mod.rs"
    );
    // Where the error criterion samples an edge: the same fractions on both sides.
    let (_, samples) = module
        .constants
        .iter()
        .find(|(_, c)| c.name.as_deref() == Some("ERROR_SAMPLES"))
        .expect("ERROR_SAMPLES in shaders/tessellate.wgsl");
    let naga::Expression::Compose { ref components, .. } = module.global_expressions[samples.init]
    else {
        panic!("ERROR_SAMPLES is not an array");
    };
    let wgsl: Vec<naga::Expression> = components
        .iter()
        .map(|&c| module.global_expressions[c].clone())
        .collect();
    let rust: Vec<naga::Expression> = omnicave::tess::criteria::ERROR_SAMPLES
        .iter()
        .map(|&f| naga::Expression::Literal(naga::Literal::F32(f)))
        .collect();
    assert_eq!(
        wgsl, rust,
        "error samples: shaders/tessellate.wgsl and src/tess/criteria.rs"
    );
}
