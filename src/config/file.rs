//! The config file as written: every section and setting with its type, default and doc line.
//!
//! This is the settings model. The TOML file deserialises straight into it (unknown keys and
//! unknown enum names are refused by serde, with the line), "Save settings" serialises it, and
//! the JSON schema (`omnicave config schema`) is derived from it. Each section's `Default` is
//! the one place its defaults are written; enums are the domain's own types, named once by
//! [`named_enum!`](crate::named_enum).

use std::collections::BTreeMap;
use std::path::PathBuf;

use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

use super::wall_output::{EyeOutputSection, WallOutput};
use crate::cave::RenderMode;
use crate::cave::omni::{PoleMerge, WarpVariant};
use crate::cave::placement::{LengthUnit, UpAxis};
use crate::gamepad::{GamepadMode, GamepadSettings};
use crate::output::formats::StereoFormat;
use crate::pano::{PanoRoute, PanoStereoKind, Projection, VOLUME_DEFAULT_PARAMS};
use crate::scene::{SceneBudget, SceneFit, Shading};
use crate::sky::{DEFAULT_PIXELS_PER_SLICE, SkyMode};
use crate::tess::{Criterion, TessSettings};
use crate::tracking::dtrack::DEFAULT_DTRACK_PORT;
use crate::tracking::natnet::DEFAULT_COMMAND_PORT as DEFAULT_NATNET_PORT;
use crate::tracking::{
    DEFAULT_OSC_PORT, OneEuroParams, OscMapping, PlausibilityLimits, QuaternionOrder, SourceKind,
    TrackingSettings,
};

/// Largest accepted wall image side; beyond any projector and wgpu's default texture limit.
pub const MAX_WALL_PIXELS: u32 = 8192;

/// The whole configuration file, as written.
#[derive(Debug, Clone, Default, PartialEq, Deserialize, Serialize, JsonSchema)]
#[serde(default, deny_unknown_fields)]
pub struct ConfigFile {
    pub cave: CaveSection,
    pub head: HeadSection,
    pub render: RenderSection,
    pub scene: SceneSection,
    pub lighting: LightingSection,
    pub shadows: ShadowsSection,
    pub omnistereo: OmnistereoSection,
    pub tessellation: TessellationSection,
    pub skybox: SkyboxSection,
    pub app: AppSection,
    pub tracking: TrackingSection,
    pub gamepad: GamepadSection,
    pub panorama: PanoramaSection,
    pub animation: AnimationSection,
    pub budgets: BudgetsSection,
    /// Cluster mode: the walls driven by several processes or PCs in lockstep (`omnicave run
    /// --cluster` under `mpirun`, in a build with the `cluster` feature).
    pub cluster: ClusterSection,
    /// The projection walls (screens), at least one: `[[wall]]` tables.
    #[serde(rename = "wall")]
    pub walls: Vec<WallSection>,
}

/// The CAVE's eyes and clipping.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize, JsonSchema)]
#[serde(default, deny_unknown_fields)]
pub struct CaveSection {
    /// Interpupillary distance in metres (0 to 0.5).
    #[schemars(range(min = 0.0, max = 0.5))]
    pub eye_separation: f32,
    /// Near clipping distance, metres.
    #[schemars(range(min = 1e-4, max = 10.0))]
    pub near: f32,
    /// Far clipping distance, metres (at least ten times `near`).
    pub far: f32,
    /// View direction assumed by fixed-direction stereo; default −z (⟂ the front wall).
    pub stereo_view_direction: [f32; 3],
    /// Projective viewpoint of the on-axis omnistereo warp; default: the room's centre.
    pub projection_centre: Option<[f32; 3]>,
    /// The unit of the walls' coordinates and sizes: m, cm, mm, inch or foot.
    pub wall_units: LengthUnit,
    /// The axis that points up in the walls' coordinates: "y" (CAVE space) or "z" (right-handed
    /// z-up: x right, y to the front). Wall angles do not depend on it (yaw is about up).
    pub wall_up_axis: UpAxis,
}

impl CaveSection {
    /// The frame the `[[wall]]` geometry is written in.
    pub fn wall_frame(&self) -> crate::cave::placement::FileFrame {
        crate::cave::placement::FileFrame {
            unit: self.wall_units,
            up: self.wall_up_axis,
        }
    }
}

impl Default for CaveSection {
    fn default() -> Self {
        Self {
            eye_separation: 0.064,
            near: 0.05,
            far: 2000.0,
            stereo_view_direction: [0.0, 0.0, -1.0],
            projection_centre: None,
            wall_units: LengthUnit::Metre,
            wall_up_axis: UpAxis::Y,
        }
    }
}

/// Omnistereo settings.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize, JsonSchema)]
#[serde(default, deny_unknown_fields)]
pub struct OmnistereoSection {
    /// `similar-triangles` (stable) or `intersection-point` (only to show where it breaks).
    pub warp: WarpVariant,
    /// Fade the eye separation to zero near the vertical axis through the head.
    pub pole_merge: bool,
    /// Elevation where the fade starts, degrees (0 to 90).
    #[schemars(range(min = 0.0, max = 90.0))]
    pub pole_merge_start_degrees: f32,
    /// Elevation where the eye separation reaches zero, degrees (start to 90).
    #[schemars(range(min = 0.0, max = 90.0))]
    pub pole_merge_end_degrees: f32,
}

impl Default for OmnistereoSection {
    fn default() -> Self {
        let merge = PoleMerge::default();
        Self {
            warp: WarpVariant::default(),
            pole_merge: true,
            pole_merge_start_degrees: merge.start_degrees,
            pole_merge_end_degrees: merge.end_degrees,
        }
    }
}

/// Adaptive tessellation before the omnistereo warp.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize, JsonSchema)]
#[serde(default, deny_unknown_fields)]
pub struct TessellationSection {
    /// `none`, `uniform:N`, `edge:PX`, `sphere:PX` or `error:PX`.
    #[serde(with = "criterion_text")]
    #[schemars(with = "String")]
    pub criterion: Option<Criterion>,
    /// Deepest subdivision (0 to 16 levels; 2^depth segments per edge at most).
    #[schemars(range(min = 0, max = crate::tess::MAX_DEPTH_LIMIT))]
    pub max_depth: u32,
    /// Cull back faces before splitting.
    pub backface_cull: bool,
    /// Cull triangles whose warped footprint misses the wall before splitting.
    pub frustum_cull: bool,
    /// Draw clusters of triangles whose warp error is provably below the criterion through
    /// the ordinary path, and tessellate only the rest (the same picture, at the cost of what
    /// needs refining). Off: every triangle goes through the tessellator.
    pub skip_fine: bool,
    /// Refine once for both eyes of a wall (edges split where either eye's warp needs it;
    /// each eye warps the shared result). Off: each eye is refined on its own, with twice
    /// the tessellator's dispatches, each eye's error held alike.
    pub shared_eyes: bool,
}

impl Default for TessellationSection {
    fn default() -> Self {
        let tess = TessSettings::default();
        Self {
            criterion: None,
            max_depth: tess.max_depth,
            backface_cull: tess.backface_cull,
            frustum_cull: tess.frustum_cull,
            skip_fine: tess.skip_fine,
            shared_eyes: tess.shared_eyes,
        }
    }
}

/// A tessellation criterion as its text (`none`, `error:0.5`, …).
mod criterion_text {
    use serde::{Deserialize, Deserializer, Serializer};

    use crate::tess::{Criterion, parse_criterion};

    pub fn serialize<S: Serializer>(c: &Option<Criterion>, s: S) -> Result<S::Ok, S::Error> {
        match c {
            None => s.serialize_str("none"),
            Some(c) => s.collect_str(c),
        }
    }

    pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<Option<Criterion>, D::Error> {
        let text = String::deserialize(d)?;
        parse_criterion(&text).map_err(serde::de::Error::custom)
    }
}

/// The sky behind the scene.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize, JsonSchema)]
#[serde(default, deny_unknown_fields)]
pub struct SkyboxSection {
    /// An equirectangular image (PNG/JPEG/HDR) or a folder of six faces; relative to the
    /// config's folder. Absent or "none": no sky.
    pub file: Option<PathBuf>,
    /// How the sky is drawn: `auto` follows the render mode.
    pub mode: SkyMode,
    /// Omni-quad mesh density: one slice per this many pixels (1 to 4096).
    #[schemars(range(min = 1.0, max = 4096.0))]
    pub pixels_per_slice: f32,
    /// Multiplier on the sky's linear colour.
    #[schemars(range(min = 0.0, max = 1e4))]
    pub exposure: f32,
    /// How much the sky lights the scene: image-based ambient light from its irradiance
    /// (0: none, e.g. indoors, where walls would hide it; the sky light is not shadowed).
    #[schemars(range(min = 0.0, max = 100.0))]
    pub light: f32,
}

impl Default for SkyboxSection {
    fn default() -> Self {
        Self {
            file: None,
            mode: SkyMode::default(),
            pixels_per_slice: DEFAULT_PIXELS_PER_SLICE,
            exposure: 1.0,
            light: 1.0,
        }
    }
}

/// Head tracking (`omnicave run`): OSC, VRPN or ART DTrack.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize, JsonSchema)]
#[serde(default, deny_unknown_fields)]
pub struct TrackingSection {
    /// Track the head from the start (the panel can switch it).
    pub enabled: bool,
    /// `osc`, `vrpn` (see `[tracking.vrpn]`), `dtrack` (`[tracking.dtrack]`) or `natnet`
    /// (`[tracking.natnet]`).
    pub source: SourceKind,
    /// OSC: UDP address:port to listen on; 0.0.0.0 is every interface.
    pub listen: String,
    /// Senders allowed to drive tracking (IP addresses): OSC and DTrack take packets only from
    /// these, VRPN and NatNet connect only to servers at these; empty: any (with a warning
    /// when OSC or DTrack listens on a network address).
    pub allowed_senders: Vec<String>,
    /// From the tracked body's origin to the midpoint of the eyes, metres, in the body's own
    /// frame as calibrated (x right, y up, −z forward of a head looking straight ahead): the
    /// marker tree sits above the glasses, e.g. [0, -0.08, 0.02].
    pub eye_offset: [f32; 3],
    /// Button number of the tracked input device (VRPN button device, DTrack flystick) →
    /// "fly" (along the wand's ray while held), "select" (what the ray hits, shown in the
    /// panel) or one of the gamepad's action names; "none" unbinds.
    pub buttons: BTreeMap<String, String>,
    /// Draw the wand's ray (when a wand is tracked).
    pub show_wand_ray: bool,
    /// How far the wand's ray is drawn (and a selection looks), metres.
    #[schemars(range(min = 0.1, max = 100.0))]
    pub wand_ray_length_m: f32,
    pub vrpn: VrpnSection,
    pub dtrack: DTrackSection,
    pub natnet: NatNetSection,
    /// `x y z` (or + quaternion, or + yaw pitch roll); empty string: off.
    pub position_address: String,
    /// A quaternion; empty string: off.
    pub orientation_address: String,
    /// `yaw pitch roll` in degrees; empty string: off.
    pub euler_address: String,
    /// The order of a quaternion's numbers.
    pub quaternion_order: QuaternionOrder,
    /// The NatNet-to-OSC form (`/rigidbody <id> position x y z`); empty string: off.
    pub natnet_address: String,
    /// The rigid body id that is the head, in the NatNet form.
    pub natnet_rigid_body: i64,
    /// No packet for this long: "tracking lost", the head holds its last pose; a VRPN server
    /// reporting a tracker, or Motive, is connected to again.
    #[schemars(range(min = 0.01, max = 60.0))]
    pub timeout_seconds: f32,
    pub calibration: CalibrationSection,
    pub filter: FilterSection,
    pub plausibility: PlausibilitySection,
}

impl Default for TrackingSection {
    fn default() -> Self {
        let mapping = OscMapping::default();
        Self {
            enabled: false,
            source: SourceKind::default(),
            listen: format!("0.0.0.0:{DEFAULT_OSC_PORT}"),
            allowed_senders: Vec::new(),
            eye_offset: [0.0; 3],
            buttons: [
                ("0", "fly"),
                ("1", "select"),
                ("2", "next-render-mode"),
                ("3", "previous-render-mode"),
                ("4", "reset-view"),
            ]
            .into_iter()
            .map(|(b, a)| (b.to_owned(), a.to_owned()))
            .collect(),
            show_wand_ray: true,
            wand_ray_length_m: 4.0,
            vrpn: VrpnSection::default(),
            dtrack: DTrackSection::default(),
            natnet: NatNetSection::default(),
            position_address: mapping.position_address,
            orientation_address: mapping.orientation_address,
            euler_address: mapping.euler_address,
            quaternion_order: mapping.quaternion_order,
            natnet_address: mapping.natnet_address,
            natnet_rigid_body: mapping.natnet_rigid_body,
            timeout_seconds: TrackingSettings::default().timeout.as_secs_f32(),
            calibration: CalibrationSection::default(),
            filter: FilterSection::default(),
            plausibility: PlausibilitySection::default(),
        }
    }
}

/// A VRPN server's devices, named as VRPN users write them: `Device@host` or
/// `Device@host:port` (port 3883 unless given).
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize, JsonSchema)]
#[serde(default, deny_unknown_fields)]
pub struct VrpnSection {
    /// The tracker whose sensor is the head.
    pub head: String,
    /// The head's sensor number.
    #[schemars(range(min = 0, max = 65535))]
    pub head_sensor: i32,
    /// The wand's tracker (often the head's); empty: no wand.
    pub wand: String,
    #[schemars(range(min = 0, max = 65535))]
    pub wand_sensor: i32,
    /// The button device; empty: none. A DTrack flystick served by VRPN has the tracker's name.
    pub buttons: String,
    /// The analog device (joystick axes); empty: none.
    pub analogs: String,
    /// While a server is absent, try again this often, seconds.
    #[schemars(range(min = 0.1, max = 60.0))]
    pub retry_seconds: f32,
}

impl Default for VrpnSection {
    fn default() -> Self {
        Self {
            head: "Tracker0@localhost".into(),
            head_sensor: 0,
            wand: String::new(),
            wand_sensor: 1,
            buttons: String::new(),
            analogs: String::new(),
            retry_seconds: 1.0,
        }
    }
}

/// ART DTrack's ASCII output (DTrack sends its frames to this machine's port).
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize, JsonSchema)]
#[serde(default, deny_unknown_fields)]
pub struct DTrackSection {
    /// UDP address:port to listen on (DTrack's "data output" port).
    pub listen: String,
    /// The `6d` body that is the head: its id in the frames, from 0 (DTrack's GUI counts from 1).
    #[schemars(range(min = 0, max = 1023))]
    pub head_body: u32,
    /// The `6df2` flystick that is the wand and gives the buttons, from 0; -1: none.
    #[schemars(range(min = -1, max = 1023))]
    pub flystick: i32,
}

impl Default for DTrackSection {
    fn default() -> Self {
        Self {
            listen: format!("0.0.0.0:{DEFAULT_DTRACK_PORT}"),
            head_body: 0,
            flystick: 0,
        }
    }
}

/// OptiTrack Motive's NatNet stream (Motive: metres, y up).
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize, JsonSchema)]
#[serde(default, deny_unknown_fields)]
pub struct NatNetSection {
    /// Motive's command address, IPv4 (port 1510 unless Motive says otherwise).
    pub server: String,
    /// The local IPv4 interface to talk and join multicast on; "0.0.0.0": the system's choice.
    pub interface: String,
    /// The streaming id of the rigid body that is the head.
    pub head_rigid_body: i32,
    /// The rigid body that is the wand; -1: none.
    pub wand_rigid_body: i32,
    /// While Motive is absent or quiet, try again this often, seconds.
    #[schemars(range(min = 0.1, max = 60.0))]
    pub retry_seconds: f32,
}

impl Default for NatNetSection {
    fn default() -> Self {
        Self {
            server: format!("127.0.0.1:{DEFAULT_NATNET_PORT}"),
            interface: "0.0.0.0".into(),
            head_rigid_body: 1,
            wand_rigid_body: -1,
            retry_seconds: 1.0,
        }
    }
}

/// Tracker frame → CAVE space: `cave = offset + rotation · (scale · axes(tracker))`.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize, JsonSchema)]
#[serde(default, deny_unknown_fields)]
pub struct CalibrationSection {
    /// The CAVE's x, y, z as signed tracker axes: ["x", "z", "-y"] for a right-handed z-up
    /// tracker, ["x", "y", "-z"] for a left-handed y-up one.
    pub axes: [String; 3],
    /// Tracker units to metres (0.001 for millimetres).
    #[schemars(range(min = 1e-6, max = 1e6))]
    pub scale: f32,
    /// Yaw, pitch, roll in degrees, applied after the axis remap.
    #[schemars(inner(range(min = -360.0, max = 360.0)))]
    pub rotation_degrees: [f32; 3],
    /// Where the tracker's origin is in CAVE space, metres.
    pub offset: [f32; 3],
}

impl Default for CalibrationSection {
    fn default() -> Self {
        Self {
            axes: ["x".into(), "y".into(), "z".into()],
            scale: 1.0,
            rotation_degrees: [0.0; 3],
            offset: [0.0; 3],
        }
    }
}

/// One Euro filter against tracker jitter.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize, JsonSchema)]
#[serde(default, deny_unknown_fields)]
pub struct FilterSection {
    pub enabled: bool,
    /// Cutoff at rest, Hz: lower is smoother and lags more.
    #[schemars(range(min = 1e-3, max = 1e3))]
    pub min_cutoff_hz: f32,
    /// How fast the cutoff rises with speed: higher lags less when moving.
    #[schemars(range(min = 0.0, max = 1e3))]
    pub beta: f32,
    /// Cutoff of the speed estimate, Hz.
    #[schemars(range(min = 1e-3, max = 1e3))]
    pub derivative_cutoff_hz: f32,
}

impl Default for FilterSection {
    fn default() -> Self {
        let params = OneEuroParams::default();
        Self {
            enabled: true,
            min_cutoff_hz: params.min_cutoff_hz,
            beta: params.beta,
            derivative_cutoff_hz: params.derivative_cutoff_hz,
        }
    }
}

/// What a head can do: the gate refuses a tracker sample beyond it in the receiver thread
/// (counted as "implausible" or "unconfirmed jump" in the panel and the stats line), so one
/// corrupt packet cannot pin the head. The wand may move and turn twice as fast.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize, JsonSchema)]
#[serde(default, deny_unknown_fields)]
pub struct PlausibilitySection {
    /// How far outside the CAVE a sample may be, metres (those nearer are clamped in).
    #[schemars(range(min = 0.0, max = 100.0))]
    pub outside_margin_m: f32,
    /// Fastest head movement accepted, m/s (a jump confirmed by 3 agreeing samples over
    /// 40 ms is taken).
    #[schemars(range(min = 0.1, max = 1000.0))]
    pub max_speed_mps: f32,
    /// Fastest head turn accepted, degrees per second.
    #[schemars(range(min = 1.0, max = 100000.0))]
    pub max_turn_dps: f32,
}

impl Default for PlausibilitySection {
    fn default() -> Self {
        let limits = PlausibilityLimits::default();
        Self {
            outside_margin_m: limits.outside_margin_m,
            max_speed_mps: limits.max_speed_mps,
            max_turn_dps: limits.max_turn_dps,
        }
    }
}

/// Cluster mode (the book's "A cluster of PCs"): every process (MPI rank) loads the same config and scene;
/// rank 0, the master, takes the input and broadcasts each frame's state; every rank renders
/// the walls whose `node` is its rank; all present together after a barrier.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize, JsonSchema)]
#[serde(default, deny_unknown_fields)]
pub struct ClusterSection {
    /// How long any process waits for another in a frame (a node's "rendered", the master's
    /// frame state or "present") before it counts that process lost, milliseconds. Longer
    /// than the slowest frame; the first frame, which compiles shaders, gets
    /// `startup_timeout_s`.
    #[schemars(range(min = 10, max = 600000))]
    pub timeout_ms: u32,
    /// How long the master waits at start-up for every node to load the config and scene and
    /// report, seconds.
    #[schemars(range(min = 1, max = 3600))]
    pub startup_timeout_s: u32,
    /// When a render node is lost: "continue" (the others go on without its walls) or "stop"
    /// (every process stops cleanly).
    pub on_node_loss: NodeLoss,
}

impl Default for ClusterSection {
    fn default() -> Self {
        Self {
            timeout_ms: 2000,
            startup_timeout_s: 120,
            on_node_loss: NodeLoss::Continue,
        }
    }
}

/// What the cluster does when a render node dies or stalls.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum NodeLoss {
    /// The others go on; the lost node's walls go dark.
    Continue,
    /// Every process stops cleanly.
    Stop,
}

crate::named_enum!(NodeLoss {
    Self::Continue => "continue",
    Self::Stop => "stop",
});

/// What inputs may cost (the book's budgets reference). A scene or sky past one is refused with the
/// budget named; images larger than `max_texture_side` are downscaled, with a warning.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize, JsonSchema)]
#[serde(default, deny_unknown_fields)]
pub struct BudgetsSection {
    /// Largest scene or sky file (and each file a glTF names), MiB.
    #[schemars(range(min = 1, max = 65536))]
    pub max_file_mb: u32,
    /// Mesh instances and nodes after expanding the scene's node graph.
    #[schemars(range(min = 1, max = 67108864))]
    pub max_instances: u32,
    /// Vertices after expanding instances (72 bytes each on the GPU).
    #[schemars(range(min = 3, max = 1073741824))]
    pub max_vertices: u32,
    /// Triangles after expanding instances.
    #[schemars(range(min = 1, max = 1073741824))]
    pub max_triangles: u32,
    /// Longest texture side, pixels; larger images are downscaled to it.
    #[schemars(range(min = 16, max = 16384))]
    pub max_texture_side: u32,
    /// All of a scene's textures with their mip levels, MiB.
    #[schemars(range(min = 1, max = 1048576))]
    pub max_texture_memory_mb: u32,
    /// Joints of one skin (each a matrix the pose pass reads per frame).
    #[schemars(range(min = 1, max = 65536))]
    pub max_joints: u32,
    /// Morph targets of one primitive (36 bytes per vertex and target on the GPU).
    #[schemars(range(min = 0, max = 4096))]
    pub max_morph_targets: u32,
    /// Animation channels of a scene file, every animation together.
    #[schemars(range(min = 0, max = 16777216))]
    pub max_animation_channels: u32,
    /// Keyframes of a scene file, every channel together.
    #[schemars(range(min = 0, max = 268435456))]
    pub max_keyframes: u32,
    /// What a scene's animated primitives hold for posing (mesh-space vertices, morph target
    /// deltas, skin weights; CPU and GPU copies), MiB.
    #[schemars(range(min = 1, max = 1048576))]
    pub max_pose_memory_mb: u32,
    /// Walls in one config (one window and render target each).
    #[schemars(range(min = 1, max = 1024))]
    pub max_walls: u32,
    /// GPU memory of every wall's render targets (both eyes, MSAA and depth), MiB.
    #[schemars(range(min = 1, max = 1048576))]
    pub max_target_memory_mb: u32,
}

impl Default for BudgetsSection {
    fn default() -> Self {
        let scene = SceneBudget::default();
        let narrow = |v: u64| u32::try_from(v).unwrap_or(u32::MAX);
        Self {
            max_file_mb: narrow(scene.max_file_bytes >> 20),
            max_instances: narrow(scene.max_instances),
            max_vertices: narrow(scene.max_vertices),
            max_triangles: narrow(scene.max_triangles),
            max_texture_side: scene.max_texture_side,
            max_texture_memory_mb: narrow(scene.max_texture_bytes >> 20),
            max_joints: scene.max_joints,
            max_morph_targets: scene.max_morph_targets,
            max_animation_channels: scene.max_animation_channels,
            max_keyframes: scene.max_keyframes,
            max_pose_memory_mb: narrow(scene.max_pose_bytes >> 20),
            max_walls: DEFAULT_MAX_WALLS,
            // Six 2560×1600 walls with MSAA 4 take 1.7 GiB; three 8192² walls with MSAA 4
            // would take 13.5 GiB, more than most lab GPUs hold.
            max_target_memory_mb: 4096,
        }
    }
}

/// Walls in one config by default: six for a closed CAVE, far more for a tiled wall.
pub const DEFAULT_MAX_WALLS: u32 = 64;

/// The gamepad (gilrs, hot-plug).
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize, JsonSchema)]
#[serde(default, deny_unknown_fields)]
pub struct GamepadSection {
    pub enabled: bool,
    /// `navigate` (move through the scene) or `head` (move the head in the CAVE).
    pub mode: GamepadMode,
    /// Radial stick dead zone, 0..1.
    #[schemars(range(min = 0.0, max = 0.9))]
    pub dead_zone: f32,
    /// Trigger dead zone, 0..1.
    #[schemars(range(min = 0.0, max = 0.9))]
    pub trigger_dead_zone: f32,
    /// Head speed at full stick (head mode), metres per second.
    #[schemars(range(min = 0.0, max = 10.0))]
    pub head_speed: f32,
    /// Button (Xbox label) → action, over the default map; "none" unbinds a button.
    #[serde(skip_serializing_if = "BTreeMap::is_empty")]
    pub buttons: BTreeMap<String, String>,
}

impl Default for GamepadSection {
    fn default() -> Self {
        let pad = GamepadSettings::default();
        Self {
            enabled: true,
            mode: pad.mode,
            dead_zone: pad.dead_zone,
            trigger_dead_zone: pad.trigger_dead_zone,
            head_speed: pad.head_speed,
            buttons: BTreeMap::new(),
        }
    }
}

/// Where the head starts (and how it is turned, for tracked stereo).
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize, JsonSchema)]
#[serde(default, deny_unknown_fields)]
pub struct HeadSection {
    /// CAVE metres.
    pub position: [f32; 3],
    #[schemars(range(min = -360.0, max = 360.0))]
    pub yaw_degrees: f32,
    #[schemars(range(min = -360.0, max = 360.0))]
    pub pitch_degrees: f32,
    #[schemars(range(min = -360.0, max = 360.0))]
    pub roll_degrees: f32,
}

impl Default for HeadSection {
    fn default() -> Self {
        Self {
            position: [0.0, 1.7, 0.0],
            yaw_degrees: 0.0,
            pitch_degrees: 0.0,
            roll_degrees: 0.0,
        }
    }
}

/// How the walls are rendered.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize, JsonSchema)]
#[serde(default, deny_unknown_fields)]
pub struct RenderSection {
    pub mode: RenderMode,
    /// Surface shading: "pbr" (glTF metallic-roughness with every map) or "simple" (the
    /// cheaper Blinn-Phong on base colour and emission).
    pub shading: Shading,
    /// MSAA sample count: 1 (off) or 4.
    pub msaa: u32,
    pub wireframe: bool,
    /// Clear colour, sRGB components in 0..1.
    pub background: [f32; 3],
}

impl Default for RenderSection {
    fn default() -> Self {
        Self {
            mode: RenderMode::Stereo,
            shading: Shading::Pbr,
            msaa: 4,
            wireframe: false,
            background: [0.02, 0.02, 0.03],
        }
    }
}

/// The scene and where the CAVE stands in it.
#[derive(Debug, Clone, Default, PartialEq, Deserialize, Serialize, JsonSchema)]
#[serde(default, deny_unknown_fields)]
pub struct SceneSection {
    /// glTF file; relative paths are relative to the config file's folder.
    pub path: Option<PathBuf>,
    /// Draw every material double-sided (no back-face culling), for content wound the wrong
    /// way (a model whose floor or walls vanish from inside).
    pub double_sided: bool,
    /// Where the model goes: "as-authored" (its own origin and units) or "floor" (its bounding
    /// box centred on the scene origin, standing on the floor: with the default placement,
    /// the middle of the CAVE's floor).
    pub fit: SceneFit,
    /// Scale the model uniformly so that its bounding box's largest side is this many metres
    /// (0: keep the file's units, metres in glTF).
    #[schemars(range(min = 0.0, max = 1e5))]
    pub size_m: f32,
    /// Then moved by this much (metres, scene space): e.g. [0, 0.9, -1] sets a model fitted
    /// to the floor on a 0.9 m table 1 m ahead of the CAVE's centre.
    pub offset_m: [f32; 3],
    /// Start at one of the file's cameras (its name, or its index in node order): the CAVE is
    /// placed so that the configured head stands at the camera, the front wall towards its
    /// view ("": the placement below).
    pub camera: String,
    pub world_from_cave: PlacementSection,
}

/// Where the CAVE stands in the scene: scene point = translation + yaw · scale · CAVE point.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize, JsonSchema)]
#[serde(default, deny_unknown_fields)]
pub struct PlacementSection {
    pub translation: [f32; 3],
    #[schemars(range(min = -360.0, max = 360.0))]
    pub yaw_degrees: f32,
    #[schemars(range(min = 1e-3, max = 1e3))]
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

/// Shadow maps from the lights (the config's and the scene file's; eight layers in all: a
/// directional or spot light takes one, a point light six).
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize, JsonSchema)]
#[serde(default, deny_unknown_fields)]
pub struct ShadowsSection {
    pub enabled: bool,
    /// Side of each shadow map, texels (memory: side² × 4 bytes × 8 layers, and side² × 4
    /// bytes for the filter's range tiles).
    #[schemars(range(min = 64, max = 4096))]
    pub map_size: u32,
    /// Look-ups move this many map texels along the surface normal (against shadow acne;
    /// larger detaches shadows from their casters).
    #[schemars(range(min = 0.0, max = 10.0))]
    pub normal_offset_texels: f32,
    /// 3×3 percentage-closer filtering: soft edges a texel or two wide.
    pub pcf: bool,
    /// The filter reads each 4×4-texel tile's depth range first and filters only where the
    /// point's depth lies within it: the same picture, a fraction of the look-ups (false:
    /// always filter).
    pub pcf_range_test: bool,
    /// Directional lights shadow this far around the CAVE, metres (a scene smaller than this
    /// is covered whole).
    #[schemars(range(min = 1.0, max = 10000.0))]
    pub distance_m: f32,
}

impl Default for ShadowsSection {
    fn default() -> Self {
        let d = crate::scene::shadows::ShadowSettings::default();
        Self {
            enabled: d.enabled,
            map_size: d.map_size,
            normal_offset_texels: d.normal_offset_texels,
            pcf: d.pcf,
            pcf_range_test: d.pcf_range_test,
            distance_m: d.distance_m,
        }
    }
}

/// The lights, in scene space.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize, JsonSchema)]
#[serde(default, deny_unknown_fields)]
pub struct LightingSection {
    /// Ambient light colour (linear).
    pub ambient: [f32; 3],
    pub directional: DirectionalLightSection,
    pub point: PointLightSection,
}

impl Default for LightingSection {
    fn default() -> Self {
        Self {
            ambient: [0.18, 0.18, 0.2],
            directional: DirectionalLightSection::default(),
            point: PointLightSection::default(),
        }
    }
}

#[derive(Debug, Clone, PartialEq, Deserialize, Serialize, JsonSchema)]
#[serde(default, deny_unknown_fields)]
pub struct DirectionalLightSection {
    /// Direction the light travels, in scene (world) space.
    pub direction: [f32; 3],
    pub color: [f32; 3],
    #[schemars(range(min = 0.0, max = 100.0))]
    pub intensity: f32,
    /// Casts shadows (when `[shadows] enabled`). A closed room's ceiling shadows the whole
    /// floor: there the sun is a fill light, false.
    pub cast_shadows: bool,
}

impl Default for DirectionalLightSection {
    fn default() -> Self {
        Self {
            direction: [-0.4, -1.0, -0.3],
            color: [1.0, 0.97, 0.9],
            intensity: 0.6,
            cast_shadows: true,
        }
    }
}

#[derive(Debug, Clone, PartialEq, Deserialize, Serialize, JsonSchema)]
#[serde(default, deny_unknown_fields)]
pub struct PointLightSection {
    /// Position in scene (world) space.
    pub position: [f32; 3],
    pub color: [f32; 3],
    #[schemars(range(min = 0.0, max = 100.0))]
    pub intensity: f32,
    /// Distance (metres) at which the light has faded to zero.
    #[schemars(range(min = 1e-3, max = 1e6))]
    pub range: f32,
    /// Casts shadows (when `[shadows] enabled`; six shadow-map layers).
    pub cast_shadows: bool,
}

impl Default for PointLightSection {
    fn default() -> Self {
        Self {
            position: [0.0, 2.4, 0.0],
            color: [1.0, 0.9, 0.75],
            intensity: 0.8,
            range: 12.0,
            cast_shadows: true,
        }
    }
}

/// One projection wall: a planar rectangle seen from inside, given one of three ways (in
/// `cave.wall_units`, with `cave.wall_up_axis` up): three corners; `centre` +
/// `yaw_pitch_roll_degrees` + `size` (nDisplay, CalVR); or `origin` (the lower-left corner) +
/// `horizontal_axis` + `vertical_axis` + `size` (Vrui).
#[derive(Debug, Clone, Default, PartialEq, Deserialize, Serialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct WallSection {
    /// 1–64 characters of a-z, A-Z, 0-9, '-' or '_' (it names output files).
    pub name: String,
    /// Corners (within ±100 km: the projection math is f32).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[schemars(inner(range(min = -1e5, max = 1e5)))]
    pub lower_left: Option<[f32; 3]>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[schemars(inner(range(min = -1e5, max = 1e5)))]
    pub lower_right: Option<[f32; 3]>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[schemars(inner(range(min = -1e5, max = 1e5)))]
    pub upper_left: Option<[f32; 3]>,
    /// The wall's centre (with `size`; `yaw_pitch_roll_degrees` default 0: a front wall).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub centre: Option<[f32; 3]>,
    /// Yaw about the up axis (+ turns left), pitch about the wall's horizontal edge (+ tilts
    /// its top towards the viewer: +90 is a ceiling, −90 a floor), roll about its normal,
    /// degrees. At 0 the wall faces the viewer as the
    /// front wall does (its right edge along +x).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[schemars(inner(range(min = -360.0, max = 360.0)))]
    pub yaw_pitch_roll_degrees: Option<[f32; 3]>,
    /// The lower-left corner (with `horizontal_axis`, `vertical_axis` and `size`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub origin: Option<[f32; 3]>,
    /// The direction of the lower edge, left to right (any length).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub horizontal_axis: Option<[f32; 3]>,
    /// The direction of the left edge, bottom to top (any length).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub vertical_axis: Option<[f32; 3]>,
    /// Width and height.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub size: Option<[f32; 2]>,
    /// Pixels (width, height).
    #[schemars(inner(range(min = 1, max = MAX_WALL_PIXELS)))]
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
    /// Stereo output format of this wall's window (default: `app.wall_output`), or one
    /// window per eye: `[[wall.output]]` tables with `eye = "left"` or `"right"` (a passive
    /// wall with a projector per eye).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub output: Option<WallOutput>,
    /// Cluster mode: the process (MPI rank) that renders and shows this wall; default 0, the
    /// master. Ignored outside cluster mode.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[schemars(range(min = 0, max = 1023))]
    pub node: Option<u32>,
}

impl WallSection {
    /// The stereo format of the wall's one window, if the file sets one.
    pub fn format(&self) -> Option<StereoFormat> {
        match &self.output {
            Some(WallOutput::Format(f)) => Some(*f),
            _ => None,
        }
    }

    /// Sets the format of the wall's one window (a wall with a window per eye keeps them).
    pub fn set_format(&mut self, format: StereoFormat) {
        if !matches!(self.output, Some(WallOutput::PerEye(_))) {
            self.output = Some(WallOutput::Format(format));
        }
    }

    /// The windows per eye, if the wall has them.
    pub fn eye_outputs(&self) -> &[EyeOutputSection] {
        match &self.output {
            Some(WallOutput::PerEye(o)) => o,
            _ => &[],
        }
    }
}

/// The scene's animation clock: which of the file's animations plays, and how. Skins and
/// morph targets are posed on the GPU before tessellation and the warp, so every wall and
/// eye shows the same instant, exactly; in a cluster the master's clock travels with each
/// frame.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize, JsonSchema)]
#[serde(default, deny_unknown_fields)]
pub struct AnimationSection {
    /// Pose the scene by its animation (off: every node at its rest transform).
    pub enabled: bool,
    /// The animation to play, by name ("": the file's first).
    pub clip: String,
    /// The clock runs (off: it holds `time_s`).
    pub playing: bool,
    /// Clock seconds per real second (negative plays backwards).
    #[schemars(range(min = -10.0, max = 10.0))]
    pub speed: f32,
    /// Start over at the end (off: hold the last pose).
    pub repeat: bool,
    /// The clock's time at start, seconds into the animation: `render` draws this instant.
    #[schemars(range(min = 0.0, max = 1000000.0))]
    pub time_s: f32,
}

impl Default for AnimationSection {
    fn default() -> Self {
        Self {
            enabled: true,
            clip: String::new(),
            playing: true,
            speed: 1.0,
            repeat: true,
            time_s: 0.0,
        }
    }
}

/// The panorama view (wide field of view up to 360°): the operator's overview of everything
/// around the CAVE user, or a desktop view on its own.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize, JsonSchema)]
#[serde(default, deny_unknown_fields)]
pub struct PanoramaSection {
    /// Show the panorama in the application (below the walls in the preview; beside the
    /// panel in CAVE mode's operator window).
    pub show: bool,
    pub projection: Projection,
    /// Horizontal field of view, degrees (up to what the projection shows).
    #[schemars(range(min = 1.0, max = 360.0))]
    pub h_fov_degrees: f32,
    /// Vertical field of view, degrees (up to what the projection shows).
    #[schemars(range(min = 1.0, max = 360.0))]
    pub v_fov_degrees: f32,
    /// "geometric" (per-vertex projection with pre-clip; equirectangular and Hammer) or
    /// "image" (cube map and inverse projection; every projection).
    pub route: PanoRoute,
    /// "mono", "volume" (VR'14: the projected volume seen by two eyes) or "omni"
    /// (omnidirectional stereo per vertex). Geometric route only.
    pub stereo: PanoStereoKind,
    /// Volume stereo: inter-ocular distance, viewing distance and zero-parallax depth, in
    /// normalised device units (VR'14's values).
    pub volume_ioid_d_offset: [f32; 3],
    /// Turn from the navigation direction, degrees, positive to the right.
    #[schemars(range(min = -360.0, max = 360.0))]
    pub yaw_degrees: f32,
    /// Image pixels (width, height).
    #[schemars(inner(range(min = 1, max = 8192)))]
    pub size: [u32; 2],
    /// Cube face pixels of the image route.
    #[schemars(range(min = 4, max = 8192))]
    pub cube_size: u32,
}

impl Default for PanoramaSection {
    fn default() -> Self {
        Self {
            show: false,
            projection: Projection::Equirectangular,
            h_fov_degrees: 360.0,
            v_fov_degrees: 180.0,
            route: PanoRoute::Geometric,
            stereo: PanoStereoKind::Mono,
            volume_ioid_d_offset: VOLUME_DEFAULT_PARAMS,
            yaw_degrees: 0.0,
            size: [1024, 512],
            cube_size: 512,
        }
    }
}

/// A monitor named in the config: by position in the system's list or by name.
#[derive(Debug, Clone, PartialEq, Eq, Deserialize, Serialize, JsonSchema)]
#[serde(untagged)]
pub enum MonitorRef {
    Index(usize),
    Name(String),
}

/// How the application shows the walls.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum AppMode {
    /// One borderless window per wall, on the monitors the config names.
    Cave,
    /// One window with the walls unfolded side by side and the panel docked.
    Preview,
}

crate::named_enum!(AppMode {
    Self::Cave => "cave",
    Self::Preview => "preview",
});

/// The interactive application (`omnicave run`): windows, panel, output formats.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize, JsonSchema)]
#[serde(default, deny_unknown_fields)]
pub struct AppSection {
    /// "cave" (a window per wall) or "preview" (one window, walls unfolded).
    pub mode: AppMode,
    /// Where the control panel goes in CAVE mode: "window" (its own operator window),
    /// "overlay:<wall>" (drawn over that wall's window) or "hidden".
    pub panel: String,
    /// Operator (or preview) window position, screen pixels; default: chosen by the system.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub window_position: Option<[i32; 2]>,
    /// Operator (or preview) window size in pixels.
    #[schemars(inner(range(min = 1, max = MAX_WALL_PIXELS)))]
    pub window_size: [u32; 2],
    /// Default stereo output format of the wall windows.
    pub wall_output: StereoFormat,
    /// Stereo output format of the preview's unfolded walls.
    pub preview_output: StereoFormat,
    /// Render the preview's walls at their configured resolution. Off (the default): each
    /// wall is rendered at the size it is shown in the preview (never larger than its
    /// resolution), which is what a laptop without a GPU can keep up with; the tessellation
    /// criteria and sky meshes then count the pixels shown.
    pub preview_full_resolution: bool,
    /// Wait for vertical blank (no tearing; caps the frame rate at the display's).
    pub vsync: bool,
    /// Navigation speed in the scene, metres per second (keyboard and gamepad).
    #[schemars(range(min = 0.0, max = 1000.0))]
    pub navigation_speed: f32,
}

impl Default for AppSection {
    fn default() -> Self {
        Self {
            mode: AppMode::Preview,
            panel: "window".into(),
            window_position: None,
            window_size: [1280, 720],
            wall_output: StereoFormat::FrameSequential,
            preview_output: StereoFormat::Anaglyph,
            preview_full_resolution: false,
            vsync: true,
            navigation_speed: 1.5,
        }
    }
}
