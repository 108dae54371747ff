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
    /// Whether the directional and the point light cast shadows.
    pub sun_shadows: bool,
    pub point_shadows: bool,
}

/// How surfaces are shaded: the glTF metallic-roughness model, or the simple Blinn-Phong model
/// omnicave used before it (cheaper; base colour and emission only).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub enum Shading {
    #[default]
    Pbr,
    Simple,
}

crate::named_enum!(Shading {
    Self::Pbr => "pbr",
    Self::Simple => "simple",
});
