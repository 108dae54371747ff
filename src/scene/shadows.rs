//! Where shadows come from, without the GPU: the shadow settings, and which shadow-map layers
//! each light gets and where they look from (`render::shadow_pass` draws them).

use glam::camera::rh::{proj, view};
use glam::{Mat4, Vec3};

use super::{Light, LightKind};

/// Shadow-map layers a frame holds at most (a directional or spot light takes one, a point
/// light six). Keep in sync with `MAX_SHADOW_LAYERS` in shaders/common.wgsl.
pub const MAX_SHADOW_LAYERS: usize = 8;

/// Side of a range tile, texels: the 3×3 filter reads the least and greatest depth it could
/// gather from a point in the tile, and gathers only where the point's depth lies between
/// them. Keep in sync with `SHADOW_TILE` in shaders/shadow.wgsl and shaders/scene.wgsl.
pub const SHADOW_TILE: u32 = 4;

/// Range tiles per side of a map of `map_size` texels.
pub fn range_tiles(map_size: u32) -> u32 {
    map_size.div_ceil(SHADOW_TILE)
}

/// How shadows are drawn (the config's `[shadows]`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ShadowSettings {
    pub enabled: bool,
    /// Side of each shadow map, texels.
    pub map_size: u32,
    /// Look-ups move this many texels along the surface normal (against shadow acne).
    pub normal_offset_texels: f32,
    /// 3×3 percentage-closer filtering (soft edges), else one comparison.
    pub pcf: bool,
    /// The filter first reads its tile's depth range and gathers only where the point's
    /// depth lies within it (the same picture; false: it always gathers).
    pub pcf_range_test: bool,
    /// Directional lights shadow this far around the CAVE (metres, scene space).
    pub distance_m: f32,
}

impl ShadowSettings {
    /// Whether the filter reads the range tiles (shadows on, filtered, range test on).
    pub fn range_test(&self) -> bool {
        self.enabled && self.pcf && self.pcf_range_test
    }
}

impl Default for ShadowSettings {
    fn default() -> Self {
        Self {
            enabled: true,
            map_size: 1024,
            normal_offset_texels: 1.5,
            pcf: true,
            pcf_range_test: true,
            distance_m: 25.0,
        }
    }
}

/// One light's shadow: its layers (consecutive) and how big a texel is.
#[derive(Debug, Clone, PartialEq)]
pub struct LightShadow {
    pub first_layer: usize,
    /// Per layer: scene space → the layer's clip space.
    pub shadow_from_world: Vec<Mat4>,
    /// Texel size at 1 m from a perspective light (spot, point); 0 for directional.
    pub texel_per_metre: f32,
    /// Texel size of an orthographic (directional) map; 0 for the others.
    pub texel: f32,
}

/// Where each light's shadow layers look from, in the light list's order, within
/// [`MAX_SHADOW_LAYERS`]: a light that does not fit casts no shadow. `bounds` are the scene's
/// (scene space); `centre` is the CAVE's centre in scene space, around which directional
/// shadows cover `settings.distance_m` (snapped to a quarter of it, so that moving a little
/// keeps the same maps).
pub fn plan_shadows(
    lights: &[Light],
    bounds: Option<(Vec3, Vec3)>,
    centre: Vec3,
    settings: &ShadowSettings,
) -> Vec<Option<LightShadow>> {
    let Some((lo, hi)) = bounds.filter(|_| settings.enabled) else {
        return vec![None; lights.len()];
    };
    let size = settings.map_size.max(1) as f32;
    let scene_centre = 0.5 * (lo + hi);
    let scene_radius = (0.5 * (hi - lo).length()).max(1e-3);
    // Farthest any part of the scene is from `p`: the far plane that holds every caster.
    let reach = |p: Vec3| (p - scene_centre).length() + scene_radius;
    let mut next = 0;
    lights
        .iter()
        .map(|light| {
            if !light.casts_shadows {
                return None;
            }
            let layers = match light.kind {
                LightKind::Point => 6,
                _ => 1,
            };
            if next + layers > MAX_SHADOW_LAYERS {
                return None;
            }
            let first_layer = next;
            next += layers;
            Some(match light.kind {
                LightKind::Directional => {
                    let (c, r) = if scene_radius <= settings.distance_m {
                        (scene_centre, scene_radius)
                    } else {
                        let step = settings.distance_m / 4.0;
                        ((centre / step).round() * step, settings.distance_m)
                    };
                    let dir = light.direction.normalize_or(Vec3::NEG_Y);
                    let back = reach(c);
                    let eye = c - dir * back;
                    let view = view::look_at_mat4(eye, c, any_perpendicular(dir));
                    let projection = proj::directx::orthographic(-r, r, -r, r, 0.0, back + r);
                    LightShadow {
                        first_layer,
                        shadow_from_world: vec![projection * view],
                        texel_per_metre: 0.0,
                        texel: 2.0 * r / size,
                    }
                }
                LightKind::Spot { outer_cone, .. } => {
                    let fov = (2.0 * outer_cone + 2f32.to_radians())
                        .clamp(2f32.to_radians(), 170f32.to_radians());
                    let far = light
                        .range
                        .unwrap_or_else(|| reach(light.position))
                        .max(0.2);
                    let dir = light.direction.normalize_or(Vec3::NEG_Y);
                    let view = view::look_at_mat4(
                        light.position,
                        light.position + dir,
                        any_perpendicular(dir),
                    );
                    LightShadow {
                        first_layer,
                        shadow_from_world: vec![
                            proj::directx::perspective(fov, 1.0, near(far), far) * view,
                        ],
                        texel_per_metre: 2.0 * (0.5 * fov).tan() / size,
                        texel: 0.0,
                    }
                }
                LightKind::Point => {
                    let far = light
                        .range
                        .unwrap_or_else(|| reach(light.position))
                        .max(0.2);
                    let projection = proj::directx::perspective(
                        // A hair over 90° so that neighbouring faces overlap at the edges.
                        91f32.to_radians(),
                        1.0,
                        near(far),
                        far,
                    );
                    let faces = [
                        (Vec3::X, Vec3::NEG_Y),
                        (Vec3::NEG_X, Vec3::NEG_Y),
                        (Vec3::Y, Vec3::Z),
                        (Vec3::NEG_Y, Vec3::NEG_Z),
                        (Vec3::Z, Vec3::NEG_Y),
                        (Vec3::NEG_Z, Vec3::NEG_Y),
                    ];
                    LightShadow {
                        first_layer,
                        shadow_from_world: faces
                            .iter()
                            .map(|&(d, up)| {
                                projection
                                    * view::look_at_mat4(light.position, light.position + d, up)
                            })
                            .collect(),
                        texel_per_metre: 2.0 * 45.5f32.to_radians().tan() / size,
                        texel: 0.0,
                    }
                }
            })
        })
        .collect()
}

/// A near plane for a perspective shadow map reaching `far` (depth precision).
fn near(far: f32) -> f32 {
    (far * 1e-4).clamp(0.01, 0.1)
}

/// A unit vector not parallel to `v` (an up vector for looking along it).
fn any_perpendicular(v: Vec3) -> Vec3 {
    if v.y.abs() > 0.9 { Vec3::Z } else { Vec3::Y }
}
