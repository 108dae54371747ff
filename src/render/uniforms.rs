//! GPU-visible uniform structs; each one mirrors a WGSL struct and must stay in sync with it.

use bytemuck::{Pod, Zeroable};
use glam::{Mat4, Vec3};

use crate::cave::ViewSetup;
use crate::cave::omni::{OmniSettings, WarpVariant};
use crate::scene::Lighting;
use crate::scene::Material;

/// Uniform slots are padded to this stride so each can be bound with a dynamic offset.
pub const UNIFORM_STRIDE: u64 = 256;

/// Per-frame data. Keep in sync with `FrameUniforms` in shaders/common.wgsl.
#[repr(C)]
#[derive(Debug, Clone, Copy, Pod, Zeroable)]
pub struct FrameUniforms {
    pub cave_from_world: [[f32; 4]; 4],
    pub normal_from_world: [[f32; 4]; 4],
    pub sun_direction: [f32; 4],
    pub sun_color: [f32; 4],
    pub point_position: [f32; 4],
    pub point_color: [f32; 4],
    pub ambient: [f32; 4],
    pub wire_color: [f32; 4],
    pub omni: [f32; 4],
}

impl FrameUniforms {
    /// Lighting is given in scene (world) space and moved into CAVE space here. `omni` is
    /// `Some` in the omnistereo modes.
    pub fn new(world_from_cave: Mat4, lighting: &Lighting, omni: Option<OmniSettings>) -> Self {
        let cave_from_world = world_from_cave.inverse();
        // Normals transform with the inverse transpose of the linear part.
        let normal_from_world =
            Mat4::from_mat3(glam::Mat3::from_mat4(cave_from_world).inverse().transpose());
        let sun = cave_from_world
            .transform_vector3(lighting.sun_direction)
            .normalize_or(Vec3::NEG_Y);
        let point = cave_from_world.transform_point3(lighting.point_position);
        // Ranges are physical distances in the scene; CAVE metres differ by the placement scale.
        let scale = cave_from_world.transform_vector3(Vec3::X).length();
        Self {
            cave_from_world: cave_from_world.to_cols_array_2d(),
            normal_from_world: normal_from_world.to_cols_array_2d(),
            sun_direction: sun.extend(0.0).to_array(),
            sun_color: lighting.sun_color.extend(0.0).to_array(),
            point_position: point.extend(lighting.point_range * scale).to_array(),
            point_color: lighting.point_color.extend(0.0).to_array(),
            ambient: lighting.ambient.extend(0.0).to_array(),
            wire_color: [0.9, 0.9, 0.9, 1.0],
            omni: match omni {
                None => [0.0; 4],
                Some(o) => {
                    let warp = match o.warp {
                        WarpVariant::SimilarTriangles => 1.0,
                        WarpVariant::IntersectionPoint => 2.0,
                    };
                    match o.pole_merge {
                        Some(p) => [
                            warp,
                            p.start_degrees.to_radians(),
                            p.end_degrees.to_radians(),
                            1.0,
                        ],
                        None => [warp, 0.0, 0.0, 0.0],
                    }
                }
            },
        }
    }
}

/// One wall from one eye. Keep in sync with `ViewUniforms` in shaders/common.wgsl.
#[repr(C)]
#[derive(Debug, Clone, Copy, Pod, Zeroable)]
pub struct ViewUniforms {
    pub clip_from_cave: [[f32; 4]; 4],
    pub eye_position: [f32; 4],
    pub wall_plane: [f32; 4],
    pub omni_head: [f32; 4],
    /// The fields below are for panorama views only (zero for walls). The projection's code
    /// + 1 (0: not a panorama).
    pub pano_projection: u32,
    /// Near and far clipping sphere radius, metres.
    pub pano_near: f32,
    pub pano_far: f32,
    /// 0 mono, 1 volume, 2 omni.
    pub pano_stereo: u32,
    /// The field of view's centre and half size in map coordinates.
    pub pano_window: [f32; 4],
    /// Image pixels.
    pub pano_size: [f32; 2],
    /// Volume stereo: signed half inter-ocular distance, viewing distance and zero-parallax
    /// depth (normalised device units).
    pub volume_half_ioid: f32,
    pub volume_distance: f32,
    pub volume_zero_parallax: f32,
    /// The panorama target's MSAA sample count.
    pub pano_msaa: u32,
    pub pano_pad: [u32; 2],
}

impl From<&ViewSetup> for ViewUniforms {
    fn from(view: &ViewSetup) -> Self {
        let (wall_plane, omni_head) = match (view.omni, view.eye) {
            (Some(o), Some(eye)) => (
                o.wall_plane.to_array(),
                o.head.extend(eye.sign() * 0.5 * o.ipd).to_array(),
            ),
            _ => ([0.0; 4], [0.0; 4]),
        };
        Self {
            clip_from_cave: view.clip_from_cave.to_cols_array_2d(),
            eye_position: view.eye_position.extend(1.0).to_array(),
            wall_plane,
            omni_head,
            ..Zeroable::zeroed()
        }
    }
}

/// One material. Keep in sync with `MaterialUniforms` in shaders/scene.wgsl.
#[repr(C)]
#[derive(Debug, Clone, Copy, Pod, Zeroable)]
pub struct MaterialUniforms {
    /// Linear RGBA multiplier.
    pub base_color: [f32; 4],
    /// Emitted light (linear).
    pub emissive: [f32; 3],
    /// 1 for unlit materials (KHR_materials_unlit).
    pub unlit: u32,
    pub shininess: f32,
    pub specular: f32,
    /// Alpha cutoff (< 0: opaque).
    pub alpha_cutoff: f32,
    pub material_pad: u32,
}

impl From<&Material> for MaterialUniforms {
    fn from(m: &Material) -> Self {
        Self {
            base_color: m.base_color,
            emissive: m.emissive,
            unlit: u32::from(m.unlit),
            shininess: m.shininess,
            specular: m.specular,
            alpha_cutoff: m.alpha_cutoff.unwrap_or(-1.0),
            material_pad: 0,
        }
    }
}
