//! Validation of the config file, section by section: ranges, geometry and cross-field
//! checks that the file's types cannot express, each error naming the file, line and field.

use std::collections::BTreeMap;
use std::net::{IpAddr, SocketAddr, SocketAddrV4};
use std::path::{Path, PathBuf};
use std::time::Duration;

use glam::Vec3;

use super::file::*;
use super::spans;
use super::{
    AppConfig, Config, ConfigError, EyeWindow, PanelPlacement, TrackingConfig, WallWindow,
};
use crate::cave::placement::{FileFrame, corners_from_axes, corners_from_centre, wall_rotation};
use crate::cave::{Cave, Wall, left_of};
use crate::gamepad::{GamepadAction, GamepadSettings, button_map};
use crate::pano::{PanoRoute, PanoStereo};
use crate::tracking::ButtonAction;
use crate::tracking::receiver::MAX_BUTTONS;
use crate::tracking::{
    Calibration, DTrackSettings, NatNetSettings, OneEuroParams, OscMapping, PlausibilityLimits,
    ReceiverSettings, SourceKind, SourceSettings, TrackingSettings, VrpnDevice, VrpnSettings,
};

/// Builds errors that name the file, the field's line (where the text is known) and value.
struct Checker<'a> {
    path: &'a Path,
    text: Option<&'a str>,
}

impl Checker<'_> {
    fn fail(&self, field: &str, value: impl std::fmt::Debug, reason: &str) -> ConfigError {
        self.fail_text(field, format!("{value:?}"), reason)
    }

    fn fail_text(&self, field: &str, value: String, reason: &str) -> ConfigError {
        ConfigError::Invalid {
            path: self.path.to_owned(),
            line: self
                .text
                .and_then(|text| spans::line_of(text, field))
                .map(|line| format!(", line {line}"))
                .unwrap_or_default(),
            field: crate::messages::cut(field, 120),
            value: crate::messages::cut(&value, 120),
            reason: reason.to_owned(),
        }
    }

    /// A tracking client's wait between connection attempts: 0.1 to 60 seconds.
    fn retry(&self, field: &str, seconds: f32) -> Result<Duration, ConfigError> {
        Duration::try_from_secs_f32(seconds)
            .ok()
            .filter(|d| (0.1..=60.0).contains(&d.as_secs_f32()))
            .ok_or_else(|| self.fail(field, seconds, "must be 0.1 to 60 seconds"))
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

impl ConfigFile {
    /// Checks every field and builds the ready-to-use config (errors name no line).
    pub fn validate(&self, path: &Path) -> Result<Config, ConfigError> {
        self.validate_text(path, None)
    }

    /// Checks every field against the text it was read from (errors name the line).
    pub(super) fn validate_text(
        &self,
        path: &Path,
        text: Option<&str>,
    ) -> Result<Config, ConfigError> {
        let ck = Checker { path, text };
        // Every range the model declares, for every setting at once.
        super::bounds::check(self).map_err(|e| ck.fail_text(&e.path, e.value, &e.reason))?;

        let walls = self.validate_walls(&ck)?;

        let target_bytes: u64 = walls
            .iter()
            .map(|w| wall_target_bytes(w.resolution, self.render.msaa))
            .sum();
        let target_budget = u64::from(self.budgets.max_target_memory_mb) << 20;
        if target_bytes > target_budget {
            return Err(ck.fail_text(
                "wall",
                format!(
                    "({} walls at MSAA {}: {} of render targets)",
                    walls.len(),
                    self.render.msaa,
                    crate::read_capped::human_bytes(target_bytes)
                ),
                &format!(
                    "over budgets.max_target_memory_mb = {} (smaller walls, render.msaa = 1, \
                     or a larger budget)",
                    self.budgets.max_target_memory_mb
                ),
            ));
        }

        let cave = self.validate_cave(&ck, walls)?;
        let o = &self.omnistereo;
        let start = o.pole_merge_start_degrees;
        // Cross-field: the fade ends after it starts (each is 0..90 by the model).
        ck.range(
            "omnistereo.pole_merge_end_degrees",
            o.pole_merge_end_degrees,
            start,
            90.0,
        )?;
        let h = &self.head;
        let head_pos = ck.finite3("head.position", h.position)?;
        if let Some(problem) = cave.head_problem(head_pos) {
            return Err(ck.fail("head.position", h.position, &problem));
        }
        self.validate_render_and_lighting(&ck)?;

        let resolve = |p: &PathBuf| {
            if p.is_absolute() {
                p.clone()
            } else {
                path.parent().unwrap_or(Path::new(".")).join(p)
            }
        };
        let scene_path = self.scene.path.as_ref().map(resolve);

        let sky_path = self
            .skybox
            .file
            .as_ref()
            .filter(|p| p.as_os_str() != "none")
            .map(resolve);

        self.panorama.validate(&ck)?;
        Ok(Config {
            source: path.to_owned(),
            cave,
            scene_path,
            sky_path,
            app: self.validate_app(&ck)?,
            tracking: self.validate_tracking(&ck)?,
            gamepad: self.validate_gamepad(&ck)?,
            settings: self.clone(),
        })
    }

    /// The walls: at least one, at most the budget's, each valid and with its own name.
    fn validate_walls(&self, ck: &Checker<'_>) -> Result<Vec<Wall>, ConfigError> {
        if self.walls.is_empty() {
            return Err(ck.fail("wall", "[]", "at least one [[wall]] is required"));
        }
        let max_walls = self.budgets.max_walls as usize;
        if self.walls.len() > max_walls {
            return Err(ck.fail_text(
                "wall",
                format!("({} walls)", self.walls.len()),
                &format!("more than budgets.max_walls = {max_walls}"),
            ));
        }
        let mut walls = Vec::with_capacity(self.walls.len());
        let mut names = std::collections::HashSet::with_capacity(self.walls.len());
        let frame = self.cave.wall_frame();
        for (i, w) in self.walls.iter().enumerate() {
            let wall = validate_wall(ck, i, w, frame)?;
            if !names.insert(wall.name.clone()) {
                return Err(ck.fail(
                    &format!("wall[{i}].name"),
                    &w.name,
                    "another wall has this name",
                ));
            }
            walls.push(wall);
        }
        Ok(walls)
    }

    /// The CAVE of `walls`: the clipping planes, the stereo view direction and a projection
    /// centre in front of every wall.
    fn validate_cave(&self, ck: &Checker<'_>, walls: Vec<Wall>) -> Result<Cave, ConfigError> {
        let c = &self.cave;
        let near = c.near;
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
        Ok(Cave {
            walls,
            near,
            far,
            stereo_view_direction: view_dir,
            projection_centre,
        })
    }

    /// The render settings, the scene's placement and the lights.
    fn validate_render_and_lighting(&self, ck: &Checker<'_>) -> Result<(), ConfigError> {
        let r = &self.render;
        if !matches!(r.msaa, 1 | 4) {
            return Err(ck.fail("render.msaa", r.msaa, "must be 1 (off) or 4"));
        }
        ck.colour("render.background", r.background, 1.0)?;
        ck.finite3(
            "scene.world_from_cave.translation",
            self.scene.world_from_cave.translation,
        )?;

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
        ck.finite3("lighting.point.position", l.point.position)?;
        ck.colour("lighting.point.color", l.point.color, 10.0)?;
        Ok(())
    }

    fn validate_tracking(&self, ck: &Checker<'_>) -> Result<TrackingConfig, ConfigError> {
        let t = &self.tracking;
        let (listen, allowed_senders) = self.validate_osc_receiver(ck)?;
        let timeout = Duration::try_from_secs_f32(t.timeout_seconds).map_err(|_| {
            ck.fail(
                "tracking.timeout_seconds",
                t.timeout_seconds,
                "must be a positive number of seconds",
            )
        })?;
        let calibration = self.validate_calibration(ck)?;
        let f = &t.filter;
        let params = OneEuroParams {
            min_cutoff_hz: f.min_cutoff_hz,
            beta: f.beta,
            derivative_cutoff_hz: f.derivative_cutoff_hz,
        };
        let eye_offset = ck.finite3("tracking.eye_offset", t.eye_offset)?;
        if eye_offset.length() > 0.5 {
            return Err(ck.fail(
                "tracking.eye_offset",
                t.eye_offset,
                "is more than 0.5 m from the tracked body: not an offset to the eyes",
            ));
        }
        let buttons = self.validate_buttons(ck)?;
        let source = match t.source {
            SourceKind::Osc => None,
            SourceKind::Vrpn => Some(SourceSettings::Vrpn(Box::new(VrpnSettings {
                allowed_senders: allowed_senders.clone(),
                idle: timeout,
                ..self.validate_vrpn(ck)?
            }))),
            SourceKind::NatNet => Some(SourceSettings::NatNet(NatNetSettings {
                allowed_senders: allowed_senders.clone(),
                idle: timeout,
                ..self.validate_natnet(ck)?
            })),
            SourceKind::DTrack => {
                let d = &t.dtrack;
                let listen: SocketAddr = d.listen.trim().parse().map_err(|_| {
                    ck.fail(
                        "tracking.dtrack.listen",
                        &d.listen,
                        "must be an address:port such as \"0.0.0.0:5000\"",
                    )
                })?;
                Some(SourceSettings::DTrack(DTrackSettings {
                    listen,
                    allowed_senders: allowed_senders.clone(),
                    head_body: d.head_body,
                    flystick: u32::try_from(d.flystick).ok(),
                }))
            }
        };
        let receiver = ReceiverSettings {
            listen,
            allowed_senders,
            mapping: OscMapping {
                position_address: t.position_address.clone(),
                orientation_address: t.orientation_address.clone(),
                euler_address: t.euler_address.clone(),
                quaternion_order: t.quaternion_order,
                natnet_address: t.natnet_address.clone(),
                natnet_rigid_body: t.natnet_rigid_body,
            },
        };
        Ok(TrackingConfig {
            enabled: t.enabled,
            source: source.unwrap_or(SourceSettings::Osc),
            buttons,
            receiver,
            settings: TrackingSettings {
                calibration,
                filter: f.enabled.then_some(params),
                eye_offset,
                plausibility: PlausibilityLimits {
                    outside_margin_m: t.plausibility.outside_margin_m,
                    max_speed_mps: t.plausibility.max_speed_mps,
                    max_turn_dps: t.plausibility.max_turn_dps,
                },
                timeout,
            },
        })
    }

    /// The OSC receiver's listening address and allowed senders, and its OSC addresses
    /// checked.
    fn validate_osc_receiver(
        &self,
        ck: &Checker<'_>,
    ) -> Result<(SocketAddr, Vec<IpAddr>), ConfigError> {
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
        Ok((listen, allowed_senders))
    }

    /// The tracker's calibration into CAVE coordinates.
    fn validate_calibration(&self, ck: &Checker<'_>) -> Result<Calibration, ConfigError> {
        let c = &self.tracking.calibration;
        let remap = Calibration::remap_from_axes(&c.axes)
            .map_err(|e| ck.fail("tracking.calibration.axes", &c.axes, &e.to_string()))?;
        let scale = c.scale;
        let [yaw, pitch, roll] = c.rotation_degrees;
        let offset = ck.finite3("tracking.calibration.offset", c.offset)?;
        Ok(Calibration {
            remap,
            scale,
            rotation: crate::cave::Head::orientation_from_degrees(yaw, pitch, roll),
            offset,
        })
    }

    /// The tracker's buttons: a button number to an action ("none" left out).
    fn validate_buttons(
        &self,
        ck: &Checker<'_>,
    ) -> Result<BTreeMap<usize, ButtonAction>, ConfigError> {
        let mut buttons = BTreeMap::new();
        for (key, action) in &self.tracking.buttons {
            let field = format!("tracking.buttons.{key}");
            let index: usize = key
                .parse()
                .ok()
                .filter(|&i| i < MAX_BUTTONS)
                .ok_or_else(|| {
                    ck.fail(
                        &field,
                        key,
                        &format!("must be a button number, 0 to {}", MAX_BUTTONS - 1),
                    )
                })?;
            if action == "none" {
                continue;
            }
            let action = ButtonAction::from_name(action).ok_or_else(|| {
                ck.fail(
                    &field,
                    action,
                    &format!(
                        "is not an action; one of: none, fly, select, {}",
                        GamepadAction::NAMES.join(", ")
                    ),
                )
            })?;
            buttons.insert(index, action);
        }
        Ok(buttons)
    }

    /// The NatNet client's settings: Motive's address, the local interface, the rigid
    /// bodies and the retry interval.
    fn validate_natnet(&self, ck: &Checker<'_>) -> Result<NatNetSettings, ConfigError> {
        let n = &self.tracking.natnet;
        let server = n.server.trim();
        let server: SocketAddrV4 = server
            .parse()
            .or_else(|_| {
                server
                    .parse::<std::net::Ipv4Addr>()
                    .map(|ip| SocketAddrV4::new(ip, crate::tracking::natnet::DEFAULT_COMMAND_PORT))
            })
            .map_err(|_| {
                ck.fail(
                    "tracking.natnet.server",
                    &n.server,
                    "must be Motive's IPv4 address, with its command port if not 1510 \
                     (\"192.168.1.10\" or \"192.168.1.10:1510\")",
                )
            })?;
        let interface = n.interface.trim().parse().map_err(|_| {
            ck.fail(
                "tracking.natnet.interface",
                &n.interface,
                "must be a local IPv4 address, or \"0.0.0.0\"",
            )
        })?;
        let retry = ck.retry("tracking.natnet.retry_seconds", n.retry_seconds)?;
        Ok(NatNetSettings {
            server,
            interface,
            head_rigid_body: n.head_rigid_body,
            wand_rigid_body: (n.wand_rigid_body >= 0).then_some(n.wand_rigid_body),
            retry,
            allowed_senders: Vec::new(),
            idle: Duration::ZERO,
        })
    }

    fn validate_vrpn(&self, ck: &Checker<'_>) -> Result<VrpnSettings, ConfigError> {
        let v = &self.tracking.vrpn;
        let device = |field: &str, text: &str| -> Result<Option<VrpnDevice>, ConfigError> {
            if text.trim().is_empty() {
                return Ok(None);
            }
            text.trim()
                .parse::<VrpnDevice>()
                .map(Some)
                .map_err(|why| ck.fail(&format!("tracking.vrpn.{field}"), text, &why))
        };
        let head = device("head", &v.head)?.ok_or_else(|| {
            ck.fail(
                "tracking.vrpn.head",
                &v.head,
                "names the head's tracker, e.g. Tracker0@localhost",
            )
        })?;
        let retry = ck.retry("tracking.vrpn.retry_seconds", v.retry_seconds)?;
        for (field, sensor) in [
            ("head_sensor", v.head_sensor),
            ("wand_sensor", v.wand_sensor),
        ] {
            if !(0..=65535).contains(&sensor) {
                return Err(ck.fail(
                    &format!("tracking.vrpn.{field}"),
                    sensor,
                    "must be 0 to 65535",
                ));
            }
        }
        Ok(VrpnSettings {
            head,
            head_sensor: v.head_sensor,
            wand: device("wand", &v.wand)?.map(|d| (d, v.wand_sensor)),
            buttons: device("buttons", &v.buttons)?,
            analogs: device("analogs", &v.analogs)?,
            retry,
            allowed_senders: Vec::new(),
            idle: Duration::ZERO,
        })
    }

    fn validate_gamepad(&self, ck: &Checker<'_>) -> Result<GamepadSettings, ConfigError> {
        let g = &self.gamepad;
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
            mode: g.mode,
            dead_zone: g.dead_zone,
            trigger_dead_zone: g.trigger_dead_zone,
            head_speed: g.head_speed,
            buttons,
        })
    }

    fn validate_app(&self, ck: &Checker<'_>) -> Result<AppConfig, ConfigError> {
        let a = &self.app;
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
        let mut walls = Vec::with_capacity(self.walls.len());
        for (i, w) in self.walls.iter().enumerate() {
            let size = w.window_size.unwrap_or(w.resolution);
            if !size.iter().all(|v| (1..=MAX_WALL_PIXELS).contains(v)) {
                return Err(ck.fail(
                    &format!("wall[{i}].window_size"),
                    size,
                    &format!("both sides must be 1..={MAX_WALL_PIXELS} pixels"),
                ));
            }
            let output = w.format().unwrap_or(a.wall_output);
            let mut eye_outputs = Vec::with_capacity(w.eye_outputs().len());
            for (k, o) in w.eye_outputs().iter().enumerate() {
                let field = |f: &str| format!("wall[{i}].output[{k}].{f}");
                let [rw, rh] = w.resolution;
                let crop = o.crop.unwrap_or([0, 0, rw, rh]);
                let [cx, cy, cw, ch] = crop;
                if cw == 0
                    || ch == 0
                    || u64::from(cx) + u64::from(cw) > u64::from(rw)
                    || u64::from(cy) + u64::from(ch) > u64::from(rh)
                {
                    return Err(ck.fail(
                        &field("crop"),
                        crop,
                        &format!("must be x, y, width, height inside the wall's {rw}×{rh} pixels"),
                    ));
                }
                if o.offset.iter().any(|v| v.abs() > 4096) {
                    return Err(ck.fail(&field("offset"), o.offset, "must be within ±4096 pixels"));
                }
                let size = o.window_size.unwrap_or([cw, ch]);
                if !size.iter().all(|v| (1..=MAX_WALL_PIXELS).contains(v)) {
                    return Err(ck.fail(
                        &field("window_size"),
                        size,
                        &format!("both sides must be 1..={MAX_WALL_PIXELS} pixels"),
                    ));
                }
                eye_outputs.push(EyeWindow {
                    eye: o.eye.eye(),
                    monitor: o.monitor.clone(),
                    position: o.window_position,
                    size,
                    crop,
                    offset: o.offset,
                });
            }
            if w.output.is_some() && w.eye_outputs().is_empty() && w.format().is_none() {
                return Err(ck.fail_text(
                    &format!("wall[{i}].output"),
                    "[]".into(),
                    "has no [[wall.output]] tables: give one per eye, or a format",
                ));
            }
            walls.push(WallWindow {
                monitor: w.monitor.clone(),
                position: w.window_position,
                size,
                output,
                eye_outputs,
            });
        }
        Ok(AppConfig {
            mode: a.mode,
            panel,
            window_position: a.window_position,
            window_size: a.window_size,
            preview_output: a.preview_output,
            vsync: a.vsync,
            navigation_speed: a.navigation_speed,
            walls,
        })
    }
}

/// A wall's three corners in CAVE space, from whichever form the file gives (exactly one).
fn wall_corners(
    ck: &Checker<'_>,
    index: usize,
    w: &WallSection,
    frame: FileFrame,
) -> Result<[Vec3; 3], ConfigError> {
    let field = |name: &str| format!("wall[{index}].{name}");
    let corners = [w.lower_left, w.lower_right, w.upper_left];
    let centre_form = [w.centre.is_some(), w.yaw_pitch_roll_degrees.is_some()];
    let axes_form = [w.origin, w.horizontal_axis, w.vertical_axis];
    let forms = [
        corners.iter().any(Option::is_some),
        centre_form.iter().any(|&b| b),
        axes_form.iter().any(Option::is_some),
    ];
    let given = forms.iter().filter(|&&b| b).count();
    let name = w.name.as_str();
    if given != 1 {
        return Err(ck.fail_text(
            &field("lower_left"),
            format!("{given} forms"),
            &format!(
                "wall '{name}' needs exactly one of: lower_left + lower_right + upper_left; \
                 centre + size (+ yaw_pitch_roll_degrees); origin + horizontal_axis + \
                 vertical_axis + size"
            ),
        ));
    }
    let point = |f: &str, v: Option<[f32; 3]>| -> Result<glam::DVec3, ConfigError> {
        let v = v.ok_or_else(|| {
            ck.fail_text(
                &field(f),
                "missing".into(),
                "is needed by the other fields given",
            )
        })?;
        Ok(frame.to_cave(ck.finite3(&field(f), v)?.as_dvec3()))
    };
    let size = || -> Result<[f64; 2], ConfigError> {
        let s = w.size.ok_or_else(|| {
            ck.fail_text(
                &field("size"),
                "missing".into(),
                "is needed: [width, height]",
            )
        })?;
        if !s.iter().all(|v| v.is_finite() && *v > 0.0) {
            return Err(ck.fail(&field("size"), s, "must be a positive width and height"));
        }
        Ok(s.map(|v| f64::from(v) * frame.unit.metres()))
    };
    let corners = if forms[0] {
        if w.size.is_some() {
            return Err(ck.fail(
                &field("size"),
                w.size,
                "goes with centre or origin, not corners",
            ));
        }
        [
            point("lower_left", w.lower_left)?,
            point("lower_right", w.lower_right)?,
            point("upper_left", w.upper_left)?,
        ]
    } else if forms[1] {
        let centre = point("centre", w.centre)?;
        let ypr = w.yaw_pitch_roll_degrees.unwrap_or_default();
        if !ypr.iter().all(|a| a.is_finite() && a.abs() <= 360.0) {
            return Err(ck.fail(
                &field("yaw_pitch_roll_degrees"),
                ypr,
                "must be angles from −360 to 360 degrees",
            ));
        }
        corners_from_centre(centre, wall_rotation(ypr.map(f64::from)), size()?)
    } else {
        let origin = point("origin", w.origin)?;
        let horizontal = point("horizontal_axis", w.horizontal_axis)?;
        let vertical = point("vertical_axis", w.vertical_axis)?;
        corners_from_axes(origin, horizontal, vertical, size()?).ok_or_else(|| {
            ck.fail(
                &field("horizontal_axis"),
                (w.horizontal_axis, w.vertical_axis),
                "the axes must not be zero",
            )
        })?
    };
    Ok(corners.map(|c| c.as_vec3()))
}

fn validate_wall(
    ck: &Checker<'_>,
    index: usize,
    w: &WallSection,
    frame: FileFrame,
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
    let [ll, lr, ul] = wall_corners(ck, index, w, frame)?;
    for (f, c) in [("lower_left", ll), ("lower_right", lr), ("upper_left", ul)] {
        if !c.is_finite() || c.abs().max_element() > 1e5 {
            return Err(ck.fail(
                &field(f),
                c,
                "is beyond ±100 km (or not finite) in CAVE metres",
            ));
        }
    }
    // A wall narrower than a millimetre is a typo, not a screen. Lengths and the angle are
    // worked in f64 so that huge corners cannot overflow into a NaN that passes the tests
    // (1e30 squared is infinite in f32); anything not finite even so is refused.
    const MIN_SIDE_M: f64 = 1e-3;
    let (ll64, lr64, ul64) = (ll.as_dvec3(), lr.as_dvec3(), ul.as_dvec3());
    let width = (lr64 - ll64).length();
    if !width.is_finite() || width < MIN_SIDE_M {
        return Err(ck.fail(
            &field("lower_right"),
            lr,
            "coincides with lower_left: the wall has no width",
        ));
    }
    let height = (ul64 - ll64).length();
    if !height.is_finite() || height < MIN_SIDE_M {
        return Err(ck.fail(
            &field("upper_left"),
            ul,
            "coincides with lower_left: the wall has no height",
        ));
    }
    // The two edges from lower_left must be perpendicular (cosine below ~0.06°); a skewed
    // parallelogram cannot be driven by a rectangular image.
    let cosine = (lr64 - ll64).dot(ul64 - ll64) / (width * height);
    if !cosine.is_finite() || cosine.abs() > 1e-3 {
        return Err(ck.fail(
            &field("upper_left"),
            ul,
            &format!(
                "edges lower_left→lower_right and lower_left→upper_left are not perpendicular \
                 (angle {:.2}°): walls must be rectangles",
                cosine.clamp(-1.0, 1.0).acos().to_degrees()
            ),
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

impl PanoramaSection {
    fn validate(&self, ck: &Checker<'_>) -> Result<(), ConfigError> {
        let (projection, route) = (self.projection, self.route);
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
        let stereo = PanoStereo::of_kind(self.stereo, [ioid, d, offset]);
        let (max_h, max_v) = projection.max_fov();
        ck.range(
            "panorama.h_fov_degrees",
            self.h_fov_degrees,
            1.0,
            max_h.to_degrees().round(),
        )?;
        ck.range(
            "panorama.v_fov_degrees",
            self.v_fov_degrees,
            1.0,
            max_v.to_degrees().round(),
        )?;
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
        Ok(())
    }
}

/// GPU memory of one wall's targets (two eyes: colour, MSAA colour, depth), as
/// `render::targets::EyeTarget::new` allocates them (keep in sync); for the config's target budget.
fn wall_target_bytes(size: [u32; 2], msaa: u32) -> u64 {
    let pixels = u64::from(size[0]) * u64::from(size[1]);
    let samples = u64::from(msaa.max(1));
    let color = 4;
    let msaa_color = if samples > 1 { 4 * samples } else { 0 };
    let depth = 4 * samples; // Depth32Float
    2 * pixels * (color + msaa_color + depth)
}
