//! Everything the control panel, the keys and (later) the trackers change at run time, and the
//! frame parameters it gives the renderer. No windows and no GPU here, so tests drive it directly.

use std::path::{Path, PathBuf};

use glam::{Mat4, Quat, Vec3};

use crate::cave::omni::{OmniSettings, WarpVariant};
use crate::cave::wand::WandRay;
use crate::cave::{Cave, Head, RenderMode};
use crate::config::{Config, ConfigFile, WallSection};
use crate::gamepad::GamepadMode;
use crate::output::formats::StereoFormat;
use crate::render::{FrameParams, RenderSettings};
use crate::setup;
use crate::sky::SkyMode;
use crate::tess::{Criterion, MAX_DEPTH_LIMIT};
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

    /// Position in [`Self::ALL`].
    fn index(self) -> usize {
        Self::ALL.iter().position(|k| *k == self).unwrap_or(3)
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
    /// Write every wall's eye images and the settings to the screenshot folder.
    Screenshot,
    Quit,
}

/// The tracked wand's pose, CAVE space.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WandPose {
    pub position: Vec3,
    pub orientation: Quat,
}

/// The panel's floor map of where guests may stand: shown or not, and which metric.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GuestMapView {
    pub show: bool,
    pub metric: crate::guests::heatmap::Metric,
}

impl Default for GuestMapView {
    fn default() -> Self {
        Self {
            show: false,
            metric: crate::guests::heatmap::Metric::Vertical,
        }
    }
}

/// The application's state: the live settings (the config file's model, edited by the panel,
/// keys, buttons and trackers, and saved as it is) and what only a running application has
/// (navigation, the moved walls, the tracked orientation, requests).
#[derive(Debug, Clone)]
pub struct AppState {
    /// The config the run started from (derived set-up: windows, tracking, the base walls).
    pub config: Config,
    /// The live settings. Everything here is saved by "Save settings" and loads back as is.
    pub settings: ConfigFile,
    /// The panel's criterion kind and the parameter it keeps for each kind (indexed as
    /// `CriterionKind::ALL`), so switching kinds, or tessellation off and on, keeps them.
    pub tess_kind: CriterionKind,
    tess_values: [f32; 4],
    pub navigation: Navigation,
    /// The tracked head orientation (used by tracked-stereo while tracking is on).
    pub tracked_orientation: Option<Quat>,
    pub swap_eyes: bool,
    pub show_help: bool,
    /// The panel's guest map.
    pub guest_map: GuestMapView,
    /// The animation clock, seconds from the animation's start (wrapped or held per frame
    /// by the pose, as `[animation] repeat` says); in a cluster, the master's.
    pub animation_clock: f64,
    pub show_panel: bool,
    pub quit_requested: bool,
    pub save_requested: bool,
    /// A screenshot was asked for (taken after this frame is rendered).
    pub screenshot_requested: bool,
    /// The tracked wand's pose, CAVE space (`None`: no wand, or lost).
    pub wand: Option<WandPose>,
    /// A pick along the wand's ray was asked for (answered with the scene in the next frame).
    pub select_requested: bool,
    /// Where "save" writes.
    pub save_path: PathBuf,
    /// Width (x), height (y) and depth (z) of the walls' bounding box, metres.
    pub cave_size: Vec3,
    /// The walls as configured, and the reference point sizes are scaled about.
    base_cave: Cave,
    base_size: Vec3,
    scale_origin: Vec3,
    /// The walls at `cave_size` (rebuilt when it changes).
    cave: Cave,
    /// Bumped whenever `cave` is rebuilt.
    cave_generation: u64,
    /// The preview's walls on screen, pixels (empty outside the preview).
    shown_sizes: Vec<[u32; 2]>,
    /// The walls as rendered when that differs from `cave` (the preview's walls at the size
    /// shown), with the `cave_generation` it was made from.
    render_cave: Option<(Cave, u64)>,
}

/// Smallest side a preview wall is rendered at, pixels (a wall squeezed to a sliver).
const MIN_SHOWN_SIDE: u32 = 16;

/// Smallest CAVE side the panel accepts (a wall cannot shrink to nothing).
const MIN_CAVE_SIDE_M: f32 = 0.5;

impl AppState {
    pub fn new(config: Config) -> Self {
        let (min, max) = Cave::bounding_box(&config.cave.walls);
        let base_size = max - min;
        let scale_origin = Vec3::new((min.x + max.x) / 2.0, min.y, (min.z + max.z) / 2.0);
        let (tess_kind, value) = config
            .settings
            .tessellation
            .criterion
            .map_or((CriterionKind::Error, 0.5), CriterionKind::of);
        let mut tess_values = [3.0, 8.0, 8.0, 0.5];
        if let Some(i) = CriterionKind::ALL.iter().position(|k| *k == tess_kind) {
            tess_values[i] = value;
        }
        Self {
            settings: config.settings.clone(),
            tess_kind,
            tess_values,
            navigation: Navigation::default(),
            tracked_orientation: None,
            swap_eyes: false,
            show_help: false,
            guest_map: GuestMapView::default(),
            animation_clock: f64::from(config.settings.animation.time_s),
            show_panel: true,
            quit_requested: false,
            save_requested: false,
            screenshot_requested: false,
            wand: None,
            select_requested: false,
            save_path: default_save_path(&config.source),
            cave_size: base_size,
            base_cave: config.cave.clone(),
            base_size,
            scale_origin,
            cave: config.cave.clone(),
            cave_generation: 0,
            shown_sizes: Vec::new(),
            render_cave: None,
            config,
        }
    }

    /// The walls as rendered: `cave()`, except in the preview, where each wall is rendered
    /// at the size it is shown (never above its resolution) unless
    /// `app.preview_full_resolution` is set.
    pub fn render_cave(&self) -> &Cave {
        self.render_cave.as_ref().map_or(&self.cave, |(c, _)| c)
    }

    /// The preview window's latest layout of the walls (each one's size on screen); brings
    /// the rendered walls up to date (nothing is allocated unless a size changed).
    pub fn set_shown_sizes(&mut self, sizes: &[[u32; 2]]) {
        if self.shown_sizes != sizes {
            self.shown_sizes.clear();
            self.shown_sizes.extend_from_slice(sizes);
        }
        self.refresh_render_cave();
    }

    /// The resolution wall `i` is rendered at.
    fn render_resolution(&self, i: usize) -> [u32; 2] {
        let full = self.cave.walls.get(i).map_or([1, 1], |w| w.resolution);
        match self.shown_sizes.get(i) {
            Some(&[w, h])
                if !self.settings.app.preview_full_resolution
                    && u64::from(w) * u64::from(h) < u64::from(full[0]) * u64::from(full[1]) =>
            {
                [w.max(MIN_SHOWN_SIDE), h.max(MIN_SHOWN_SIDE)]
            }
            _ => full,
        }
    }

    fn refresh_render_cave(&mut self) {
        let current = self.render_cave();
        let up_to_date = self
            .render_cave
            .as_ref()
            .is_none_or(|(_, g)| *g == self.cave_generation)
            && current.walls.len() == self.cave.walls.len()
            && (0..current.walls.len())
                .all(|i| current.walls[i].resolution == self.render_resolution(i));
        if up_to_date {
            return;
        }
        let resolutions: Vec<[u32; 2]> = (0..self.cave.walls.len())
            .map(|i| self.render_resolution(i))
            .collect();
        if resolutions
            .iter()
            .zip(&self.cave.walls)
            .all(|(r, w)| *r == w.resolution)
        {
            self.render_cave = None;
            return;
        }
        let mut cave = self.cave.clone();
        for (wall, r) in cave.walls.iter_mut().zip(resolutions) {
            wall.resolution = r;
        }
        self.render_cave = Some((cave, self.cave_generation));
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
        let frame = self.settings.cave.wall_frame();
        let in_file = |p: Vec3| Some(frame.from_cave(p.as_dvec3()).as_vec3().to_array());
        for (wall, section) in cave.walls.iter_mut().zip(&mut self.settings.walls) {
            wall.lower_left = map(wall.lower_left);
            wall.lower_right = map(wall.lower_right);
            wall.upper_left = map(wall.upper_left);
            // A resized wall is saved as corners, in the file's units and axes.
            *section = WallSection {
                lower_left: in_file(wall.lower_left),
                lower_right: in_file(wall.lower_right),
                upper_left: in_file(wall.upper_left),
                centre: None,
                yaw_pitch_roll_degrees: None,
                origin: None,
                horizontal_axis: None,
                vertical_axis: None,
                size: None,
                ..std::mem::take(section)
            };
        }
        cave.projection_centre = map(cave.projection_centre);
        self.settings.cave.projection_centre = Some(cave.projection_centre.to_array());
        self.cave = cave;
        self.cave_generation += 1;
        self.refresh_render_cave();
        self.cave_size = Vec3::select(
            self.base_size.cmpgt(Vec3::splat(1e-6)),
            size,
            self.base_size,
        );
        // The head was valid before; if the moved walls exclude it, it stays where it was.
        let _ = self.set_head_position(self.head_position());
    }

    /// Where the head is (CAVE metres).
    pub fn head_position(&self) -> Vec3 {
        Vec3::from(self.settings.head.position)
    }

    /// Where the head may be: the walls' bounding box less a margin (flat axes, as of a single
    /// wall, are unbounded).
    pub fn head_bounds(&self) -> (Vec3, Vec3) {
        Cave::head_bounds(&self.cave.walls)
    }

    /// Sets the head, kept inside the walls' bounding box; a position behind a wall (a CAVE
    /// that is not a box) is refused with the reason, and the head stays.
    pub fn set_head_position(&mut self, p: Vec3) -> Result<(), String> {
        let (lo, hi) = self.head_bounds();
        let p = if p.is_finite() {
            p
        } else {
            self.head_position()
        };
        let p = p.clamp(lo, hi);
        match self.cave.head_problem(p) {
            None => {
                self.settings.head.position = p.to_array();
                Ok(())
            }
            Some(problem) => Err(problem),
        }
    }

    /// Applies a pose from the tracker (the position is refused, with the reason, if it is
    /// behind a wall; the orientation is taken either way).
    pub fn apply_tracked_pose(&mut self, pose: HeadPose) -> Result<(), String> {
        // The pose's own orientation: one from an earlier packet is not carried forward (a
        // position-only tracker leaves the settings' yaw, pitch and roll).
        self.tracked_orientation = pose.orientation.filter(|q| q.is_finite());
        self.set_head_position(pose.position)
    }

    /// The tracker's filter parameters as the panel has them (`None`: off).
    pub fn tracking_filter(&self) -> Option<OneEuroParams> {
        self.settings.tracking_filter()
    }

    /// The head's pose: the tracked orientation while tracking drives it, else the settings'
    /// yaw, pitch and roll.
    pub fn head(&self) -> Head {
        if self.settings.tracking.enabled
            && let Some(orientation) = self.tracked_orientation
        {
            return Head {
                position: self.head_position(),
                orientation,
            };
        }
        self.settings.head()
    }

    /// The active tessellation criterion, if tessellation is on.
    pub fn criterion(&self) -> Option<Criterion> {
        self.settings.tessellation.criterion
    }

    /// Whether adaptive tessellation is on.
    pub fn tess_on(&self) -> bool {
        self.settings.tessellation.criterion.is_some()
    }

    /// Switches tessellation on (with the panel's kind and parameter) or off.
    pub fn set_tess_on(&mut self, on: bool) {
        self.settings.tessellation.criterion = on.then(|| self.chosen_criterion());
    }

    /// The criterion of the panel's kind and parameter.
    fn chosen_criterion(&self) -> Criterion {
        let range = self.tess_kind.range();
        let v = self.tess_values[self.tess_kind.index()].clamp(*range.start(), *range.end());
        match self.tess_kind {
            CriterionKind::Uniform => Criterion::Uniform(v.round() as u32),
            CriterionKind::Edge => Criterion::Edge(v),
            CriterionKind::Sphere => Criterion::Sphere(v),
            CriterionKind::Error => Criterion::Error(v),
        }
    }

    /// The parameter of the current criterion kind (for the panel's slider; apply it with
    /// [`Self::set_tess_on`]).
    pub fn tess_value_mut(&mut self) -> &mut f32 {
        &mut self.tess_values[self.tess_kind.index()]
    }

    pub fn omni(&self) -> OmniSettings {
        self.settings.omni()
    }

    /// The output format of wall `index`'s window.
    pub fn wall_output(&self, index: usize) -> Option<StereoFormat> {
        let wall = self.settings.walls.get(index)?;
        Some(wall.format().unwrap_or(self.settings.app.wall_output))
    }

    /// Where the CAVE stands in the scene: the configured placement moved by navigation.
    pub fn world_from_cave(&self) -> Mat4 {
        Mat4::from_translation(self.navigation.position)
            * Mat4::from_rotation_y(self.navigation.yaw)
            * self.settings.world_from_cave()
    }

    /// The renderer's parameters for this frame.
    pub fn frame_params(&self) -> FrameParams<'_> {
        let mut frame = setup::frame_params_from(
            &self.settings,
            self.render_cave(),
            self.head(),
            self.world_from_cave(),
        );
        if self.settings.tracking.enabled && self.settings.tracking.show_wand_ray {
            frame.wand_ray = self.wand_ray();
        }
        frame.animation.seconds = self.animation_clock;
        frame
    }

    /// Runs the animation clock for `dt` real seconds at `[animation] speed`, if it plays.
    pub fn advance_animation(&mut self, dt: f32) {
        let a = &self.settings.animation;
        if a.enabled && a.playing && dt.is_finite() && dt > 0.0 {
            self.animation_clock += f64::from(dt) * f64::from(a.speed);
            if !self.animation_clock.is_finite() {
                self.animation_clock = 0.0;
            }
        }
    }

    /// Settings that change pipelines or targets.
    pub fn render_settings(&self) -> RenderSettings {
        setup::render_settings(&self.settings)
    }

    /// Moves through the scene for `dt` seconds of `input` at the configured speed.
    pub fn navigate(&mut self, input: NavInput, dt: f32) {
        if !(dt.is_finite() && dt > 0.0) {
            return;
        }
        let speed = self.settings.app.navigation_speed;
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

    /// The wand's ray as drawn (`None` without a tracked wand).
    pub fn wand_ray(&self) -> Option<WandRay> {
        let pose = self.wand?;
        WandRay::from_pose(
            pose.position,
            pose.orientation,
            self.settings.tracking.wand_ray_length_m,
        )
    }

    /// Flies the CAVE through the scene along `direction` (CAVE space, its length the
    /// fraction of the navigation speed) for `dt` seconds: point-and-fly.
    pub fn fly(&mut self, direction: Vec3, dt: f32) {
        if !(dt.is_finite() && dt > 0.0 && direction.is_finite()) {
            return;
        }
        let speed = self.settings.app.navigation_speed;
        let rotation = Quat::from_rotation_y(self.navigation.yaw);
        self.navigation.position += rotation * direction.clamp_length_max(1.0) * speed * dt;
    }

    /// Turns by a mouse movement (radians).
    pub fn turn(&mut self, radians: f32) {
        if radians.is_finite() {
            self.navigation.yaw += radians;
        }
    }

    /// Applies a key or gamepad action.
    pub fn apply(&mut self, action: Action) {
        fn next<T: Copy + PartialEq>(all: &[T], value: T, step: i32) -> T {
            let n = all.len() as i32;
            let i = all.iter().position(|v| *v == value).unwrap_or(0) as i32;
            all[(i + step).rem_euclid(n.max(1)) as usize]
        }
        let s = &mut self.settings;
        match action {
            Action::SetMode(mode) => s.render.mode = mode,
            Action::ToggleTessellation => {
                let on = !self.tess_on();
                self.set_tess_on(on);
            }
            Action::CycleSky => s.skybox.mode = next(&SkyMode::ALL, s.skybox.mode, 1),
            Action::ToggleWireframe => s.render.wireframe = !s.render.wireframe,
            Action::TogglePoleMerge => s.omnistereo.pole_merge = !s.omnistereo.pole_merge,
            Action::CycleWarp => s.omnistereo.warp = next(&WarpVariant::ALL, s.omnistereo.warp, 1),
            Action::CycleOutput => {
                s.app.preview_output = next(&StereoFormat::ALL, s.app.preview_output, 1);
                let default = s.app.wall_output;
                for wall in &mut s.walls {
                    wall.set_format(next(
                        &StereoFormat::ALL,
                        wall.format().unwrap_or(default),
                        1,
                    ));
                }
            }
            Action::SwapEyes => self.swap_eyes = !self.swap_eyes,
            Action::StepMode(step) => s.render.mode = next(&RenderMode::ALL, s.render.mode, step),
            Action::ScaleNavigationSpeed(factor) => {
                if factor.is_finite() && factor > 0.0 {
                    s.app.navigation_speed = (s.app.navigation_speed * factor)
                        .clamp(MIN_NAVIGATION_SPEED, MAX_NAVIGATION_SPEED);
                }
            }
            Action::ToggleGamepadMode => {
                s.gamepad.mode = next(&GamepadMode::ALL, s.gamepad.mode, 1)
            }
            Action::ToggleTracking => s.tracking.enabled = !s.tracking.enabled,
            Action::EyeSeparation(delta) => {
                s.cave.eye_separation =
                    (s.cave.eye_separation + delta).clamp(0.0, MAX_EYE_SEPARATION)
            }
            Action::MoveHead(delta) => {
                // A step behind a wall is not taken.
                let _ = self.set_head_position(self.head_position() + delta);
            }
            Action::ResetView => {
                self.navigation = Navigation::default();
                s.app.navigation_speed = self.config.settings.app.navigation_speed;
                // The configured head was validated at load.
                let _ = self.set_head_position(Vec3::from(self.config.settings.head.position));
            }
            Action::ToggleHelp => self.show_help = !self.show_help,
            Action::TogglePanel => self.show_panel = !self.show_panel,
            Action::Save => self.save_requested = true,
            Action::Screenshot => self.screenshot_requested = true,
            Action::Quit => self.quit_requested = true,
        }
    }

    /// The config file of the current settings, to be written at `target` (relative asset
    /// paths are rewritten when `target` is in another folder than the loaded config).
    pub fn to_config_file(&self, target: &Path) -> ConfigFile {
        let mut file = self.settings.clone();
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
