//! Every Rust struct shared with WGSL has its WGSL twin's layout: the same size and every WGSL
//! member at the offset the Rust struct puts it, as naga (the compiler wgpu uses) lays them
//! out. A field added, dropped, reordered or retyped on one side only fails here.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use std::mem::{offset_of, size_of};

use omnicave::render::panorama::ResolveUniforms;
use omnicave::render::present::PresentUniforms;
use omnicave::render::shaders::{self, compose};
use omnicave::render::sky_pass::SkyUniforms;
use omnicave::render::tessellator::{GpuTessEntry, TessUniforms};
use omnicave::render::uniforms::{FrameUniforms, MaterialUniforms, ViewUniforms};

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

fn cases() -> Vec<(&'static str, &'static str, RustLayout)> {
    vec![
        (
            shaders::SCENE,
            "FrameUniforms",
            layout!(FrameUniforms,
                "cave_from_world" => cave_from_world,
                "normal_from_world" => normal_from_world,
                "sun_direction" => sun_direction,
                "sun_color" => sun_color,
                "point_position" => point_position,
                "point_color" => point_color,
                "ambient" => ambient,
                "wire_color" => wire_color,
                "omni" => omni,
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
                "unlit" => unlit,
                "shininess" => shininess,
                "specular" => specular,
                "alpha_cutoff" => alpha_cutoff,
                "material_pad" => material_pad,
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
        "emissive" => shininess,
        "unlit" => unlit,
        "shininess" => shininess,
        "specular" => specular,
        "alpha_cutoff" => alpha_cutoff,
        "material_pad" => material_pad,
    );
    let found = differences(&source, "MaterialUniforms", &moved);
    assert_eq!(found.len(), 1, "{found:?}");
    assert!(
        found[0].contains("MaterialUniforms.emissive is at byte 16 in WGSL, 32 in"),
        "{found:?}"
    );
}
