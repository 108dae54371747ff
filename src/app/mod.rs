//! The interactive application: a window per wall (CAVE mode) or one window with the walls
//! unfolded (preview), the egui control panel, keys and mouse; one process, one wgpu device.

pub mod cluster_link;
pub mod devices;
mod error;
pub mod guest_map;
pub mod keys;
pub mod monitors;
pub mod panel;
pub mod state;
pub mod stats;
mod window;
#[cfg(target_os = "linux")]
mod x11_errors;

use std::panic::AssertUnwindSafe;
use std::path::PathBuf;
use std::time::{Duration, Instant};

use winit::application::ApplicationHandler;
use winit::event::{ElementState, MouseButton, WindowEvent};
use winit::event_loop::{ActiveEventLoop, ControlFlow, EventLoop};
use winit::keyboard::PhysicalKey;
use winit::window::WindowId;

use crate::cluster::ClusterError;
use crate::config::{AppMode, Config, PanelPlacement};
use crate::render::Renderer;
use crate::render::gpu::Gpu;
use crate::scene::Scene;
use crate::setup::{load_config_sky, load_scene};
use crate::sky::CubeMap;
use crate::tracking::LinkState;
use cluster_link::{ClusterLink, NodeNext};
use devices::{Gamepads, Tracking};
pub use error::AppError;
use keys::HeldKeys;
use panel::PanelInfo;
use state::AppState;
use stats::FrameClock;
use std::sync::Arc;
use window::{EguiHost, OutputWindow, Role};

/// How to start the application.
#[derive(Debug, Clone, Default)]
pub struct RunOptions {
    pub config: PathBuf,
    /// A scene instead of the config's (`none`: the sky alone).
    pub scene: Option<PathBuf>,
    /// CAVE or preview, instead of the config's `[app] mode`.
    pub mode: Option<AppMode>,
    /// Log the frame statistics every this many seconds.
    pub stats_every: Option<f64>,
    /// Quit by itself after this many seconds (demos, soak tests).
    pub quit_after: Option<f64>,
    /// Listen for OSC head tracking on this address (switches tracking on).
    pub osc_listen: Option<std::net::SocketAddr>,
    /// Cluster mode: this process is one rank of an `mpirun` job (rank 0 the master).
    pub cluster: bool,
    /// Write this process's walls' eye images and the frame's state to
    /// `DIR/frame-NNNNNN/` every `record_every` frames.
    pub record: Option<PathBuf>,
    pub record_every: u64,
}

/// Loads config, scene and sky, opens the windows and runs until quit.
pub fn run(options: RunOptions) -> Result<(), AppError> {
    let mut config = Config::load(&options.config)?;
    if let Some(mode) = options.mode {
        config.app.mode = mode;
    }
    if let Some(listen) = options.osc_listen {
        config.tracking.receiver.listen = listen;
        config.tracking.enabled = true;
        config.settings.tracking.enabled = true;
    }
    let head = config.settings.head().position;
    if let Some(problem) = config.cave.head_problem(head) {
        return Err(AppError::Head {
            position: head,
            problem,
        });
    }
    let scene = match options.scene.clone().or_else(|| config.scene_path.clone()) {
        Some(path) => load_scene(&config.settings, &path)?,
        None => Scene::default(),
    };
    crate::setup::place_at_camera(&mut config.settings, &scene)?;
    let sky = load_config_sky(&config);
    let cluster = if options.cluster {
        Some(start_cluster(&config, &scene)?)
    } else {
        None
    };
    // `main` installed the signal handler before anything else; a signal during loading
    // ends here, cleanly, before any window opens.
    if crate::signals::stop_requested() {
        tracing::info!("stopped by a signal while loading");
        return Ok(());
    }
    // A window destroyed from outside must not end the program through a stale X error.
    #[cfg(target_os = "linux")]
    x11_errors::install();
    let event_loop = EventLoop::new().map_err(|e| AppError::EventLoop(e.to_string()))?;
    let tracking = Tracking::new(config.tracking.clone());
    let mut info = PanelInfo::default();
    // A render node takes no input: the master's frame state drives it.
    let is_node = cluster.as_ref().is_some_and(|c| c.rank() != 0);
    let gamepads = match Gamepads::start(config.gamepad.clone()) {
        _ if is_node => None,
        Ok(g) => g,
        Err(e) => {
            tracing::warn!("{e}; running without a gamepad");
            info.tracking.gamepad_error = Some(e);
            None
        }
    };
    let mut app = App {
        state: AppState::new(config),
        scene: Arc::new(scene),
        sky,
        options,
        gfx: None,
        result: Ok(()),
        held: HeldKeys::default(),
        shift: false,
        ctrl: false,
        drag: None,
        clock: FrameClock::new(),
        started: Instant::now(),
        last_frame: None,
        last_stats_log: Instant::now(),
        info,
        surface_recoveries: 0,
        eye_frame: 0,
        eye_resyncs: 0,
        tracking,
        gamepads,
        cluster,
        own_walls: Vec::new(),
        guest_map: None,
    };
    event_loop
        .run_app(&mut app)
        .map_err(|e| AppError::EventLoop(e.to_string()))?;
    app.result
}

/// GPU objects and windows (created once the event loop is running).
struct Graphics {
    gpu: Gpu,
    renderer: Renderer,
    windows: Vec<OutputWindow>,
    egui: Option<EguiHost>,
}

struct App {
    state: AppState,
    /// Shared with the guest map's worker.
    scene: Arc<Scene>,
    sky: Option<CubeMap>,
    options: RunOptions,
    gfx: Option<Graphics>,
    result: Result<(), AppError>,
    held: HeldKeys,
    shift: bool,
    ctrl: bool,
    /// Last cursor x while the right button drags (mouse-look).
    drag: Option<Option<f64>>,
    clock: FrameClock,
    started: Instant,
    last_frame: Option<Instant>,
    last_stats_log: Instant,
    info: PanelInfo,
    surface_recoveries: u64,
    /// The frame counter every window's eye phase comes from (frame-sequential: left eye on
    /// even frames), advanced once per frame.
    eye_frame: u64,
    /// Frame-sequential windows brought back into the shared eye phase after missing presents.
    eye_resyncs: u64,
    tracking: Tracking,
    gamepads: Option<Gamepads>,
    /// Cluster mode's session (master or node).
    cluster: Option<ClusterLink>,
    /// The walls this process renders and shows (all but in cluster mode).
    own_walls: Vec<bool>,
    /// The panel's floor map of where guests may stand (started when first shown).
    guest_map: Option<guest_map::GuestMapWorker>,
}

/// Starts cluster mode: MPI, then the start-up check with every other rank.
fn start_cluster(config: &Config, scene: &Scene) -> Result<ClusterLink, AppError> {
    if config.app.mode != AppMode::Cave {
        return Err(ClusterError::NotCaveMode.into());
    }
    // The panel belongs to the master, which takes the input.
    if let PanelPlacement::Overlay(wall) = config.app.panel
        && cluster_link::node_of(config, wall) != 0
    {
        return Err(ClusterError::PanelOnNode {
            wall: config
                .cave
                .walls
                .get(wall)
                .map_or_else(String::new, |w| w.name.clone()),
            node: cluster_link::node_of(config, wall),
        }
        .into());
    }
    #[cfg(feature = "cluster")]
    {
        use crate::cluster::Transport as _;
        let transport = crate::cluster::mpi_transport::MpiTransport::init()?;
        let identity = crate::cluster::identity(transport.host(), config, scene);
        tracing::info!(
            target: "omnicave::cluster",
            "rank {} of {} on {} (pid {}): settings {}, scene {}",
            transport.rank(),
            transport.size(),
            identity.host,
            std::process::id(),
            identity.config,
            identity.scene
        );
        Ok(ClusterLink::start(Box::new(transport), config, &identity)?)
    }
    #[cfg(not(feature = "cluster"))]
    {
        let _ = scene;
        Err(ClusterError::NotBuilt.into())
    }
}

/// Radians of turn per pixel of mouse drag.
const MOUSE_TURN_PER_PIXEL: f32 = 0.004;

impl App {
    fn fail(&mut self, event_loop: &ActiveEventLoop, error: AppError) {
        tracing::error!("{error}");
        match self.cluster.as_mut() {
            Some(ClusterLink::Master(master)) => {
                master.session.stop(&format!("the master failed: {error}"));
            }
            Some(ClusterLink::Node(node)) => node.session.leave(&error.to_string()),
            None => {}
        }
        self.result = Err(error);
        event_loop.exit();
    }

    fn start(&mut self, event_loop: &ActiveEventLoop) -> Result<Graphics, AppError> {
        let instance = wgpu::Instance::new(
            wgpu::InstanceDescriptor::new_with_display_handle(Box::new(
                event_loop.owned_display_handle(),
            ))
            .with_env(),
        );
        let config = &self.state.config;
        let rank = self.cluster.as_ref().map(ClusterLink::rank);
        // This process's walls (cluster mode: those whose `node` is its rank).
        let own: Vec<bool> = (0..config.cave.walls.len())
            .map(|i| rank.is_none_or(|r| cluster_link::node_of(config, i) == r))
            .collect();
        let mut plans = Vec::new();
        match config.app.mode {
            AppMode::Preview => plans.push(Role::Preview),
            AppMode::Cave => {
                for i in (0..config.cave.walls.len()).filter(|i| own[*i]) {
                    // A passive wall with a projector per eye: a window per eye, both showing
                    // the eye images rendered once for the wall.
                    let eyes = config.app.walls.get(i).map_or(0, |w| w.eye_outputs.len());
                    if eyes == 0 {
                        plans.push(Role::Wall(i));
                    }
                    for output in 0..eyes {
                        plans.push(Role::WallEye { wall: i, output });
                    }
                }
                if config.app.panel == PanelPlacement::Window && rank.is_none_or(|r| r == 0) {
                    plans.push(Role::Operator);
                }
            }
        }
        let mut windows = Vec::with_capacity(plans.len());
        let mut gpu: Option<Gpu> = None;
        for role in plans {
            let win = window::create_window(event_loop, config, role)?;
            let surface = instance
                .create_surface(win.clone())
                .map_err(|e| AppError::Surface {
                    name: role.name(config),
                    message: e.to_string(),
                })?;
            if gpu.is_none() {
                gpu = Some(Gpu::for_surface(instance.clone(), &surface)?);
            }
            let Some(g) = gpu.as_ref() else {
                continue;
            };
            windows.push(OutputWindow::new(g, role, win, surface, config)?);
        }
        let gpu = match gpu {
            Some(g) => g,
            None => Gpu::headless()?,
        };
        gpu.apply_test_fault_hook();
        // Another process's walls get 1×1 targets from the start (no full-size spike).
        let mut cave = self.state.cave().clone();
        for (wall, mine) in cave.walls.iter_mut().zip(&own) {
            if !mine {
                wall.resolution = [1, 1];
            }
        }
        let mut renderer = match Renderer::new(&gpu, &cave, self.state.render_settings()) {
            Ok(r) => r,
            Err(e) => {
                // A lost device explains the failure better than what failed because of it.
                gpu.check()?;
                return Err(e.into());
            }
        };
        if rank.is_some() {
            renderer.set_wall_filter(Some(own.clone()));
        }
        self.own_walls = own;
        renderer.set_scene(&self.scene)?;
        if let Err(e) = renderer.set_sky(self.sky.as_ref()) {
            tracing::error!("{e}; running without a sky");
        }
        let gpu_timing = renderer.enable_gpu_timing(&gpu);
        for w in &windows {
            renderer.ensure_present_format(w.format());
        }
        let host = match (config.app.mode, &config.app.panel) {
            (AppMode::Preview, _) => windows.iter().position(|w| w.role == Role::Preview),
            (AppMode::Cave, PanelPlacement::Window) => {
                windows.iter().position(|w| w.role == Role::Operator)
            }
            (AppMode::Cave, PanelPlacement::Overlay(wall)) => {
                windows.iter().position(|w| w.role.wall() == Some(*wall))
            }
            (AppMode::Cave, PanelPlacement::Hidden) => None,
        };
        // Render nodes show no panel: the master's operator drives the cluster.
        let host = host.filter(|_| rank.is_none_or(|r| r == 0));
        let egui = host.map(|index| EguiHost::new(&gpu, &windows[index], index));
        let info = gpu.adapter.get_info();
        self.info.adapter = format!("{} ({:?})", info.name, info.backend);
        self.info.gpu_timing = gpu_timing;
        self.info.has_sky = renderer.has_sky();
        self.info.animations = self
            .scene
            .rig
            .clips
            .iter()
            .map(|c| (c.name.clone(), c.duration()))
            .collect();
        self.info.posed = !self.scene.rig.is_empty();
        self.info.tessellation_supported = gpu.tessellation_supported();
        self.info.cave_mode = config.app.mode == AppMode::Cave;
        tracing::info!(
            "{} window(s) open in {} mode; F1 shows the key map",
            windows.len(),
            match config.app.mode {
                AppMode::Cave => "CAVE",
                AppMode::Preview => "preview",
            }
        );
        Ok(Graphics {
            gpu,
            renderer,
            windows,
            egui,
        })
    }

    /// Renders the walls once and presents every window.
    /// One frame: input, the panel, rendering, presenting every window, then statistics and
    /// a requested save.
    fn frame(&mut self, event_loop: &ActiveEventLoop) {
        if self.gfx.is_none() {
            return;
        }
        let now = Instant::now();
        let Some(mut screenshot_id) = self.take_input(event_loop, now) else {
            return;
        };
        let Some(egui_frame) = self.run_panel(event_loop) else {
            return;
        };
        if self.state.screenshot_requested {
            self.state.screenshot_requested = false;
            screenshot_id = std::time::SystemTime::now()
                .duration_since(std::time::UNIX_EPOCH)
                .map_or(1, |d| d.as_secs().max(1));
        }
        if self.render_frame(event_loop, screenshot_id).is_none() {
            return;
        }
        if screenshot_id != 0 {
            self.save_screenshot(screenshot_id);
        }
        let recorded = self.record_if_due();
        if self.cluster_barrier(event_loop, recorded).is_none() {
            return;
        }
        if self.present(event_loop, egui_frame).is_none() {
            return;
        }
        self.read_back_figures(now);
        self.log_stats();
        self.save_if_requested();
    }

    /// This frame's input: a render node takes the master's frame (settings, state, number
    /// and screenshot), the master and a single process their own input. The screenshot id
    /// asked for (0: none), or `None` when the run ends here.
    fn take_input(&mut self, event_loop: &ActiveEventLoop, now: Instant) -> Option<u64> {
        match self.cluster.as_mut() {
            Some(ClusterLink::Node(node)) => match node.next(&mut self.state) {
                Ok(NodeNext::Render(s)) => {
                    self.eye_frame = s.frame;
                    Some(s.screenshot)
                }
                Ok(NodeNext::Stop(why)) => {
                    self.quit_now(event_loop, &format!("the master said stop: {why}"));
                    None
                }
                Err(e) => {
                    self.fail(event_loop, e.into());
                    None
                }
            },
            _ => {
                self.poll_input(now);
                Some(0)
            }
        }
    }

    /// The panel, first, so that what it changes shows in this frame: its paint (`None`
    /// inside when there is no panel), or `None` when its window is gone.
    fn run_panel(&mut self, event_loop: &ActiveEventLoop) -> Option<Option<window::EguiFrame>> {
        let gfx = self.gfx.as_mut()?;
        let Some(host) = gfx.egui.as_mut() else {
            return Some(None);
        };
        let index = host.window_index;
        let win = &gfx.windows[index];
        let (state, info, gpu) = (&mut self.state, &self.info, &gfx.gpu);
        // A window destroyed since the events were read: winit's size query panics.
        match std::panic::catch_unwind(AssertUnwindSafe(|| host.run(gpu, win, state, info))) {
            Ok(frame) => Some(Some(frame)),
            Err(_) => {
                self.window_gone(
                    event_loop,
                    index,
                    "destroyed from outside (its window system calls failed)",
                );
                None
            }
        }
    }

    /// The master's broadcast of this frame, then every view rendered and a wand selection
    /// asked for made; `None` when the run ends here.
    fn render_frame(&mut self, event_loop: &ActiveEventLoop, screenshot_id: u64) -> Option<()> {
        if let Some(ClusterLink::Master(master)) = self.cluster.as_mut()
            && let Err(e) = master.broadcast(&self.state, self.eye_frame, screenshot_id)
        {
            self.fail(event_loop, e.into());
            return None;
        }
        let node = matches!(self.cluster, Some(ClusterLink::Node(_)));
        let gfx = self.gfx.as_mut()?;
        // A validation error or a lost device ends the run with its message, not a panic.
        if let Err(e) = gfx.gpu.check() {
            self.fail(event_loop, e.into());
            return None;
        }
        if let Err(e) = render_views(gfx, &mut self.state, &mut self.info, node) {
            self.fail(event_loop, e);
            return None;
        }
        if self.state.guest_map.show && !node {
            self.update_guest_map();
        }
        if self.state.select_requested {
            self.state.select_requested = false;
            self.info.tracking.selection = Some(select(&self.scene, &self.state));
            if let Some(s) = &self.info.tracking.selection {
                tracing::info!("selected: {s}");
            }
        }
        Some(())
    }

    /// Asks the guest map's worker for the current head, mode and eyes, and hands its newest
    /// map to the panel; neither waits.
    fn update_guest_map(&mut self) {
        let worker = self
            .guest_map
            .get_or_insert_with(|| guest_map::GuestMapWorker::start(Arc::clone(&self.scene)));
        let settings = &self.state.settings;
        worker.request(
            self.state.cave(),
            guest_map::GuestMapPose {
                head: self.state.head(),
                mode: settings.render.mode,
                ipd: f64::from(settings.cave.eye_separation),
                pole_merge: settings.omni().pole_merge,
                world_from_cave: self.state.world_from_cave(),
            },
        );
        if let Some(map) = worker.newest() {
            self.info.guest_map = Some(Arc::new(map));
        }
    }

    /// Writes this frame's screenshot (`id` names its folder) and says where in the panel.
    fn save_screenshot(&mut self, id: u64) {
        let Some(gfx) = self.gfx.as_mut() else {
            return;
        };
        let shot = screenshot(gfx, &self.state, id, self.eye_frame, &self.own_walls);
        self.info.save_message = Some(match shot {
            Ok(dir) => {
                tracing::info!("screenshot written to {}", dir.display());
                format!("screenshot in {}", dir.display())
            }
            Err(e) => {
                tracing::error!("screenshot: {e}");
                format!("screenshot failed: {e}")
            }
        });
    }

    /// Records this frame when `--record` asks for it; whether it did.
    fn record_if_due(&mut self) -> bool {
        let recorded = self.options.record.is_some()
            && self
                .eye_frame
                .is_multiple_of(self.options.record_every.max(1));
        let describe = !matches!(self.cluster, Some(ClusterLink::Node(_)));
        if let (Some(dir), Some(gfx)) = (
            self.options.record.as_ref().filter(|_| recorded),
            self.gfx.as_mut(),
        ) && let Err(e) = record_frame(
            gfx,
            &self.state,
            dir,
            self.eye_frame,
            &self.own_walls,
            describe,
        ) {
            tracing::error!("recording frame {}: {e}", self.eye_frame);
        }
        recorded
    }

    /// Cluster mode: every process presents this frame together, once all have rendered it.
    /// `None` when the run ends here.
    fn cluster_barrier(&mut self, event_loop: &ActiveEventLoop, recorded: bool) -> Option<()> {
        match self.cluster.as_mut() {
            Some(ClusterLink::Master(master)) => {
                let passed = master.barrier(self.eye_frame, recorded);
                let info = self.info.cluster.get_or_insert_with(Default::default);
                info.figures = master.session.figures;
                let nodes = master.session.nodes();
                // Names and losses are copied when they change; figures every frame.
                let same = info.nodes.len() == nodes.len()
                    && info.nodes.iter().zip(nodes).all(|(a, b)| a.lost == b.lost);
                if same {
                    for (shown, node) in info.nodes.iter_mut().zip(nodes) {
                        shown.figures = node.figures;
                    }
                } else {
                    info.nodes = nodes.to_vec();
                }
                if let Err(e) = passed {
                    self.fail(event_loop, e.into());
                    return None;
                }
            }
            Some(ClusterLink::Node(node)) => match node.barrier(recorded) {
                Ok(None) => {}
                Ok(Some(why)) => {
                    self.quit_now(event_loop, &format!("the master said stop: {why}"));
                    return None;
                }
                Err(e) => {
                    self.fail(event_loop, e.into());
                    return None;
                }
            },
            None => {}
        }
        Some(())
    }

    /// Presents every window (with the panel's paint); `None` when a window is gone.
    fn present(
        &mut self,
        event_loop: &ActiveEventLoop,
        egui_frame: Option<window::EguiFrame>,
    ) -> Option<()> {
        let gfx = self.gfx.as_mut()?;
        let presented = present_windows(gfx, &self.state, egui_frame, self.eye_frame);
        // The next frame renders the preview's walls at the size they were just shown.
        if let Some(preview) = gfx.windows.iter().find(|w| w.role == Role::Preview) {
            self.state.set_shown_sizes(preview.shown_sizes());
        }
        self.eye_frame += 1;
        self.surface_recoveries += presented.recovered;
        self.eye_resyncs += presented.resynced;
        if let Some(index) = presented.lost {
            self.window_gone(
                event_loop,
                index,
                "destroyed from outside (its window system calls failed)",
            );
            return None;
        }
        Some(())
    }

    /// The newest frame the GPU has finished: its time and tessellation counts (never
    /// waits), into the panel's figures and the frame clock.
    fn read_back_figures(&mut self, started: Instant) {
        let Some(gfx) = self.gfx.as_mut() else {
            return;
        };
        let capacity = gfx.renderer.tess_capacity();
        let readback = gfx.renderer.poll_readbacks();
        let gpu_ms = readback.gpu_ms;
        // Reuses the panel's buffers: nothing grows per frame.
        self.info.breakdown.clone_from(&readback.breakdown);
        // Warn once when a view's budget runs out (formatted on that change only).
        let overflowed = readback.tess.iter().find(|t| t.overflowed);
        match (overflowed, &self.info.tess_shortfall) {
            (Some(stats), None) => {
                let tess = self.state.settings.tess();
                if let Some(note) = stats.shortfall(&tess, capacity) {
                    tracing::warn!("tessellation: {note}");
                    self.info.tess_shortfall = Some(note);
                }
            }
            (None, Some(_)) if !readback.tess.is_empty() => self.info.tess_shortfall = None,
            _ => {}
        }
        if !readback.tess.is_empty() {
            self.info.triangles_drawn = readback
                .tess
                .iter()
                .map(|t| t.emitted as usize)
                .sum::<usize>()
                + self.info.fine_triangles;
        }
        per_wall_counts(
            &gfx.renderer,
            self.state.cave().walls.len(),
            &mut self.info.tess_emitted,
        );
        self.clock.record(Instant::now(), started.elapsed(), gpu_ms);
        self.info.stats = self.clock.summary;
    }

    /// Tracking, gamepads and held keys move the state for the time since the last frame.
    fn poll_input(&mut self, now: Instant) {
        let since_last = self.last_frame.map(|t| now.saturating_duration_since(t));
        let dt = since_last.map_or(0.0, |d| d.as_secs_f32().min(0.25));
        self.last_frame = Some(now);
        // The newest tracked pose first: the latency from its arrival ends here.
        self.tracking.poll(&mut self.state, now);
        if let Some(pads) = self.gamepads.as_mut() {
            let head_tracked = self.tracking.drives_head(&self.state);
            pads.poll(&mut self.state, dt, head_tracked);
        }
        if self.held.any() {
            self.state.navigate(self.held.input(), dt);
        }
        self.state.advance_animation(dt);
        self.tracking.info(now, &mut self.info.tracking);
        // The plot: the time since the last frame began, and the age of the pose this one uses.
        if let Some(d) = since_last {
            let tracking =
                self.info.tracking.status == Some(crate::tracking::TrackingStatus::Tracking);
            self.info.history.record(
                now.saturating_duration_since(self.started).as_secs_f64(),
                d.as_secs_f64() * 1e3,
                tracking.then_some(self.info.tracking.stats.latency_last_ms),
            );
        }
        if let Some(pads) = self.gamepads.as_ref()
            && self.info.tracking.gamepads != pads.names()
        {
            self.info.tracking.gamepads = pads.names().to_vec();
        }
    }

    /// The `--stats-every` log lines, when their interval has passed.
    fn log_stats(&mut self) {
        let Some(every) = self.options.stats_every else {
            return;
        };
        if self.last_stats_log.elapsed().as_secs_f64() < every {
            return;
        }
        self.last_stats_log = Instant::now();
        tracing::info!(
            target: "omnicave::stats",
            "stats: {} | frames {} | mode {} | windows {} | views {} | surface recoveries {} \
             | eye re-syncs {}",
            self.clock.summary,
            self.clock.total_frames,
            self.state.settings.render.mode.name(),
            self.gfx.as_ref().map_or(0, |g| g.windows.len()),
            self.gfx.as_ref().map_or(0, |g| g.renderer.last_views().len()),
            self.surface_recoveries,
            self.eye_resyncs
        );
        let b = &self.info.breakdown;
        if !b.views.is_empty() {
            let stages: Vec<String> = crate::render::ViewStage::ALL
                .iter()
                .map(|&stage| format!("{} {:.2}", stage.name(), b.stage_ms(stage)))
                .collect();
            tracing::info!(
                target: "omnicave::stats",
                "gpu stages (ms, all views): pose {:.2} | shadows {:.2} | {} | other {:.2}",
                b.pose_ms,
                b.shadows_ms,
                stages.join(" | "),
                b.total_ms - b.pose_ms - b.shadows_ms - b.views.iter().flatten().sum::<f64>()
            );
        }
        self.log_cluster();
        let t = &self.info.tracking;
        let head = self.state.head();
        if let Some(status) = t.status.filter(|_| self.state.settings.tracking.enabled) {
            let c = &t.counters;
            let (p, q) = (head.position, head.orientation);
            tracing::info!(
                target: "omnicave::stats",
                "tracking: {}, {:.1} Hz, head ({:.4}, {:.4}, {:.4}) m, orientation xyzw \
                 ({:.5}, {:.5}, {:.5}, {:.5}), {} button actions, latency avg {:.2} ms \
                 max {:.2} ms ({:.2} frame) | packets {} received, {} accepted, {} ignored, \
                 {} dropped, {} clamped | samples refused: {} | lost {} times | link {}",
                status.describe(),
                t.stats.rate_hz,
                p.x,
                p.y,
                p.z,
                q.x,
                q.y,
                q.z,
                q.w,
                t.button_actions,
                t.stats.latency_avg_ms,
                t.stats.latency_max_ms,
                t.stats.latency_max_frames,
                c.received,
                c.accepted,
                c.ignored,
                c.dropped(),
                t.stats.clamped,
                c.gate.describe(),
                t.stats.lost_events,
                t.link.as_ref().map_or_else(String::new, LinkState::describe)
            );
        }
    }

    /// The stats line's cluster figures: the master's broadcast and barrier with every node's
    /// figures, or a node's own.
    fn log_cluster(&self) {
        match &self.cluster {
            Some(ClusterLink::Master(m)) => {
                let f = m.session.figures;
                let nodes: Vec<String> = m
                    .session
                    .nodes()
                    .iter()
                    .skip(1)
                    .map(|n| match &n.lost {
                        Some(why) => format!("{} LOST: {why}", n.describe()),
                        None => format!(
                            "{} state wait {:.2} ms, barrier wait {:.3} ms, render {:.2} ms",
                            n.describe(),
                            n.figures.state_wait_ms,
                            n.figures.barrier_ms,
                            n.figures.render_ms
                        ),
                    })
                    .collect();
                tracing::info!(
                    target: "omnicave::stats",
                    "cluster: master frame {}, broadcast {:.3} ms, barrier wait {:.3} ms | {}",
                    f.frame,
                    f.broadcast_ms,
                    f.barrier_ms,
                    nodes.join(" | ")
                );
            }
            Some(ClusterLink::Node(n)) => {
                let f = n.session.figures;
                tracing::info!(
                    target: "omnicave::stats",
                    "cluster: node {} frame {}, state wait {:.2} ms, barrier wait {:.3} ms, \
                     render {:.2} ms",
                    n.rank,
                    n.frame,
                    f.state_wait_ms,
                    f.barrier_ms,
                    f.render_ms
                );
            }
            None => {}
        }
    }

    /// Writes the settings if the panel, a key or a button asked to.
    fn save_if_requested(&mut self) {
        if !self.state.save_requested {
            return;
        }
        self.state.save_requested = false;
        let path = self.state.save_path.clone();
        self.info.save_message = Some(match self.state.save(&path) {
            Ok(()) => {
                tracing::info!("settings saved to {}", path.display());
                format!("saved to {}", path.display())
            }
            Err(e) => {
                tracing::error!("{e}");
                e.to_string()
            }
        });
    }

    /// A window went (closed, destroyed, or failing beyond recovery): a wall's window is
    /// dropped and the others keep rendering; the operator or preview window's loss, or the
    /// last window's, ends the program cleanly.
    fn window_gone(&mut self, event_loop: &ActiveEventLoop, index: usize, how: &str) {
        let Some(gfx) = self.gfx.as_mut() else {
            return;
        };
        let Some(role) = gfx.windows.get(index).map(|w| w.role) else {
            return;
        };
        let name = role.name(&self.state.config);
        if !(role.wall().is_some() && gfx.windows.len() > 1) {
            self.quit_now(event_loop, &format!("window {name} {how}"));
            return;
        }
        tracing::warn!("window of wall {name} {how}; the other windows keep rendering");
        let gone = gfx.windows.remove(index);
        match gfx.egui.as_ref().map(|h| h.window_index) {
            Some(host) if host == index => gfx.egui = None,
            Some(host) if host > index => {
                if let Some(h) = gfx.egui.as_mut() {
                    h.window_index -= 1;
                }
            }
            _ => {}
        }
        drop(gone);
    }

    fn quit_now(&mut self, event_loop: &ActiveEventLoop, why: &str) {
        tracing::info!("quitting: {why}");
        match self.cluster.as_mut() {
            Some(ClusterLink::Master(master)) => {
                master.session.stop(&format!("the master quit ({why})"));
            }
            // After the master's stop this says nothing more; otherwise the master hears why.
            Some(ClusterLink::Node(node)) => node.session.leave(why),
            None => {}
        }
        if let Some(gfx) = self.gfx.as_ref()
            && let Err(e) = gfx.renderer.wait_idle()
        {
            tracing::warn!("{e}");
        }
        // Windows and surfaces are dropped before the device.
        if let Some(mut gfx) = self.gfx.take() {
            gfx.egui = None;
            gfx.windows.clear();
        }
        event_loop.exit();
    }
}

impl ApplicationHandler for App {
    fn resumed(&mut self, event_loop: &ActiveEventLoop) {
        if self.gfx.is_some() {
            return;
        }
        match self.start(event_loop) {
            Ok(gfx) => self.gfx = Some(gfx),
            Err(e) => self.fail(event_loop, e),
        }
        event_loop.set_control_flow(ControlFlow::Poll);
    }

    fn window_event(&mut self, event_loop: &ActiveEventLoop, id: WindowId, event: WindowEvent) {
        let Some(gfx) = self.gfx.as_mut() else {
            return;
        };
        let Some(index) = gfx.windows.iter().position(|w| w.id() == id) else {
            return;
        };
        let mut consumed = false;
        if let Some(host) = gfx.egui.as_mut()
            && host.window_index == index
        {
            consumed = host.on_event(&gfx.windows[index], &event);
        }
        match event {
            WindowEvent::CloseRequested => self.window_gone(event_loop, index, "closed"),
            // XDestroyWindow from another client (`xdotool windowclose`): like a close, but
            // nothing may touch the window again (winit's size query would panic).
            WindowEvent::Destroyed => {
                self.window_gone(event_loop, index, "destroyed from outside");
            }
            WindowEvent::Resized(size) => {
                gfx.windows[index].resize(&gfx.gpu, size.width, size.height);
            }
            WindowEvent::ModifiersChanged(m) => {
                self.shift = m.state().shift_key();
                self.ctrl = m.state().control_key();
            }
            // A render node takes no input: its windows show the master's frames.
            WindowEvent::KeyboardInput { .. }
            | WindowEvent::MouseInput { .. }
            | WindowEvent::CursorMoved { .. }
                if matches!(self.cluster, Some(ClusterLink::Node(_))) => {}
            WindowEvent::KeyboardInput { event, .. } => {
                let PhysicalKey::Code(code) = event.physical_key else {
                    return;
                };
                let pressed = event.state == ElementState::Pressed;
                if consumed && pressed {
                    return;
                }
                let modified = self.shift || self.ctrl;
                if !modified && self.held.set(code, pressed) {
                    return;
                }
                if pressed
                    && !event.repeat
                    && let Some(action) = keys::action_for_key(code, self.shift, self.ctrl)
                {
                    self.state.apply(action);
                }
            }
            WindowEvent::MouseInput {
                button: MouseButton::Right,
                state,
                ..
            } => {
                self.drag = (state == ElementState::Pressed && !consumed).then_some(None);
            }
            WindowEvent::CursorMoved { position, .. } => {
                if let Some(last) = self.drag.as_mut() {
                    if let Some(x) = *last {
                        self.state
                            .turn(-((position.x - x) as f32) * MOUSE_TURN_PER_PIXEL);
                    }
                    *last = Some(position.x);
                }
            }
            WindowEvent::Focused(false) => {
                // Keys released while another window has focus never arrive.
                self.held = HeldKeys::default();
                self.drag = None;
            }
            _ => {}
        }
    }

    fn about_to_wait(&mut self, event_loop: &ActiveEventLoop) {
        if self.gfx.is_none() {
            return;
        }
        if crate::signals::stop_requested() {
            self.quit_now(event_loop, "signal");
            return;
        }
        if self.state.quit_requested {
            self.quit_now(event_loop, "asked from the keyboard or panel");
            return;
        }
        // A render node ends when the master says so.
        let node = matches!(self.cluster, Some(ClusterLink::Node(_)));
        if let Some(limit) = self.options.quit_after.filter(|_| !node)
            && self.started.elapsed() >= Duration::from_secs_f64(limit.max(0.0))
        {
            self.quit_now(event_loop, "--quit-after elapsed");
            return;
        }
        self.frame(event_loop);
    }

    fn exiting(&mut self, _event_loop: &ActiveEventLoop) {
        tracing::info!("{} frames rendered", self.clock.total_frames);
    }
}

/// Renders the walls (and the panorama when shown) from the state; applies settings that
/// change pipelines or targets first. A cluster `node` shows no panorama (the master's
/// operator window does), and a setting it cannot apply ends it rather than let its walls
/// differ from the others'.
fn render_views(
    gfx: &mut Graphics,
    state: &mut AppState,
    info: &mut PanelInfo,
    node: bool,
) -> Result<(), AppError> {
    let settings = state.render_settings();
    if gfx.renderer.settings() != settings
        && let Err(e) = gfx.renderer.set_settings(settings, state.render_cave())
    {
        if node {
            return Err(e.into());
        }
        tracing::error!("{e}; keeping the previous settings");
        state.settings.render.msaa = gfx.renderer.settings().msaa;
    }
    let stats = gfx.renderer.render(&state.frame_params())?;
    if state.settings.panorama.show && !node {
        let frame = state.frame_params();
        if let Err(e) = gfx.renderer.render_panorama(&frame, &state.settings.pano()) {
            tracing::error!("panorama: {e}; closing the panorama view");
            state.settings.panorama.show = false;
        }
    }
    // Every wall this process renders (all but in cluster mode) draws the whole scene once
    // per view of it.
    let views_per_wall = if state.settings.render.mode.is_stereo() {
        2
    } else {
        1
    };
    let walls = (stats.views / views_per_wall).max(1);
    info.triangles_per_wall = stats.triangles_submitted / walls;
    info.dispatches = stats.dispatches;
    info.fine_triangles = stats.fine_triangles;
    if stats.dispatches == 0 {
        info.triangles_drawn = stats.triangles_submitted;
    }
    Ok(())
}

/// Composes and presents every window (the panel into its host window): the number of
/// surfaces recovered on the way, and a window lost on the way (its window system calls
/// panicked: destroyed from outside between the events and this frame).
fn present_windows(
    gfx: &mut Graphics,
    state: &AppState,
    egui_frame: Option<window::EguiFrame>,
    eye_frame: u64,
) -> Presented {
    let mut out = Presented::default();
    for (index, win) in gfx.windows.iter_mut().enumerate() {
        let egui = match (&mut gfx.egui, &egui_frame) {
            (Some(host), Some(frame)) if host.window_index == index => Some((host, frame)),
            _ => None,
        };
        let (gpu, renderer) = (&gfx.gpu, &gfx.renderer);
        let drawn = std::panic::catch_unwind(AssertUnwindSafe(|| {
            win.draw(gpu, renderer, state, egui, eye_frame)
        }));
        match drawn {
            Ok(Ok(r)) => {
                out.recovered += u64::from(r.recovered);
                out.resynced += u64::from(r.resynced);
            }
            Ok(Err(e)) => tracing::warn!("{e}"),
            Err(_) => {
                out.lost = Some(index);
                break;
            }
        }
    }
    if let (Some(host), Some(frame)) = (gfx.egui.as_mut(), egui_frame) {
        host.free_textures(frame);
    }
    out
}

/// What the wand's ray hits, in words for the panel (scene space is the scene file's units).
fn select(scene: &Scene, state: &AppState) -> String {
    let Some(ray) = state.wand_ray() else {
        return "no wand tracked".into();
    };
    let world = state.world_from_cave();
    let origin = world.transform_point3(ray.origin);
    let far = world.transform_point3(ray.tip());
    let Some(dir) = (far - origin).try_normalize() else {
        return "no wand ray".into();
    };
    let reach = (far - origin).length();
    match crate::scene::pick::pick(scene, origin, dir, reach) {
        Some(p) => format!(
            "{} (material {}), {:.2} m along the ray, triangle {} (wand at {:.3}, pointing {:.3})",
            if p.material_name.is_empty() {
                "unnamed"
            } else {
                &p.material_name
            },
            p.material,
            p.distance * ray.length / reach,
            p.triangle,
            ray.origin,
            ray.direction
        ),
        None => format!(
            "nothing within {:.1} m (wand at {:.3}, pointing {:.3})",
            ray.length, ray.origin, ray.direction
        ),
    }
}

/// Where screenshots go (a folder per shot, named by time and frame).
const SCREENSHOT_DIR: &str = "screenshots";

/// Writes every wall's eye images as PNG (`<wall>-left.png`, `<wall>-right.png`) and the
/// settings they were rendered with (`settings.toml`, loadable as a config) to a new folder
/// named by `id` (the master's clock in cluster mode, so that every process writes its walls
/// into the same folder). Reads the images back once, on request: never in the frame loop
/// otherwise.
fn screenshot(
    gfx: &Graphics,
    state: &AppState,
    id: u64,
    frame: u64,
    own_walls: &[bool],
) -> Result<PathBuf, String> {
    let dir = PathBuf::from(SCREENSHOT_DIR).join(format!("shot-{id}-frame{frame}"));
    write_walls(gfx, state, &dir, own_walls)?;
    state
        .save(&dir.join("settings.toml"))
        .map_err(|e| e.to_string())?;
    Ok(dir)
}

/// `--record`: this process's walls' eye images of `frame` into `DIR/frame-NNNNNN/`, and
/// (`describe`: the master or a single process) the frame's state as broadcast
/// (`frame.bin`) and its settings as sent (`settings.toml`), from which any process can
/// render the same frame again.
fn record_frame(
    gfx: &Graphics,
    state: &AppState,
    dir: &std::path::Path,
    frame: u64,
    own_walls: &[bool],
    describe: bool,
) -> Result<(), String> {
    let dir = dir.join(format!("frame-{frame:06}"));
    write_walls(gfx, state, &dir, own_walls)?;
    if describe {
        let mut bytes = Vec::new();
        crate::cluster::Message::Frame(cluster_link::frame_state(state, frame, 0, 0))
            .encode(&mut bytes);
        let text = crate::cluster::settings_text(&state.settings)?;
        for (name, data) in [
            ("frame.bin", &bytes[..]),
            ("settings.toml", text.as_bytes()),
        ] {
            let path = dir.join(name);
            std::fs::write(&path, data)
                .map_err(|e| format!("cannot write {}: {e}", path.display()))?;
        }
    }
    Ok(())
}

/// Writes the eye images of the walls marked in `own_walls` (all when empty) into `dir`.
fn write_walls(
    gfx: &Graphics,
    state: &AppState,
    dir: &std::path::Path,
    own_walls: &[bool],
) -> Result<(), String> {
    std::fs::create_dir_all(dir).map_err(|e| format!("cannot create {}: {e}", dir.display()))?;
    let mut textures = Vec::new();
    let mut names = Vec::new();
    for (i, wall) in state.cave().walls.iter().enumerate() {
        if !own_walls.get(i).copied().unwrap_or(true) {
            continue;
        }
        for eye in crate::cave::Eye::BOTH {
            if let Some(t) = gfx.renderer.eye_texture(i, eye) {
                textures.push(t);
                names.push(format!("{}-{}.png", wall.name, eye.name()));
            }
        }
    }
    let images = crate::render::targets::read_textures(&gfx.gpu.device, &gfx.gpu.queue, &textures)
        .map_err(|e| e.to_string())?;
    for (image, name) in images.iter().zip(&names) {
        let path = dir.join(name);
        image
            .save(&path)
            .map_err(|e| format!("cannot write {}: {e}", path.display()))?;
    }
    Ok(())
}

/// What presenting every window did.
#[derive(Debug, Default)]
struct Presented {
    /// Surfaces recovered.
    recovered: u64,
    /// Frame-sequential windows brought back into the shared eye phase.
    resynced: u64,
    /// A window lost on the way (its window system calls panicked).
    lost: Option<usize>,
}

/// The tessellator's counts of the newest frame read back, summed per wall (both eyes), into
/// `counts` (reused; emptied when that frame was not tessellated or had other views).
fn per_wall_counts(renderer: &Renderer, walls: usize, counts: &mut Vec<u32>) {
    counts.clear();
    let stats = &renderer.latest_readback().tess;
    let views = renderer.last_views();
    if stats.is_empty() || stats.len() != views.len() {
        return;
    }
    counts.resize(walls, 0);
    for (view, s) in views.iter().zip(stats) {
        if let Some(count) = counts.get_mut(view.wall) {
            *count += s.emitted;
        }
    }
}
