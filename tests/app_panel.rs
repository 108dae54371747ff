//! The control panel driven as a user would, through egui with synthetic pointer clicks on
//! widgets found by their accessibility labels: every render mode and tessellation criterion
//! switched from the panel renders what the same settings render headless, on one device and
//! one renderer, and no pipeline is built after start-up.

#![allow(clippy::unwrap_used, clippy::expect_used)]

mod common;

use egui::accesskit;
use glam::Vec3;
use omnicave::app::panel::{PanelInfo, panel_ui};
use omnicave::app::state::{AppState, CriterionKind};
use omnicave::cave::RenderMode;
use omnicave::config::Config;
use omnicave::render::{RenderSettings, Renderer, WallImages};
use omnicave::scene::{Scene, load_gltf};
use omnicave::tess::Criterion;

/// A tall screen, so the whole panel is visible without scrolling.
const SCREEN: egui::Vec2 = egui::vec2(420.0, 2400.0);

/// The panel in a headless egui context, clicked by widget label.
struct PanelDriver {
    ctx: egui::Context,
    info: PanelInfo,
    /// Events for the next frame.
    pending: Vec<egui::Event>,
    time: f64,
}

impl PanelDriver {
    fn new() -> Self {
        let ctx = egui::Context::default();
        ctx.enable_accesskit();
        Self {
            ctx,
            info: PanelInfo {
                tessellation_supported: true,
                has_sky: false,
                ..Default::default()
            },
            pending: Vec::new(),
            time: 0.0,
        }
    }

    /// Runs one frame with the pending events; returns the accessibility tree's nodes.
    fn frame(&mut self, state: &mut AppState) -> Vec<accesskit::Node> {
        self.time += 0.1;
        let raw = egui::RawInput {
            screen_rect: Some(egui::Rect::from_min_size(egui::Pos2::ZERO, SCREEN)),
            events: std::mem::take(&mut self.pending),
            time: Some(self.time),
            ..Default::default()
        };
        let info = self.info.clone();
        let mut output = self.ctx.run_ui(raw, |ui| {
            egui::CentralPanel::default_margins().show(ui, |ui| {
                panel_ui(ui, state, &info);
            });
        });
        output.textures_delta.clear();
        output
            .platform_output
            .accesskit_update
            .map(|u| u.nodes.into_iter().map(|(_, n)| n).collect())
            .unwrap_or_default()
    }

    /// Clicks the first widget `pick` finds in the current tree (a few frames: find, move,
    /// press, release, settle).
    fn click_where(
        &mut self,
        state: &mut AppState,
        what: &str,
        pick: impl Fn(&[accesskit::Node]) -> Option<accesskit::Rect>,
    ) {
        let nodes = self.frame(state);
        let b = pick(&nodes).unwrap_or_else(|| {
            let known: Vec<_> = nodes
                .iter()
                .map(|n| format!("{:?} {:?} {:?}", n.role(), n.label(), n.value()))
                .collect();
            panic!("no widget for '{what}'; tree: {known:?}")
        });
        let pos = egui::pos2(((b.x0 + b.x1) / 2.0) as f32, ((b.y0 + b.y1) / 2.0) as f32);
        self.pending.push(egui::Event::PointerMoved(pos));
        self.frame(state);
        let button = |pressed| egui::Event::PointerButton {
            pos,
            button: egui::PointerButton::Primary,
            pressed,
            modifiers: egui::Modifiers::NONE,
        };
        self.pending.push(button(true));
        self.frame(state);
        self.pending.push(button(false));
        self.frame(state);
        self.frame(state);
    }

    /// Clicks the button or checkbox labelled `label`.
    fn click(&mut self, state: &mut AppState, label: &str) {
        self.click_where(state, label, |nodes| {
            nodes
                .iter()
                .find(|n| n.label() == Some(label) && n.role() != accesskit::Role::Label)
                .and_then(|n| n.bounds())
        });
    }

    /// Opens the combo box beside the text `combo` and picks the entry `option`.
    fn choose(&mut self, state: &mut AppState, combo: &str, option: &str) {
        self.click_where(state, combo, |nodes| {
            let text = nodes
                .iter()
                .find(|n| n.role() == accesskit::Role::Label && n.value() == Some(combo))?
                .bounds()?;
            // The combo box on the text's row.
            nodes
                .iter()
                .filter(|n| n.role() == accesskit::Role::ComboBox)
                .filter_map(|n| n.bounds())
                .find(|b| b.y0 < text.y1 && text.y0 < b.y1)
        });
        self.click_where(state, option, |nodes| {
            nodes
                .iter()
                .find(|n| {
                    !matches!(n.role(), accesskit::Role::ComboBox | accesskit::Role::Label)
                        && (n.label() == Some(option) || n.value() == Some(option))
                })
                .and_then(|n| n.bounds())
        });
    }
}

/// The desktop config at small walls (fast), with the bundled living room.
fn config() -> Config {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("config/desktop.toml");
    let text = std::fs::read_to_string(&path)
        .expect("config")
        .replace("resolution = [480, 422]", "resolution = [200, 176]")
        .replace("msaa = 4", "msaa = 1");
    Config::from_toml(&text, &path).expect("config")
}

/// Renders the state's frame on `renderer` and reads it back.
fn render(renderer: &mut Renderer, state: &AppState) -> Vec<WallImages> {
    renderer.render(&state.frame_params()).expect("render");
    renderer.read_images().expect("read")
}

/// The reference: a fresh renderer set up from a config with the same settings.
fn reference(config: &Config, scene: &Scene) -> Vec<WallImages> {
    omnicave::setup::render_images(common::gpu(), config, scene, None).expect("reference")
}

/// Share of eye-image pixels that differ at all.
fn differing(a: &[WallImages], b: &[WallImages]) -> f64 {
    let mut total = 0usize;
    let mut off = 0usize;
    for (x, y) in a.iter().zip(b) {
        for (p, q) in [(&x.left, &y.left), (&x.right, &y.right)] {
            total += p.pixels().len();
            off += p.pixels().zip(q.pixels()).filter(|(u, v)| u != v).count();
        }
    }
    off as f64 / total.max(1) as f64
}

/// Whether at most `limit` of the pixels differ.
fn same_within(a: &[WallImages], b: &[WallImages], limit: f64) -> bool {
    differing(a, b) <= limit
}

/// Untessellated frames are deterministic: the same settings give the same pixels, exactly
/// (the smallest change of setting, omni on-axis → off-axis, changes 0.046 % of them).
fn same(a: &[WallImages], b: &[WallImages]) -> bool {
    same_within(a, b, 0.0)
}

/// The compute tessellator appends triangles with atomics, so their order varies between runs
/// and pixels on edges shared at equal depth may take either triangle's shading (measured: 0 to
/// 0.023 % of pixels); switching the criterion changes 9–53 % of them.
const TESSELLATION_ORDER_NOISE: f64 = 0.001;

#[test]
fn every_mode_and_tessellation_setting_switches_from_the_panel() {
    let gpu = common::gpu();
    let base = config();
    let scene = load_gltf(base.scene_path.as_ref().expect("scene")).expect("scene");
    let mut state = AppState::new(base.clone());
    // Off-centre and turned, so every mode's eyes differ (tracked stereo follows the yaw).
    state
        .set_head_position(Vec3::new(0.3, 1.6, 0.2))
        .expect("head inside");
    state.settings.head.yaw_degrees = 30.0;
    let mut renderer = Renderer::new(
        gpu,
        state.cave(),
        RenderSettings {
            msaa: 1,
            wireframe: false,
        },
    )
    .expect("renderer");
    renderer.set_scene(&scene).expect("scene upload");
    let device = gpu.device.clone();
    let pipelines_at_start = renderer.pipelines_built();
    let mut panel = PanelDriver::new();

    let mut previous: Option<(RenderMode, Vec<WallImages>)> = None;
    for mode in RenderMode::ALL {
        panel.choose(&mut state, "Render mode", mode.name());
        assert_eq!(
            state.settings.render.mode,
            mode,
            "the panel did not switch to {}",
            mode.name()
        );
        let images = render(&mut renderer, &state);
        let mut expected_config = base.clone();
        expected_config.settings.render.mode = mode;
        expected_config.settings.head = state.settings.head.clone();
        assert!(
            same(&images, &reference(&expected_config, &scene)),
            "{}: the panel's frame differs from the same settings rendered headless",
            mode.name()
        );
        if let Some((prev_mode, prev)) = &previous {
            assert!(
                !same(&images, prev),
                "switching {} → {} did not change the image",
                prev_mode.name(),
                mode.name()
            );
        }
        previous = Some((mode, images));
    }

    // Tessellation in the omnistereo mode: on, then every criterion.
    assert_eq!(state.settings.render.mode, RenderMode::OmniOffAxis);
    let untessellated = render(&mut renderer, &state);
    panel.click(&mut state, "Adaptive tessellation");
    assert!(state.tess_on());
    for kind in CriterionKind::ALL {
        panel.choose(&mut state, "Criterion", kind.name());
        assert_eq!(state.tess_kind, kind);
        let criterion = state.criterion().expect("criterion");
        let images = render(&mut renderer, &state);
        let mut expected_config = base.clone();
        expected_config.settings.render.mode = RenderMode::OmniOffAxis;
        expected_config.settings.head = state.settings.head.clone();
        expected_config.settings.tessellation.criterion = Some(criterion);
        assert!(
            same_within(
                &images,
                &reference(&expected_config, &scene),
                TESSELLATION_ORDER_NOISE
            ),
            "{criterion}: the panel's frame differs from the same settings rendered headless"
        );
        // Every default parameter refines the room's large quads, which bends their edges
        // under the warp: the image must change from the plain warp.
        assert!(
            !same_within(&images, &untessellated, 0.01),
            "{criterion} did not change the image"
        );
        if kind == CriterionKind::Error {
            assert_eq!(criterion, Criterion::Error(0.5));
        }
    }
    panel.click(&mut state, "Adaptive tessellation");
    assert!(!state.tess_on());
    assert!(same(&render(&mut renderer, &state), &untessellated));

    // Wireframe is a pipeline variant built at start-up, not on demand.
    panel.click(&mut state, "Wireframe");
    assert!(state.settings.render.wireframe);
    renderer
        .set_settings(state.render_settings(), state.cave())
        .expect("settings");
    let wire = render(&mut renderer, &state);
    if gpu.wireframe_supported {
        assert!(!same(&wire, &untessellated), "wireframe did not draw");
    }

    assert_eq!(
        renderer.pipelines_built(),
        pipelines_at_start,
        "switching built pipelines"
    );
    assert!(device == gpu.device, "the device was replaced");
}

#[test]
fn saved_settings_load_back_as_they_were() {
    let mut state = AppState::new(config());
    state.settings.render.mode = RenderMode::OmniOnAxis;
    state.settings.cave.eye_separation = 0.07;
    state.tess_kind = CriterionKind::Sphere;
    *state.tess_value_mut() = 12.0;
    state.set_tess_on(true);
    state.settings.omnistereo.pole_merge = false;
    state.set_cave_size(Vec3::new(4.0, 3.0, 3.3));
    state
        .set_head_position(Vec3::new(0.2, 1.5, -0.4))
        .expect("head inside");
    state.settings.app.preview_output = omnicave::output::formats::StereoFormat::RowInterleaved;
    state.settings.tracking.enabled = true;
    state.settings.tracking.filter.beta = 3.5;
    state.settings.gamepad.mode = omnicave::gamepad::GamepadMode::Head;
    state.settings.app.navigation_speed = 4.0;
    // Another folder than the config's, so relative asset paths must be rewritten.
    let dir = std::env::temp_dir().join("omnicave-save-test");
    std::fs::create_dir_all(&dir).expect("dir");
    let path = dir.join("saved.toml");
    state.save(&path).expect("save");
    let loaded = AppState::new(Config::load(&path).expect("saved config loads"));
    assert_eq!(loaded.settings.render.mode, RenderMode::OmniOnAxis);
    assert_eq!(loaded.settings.cave.eye_separation, 0.07);
    assert_eq!(loaded.criterion(), Some(Criterion::Sphere(12.0)));
    assert_eq!(loaded.omni(), state.omni());
    assert_eq!(loaded.head_position(), state.head_position());
    assert_eq!(loaded.cave(), state.cave(), "moved walls are saved");
    assert_eq!(
        loaded.settings.app.preview_output,
        state.settings.app.preview_output
    );
    assert!(loaded.settings.tracking.enabled);
    assert_eq!(loaded.tracking_filter(), state.tracking_filter());
    assert_eq!(loaded.settings.gamepad.mode, state.settings.gamepad.mode);
    assert_eq!(loaded.settings.app.navigation_speed, 4.0);
    assert!(
        loaded
            .config
            .scene_path
            .as_ref()
            .is_some_and(|p| p.is_file()),
        "the scene path still resolves from the new folder"
    );
}

#[test]
fn the_panel_shows_tracking_status_and_switches_tracking_filter_and_sticks() {
    use omnicave::gamepad::GamepadMode;
    use omnicave::tracking::TrackingStatus;

    let mut state = AppState::new(config());
    let mut driver = PanelDriver::new();
    assert!(!state.settings.tracking.enabled);
    driver.click(&mut state, "Use tracking (osc)");
    assert!(state.settings.tracking.enabled);
    let filter = state.settings.tracking.filter.enabled;
    driver.click(&mut state, "One Euro filter");
    assert_eq!(state.settings.tracking.filter.enabled, !filter);
    driver.choose(&mut state, "Sticks drive", "head");
    assert_eq!(state.settings.gamepad.mode, GamepadMode::Head);

    // The receiver reports a loss: the panel says so at the top and in its section.
    driver.info.tracking.source = Some("OSC on 127.0.0.1:7000".into());
    driver.info.tracking.status = Some(TrackingStatus::Lost);
    driver.info.tracking.lost_for = Some(2.5);
    let texts = |nodes: &[accesskit::Node]| -> Vec<String> {
        nodes
            .iter()
            .filter(|n| n.role() == accesskit::Role::Label)
            .filter_map(|n| n.value().map(str::to_owned))
            .collect()
    };
    let shown = texts(&driver.frame(&mut state));
    assert!(
        shown
            .iter()
            .any(|t| t == "Tracking: tracking lost for 2.5 s: head holds its last pose"),
        "{shown:?}"
    );
    assert!(
        shown.iter().any(|t| t == "OSC on 127.0.0.1:7000"),
        "{shown:?}"
    );
    driver.info.tracking.status = Some(TrackingStatus::Tracking);
    driver.info.tracking.lost_for = None;
    let shown = texts(&driver.frame(&mut state));
    assert!(shown.iter().any(|t| t == "Tracking: tracking"), "{shown:?}");
    // Switched off, the status line goes.
    driver.click(&mut state, "Use tracking (osc)");
    assert!(!state.settings.tracking.enabled);
    let shown = texts(&driver.frame(&mut state));
    assert!(
        !shown.iter().any(|t| t.starts_with("Tracking:")),
        "{shown:?}"
    );
    // The wand and the last selection, while tracking is on.
    driver.click(&mut state, "Use tracking (osc)");
    driver.info.tracking.status = Some(TrackingStatus::Tracking);
    driver.info.tracking.source = Some("OSC on 127.0.0.1:7000".into());
    driver.info.tracking.selection = Some("parquet (material 0), 1.00 m along the ray".into());
    state.wand = Some(omnicave::app::state::WandPose {
        position: glam::Vec3::new(0.1, 1.0, -0.2),
        orientation: glam::Quat::IDENTITY,
    });
    let shown = texts(&driver.frame(&mut state));
    assert!(
        shown
            .iter()
            .any(|t| t == "wand at (0.10, 1.00, -0.20) m, pointing (0.00, 0.00, -1.00)"),
        "{shown:?}"
    );
    assert!(
        shown
            .iter()
            .any(|t| t == "selected: parquet (material 0), 1.00 m along the ray"),
        "{shown:?}"
    );
    driver.click(&mut state, "Show the wand's ray");
    assert!(!state.settings.tracking.show_wand_ray);
    assert!(state.frame_params().wand_ray.is_none(), "the ray is off");
}

/// The eye offset's helper. A viewer whose eyes are at E looks straight at the front
/// wall's centre; the marker tree sits 8 cm above, 1 cm right of and 5 cm behind the eyes. One
/// click (with the offset's forward part already right) finds the offset back, so that the
/// eyes lie on that line of sight (to 0.1 mm).
#[test]
fn the_eye_offset_helper_puts_the_eyes_on_the_line_of_sight() {
    use glam::{Quat, Vec3};
    let mut state = AppState::new(config());
    state.settings.tracking.enabled = true;
    state.settings.tracking.eye_offset = [0.0, 0.0, -0.05];
    let front = state
        .cave()
        .walls
        .iter()
        .find(|w| w.name == "front")
        .expect("front wall")
        .clone();
    let centre = 0.5 * (front.lower_right + front.upper_left);
    // Eyes at E, looking at the centre (yaw and pitch from the direction, no roll).
    let eyes_true = Vec3::new(0.4, 1.75, 0.3);
    let d = (centre - eyes_true).normalize();
    let yaw = (-d.x).atan2(-d.z);
    let pitch = d.y.asin();
    let r = Quat::from_rotation_y(yaw) * Quat::from_rotation_x(pitch);
    assert!((r * Vec3::NEG_Z - d).length() < 1e-5);
    let o_true = Vec3::new(-0.01, -0.08, -0.05);
    let body = (eyes_true - r * o_true, r);
    let mut driver = PanelDriver::new();
    driver.info.tracking.status = Some(omnicave::tracking::TrackingStatus::Tracking);
    driver.info.tracking.source = Some("DTrack on 127.0.0.1:5000".into());
    driver.info.tracking.body = Some(body);
    driver.click(
        &mut state,
        "Viewer looks at the front wall's centre: set the eye offset",
    );
    let o = Vec3::from(state.settings.tracking.eye_offset);
    assert!((o - o_true).length() < 1e-4, "offset {o}, true {o_true}");
    // The eyes: body + R·o; the line of sight: the body's forward axis R·(−z) through them.
    let eyes = body.0 + r * o;
    let off_line = (centre - eyes).cross(r * Vec3::NEG_Z).length();
    assert!(
        off_line < 1e-4,
        "the eyes are {off_line} m off the line of sight"
    );
}

/// The panel plots the last frames' times and tracking latencies.
#[test]
fn the_panel_plots_frame_times_and_tracking_latency() {
    let mut state = AppState::new(config());
    let mut driver = PanelDriver::new();
    for i in 0..400 {
        driver.info.history.record(
            f64::from(i) / 60.0,
            16.0 + f64::from(i % 7),
            (i % 3 != 0).then_some(4.0),
        );
    }
    assert_eq!(
        driver.info.history.frame_ms.len(),
        300,
        "the last 300 frames"
    );
    driver.click(&mut state, "Frame time and tracking latency");
    // Open, the plot is drawn (a widget of its own in the tree) with its legend.
    let nodes = driver.frame(&mut state);
    let labels: Vec<_> = nodes.iter().filter_map(|n| n.label()).collect();
    // The legend's two entries (not the header, whose label holds both words too).
    assert!(labels.contains(&"frame"), "{labels:?}");
    assert!(labels.contains(&"tracking latency"), "{labels:?}");
}

#[test]
fn a_config_saved_before_the_settings_model_still_loads_as_it_was_saved() {
    // tests/data/saved-at-0dd4a4e.toml is what "Save settings" wrote at commit 0dd4a4e (the
    // state of `saved_settings_load_back_as_they_were`, saved by that commit's code; only its
    // absolute asset paths were made relative to the file). It loads into the same state.
    let path =
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/saved-at-0dd4a4e.toml");
    let loaded = AppState::new(Config::load(&path).expect("an old saved config loads"));
    assert_eq!(loaded.settings.render.mode, RenderMode::OmniOnAxis);
    assert_eq!(loaded.settings.cave.eye_separation, 0.07);
    assert_eq!(loaded.criterion(), Some(Criterion::Sphere(12.0)));
    assert!(!loaded.settings.omnistereo.pole_merge);
    assert_eq!(loaded.head_position(), Vec3::new(0.2, 1.5, -0.4));
    assert_eq!(
        loaded.settings.app.preview_output,
        omnicave::output::formats::StereoFormat::RowInterleaved
    );
    assert!(loaded.settings.tracking.enabled);
    assert_eq!(loaded.settings.tracking.filter.beta, 3.5);
    assert_eq!(
        loaded.settings.gamepad.mode,
        omnicave::gamepad::GamepadMode::Head
    );
    assert_eq!(loaded.settings.app.navigation_speed, 4.0);
    // The moved walls: 4 m wide, 3 m high, 3.3 m deep.
    let (min, max) = omnicave::cave::Cave::bounding_box(&loaded.cave().walls);
    assert!(((max - min) - Vec3::new(4.0, 3.0, 3.3)).abs().max_element() < 1e-5);
    assert!(
        loaded
            .config
            .scene_path
            .as_ref()
            .is_some_and(|p| p.is_file()),
        "the scene path resolves"
    );
}

#[test]
fn the_preview_renders_each_wall_at_the_size_it_is_shown() {
    // The preview window reports each wall's size on screen; the next frame renders the
    // walls at that size (never above their resolution), unless full resolution is asked.
    let config = config();
    let scene =
        load_gltf(&std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/living-room.glb"))
            .expect("scene");
    let mut state = AppState::new(config.clone());
    let full = [200, 176];
    assert!(
        state
            .render_cave()
            .walls
            .iter()
            .all(|w| w.resolution == full)
    );
    let mut renderer = Renderer::new(
        common::gpu(),
        state.cave(),
        RenderSettings {
            msaa: 1,
            wireframe: false,
        },
    )
    .expect("renderer");
    renderer.set_scene(&scene).expect("scene");
    let at_full = render(&mut renderer, &state);

    state.set_shown_sizes(&[[100, 88]; 3]);
    assert!(
        state
            .render_cave()
            .walls
            .iter()
            .all(|w| w.resolution == [100, 88])
    );
    let shown = render(&mut renderer, &state);
    for w in &shown {
        assert_eq!(w.left.dimensions(), (100, 88));
    }
    // The same picture at the size shown: against the full-size render averaged over 2×2
    // pixels, only edges differ (sub-pixel positions sample differently): under 6 % of the
    // pixels by more than 24 levels (measured 3.1 %).
    let mut off = 0usize;
    let mut total = 0usize;
    for (small, big) in shown.iter().zip(&at_full) {
        for (s, b) in [(&small.left, &big.left), (&small.right, &big.right)] {
            for (x, y, p) in s.enumerate_pixels() {
                let mean = |c: usize| {
                    let sum: u32 = [(0, 0), (1, 0), (0, 1), (1, 1)]
                        .iter()
                        .map(|(dx, dy)| u32::from(b.get_pixel(2 * x + dx, 2 * y + dy)[c]))
                        .sum();
                    (sum / 4) as i32
                };
                total += 1;
                if (0..3).any(|c| (i32::from(p[c]) - mean(c)).abs() > 24) {
                    off += 1;
                }
            }
        }
    }
    let share = off as f64 / total as f64;
    assert!(share < 0.06, "{share}");

    // Larger than the wall's resolution, or full resolution asked: the configured size.
    let at_full_size = |state: &AppState| {
        state
            .render_cave()
            .walls
            .iter()
            .all(|w| w.resolution == full)
    };
    state.set_shown_sizes(&[[400, 352]; 3]);
    assert!(at_full_size(&state));
    state.settings.app.preview_full_resolution = true;
    state.set_shown_sizes(&[[100, 88]; 3]);
    assert!(at_full_size(&state));
    state.settings.app.preview_full_resolution = false;
    state.set_shown_sizes(&[[100, 88]; 3]);
    // The walls moved from the panel: the rendered walls follow, at the size shown.
    let size = state.base_cave_size() * glam::Vec3::new(1.2, 1.0, 1.0);
    state.set_cave_size(size);
    for (r, w) in state.render_cave().walls.iter().zip(&state.cave().walls) {
        assert_eq!(r.lower_left, w.lower_left);
        assert_eq!(r.resolution, [100, 88]);
    }
}

#[test]
fn the_panel_shows_the_guest_map_for_the_current_mode_from_its_worker() {
    use omnicave::app::guest_map::{GuestMapPose, GuestMapWorker};

    let config = config();
    let scene = std::sync::Arc::new(
        omnicave::setup::load_scene(&config.settings, &common::repo("assets/living-room.glb"))
            .unwrap(),
    );
    let mut state = AppState::new(config);
    state.settings.render.mode = RenderMode::OmniOnAxis;
    let mut driver = PanelDriver::new();
    driver.click(&mut state, "Where guests may stand");
    driver.click(&mut state, "Show the floor map");
    assert!(state.guest_map.show, "the checkbox turns the map on");
    let nodes = driver.frame(&mut state);
    let values: Vec<_> = nodes.iter().filter_map(|n| n.value()).collect();
    assert!(values.contains(&"computing…"), "{values:?}");
    // What the application asks its worker each frame (it never waits for the answer).
    let mut worker = GuestMapWorker::start(scene);
    worker.request(
        state.cave(),
        GuestMapPose {
            head: state.head(),
            mode: state.settings.render.mode,
            ipd: f64::from(state.settings.cave.eye_separation),
            pole_merge: state.settings.omni().pole_merge,
            world_from_cave: state.world_from_cave(),
        },
    );
    let started = std::time::Instant::now();
    let map = loop {
        if let Some(map) = worker.newest() {
            break map;
        }
        assert!(started.elapsed().as_secs() < 60, "no map within a minute");
        std::thread::sleep(std::time::Duration::from_millis(20));
    };
    driver.info.guest_map = Some(std::sync::Arc::new(map));
    let nodes = driver.frame(&mut state);
    let values: Vec<_> = nodes.iter().filter_map(|n| n.value()).collect();
    assert!(
        values
            .iter()
            .any(|v| v.starts_with("omni-onaxis for the head at")),
        "{values:?}"
    );
    assert!(
        values.iter().any(|v| v.starts_with("fusion area")),
        "{values:?}"
    );
    // Another mode: the panel says the shown map is the previous mode's until the next one.
    state.settings.render.mode = RenderMode::Stereo;
    let nodes = driver.frame(&mut state);
    let values: Vec<_> = nodes.iter().filter_map(|n| n.value()).collect();
    assert!(
        values
            .iter()
            .any(|v| v.contains("computing the map for the new mode")),
        "{values:?}"
    );
}

#[test]
fn the_panel_plays_pauses_and_chooses_the_scenes_animation() {
    let mut state = AppState::new(config());
    let mut driver = PanelDriver::new();
    driver.info.animations = vec![("Show".into(), 4.0), ("Wave".into(), 2.0)];
    driver.info.posed = true;
    driver.click(&mut state, "Animation");
    assert!(state.settings.animation.playing);
    // The clock runs at the configured speed while playing, not while paused.
    state.settings.animation.speed = 2.0;
    state.advance_animation(0.25);
    assert!((state.animation_clock - 0.5).abs() < 1e-9);
    driver.click(&mut state, "Pause");
    assert!(!state.settings.animation.playing, "Pause stops the clock");
    state.advance_animation(0.25);
    assert!((state.animation_clock - 0.5).abs() < 1e-9);
    driver.click(&mut state, "Play");
    assert!(state.settings.animation.playing);
    driver.click(&mut state, "Repeat");
    assert!(!state.settings.animation.repeat);
    // Another animation starts from its beginning.
    driver.choose(&mut state, "Animation", "Wave (2.00 s)");
    assert_eq!(state.settings.animation.clip, "Wave");
    assert_eq!(state.animation_clock, 0.0);
    // What the renderer is given: the chosen animation at the clock's time.
    state.animation_clock = 1.25;
    let frame = state.frame_params();
    assert_eq!(frame.animation.clip, "Wave");
    assert_eq!(frame.animation.seconds, 1.25);
    assert!(!frame.animation.repeat);
}
