//! What the bundled sky (`assets/sky.png`, made by `gen-assets`) shows where: calibration
//! beacons at known directions and a black ring at a known elevation, among clouds, distant
//! mountains and a gradient. The beacons sit on plain sky or ground (clouds start above 31°,
//! mountains stay below 7°), so their anti-aliased rims blend with one colour all round. Tests find these features in rendered walls and compare them with
//! the eye model.
//!
//! Directions are given as azimuth (degrees, 0 = front (−z), positive towards the right wall
//! (+x)) and elevation (degrees above the horizon).

use glam::Vec3;

/// A round beacon (a spherical cap) of one flat colour.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Beacon {
    pub name: &'static str,
    pub azimuth_degrees: f32,
    pub elevation_degrees: f32,
    /// Angular radius of the cap.
    pub radius_degrees: f32,
    /// sRGB colour.
    pub rgb: [u8; 3],
}

impl Beacon {
    pub fn direction(&self) -> Vec3 {
        direction(self.azimuth_degrees, self.elevation_degrees)
    }
}

/// Unit direction of an azimuth and elevation (degrees).
pub fn direction(azimuth_degrees: f32, elevation_degrees: f32) -> Vec3 {
    let (az, el) = (azimuth_degrees.to_radians(), elevation_degrees.to_radians());
    Vec3::new(el.cos() * az.sin(), el.sin(), -el.cos() * az.cos())
}

/// The beacons. Five face the three walls of the default CAVE from its centre (two straddle the
/// front corners, where the walls meet); one is behind the viewer.
pub const BEACONS: [Beacon; 6] = [
    Beacon {
        name: "red",
        azimuth_degrees: 0.0,
        elevation_degrees: 15.0,
        radius_degrees: 1.5,
        rgb: [220, 20, 20],
    },
    Beacon {
        name: "yellow",
        azimuth_degrees: -45.0,
        elevation_degrees: 20.0,
        radius_degrees: 1.5,
        rgb: [240, 220, 0],
    },
    Beacon {
        name: "green",
        azimuth_degrees: 45.0,
        elevation_degrees: 24.0,
        radius_degrees: 1.5,
        rgb: [20, 190, 20],
    },
    Beacon {
        name: "magenta",
        azimuth_degrees: -80.0,
        elevation_degrees: 28.0,
        radius_degrees: 1.5,
        rgb: [220, 0, 220],
    },
    Beacon {
        name: "orange",
        azimuth_degrees: 100.0,
        elevation_degrees: -8.0,
        radius_degrees: 1.5,
        rgb: [250, 120, 0],
    },
    Beacon {
        name: "purple",
        azimuth_degrees: 180.0,
        elevation_degrees: 15.0,
        radius_degrees: 1.5,
        rgb: [110, 20, 220],
    },
];

/// The black calibration ring: all azimuths between these elevations (degrees), with ticks
/// every [`RING_TICK_DEGREES`] of azimuth rising to [`RING_TICK_TOP_DEGREES`].
pub const RING_ELEVATION_DEGREES: (f32, f32) = (9.0, 10.0);
pub const RING_TICK_DEGREES: f32 = 15.0;
pub const RING_TICK_TOP_DEGREES: f32 = 12.0;
/// Half the angular width of a tick.
pub const RING_TICK_HALF_WIDTH_DEGREES: f32 = 0.25;
/// sRGB colour of the ring and ticks.
pub const RING_RGB: [u8; 3] = [0, 0, 0];

/// Where the bundled sky is, relative to the repository root.
pub const PATH: &str = "assets/sky.png";
