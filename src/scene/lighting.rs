//! The scene's lights as the renderer takes them (scene/world space); the config builds them.

use glam::Vec3;

/// Lighting ready for the renderer (scene/world space). Its `Default` is the config's default
/// `[lighting]` section.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Lighting {
    pub ambient: Vec3,
    pub sun_direction: Vec3,
    pub sun_color: Vec3,
    pub point_position: Vec3,
    pub point_color: Vec3,
    pub point_range: f32,
}
