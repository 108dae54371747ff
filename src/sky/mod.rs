//! Skyboxes without the GPU: sky modes and settings, cube maps from files, and the eye model
//! every sky mode follows (the CPU twin of shaders/sky.wgsl).

pub mod bundled;
pub mod cubemap;
pub mod irradiance;
pub mod lookup;

pub use cubemap::{CubeMap, SkyError, load_sky, load_sky_within};

use crate::cave::RenderMode;

/// How the sky behind the scene is computed for each wall and eye.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub enum SkyMode {
    /// `offaxis` in the mono and off-axis stereo modes, `omni-exact` in the omnistereo ones,
    /// so that sky and scene always follow the same eye model.
    #[default]
    Auto,
    /// A full-screen lookup from the view's eye (fixed-direction eyes in the omnistereo modes):
    /// the ordinary skybox, with stereo only for directions near the assumed view direction.
    Offaxis,
    /// The thesis's omnistereo skybox (6.3): a pre-tessellated full-screen mesh per wall, eyes
    /// per vertex, the lookup vector interpolated.
    OmniQuad,
    /// The omnistereo lookup computed per pixel in the fragment shader: no mesh, no
    /// interpolation error.
    OmniExact,
    /// No sky drawn (the cube map stays loaded, so switching back costs nothing).
    Off,
}

crate::named_enum!(SkyMode {
    Self::Auto => "auto",
    Self::Offaxis => "offaxis",
    Self::OmniQuad => "omni-quad",
    Self::OmniExact => "omni-exact",
    Self::Off => "off",
});

impl SkyMode {
    /// The concrete mode used with `render_mode` (never `Auto`).
    pub fn resolve(self, render_mode: RenderMode) -> Self {
        match self {
            Self::Auto if render_mode.is_omni() => Self::OmniExact,
            Self::Auto => Self::Offaxis,
            other => other,
        }
    }
}

/// The per-frame sky settings (the cube map itself is renderer state).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SkySettings {
    pub mode: SkyMode,
    /// Omni-quad mesh density: one slice per this many pixels (thesis: about 30; default 8).
    pub pixels_per_slice: f32,
    /// Multiplier on the sky's linear colour (for HDR skies).
    pub exposure: f32,
    /// How much the sky lights the scene (image-based ambient light; 0: none).
    pub light: f32,
}

/// One slice per 8 pixels (both directions where the eye varies with height): keeps the
/// omni-quad sky within 0.5 px of the exact one for heads down to 0.3 m from a wall with pole
/// merging on (measured by `tests/sky.rs`). The thesis's one slice per 30 px holds there only
/// without pole merging, whose IPD fade makes the eye change quickly near the top of a wall the
/// viewer stands close to.
pub const DEFAULT_PIXELS_PER_SLICE: f32 = 8.0;

impl Default for SkySettings {
    fn default() -> Self {
        Self {
            mode: SkyMode::Auto,
            pixels_per_slice: DEFAULT_PIXELS_PER_SLICE,
            exposure: 1.0,
            light: 1.0,
        }
    }
}
