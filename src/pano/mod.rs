//! The panorama view (wide field of view up to 360°): cartographic projections of the
//! directions around the viewer onto one image, without GPU types (the render layer's
//! panorama passes use these as their CPU twin).

pub mod projection;
pub mod raycast;

use glam::{Mat4, Vec3};

pub use projection::{PanoProjection, Projection, direction, lon_lat};

/// An angle in degrees as the same direction within [−180, 180].
pub fn wrap_degrees(a: f32) -> f32 {
    if !a.is_finite() {
        return 0.0;
    }
    a - 360.0 * (a / 360.0).round()
}

/// How the panorama is drawn.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum PanoRoute {
    /// Every vertex projected with the map itself (VR'14): sharp, curved edges bounded by the
    /// tessellation; triangles across the rear meridian or around a pole go through the
    /// pre-clip. Equirectangular and Hammer only.
    Geometric,
    /// The scene into a cube map, then every pixel looked up through the inverse map (3DUI):
    /// any projection, blurred by the cube map's sampling, mono.
    Image,
}

crate::named_enum!(PanoRoute {
    Self::Geometric => "geometric",
    Self::Image => "image",
});

/// VR'14's volume stereo parameters: inter-ocular distance, viewing distance and zero-parallax
/// depth, in normalised device units.
pub const VOLUME_DEFAULT_PARAMS: [f32; 3] = [0.5, 5.0, -0.8];

/// How the two eyes of a panorama differ (geometric route; the image route is mono).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum PanoStereo {
    Mono,
    /// VR'14's stereo of the projected volume: two perspective views of the unit cube, with
    /// inter-ocular distance `ioid`, viewing distance `d` and zero-parallax depth `offset`,
    /// all in normalised device units (their defaults: 0.5, 5, −0.8).
    Volume {
        ioid: f32,
        d: f32,
        offset: f32,
    },
    /// Omnidirectional stereo: every vertex seen from its own eye, half the IPD sideways of
    /// the head, perpendicular to the vertex's direction (with the CAVE's pole merge).
    Omni,
}

impl PanoStereo {
    pub const VOLUME_DEFAULT: PanoStereo = PanoStereo::Volume {
        ioid: VOLUME_DEFAULT_PARAMS[0],
        d: VOLUME_DEFAULT_PARAMS[1],
        offset: VOLUME_DEFAULT_PARAMS[2],
    };

    pub fn kind(self) -> PanoStereoKind {
        match self {
            Self::Mono => PanoStereoKind::Mono,
            Self::Volume { .. } => PanoStereoKind::Volume,
            Self::Omni => PanoStereoKind::Omni,
        }
    }

    pub fn name(self) -> &'static str {
        self.kind().name()
    }

    /// The stereo of a kind; volume stereo takes its parameters `[ioid, d, offset]`.
    pub fn of_kind(kind: PanoStereoKind, [ioid, d, offset]: [f32; 3]) -> Self {
        match kind {
            PanoStereoKind::Mono => Self::Mono,
            PanoStereoKind::Volume => Self::Volume { ioid, d, offset },
            PanoStereoKind::Omni => Self::Omni,
        }
    }

    pub fn is_stereo(self) -> bool {
        !matches!(self, Self::Mono)
    }
}

/// The kind of panorama stereo, as the config, the CLI and the panel name it (volume stereo's
/// parameters are set apart).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PanoStereoKind {
    Mono,
    Volume,
    Omni,
}

crate::named_enum!(PanoStereoKind {
    Self::Mono => "mono",
    Self::Volume => "volume",
    Self::Omni => "omni",
});

/// Everything that defines a panorama image, apart from the scene and the head.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PanoSettings {
    pub projection: Projection,
    /// Field of view in radians (clamped to what the projection shows).
    pub h_fov: f32,
    pub v_fov: f32,
    pub route: PanoRoute,
    pub stereo: PanoStereo,
    /// Turn of the view about the vertical, radians, positive to the right, from the
    /// navigation direction (CAVE −z).
    pub yaw: f32,
    /// Image size in pixels.
    pub size: [u32; 2],
    /// Cube map face size of the image route, pixels.
    pub cube_size: u32,
}

impl Default for PanoSettings {
    fn default() -> Self {
        Self {
            projection: Projection::Equirectangular,
            h_fov: std::f32::consts::TAU,
            v_fov: std::f32::consts::PI,
            route: PanoRoute::Geometric,
            stereo: PanoStereo::Mono,
            yaw: 0.0,
            size: [1024, 512],
            cube_size: 512,
        }
    }
}

impl PanoSettings {
    /// The projection fitted to the field of view.
    pub fn fitted(&self) -> PanoProjection {
        PanoProjection::new(self.projection, self.h_fov, self.v_fov)
    }

    /// The route actually used: the geometric one only draws the projections it supports.
    pub fn effective_route(&self) -> PanoRoute {
        if self.projection.geometric() {
            self.route
        } else {
            PanoRoute::Image
        }
    }

    /// View space (centred on `head`, −z the navigation direction turned by `yaw`) from CAVE
    /// space.
    pub fn view_from_cave(&self, head: Vec3) -> Mat4 {
        Mat4::from_rotation_y(self.yaw) * Mat4::from_translation(-head)
    }
}
