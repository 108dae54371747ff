//! The settings model turned into the domain's types: the head, the omnistereo, tessellation,
//! sky and panorama settings, the CAVE's placement in the scene and the lights. Validation,
//! the application and the render command all build them here, so each is built once.

use crate::scene::shadows::ShadowSettings;
use glam::{Mat4, Quat, Vec3};

use super::file::{ConfigFile, LightingSection};
use crate::cave::Head;
use crate::cave::omni::{OmniSettings, PoleMerge};
use crate::pano::{PanoSettings, PanoStereo};
use crate::scene::{Lighting, SceneBudget};
use crate::sky::SkySettings;
use crate::tess::{MAX_DEPTH_LIMIT, TessSettings};
use crate::tracking::OneEuroParams;

impl ConfigFile {
    /// The head's pose (`[head]`: position and yaw, pitch, roll).
    pub fn head(&self) -> Head {
        let h = &self.head;
        Head {
            position: Vec3::from(h.position),
            orientation: Head::orientation_from_degrees(
                h.yaw_degrees,
                h.pitch_degrees,
                h.roll_degrees,
            ),
        }
    }

    /// The omnistereo warp and pole merge (`[omnistereo]`; the merge's end is kept at or
    /// after its start).
    pub fn omni(&self) -> OmniSettings {
        let o = &self.omnistereo;
        let start = o.pole_merge_start_degrees.clamp(0.0, 90.0);
        OmniSettings {
            warp: o.warp,
            pole_merge: o.pole_merge.then_some(PoleMerge {
                start_degrees: start,
                end_degrees: o.pole_merge_end_degrees.clamp(start, 90.0),
            }),
        }
    }

    /// Adaptive tessellation (`[tessellation]`).
    pub fn tess(&self) -> TessSettings {
        let t = &self.tessellation;
        TessSettings {
            criterion: t.criterion,
            max_depth: t.max_depth.min(MAX_DEPTH_LIMIT),
            backface_cull: t.backface_cull,
            frustum_cull: t.frustum_cull,
            skip_fine: t.skip_fine,
            shared_eyes: t.shared_eyes,
        }
    }

    /// The sky's mode and parameters (`[skybox]`).
    pub fn sky(&self) -> SkySettings {
        let k = &self.skybox;
        SkySettings {
            mode: k.mode,
            pixels_per_slice: k.pixels_per_slice,
            exposure: k.exposure,
            light: k.light,
        }
    }

    /// The animation clock's playback as `[animation]` sets it (its time: `time_s`).
    pub fn playback(&self) -> crate::scene::rig::Playback<'_> {
        let a = &self.animation;
        crate::scene::rig::Playback {
            enabled: a.enabled,
            clip: &a.clip,
            seconds: f64::from(a.time_s),
            repeat: a.repeat,
        }
    }

    /// The panorama view (`[panorama]`, angles in radians).
    pub fn pano(&self) -> PanoSettings {
        let p = &self.panorama;
        PanoSettings {
            projection: p.projection,
            h_fov: p.h_fov_degrees.to_radians(),
            v_fov: p.v_fov_degrees.to_radians(),
            route: p.route,
            stereo: PanoStereo::of_kind(p.stereo, p.volume_ioid_d_offset),
            yaw: p.yaw_degrees.to_radians(),
            size: p.size,
            cube_size: p.cube_size,
        }
    }

    /// Where the CAVE stands in the scene (`[scene.world_from_cave]`).
    pub fn world_from_cave(&self) -> Mat4 {
        let p = &self.scene.world_from_cave;
        Mat4::from_scale_rotation_translation(
            Vec3::splat(p.scale),
            Quat::from_rotation_y(p.yaw_degrees.to_radians()),
            Vec3::from(p.translation),
        )
    }

    /// The lights (`[lighting]`, scene space).
    pub fn lighting(&self) -> Lighting {
        self.lighting.to_lighting()
    }

    /// The shadow maps' settings.
    pub fn shadows(&self) -> ShadowSettings {
        let s = &self.shadows;
        ShadowSettings {
            enabled: s.enabled,
            map_size: s.map_size,
            normal_offset_texels: s.normal_offset_texels,
            pcf: s.pcf,
            pcf_range_test: s.pcf_range_test,
            distance_m: s.distance_m,
        }
    }

    /// The scene budget `[budgets]` sets.
    pub fn scene_budget(&self) -> SceneBudget {
        let b = &self.budgets;
        SceneBudget {
            max_file_bytes: u64::from(b.max_file_mb) << 20,
            max_instances: u64::from(b.max_instances),
            max_vertices: u64::from(b.max_vertices),
            max_triangles: u64::from(b.max_triangles),
            max_texture_side: b.max_texture_side,
            max_texture_bytes: u64::from(b.max_texture_memory_mb) << 20,
            max_joints: b.max_joints,
            max_morph_targets: b.max_morph_targets,
            max_animation_channels: b.max_animation_channels,
            max_keyframes: b.max_keyframes,
            max_pose_bytes: u64::from(b.max_pose_memory_mb) << 20,
        }
    }

    /// The tracker's One Euro filter (`None`: off).
    pub fn tracking_filter(&self) -> Option<OneEuroParams> {
        let f = &self.tracking.filter;
        f.enabled.then_some(OneEuroParams {
            min_cutoff_hz: f.min_cutoff_hz,
            beta: f.beta,
            derivative_cutoff_hz: f.derivative_cutoff_hz,
        })
    }
}

impl LightingSection {
    fn to_lighting(&self) -> Lighting {
        Lighting {
            ambient: Vec3::from(self.ambient),
            sun_direction: Vec3::from(self.directional.direction).normalize_or(Vec3::NEG_Y),
            sun_color: Vec3::from(self.directional.color) * self.directional.intensity,
            point_position: Vec3::from(self.point.position),
            point_color: Vec3::from(self.point.color) * self.point.intensity,
            point_range: self.point.range,
            sun_shadows: self.directional.cast_shadows,
            point_shadows: self.point.cast_shadows,
        }
    }
}

impl Default for Lighting {
    /// The config's default lights.
    fn default() -> Self {
        LightingSection::default().to_lighting()
    }
}
