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
use crate::pano::{PanoRoute, PanoStereoKind, Projection};
use crate::scene::Shading;
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
    /// Per wall (in wall order): triangles the tessellator emitted for both eyes, from the
    /// newest frame read back (empty while the frame is not tessellated).
    pub tess_emitted: Vec<u32>,
    /// Why the newest frame read back is less refined than asked (its budget ran out).
    pub tess_shortfall: Option<String>,
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
    /// Frame times and tracking latencies of the last frames, for the plot.
    pub history: super::stats::TimingHistory,
    /// Where the newest timed frame's GPU time went, per stage and view.
    pub breakdown: crate::render::FrameBreakdown,
    /// Compute dispatches and drawn triangles (all views) of the last frame.
    pub dispatches: usize,
    pub triangles_drawn: usize,
    /// Of those, drawn directly (clusters that need no refinement) in a tessellated frame.
    pub fine_triangles: usize,
    /// Cluster mode (master): the frame's broadcast and barrier, and every node.
    pub cluster: Option<ClusterInfo>,
    /// The newest floor map of where guests may stand (while the panel shows it).
    pub guest_map: Option<std::sync::Arc<super::guest_map::GuestMap>>,
    /// The scene's animations: name and length, seconds.
    pub animations: Vec<(String, f32)>,
    /// Whether anything in the scene is posed (skins, morph targets, animated nodes).
    pub posed: bool,
}

/// The master's view of the cluster, for the panel.
#[derive(Debug, Clone, Default)]
pub struct ClusterInfo {
    pub figures: crate::cluster::MasterFigures,
    /// Every process (index = rank; 0 the master).
    pub nodes: Vec<crate::cluster::NodeStatus>,
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

/// Where guests may stand: the current mode's floor map for the current head (computed off
/// the render thread; the newest finished one is shown).
fn guests_section(ui: &mut Ui, state: &mut AppState, info: &PanelInfo) {
    use crate::guests::heatmap::{Metric, Scale, colour_rgb};

    egui::CollapsingHeader::new("Where guests may stand").show(ui, |ui| {
        ui.checkbox(&mut state.guest_map.show, "Show the floor map");
        if !state.guest_map.show {
            return;
        }
        combo(
            ui,
            "Map metric",
            &mut state.guest_map.metric,
            &Metric::ALL,
            Metric::name,
        );
        let Some(map) = &info.guest_map else {
            ui.label("computing…");
            return;
        };
        let metric = state.guest_map.metric;
        let scale = Scale::shared(metric, std::slice::from_ref(&map.map), &map.limits);
        let grid = &map.grid;
        let cell = (240.0 / grid.columns.max(grid.rows).max(1) as f32).max(1.0);
        let size = egui::vec2(cell * grid.columns as f32, cell * grid.rows as f32);
        let (response, painter) = ui.allocate_painter(size, egui::Sense::hover());
        let origin = response.rect.min;
        let x0 = grid.first[0] - 0.5 * grid.step;
        let z0 = grid.first[1] - 0.5 * grid.step;
        let to_screen = |x: f64, z: f64| {
            origin
                + egui::vec2(
                    ((x - x0) / grid.step) as f32 * cell,
                    ((z - z0) / grid.step) as f32 * cell,
                )
        };
        for (index, figures) in map.map.cells.iter().enumerate() {
            let v = grid.viewer(index);
            let fill = match figures {
                Some(f) => {
                    let [r, g, b] = colour_rgb(metric, scale.position(metric.of(f)));
                    egui::Color32::from_rgb(r, g, b)
                }
                None if grid.inside[index] => egui::Color32::GRAY,
                None => continue,
            };
            let min = to_screen(v.x - 0.5 * grid.step, v.z - 0.5 * grid.step);
            painter.rect_filled(egui::Rect::from_min_size(min, egui::vec2(cell, cell)), 0.0, fill);
        }
        for wall in &map.request.cave.walls {
            let (a, b) = (wall.lower_left.as_dvec3(), wall.lower_right.as_dvec3());
            painter.line_segment(
                [to_screen(a.x, a.z), to_screen(b.x, b.z)],
                egui::Stroke::new(3.0, egui::Color32::BLACK),
            );
        }
        painter.circle(
            to_screen(map.head.x, map.head.z),
            4.0,
            egui::Color32::WHITE,
            egui::Stroke::new(1.0, egui::Color32::BLACK),
        );
        ui.label(format!(
            "{} for the head at ({:.2}, {:.2}) m: {}; scale {:.3} to {:.3}",
            map.request.pose.mode.name(),
            map.head.x,
            map.head.z,
            metric.title(),
            scale.lo,
            scale.hi,
        ));
        ui.label(format!(
            "fusion area {:.2} m² (p95 vertical < {} arcmin); sweet area within reach {:.4} m² (and direction < {}°); {} points, {:.2} s",
            map.map.sweet_area(grid, &map.limits.fusion_only()),
            map.limits.vertical_arcmin,
            map.map.reach_area_m2,
            map.limits.direction_degrees,
            map.map.shown_points,
            map.seconds
        ));
        if map.request.pose.mode != state.settings.render.mode {
            ui.label("(computing the map for the new mode…)");
        }
    });
}

/// Draws the whole panel into `ui` (scrolls when the window is short).
pub fn panel_ui(ui: &mut Ui, state: &mut AppState, info: &PanelInfo) {
    egui::ScrollArea::vertical().show(ui, |ui| {
        ui.heading("omnicave");
        stats_section(ui, state, info);
        timing_plot(ui, info);
        if let Some(cluster) = &info.cluster {
            cluster_section(ui, cluster);
        }
        ui.separator();
        render_section(ui, state, info);
        ui.separator();
        tessellation_section(ui, state, info);
        ui.separator();
        head_and_cave_section(ui, state);
        ui.separator();
        guests_section(ui, state, info);
        ui.separator();
        animation_section(ui, state, info);
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
}

/// Cluster mode: this frame's broadcast and barrier on the master, and each node's figures
/// (or why it was lost).
fn cluster_section(ui: &mut Ui, cluster: &ClusterInfo) {
    egui::CollapsingHeader::new("Cluster")
        .default_open(true)
        .show(ui, |ui| {
            let f = &cluster.figures;
            ui.label(format!(
                "frame {}: broadcast {:.3} ms, barrier wait {:.3} ms (master)",
                f.frame, f.broadcast_ms, f.barrier_ms
            ));
            for node in cluster.nodes.iter().skip(1) {
                let text = match &node.lost {
                    Some(why) => format!("{}: LOST ({why})", node.describe()),
                    None => format!(
                        "{}: state wait {:.2} ms, barrier wait {:.3} ms, render {:.2} ms",
                        node.describe(),
                        node.figures.state_wait_ms,
                        node.figures.barrier_ms,
                        node.figures.render_ms
                    ),
                };
                if node.lost.is_some() {
                    ui.colored_label(egui::Color32::from_rgb(230, 80, 60), text);
                } else {
                    ui.label(text);
                }
            }
        });
}

/// Frame times and tracking latencies of the last frames, one line each (ms over seconds).
fn timing_plot(ui: &mut Ui, info: &PanelInfo) {
    egui::CollapsingHeader::new("Frame time and tracking latency")
        .default_open(false)
        .show(ui, |ui| {
            let h = &info.history;
            egui_plot::Plot::new("timing")
                .height(120.0)
                .legend(egui_plot::Legend::default())
                .y_axis_label("ms")
                .show(ui, |plot| {
                    plot.line(egui_plot::Line::new("frame", &h.frame_ms[..]));
                    plot.line(egui_plot::Line::new("tracking latency", &h.latency_ms[..]));
                });
        });
}

/// GPU time per stage of the newest timed frame: a row per stage, a column per view.
fn gpu_stages(ui: &mut Ui, state: &AppState, info: &PanelInfo) {
    let b = &info.breakdown;
    ui.label(format!(
        "{} dispatches, {} triangles drawn per frame ({} of them directly, needing no \
         refinement)",
        info.dispatches, info.triangles_drawn, info.fine_triangles
    ));
    if b.views.is_empty() {
        return;
    }
    egui::CollapsingHeader::new("GPU time per stage (ms)")
        .default_open(false)
        .show(ui, |ui| {
            if !b.inside_passes {
                ui.label("no timestamps inside passes here: tessellation under 'tess cull', the pass under 'scene'");
            }
            let walls = &state.render_cave().walls;
            egui::Grid::new("gpu_stages").striped(true).show(ui, |ui| {
                ui.label("stage");
                ui.label("all");
                for (i, _) in b.views.iter().enumerate() {
                    // Views come wall by wall, left eye first (mono: one per wall).
                    let per_wall = if b.views.len() > walls.len() { 2 } else { 1 };
                    let name = walls.get(i / per_wall).map_or("?", |w| w.name.as_str());
                    let eye = match (per_wall, i % 2) {
                        (1, _) => "",
                        (_, 0) => " L",
                        _ => " R",
                    };
                    ui.label(format!("{name}{eye}"));
                }
                ui.end_row();
                ui.label("pose");
                ui.label(format!("{:.2}", b.pose_ms));
                ui.end_row();
                ui.label("shadows");
                ui.label(format!("{:.2}", b.shadows_ms));
                ui.end_row();
                for stage in crate::render::ViewStage::ALL {
                    ui.label(stage.name());
                    ui.label(format!("{:.2}", b.stage_ms(stage)));
                    for v in &b.views {
                        ui.label(format!("{:.2}", v[stage as usize]));
                    }
                    ui.end_row();
                }
            });
        });
}

fn stats_section(ui: &mut Ui, state: &AppState, info: &PanelInfo) {
    let s = &info.stats;
    ui.label(format!("GPU: {}", info.adapter));
    ui.label(format!("{:.1} fps   frame {:.1} ms", s.fps, s.frame_ms));
    let gpu = match (info.gpu_timing, s.gpu_ms) {
        (true, Some(g)) => format!("{g:.2} ms"),
        (true, None) => "waiting".to_owned(),
        (false, _) => "n/a (no timestamps)".to_owned(),
    };
    ui.label(format!("CPU {:.2} ms   GPU {gpu}", s.cpu_ms));
    gpu_stages(ui, state, info);
    // Tracking's state at the top, where an operator looks first.
    if state.settings.tracking.enabled {
        match (&info.tracking.error, tracking_status(&info.tracking)) {
            (Some(e), _) => {
                ui.colored_label(egui::Color32::LIGHT_RED, format!("Tracking: {e}"));
            }
            (None, Some((colour, text))) => {
                ui.colored_label(colour, format!("Tracking: {text}"));
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
                .get(i)
                .map_or_else(|| "–".to_owned(), u32::to_string);
            ui.label(emitted);
            ui.end_row();
        }
    });
    if let Some(note) = &info.tess_shortfall {
        ui.colored_label(egui::Color32::YELLOW, format!("Tessellation: {note}"));
    }
}

/// Settings whose slider takes its range from the settings model.
const POLE_MERGE_START: &str = "omnistereo.pole_merge_start_degrees";
const PANO_H_FOV: &str = "panorama.h_fov_degrees";
const PANO_V_FOV: &str = "panorama.v_fov_degrees";
const SHADOW_OFFSET: &str = "shadows.normal_offset_texels";
const ANIMATION_SPEED: &str = "animation.speed";

/// The model's range of the setting at `path` (the one declared beside it in the config's
/// settings model), for a slider (a test checks every path used here has one).
fn model_range(path: &str) -> std::ops::RangeInclusive<f32> {
    crate::config::bounds(path).map_or(0.0..=1.0, |b| b.f32_range())
}

fn render_section(ui: &mut Ui, state: &mut AppState, info: &PanelInfo) {
    let s = &mut state.settings;
    combo(
        ui,
        "Render mode",
        &mut s.render.mode,
        &RenderMode::ALL,
        RenderMode::name,
    );
    combo(
        ui,
        "Shading",
        &mut s.render.shading,
        &Shading::ALL,
        Shading::name,
    );
    let o = &mut s.omnistereo;
    combo(
        ui,
        "Warp",
        &mut o.warp,
        &WarpVariant::ALL,
        WarpVariant::name,
    );
    ui.checkbox(&mut o.pole_merge, "Pole merge");
    ui.add_enabled_ui(o.pole_merge, |ui| {
        let range = model_range(POLE_MERGE_START);
        ui.add(Slider::new(&mut o.pole_merge_start_degrees, range.clone()).text("merge start °"));
        let end = o.pole_merge_start_degrees..=*range.end();
        ui.add(Slider::new(&mut o.pole_merge_end_degrees, end).text("merge end °"));
    });
    ui.add(
        Slider::new(&mut s.cave.eye_separation, 0.0..=MAX_EYE_SEPARATION)
            .text("eye separation m")
            .step_by(0.001),
    );
    ui.add_enabled_ui(info.has_sky, |ui| {
        combo(
            ui,
            "Skybox",
            &mut s.skybox.mode,
            &SkyMode::ALL,
            SkyMode::name,
        );
    });
    let shadows = &mut s.shadows;
    ui.horizontal(|ui| {
        ui.checkbox(&mut shadows.enabled, "Shadows");
        ui.add_enabled(
            shadows.enabled,
            egui::Checkbox::new(&mut shadows.pcf, "soft edges"),
        );
        ui.add_enabled(
            shadows.enabled && shadows.pcf,
            egui::Checkbox::new(&mut shadows.pcf_range_test, "range test"),
        )
        .on_hover_text(
            "filter only where the point's depth lies within its shadow-map tile's depth range \
             (the same picture, faster)",
        );
    });
    ui.add_enabled_ui(shadows.enabled, |ui| {
        let range = model_range(SHADOW_OFFSET);
        ui.add(Slider::new(&mut shadows.normal_offset_texels, range).text("shadow offset texels"));
    });
    ui.checkbox(&mut s.render.wireframe, "Wireframe");
    ui.horizontal(|ui| {
        ui.label("MSAA");
        ui.radio_value(&mut s.render.msaa, 1, "off");
        ui.radio_value(&mut s.render.msaa, 4, "4×");
    });
}

fn tessellation_section(ui: &mut Ui, state: &mut AppState, info: &PanelInfo) {
    ui.add_enabled_ui(info.tessellation_supported, |ui| {
        let mut on = state.tess_on();
        ui.checkbox(&mut on, "Adaptive tessellation");
        ui.add_enabled_ui(on, |ui| {
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
            let t = &mut state.settings.tessellation;
            ui.add(
                Slider::new(&mut t.max_depth, 0..=crate::tess::MAX_DEPTH_LIMIT).text("max depth"),
            );
            ui.checkbox(&mut t.backface_cull, "Back-face cull");
            ui.checkbox(&mut t.frustum_cull, "Frustum cull");
            ui.checkbox(&mut t.skip_fine, "Draw what needs no refining directly");
            ui.checkbox(&mut t.shared_eyes, "One refinement for both eyes of a wall");
        });
        // The kind and parameter above apply while tessellation is on.
        state.set_tess_on(on);
    });
}

fn head_and_cave_section(ui: &mut Ui, state: &mut AppState) {
    ui.label("Head (CAVE space, m)");
    let mut head = state.head_position();
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
    // The same direction shown within ±180° (the config allows ±360°): written back only when
    // moved, so showing the panel never changes a configured yaw.
    let mut yaw = crate::pano::wrap_degrees(state.settings.head.yaw_degrees);
    if ui
        .add(Slider::new(&mut yaw, -180.0..=180.0).text("head yaw ° (tracked)"))
        .changed()
    {
        state.settings.head.yaw_degrees = yaw;
    }
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
    let mut text = match (status, info.lost_for) {
        (TrackingStatus::Lost | TrackingStatus::NotVisible, Some(s)) => {
            format!(
                "{} for {s:.1} s: head holds its last pose",
                status.describe()
            )
        }
        _ => status.describe().to_owned(),
    };
    // Whether anything is being done about it: a connection being made again, or one up
    // with no data (the tracker itself stopped), or a port listened on.
    if status != TrackingStatus::Tracking
        && let Some(link) = &info.link
    {
        text = format!("{text} ({})", link.describe());
    }
    let colour = match status {
        TrackingStatus::Tracking => egui::Color32::LIGHT_GREEN,
        TrackingStatus::Waiting => egui::Color32::LIGHT_YELLOW,
        TrackingStatus::Lost | TrackingStatus::NotVisible => egui::Color32::LIGHT_RED,
    };
    Some((colour, text))
}

/// The eye offset and its calibration: the viewer looks straight at the front wall's centre
/// (or the first wall's), and the offset is set so that the eyes lie on that line of sight.
fn eye_offset_helper(ui: &mut Ui, state: &mut AppState, info: &TrackingInfo) {
    let [x, y, z] = state.settings.tracking.eye_offset;
    ui.label(format!(
        "eye offset ({:.3}, {:.3}, {:.3}) m from the tracked body",
        x, y, z
    ));
    let walls = &state.cave().walls;
    let target = walls
        .iter()
        .find(|w| w.name == "front")
        .or_else(|| walls.first())
        .map(|w| (w.name.clone(), 0.5 * (w.lower_right + w.upper_left)));
    let (Some(body), Some((name, centre))) = (info.body, target) else {
        return;
    };
    if ui
        .button(format!(
            "Viewer looks at the {name} wall's centre: set the eye offset"
        ))
        .on_hover_text("Sets the offset's sideways and vertical parts; its forward part stays")
        .clicked()
    {
        let o = crate::tracking::HeadTracker::eye_offset_looking_at(body, centre, z);
        if o.is_finite() && o.length() <= 0.5 {
            state.settings.tracking.eye_offset = o.to_array();
            tracing::info!("eye offset set to ({:.3}, {:.3}, {:.3}) m", o.x, o.y, o.z);
        } else {
            tracing::warn!("eye offset not set: {o} is more than 0.5 m from the tracked body");
        }
    }
}

fn tracking_section(ui: &mut Ui, state: &mut AppState, info: &TrackingInfo) {
    let settings = &mut state.settings;
    let source = settings.tracking.source.name();
    ui.checkbox(
        &mut settings.tracking.enabled,
        format!("Use tracking ({source})"),
    );
    if let Some(error) = &info.error {
        ui.colored_label(egui::Color32::LIGHT_RED, error);
    }
    if settings.tracking.enabled
        && let (Some(source), Some((colour, text))) = (&info.source, tracking_status(info))
    {
        ui.label(source);
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
            c.received, c.accepted, c.ignored, c.malformed, c.non_finite, c.refused, s.clamped,
        ));
        let g = &c.gate;
        ui.label(format!(
            "samples refused: {} · tracking lost {} times",
            g.describe(),
            s.lost_events
        ));
        for (stream, senders) in &info.senders {
            let Some(owner) = senders.owner else { continue };
            match senders.conflicting {
                Some(other) => ui.colored_label(
                    egui::Color32::YELLOW,
                    format!("{}: from {owner}; refusing {other}", stream.name()),
                ),
                None => ui.label(format!("{}: from {owner}", stream.name())),
            };
        }
        if let Some(warning) = &info.open_warning {
            ui.colored_label(egui::Color32::YELLOW, warning);
        }
        match state.wand {
            Some(w) => {
                let d = w.orientation * glam::Vec3::NEG_Z;
                ui.label(format!(
                    "wand at ({:.2}, {:.2}, {:.2}) m, pointing ({:.2}, {:.2}, {:.2})",
                    w.position.x, w.position.y, w.position.z, d.x, d.y, d.z
                ));
            }
            None => {
                ui.label("no wand tracked");
            }
        }
        if let Some(s) = &info.selection {
            ui.label(format!("selected: {s}"));
        }
        ui.checkbox(&mut settings.tracking.show_wand_ray, "Show the wand's ray");
    }
    let f = &mut settings.tracking.filter;
    ui.checkbox(&mut f.enabled, "One Euro filter");
    ui.add_enabled_ui(f.enabled, |ui| {
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
        &mut settings.gamepad.mode,
        &GamepadMode::ALL,
        GamepadMode::name,
    );
    ui.add(
        Slider::new(
            &mut settings.app.navigation_speed,
            super::state::MIN_NAVIGATION_SPEED..=super::state::MAX_NAVIGATION_SPEED,
        )
        .logarithmic(true)
        .text("navigation m/s"),
    );
    if state.settings.tracking.enabled {
        eye_offset_helper(ui, state, info);
    }
}

fn output_section(ui: &mut Ui, state: &mut AppState, info: &PanelInfo) {
    let format_combo = |ui: &mut Ui, label: &str, format: &mut StereoFormat| {
        combo(ui, label, format, &StereoFormat::ALL, StereoFormat::name);
    };
    let s = &mut state.settings;
    if info.cave_mode {
        let default = s.app.wall_output;
        for wall in &mut s.walls {
            let mut format = wall.format().unwrap_or(default);
            format_combo(ui, &format!("output {}", wall.name), &mut format);
            if format != wall.format().unwrap_or(default) {
                wall.set_format(format);
            }
        }
    } else {
        format_combo(ui, "Preview output", &mut s.app.preview_output);
        ui.checkbox(
            &mut s.app.preview_full_resolution,
            "Full resolution (else the size shown)",
        );
    }
    ui.checkbox(&mut state.swap_eyes, "Swap eyes");
}

/// The animation clock: which animation, play or pause, speed, repeat, and a seek slider.
fn animation_section(ui: &mut Ui, state: &mut AppState, info: &PanelInfo) {
    egui::CollapsingHeader::new("Animation").show(ui, |ui| {
        if info.animations.is_empty() {
            ui.label(if info.posed {
                "The scene has skins or morph targets but no animation: drawn in its rest pose."
            } else {
                "The scene has no animation."
            });
            return;
        }
        let a = &mut state.settings.animation;
        ui.checkbox(&mut a.enabled, "Pose the scene by its animation");
        let current = info
            .animations
            .iter()
            .position(|(name, _)| *name == a.clip)
            .unwrap_or(0);
        let mut chosen = current;
        ComboBox::from_label("Animation")
            .selected_text(info.animations[current].0.as_str())
            .show_ui(ui, |ui| {
                for (i, (name, length)) in info.animations.iter().enumerate() {
                    ui.selectable_value(&mut chosen, i, format!("{name} ({length:.2} s)"));
                }
            });
        if chosen != current || (a.clip.is_empty() && chosen != 0) {
            a.clip = info.animations[chosen].0.clone();
            state.animation_clock = 0.0;
        }
        ui.horizontal(|ui| {
            let label = if a.playing { "Pause" } else { "Play" };
            if ui.button(label).clicked() {
                a.playing = !a.playing;
            }
            ui.checkbox(&mut a.repeat, "Repeat");
        });
        ui.add(Slider::new(&mut a.speed, model_range(ANIMATION_SPEED)).text("speed"));
        let length = info.animations[chosen].1.max(0.0);
        let shown = if a.repeat && length > 0.0 {
            state.animation_clock.rem_euclid(f64::from(length))
        } else {
            state.animation_clock.clamp(0.0, f64::from(length))
        };
        let mut seek = shown as f32;
        if ui
            .add(Slider::new(&mut seek, 0.0..=length).text("time (s)"))
            .changed()
        {
            state.animation_clock = f64::from(seek);
        }
    });
}

/// The panorama view: what it shows and how it is drawn.
fn panorama_section(ui: &mut Ui, state: &mut AppState, info: &PanelInfo) {
    let pano = &mut state.settings.panorama;
    ui.checkbox(
        &mut pano.show,
        if info.cave_mode {
            "Panorama view (operator window)"
        } else {
            "Panorama view"
        },
    );
    ui.add_enabled_ui(pano.show, |ui| {
        combo(
            ui,
            "Projection",
            &mut pano.projection,
            &Projection::ALL,
            Projection::name,
        );
        let (max_h, max_v) = pano.projection.max_fov();
        let (max_h, max_v) = (max_h.to_degrees(), max_v.to_degrees());
        // The model's ranges, narrowed to what the projection shows (switching to a narrower
        // projection clamps the field of view to it, as the image would be).
        let h = model_range(PANO_H_FOV);
        let v = model_range(PANO_V_FOV);
        ui.add(
            Slider::new(&mut pano.h_fov_degrees, *h.start()..=max_h.min(*h.end()))
                .text("horizontal FoV °"),
        );
        ui.add(
            Slider::new(&mut pano.v_fov_degrees, *v.start()..=max_v.min(*v.end()))
                .text("vertical FoV °"),
        );
        // The same direction, shown within ±180°.
        let mut yaw = crate::pano::wrap_degrees(pano.yaw_degrees);
        if ui
            .add(Slider::new(&mut yaw, -180.0..=180.0).text("turn °"))
            .changed()
        {
            pano.yaw_degrees = yaw;
        }
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
        let drawn_geometric = pano.projection.geometric() && pano.route == PanoRoute::Geometric;
        ui.add_enabled_ui(drawn_geometric, |ui| {
            // Volume stereo uses the configured parameters.
            combo(
                ui,
                "Panorama stereo",
                &mut pano.stereo,
                &PanoStereoKind::ALL,
                PanoStereoKind::name,
            );
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_slider_range_comes_from_the_model() {
        for path in [
            POLE_MERGE_START,
            PANO_H_FOV,
            PANO_V_FOV,
            SHADOW_OFFSET,
            ANIMATION_SPEED,
        ] {
            assert!(crate::config::bounds(path).is_some(), "{path} has no range");
        }
    }
}
