//! `bench --cluster`: what lockstep costs per frame, run under `mpirun`. Every rank renders
//! its walls headless; rank 0 writes `cluster.md` and `cluster.csv`.
//!
//! Two phases, each of `frames` frames after three warm-up frames:
//! - **lockstep**: the master broadcasts a frame state (the head walking a small circle);
//!   every rank renders its walls and waits for its GPU; nodes report; the master's barrier
//!   releases them. A frame's cost of the cluster is its time less the slowest rank's render.
//! - **protocol**: the same broadcast and barrier with nothing rendered: the messaging's own
//!   round trip (on one machine: loopback and shared memory).

use std::io::Write as _;
use std::path::{Path, PathBuf};
use std::time::Instant;

use glam::Vec3;

use super::BenchError;
use super::measure::percentile;
use crate::cluster::roles::{node_of, walls_by_node};
use crate::cluster::session::Timeouts;
use crate::cluster::{FrameState, Master, Node, NodeStep, Transport, identity};
use crate::config::Config;
use crate::render::{Gpu, Renderer};
use crate::setup::{
    frame_params_from, load_config_sky, load_scene, place_at_camera, render_settings,
};

/// Frame numbers from here on are the protocol phase (nothing rendered).
const PROTOCOL_FRAMES_FROM: u64 = 1 << 40;
const WARM_UP: usize = 3;

/// What to measure.
#[derive(Debug, Clone)]
pub struct ClusterBenchOptions {
    pub config: PathBuf,
    /// Instead of the config's scene.
    pub scene: Option<PathBuf>,
    /// Timed frames per phase.
    pub frames: usize,
    /// Every wall's pixel size, instead of the config's.
    pub size: Option<[u32; 2]>,
    pub out: PathBuf,
}

/// One timed frame on the master.
#[derive(Debug, Clone, Copy, Default)]
struct FrameRow {
    frame_ms: f64,
    master_render_ms: f64,
    slowest_render_ms: f64,
    broadcast_ms: f64,
    barrier_ms: f64,
}

/// This rank's renderer of its own walls, and the frame each frame number renders.
struct RankRenderer<'a> {
    config: &'a Config,
    renderer: Renderer,
    /// The head at rest; frames walk it round a small circle.
    base: Vec3,
}

impl RankRenderer<'_> {
    /// Renders `frame` (the head on its circle) and waits for the GPU; returns the time, ms.
    fn render(&mut self, frame: u64) -> Result<f64, BenchError> {
        let config = self.config;
        let start = Instant::now();
        let mut head = config.settings.head();
        let t = frame as f32 * 0.1;
        head.position = self.base + Vec3::new(0.2 * t.cos(), 0.0, 0.2 * t.sin());
        let params = frame_params_from(
            &config.settings,
            &config.cave,
            head,
            config.settings.world_from_cave(),
        );
        self.renderer.render(&params)?;
        self.renderer.wait_idle()?;
        Ok(start.elapsed().as_secs_f64() * 1e3)
    }
}

/// Runs this rank's part; on rank 0, writes the report and returns its files.
pub fn run_cluster(
    options: &ClusterBenchOptions,
    transport: Box<dyn Transport>,
) -> Result<Vec<PathBuf>, BenchError> {
    let (config, scene) = load_cluster_config(options)?;
    let sky = load_config_sky(&config);
    let rank = transport.rank();
    let size = transport.size();
    let walls = walls_by_node(&config, size).map_err(BenchError::Cluster)?;
    let own: Vec<bool> = (0..config.cave.walls.len())
        .map(|i| node_of(&config, i) == rank)
        .collect();
    let gpu = Gpu::headless()?;
    let mut renderer = Renderer::new(&gpu, &config.cave, render_settings(&config.settings))?;
    renderer.set_scene(&scene)?;
    if let Err(e) = renderer.set_sky(sky.as_ref()) {
        tracing::error!("{e}; without a sky");
    }
    renderer.set_wall_filter(Some(own));
    let me = identity(transport.host(), &config, &scene);
    let timeouts = Timeouts::from_settings(&config.settings.cluster);
    let base = config.settings.head().position;
    let mut rank_renderer = RankRenderer {
        config: &config,
        renderer,
        base,
    };
    if rank != 0 {
        let node = Node::start(transport, &me, timeouts).map_err(BenchError::Cluster)?;
        return follow_master(node, &mut rank_renderer);
    }
    let mut master = Master::start(transport, &me, walls, timeouts).map_err(BenchError::Cluster)?;
    let mut lockstep = Vec::with_capacity(options.frames);
    let mut protocol = Vec::with_capacity(options.frames);
    for (phase, first) in [(&mut lockstep, 0), (&mut protocol, PROTOCOL_FRAMES_FROM)] {
        time_phase(
            &mut master,
            &mut rank_renderer,
            first,
            options.frames,
            phase,
        )?;
    }
    master.stop("bench done");
    let hosts: Vec<String> = master.nodes().iter().map(|n| n.describe()).collect();
    write_report(
        &options.out,
        &config,
        &hosts,
        &lockstep,
        &protocol,
        gpu.adapter.get_info().name,
    )
}

/// The config with every wall at the run's size, and its scene, the camera placed in it.
fn load_cluster_config(
    options: &ClusterBenchOptions,
) -> Result<(Config, crate::scene::Scene), BenchError> {
    let mut config = Config::load(&options.config)?;
    if let Some(size) = options.size {
        for wall in &mut config.cave.walls {
            wall.resolution = size;
        }
        for wall in &mut config.settings.walls {
            wall.resolution = size;
        }
    }
    let scene_path = options.scene.clone().or_else(|| config.scene_path.clone());
    let scene = match &scene_path {
        Some(p) => load_scene(&config.settings, p)?,
        None => crate::scene::Scene::default(),
    };
    place_at_camera(&mut config.settings, &scene)?;
    Ok((config, scene))
}

/// A node's part: renders each frame the master sends (nothing in the protocol phase) and
/// reports at the barrier, until the master stops.
fn follow_master(
    mut node: Node<Box<dyn Transport>>,
    rank_renderer: &mut RankRenderer<'_>,
) -> Result<Vec<PathBuf>, BenchError> {
    loop {
        match node.next_frame(|_, _| {}).map_err(BenchError::Cluster)? {
            NodeStep::Stop(_) => return Ok(Vec::new()),
            NodeStep::Frame(s) => {
                let ms = if s.frame >= PROTOCOL_FRAMES_FROM {
                    0.0
                } else {
                    rank_renderer.render(s.frame)?
                };
                if node
                    .barrier(s.frame, ms, false)
                    .map_err(BenchError::Cluster)?
                    .is_some()
                {
                    return Ok(Vec::new());
                }
            }
        }
    }
}

/// One phase on the master: the warm-up frames, then `frames` timed ones numbered from
/// `first` (rendered in the lockstep phase, from 0), appended to `phase`.
fn time_phase(
    master: &mut Master<Box<dyn Transport>>,
    rank_renderer: &mut RankRenderer<'_>,
    first: u64,
    frames: usize,
    phase: &mut Vec<FrameRow>,
) -> Result<(), BenchError> {
    for i in 0..(WARM_UP + frames) as u64 {
        let frame = first + i;
        let start = Instant::now();
        let state = FrameState {
            frame,
            head_position: rank_renderer.base,
            ..Default::default()
        };
        let lost = master.broadcast(None, &state);
        let master_render_ms = if first == 0 {
            rank_renderer.render(frame)?
        } else {
            0.0
        };
        let lost = master
            .barrier(frame, false, lost)
            .map_err(BenchError::Cluster)?;
        if !lost.is_empty() {
            master.stop("bench: a node was lost");
            return Err(BenchError::Cluster(
                crate::cluster::ClusterError::NodeLostStop(format!("{lost:?}")),
            ));
        }
        let slowest = master
            .nodes()
            .iter()
            .skip(1)
            .map(|n| f64::from(n.figures.render_ms))
            .fold(master_render_ms, f64::max);
        if i as usize >= WARM_UP {
            phase.push(FrameRow {
                frame_ms: start.elapsed().as_secs_f64() * 1e3,
                master_render_ms,
                slowest_render_ms: slowest,
                broadcast_ms: master.figures.broadcast_ms,
                barrier_ms: master.figures.barrier_ms,
            });
        }
    }
    Ok(())
}

fn quantile(rows: &[FrameRow], q: f64, f: impl Fn(&FrameRow) -> f64) -> f64 {
    let mut v: Vec<f64> = rows.iter().map(f).collect();
    v.sort_by(f64::total_cmp);
    percentile(&v, q)
}

fn median(rows: &[FrameRow], f: impl Fn(&FrameRow) -> f64) -> f64 {
    quantile(rows, 0.5, f)
}

fn p95(rows: &[FrameRow], f: impl Fn(&FrameRow) -> f64) -> f64 {
    quantile(rows, 0.95, f)
}

fn write_report(
    out: &Path,
    config: &Config,
    hosts: &[String],
    lockstep: &[FrameRow],
    protocol: &[FrameRow],
    adapter: String,
) -> Result<Vec<PathBuf>, BenchError> {
    std::fs::create_dir_all(out).map_err(|source| BenchError::Write {
        path: out.to_owned(),
        source,
    })?;
    let csv_path = out.join("cluster.csv");
    let csv_err = |e: csv::Error| BenchError::Csv {
        path: csv_path.clone(),
        message: e.to_string(),
    };
    let mut csv = csv::Writer::from_path(&csv_path).map_err(csv_err)?;
    csv.write_record([
        "phase",
        "frame",
        "frame_ms",
        "master_render_ms",
        "slowest_render_ms",
        "cluster_cost_ms",
        "broadcast_ms",
        "barrier_ms",
    ])
    .map_err(csv_err)?;
    for (phase, rows) in [("lockstep", lockstep), ("protocol", protocol)] {
        for (i, r) in rows.iter().enumerate() {
            csv.write_record([
                phase.to_owned(),
                i.to_string(),
                format!("{:.4}", r.frame_ms),
                format!("{:.4}", r.master_render_ms),
                format!("{:.4}", r.slowest_render_ms),
                format!("{:.4}", r.frame_ms - r.slowest_render_ms),
                format!("{:.4}", r.broadcast_ms),
                format!("{:.4}", r.barrier_ms),
            ])
            .map_err(csv_err)?;
        }
    }
    csv.flush().map_err(|source| BenchError::Write {
        path: csv_path.clone(),
        source,
    })?;
    let cost = |r: &FrameRow| r.frame_ms - r.slowest_render_ms;
    let round_trip = |r: &FrameRow| r.broadcast_ms + r.barrier_ms;
    let wall = config.cave.walls.first().map_or([0, 0], |w| w.resolution);
    let text = format!(
        "# Cluster bench\n\n\
         {} processes ({}); {} walls of {}×{} in {}; adapter {adapter}; {} frames per phase.\n\n\
         | phase | frame (median) | slowest rank's render | cluster cost per frame (median / p95) | broadcast | master's barrier wait |\n\
         |---|---:|---:|---:|---:|---:|\n\
         | lockstep | {:.3} ms | {:.3} ms | {:.3} / {:.3} ms | {:.4} ms | {:.3} ms |\n\
         | protocol only | {:.4} ms | — | {:.4} / {:.4} ms (round trip) | {:.4} ms | {:.4} ms |\n\n\
         The cluster cost of a lockstep frame is its time less the slowest rank's render (each \
         rank's render includes waiting for its GPU): broadcast, the reports, the barrier and \
         the release. The protocol phase is the same exchange with nothing rendered.\n",
        hosts.len(),
        hosts.join("; "),
        config.cave.walls.len(),
        wall[0],
        wall[1],
        config.settings.render.mode.name(),
        lockstep.len(),
        median(lockstep, |r| r.frame_ms),
        median(lockstep, |r| r.slowest_render_ms),
        median(lockstep, cost),
        p95(lockstep, cost),
        median(lockstep, |r| r.broadcast_ms),
        median(lockstep, |r| r.barrier_ms),
        median(protocol, round_trip),
        median(protocol, round_trip),
        p95(protocol, round_trip),
        median(protocol, |r| r.broadcast_ms),
        median(protocol, |r| r.barrier_ms),
    );
    let md_path = out.join("cluster.md");
    let mut f = std::fs::File::create(&md_path).map_err(|source| BenchError::Write {
        path: md_path.clone(),
        source,
    })?;
    f.write_all(text.as_bytes())
        .map_err(|source| BenchError::Write {
            path: md_path.clone(),
            source,
        })?;
    tracing::info!("{text}");
    Ok(vec![md_path, csv_path])
}
