//! The egui control panel: every run-time setting, frame statistics, saving; and the F1 key map.

use egui::{ComboBox, Slider, Ui};

use super::devices::TrackingInfo;
use super::keys::KEY_MAP;
use super::state::{AppState, CriterionKind, MAX_EYE_SEPARATION};
use super::stats::StatsSummary;
use crate::cave::RenderMode;
use crate::cave::omni::WarpVariant;
use crate::gamepad::GamepadMode;
use crate::output::formats::StereoFormat;
use crate::pano::{PanoRoute, PanoStereo, Projection};
use crate::sky::SkyMode;
use crate::tracking::TrackingStatus;

/// What the panel shows but does not change.
#[derive(Debug, Clone, Default)]
pub struct PanelInfo {
    pub adapter: String,
    pub stats: StatsSummary,
    /// Whether GPU times are measured (adapter timestamps).
    pub gpu_timing: bool,
    /// Triangles submitted for each wall (scene triangles × views of a wall).
    pub triangles_per_wall: usize,
    /// Per wall (in wall order): triangles the tessellator emitted, when last read (button).
    pub tess_emitted: Option<Vec<u32>>,
    /// Whether the scene has a sky loaded.
    pub has_sky: bool,
    /// Whether this device can tessellate.
    pub tessellation_supported: bool,
    /// True in CAVE mode (one output format per wall window), false in the preview.
    pub cave_mode: bool,
    /// Result of the last save (shown under the button).
    pub save_message: Option<String>,
    /// OSC tracking and gamepads.
    pub tracking: TrackingInfo,
}

/// Requests from the panel that need the app (not just state changes).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct PanelRequests {
    /// Read the tessellator's per-view counts once (a blocking read, on demand only).
    pub read_tess_counts: bool,
}

/// A drop-down labelled `label` choosing `value` among `all`, each shown by `name`.
fn combo<T: Copy + PartialEq>(
    ui: &mut Ui,
    label: &str,
    value: &mut T,
    all: &[T],
    name: fn(T) -> &'static str,
) {
    ComboBox::from_label(label)
        .selected_text(name(*value))
        .show_ui(ui, |ui| {
            for &item in all {
                ui.selectable_value(value, item, name(item));
            }
        });
}

/// Draws the whole panel into `ui` (scrolls when the window is short).
pub fn panel_ui(ui: &mut Ui, state: &mut AppState, info: &PanelInfo) -> PanelRequests {
    let mut requests = PanelRequests::default();
    egui::ScrollArea::vertical().show(ui, |ui| {
        ui.heading("omnicave");
        stats_section(ui, state, info, &mut requests);
        ui.separator();
        render_section(ui, state, info);
        ui.separator();
        tessellation_section(ui, state, info);
        ui.separator();
        head_and_cave_section(ui, state);
        ui.separator();
        tracking_section(ui, state, &info.tracking);
        ui.separator();
        output_section(ui, state, info);
        ui.separator();
        panorama_section(ui, state, info);
        ui.separator();
        ui.horizontal(|ui| {
            if ui.button("Save settings").clicked() {
                state.save_requested = true;
            }
            if ui.button("Key map (F1)").clicked() {
                state.show_help = !state.show_help;
            }
            if ui.button("Quit").clicked() {
                state.quit_requested = true;
            }
        });
        ui.label(format!("save to: {}", state.save_path.display()));
        if let Some(message) = &info.save_message {
            ui.label(message);
        }
    });
    requests
}

fn stats_section(ui: &mut Ui, state: &AppState, info: &PanelInfo, requests: &mut PanelRequests) {
    let s = &info.stats;
    ui.label(format!("GPU: {}", info.adapter));
    ui.label(format!("{:.1} fps   frame {:.1} ms", s.fps, s.frame_ms));
    let gpu = match (info.gpu_timing, s.gpu_ms) {
        (true, Some(g)) => format!("{g:.2} ms"),
        (true, None) => "waiting".to_owned(),
        (false, _) => "n/a (no timestamps)".to_owned(),
    };
    ui.label(format!("CPU {:.2} ms   GPU {gpu}", s.cpu_ms));
    // Tracking's state at the top, where an operator looks first.
    if state.tracking_on {
        match (&info.tracking.error, tracking_status(&info.tracking)) {
            (Some(e), _) => {
                ui.colored_label(egui::Color32::LIGHT_RED, format!("OSC: {e}"));
            }
            (None, Some((colour, text))) => {
                ui.colored_label(colour, format!("OSC: {text}"));
            }
            (None, None) => {}
        }
    }
    egui::Grid::new("triangles").striped(true).show(ui, |ui| {
        ui.label("wall");
        ui.label("submitted");
        ui.label("tessellated");
        ui.end_row();
        for (i, wall) in state.cave().walls.iter().enumerate() {
            ui.label(&wall.name);
            ui.label(info.triangles_per_wall.to_string());
            let emitted = info
                .tess_emitted
                .as_ref()
                .and_then(|t| t.get(i))
                .map_or_else(|| "–".to_owned(), u32::to_string);
            ui.label(emitted);
            ui.end_row();
        }
    });
    if ui.button("Read tessellation counts").clicked() {
        requests.read_tess_counts = true;
    }
}

fn render_section(ui: &mut Ui, state: &mut AppState, info: &PanelInfo) {
    combo(
        ui,
        "Render mode",
        &mut state.mode,
        &RenderMode::ALL,
        RenderMode::name,
    );
    combo(
        ui,
        "Warp",
        &mut state.warp,
        &WarpVariant::ALL,
        WarpVariant::name,
    );
    ui.checkbox(&mut state.pole_merge_on, "Pole merge");
    ui.add_enabled_ui(state.pole_merge_on, |ui| {
        ui.add(Slider::new(&mut state.pole_merge.start_degrees, 0.0..=90.0).text("merge start °"));
        let start = state.pole_merge.start_degrees;
        ui.add(Slider::new(&mut state.pole_merge.end_degrees, start..=90.0).text("merge end °"));
    });
    ui.add(
        Slider::new(&mut state.eye_separation, 0.0..=MAX_EYE_SEPARATION)
            .text("eye separation m")
            .step_by(0.001),
    );
    ui.add_enabled_ui(info.has_sky, |ui| {
        combo(
            ui,
            "Skybox",
            &mut state.sky_mode,
            &SkyMode::ALL,
            SkyMode::name,
        );
    });
    ui.checkbox(&mut state.wireframe, "Wireframe");
    ui.horizontal(|ui| {
        ui.label("MSAA");
        ui.radio_value(&mut state.msaa, 1, "off");
        ui.radio_value(&mut state.msaa, 4, "4×");
    });
}

fn tessellation_section(ui: &mut Ui, state: &mut AppState, info: &PanelInfo) {
    ui.add_enabled_ui(info.tessellation_supported, |ui| {
        ui.checkbox(&mut state.tess_on, "Adaptive tessellation");
        ui.add_enabled_ui(state.tess_on, |ui| {
            combo(
                ui,
                "Criterion",
                &mut state.tess_kind,
                &CriterionKind::ALL,
                CriterionKind::name,
            );
            let range = state.tess_kind.range();
            let uniform = state.tess_kind == CriterionKind::Uniform;
            let mut slider = Slider::new(state.tess_value_mut(), range).text("parameter");
            if uniform {
                slider = slider.step_by(1.0);
            } else {
                slider = slider.logarithmic(true);
            }
            ui.add(slider);
            ui.add(
                Slider::new(&mut state.tess_max_depth, 0..=crate::tess::MAX_DEPTH_LIMIT)
                    .text("max depth"),
            );
            ui.checkbox(&mut state.tess_backface_cull, "Back-face cull");
            ui.checkbox(&mut state.tess_frustum_cull, "Frustum cull");
        });
    });
}

fn head_and_cave_section(ui: &mut Ui, state: &mut AppState) {
    ui.label("Head (CAVE space, m)");
    let mut head = state.head_position;
    let size = state.cave_size;
    let mut changed = false;
    for (axis, name) in ["x", "y", "z"].iter().enumerate() {
        let half = size[axis].max(0.1) / 2.0;
        let range = if axis == 1 {
            0.0..=size[1].max(0.1)
        } else {
            -half..=half
        };
        changed |= ui
            .add(Slider::new(&mut head[axis], range).text(format!("head {name}")))
            .changed();
    }
    if changed {
        // A slider move that would put the head behind a wall is not taken.
        let _ = state.set_head_position(head);
    }
    ui.add(Slider::new(&mut state.head_yaw_degrees, -180.0..=180.0).text("head yaw ° (tracked)"));
    ui.label("CAVE size (walls move live, m)");
    let mut size = state.cave_size;
    let base = state.base_cave_size();
    let mut resized = false;
    for (axis, name) in ["width", "height", "depth"].iter().enumerate() {
        if base[axis] > 1e-6 {
            resized |= ui
                .add(Slider::new(&mut size[axis], 0.5..=(base[axis] * 3.0).max(1.0)).text(*name))
                .changed();
        }
    }
    if resized {
        state.set_cave_size(size);
    }
    ui.horizontal(|ui| {
        if ui.button("Reset view").clicked() {
            state.apply(super::state::Action::ResetView);
        }
        ui.label(format!(
            "navigation: ({:.2}, {:.2}, {:.2}) m, {:.0}°",
            state.navigation.position.x,
            state.navigation.position.y,
            state.navigation.position.z,
            state.navigation.yaw.to_degrees()
        ));
    });
}

/// The tracking status line and its colour (`None` while the receiver is not running).
fn tracking_status(info: &TrackingInfo) -> Option<(egui::Color32, String)> {
    let status = info.status?;
    let text = match (status, info.lost_for) {
        (TrackingStatus::Lost | TrackingStatus::NotVisible, Some(s)) => {
            format!(
                "{} for {s:.1} s: head holds its last pose",
                status.describe()
            )
        }
        _ => status.describe().to_owned(),
    };
    let colour = match status {
        TrackingStatus::Tracking => egui::Color32::LIGHT_GREEN,
        TrackingStatus::Waiting => egui::Color32::LIGHT_YELLOW,
        TrackingStatus::Lost | TrackingStatus::NotVisible => egui::Color32::LIGHT_RED,
    };
    Some((colour, text))
}

fn tracking_section(ui: &mut Ui, state: &mut AppState, info: &TrackingInfo) {
    ui.checkbox(&mut state.tracking_on, "Use OSC tracking");
    if let Some(error) = &info.error {
        ui.colored_label(egui::Color32::LIGHT_RED, error);
    }
    if state.tracking_on
        && let (Some(address), Some((colour, text))) = (info.listening, tracking_status(info))
    {
        ui.label(format!("listening on {address}"));
        ui.colored_label(colour, text);
        let s = &info.stats;
        ui.label(format!(
            "{:.0} Hz, latency {:.1} ms avg, {:.1} ms max ({:.2} frame)",
            s.rate_hz, s.latency_avg_ms, s.latency_max_ms, s.latency_max_frames
        ));
        let c = &info.counters;
        ui.label(format!(
            "packets {} · accepted {} · ignored {} · malformed {} · non-finite {} · refused {} \
             · clamped {}",
            c.received, c.accepted, c.ignored, c.malformed, c.non_finite, c.refused, s.clamped
        ));
    }
    ui.checkbox(&mut state.tracking_filter_on, "One Euro filter");
    ui.add_enabled_ui(state.tracking_filter_on, |ui| {
        let f = &mut state.tracking_filter;
        ui.add(
            Slider::new(&mut f.min_cutoff_hz, 0.01..=20.0)
                .logarithmic(true)
                .text("min cutoff Hz"),
        );
        ui.add(
            Slider::new(&mut f.beta, 0.0..=100.0)
                .logarithmic(true)
                .text("beta"),
        );
        ui.add(
            Slider::new(&mut f.derivative_cutoff_hz, 0.01..=20.0)
                .logarithmic(true)
                .text("speed cutoff Hz"),
        );
    });
    ui.label("Gamepad");
    match (&info.gamepad_error, info.gamepads.is_empty()) {
        (Some(e), _) => {
            ui.label(e);
        }
        (None, true) => {
            ui.label("no gamepad connected");
        }
        (None, false) => {
            ui.label(info.gamepads.join(", "));
        }
    }
    combo(
        ui,
        "Sticks drive",
        &mut state.gamepad_mode,
        &GamepadMode::ALL,
        GamepadMode::name,
    );
    ui.add(
        Slider::new(
            &mut state.navigation_speed,
            super::state::MIN_NAVIGATION_SPEED..=super::state::MAX_NAVIGATION_SPEED,
        )
        .logarithmic(true)
        .text("navigation m/s"),
    );
}

fn output_section(ui: &mut Ui, state: &mut AppState, info: &PanelInfo) {
    let format_combo = |ui: &mut Ui, label: &str, format: &mut StereoFormat| {
        combo(ui, label, format, &StereoFormat::ALL, StereoFormat::name);
    };
    if info.cave_mode {
        let names: Vec<String> = state.cave().walls.iter().map(|w| w.name.clone()).collect();
        for (name, format) in names.iter().zip(state.wall_outputs.iter_mut()) {
            format_combo(ui, &format!("output {name}"), format);
        }
    } else {
        format_combo(ui, "Preview output", &mut state.preview_output);
    }
    ui.checkbox(&mut state.swap_eyes, "Swap eyes");
}

/// The panorama view: what it shows and how it is drawn.
fn panorama_section(ui: &mut Ui, state: &mut AppState, info: &PanelInfo) {
    ui.checkbox(
        &mut state.panorama_on,
        if info.cave_mode {
            "Panorama view (operator window)"
        } else {
            "Panorama view"
        },
    );
    // Choosing "volume" uses the configured parameters.
    let [ioid, d, offset] = state.panorama_volume;
    let volume = PanoStereo::Volume { ioid, d, offset };
    let pano = &mut state.panorama;
    ui.add_enabled_ui(state.panorama_on, |ui| {
        combo(
            ui,
            "Projection",
            &mut pano.projection,
            &Projection::ALL,
            Projection::name,
        );
        let (max_h, max_v) = pano.projection.max_fov();
        let mut h = pano.h_fov.to_degrees().min(max_h.to_degrees());
        let mut v = pano.v_fov.to_degrees().min(max_v.to_degrees());
        // Ranges that hold every value the config accepts: a slider clamps what it shows.
        ui.add(Slider::new(&mut h, 1.0..=max_h.to_degrees()).text("horizontal FoV °"));
        ui.add(Slider::new(&mut v, 1.0..=max_v.to_degrees()).text("vertical FoV °"));
        pano.h_fov = h.to_radians();
        pano.v_fov = v.to_radians();
        // The same direction, shown within ±180°.
        let mut yaw = crate::pano::wrap_degrees(pano.yaw.to_degrees());
        ui.add(Slider::new(&mut yaw, -180.0..=180.0).text("turn °"));
        pano.yaw = yaw.to_radians();
        let geometric = pano.projection.geometric() && info.tessellation_supported;
        ui.horizontal(|ui| {
            ui.label("Route");
            ui.add_enabled_ui(geometric, |ui| {
                ui.radio_value(&mut pano.route, PanoRoute::Geometric, "geometric");
            });
            ui.radio_value(&mut pano.route, PanoRoute::Image, "image (cube map)");
        });
        if !geometric && pano.route == PanoRoute::Geometric {
            ui.label("this projection is drawn by the image route");
        }
        ui.add_enabled_ui(pano.effective_route() == PanoRoute::Geometric, |ui| {
            let stereos = [PanoStereo::Mono, volume, PanoStereo::Omni];
            let mut chosen = stereos
                .iter()
                .position(|s| s.name() == pano.stereo.name())
                .unwrap_or(0);
            ComboBox::from_label("Panorama stereo")
                .selected_text(stereos[chosen].name())
                .show_ui(ui, |ui| {
                    for (i, s) in stereos.iter().enumerate() {
                        ui.selectable_value(&mut chosen, i, s.name());
                    }
                });
            // Keep the volume stereo's own parameters when it stays selected.
            if stereos[chosen].name() != pano.stereo.name() {
                pano.stereo = stereos[chosen];
            }
        });
    });
}

/// The F1 key map as a floating window.
pub fn help_window(ctx: &egui::Context, open: &mut bool) {
    egui::Window::new("Key map")
        .open(open)
        .resizable(false)
        .show(ctx, |ui| {
            egui::Grid::new("keys").striped(true).show(ui, |ui| {
                for (key, what) in KEY_MAP {
                    ui.label(*key);
                    ui.label(*what);
                    ui.end_row();
                }
            });
        });
}
