//! Everything the control panel, the keys and (later) the trackers change at run time, and the
//! frame parameters it gives the renderer. No windows and no GPU here, so tests drive it directly.

use std::path::{Path, PathBuf};

use glam::{Mat4, Quat, Vec3};

use crate::cave::omni::{OmniSettings, PoleMerge, WarpVariant};
use crate::cave::{Cave, Head, RenderMode};
use crate::config::{Config, ConfigFile};
use crate::gamepad::GamepadMode;
use crate::output::formats::StereoFormat;
use crate::pano::{PanoSettings, PanoStereo};
use crate::render::{FrameParams, RenderSettings};
use crate::sky::{SkyMode, SkySettings};
use crate::tess::{Criterion, MAX_DEPTH_LIMIT, TessSettings};
use crate::tracking::{HeadPose, OneEuroParams};

/// The kind of tessellation criterion the panel offers; its parameter is kept separately so
/// switching kinds and back keeps each value.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CriterionKind {
    Uniform,
    Edge,
    Sphere,
    Error,
}

impl CriterionKind {
    pub const ALL: [CriterionKind; 4] = [Self::Uniform, Self::Edge, Self::Sphere, Self::Error];

    pub fn name(self) -> &'static str {
        match self {
            Self::Uniform => "uniform (levels)",
            Self::Edge => "edge length (px)",
            Self::Sphere => "sphere diameter (px)",
            Self::Error => "warp error (px)",
        }
    }

    fn of(c: Criterion) -> (Self, f32) {
        match c {
            Criterion::Uniform(n) => (Self::Uniform, n as f32),
            Criterion::Edge(px) => (Self::Edge, px),
            Criterion::Sphere(px) => (Self::Sphere, px),
            Criterion::Error(px) => (Self::Error, px),
        }
    }

    /// The parameter's sensible range for a slider.
    pub fn range(self) -> std::ops::RangeInclusive<f32> {
        match self {
            Self::Uniform => 0.0..=MAX_DEPTH_LIMIT as f32,
            Self::Edge | Self::Sphere => 1.0..=200.0,
            Self::Error => 0.05..=20.0,
        }
    }
}

/// Where the user has navigated to in the scene (moves the CAVE through the world).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Navigation {
    /// Scene-space offset of the CAVE's origin, metres.
    pub position: Vec3,
    /// Turn about +y, radians (positive turns left).
    pub yaw: f32,
}

/// One step of navigation input, each axis in −1..1 (stick or keys).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct NavInput {
    /// +1 moves towards the front wall.
    pub forward: f32,
    /// +1 moves to the right.
    pub right: f32,
    /// +1 moves up.
    pub up: f32,
    /// +1 turns left.
    pub turn: f32,
}

/// Keyboard (and later gamepad) actions that change the state.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Action {
    SetMode(RenderMode),
    ToggleTessellation,
    CycleSky,
    ToggleWireframe,
    TogglePoleMerge,
    CycleWarp,
    /// Next output format of every wall window (CAVE mode) or of the preview.
    CycleOutput,
    SwapEyes,
    /// Change the eye separation by this many metres.
    EyeSeparation(f32),
    /// Next (+1) or previous (−1) render mode.
    StepMode(i32),
    /// Multiply the navigation speed by this factor.
    ScaleNavigationSpeed(f32),
    ToggleGamepadMode,
    ToggleTracking,
    /// Move the head by this many metres in CAVE space.
    MoveHead(Vec3),
    ResetView,
    ToggleHelp,
    TogglePanel,
    Save,
    Quit,
}

/// The live settings of the application.
#[derive(Debug, Clone)]
pub struct AppState {
    /// The config the run started from (saving writes changes over its text).
    pub config: Config,
    pub mode: RenderMode,
    pub eye_separation: f32,
    pub head_position: Vec3,
    /// Head yaw in degrees (tracked-stereo).
    pub head_yaw_degrees: f32,
    pub warp: WarpVariant,
    pub pole_merge_on: bool,
    pub pole_merge: PoleMerge,
    pub tess_on: bool,
    pub tess_kind: CriterionKind,
    /// Parameter of each criterion kind, indexed as `CriterionKind::ALL`.
    pub tess_values: [f32; 4],
    pub tess_max_depth: u32,
    pub tess_backface_cull: bool,
    pub tess_frustum_cull: bool,
    pub sky_mode: SkyMode,
    pub wireframe: bool,
    pub msaa: u32,
    /// Width (x), height (y) and depth (z) of the walls' bounding box, metres.
    pub cave_size: Vec3,
    pub navigation: Navigation,
    /// Output format of each wall's window (CAVE mode).
    pub wall_outputs: Vec<StereoFormat>,
    pub preview_output: StereoFormat,
    pub swap_eyes: bool,
    pub show_help: bool,
    pub show_panel: bool,
    /// Navigation speed, metres per second (keys and gamepad).
    pub navigation_speed: f32,
    /// Whether OSC head tracking moves the head.
    pub tracking_on: bool,
    /// Whether the One Euro filter smooths the tracked head, and its parameters.
    pub tracking_filter_on: bool,
    pub tracking_filter: OneEuroParams,
    /// The tracked head orientation (used by tracked-stereo while tracking is on).
    pub tracked_orientation: Option<Quat>,
    /// What the gamepad's sticks drive.
    pub gamepad_mode: GamepadMode,
    /// The panorama view: shown or not, and its settings.
    pub panorama_on: bool,
    pub panorama: PanoSettings,
    /// The volume stereo's parameters as configured (the panel's choice of "volume" uses
    /// them).
    pub panorama_volume: [f32; 3],
    pub quit_requested: bool,
    pub save_requested: bool,
    /// Where "save" writes.
    pub save_path: PathBuf,
    /// The walls as configured, and the reference point sizes are scaled about.
    base_cave: Cave,
    base_size: Vec3,
    scale_origin: Vec3,
    /// The walls at `cave_size` (rebuilt when it changes).
    cave: Cave,
}

/// Smallest CAVE side the panel accepts (a wall cannot shrink to nothing).
const MIN_CAVE_SIDE_M: f32 = 0.5;
/// The head is kept this far inside the walls when they move.
const HEAD_MARGIN_M: f32 = 0.05;

impl AppState {
    pub fn new(config: Config) -> Self {
        let (min, max) = Cave::bounding_box(&config.cave.walls);
        let base_size = max - min;
        let scale_origin = Vec3::new((min.x + max.x) / 2.0, min.y, (min.z + max.z) / 2.0);
        let (tess_kind, value) = config
            .tess
            .criterion
            .map_or((CriterionKind::Error, 0.5), CriterionKind::of);
        let mut tess_values = [3.0, 8.0, 8.0, 0.5];
        if let Some(i) = CriterionKind::ALL.iter().position(|k| *k == tess_kind) {
            tess_values[i] = value;
        }
        let save_path = default_save_path(&config.source);
        Self {
            mode: config.mode,
            eye_separation: config.eye_separation,
            head_position: config.head.position,
            head_yaw_degrees: yaw_degrees(config.head.orientation),
            warp: config.omni.warp,
            pole_merge_on: config.omni.pole_merge.is_some(),
            pole_merge: config.omni.pole_merge.unwrap_or_default(),
            tess_on: config.tess.criterion.is_some(),
            tess_kind,
            tess_values,
            tess_max_depth: config.tess.max_depth,
            tess_backface_cull: config.tess.backface_cull,
            tess_frustum_cull: config.tess.frustum_cull,
            sky_mode: config.sky.mode,
            wireframe: config.wireframe,
            msaa: config.msaa,
            cave_size: base_size,
            navigation: Navigation::default(),
            wall_outputs: config.app.walls.iter().map(|w| w.output).collect(),
            preview_output: config.app.preview_output,
            swap_eyes: false,
            show_help: false,
            show_panel: true,
            navigation_speed: config.app.navigation_speed,
            tracking_on: config.tracking.enabled,
            tracking_filter_on: config.tracking.settings.filter.is_some(),
            tracking_filter: config.tracking.settings.filter.unwrap_or_default(),
            tracked_orientation: None,
            gamepad_mode: config.gamepad.mode,
            panorama_on: config.file.panorama.show,
            panorama: config.panorama,
            panorama_volume: config.file.panorama.volume_ioid_d_offset,
            quit_requested: false,
            save_requested: false,
            save_path,
            base_cave: config.cave.clone(),
            base_size,
            scale_origin,
            cave: config.cave.clone(),
            config,
        }
    }

    /// The walls as they are now (moved by `cave_size`).
    pub fn cave(&self) -> &Cave {
        &self.cave
    }

    /// The configured size of the walls' bounding box.
    pub fn base_cave_size(&self) -> Vec3 {
        self.base_size
    }

    /// Moves the walls to a new bounding-box size (scaled about the floor's centre), keeping the
    /// head inside. Axes the CAVE has no extent in (one flat wall) stay as they are.
    pub fn set_cave_size(&mut self, size: Vec3) {
        let size = size.max(Vec3::splat(MIN_CAVE_SIDE_M));
        let scale = Vec3::select(
            self.base_size.cmpgt(Vec3::splat(1e-6)),
            size / self.base_size.max(Vec3::splat(1e-6)),
            Vec3::ONE,
        );
        let o = self.scale_origin;
        let map = |p: Vec3| o + (p - o) * scale;
        let mut cave = self.base_cave.clone();
        for wall in &mut cave.walls {
            wall.lower_left = map(wall.lower_left);
            wall.lower_right = map(wall.lower_right);
            wall.upper_left = map(wall.upper_left);
        }
        cave.projection_centre = map(cave.projection_centre);
        self.cave = cave;
        self.cave_size = Vec3::select(
            self.base_size.cmpgt(Vec3::splat(1e-6)),
            size,
            self.base_size,
        );
        // The head was valid before; if the moved walls exclude it, it stays where it was.
        let _ = self.set_head_position(self.head_position);
    }

    /// Where the head may be: the walls' bounding box less a margin (flat axes, as of a single
    /// wall, are unbounded).
    pub fn head_bounds(&self) -> (Vec3, Vec3) {
        let (min, max) = Cave::bounding_box(&self.cave.walls);
        let margin = Vec3::splat(HEAD_MARGIN_M);
        let mut lo = min + margin;
        let mut hi = (max - margin).max(lo);
        for axis in 0..3 {
            if max[axis] - min[axis] <= 2.0 * HEAD_MARGIN_M {
                lo[axis] = f32::NEG_INFINITY;
                hi[axis] = f32::INFINITY;
            }
        }
        (lo, hi)
    }

    /// Sets the head, kept inside the walls' bounding box; a position behind a wall (a CAVE
    /// that is not a box) is refused with the reason, and the head stays.
    pub fn set_head_position(&mut self, p: Vec3) -> Result<(), String> {
        let (lo, hi) = self.head_bounds();
        let p = if p.is_finite() { p } else { self.head_position };
        let p = p.clamp(lo, hi);
        match self.cave.head_problem(p) {
            None => {
                self.head_position = p;
                Ok(())
            }
            Some(problem) => Err(problem),
        }
    }

    /// Applies a pose from the tracker (the position is refused, with the reason, if it is
    /// behind a wall; the orientation is taken either way).
    pub fn apply_tracked_pose(&mut self, pose: HeadPose) -> Result<(), String> {
        if let Some(q) = pose.orientation.filter(|q| q.is_finite()) {
            self.tracked_orientation = Some(q);
        }
        self.set_head_position(pose.position)
    }

    /// The tracker's filter parameters as the panel has them (`None`: off).
    pub fn tracking_filter(&self) -> Option<OneEuroParams> {
        self.tracking_filter_on.then_some(self.tracking_filter)
    }

    /// The head's pose (the panel's yaw turns the configured orientation, keeping its pitch
    /// and roll).
    pub fn head(&self) -> Head {
        if self.tracking_on
            && let Some(orientation) = self.tracked_orientation
        {
            return Head {
                position: self.head_position,
                orientation,
            };
        }
        let base_yaw = yaw_degrees(self.config.head.orientation);
        let turn = Quat::from_rotation_y((self.head_yaw_degrees - base_yaw).to_radians());
        Head {
            position: self.head_position,
            orientation: turn * self.config.head.orientation,
        }
    }

    /// The active tessellation criterion, if tessellation is on.
    pub fn criterion(&self) -> Option<Criterion> {
        if !self.tess_on {
            return None;
        }
        let index = CriterionKind::ALL
            .iter()
            .position(|k| *k == self.tess_kind)
            .unwrap_or(3);
        let range = self.tess_kind.range();
        let v = self.tess_values[index].clamp(*range.start(), *range.end());
        Some(match self.tess_kind {
            CriterionKind::Uniform => Criterion::Uniform(v.round() as u32),
            CriterionKind::Edge => Criterion::Edge(v),
            CriterionKind::Sphere => Criterion::Sphere(v),
            CriterionKind::Error => Criterion::Error(v),
        })
    }

    /// The parameter of the current criterion kind (for the panel's slider).
    pub fn tess_value_mut(&mut self) -> &mut f32 {
        let index = CriterionKind::ALL
            .iter()
            .position(|k| *k == self.tess_kind)
            .unwrap_or(3);
        &mut self.tess_values[index]
    }

    pub fn omni(&self) -> OmniSettings {
        let mut merge = self.pole_merge;
        merge.start_degrees = merge.start_degrees.clamp(0.0, 90.0);
        merge.end_degrees = merge.end_degrees.clamp(merge.start_degrees, 90.0);
        OmniSettings {
            warp: self.warp,
            pole_merge: self.pole_merge_on.then_some(merge),
        }
    }

    /// Where the CAVE stands in the scene: the config's placement moved by navigation.
    pub fn world_from_cave(&self) -> Mat4 {
        Mat4::from_translation(self.navigation.position)
            * Mat4::from_rotation_y(self.navigation.yaw)
            * self.config.world_from_cave
    }

    /// The renderer's parameters for this frame.
    pub fn frame_params(&self) -> FrameParams<'_> {
        FrameParams {
            cave: &self.cave,
            head: self.head(),
            mode: self.mode,
            eye_separation: self.eye_separation,
            world_from_cave: self.world_from_cave(),
            lighting: self.config.lighting,
            background: self.config.background,
            omni: self.omni(),
            tess: TessSettings {
                criterion: self.criterion(),
                max_depth: self.tess_max_depth.min(MAX_DEPTH_LIMIT),
                backface_cull: self.tess_backface_cull,
                frustum_cull: self.tess_frustum_cull,
            },
            sky: SkySettings {
                mode: self.sky_mode,
                ..self.config.sky
            },
        }
    }

    /// Settings that change pipelines or targets.
    pub fn render_settings(&self) -> RenderSettings {
        RenderSettings {
            msaa: self.msaa,
            wireframe: self.wireframe,
        }
    }

    /// Moves through the scene for `dt` seconds of `input` at the configured speed.
    pub fn navigate(&mut self, input: NavInput, dt: f32) {
        if !(dt.is_finite() && dt > 0.0) {
            return;
        }
        let speed = self.navigation_speed;
        let nav = &mut self.navigation;
        nav.yaw += input.turn.clamp(-1.0, 1.0) * TURN_RATE * dt;
        let rotation = Quat::from_rotation_y(nav.yaw);
        let step = Vec3::new(
            input.right.clamp(-1.0, 1.0),
            input.up.clamp(-1.0, 1.0),
            -input.forward.clamp(-1.0, 1.0),
        ) * speed
            * dt;
        nav.position += rotation * step;
    }

    /// Turns by a mouse movement (radians).
    pub fn turn(&mut self, radians: f32) {
        if radians.is_finite() {
            self.navigation.yaw += radians;
        }
    }

    /// Applies a key or gamepad action.
    pub fn apply(&mut self, action: Action) {
        match action {
            Action::SetMode(mode) => self.mode = mode,
            Action::ToggleTessellation => self.tess_on = !self.tess_on,
            Action::CycleSky => {
                let i = SkyMode::ALL.iter().position(|m| *m == self.sky_mode);
                self.sky_mode = SkyMode::ALL[i.map_or(0, |i| (i + 1) % SkyMode::ALL.len())];
            }
            Action::ToggleWireframe => self.wireframe = !self.wireframe,
            Action::TogglePoleMerge => self.pole_merge_on = !self.pole_merge_on,
            Action::CycleWarp => {
                let i = WarpVariant::ALL.iter().position(|w| *w == self.warp);
                self.warp = WarpVariant::ALL[i.map_or(0, |i| (i + 1) % WarpVariant::ALL.len())];
            }
            Action::CycleOutput => {
                let next = |f: StereoFormat| {
                    let i = StereoFormat::ALL.iter().position(|g| *g == f);
                    StereoFormat::ALL[i.map_or(0, |i| (i + 1) % StereoFormat::ALL.len())]
                };
                self.preview_output = next(self.preview_output);
                for f in &mut self.wall_outputs {
                    *f = next(*f);
                }
            }
            Action::SwapEyes => self.swap_eyes = !self.swap_eyes,
            Action::StepMode(step) => {
                let n = RenderMode::ALL.len() as i32;
                let i = RenderMode::ALL
                    .iter()
                    .position(|m| *m == self.mode)
                    .unwrap_or(0) as i32;
                self.mode = RenderMode::ALL[(i + step).rem_euclid(n) as usize];
            }
            Action::ScaleNavigationSpeed(factor) => {
                if factor.is_finite() && factor > 0.0 {
                    self.navigation_speed = (self.navigation_speed * factor)
                        .clamp(MIN_NAVIGATION_SPEED, MAX_NAVIGATION_SPEED);
                }
            }
            Action::ToggleGamepadMode => {
                self.gamepad_mode = match self.gamepad_mode {
                    GamepadMode::Navigate => GamepadMode::Head,
                    GamepadMode::Head => GamepadMode::Navigate,
                }
            }
            Action::ToggleTracking => self.tracking_on = !self.tracking_on,
            Action::EyeSeparation(delta) => {
                self.eye_separation = (self.eye_separation + delta).clamp(0.0, MAX_EYE_SEPARATION)
            }
            Action::MoveHead(delta) => {
                // A step behind a wall is not taken.
                let _ = self.set_head_position(self.head_position + delta);
            }
            Action::ResetView => {
                self.navigation = Navigation::default();
                self.navigation_speed = self.config.app.navigation_speed;
                // The configured head was validated at load.
                let _ = self.set_head_position(self.config.head.position);
            }
            Action::ToggleHelp => self.show_help = !self.show_help,
            Action::TogglePanel => self.show_panel = !self.show_panel,
            Action::Save => self.save_requested = true,
            Action::Quit => self.quit_requested = true,
        }
    }

    /// The config file with the current settings written over the loaded one.
    pub fn to_config_file(&self, target: &Path) -> ConfigFile {
        let mut file = self.config.file.clone();
        file.cave.eye_separation = self.eye_separation;
        file.cave.projection_centre = Some(self.cave.projection_centre.to_array());
        file.head.position = self.head_position.to_array();
        file.head.yaw_degrees = self.head_yaw_degrees;
        file.render.mode = self.mode;
        file.render.msaa = self.msaa;
        file.render.wireframe = self.wireframe;
        file.omnistereo.warp = self.warp;
        file.omnistereo.pole_merge = self.pole_merge_on;
        let omni = self.omni();
        let merge = omni.pole_merge.unwrap_or(self.pole_merge);
        file.omnistereo.pole_merge_start_degrees = merge.start_degrees;
        file.omnistereo.pole_merge_end_degrees = merge.end_degrees;
        file.tessellation.criterion = self.criterion();
        file.tessellation.max_depth = self.tess_max_depth;
        file.tessellation.backface_cull = self.tess_backface_cull;
        file.tessellation.frustum_cull = self.tess_frustum_cull;
        file.skybox.mode = self.sky_mode;
        file.app.preview_output = self.preview_output;
        file.app.navigation_speed = self.navigation_speed;
        file.tracking.enabled = self.tracking_on;
        file.tracking.filter.enabled = self.tracking_filter_on;
        file.tracking.filter.min_cutoff_hz = self.tracking_filter.min_cutoff_hz;
        file.tracking.filter.beta = self.tracking_filter.beta;
        file.tracking.filter.derivative_cutoff_hz = self.tracking_filter.derivative_cutoff_hz;
        file.gamepad.mode = self.gamepad_mode;
        let pano = &self.panorama;
        file.panorama.show = self.panorama_on;
        file.panorama.projection = pano.projection;
        file.panorama.h_fov_degrees = pano.h_fov.to_degrees();
        file.panorama.v_fov_degrees = pano.v_fov.to_degrees();
        file.panorama.route = pano.route;
        file.panorama.stereo = pano.stereo.kind();
        if let PanoStereo::Volume { ioid, d, offset } = pano.stereo {
            file.panorama.volume_ioid_d_offset = [ioid, d, offset];
        }
        file.panorama.yaw_degrees = pano.yaw.to_degrees();
        for ((section, wall), output) in file
            .walls
            .iter_mut()
            .zip(&self.cave.walls)
            .zip(&self.wall_outputs)
        {
            section.lower_left = wall.lower_left.to_array();
            section.lower_right = wall.lower_right.to_array();
            section.upper_left = wall.upper_left.to_array();
            section.output = Some(*output);
        }
        // Relative paths were relative to the loaded file; keep them valid from the new one.
        let source_dir = self.config.source.parent().unwrap_or(Path::new("."));
        let target_dir = target.parent().unwrap_or(Path::new("."));
        if !same_dir(source_dir, target_dir) {
            let absolute = |p: &PathBuf| {
                if p.is_absolute() || p.as_os_str() == "none" {
                    p.clone()
                } else {
                    std::path::absolute(source_dir.join(p)).unwrap_or_else(|_| source_dir.join(p))
                }
            };
            file.scene.path = file.scene.path.as_ref().map(absolute);
            file.skybox.file = file.skybox.file.as_ref().map(absolute);
        }
        file
    }

    /// Writes the current settings to `path` as a config that loads back to this state.
    pub fn save(&self, path: &Path) -> Result<(), SaveError> {
        let file = self.to_config_file(path);
        let text = toml::to_string_pretty(&file).map_err(|e| SaveError::Encode {
            path: path.to_owned(),
            message: e.to_string(),
        })?;
        // Refuse to write what would not load back.
        file.validate(path).map_err(|e| SaveError::Encode {
            path: path.to_owned(),
            message: e.to_string(),
        })?;
        let header = format!(
            "# Saved by omnicave from the control panel (based on {}).\n\n",
            self.config.source.display()
        );
        std::fs::write(path, header + &text).map_err(|source| SaveError::Write {
            path: path.to_owned(),
            source,
        })
    }
}

/// Navigation speed limits (bumpers and panel), metres per second.
pub const MIN_NAVIGATION_SPEED: f32 = 0.05;
pub const MAX_NAVIGATION_SPEED: f32 = 200.0;

/// Largest eye separation the panel and keys allow, metres.
pub const MAX_EYE_SEPARATION: f32 = 0.2;
/// Turning speed for full stick or key deflection, radians per second.
const TURN_RATE: f32 = 1.2;

/// Saving the settings failed.
#[derive(Debug, thiserror::Error)]
pub enum SaveError {
    #[error("cannot write config {path}: {source}")]
    Write {
        path: PathBuf,
        source: std::io::Error,
    },
    #[error("cannot save config {path}: {message}")]
    Encode { path: PathBuf, message: String },
}

fn same_dir(a: &Path, b: &Path) -> bool {
    let canon = |p: &Path| {
        let p = if p.as_os_str().is_empty() {
            Path::new(".")
        } else {
            p
        };
        std::fs::canonicalize(p).ok()
    };
    match (canon(a), canon(b)) {
        (Some(a), Some(b)) => a == b,
        _ => false,
    }
}

/// `cave.toml` → `cave.saved.toml` beside it.
fn default_save_path(source: &Path) -> PathBuf {
    let stem = source
        .file_stem()
        .map_or_else(|| "omnicave".into(), |s| s.to_string_lossy().into_owned());
    source.with_file_name(format!("{stem}.saved.toml"))
}

fn yaw_degrees(q: Quat) -> f32 {
    let forward = q * Vec3::NEG_Z;
    // + 0.0 turns −0 into 0 for display.
    (-forward.x).atan2(-forward.z).to_degrees() + 0.0
}
