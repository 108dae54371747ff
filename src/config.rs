//! The TOML configuration: CAVE walls, head, eyes, scene placement, lighting and render defaults.
//!
//! Parsing is strict (unknown keys are refused) and every semantic check names the file, the
//! field and the offending value, so a lab engineer can fix a config without reading code.

use std::path::{Path, PathBuf};

use glam::{Mat4, Quat, Vec3};
use serde::{Deserialize, Serialize};

use std::collections::BTreeMap;
use std::net::{IpAddr, SocketAddr};
use std::time::Duration;

use crate::cave::omni::{OmniSettings, PoleMerge, WarpVariant};
use crate::cave::{Cave, Head, RenderMode, Wall, left_of};
use crate::gamepad::{GamepadMode, GamepadSettings, button_map};
use crate::output::formats::StereoFormat;
use crate::pano::{PanoRoute, PanoSettings, PanoStereo, Projection};
use crate::sky::{DEFAULT_PIXELS_PER_SLICE, SkyMode, SkySettings};
use crate::tess::{MAX_DEPTH_LIMIT, TessSettings, parse_criterion};
use crate::tracking::{
    Calibration, DEFAULT_OSC_PORT, OneEuroParams, OscMapping, QuaternionOrder, ReceiverSettings,
    TrackingSettings,
};

/// Everything that can be wrong with a config file.
#[derive(Debug, thiserror::Error)]
pub enum ConfigError {
    #[error("cannot read config file {path}: {source}")]
    Read {
        path: PathBuf,
        source: std::io::Error,
    },
    #[error("config file {path} is not valid: {message}")]
    Parse { path: PathBuf, message: String },
    #[error("config file {path}: field `{field}` has invalid value {value}: {reason}")]
    Invalid {
        path: PathBuf,
        field: String,
        value: String,
        reason: String,
    },
}

/// The whole configuration file, as written.
#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct ConfigFile {
    #[serde(default)]
    pub cave: CaveSection,
    #[serde(default)]
    pub head: HeadSection,
    #[serde(default)]
    pub render: RenderSection,
    #[serde(default)]
    pub scene: SceneSection,
    #[serde(default)]
    pub lighting: LightingSection,
    #[serde(default)]
    pub omnistereo: OmnistereoSection,
    #[serde(default)]
    pub tessellation: TessellationSection,
    #[serde(default)]
    pub skybox: SkyboxSection,
    #[serde(default)]
    pub app: AppSection,
    #[serde(default)]
    pub tracking: TrackingSection,
    #[serde(default)]
    pub gamepad: GamepadSection,
    #[serde(default)]
    pub panorama: PanoramaSection,
    #[serde(rename = "wall")]
    pub walls: Vec<WallSection>,
}

#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct CaveSection {
    /// Interpupillary distance in metres.
    #[serde(default = "default_ipd")]
    pub eye_separation: f32,
    #[serde(default = "default_near")]
    pub near: f32,
    #[serde(default = "default_far")]
    pub far: f32,
    /// View direction assumed by fixed-direction stereo; default −z (⟂ the front wall).
    #[serde(default = "default_view_direction")]
    pub stereo_view_direction: [f32; 3],
    /// Projective viewpoint of the on-axis omnistereo warp; default: the room's centre.
    #[serde(default)]
    pub projection_centre: Option<[f32; 3]>,
}

impl Default for CaveSection {
    fn default() -> Self {
        Self {
            eye_separation: default_ipd(),
            near: default_near(),
            far: default_far(),
            stereo_view_direction: default_view_direction(),
            projection_centre: None,
        }
    }
}

/// Omnistereo settings.
#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct OmnistereoSection {
    /// `similar-triangles` (stable) or `intersection-point` (only to show where it breaks).
    #[serde(default = "default_warp")]
    pub warp: String,
    /// Fade the eye separation to zero near the vertical axis through the head.
    #[serde(default = "yes")]
    pub pole_merge: bool,
    #[serde(default = "default_pole_start")]
    pub pole_merge_start_degrees: f32,
    #[serde(default = "default_pole_end")]
    pub pole_merge_end_degrees: f32,
}

impl Default for OmnistereoSection {
    fn default() -> Self {
        Self {
            warp: default_warp(),
            pole_merge: true,
            pole_merge_start_degrees: default_pole_start(),
            pole_merge_end_degrees: default_pole_end(),
        }
    }
}

/// Adaptive tessellation before the omnistereo warp.
#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct TessellationSection {
    /// `none`, `uniform:N`, `edge:PX`, `sphere:PX` or `error:PX`.
    #[serde(default = "default_criterion")]
    pub criterion: String,
    #[serde(default = "default_max_depth")]
    pub max_depth: u32,
    #[serde(default = "yes")]
    pub backface_cull: bool,
    #[serde(default = "yes")]
    pub frustum_cull: bool,
}

impl Default for TessellationSection {
    fn default() -> Self {
        Self {
            criterion: default_criterion(),
            max_depth: default_max_depth(),
            backface_cull: true,
            frustum_cull: true,
        }
    }
}

/// The sky behind the scene.
#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct SkyboxSection {
    /// An equirectangular image (PNG/JPEG/HDR) or a folder of six faces; relative to the
    /// config's folder. Absent or "none": no sky.
    #[serde(default)]
    pub file: Option<PathBuf>,
    /// `auto`, `offaxis`, `omni-quad` or `omni-exact`.
    #[serde(default = "default_sky_mode")]
    pub mode: String,
    /// Omni-quad mesh density: one slice per this many pixels.
    #[serde(default = "default_pixels_per_slice")]
    pub pixels_per_slice: f32,
    /// Multiplier on the sky's linear colour.
    #[serde(default = "one")]
    pub exposure: f32,
}

impl Default for SkyboxSection {
    fn default() -> Self {
        Self {
            file: None,
            mode: default_sky_mode(),
            pixels_per_slice: default_pixels_per_slice(),
            exposure: 1.0,
        }
    }
}

/// OSC head tracking (`omnicave run`).
#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct TrackingSection {
    /// Listen for head positions over OSC from the start (the panel can switch it).
    #[serde(default)]
    pub enabled: bool,
    /// UDP address:port to listen on; 0.0.0.0 is every interface.
    #[serde(default = "default_listen")]
    pub listen: String,
    /// Senders allowed to move the head (IP addresses); empty: any.
    #[serde(default)]
    pub allowed_senders: Vec<String>,
    /// `x y z` (or + quaternion, or + yaw pitch roll); empty string: off.
    #[serde(default = "default_position_address")]
    pub position_address: String,
    /// A quaternion; empty string: off.
    #[serde(default = "default_orientation_address")]
    pub orientation_address: String,
    /// `yaw pitch roll` in degrees; empty string: off.
    #[serde(default = "default_euler_address")]
    pub euler_address: String,
    /// `wxyz` or `xyzw`.
    #[serde(default = "default_quaternion_order")]
    pub quaternion_order: String,
    /// The NatNet-to-OSC form (`/rigidbody <id> position x y z`); empty string: off.
    #[serde(default = "default_natnet_address")]
    pub natnet_address: String,
    #[serde(default = "default_rigid_body")]
    pub natnet_rigid_body: i64,
    /// No packet for this long: "tracking lost", the head holds its last pose.
    #[serde(default = "default_tracking_timeout")]
    pub timeout_seconds: f32,
    #[serde(default)]
    pub calibration: CalibrationSection,
    #[serde(default)]
    pub filter: FilterSection,
}

impl Default for TrackingSection {
    fn default() -> Self {
        Self {
            enabled: false,
            listen: default_listen(),
            allowed_senders: Vec::new(),
            position_address: default_position_address(),
            orientation_address: default_orientation_address(),
            euler_address: default_euler_address(),
            quaternion_order: default_quaternion_order(),
            natnet_address: default_natnet_address(),
            natnet_rigid_body: default_rigid_body(),
            timeout_seconds: default_tracking_timeout(),
            calibration: CalibrationSection::default(),
            filter: FilterSection::default(),
        }
    }
}

fn default_listen() -> String {
    format!("0.0.0.0:{DEFAULT_OSC_PORT}")
}
fn default_position_address() -> String {
    OscMapping::default().position_address
}
fn default_orientation_address() -> String {
    OscMapping::default().orientation_address
}
fn default_euler_address() -> String {
    OscMapping::default().euler_address
}
fn default_quaternion_order() -> String {
    QuaternionOrder::default().name().into()
}
fn default_natnet_address() -> String {
    OscMapping::default().natnet_address
}
fn default_rigid_body() -> i64 {
    OscMapping::default().natnet_rigid_body
}
fn default_tracking_timeout() -> f32 {
    TrackingSettings::default().timeout.as_secs_f32()
}

/// Tracker frame → CAVE space: `cave = offset + rotation · (scale · axes(tracker))`.
#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct CalibrationSection {
    /// The CAVE's x, y, z as signed tracker axes: ["x", "z", "-y"] for a right-handed z-up
    /// tracker, ["x", "y", "-z"] for a left-handed y-up one.
    #[serde(default = "default_axes")]
    pub axes: [String; 3],
    /// Tracker units to metres (0.001 for millimetres).
    #[serde(default = "one")]
    pub scale: f32,
    /// Yaw, pitch, roll in degrees, applied after the axis remap.
    #[serde(default)]
    pub rotation_degrees: [f32; 3],
    /// Where the tracker's origin is in CAVE space, metres.
    #[serde(default)]
    pub offset: [f32; 3],
}

impl Default for CalibrationSection {
    fn default() -> Self {
        Self {
            axes: default_axes(),
            scale: 1.0,
            rotation_degrees: [0.0; 3],
            offset: [0.0; 3],
        }
    }
}

fn default_axes() -> [String; 3] {
    ["x".into(), "y".into(), "z".into()]
}

/// One Euro filter against tracker jitter.
#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct FilterSection {
    #[serde(default = "yes")]
    pub enabled: bool,
    #[serde(default = "default_min_cutoff")]
    pub min_cutoff_hz: f32,
    #[serde(default = "default_beta")]
    pub beta: f32,
    #[serde(default = "default_derivative_cutoff")]
    pub derivative_cutoff_hz: f32,
}

impl Default for FilterSection {
    fn default() -> Self {
        Self {
            enabled: true,
            min_cutoff_hz: default_min_cutoff(),
            beta: default_beta(),
            derivative_cutoff_hz: default_derivative_cutoff(),
        }
    }
}

fn default_min_cutoff() -> f32 {
    OneEuroParams::default().min_cutoff_hz
}
fn default_beta() -> f32 {
    OneEuroParams::default().beta
}
fn default_derivative_cutoff() -> f32 {
    OneEuroParams::default().derivative_cutoff_hz
}

/// The gamepad (gilrs, hot-plug).
#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct GamepadSection {
    #[serde(default = "yes")]
    pub enabled: bool,
    /// `navigate` (move through the scene) or `head` (move the head in the CAVE).
    #[serde(default = "default_gamepad_mode")]
    pub mode: String,
    /// Radial stick dead zone, 0..1.
    #[serde(default = "default_dead_zone")]
    pub dead_zone: f32,
    #[serde(default = "default_trigger_dead_zone")]
    pub trigger_dead_zone: f32,
    /// Head speed at full stick (head mode), metres per second.
    #[serde(default = "default_head_speed")]
    pub head_speed: f32,
    /// Button (Xbox label) → action, over the default map; "none" unbinds a button.
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub buttons: BTreeMap<String, String>,
}

impl Default for GamepadSection {
    fn default() -> Self {
        Self {
            enabled: true,
            mode: default_gamepad_mode(),
            dead_zone: default_dead_zone(),
            trigger_dead_zone: default_trigger_dead_zone(),
            head_speed: default_head_speed(),
            buttons: BTreeMap::new(),
        }
    }
}

fn default_gamepad_mode() -> String {
    GamepadSettings::default().mode.name().into()
}
fn default_dead_zone() -> f32 {
    GamepadSettings::default().dead_zone
}
fn default_trigger_dead_zone() -> f32 {
    GamepadSettings::default().trigger_dead_zone
}
fn default_head_speed() -> f32 {
    GamepadSettings::default().head_speed
}

fn default_sky_mode() -> String {
    SkyMode::default().name().into()
}
fn default_pixels_per_slice() -> f32 {
    DEFAULT_PIXELS_PER_SLICE
}

fn default_criterion() -> String {
    "none".into()
}
fn default_max_depth() -> u32 {
    TessSettings::default().max_depth
}

fn default_warp() -> String {
    WarpVariant::default().name().into()
}
fn yes() -> bool {
    true
}
fn default_pole_start() -> f32 {
    PoleMerge::default().start_degrees
}
fn default_pole_end() -> f32 {
    PoleMerge::default().end_degrees
}

fn default_ipd() -> f32 {
    0.064
}
fn default_near() -> f32 {
    0.05
}
fn default_far() -> f32 {
    2000.0
}
fn default_view_direction() -> [f32; 3] {
    [0.0, 0.0, -1.0]
}

#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct HeadSection {
    #[serde(default = "default_head_position")]
    pub position: [f32; 3],
    #[serde(default)]
    pub yaw_degrees: f32,
    #[serde(default)]
    pub pitch_degrees: f32,
    #[serde(default)]
    pub roll_degrees: f32,
}

impl Default for HeadSection {
    fn default() -> Self {
        Self {
            position: default_head_position(),
            yaw_degrees: 0.0,
            pitch_degrees: 0.0,
            roll_degrees: 0.0,
        }
    }
}

fn default_head_position() -> [f32; 3] {
    [0.0, 1.7, 0.0]
}

#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct RenderSection {
    #[serde(default = "default_mode")]
    pub mode: String,
    /// MSAA sample count: 1 (off) or 4.
    #[serde(default = "default_msaa")]
    pub msaa: u32,
    #[serde(default)]
    pub wireframe: bool,
    /// Clear colour, sRGB components in 0..1.
    #[serde(default = "default_background")]
    pub background: [f32; 3],
}

impl Default for RenderSection {
    fn default() -> Self {
        Self {
            mode: default_mode(),
            msaa: default_msaa(),
            wireframe: false,
            background: default_background(),
        }
    }
}

fn default_mode() -> String {
    "stereo".into()
}
fn default_msaa() -> u32 {
    4
}
fn default_background() -> [f32; 3] {
    [0.02, 0.02, 0.03]
}

#[derive(Debug, Clone, Default, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct SceneSection {
    /// glTF file; relative paths are relative to the config file's folder.
    pub path: Option<PathBuf>,
    #[serde(default)]
    pub world_from_cave: PlacementSection,
}

/// Where the CAVE stands in the scene: scene point = translation + yaw · scale · CAVE point.
#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct PlacementSection {
    #[serde(default)]
    pub translation: [f32; 3],
    #[serde(default)]
    pub yaw_degrees: f32,
    #[serde(default = "one")]
    pub scale: f32,
}

impl Default for PlacementSection {
    fn default() -> Self {
        Self {
            translation: [0.0; 3],
            yaw_degrees: 0.0,
            scale: 1.0,
        }
    }
}

fn one() -> f32 {
    1.0
}

#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct LightingSection {
    /// Ambient light colour (linear).
    #[serde(default = "default_ambient")]
    pub ambient: [f32; 3],
    #[serde(default)]
    pub directional: DirectionalLightSection,
    #[serde(default)]
    pub point: PointLightSection,
}

impl Default for LightingSection {
    fn default() -> Self {
        Self {
            ambient: default_ambient(),
            directional: DirectionalLightSection::default(),
            point: PointLightSection::default(),
        }
    }
}

fn default_ambient() -> [f32; 3] {
    [0.18, 0.18, 0.2]
}

#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct DirectionalLightSection {
    /// Direction the light travels, in scene (world) space.
    #[serde(default = "default_sun_direction")]
    pub direction: [f32; 3],
    #[serde(default = "default_sun_color")]
    pub color: [f32; 3],
    #[serde(default = "default_sun_intensity")]
    pub intensity: f32,
}

impl Default for DirectionalLightSection {
    fn default() -> Self {
        Self {
            direction: default_sun_direction(),
            color: default_sun_color(),
            intensity: default_sun_intensity(),
        }
    }
}

fn default_sun_direction() -> [f32; 3] {
    [-0.4, -1.0, -0.3]
}
fn default_sun_color() -> [f32; 3] {
    [1.0, 0.97, 0.9]
}
fn default_sun_intensity() -> f32 {
    0.6
}

#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct PointLightSection {
    /// Position in scene (world) space.
    #[serde(default = "default_point_position")]
    pub position: [f32; 3],
    #[serde(default = "default_point_color")]
    pub color: [f32; 3],
    #[serde(default = "default_point_intensity")]
    pub intensity: f32,
    /// Distance (metres) at which the light has faded to zero.
    #[serde(default = "default_point_range")]
    pub range: f32,
}

impl Default for PointLightSection {
    fn default() -> Self {
        Self {
            position: default_point_position(),
            color: default_point_color(),
            intensity: default_point_intensity(),
            range: default_point_range(),
        }
    }
}

fn default_point_position() -> [f32; 3] {
    [0.0, 2.4, 0.0]
}
fn default_point_color() -> [f32; 3] {
    [1.0, 0.9, 0.75]
}
fn default_point_intensity() -> f32 {
    0.8
}
fn default_point_range() -> f32 {
    12.0
}

#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct WallSection {
    pub name: String,
    pub lower_left: [f32; 3],
    pub lower_right: [f32; 3],
    pub upper_left: [f32; 3],
    /// Pixels (width, height).
    pub resolution: [u32; 2],
    /// The monitor this wall's window goes fullscreen on (CAVE mode): an index into the
    /// system's monitor list or a monitor name. Missing monitor: `window_position`/`size`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub monitor: Option<MonitorRef>,
    /// Borderless window position (screen pixels) when no monitor is named or found.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub window_position: Option<[i32; 2]>,
    /// Window size (pixels) when no monitor is named or found; default: `resolution`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub window_size: Option<[u32; 2]>,
    /// Stereo output format of this wall's window; default: `app.wall_output`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub output: Option<String>,
}

/// The panorama view (wide field of view up to 360°): the operator's overview of everything
/// around the CAVE user, or a desktop view on its own.
#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct PanoramaSection {
    /// Show the panorama in the application (below the walls in the preview; beside the
    /// panel in CAVE mode's operator window).
    #[serde(default)]
    pub show: bool,
    /// perspective, equirectangular, hammer, albers or azimuthal-equidistant.
    #[serde(default = "default_pano_projection")]
    pub projection: String,
    #[serde(default = "default_pano_h_fov")]
    pub h_fov_degrees: f32,
    #[serde(default = "default_pano_v_fov")]
    pub v_fov_degrees: f32,
    /// "geometric" (per-vertex projection with pre-clip; equirectangular and Hammer) or
    /// "image" (cube map and inverse projection; every projection).
    #[serde(default = "default_pano_route")]
    pub route: String,
    /// "mono", "volume" (VR'14: the projected volume seen by two eyes) or "omni"
    /// (omnidirectional stereo per vertex). Geometric route only.
    #[serde(default = "default_pano_stereo")]
    pub stereo: String,
    /// Volume stereo: inter-ocular distance, viewing distance and zero-parallax depth, in
    /// normalised device units (VR'14's values).
    #[serde(default = "default_pano_volume")]
    pub volume_ioid_d_offset: [f32; 3],
    /// Turn from the navigation direction, degrees, positive to the right.
    #[serde(default)]
    pub yaw_degrees: f32,
    /// Image pixels (width, height).
    #[serde(default = "default_pano_size")]
    pub size: [u32; 2],
    /// Cube face pixels of the image route.
    #[serde(default = "default_pano_cube_size")]
    pub cube_size: u32,
}

impl Default for PanoramaSection {
    fn default() -> Self {
        Self {
            show: false,
            projection: default_pano_projection(),
            h_fov_degrees: default_pano_h_fov(),
            v_fov_degrees: default_pano_v_fov(),
            route: default_pano_route(),
            stereo: default_pano_stereo(),
            volume_ioid_d_offset: default_pano_volume(),
            yaw_degrees: 0.0,
            size: default_pano_size(),
            cube_size: default_pano_cube_size(),
        }
    }
}

fn default_pano_projection() -> String {
    "equirectangular".into()
}
fn default_pano_h_fov() -> f32 {
    360.0
}
fn default_pano_v_fov() -> f32 {
    180.0
}
fn default_pano_route() -> String {
    "geometric".into()
}
fn default_pano_stereo() -> String {
    "mono".into()
}
fn default_pano_volume() -> [f32; 3] {
    [0.5, 5.0, -0.8]
}
fn default_pano_size() -> [u32; 2] {
    [1024, 512]
}
fn default_pano_cube_size() -> u32 {
    512
}

impl PanoramaSection {
    fn validate(&self, ck: &Checker<'_>) -> Result<PanoSettings, ConfigError> {
        let names = |all: &[&str]| all.join(", ");
        let projection = Projection::from_name(self.projection.trim()).ok_or_else(|| {
            let all: Vec<_> = Projection::ALL.iter().map(|p| p.name()).collect();
            ck.fail(
                "panorama.projection",
                &self.projection,
                &format!("must be one of {}", names(&all)),
            )
        })?;
        let route = PanoRoute::from_name(self.route.trim())
            .ok_or_else(|| ck.fail("panorama.route", &self.route, "must be geometric or image"))?;
        let [ioid, d, offset] = self.volume_ioid_d_offset;
        let volume_valid = (0.0..=2.0).contains(&ioid)
            && d.is_finite()
            && d > 1.0
            && (-1.0..=1.0).contains(&offset);
        if !volume_valid {
            return Err(ck.fail(
                "panorama.volume_ioid_d_offset",
                self.volume_ioid_d_offset,
                "needs 0 ≤ ioid ≤ 2, d > 1 (outside the unit cube) and −1 ≤ offset ≤ 1",
            ));
        }
        let stereo = match self.stereo.trim() {
            "volume" => PanoStereo::Volume { ioid, d, offset },
            other => PanoStereo::from_name(other).ok_or_else(|| {
                ck.fail(
                    "panorama.stereo",
                    &self.stereo,
                    "must be mono, volume or omni",
                )
            })?,
        };
        let (max_h, max_v) = projection.max_fov();
        let h = ck.range(
            "panorama.h_fov_degrees",
            self.h_fov_degrees,
            1.0,
            max_h.to_degrees().round(),
        )?;
        let v = ck.range(
            "panorama.v_fov_degrees",
            self.v_fov_degrees,
            1.0,
            max_v.to_degrees().round(),
        )?;
        let yaw = ck.range("panorama.yaw_degrees", self.yaw_degrees, -360.0, 360.0)?;
        let [w, h_px] = self.size;
        if !(1..=8192).contains(&w) || !(1..=8192).contains(&h_px) {
            return Err(ck.fail("panorama.size", self.size, "must be 1 to 8192 pixels each"));
        }
        if !(4..=8192).contains(&self.cube_size) {
            return Err(ck.fail(
                "panorama.cube_size",
                self.cube_size,
                "must be 4 to 8192 pixels",
            ));
        }
        if route == PanoRoute::Geometric && !projection.geometric() {
            tracing::warn!(
                "{}: panorama.route = \"geometric\" draws equirectangular and hammer only; \
                 {} is drawn by the image route",
                ck.path.display(),
                projection.name()
            );
        }
        if stereo.is_stereo() && (route == PanoRoute::Image || !projection.geometric()) {
            tracing::warn!(
                "{}: panorama.stereo = \"{}\" needs the geometric route; the image route is mono",
                ck.path.display(),
                stereo.name()
            );
        }
        Ok(PanoSettings {
            projection,
            h_fov: h.to_radians(),
            v_fov: v.to_radians(),
            route,
            stereo,
            yaw: yaw.to_radians(),
            size: self.size,
            cube_size: self.cube_size,
        })
    }
}

/// A monitor named in the config: by position in the system's list or by name.
#[derive(Debug, Clone, PartialEq, Eq, Deserialize, Serialize)]
#[serde(untagged)]
pub enum MonitorRef {
    Index(usize),
    Name(String),
}

/// The interactive application (`omnicave run`): windows, panel, output formats.
#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct AppSection {
    /// "cave" (a window per wall) or "preview" (one window, walls unfolded).
    #[serde(default = "default_app_mode")]
    pub mode: String,
    /// Where the control panel goes in CAVE mode: "window" (its own operator window),
    /// "overlay:<wall>" (drawn over that wall's window) or "hidden".
    #[serde(default = "default_panel")]
    pub panel: String,
    /// Operator (or preview) window position, screen pixels; default: chosen by the system.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub window_position: Option<[i32; 2]>,
    /// Operator (or preview) window size in pixels.
    #[serde(default = "default_app_window_size")]
    pub window_size: [u32; 2],
    /// Default stereo output format of the wall windows.
    #[serde(default = "default_wall_output")]
    pub wall_output: String,
    /// Stereo output format of the preview's unfolded walls.
    #[serde(default = "default_preview_output")]
    pub preview_output: String,
    /// Wait for vertical blank (no tearing; caps the frame rate at the display's).
    #[serde(default = "default_true")]
    pub vsync: bool,
    /// Navigation speed in the scene, metres per second (keyboard and gamepad).
    #[serde(default = "default_nav_speed")]
    pub navigation_speed: f32,
}

impl Default for AppSection {
    fn default() -> Self {
        Self {
            mode: default_app_mode(),
            panel: default_panel(),
            window_position: None,
            window_size: default_app_window_size(),
            wall_output: default_wall_output(),
            preview_output: default_preview_output(),
            vsync: true,
            navigation_speed: default_nav_speed(),
        }
    }
}

fn default_app_mode() -> String {
    "preview".into()
}
fn default_panel() -> String {
    "window".into()
}
fn default_app_window_size() -> [u32; 2] {
    [1280, 720]
}
fn default_wall_output() -> String {
    "frame-sequential".into()
}
fn default_preview_output() -> String {
    "anaglyph".into()
}
fn default_true() -> bool {
    true
}
fn default_nav_speed() -> f32 {
    1.5
}

/// How the application shows the walls.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum AppMode {
    /// One borderless window per wall, on the monitors the config names.
    Cave,
    /// One window with the walls unfolded side by side and the panel docked.
    Preview,
}

/// Where the control panel is drawn in CAVE mode.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum PanelPlacement {
    Window,
    /// Over the wall with this index.
    Overlay(usize),
    Hidden,
}

/// Where one wall's window goes.
#[derive(Debug, Clone, PartialEq)]
pub struct WallWindow {
    pub monitor: Option<MonitorRef>,
    pub position: Option<[i32; 2]>,
    pub size: [u32; 2],
    pub output: StereoFormat,
}

/// The validated `[app]` section and per-wall window settings.
#[derive(Debug, Clone, PartialEq)]
pub struct AppConfig {
    pub mode: AppMode,
    pub panel: PanelPlacement,
    pub window_position: Option<[i32; 2]>,
    pub window_size: [u32; 2],
    pub preview_output: StereoFormat,
    pub vsync: bool,
    pub navigation_speed: f32,
    /// One per wall, in wall order.
    pub walls: Vec<WallWindow>,
}

/// The validated `[tracking]` section.
#[derive(Debug, Clone, PartialEq)]
pub struct TrackingConfig {
    /// Start listening at launch.
    pub enabled: bool,
    pub receiver: ReceiverSettings,
    pub settings: TrackingSettings,
}

/// Lighting ready for the renderer (scene/world space).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Lighting {
    pub ambient: Vec3,
    pub sun_direction: Vec3,
    pub sun_color: Vec3,
    pub point_position: Vec3,
    pub point_color: Vec3,
    pub point_range: f32,
}

impl Default for Lighting {
    fn default() -> Self {
        LightingSection::default().to_lighting()
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
        }
    }
}

/// A validated configuration, ready to use.
#[derive(Debug, Clone)]
pub struct Config {
    /// The file it came from (for messages and relative paths).
    pub source: PathBuf,
    pub cave: Cave,
    pub head: Head,
    pub eye_separation: f32,
    pub mode: RenderMode,
    pub msaa: u32,
    pub wireframe: bool,
    /// Clear colour, sRGB.
    pub background: [f32; 3],
    /// Scene file, already resolved against the config's folder.
    pub scene_path: Option<PathBuf>,
    pub world_from_cave: Mat4,
    pub lighting: Lighting,
    pub omni: OmniSettings,
    pub tess: TessSettings,
    /// Sky file, already resolved against the config's folder (`None`: no sky).
    pub sky_path: Option<PathBuf>,
    pub sky: SkySettings,
    /// Windows, panel and output formats of the interactive application.
    pub app: AppConfig,
    /// OSC head tracking.
    pub tracking: TrackingConfig,
    pub gamepad: GamepadSettings,
    /// The panorama view.
    pub panorama: PanoSettings,
    /// The file as written (to save changed settings back without losing the rest).
    pub file: ConfigFile,
}

impl Config {
    /// Reads and validates a config file.
    pub fn load(path: &Path) -> Result<Self, ConfigError> {
        let text = std::fs::read_to_string(path).map_err(|source| ConfigError::Read {
            path: path.to_owned(),
            source,
        })?;
        Self::from_toml(&text, path)
    }

    /// Parses and validates config text; `path` is used for messages and relative paths.
    pub fn from_toml(text: &str, path: &Path) -> Result<Self, ConfigError> {
        let file: ConfigFile = toml::from_str(text).map_err(|e| ConfigError::Parse {
            path: path.to_owned(),
            message: e.to_string().trim_end().to_owned(),
        })?;
        file.validate(path)
    }
}

struct Checker<'a> {
    path: &'a Path,
}

impl Checker<'_> {
    fn fail(&self, field: &str, value: impl std::fmt::Debug, reason: &str) -> ConfigError {
        ConfigError::Invalid {
            path: self.path.to_owned(),
            field: field.to_owned(),
            value: format!("{value:?}"),
            reason: reason.to_owned(),
        }
    }

    fn finite3(&self, field: &str, v: [f32; 3]) -> Result<Vec3, ConfigError> {
        if v.iter().all(|c| c.is_finite()) {
            Ok(Vec3::from(v))
        } else {
            Err(self.fail(field, v, "every component must be a finite number"))
        }
    }

    fn range(&self, field: &str, v: f32, lo: f32, hi: f32) -> Result<f32, ConfigError> {
        if v.is_finite() && v >= lo && v <= hi {
            Ok(v)
        } else {
            Err(self.fail(field, v, &format!("must be between {lo} and {hi}")))
        }
    }

    fn colour(&self, field: &str, v: [f32; 3], max: f32) -> Result<Vec3, ConfigError> {
        let c = self.finite3(field, v)?;
        if c.min_element() < 0.0 || c.max_element() > max {
            return Err(self.fail(field, v, &format!("components must be in 0..{max}")));
        }
        Ok(c)
    }
}

/// Largest accepted wall image side; beyond any projector and wgpu's default texture limit.
const MAX_WALL_PIXELS: u32 = 8192;

impl ConfigFile {
    /// Checks every field and builds the ready-to-use config.
    pub fn validate(&self, path: &Path) -> Result<Config, ConfigError> {
        let ck = Checker { path };

        if self.walls.is_empty() {
            return Err(ck.fail("wall", "[]", "at least one [[wall]] is required"));
        }
        let mut walls = Vec::with_capacity(self.walls.len());
        for (i, w) in self.walls.iter().enumerate() {
            walls.push(validate_wall(&ck, i, w, &walls)?);
        }

        let c = &self.cave;
        let eye_separation = ck.range("cave.eye_separation", c.eye_separation, 0.0, 0.5)?;
        let near = ck.range("cave.near", c.near, 1e-4, 10.0)?;
        let far = c.far;
        if !(far.is_finite() && far > near * 10.0 && far <= 1e7) {
            return Err(ck.fail(
                "cave.far",
                far,
                "must be finite, at most 1e7 and at least ten times cave.near",
            ));
        }
        let view_dir = ck.finite3("cave.stereo_view_direction", c.stereo_view_direction)?;
        if left_of(view_dir).is_none() {
            return Err(ck.fail(
                "cave.stereo_view_direction",
                c.stereo_view_direction,
                "must have a horizontal component (it sets which way the stereo eyes are split)",
            ));
        }

        let projection_centre = match c.projection_centre {
            Some(p) => ck.finite3("cave.projection_centre", p)?,
            None => Cave::default_projection_centre(&walls),
        };
        // The on-axis warp projects every wall from this point: it must see each wall's front.
        for (i, w) in walls.iter().enumerate() {
            if w.signed_distance(projection_centre) < 0.01 {
                return Err(ck.fail(
                    "cave.projection_centre",
                    projection_centre.to_array(),
                    &format!(
                        "must lie at least 1 cm in front of every wall; wall[{i}] ({}) is not",
                        w.name
                    ),
                ));
            }
        }

        let o = &self.omnistereo;
        let warp = WarpVariant::from_name(&o.warp).ok_or_else(|| {
            let names: Vec<_> = WarpVariant::ALL.iter().map(|w| w.name()).collect();
            ck.fail(
                "omnistereo.warp",
                &o.warp,
                &format!("must be one of {}", names.join(", ")),
            )
        })?;
        let start = ck.range(
            "omnistereo.pole_merge_start_degrees",
            o.pole_merge_start_degrees,
            0.0,
            90.0,
        )?;
        let end = ck.range(
            "omnistereo.pole_merge_end_degrees",
            o.pole_merge_end_degrees,
            start,
            90.0,
        )?;
        let omni = OmniSettings {
            warp,
            pole_merge: o.pole_merge.then_some(PoleMerge {
                start_degrees: start,
                end_degrees: end,
            }),
        };

        let t = &self.tessellation;
        let criterion = parse_criterion(&t.criterion)
            .map_err(|reason| ck.fail("tessellation.criterion", &t.criterion, &reason))?;
        if t.max_depth > MAX_DEPTH_LIMIT {
            return Err(ck.fail(
                "tessellation.max_depth",
                t.max_depth,
                &format!("must be at most {MAX_DEPTH_LIMIT}"),
            ));
        }
        let tess = TessSettings {
            criterion,
            max_depth: t.max_depth,
            backface_cull: t.backface_cull,
            frustum_cull: t.frustum_cull,
        };

        let h = &self.head;
        let head_pos = ck.finite3("head.position", h.position)?;
        let cave_for_check = Cave {
            walls: walls.clone(),
            near,
            far,
            stereo_view_direction: view_dir,
            projection_centre,
        };
        if let Some(problem) = cave_for_check.head_problem(head_pos) {
            return Err(ck.fail("head.position", h.position, &problem));
        }
        for (field, v) in [
            ("head.yaw_degrees", h.yaw_degrees),
            ("head.pitch_degrees", h.pitch_degrees),
            ("head.roll_degrees", h.roll_degrees),
        ] {
            ck.range(field, v, -360.0, 360.0)?;
        }

        let r = &self.render;
        let mode = RenderMode::from_name(&r.mode).ok_or_else(|| {
            let names: Vec<_> = RenderMode::ALL.iter().map(|m| m.name()).collect();
            ck.fail(
                "render.mode",
                &r.mode,
                &format!("must be one of {}", names.join(", ")),
            )
        })?;
        if !matches!(r.msaa, 1 | 4) {
            return Err(ck.fail("render.msaa", r.msaa, "must be 1 (off) or 4"));
        }
        let background = ck.colour("render.background", r.background, 1.0)?;

        let p = &self.scene.world_from_cave;
        let translation = ck.finite3("scene.world_from_cave.translation", p.translation)?;
        let yaw = ck.range(
            "scene.world_from_cave.yaw_degrees",
            p.yaw_degrees,
            -360.0,
            360.0,
        )?;
        let scale = ck.range("scene.world_from_cave.scale", p.scale, 1e-3, 1e3)?;
        let world_from_cave = Mat4::from_scale_rotation_translation(
            Vec3::splat(scale),
            Quat::from_rotation_y(yaw.to_radians()),
            translation,
        );

        let l = &self.lighting;
        ck.colour("lighting.ambient", l.ambient, 10.0)?;
        let sun = ck.finite3("lighting.directional.direction", l.directional.direction)?;
        if sun.length() < 1e-6 {
            return Err(ck.fail(
                "lighting.directional.direction",
                l.directional.direction,
                "must not be the zero vector",
            ));
        }
        ck.colour("lighting.directional.color", l.directional.color, 10.0)?;
        ck.range(
            "lighting.directional.intensity",
            l.directional.intensity,
            0.0,
            100.0,
        )?;
        ck.finite3("lighting.point.position", l.point.position)?;
        ck.colour("lighting.point.color", l.point.color, 10.0)?;
        ck.range("lighting.point.intensity", l.point.intensity, 0.0, 100.0)?;
        ck.range("lighting.point.range", l.point.range, 1e-3, 1e6)?;

        let resolve = |p: &PathBuf| {
            if p.is_absolute() {
                p.clone()
            } else {
                path.parent().unwrap_or(Path::new(".")).join(p)
            }
        };
        let scene_path = self.scene.path.as_ref().map(resolve);

        let k = &self.skybox;
        let sky_mode = SkyMode::from_name(&k.mode).ok_or_else(|| {
            let names: Vec<_> = SkyMode::ALL.iter().map(|m| m.name()).collect();
            ck.fail(
                "skybox.mode",
                &k.mode,
                &format!("must be one of {}", names.join(", ")),
            )
        })?;
        let sky = SkySettings {
            mode: sky_mode,
            pixels_per_slice: ck.range(
                "skybox.pixels_per_slice",
                k.pixels_per_slice,
                1.0,
                4096.0,
            )?,
            exposure: ck.range("skybox.exposure", k.exposure, 0.0, 1e4)?,
        };
        let sky_path = k
            .file
            .as_ref()
            .filter(|p| p.as_os_str() != "none")
            .map(resolve);

        Ok(Config {
            source: path.to_owned(),
            cave: cave_for_check,
            head: Head {
                position: head_pos,
                orientation: Head::orientation_from_degrees(
                    h.yaw_degrees,
                    h.pitch_degrees,
                    h.roll_degrees,
                ),
            },
            eye_separation,
            mode,
            msaa: r.msaa,
            wireframe: r.wireframe,
            background: background.to_array(),
            scene_path,
            world_from_cave,
            lighting: l.to_lighting(),
            omni,
            tess,
            sky_path,
            sky,
            app: self.validate_app(&ck)?,
            tracking: self.validate_tracking(&ck)?,
            gamepad: self.validate_gamepad(&ck)?,
            panorama: self.panorama.validate(&ck)?,
            file: self.clone(),
        })
    }

    fn validate_tracking(&self, ck: &Checker<'_>) -> Result<TrackingConfig, ConfigError> {
        let t = &self.tracking;
        let listen: SocketAddr = t.listen.trim().parse().map_err(|_| {
            ck.fail(
                "tracking.listen",
                &t.listen,
                "must be an address:port such as \"0.0.0.0:7000\" or \"[::]:7000\"",
            )
        })?;
        let mut allowed_senders = Vec::with_capacity(t.allowed_senders.len());
        for (i, s) in t.allowed_senders.iter().enumerate() {
            let ip: IpAddr = s.trim().parse().map_err(|_| {
                ck.fail(
                    &format!("tracking.allowed_senders[{i}]"),
                    s,
                    "must be an IP address such as \"192.168.1.20\"",
                )
            })?;
            allowed_senders.push(ip);
        }
        for (field, address) in [
            ("tracking.position_address", &t.position_address),
            ("tracking.orientation_address", &t.orientation_address),
            ("tracking.euler_address", &t.euler_address),
            ("tracking.natnet_address", &t.natnet_address),
        ] {
            if !address.is_empty() && (!address.starts_with('/') || address.contains(' ')) {
                return Err(ck.fail(
                    field,
                    address,
                    "must be an OSC address starting with '/' (no spaces), or \"\" for off",
                ));
            }
        }
        let quaternion_order =
            QuaternionOrder::from_name(&t.quaternion_order).ok_or_else(|| {
                ck.fail(
                    "tracking.quaternion_order",
                    &t.quaternion_order,
                    "must be \"wxyz\" or \"xyzw\"",
                )
            })?;
        let timeout = ck.range("tracking.timeout_seconds", t.timeout_seconds, 0.01, 60.0)?;

        let c = &t.calibration;
        let remap = Calibration::remap_from_axes(&c.axes)
            .map_err(|e| ck.fail("tracking.calibration.axes", &c.axes, &e.to_string()))?;
        let scale = ck.range("tracking.calibration.scale", c.scale, 1e-6, 1e6)?;
        let [yaw, pitch, roll] = c.rotation_degrees;
        for v in c.rotation_degrees {
            ck.range("tracking.calibration.rotation_degrees", v, -360.0, 360.0)?;
        }
        let offset = ck.finite3("tracking.calibration.offset", c.offset)?;

        let f = &t.filter;
        let params = OneEuroParams {
            min_cutoff_hz: ck.range("tracking.filter.min_cutoff_hz", f.min_cutoff_hz, 1e-3, 1e3)?,
            beta: ck.range("tracking.filter.beta", f.beta, 0.0, 1e3)?,
            derivative_cutoff_hz: ck.range(
                "tracking.filter.derivative_cutoff_hz",
                f.derivative_cutoff_hz,
                1e-3,
                1e3,
            )?,
        };
        Ok(TrackingConfig {
            enabled: t.enabled,
            receiver: ReceiverSettings {
                listen,
                allowed_senders,
                mapping: OscMapping {
                    position_address: t.position_address.clone(),
                    orientation_address: t.orientation_address.clone(),
                    euler_address: t.euler_address.clone(),
                    quaternion_order,
                    natnet_address: t.natnet_address.clone(),
                    natnet_rigid_body: t.natnet_rigid_body,
                },
            },
            settings: TrackingSettings {
                calibration: Calibration {
                    remap,
                    scale,
                    rotation: Head::orientation_from_degrees(yaw, pitch, roll),
                    offset,
                },
                filter: f.enabled.then_some(params),
                timeout: Duration::from_secs_f32(timeout),
            },
        })
    }

    fn validate_gamepad(&self, ck: &Checker<'_>) -> Result<GamepadSettings, ConfigError> {
        let g = &self.gamepad;
        let mode = GamepadMode::from_name(&g.mode)
            .ok_or_else(|| ck.fail("gamepad.mode", &g.mode, "must be \"navigate\" or \"head\""))?;
        let buttons = button_map(&g.buttons).map_err(|e| {
            let (field, value) = match &e {
                crate::gamepad::ButtonMapError::Button(b) => {
                    (format!("gamepad.buttons.{b}"), b.clone())
                }
                crate::gamepad::ButtonMapError::Action(a) => {
                    let key = g
                        .buttons
                        .iter()
                        .find(|(_, v)| *v == a)
                        .map_or_else(String::new, |(k, _)| k.clone());
                    (format!("gamepad.buttons.{key}"), a.clone())
                }
            };
            ck.fail(&field, value, &e.to_string())
        })?;
        Ok(GamepadSettings {
            enabled: g.enabled,
            mode,
            dead_zone: ck.range("gamepad.dead_zone", g.dead_zone, 0.0, 0.9)?,
            trigger_dead_zone: ck.range(
                "gamepad.trigger_dead_zone",
                g.trigger_dead_zone,
                0.0,
                0.9,
            )?,
            head_speed: ck.range("gamepad.head_speed", g.head_speed, 0.0, 10.0)?,
            buttons,
        })
    }

    fn validate_app(&self, ck: &Checker<'_>) -> Result<AppConfig, ConfigError> {
        let a = &self.app;
        let format = |field: &str, name: &str| {
            StereoFormat::from_name(name).ok_or_else(|| {
                let names: Vec<_> = StereoFormat::ALL.iter().map(|f| f.name()).collect();
                ck.fail(field, name, &format!("must be one of {}", names.join(", ")))
            })
        };
        let mode = match a.mode.as_str() {
            "cave" => AppMode::Cave,
            "preview" => AppMode::Preview,
            other => return Err(ck.fail("app.mode", other, "must be \"cave\" or \"preview\"")),
        };
        let panel = match a.panel.as_str() {
            "window" => PanelPlacement::Window,
            "hidden" => PanelPlacement::Hidden,
            other => match other.strip_prefix("overlay:") {
                Some(wall) => PanelPlacement::Overlay(
                    self.walls
                        .iter()
                        .position(|w| w.name == wall)
                        .ok_or_else(|| {
                            ck.fail("app.panel", other, "names no wall of this config")
                        })?,
                ),
                None => {
                    return Err(ck.fail(
                        "app.panel",
                        other,
                        "must be \"window\", \"hidden\" or \"overlay:<wall name>\"",
                    ));
                }
            },
        };
        let size_ok = |s: [u32; 2]| s.iter().all(|&v| (1..=MAX_WALL_PIXELS).contains(&v));
        if !size_ok(a.window_size) {
            return Err(ck.fail(
                "app.window_size",
                a.window_size,
                &format!("both sides must be 1..={MAX_WALL_PIXELS} pixels"),
            ));
        }
        let wall_output = format("app.wall_output", &a.wall_output)?;
        let preview_output = format("app.preview_output", &a.preview_output)?;
        let navigation_speed = ck.range("app.navigation_speed", a.navigation_speed, 0.0, 1000.0)?;
        let mut walls = Vec::with_capacity(self.walls.len());
        for (i, w) in self.walls.iter().enumerate() {
            let size = w.window_size.unwrap_or(w.resolution);
            if !size_ok(size) {
                return Err(ck.fail(
                    &format!("wall[{i}].window_size"),
                    size,
                    &format!("both sides must be 1..={MAX_WALL_PIXELS} pixels"),
                ));
            }
            let output = match &w.output {
                Some(name) => format(&format!("wall[{i}].output"), name)?,
                None => wall_output,
            };
            walls.push(WallWindow {
                monitor: w.monitor.clone(),
                position: w.window_position,
                size,
                output,
            });
        }
        Ok(AppConfig {
            mode,
            panel,
            window_position: a.window_position,
            window_size: a.window_size,
            preview_output,
            vsync: a.vsync,
            navigation_speed,
            walls,
        })
    }
}

fn validate_wall(
    ck: &Checker<'_>,
    index: usize,
    w: &WallSection,
    earlier: &[Wall],
) -> Result<Wall, ConfigError> {
    let field = |name: &str| format!("wall[{index}].{name}");
    let name_ok = !w.name.is_empty()
        && w.name.len() <= 64
        && w.name
            .chars()
            .all(|c| c.is_ascii_alphanumeric() || c == '-' || c == '_');
    if !name_ok {
        return Err(ck.fail(
            &field("name"),
            &w.name,
            "must be 1–64 characters of a-z, A-Z, 0-9, '-' or '_' (it names output files)",
        ));
    }
    if earlier.iter().any(|e| e.name == w.name) {
        return Err(ck.fail(&field("name"), &w.name, "another wall has this name"));
    }
    let ll = ck.finite3(&field("lower_left"), w.lower_left)?;
    let lr = ck.finite3(&field("lower_right"), w.lower_right)?;
    let ul = ck.finite3(&field("upper_left"), w.upper_left)?;
    // A wall narrower than a millimetre is a typo, not a screen.
    const MIN_SIDE_M: f32 = 1e-3;
    let width = (lr - ll).length();
    if width < MIN_SIDE_M {
        return Err(ck.fail(
            &field("lower_right"),
            w.lower_right,
            "coincides with lower_left: the wall has no width",
        ));
    }
    let height = (ul - ll).length();
    if height < MIN_SIDE_M {
        return Err(ck.fail(
            &field("upper_left"),
            w.upper_left,
            "coincides with lower_left: the wall has no height",
        ));
    }
    // The two edges from lower_left must be perpendicular (cosine below ~0.06°); a skewed
    // parallelogram cannot be driven by a rectangular image.
    let cosine = (lr - ll).dot(ul - ll) / (width * height);
    if cosine.abs() > 1e-3 {
        return Err(ck.fail(
            &field("upper_left"),
            w.upper_left,
            &format!(
                "edges lower_left→lower_right and lower_left→upper_left are not perpendicular \
                 (angle {:.2}°): walls must be rectangles",
                cosine.clamp(-1.0, 1.0).acos().to_degrees()
            ),
        ));
    }
    let [pw, ph] = w.resolution;
    if pw == 0 || ph == 0 || pw > MAX_WALL_PIXELS || ph > MAX_WALL_PIXELS {
        return Err(ck.fail(
            &field("resolution"),
            w.resolution,
            &format!("width and height must be 1..={MAX_WALL_PIXELS} pixels"),
        ));
    }
    Ok(Wall {
        name: w.name.clone(),
        lower_left: ll,
        lower_right: lr,
        upper_left: ul,
        resolution: w.resolution,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    const GOOD: &str = r#"
[[wall]]
name = "front"
lower_left = [-1.65, 0.0, -1.65]
lower_right = [1.65, 0.0, -1.65]
upper_left = [-1.65, 2.9, -1.65]
resolution = [1280, 720]
"#;

    fn err(text: &str) -> String {
        match Config::from_toml(text, Path::new("test.toml")) {
            Ok(_) => panic!("accepted:\n{text}"),
            Err(e) => e.to_string(),
        }
    }

    #[test]
    fn minimal_config_gets_defaults() {
        let cfg = Config::from_toml(GOOD, Path::new("x/test.toml")).expect("valid");
        assert_eq!(cfg.cave.walls.len(), 1);
        assert_eq!(cfg.mode, RenderMode::Stereo);
        assert!((cfg.eye_separation - 0.064).abs() < 1e-7);
    }

    #[test]
    fn omnistereo_defaults_match_the_library_defaults() {
        let cfg = Config::from_toml(GOOD, Path::new("test.toml")).expect("valid");
        assert_eq!(cfg.omni, OmniSettings::default());
    }

    #[test]
    fn unknown_key_is_named() {
        let e = err(&format!("{GOOD}\n[head]\nposition = [0,1,0]\nheigth = 3\n"));
        assert!(e.contains("test.toml") && e.contains("heigth"), "{e}");
    }

    #[test]
    fn nan_is_refused_with_field_and_value() {
        let e = err(&GOOD.replace("[-1.65, 2.9, -1.65]", "[-1.65, nan, -1.65]"));
        assert!(e.contains("wall[0].upper_left") && e.contains("NaN"), "{e}");
    }

    #[test]
    fn skewed_wall_is_refused() {
        let e = err(&GOOD.replace("[-1.65, 2.9, -1.65]", "[-1.0, 2.9, -1.65]"));
        assert!(e.contains("not perpendicular"), "{e}");
    }

    #[test]
    fn degenerate_and_zero_size_walls_are_refused() {
        let e = err(&GOOD.replace("[1.65, 0.0, -1.65]", "[-1.65, 0.0, -1.65]"));
        assert!(
            e.contains("wall[0].lower_right") && e.contains("no width"),
            "{e}"
        );
        let e = err(&GOOD.replace("[1280, 720]", "[0, 720]"));
        assert!(
            e.contains("wall[0].resolution") && e.contains("[0, 720]"),
            "{e}"
        );
    }

    #[test]
    fn bad_mode_lists_the_choices() {
        let e = err(&format!("{GOOD}\n[render]\nmode = \"omni\"\n"));
        assert!(
            e.contains("render.mode") && e.contains("tracked-stereo"),
            "{e}"
        );
    }
}
