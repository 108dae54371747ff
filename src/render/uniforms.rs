//! GPU-visible uniform structs; each one mirrors a WGSL struct and must stay in sync with it.

use bytemuck::{Pod, Zeroable};
use glam::{Mat4, Vec3};

use crate::cave::ViewSetup;
use crate::cave::omni::{OmniSettings, WarpVariant};
use crate::scene::shadows::{LightShadow, MAX_SHADOW_LAYERS, ShadowSettings};
use crate::scene::{
    AlphaMode, Light, LightKind, Lighting, Material, Shading, TEXTURE_SLOTS, UvTransform,
};
use crate::sky::irradiance::SkyIrradiance;

/// Lights a frame holds at most. Keep in sync with `MAX_LIGHTS` in shaders/common.wgsl.
pub const MAX_LIGHTS: usize = 8;

/// One light, CAVE space. Keep in sync with `Light` in shaders/common.wgsl.
#[repr(C)]
#[derive(Debug, Clone, Copy, Pod, Zeroable, PartialEq)]
pub struct GpuLight {
    /// xyz: position; w: range in metres (0: no cut-off).
    pub position: [f32; 4],
    /// xyz: unit direction the light travels; w: kind (0 directional, 1 point, 2 spot).
    pub direction: [f32; 4],
    /// rgb: linear colour × intensity; w: falloff (0 inverse square with the glTF range
    /// window, 1 the config's smooth fade).
    pub color: [f32; 4],
    /// Spot: x cos(outer cone), y 1 / (cos(inner) − cos(outer)).
    pub cone: [f32; 4],
    /// x: first shadow-map layer (< 0: none); y: layers; z: texel size at 1 m (perspective);
    /// w: texel size (orthographic).
    pub shadow: [f32; 4],
}

impl GpuLight {
    /// A scene light moved into CAVE space (`scale`: CAVE metres per scene unit).
    pub fn from_scene(light: &Light, cave_from_world: Mat4, scale: f32) -> Self {
        let (kind, cone) = match light.kind {
            LightKind::Directional => (0.0, [0.0; 4]),
            LightKind::Point => (1.0, [0.0; 4]),
            LightKind::Spot {
                inner_cone,
                outer_cone,
            } => {
                let (cos_outer, cos_inner) = (outer_cone.cos(), inner_cone.cos());
                (
                    2.0,
                    [cos_outer, 1.0 / (cos_inner - cos_outer).max(1e-4), 0.0, 0.0],
                )
            }
        };
        let direction = cave_from_world
            .transform_vector3(light.direction)
            .normalize_or(Vec3::NEG_Y);
        Self {
            position: cave_from_world
                .transform_point3(light.position)
                .extend(light.range.map_or(0.0, |r| r * scale))
                .to_array(),
            direction: direction.extend(kind).to_array(),
            color: light.color.extend(0.0).to_array(),
            cone,
            shadow: [-1.0, 0.0, 0.0, 0.0],
        }
    }
}

/// Per-frame data. Keep in sync with `FrameUniforms` in shaders/common.wgsl.
#[repr(C)]
#[derive(Debug, Clone, Copy, Pod, Zeroable)]
pub struct FrameUniforms {
    pub cave_from_world: [[f32; 4]; 4],
    pub normal_from_world: [[f32; 4]; 4],
    /// rgb: ambient radiance (linear).
    pub ambient: [f32; 4],
    pub wire_color: [f32; 4],
    pub omni: [f32; 4],
    /// Lights in use (0..=MAX_LIGHTS).
    pub light_count: u32,
    /// 0 physically based, 1 simple.
    pub shading: u32,
    /// Shadow-map range tiles per side ([`crate::scene::shadows::range_tiles`]); 0: the 3×3
    /// filter always gathers.
    pub shadow_tiles: u32,
    pub frame_pad: u32,
    /// x: normal offset of look-ups, texels; y: 1 for 3×3 filtering; z: 1 / map size; w: 1
    /// when shadows are on.
    pub shadow_params: [f32; 4],
    /// x: 1 when the sky lights the scene.
    pub sky_params: [f32; 4],
    /// CAVE → scene directions, for the sky's irradiance.
    pub sky_from_cave: [[f32; 4]; 4],
    /// The sky's irradiance (spherical harmonics, rgb), strength and exposure applied.
    pub sky_sh: [[f32; 4]; 9],
    pub lights: [GpuLight; MAX_LIGHTS],
    /// CAVE space → each shadow-map layer's clip space.
    pub shadow_from_cave: [[[f32; 4]; 4]; MAX_SHADOW_LAYERS],
}

/// The lights of a frame: the config's directional and point light (when they shine) and
/// the scene file's, in scene space.
#[derive(Debug, Clone, Copy)]
pub struct FrameLights<'a> {
    pub config: &'a Lighting,
    pub scene: &'a [Light],
    pub shading: Shading,
}

impl FrameLights<'_> {
    /// Every light of the frame in order (scene space), at most [`MAX_LIGHTS`]: the ones past
    /// it are left out.
    pub fn all(&self) -> Vec<Light> {
        let mut all = config_lights(self.config);
        all.extend(self.scene.iter().cloned());
        all.truncate(MAX_LIGHTS);
        all
    }
}

/// The sky's light on a frame: its irradiance and how strongly it counts (light × exposure).
#[derive(Debug, Clone, Copy)]
pub struct SkyLight<'a> {
    pub irradiance: &'a SkyIrradiance,
    pub strength: f32,
}

/// A frame's shadows: the settings and, per light of [`FrameLights::all`], its layers.
#[derive(Debug, Clone, Copy)]
pub struct FrameShadows<'a> {
    pub settings: &'a ShadowSettings,
    pub plan: &'a [Option<LightShadow>],
}

impl FrameUniforms {
    /// Lighting is given in scene (world) space and moved into CAVE space here. `omni` is
    /// `Some` in the omnistereo modes. Lights past [`MAX_LIGHTS`] are left out (the loader
    /// warned about them).
    pub fn new(
        world_from_cave: Mat4,
        lights: FrameLights<'_>,
        shadows: Option<FrameShadows<'_>>,
        sky: Option<SkyLight<'_>>,
        omni: Option<OmniSettings>,
    ) -> Self {
        let cave_from_world = world_from_cave.inverse();
        // Normals transform with the inverse transpose of the linear part.
        let normal_from_world =
            Mat4::from_mat3(glam::Mat3::from_mat4(cave_from_world).inverse().transpose());
        // Ranges are physical distances in the scene; CAVE metres differ by the placement scale.
        let scale = cave_from_world.transform_vector3(Vec3::X).length();
        let mut gpu_lights = [GpuLight::zeroed(); MAX_LIGHTS];
        let mut shadow_from_cave = [[[0.0; 4]; 4]; MAX_SHADOW_LAYERS];
        let all = lights.all();
        for (k, light) in all.iter().enumerate() {
            let mut gpu = GpuLight::from_scene(light, cave_from_world, scale);
            if matches!(light.kind, LightKind::Point) && light.name == CONFIG_POINT_LIGHT {
                gpu.color[3] = 1.0;
            }
            if let Some(Some(s)) = shadows.and_then(|f| f.plan.get(k)) {
                // Texel sizes in CAVE metres.
                gpu.shadow = [
                    s.first_layer as f32,
                    s.shadow_from_world.len() as f32,
                    s.texel_per_metre,
                    s.texel / scale.max(1e-6),
                ];
                for (i, m) in s.shadow_from_world.iter().enumerate() {
                    if let Some(slot) = shadow_from_cave.get_mut(s.first_layer + i) {
                        *slot = (*m * world_from_cave).to_cols_array_2d();
                    }
                }
            }
            gpu_lights[k] = gpu;
        }
        let count = all.len();
        Self {
            cave_from_world: cave_from_world.to_cols_array_2d(),
            normal_from_world: normal_from_world.to_cols_array_2d(),
            ambient: lights.config.ambient.extend(0.0).to_array(),
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
            light_count: count as u32,
            shading: match lights.shading {
                Shading::Pbr => 0,
                Shading::Simple => 1,
            },
            shadow_tiles: match shadows {
                Some(f) if f.settings.range_test() => {
                    crate::scene::shadows::range_tiles(f.settings.map_size)
                }
                _ => 0,
            },
            frame_pad: 0,
            shadow_params: match shadows {
                Some(f) if f.settings.enabled => [
                    f.settings.normal_offset_texels,
                    if f.settings.pcf { 1.0 } else { 0.0 },
                    1.0 / f.settings.map_size.max(1) as f32,
                    1.0,
                ],
                _ => [0.0; 4],
            },
            sky_params: [
                if sky.is_some_and(|s| s.strength > 0.0) {
                    1.0
                } else {
                    0.0
                },
                0.0,
                0.0,
                0.0,
            ],
            // The placement's rotation without its scale (directions only).
            sky_from_cave: Mat4::from_mat3(
                glam::Mat3::from_mat4(world_from_cave) * (1.0 / scale.max(1e-12)),
            )
            .to_cols_array_2d(),
            sky_sh: match sky {
                Some(s) => s
                    .irradiance
                    .coefficients
                    .map(|c| (c * s.strength).extend(0.0).to_array()),
                None => [[0.0; 4]; 9],
            },
            lights: gpu_lights,
            shadow_from_cave,
        }
    }
}

/// Name of the config's point light among a frame's lights (its falloff is the config's
/// smooth fade, not the inverse square).
const CONFIG_POINT_LIGHT: &str = "[lighting.point]";

/// The config's lights as scene lights: intensities carry π, so that a white matte surface
/// facing a light of intensity 1 is white (the config's lights are display-referred; glTF
/// lights are photometric and taken as they are). Dark lights are left out.
fn config_lights(l: &Lighting) -> Vec<Light> {
    let pi = std::f32::consts::PI;
    let mut lights = Vec::with_capacity(2);
    if l.sun_color.max_element() > 0.0 {
        lights.push(Light {
            name: "[lighting.directional]".into(),
            kind: LightKind::Directional,
            position: Vec3::ZERO,
            direction: l.sun_direction,
            color: l.sun_color * pi,
            range: None,
            casts_shadows: l.sun_shadows,
        });
    }
    if l.point_color.max_element() > 0.0 && l.point_range > 0.0 {
        lights.push(Light {
            name: CONFIG_POINT_LIGHT.into(),
            kind: LightKind::Point,
            position: l.point_position,
            direction: Vec3::NEG_Y,
            color: l.point_color * pi,
            range: Some(l.point_range),
            casts_shadows: l.point_shadows,
        });
    }
    lights
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
    /// Bit k: texture slot k is bound; bit 8 + k: slot k reads `TEXCOORD_1`.
    pub texture_flags: u32,
    pub metallic: f32,
    pub roughness: f32,
    pub normal_scale: f32,
    pub occlusion_strength: f32,
    /// Alpha cutoff (< 0: no mask).
    pub alpha_cutoff: f32,
    /// 1: alpha-blended.
    pub alpha_blend: u32,
    /// 1 for unlit materials (KHR_materials_unlit).
    pub unlit: u32,
    pub material_pad: u32,
    /// `KHR_texture_transform` of slot k: rows 2k and 2k + 1 (xyz used).
    pub uv_transforms: [[f32; 4]; 2 * TEXTURE_SLOTS],
}

impl From<&Material> for MaterialUniforms {
    fn from(m: &Material) -> Self {
        let mut texture_flags = 0;
        let mut uv_transforms = [[0.0; 4]; 2 * TEXTURE_SLOTS];
        for (slot, texture) in m.texture_slots().iter().enumerate() {
            let transform = match texture {
                Some(t) => {
                    texture_flags |= 1 << slot;
                    if t.tex_coord == 1 {
                        texture_flags |= 1 << (8 + slot);
                    }
                    t.transform
                }
                None => UvTransform::IDENTITY,
            };
            for (row, values) in transform.rows.iter().enumerate() {
                uv_transforms[2 * slot + row] = [values[0], values[1], values[2], 0.0];
            }
        }
        let (alpha_cutoff, alpha_blend) = match m.alpha_mode {
            AlphaMode::Opaque => (-1.0, 0),
            AlphaMode::Mask(cutoff) => (cutoff, 0),
            AlphaMode::Blend => (-1.0, 1),
        };
        Self {
            base_color: m.base_color,
            emissive: m.emissive,
            texture_flags,
            metallic: m.metallic,
            roughness: m.roughness,
            normal_scale: m.normal_scale,
            occlusion_strength: m.occlusion_strength,
            alpha_cutoff,
            alpha_blend,
            unlit: u32::from(m.unlit),
            material_pad: 0,
            uv_transforms,
        }
    }
}
