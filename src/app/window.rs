//! Windows and their surfaces: placing wall windows on monitors, composing each frame into them
//! (with the panel drawn by egui where it lives), and recovering lost or outdated surfaces.

use std::sync::Arc;

use winit::dpi::{PhysicalPosition, PhysicalSize};
use winit::event::WindowEvent;
use winit::event_loop::ActiveEventLoop;
use winit::monitor::MonitorHandle;
use winit::window::{Fullscreen, Window, WindowId};

use super::error::AppError;
use super::panel::{self, PanelInfo};
use super::state::AppState;
use crate::cave::Eye;
use crate::config::{Config, MonitorRef};
use crate::output::formats::StereoFormat;
use crate::render::Renderer;
use crate::render::gpu::Gpu;
use crate::render::overlay::{OverlayImage, OverlayPass};
use crate::render::present::{Crop, PresentBinding, PresentParams, PresentPass, Tile};

/// What a window shows.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Role {
    /// One wall's image in its output format (CAVE mode).
    Wall(usize),
    /// One eye of a wall with a window per eye (`[[wall.output]]`): the wall and the output's
    /// index among its eye outputs.
    WallEye { wall: usize, output: usize },
    /// The control panel alone (CAVE mode's operator window).
    Operator,
    /// The walls unfolded side by side with the panel docked.
    Preview,
}

impl Role {
    pub fn name(self, config: &Config) -> String {
        match self {
            Role::Wall(i) => config
                .cave
                .walls
                .get(i)
                .map_or_else(|| format!("wall {i}"), |w| w.name.clone()),
            Role::WallEye { wall, output } => {
                let eye = config
                    .app
                    .walls
                    .get(wall)
                    .and_then(|w| w.eye_outputs.get(output))
                    .map_or("eye", |o| o.eye.name());
                format!("{}-{eye}", Role::Wall(wall).name(config))
            }
            Role::Operator => "operator".into(),
            Role::Preview => "preview".into(),
        }
    }

    /// The wall this window shows alone, if it shows one.
    pub fn wall(self) -> Option<usize> {
        match self {
            Role::Wall(i) | Role::WallEye { wall: i, .. } => Some(i),
            Role::Operator | Role::Preview => None,
        }
    }
}

/// Opens a window for `role` where the config puts it.
pub fn create_window(
    event_loop: &ActiveEventLoop,
    config: &Config,
    role: Role,
) -> Result<Arc<Window>, AppError> {
    let name = role.name(config);
    let mut attrs = Window::default_attributes().with_title(format!("omnicave — {name}"));
    match role {
        Role::Wall(_) | Role::WallEye { .. } => {
            let missing = || AppError::Window {
                name: name.clone(),
                message: "no window settings for this wall".into(),
            };
            let wall = config.app.walls.get(role.wall().unwrap_or(usize::MAX));
            let placement = match role {
                Role::WallEye { output, .. } => wall
                    .and_then(|w| w.eye_outputs.get(output))
                    .map(|o| (o.monitor.as_ref(), o.size, o.position)),
                _ => wall.map(|w| (w.monitor.as_ref(), w.size, w.position)),
            };
            let (monitor, size, position) = placement.ok_or_else(missing)?;
            attrs = attrs.with_decorations(false);
            let monitor = monitor.and_then(|m| find_monitor(event_loop, m, &name));
            match monitor {
                Some(m) => {
                    tracing::info!(
                        "wall {name}: fullscreen on monitor {}",
                        m.name().unwrap_or_default()
                    );
                    attrs = attrs.with_fullscreen(Some(Fullscreen::Borderless(Some(m))));
                }
                None => {
                    attrs = attrs.with_inner_size(PhysicalSize::new(size[0], size[1]));
                    if let Some([x, y]) = position {
                        attrs = attrs.with_position(PhysicalPosition::new(x, y));
                    }
                }
            }
        }
        Role::Operator | Role::Preview => {
            let [w, h] = config.app.window_size;
            attrs = attrs.with_inner_size(PhysicalSize::new(w, h));
            if let Some([x, y]) = config.app.window_position {
                attrs = attrs.with_position(PhysicalPosition::new(x, y));
            }
        }
    }
    event_loop
        .create_window(attrs)
        .map(Arc::new)
        .map_err(|e| AppError::Window {
            name,
            message: e.to_string(),
        })
}

/// The monitor a config names, or `None` (with a warning listing what there is).
fn find_monitor(
    event_loop: &ActiveEventLoop,
    wanted: &MonitorRef,
    wall: &str,
) -> Option<MonitorHandle> {
    let monitors: Vec<MonitorHandle> = event_loop.available_monitors().collect();
    let found = match wanted {
        MonitorRef::Index(i) => monitors.get(*i).cloned(),
        MonitorRef::Name(n) => monitors
            .iter()
            .find(|m| m.name().as_deref() == Some(n.as_str()))
            .cloned(),
    };
    if found.is_none() {
        let names: Vec<String> = monitors
            .iter()
            .enumerate()
            .map(|(i, m)| format!("{i}: {}", m.name().unwrap_or_else(|| "?".into())))
            .collect();
        tracing::warn!(
            "wall {wall}: monitor {wanted:?} not found (monitors: {}); using window_position \
             and window_size",
            names.join(", ")
        );
    }
    found
}

/// A window, its surface and the bindings of the eye images it composes.
pub struct OutputWindow {
    pub role: Role,
    window: Arc<Window>,
    surface: wgpu::Surface<'static>,
    surface_config: wgpu::SurfaceConfiguration,
    /// False while the window has no area (minimised).
    configured: bool,
    /// One per wall shown (a wall window: its wall; the preview: every wall).
    bindings: Vec<PresentBinding>,
    /// (targets generation, mono) the bindings were made for.
    bound: Option<(u64, bool)>,
    /// The panorama's eye images, and the (panorama generation, stereo) they were bound for.
    pano_binding: Option<(PresentBinding, (u64, bool))>,
    /// Frames presented.
    presented: u64,
    /// The shared eye frame of this window's last present, and when it was.
    last_present: Option<(u64, std::time::Instant)>,
    /// Smoothed time between this window's presents, seconds (0: none yet).
    present_interval: f64,
    background: wgpu::Color,
    /// The preview's walls as last laid out: each one's size on screen, pixels (empty for
    /// other windows).
    shown_sizes: Vec<[u32; 2]>,
}

/// What drawing a window did besides presenting.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct DrawOutcome {
    /// The surface had to be recovered (the frame was skipped).
    pub recovered: bool,
    /// A frame-sequential window missed presents (it skipped frames, or its present came late
    /// by its timing) and was brought back to the shared eye phase.
    pub resynced: bool,
}

/// A surface texture to draw into, or why there is none this frame.
enum Acquired {
    /// The texture, and whether the surface is suboptimal (resized after presenting).
    Frame(wgpu::SurfaceTexture, bool),
    /// No texture: skip the frame (`recovered`: the surface was made again).
    Skipped { recovered: bool },
}

/// Which bound image a tile shows.
#[derive(Debug, Clone, Copy)]
enum TileSource {
    /// The window's `i`th wall binding.
    Wall(usize),
    /// The panorama's binding.
    Panorama,
}

/// One tile of a window's frame before it is bound: its image, format, place and crop.
#[derive(Debug, Clone, Copy)]
struct TilePlan {
    source: TileSource,
    format: StereoFormat,
    /// x, y, width, height in window pixels.
    rect: [f32; 4],
    crop: Option<Crop>,
}

impl TilePlan {
    /// A tile without a crop.
    fn new(source: TileSource, format: StereoFormat, rect: [f32; 4]) -> Self {
        Self {
            source,
            format,
            rect,
            crop: None,
        }
    }
}

impl OutputWindow {
    /// The preview's walls as last laid out: each one's size on screen, pixels (empty for
    /// other windows, and before the first frame).
    pub fn shown_sizes(&self) -> &[[u32; 2]] {
        &self.shown_sizes
    }

    pub fn new(
        gpu: &Gpu,
        role: Role,
        window: Arc<Window>,
        surface: wgpu::Surface<'static>,
        config: &Config,
    ) -> Result<Self, AppError> {
        let size = window.inner_size();
        let caps = surface.get_capabilities(&gpu.adapter);
        // egui paints in gamma space and the present shader encodes sRGB itself, so a plain
        // 8-bit format is preferred; an sRGB one works too.
        let format = caps
            .formats
            .iter()
            .copied()
            .find(|f| {
                matches!(
                    f,
                    wgpu::TextureFormat::Bgra8Unorm | wgpu::TextureFormat::Rgba8Unorm
                )
            })
            .or_else(|| caps.formats.first().copied())
            .ok_or_else(|| AppError::Surface {
                name: role.name(config),
                message: "the adapter cannot present to this window".into(),
            })?;
        let [width, height] = clamp_surface_size(gpu, size.width, size.height);
        if [width, height] != [size.width, size.height] {
            warn_clamped(
                &role.name(config),
                [size.width, size.height],
                [width, height],
            );
        }
        let mut surface_config = surface
            .get_default_config(&gpu.adapter, width.max(1), height.max(1))
            .ok_or_else(|| AppError::Surface {
                name: role.name(config),
                message: "no surface configuration is supported".into(),
            })?;
        surface_config.format = format;
        surface_config.present_mode = if config.app.vsync {
            wgpu::PresentMode::AutoVsync
        } else {
            wgpu::PresentMode::AutoNoVsync
        };
        surface_config.desired_maximum_frame_latency = 2;
        let configured = size.width > 0 && size.height > 0;
        if configured {
            surface.configure(&gpu.device, &surface_config);
        }
        // A plain-format surface stores sRGB values as they are; an sRGB one wants linear.
        let background = if format.is_srgb() {
            crate::render::srgb_to_linear_color(config.settings.render.background)
        } else {
            let [r, g, b] = config.settings.render.background.map(f64::from);
            wgpu::Color { r, g, b, a: 1.0 }
        };
        tracing::info!(
            "window {}: {}×{} {:?} {:?}",
            role.name(config),
            size.width,
            size.height,
            format,
            surface_config.present_mode
        );
        Ok(Self {
            role,
            window,
            surface,
            surface_config,
            configured,
            bindings: Vec::new(),
            bound: None,
            pano_binding: None,
            shown_sizes: Vec::new(),
            presented: 0,
            last_present: None,
            present_interval: 0.0,
            background,
        })
    }

    pub fn id(&self) -> WindowId {
        self.window.id()
    }

    pub fn window(&self) -> &Window {
        &self.window
    }

    pub fn format(&self) -> wgpu::TextureFormat {
        self.surface_config.format
    }

    /// Size in pixels as configured.
    pub fn size(&self) -> [u32; 2] {
        [self.surface_config.width, self.surface_config.height]
    }

    /// Follows a window resize (a zero size pauses drawing until it has an area again).
    pub fn resize(&mut self, gpu: &Gpu, width: u32, height: u32) {
        self.configured = width > 0 && height > 0;
        let clamped = clamp_surface_size(gpu, width, height);
        // Logged when the clamped size changes, not on every reconfiguration at that size.
        if clamped != [width, height] && clamped != self.size() {
            warn_clamped(&format!("{:?}", self.role), [width, height], clamped);
        }
        let [width, height] = clamped;
        if self.configured {
            self.surface_config.width = width;
            self.surface_config.height = height;
            self.surface.configure(&gpu.device, &self.surface_config);
        }
    }

    /// Rebinds the eye textures when the renderer has replaced them (or mono changed).
    fn ensure_bindings(
        &mut self,
        gpu: &Gpu,
        renderer: &Renderer,
        present: &PresentPass,
        walls: usize,
    ) {
        let mono = renderer.last_views().iter().any(|v| v.eye.is_none());
        let key = (renderer.targets_generation(), mono);
        if self.bound == Some(key) {
            return;
        }
        let shown: Vec<usize> = match self.role {
            Role::Wall(i) | Role::WallEye { wall: i, .. } => vec![i],
            Role::Preview => (0..walls).collect(),
            Role::Operator => Vec::new(),
        };
        self.bindings = shown
            .into_iter()
            .filter_map(|i| {
                let left = renderer.eye_texture(i, Eye::Left)?;
                let right = renderer.eye_texture(i, Eye::Right)?;
                Some(present.bind(&gpu.device, left, right))
            })
            .collect();
        self.bound = Some(key);
    }

    /// Rebinds the panorama's eye textures when the renderer has replaced them.
    fn ensure_pano_binding(&mut self, gpu: &Gpu, renderer: &Renderer, present: &PresentPass) {
        let key = (
            renderer.panorama_generation(),
            renderer.panorama_is_stereo(),
        );
        if self.pano_binding.as_ref().is_some_and(|(_, k)| *k == key) {
            return;
        }
        if let (Some(left), Some(right)) = (
            renderer.panorama_texture(Eye::Left),
            renderer.panorama_texture(Eye::Right),
        ) {
            self.pano_binding = Some((present.bind(&gpu.device, left, right), key));
        }
    }

    /// Composes and presents this window's frame `eye_frame` (the frame counter every window
    /// shares: frame-sequential outputs show the left eye on even frames, so all windows show
    /// the same eye in a frame, whatever each one missed before).
    pub fn draw(
        &mut self,
        gpu: &Gpu,
        renderer: &Renderer,
        state: &AppState,
        egui: Option<(&mut EguiHost, &EguiFrame)>,
        eye_frame: u64,
    ) -> Result<DrawOutcome, AppError> {
        if !self.configured {
            return Ok(DrawOutcome::default());
        }
        let present = renderer.present_pass();
        self.ensure_bindings(gpu, renderer, present, state.cave().walls.len());
        let show_pano =
            state.settings.panorama.show && matches!(self.role, Role::Preview | Role::Operator);
        if show_pano {
            self.ensure_pano_binding(gpu, renderer, present);
        }
        let (frame, suboptimal) = match self.acquire(gpu)? {
            Acquired::Frame(frame, suboptimal) => (frame, suboptimal),
            Acquired::Skipped { recovered } => {
                return Ok(DrawOutcome {
                    recovered,
                    resynced: false,
                });
            }
        };
        let view = frame.texture.create_view(&wgpu::TextureViewDescriptor {
            // The surface's own format (plain or sRGB), as the pipelines were built for.
            format: Some(self.surface_config.format),
            ..Default::default()
        });
        let central = egui.as_ref().and_then(|(_, f)| f.central);
        let plans = self.plan_tiles(state, central, show_pano);
        let tiles: Vec<Tile<'_>> = plans
            .iter()
            .filter_map(|plan| {
                let binding = match plan.source {
                    TileSource::Wall(i) => self.bindings.get(i),
                    TileSource::Panorama => self.pano_binding.as_ref().map(|(b, _)| b),
                }?;
                Some(Tile {
                    binding,
                    params: PresentParams {
                        format: plan.format,
                        frame: eye_frame,
                        swap_eyes: state.swap_eyes,
                    },
                    rect: plan.rect,
                    crop: plan.crop,
                })
            })
            .collect();
        let mut encoder = gpu
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                label: Some("OutputWindow::frame"),
            });
        present.encode_tiles(
            &gpu.queue,
            &mut encoder,
            &tiles,
            &view,
            self.surface_config.format,
            wgpu::LoadOp::Clear(self.background),
        );
        let first_format = tiles.first().map(|t| t.params.format);
        let mut extra = Vec::new();
        if let Some((host, egui_frame)) = egui {
            extra = host.paint(gpu, &mut encoder, &view, egui_frame, self.size());
        }
        gpu.queue
            .submit(extra.into_iter().chain(std::iter::once(encoder.finish())));
        self.window.pre_present_notify();
        gpu.queue.present(frame);
        self.presented += 1;
        let resynced = self.note_present(eye_frame, first_format);
        Ok(DrawOutcome {
            recovered: suboptimal && self.recover_suboptimal(gpu),
            resynced,
        })
    }

    /// The surface's next texture, or why this frame is skipped (the surface timed out, is
    /// hidden, or was outdated or lost and is made again: `recovered`).
    fn acquire(&mut self, gpu: &Gpu) -> Result<Acquired, AppError> {
        let skipped = |recovered| Ok(Acquired::Skipped { recovered });
        match self.surface.get_current_texture() {
            wgpu::CurrentSurfaceTexture::Success(t) => Ok(Acquired::Frame(t, false)),
            wgpu::CurrentSurfaceTexture::Suboptimal(t) => Ok(Acquired::Frame(t, true)),
            wgpu::CurrentSurfaceTexture::Timeout | wgpu::CurrentSurfaceTexture::Occluded => {
                skipped(false)
            }
            wgpu::CurrentSurfaceTexture::Outdated => {
                let size = self.window.inner_size();
                self.resize(gpu, size.width, size.height);
                // A surface clamped below its window goes out of date again and again on
                // some drivers (Mesa's X11 swapchain): expected while the clamp holds, so
                // not counted as a recovery.
                let clamped = clamp_surface_size(gpu, size.width, size.height);
                skipped(clamped == [size.width, size.height])
            }
            wgpu::CurrentSurfaceTexture::Lost => {
                // Recreate the surface on the same window (e.g. after a display change).
                let target: Arc<Window> = self.window.clone();
                match gpu.instance.create_surface(target) {
                    Ok(surface) => {
                        self.surface = surface;
                        let size = self.window.inner_size();
                        self.resize(gpu, size.width, size.height);
                        skipped(true)
                    }
                    Err(e) => Err(AppError::Surface {
                        name: format!("{:?}", self.role),
                        message: e.to_string(),
                    }),
                }
            }
            other => Err(AppError::Surface {
                name: format!("{:?}", self.role),
                message: format!("{other:?}"),
            }),
        }
    }

    /// After presenting a suboptimal frame: resizes the surface to its window, unless it is
    /// clamped below the window's size by design; whether it recovered.
    fn recover_suboptimal(&mut self, gpu: &Gpu) -> bool {
        let size = self.window.inner_size();
        // A surface clamped below its window's size is suboptimal by design: nothing to
        // recover while the clamp holds.
        let clamped = clamp_surface_size(gpu, size.width, size.height);
        if clamped != [size.width, size.height] && clamped == self.size() {
            return false;
        }
        self.resize(gpu, size.width, size.height);
        true
    }

    /// Where this window's role puts each image: a wall's format, a projector's eye and
    /// crop, the preview's walls unfolded (their shown sizes noted) with the panorama below,
    /// or the operator's panorama. `central`: the area the panel leaves, if any.
    fn plan_tiles(
        &mut self,
        state: &AppState,
        central: Option<[f32; 4]>,
        show_pano: bool,
    ) -> Vec<TilePlan> {
        let [w, h] = self.size();
        let whole = [0.0, 0.0, w as f32, h as f32];
        let show_pano = show_pano && self.pano_binding.is_some();
        let preview = state.settings.app.preview_output;
        let mut plans = Vec::with_capacity(self.bindings.len() + 1);
        match self.role {
            Role::Wall(i) => {
                if let Some(&format) = state.wall_output(i).as_ref() {
                    plans.push(TilePlan::new(TileSource::Wall(0), format, whole));
                }
            }
            Role::WallEye { wall, output } => {
                let out = state
                    .config
                    .app
                    .walls
                    .get(wall)
                    .and_then(|w| w.eye_outputs.get(output));
                if let Some(out) = out {
                    let format = match out.eye {
                        Eye::Left => StereoFormat::LeftOnly,
                        Eye::Right => StereoFormat::RightOnly,
                    };
                    plans.push(TilePlan {
                        crop: Some(Crop {
                            rect: out.crop,
                            offset: out.offset,
                        }),
                        ..TilePlan::new(TileSource::Wall(0), format, whole)
                    });
                }
            }
            Role::Preview => {
                let mut area = central.unwrap_or(whole);
                if show_pano {
                    // The walls above, the panorama below: each in half the area.
                    let [x, y, aw, ah] = area;
                    let below = [x, y + 0.5 * ah, aw, 0.5 * ah];
                    let rect = clamp_rect(fit(below, state.settings.panorama.size), [w, h]);
                    plans.push(TilePlan::new(TileSource::Panorama, preview, rect));
                    area = [x, y, aw, 0.5 * ah];
                }
                let walls = &state.cave().walls;
                let sizes: Vec<[f32; 2]> = walls.iter().map(|w| w.size_m().to_array()).collect();
                let rects = unfolded_layout(&sizes, area);
                self.shown_sizes.clear();
                self.shown_sizes.extend(
                    rects
                        .iter()
                        .map(|r| [r[2].max(0.0) as u32, r[3].max(0.0) as u32]),
                );
                for (i, rect) in rects.into_iter().enumerate().take(self.bindings.len()) {
                    let rect = clamp_rect(rect, [w, h]);
                    plans.push(TilePlan::new(TileSource::Wall(i), preview, rect));
                }
            }
            Role::Operator => {
                if show_pano {
                    let area = central.unwrap_or(whole);
                    let rect = clamp_rect(fit(area, state.settings.panorama.size), [w, h]);
                    plans.push(TilePlan::new(TileSource::Panorama, preview, rect));
                }
            }
        }
        plans
    }

    /// Records a present of `eye_frame`: whether this frame-sequential window had fallen out of
    /// step (it skipped frames the others presented, or this present came more than 1.8 times
    /// its usual interval after the last: a stall the projector showed as a repeated eye). It
    /// is back in phase with this present either way, as it takes its eye from the shared
    /// counter.
    fn note_present(&mut self, eye_frame: u64, format: Option<StereoFormat>) -> bool {
        let now = std::time::Instant::now();
        let sequential = format == Some(StereoFormat::FrameSequential);
        let mut resynced = false;
        if let Some((last, at)) = self.last_present {
            let gap = now.saturating_duration_since(at).as_secs_f64();
            let skipped = eye_frame > last + 1;
            let late = self.present_interval > 0.0 && gap > 1.8 * self.present_interval;
            resynced = sequential && (skipped || late);
            if !skipped && !late {
                self.present_interval = if self.present_interval == 0.0 {
                    gap
                } else {
                    0.9 * self.present_interval + 0.1 * gap
                };
            }
        }
        if sequential {
            tracing::debug!(
                target: "omnicave::eye_phase",
                "present window {:?} frame {eye_frame} eye {}{}",
                self.role,
                if eye_frame.is_multiple_of(2) { "left" } else { "right" },
                if resynced { " (re-sync)" } else { "" }
            );
        }
        self.last_present = Some((eye_frame, now));
        resynced
    }
}

/// A window size limited to what the device can present (a surface is a texture: a window
/// stretched past 16 384 pixels would make wgpu panic).
fn clamp_surface_size(gpu: &Gpu, width: u32, height: u32) -> [u32; 2] {
    let max = gpu.device.limits().max_texture_dimension_2d;
    [width.min(max), height.min(max)]
}

fn warn_clamped(name: &str, [width, height]: [u32; 2], [w, h]: [u32; 2]) {
    tracing::warn!(
        "window {name} is {width}×{height}; its surface is limited to {w}×{h} (this GPU's \
         max_texture_dimension_2d): the rest of the window is not drawn"
    );
}

/// The largest rectangle of an image's proportions (`size` pixels) centred in `area`.
fn fit(area: [f32; 4], size: [u32; 2]) -> [f32; 4] {
    let [x, y, w, h] = area;
    let aspect = size[0].max(1) as f32 / size[1].max(1) as f32;
    let (fw, fh) = if w / h.max(1.0) > aspect {
        (h * aspect, h)
    } else {
        (w, w / aspect)
    };
    [x + 0.5 * (w - fw), y + 0.5 * (h - fh), fw, fh]
}

/// Walls side by side as one continuous strip (each in proportion to its size in metres),
/// fitted and centred in `area` (x, y, width, height in pixels).
pub fn unfolded_layout(wall_sizes_m: &[[f32; 2]], area: [f32; 4]) -> Vec<[f32; 4]> {
    let total_w: f32 = wall_sizes_m.iter().map(|s| s[0]).sum();
    let max_h = wall_sizes_m.iter().map(|s| s[1]).fold(0.0f32, f32::max);
    if total_w <= 0.0 || max_h <= 0.0 {
        return Vec::new();
    }
    let [x0, y0, aw, ah] = area;
    let scale = (aw / total_w).min(ah / max_h).max(0.0);
    let strip_w = total_w * scale;
    let mut x = x0 + (aw - strip_w) / 2.0;
    let y_mid = y0 + ah / 2.0;
    wall_sizes_m
        .iter()
        .map(|s| {
            let (w, h) = (s[0] * scale, s[1] * scale);
            // Edges rounded once each, so neighbours share them (no gap, no overlap).
            let (left, right) = (x.round(), (x + w).round());
            let top = (y_mid - h / 2.0).round();
            x += w;
            [left, top, right - left, (y_mid + h / 2.0).round() - top]
        })
        .collect()
}

/// Keeps a tile inside the target (viewports must not leave it).
fn clamp_rect(rect: [f32; 4], size: [u32; 2]) -> [f32; 4] {
    let (tw, th) = (size[0] as f32, size[1] as f32);
    let x = rect[0].clamp(0.0, tw);
    let y = rect[1].clamp(0.0, th);
    [
        x,
        y,
        rect[2].min(tw - x).max(0.0),
        rect[3].min(th - y).max(0.0),
    ]
}

/// One egui frame, ready to paint.
pub struct EguiFrame {
    jobs: Vec<egui::ClippedPrimitive>,
    /// Textures egui released this frame (freed after painting).
    textures_free: Vec<egui::TextureId>,
    /// Whether egui set or freed a texture since the panel was last painted (the font atlas
    /// grows, an image changes): what the panel shows may change with the same primitives.
    textures_changed: bool,
    pixels_per_point: f32,
    /// The area left beside the docked panel, in pixels (preview).
    central: Option<[f32; 4]>,
}

/// The window that shows the control panel: egui's input state and painter.
pub struct EguiHost {
    pub window_index: usize,
    ctx: egui::Context,
    input: egui_winit::State,
    painter: egui_wgpu::Renderer,
    role: Role,
    /// Composites the panel's image over each frame.
    overlay: OverlayPass,
    /// The panel as last painted, and the primitives it was painted from.
    panel: Option<(OverlayImage, PaintedPanel)>,
    /// egui set or freed a texture since the panel was last painted (a frame the window
    /// could not present does not paint).
    textures_pending: bool,
}

/// What the panel's image was painted from: it is painted again only when this changes.
#[derive(Debug, Clone, Default)]
struct PaintedPanel {
    jobs: Vec<egui::ClippedPrimitive>,
    pixels_per_point: f32,
    /// The pixels the image covers (`covered_pixels`).
    covered: [u32; 4],
}

impl PaintedPanel {
    /// Whether `frame` paints the same pixels as this (false for paint callbacks, whose
    /// output is not known).
    fn paints_the_same(&self, frame: &EguiFrame) -> bool {
        !frame.textures_changed
            && self.pixels_per_point == frame.pixels_per_point
            && self.jobs.len() == frame.jobs.len()
            && self.jobs.iter().zip(&frame.jobs).all(|(a, b)| {
                a.clip_rect == b.clip_rect
                    && match (&a.primitive, &b.primitive) {
                        (egui::epaint::Primitive::Mesh(a), egui::epaint::Primitive::Mesh(b)) => {
                            a == b
                        }
                        _ => false,
                    }
            })
    }
}

/// The pixels (x, y, width, height) the primitives can touch: the union of their meshes'
/// bounds within their clip rectangles, within the window (the whole window for a paint
/// callback, whose extent is not known).
fn covered_pixels(
    jobs: &[egui::ClippedPrimitive],
    pixels_per_point: f32,
    size: [u32; 2],
) -> [u32; 4] {
    let union = jobs.iter().fold(egui::Rect::NOTHING, |r, job| {
        let drawn = match &job.primitive {
            egui::epaint::Primitive::Mesh(mesh) => mesh.calc_bounds(),
            egui::epaint::Primitive::Callback(_) => egui::Rect::EVERYTHING,
        };
        let visible = drawn.intersect(job.clip_rect);
        if visible.is_positive() {
            r.union(visible)
        } else {
            r
        }
    });
    if !union.is_positive() {
        return [0; 4];
    }
    // Clamped to the window before converting (a clip rectangle may be infinite).
    let px = |v: f32, max: u32| (v * pixels_per_point).clamp(0.0, max as f32);
    let x0 = px(union.min.x, size[0]).floor() as u32;
    let y0 = px(union.min.y, size[1]).floor() as u32;
    let x1 = px(union.max.x, size[0]).ceil() as u32;
    let y1 = px(union.max.y, size[1]).ceil() as u32;
    [x0, y0, x1.saturating_sub(x0), y1.saturating_sub(y0)]
}

impl EguiHost {
    pub fn new(gpu: &Gpu, window: &OutputWindow, window_index: usize) -> Self {
        let ctx = egui::Context::default();
        let max_side = gpu.device.limits().max_texture_dimension_2d as usize;
        let input = egui_winit::State::new(
            ctx.clone(),
            egui::ViewportId::ROOT,
            window.window(),
            Some(window.window().scale_factor() as f32),
            window.window().theme(),
            Some(max_side),
        );
        let painter = egui_wgpu::Renderer::new(
            &gpu.device,
            window.format(),
            egui_wgpu::RendererOptions::default(),
        );
        Self {
            window_index,
            ctx,
            input,
            painter,
            role: window.role,
            overlay: OverlayPass::new(&gpu.device, window.format()),
            panel: None,
            textures_pending: false,
        }
    }

    /// Feeds a window event to egui; true if egui used it (typing, clicking on the panel).
    pub fn on_event(&mut self, window: &OutputWindow, event: &WindowEvent) -> bool {
        self.input.on_window_event(window.window(), event).consumed
    }

    /// Runs the panel for this frame.
    pub fn run(
        &mut self,
        gpu: &Gpu,
        window: &OutputWindow,
        state: &mut AppState,
        info: &PanelInfo,
    ) -> EguiFrame {
        let raw = self.input.take_egui_input(window.window());
        let mut central = None;
        let role = self.role;
        let output = self.ctx.run_ui(raw, |ui| {
            match role {
                Role::Preview => {
                    if state.show_panel {
                        egui::Panel::left("controls")
                            .default_size(340.0)
                            .resizable(true)
                            .show(ui, |ui| panel::panel_ui(ui, state, info));
                    }
                    central = Some(ui.available_rect_before_wrap());
                }
                Role::Operator if state.settings.panorama.show => {
                    // The panel docked, the operator's overview of the panorama beside it.
                    egui::Panel::left("controls")
                        .default_size(340.0)
                        .resizable(true)
                        .show(ui, |ui| panel::panel_ui(ui, state, info));
                    central = Some(ui.available_rect_before_wrap());
                }
                Role::Operator => {
                    egui::CentralPanel::default_margins()
                        .show(ui, |ui| panel::panel_ui(ui, state, info));
                }
                Role::Wall(_) | Role::WallEye { .. } => {
                    if state.show_panel {
                        egui::Window::new("omnicave controls")
                            .default_width(340.0)
                            .show(ui.ctx(), |ui| panel::panel_ui(ui, state, info));
                    }
                }
            }
            panel::help_window(ui.ctx(), &mut state.show_help);
        });
        self.input
            .handle_platform_output(window.window(), output.platform_output);
        let ppp = output.pixels_per_point;
        let jobs = self.ctx.tessellate(output.shapes, ppp);
        // Uploaded now, whether or not the window can present this frame.
        let mut textures = output.textures_delta;
        self.textures_pending |= !textures.set.is_empty() || !textures.free.is_empty();
        for (id, deltas) in &textures.set {
            for delta in deltas {
                self.painter
                    .update_texture(&gpu.device, &gpu.queue, *id, delta);
            }
        }
        let textures_free = std::mem::take(&mut textures.free).into_iter().collect();
        textures.clear();
        EguiFrame {
            jobs,
            textures_free,
            textures_changed: self.textures_pending,
            pixels_per_point: ppp,
            central: central.map(|r| {
                [
                    r.min.x * ppp,
                    r.min.y * ppp,
                    r.width() * ppp,
                    r.height() * ppp,
                ]
            }),
        }
    }

    /// Records the panel over what the window already shows: painted into its image when it
    /// changed, then the image composited over the frame. Returns egui's own command buffers
    /// (submitted before the encoder's).
    fn paint(
        &mut self,
        gpu: &Gpu,
        encoder: &mut wgpu::CommandEncoder,
        view: &wgpu::TextureView,
        frame: &EguiFrame,
        size: [u32; 2],
    ) -> Vec<wgpu::CommandBuffer> {
        let mut buffers = Vec::new();
        let fresh = self
            .panel
            .as_ref()
            .is_some_and(|(image, painted)| image.size == size && painted.paints_the_same(frame));
        if !fresh {
            let (image, mut painted) = match self.panel.take() {
                Some((image, painted)) if image.size == size => (image, painted),
                _ => (
                    self.overlay.image(&gpu.device, size),
                    PaintedPanel::default(),
                ),
            };
            let screen = egui_wgpu::ScreenDescriptor {
                size_in_pixels: size,
                pixels_per_point: frame.pixels_per_point,
            };
            buffers =
                self.painter
                    .update_buffers(&gpu.device, &gpu.queue, encoder, &frame.jobs, &screen);
            let mut pass = crate::render::fullscreen::begin_colour_pass(
                encoder,
                "EguiHost::panel_pass",
                &image.view,
                wgpu::LoadOp::Clear(wgpu::Color::TRANSPARENT),
            )
            .forget_lifetime();
            self.painter.render(&mut pass, &frame.jobs, &screen);
            drop(pass);
            // Reuses the last list's allocation (the panel can change every frame, e.g. with
            // its frame-time plot open).
            painted.jobs.clone_from(&frame.jobs);
            painted.pixels_per_point = frame.pixels_per_point;
            painted.covered = covered_pixels(&frame.jobs, frame.pixels_per_point, size);
            self.panel = Some((image, painted));
            self.textures_pending = false;
        }
        if let Some((image, painted)) = &self.panel {
            self.overlay.encode(encoder, image, view, painted.covered);
        }
        buffers
    }

    /// Frees the textures egui released this frame (after painting).
    pub fn free_textures(&mut self, frame: EguiFrame) {
        for id in &frame.textures_free {
            self.painter.free_texture(id);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn rect_job(min: [f32; 2], max: [f32; 2], clip: egui::Rect) -> egui::ClippedPrimitive {
        let mut mesh = egui::Mesh::default();
        mesh.add_colored_rect(
            egui::Rect::from_min_max(min.into(), max.into()),
            egui::Color32::from_rgb(40, 40, 40),
        );
        egui::ClippedPrimitive {
            clip_rect: clip,
            primitive: egui::epaint::Primitive::Mesh(mesh),
        }
    }

    fn frame_of(jobs: Vec<egui::ClippedPrimitive>) -> EguiFrame {
        EguiFrame {
            jobs,
            textures_free: Vec::new(),
            textures_changed: false,
            pixels_per_point: 1.0,
            central: None,
        }
    }

    #[test]
    fn the_panel_is_painted_again_exactly_when_what_it_shows_changes() {
        let panel = rect_job([0.0, 0.0], [340.0, 720.0], egui::Rect::EVERYTHING);
        let painted = PaintedPanel {
            jobs: vec![panel.clone()],
            pixels_per_point: 1.0,
            covered: [0, 0, 340, 720],
        };
        assert!(painted.paints_the_same(&frame_of(vec![panel.clone()])));
        // A glyph's colour, a vertex moved, a primitive more or less, another clip.
        let mut recoloured = panel.clone();
        if let egui::epaint::Primitive::Mesh(m) = &mut recoloured.primitive {
            m.vertices[2].color = egui::Color32::WHITE;
        }
        let mut moved = panel.clone();
        if let egui::epaint::Primitive::Mesh(m) = &mut moved.primitive {
            m.vertices[0].pos.x += 0.25;
        }
        let clipped = egui::ClippedPrimitive {
            clip_rect: egui::Rect::from_min_max([0.0, 0.0].into(), [100.0, 100.0].into()),
            ..panel.clone()
        };
        for (what, jobs) in [
            ("recoloured", vec![recoloured]),
            ("moved", vec![moved]),
            ("one more", vec![panel.clone(), panel.clone()]),
            ("none", vec![]),
            ("clipped", vec![clipped]),
        ] {
            assert!(!painted.paints_the_same(&frame_of(jobs)), "{what}");
        }
        // The same primitives with a texture changed (the font atlas grew) or at another
        // scale paint other pixels.
        let mut textures = frame_of(vec![panel.clone()]);
        textures.textures_changed = true;
        assert!(!painted.paints_the_same(&textures));
        let mut scaled = frame_of(vec![panel]);
        scaled.pixels_per_point = 2.0;
        assert!(!painted.paints_the_same(&scaled));
    }

    #[test]
    fn the_panel_is_composited_where_its_meshes_are_drawn() {
        let everything = egui::Rect::EVERYTHING;
        let jobs = vec![
            rect_job([0.0, 0.0], [340.0, 720.0], everything),
            // A popup reaching past the window, clipped to a rectangle inside it.
            rect_job(
                [300.0, 100.5],
                [2000.0, 200.0],
                egui::Rect::from_min_max([0.0, 0.0].into(), [500.0, 150.25].into()),
            ),
        ];
        assert_eq!(covered_pixels(&jobs, 1.0, [1280, 720]), [0, 0, 500, 720]);
        // Points to pixels, rounded outwards, and never past the window.
        assert_eq!(
            covered_pixels(&jobs[1..], 2.0, [1280, 720]),
            [600, 201, 400, 100]
        );
        assert_eq!(covered_pixels(&jobs, 2.0, [800, 600]), [0, 0, 800, 600]);
        assert_eq!(covered_pixels(&[], 1.0, [1280, 720])[2..], [0, 0]);
        // A mesh entirely outside its clip rectangle covers nothing.
        let hidden = rect_job(
            [600.0, 0.0],
            [700.0, 10.0],
            egui::Rect::from_min_max([0.0, 0.0].into(), [100.0, 100.0].into()),
        );
        assert_eq!(covered_pixels(&[hidden], 1.0, [1280, 720])[2..], [0, 0]);
    }

    #[test]
    fn unfolded_walls_form_one_centred_strip() {
        // Three 3.3 × 2.9 m walls in a 1000 × 500 area at (100, 0).
        let rects = unfolded_layout(&[[3.3, 2.9]; 3], [100.0, 0.0, 1000.0, 500.0]);
        assert_eq!(rects.len(), 3);
        // Width-limited: 1000 px over 9.9 m.
        let scale = 1000.0 / 9.9;
        for (i, r) in rects.iter().enumerate() {
            assert!((r[2] - (3.3 * scale as f32).round()).abs() <= 1.0);
            if i > 0 {
                // Adjacent: no gap and no overlap.
                let prev = rects[i - 1];
                assert_eq!(prev[0] + prev[2], r[0], "{rects:?}");
            }
        }
        assert!((rects[0][0] - 100.0).abs() <= 1.0);
        let h = rects[0][3];
        assert!((rects[0][1] - (250.0 - h / 2.0)).abs() <= 1.0);
    }

    #[test]
    fn tiles_never_leave_the_target() {
        let r = clamp_rect([-5.0, 10.0, 300.0, 300.0], [200, 100]);
        assert_eq!(r, [0.0, 10.0, 200.0, 90.0]);
    }
}
