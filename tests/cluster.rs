//! Cluster mode, for real: `mpirun -np 3` of the omnicave binary under Xvfb, one
//! wall window per process. Every recorded frame of the three processes (an animated scene
//! playing) is compared per pixel with the single-process renderer given the same state and
//! animation instant; the processes present the
//! same frames on the same eye; a stalled or killed node is reported and handled as
//! configured; a node that loaded something else is refused by name.
//!
//! Needs Open MPI's `mpirun` (scripts/setup.sh installs it) and a build with
//! `--features cluster` (scripts/test.sh builds so): the file is empty otherwise.
#![cfg(feature = "cluster")]
#![allow(clippy::unwrap_used, clippy::expect_used)]

mod common;

use std::collections::{BTreeMap, BTreeSet};
use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use common::xvfb::{X_SERVER, Xvfb};
use omnicave::app::cluster_link::{apply_frame_state, apply_settings};
use omnicave::app::state::AppState;
use omnicave::cluster::{FrameState, Message};
use omnicave::config::Config;
use omnicave::render::Renderer;
use omnicave::setup::{load_config_sky, load_scene, place_at_camera};

const SCREEN: [u32; 2] = [1400, 900];
/// Wall windows side by side; the operator window below.
const WALLS: [(&str, [i32; 2], u32); 3] = [
    ("left", [0, 0], 1),
    ("front", [330, 0], 0),
    ("right", [660, 0], 2),
];

fn repo() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

fn out_dir(name: &str) -> PathBuf {
    let dir = repo().join("target/test-output/cluster").join(name);
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).expect("out dir");
    dir
}

/// The desktop config as a three-wall CAVE of 320×240 frame-sequential walls, one per rank
/// (left on 1, front on the master, right on 2), the panel in an operator window, with
/// `extra` appended (TOML sections).
fn write_config(dir: &Path, name: &str, extra: &str) -> PathBuf {
    write_config_with_output(dir, name, extra, "frame-sequential")
}

/// As [`write_config`], every wall window in stereo format `output`.
fn write_config_with_output(dir: &Path, name: &str, extra: &str, output: &str) -> PathBuf {
    let desktop = std::fs::read_to_string(repo().join("config/desktop.toml")).expect("config");
    let app_start = desktop.find("\n[app]").expect("[app] in desktop.toml");
    let app_end = app_start
        + desktop[app_start..]
            .find("\n[[wall]]")
            .expect("walls after [app]");
    let desktop = format!("{}{}", &desktop[..app_start], &desktop[app_end..]);
    let assets = repo().join("assets");
    let text = desktop
        .replace("resolution = [480, 422]", "resolution = [320, 240]")
        .replace("\"../assets/", &format!("\"{}/", assets.display()));
    let mut parts: Vec<String> = text.split("[[wall]]").map(str::to_owned).collect();
    for (part, (name, pos, node)) in parts.iter_mut().skip(1).zip(WALLS) {
        assert!(part.contains(&format!("\"{name}\"")));
        *part = format!(
            "{}\nwindow_position = [{}, {}]\noutput = \"{output}\"\nnode = {node}\n\n",
            part.trim_end(),
            pos[0],
            pos[1]
        );
    }
    let text = format!(
        "{}[app]\nmode = \"cave\"\npanel = \"window\"\nwindow_position = [0, 260]\n\
         window_size = [1000, 600]\nvsync = false\n\n{extra}\n\n[[wall]]{}",
        parts[0],
        parts[1..].join("[[wall]]")
    );
    let path = dir.join(name);
    std::fs::write(&path, text).expect("write config");
    path
}

/// `mpirun` of three omnicave ranks, with every rank's log lines collected by rank.
struct Cluster {
    child: Child,
    lines: Arc<Mutex<Vec<(usize, String)>>>,
}

fn mpirun() -> PathBuf {
    let found = Command::new("sh")
        .args(["-c", "command -v mpirun"])
        .output()
        .expect("sh");
    let path = String::from_utf8_lossy(&found.stdout).trim().to_owned();
    // Never a skip: CI installs Open MPI (scripts/setup.sh) and must run these tests.
    assert!(
        !path.is_empty(),
        "mpirun not found: install Open MPI (openmpi-bin; scripts/setup.sh does)"
    );
    PathBuf::from(path)
}

impl Cluster {
    /// `mpirun [launch…] -np N omnicave run --cluster ARGS` (or an MPMD line when `launch`
    /// has its own `:` parts), logging at `filter`.
    fn start(display: &str, launch: &[String], filter: &str, cwd: &Path) -> Cluster {
        let runtime = std::env::temp_dir().join("omnicave-xdg");
        std::fs::create_dir_all(&runtime).expect("runtime dir");
        {
            use std::os::unix::fs::PermissionsExt;
            std::fs::set_permissions(&runtime, std::fs::Permissions::from_mode(0o700))
                .expect("chmod");
        }
        let mut child = Command::new(mpirun())
            // Root in containers; more ranks than cores; a lost rank does not end the job
            // (the others decide: cluster.on_node_loss); each line tagged with its rank.
            .args([
                "--allow-run-as-root",
                "--oversubscribe",
                "--enable-recovery",
            ])
            // No cross-process memory copy between ranks: containers often forbid it (ptrace).
            .args([
                "--tag-output",
                "--mca",
                "btl_vader_single_copy_mechanism",
                "none",
            ])
            .args(launch)
            .env("DISPLAY", display)
            .env("XDG_RUNTIME_DIR", &runtime)
            .env("RUST_LOG", filter)
            .env("NO_COLOR", "1")
            .env_remove("WAYLAND_DISPLAY")
            .current_dir(cwd)
            .stdin(Stdio::null())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .expect("start mpirun");
        let lines = Arc::new(Mutex::new(Vec::new()));
        for stream in [
            Box::new(child.stdout.take().expect("stdout")) as Box<dyn std::io::Read + Send>,
            Box::new(child.stderr.take().expect("stderr")),
        ] {
            let sink = lines.clone();
            std::thread::spawn(move || {
                for line in BufReader::new(stream).lines().map_while(Result::ok) {
                    // "[1,2]<stderr>:…": job 1, rank 2.
                    let rank = line
                        .strip_prefix('[')
                        .and_then(|l| l.split(']').next())
                        .and_then(|tag| tag.split(',').nth(1))
                        .and_then(|r| r.parse().ok())
                        .unwrap_or(usize::MAX);
                    sink.lock().unwrap().push((rank, line));
                }
            });
        }
        Cluster { child, lines }
    }

    fn log(&self) -> String {
        let lines = self.lines.lock().unwrap();
        lines
            .iter()
            .map(|(_, l)| l.as_str())
            .collect::<Vec<_>>()
            .join("\n")
    }

    fn lines_of(&self, rank: usize) -> Vec<String> {
        let lines = self.lines.lock().unwrap();
        lines
            .iter()
            .filter(|(r, _)| *r == rank)
            .map(|(_, l)| l.clone())
            .collect()
    }

    /// Waits (at most `limit`) until a line of `rank` satisfies `find`.
    fn wait_for<T>(
        &mut self,
        rank: usize,
        what: &str,
        limit: Duration,
        find: impl Fn(&str) -> Option<T>,
    ) -> T {
        let start = Instant::now();
        loop {
            if let Some(found) = self.lines_of(rank).iter().find_map(|l| find(l)) {
                return found;
            }
            if let Ok(Some(status)) = self.child.try_wait() {
                panic!("mpirun exited ({status}) before {what}:\n{}", self.log());
            }
            assert!(
                start.elapsed() < limit,
                "no {what} within {limit:?}:\n{}",
                self.log()
            );
            std::thread::sleep(Duration::from_millis(50));
        }
    }

    /// The newest frame number `rank` has logged in a cluster stats line.
    fn frame_of(&self, rank: usize) -> Option<u64> {
        self.lines_of(rank)
            .iter()
            .filter_map(|l| {
                let rest = l.split("cluster: ").nth(1)?;
                let rest = rest.split(" frame ").nth(1)?;
                rest.split([',', ' ']).next()?.parse().ok()
            })
            .max()
    }

    fn wait_frame(&mut self, rank: usize, frame: u64, limit: Duration) {
        let start = Instant::now();
        while self.frame_of(rank).unwrap_or(0) < frame {
            if let Ok(Some(status)) = self.child.try_wait() {
                panic!(
                    "mpirun exited ({status}) before frame {frame}:\n{}",
                    self.log()
                );
            }
            assert!(
                start.elapsed() < limit,
                "rank {rank} not at frame {frame} within {limit:?}:\n{}",
                self.log()
            );
            std::thread::sleep(Duration::from_millis(100));
        }
    }

    /// The newest frame count `rank` has logged in a stats line (cluster or not).
    fn frames_of(&self, rank: usize) -> u64 {
        self.lines_of(rank)
            .iter()
            .filter_map(|l| l.split("| frames ").nth(1)?.split(' ').next()?.parse().ok())
            .max()
            .unwrap_or(0)
    }

    /// Waits for mpirun to end (at most `limit`: nothing may hang); its status.
    fn wait_exit(&mut self, limit: Duration) -> std::process::ExitStatus {
        let start = Instant::now();
        loop {
            if let Ok(Some(status)) = self.child.try_wait() {
                // Let the readers drain the last lines.
                std::thread::sleep(Duration::from_millis(300));
                return status;
            }
            if start.elapsed() > limit {
                let _ = self.child.kill();
                panic!(
                    "the cluster hung: mpirun still running after {limit:?}:\n{}",
                    self.log()
                );
            }
            std::thread::sleep(Duration::from_millis(50));
        }
    }

    /// The pid rank `rank` logged at start-up.
    fn pid_of(&mut self, rank: usize) -> u32 {
        self.wait_for(rank, "its pid", Duration::from_secs(120), |l| {
            l.split("(pid ").nth(1)?.split(')').next()?.parse().ok()
        })
    }
}

impl Drop for Cluster {
    fn drop(&mut self) {
        if let Ok(None) = self.child.try_wait() {
            let _ = self.child.kill();
            let _ = self.child.wait();
        }
    }
}

/// `-np 3 omnicave run --cluster --config CONFIG` plus `args`.
fn launch(config: &Path, args: &[&str]) -> Vec<String> {
    let mut v: Vec<String> = [
        "-np",
        "3",
        env!("CARGO_BIN_EXE_omnicave"),
        "run",
        "--cluster",
    ]
    .iter()
    .map(|s| s.to_string())
    .collect();
    v.extend(["--config".to_owned(), config.display().to_string()]);
    v.extend(["--stats-every".to_owned(), "0.5".to_owned()]);
    v.extend(args.iter().map(|s| s.to_string()));
    v
}

/// Presses `keysym` in the window whose top-left corner is at `window_at`.
fn press_key(display: &str, at: [i16; 2], keysym: u32) {
    common::xvfb::press_key(display, window_at(display, at), keysym);
}

/// The window whose top-left corner is at `at` on `display`.
fn window_at(display: &str, at: [i16; 2]) -> u32 {
    use x11rb::protocol::xproto::ConnectionExt;
    let (conn, screen) = x11rb::connect(Some(display)).expect("X connection");
    let root = x11rb::connection::Connection::setup(&conn).roots[screen].root;
    let tree = conn.query_tree(root).unwrap().reply().unwrap();
    tree.children
        .into_iter()
        .find(|&w| {
            let g = conn.get_geometry(w).unwrap().reply().unwrap();
            let a = conn.get_window_attributes(w).unwrap().reply().unwrap();
            a.map_state == x11rb::protocol::xproto::MapState::VIEWABLE && [g.x, g.y] == at
        })
        .expect("the window")
}

/// Sends `signal` (`-STOP`, `-CONT`, `-KILL`) to process `pid`.
fn signal(pid: u32, signal: &str) {
    let status = Command::new("kill")
        .args([signal, &pid.to_string()])
        .status()
        .expect("kill");
    assert!(status.success(), "kill {signal} {pid}");
}

/// Asserts that `rank` stopped because the master said so.
fn assert_told_to_stop(cluster: &Cluster, rank: usize) {
    assert!(
        cluster
            .lines_of(rank)
            .iter()
            .any(|l| l.contains("the master said stop")),
        "rank {rank} was not told to stop:\n{}",
        cluster.log()
    );
}

/// The master and node 1 render four more frames each.
fn assert_master_and_node_1_go_on(cluster: &mut Cluster) {
    let (m, n) = (cluster.frame_of(0).unwrap(), cluster.frame_of(1).unwrap());
    cluster.wait_frame(0, m + 4, Duration::from_secs(120));
    cluster.wait_frame(1, n + 4, Duration::from_secs(120));
}

/// Asserts that each of `ranks` ended with an error message.
fn assert_stopped_with_error(cluster: &Cluster, ranks: std::ops::Range<usize>) {
    for rank in ranks {
        assert!(
            // (mpirun tags each write: "error: " and the message may come apart.)
            cluster
                .lines_of(rank)
                .iter()
                .any(|l| l.contains("omnicave stopped: ")),
            "rank {rank} ends with an error:\n{}",
            cluster.log()
        );
    }
}

/// `(rank, frame, eye)` of every frame-sequential present logged at `omnicave::eye_phase`.
fn presents(cluster: &Cluster) -> Vec<(usize, u64, String)> {
    let lines = cluster.lines.lock().unwrap();
    lines
        .iter()
        .filter_map(|(rank, l)| {
            let rest = l.split("present window ").nth(1)?;
            let frame = rest
                .split(" frame ")
                .nth(1)?
                .split(' ')
                .next()?
                .parse()
                .ok()?;
            let eye = rest.split(" eye ").nth(1)?.split(' ').next()?.to_owned();
            Some((*rank, frame, eye))
        })
        .collect()
}

/// The acceptance test: three processes, three wall windows, the head moved by track-sim and
/// settings changed from the master's keyboard while it runs; every recorded frame of every
/// wall equals, per pixel, what the single-process renderer draws from the same state.
#[test]
fn three_ranks_show_per_pixel_what_one_process_shows_frame_after_frame() {
    let out = out_dir("lockstep");
    // Unfiltered tracking, so that the head moves every frame.
    let config_path = write_config(
        &out,
        "cluster.toml",
        "[cluster]\ntimeout_ms = 20000\n\n[tracking.filter]\nenabled = false",
    );
    // The animated sample, playing: every wall must show the master's instant.
    let text = std::fs::read_to_string(&config_path).unwrap();
    assert!(
        text.contains("living-room.glb"),
        "the desktop config's scene"
    );
    // The CAVE turned 55° in the scene: the sample's surface and one more of its animated
    // pieces are seen through a node's side wall, not only the master's front wall.
    let text = text.replace("living-room.glb", "animated.glb").replace(
        "translation = [0.0, 0.0, 0.0]\nyaw_degrees = 0.0",
        "translation = [0.0, 0.0, 0.0]\nyaw_degrees = 55.0",
    );
    assert!(text.contains("yaw_degrees = 55.0"), "the CAVE's placement");
    std::fs::write(&config_path, text).unwrap();
    let record = out.join("record");
    let _x_lock = X_SERVER.lock().unwrap_or_else(|e| e.into_inner());
    let x = Xvfb::start(SCREEN);
    let args = launch(
        &config_path,
        &[
            "--osc-listen",
            "127.0.0.1:0",
            "--record",
            record.to_str().unwrap(),
            "--record-every",
            "3",
        ],
    );
    let mut cluster = Cluster::start(&x.display, &args, "info,omnicave::eye_phase=debug", &out);
    let port: u16 = cluster.wait_for(0, "the OSC port", Duration::from_secs(240), |l| {
        l.split("listening on 127.0.0.1:")
            .nth(1)?
            .trim()
            .parse()
            .ok()
    });
    // A head walking a circle at 60 Hz, as a tracker would send it.
    let mut sim = Command::new(env!("CARGO_BIN_EXE_omnicave"))
        .arg("track-sim")
        .args(["--target", &format!("127.0.0.1:{port}"), "--rate", "60"])
        .args([
            "--pattern",
            "circle",
            "--radius",
            "0.4",
            "--period",
            "3",
            "--duration",
            "600",
        ])
        .env("RUST_LOG", "warn")
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .expect("track-sim");
    cluster.wait_frame(0, 6, Duration::from_secs(240));
    // Live settings from the master's keyboard: omni-offaxis (5), the sky cycled (k), eyes
    // further apart (]).
    for (keysym, settle) in [
        (u32::from(b'5'), 4),
        (u32::from(b'k'), 4),
        (u32::from(b']'), 4),
    ] {
        let now = cluster.frame_of(0).unwrap_or(0);
        press_key(&x.display, [0, 260], keysym);
        cluster.wait_frame(0, now + settle, Duration::from_secs(240));
    }
    // Escape on the operator window: the master quits and every node with it.
    press_key(&x.display, [0, 260], 0xff1b);
    let status = cluster.wait_exit(Duration::from_secs(120));
    let _ = sim.kill();
    let _ = sim.wait();
    let log = cluster.log();
    assert!(status.success(), "mpirun {status}:\n{log}");
    for rank in 1..3 {
        assert_told_to_stop(&cluster, rank);
    }

    // The same frames on the same eye in every process.
    let presented = presents(&cluster);
    let mut by_rank: BTreeMap<usize, BTreeSet<u64>> = BTreeMap::new();
    let mut eyes: BTreeMap<u64, BTreeSet<String>> = BTreeMap::new();
    for (rank, frame, eye) in &presented {
        by_rank.entry(*rank).or_default().insert(*frame);
        eyes.entry(*frame).or_default().insert(eye.clone());
    }
    assert_eq!(by_rank.len(), 3, "every rank presents:\n{log}");
    let first = &by_rank[&0];
    for (rank, frames) in &by_rank {
        assert_eq!(
            frames, first,
            "rank {rank} presented other frames than the master"
        );
    }
    assert!(first.len() >= 18, "{} frames presented", first.len());
    for (frame, seen) in &eyes {
        assert_eq!(seen.len(), 1, "frame {frame} shown on both eyes: {seen:?}");
    }

    // Every recorded frame, rendered again by one process from its recorded state.
    let mut config = Config::load(&config_path).expect("config");
    let scene = load_scene(&config.settings, config.scene_path.as_ref().unwrap()).expect("scene");
    place_at_camera(&mut config.settings, &scene).expect("placement");
    let sky = load_config_sky(&config);
    let mut state = AppState::new(config);
    let gpu = common::gpu();
    let mut renderer = Renderer::new(gpu, state.cave(), state.render_settings()).expect("renderer");
    renderer.set_scene(&scene).expect("scene");
    renderer.set_sky(sky.as_ref()).expect("sky");
    let mut frames: Vec<PathBuf> = std::fs::read_dir(&record)
        .expect("the record folder")
        .map(|e| e.unwrap().path())
        .collect();
    frames.sort();
    assert!(frames.len() >= 6, "{} frames recorded", frames.len());
    let (mut heads, mut modes, mut compared) = (BTreeSet::new(), BTreeSet::new(), 0);
    let mut instants = BTreeSet::new();
    for dir in &frames {
        // A frame the master recorded as the cluster stopped may lack a node's walls.
        if !dir.join("frame.bin").exists() || !dir.join("right-right.png").exists() {
            continue;
        }
        let bytes = std::fs::read(dir.join("frame.bin")).unwrap();
        let Message::Frame(fs) = Message::decode(&bytes).unwrap() else {
            panic!("frame.bin holds no frame state");
        };
        let fs: FrameState = fs;
        let settings = std::fs::read_to_string(dir.join("settings.toml")).unwrap();
        apply_settings(&mut state, &settings).expect("the recorded settings apply");
        apply_frame_state(&mut state, &fs);
        if renderer.settings() != state.render_settings() {
            renderer
                .set_settings(state.render_settings(), state.render_cave())
                .expect("settings");
        }
        renderer.render(&state.frame_params()).expect("render");
        let images = renderer.read_images().expect("read back");
        for wall in &images {
            for (eye, img) in [("left", &wall.left), ("right", &wall.right)] {
                let path = dir.join(format!("{}-{eye}.png", wall.wall));
                let shown = image::open(&path)
                    .unwrap_or_else(|e| panic!("{}: {e}", path.display()))
                    .to_rgba8();
                // Exact: the same renderer, inputs and device in both; any difference is a
                // state that did not travel.
                let differing = shown
                    .pixels()
                    .zip(img.pixels())
                    .filter(|(a, b)| a != b)
                    .count();
                assert_eq!(
                    differing,
                    0,
                    "{}: {differing} pixels differ from the single-process render",
                    path.display()
                );
            }
        }
        heads.insert(format!("{:?}", fs.head_position));
        instants.insert(fs.animation_clock.to_bits());
        modes.insert(format!(
            "{} {}",
            state.settings.render.mode.name(),
            state.settings.cave.eye_separation
        ));
        compared += 1;
    }
    assert!(compared >= 6, "only {compared} frames compared");
    assert!(
        heads.len() >= 4,
        "the head did not move between recorded frames: {heads:?}"
    );
    assert!(
        modes.len() >= 3,
        "the settings did not change between recorded frames: {modes:?}"
    );
    assert!(
        instants.len() >= 4,
        "the animation clock did not move between recorded frames: {} instants",
        instants.len()
    );
}

/// A stalled node (SIGSTOP) is reported by the master within the timeout, naming the node
/// and its wall; the master and the other node go on; the stalled node, woken, finds it was
/// dropped and ends by itself. Nothing hangs.
#[test]
fn a_stalled_node_is_reported_and_the_others_go_on() {
    let out = out_dir("stall");
    let config_path = write_config(
        &out,
        "cluster.toml",
        "[cluster]\ntimeout_ms = 3000\non_node_loss = \"continue\"",
    );
    let _x_lock = X_SERVER.lock().unwrap_or_else(|e| e.into_inner());
    let x = Xvfb::start(SCREEN);
    let mut cluster = Cluster::start(&x.display, &launch(&config_path, &[]), "info", &out);
    let pid = cluster.pid_of(2);
    cluster.wait_frame(0, 4, Duration::from_secs(240));
    let stopped_at = Instant::now();
    signal(pid, "-STOP");
    let reported = cluster.wait_for(0, "the lost node", Duration::from_secs(60), |l| {
        l.contains("node 2 (").then_some(())?;
        l.contains("wall right) lost").then(|| l.to_owned())
    });
    let after = stopped_at.elapsed();
    assert!(reported.contains("did not report frame"), "{reported}");
    // The timeout (3 s) plus at most one frame in flight on this slow machine.
    assert!(after < Duration::from_secs(15), "reported after {after:?}");
    // The master and node 1 go on.
    assert_master_and_node_1_go_on(&mut cluster);
    assert!(
        cluster.log().contains("LOST: did not report frame"),
        "the stats line names the lost node:\n{}",
        cluster.log()
    );
    // Woken, the dropped node ends by itself.
    signal(pid, "-CONT");
    cluster.wait_for(2, "the dropped node's end", Duration::from_secs(60), |l| {
        l.contains("dropped by the master").then_some(())
    });
    press_key(&x.display, [0, 260], 0xff1b);
    cluster.wait_exit(Duration::from_secs(60));
    assert_told_to_stop(&cluster, 1);
}

/// A killed node (SIGKILL) under `on_node_loss = "continue"`: the master reports it within the
/// timeout, naming it and its wall, and the master and the other node go on; everything ends
/// when the master quits.
#[test]
fn a_killed_node_is_reported_and_the_others_go_on() {
    let out = out_dir("kill-continue");
    let config_path = write_config(
        &out,
        "cluster.toml",
        "[cluster]\ntimeout_ms = 3000\non_node_loss = \"continue\"",
    );
    let _x_lock = X_SERVER.lock().unwrap_or_else(|e| e.into_inner());
    let x = Xvfb::start(SCREEN);
    let mut cluster = Cluster::start(&x.display, &launch(&config_path, &[]), "info", &out);
    let pid = cluster.pid_of(2);
    cluster.wait_frame(0, 4, Duration::from_secs(240));
    let killed_at = Instant::now();
    signal(pid, "-KILL");
    cluster.wait_for(0, "the lost node", Duration::from_secs(60), |l| {
        (l.contains("node 2 (") && l.contains("wall right) lost")).then_some(())
    });
    let after = killed_at.elapsed();
    // The timeout (3 s) plus at most one frame in flight on this slow machine.
    assert!(after < Duration::from_secs(15), "reported after {after:?}");
    assert_master_and_node_1_go_on(&mut cluster);
    press_key(&x.display, [0, 260], 0xff1b);
    cluster.wait_exit(Duration::from_secs(60));
    assert_told_to_stop(&cluster, 1);
}

/// With `on_node_loss = "stop"`, a killed node stops the whole cluster cleanly: the master
/// names it and exits with an error, the other node is told and ends. Nothing hangs.
#[test]
fn a_killed_node_stops_every_process_when_so_configured() {
    let out = out_dir("kill");
    let config_path = write_config(
        &out,
        "cluster.toml",
        "[cluster]\ntimeout_ms = 3000\non_node_loss = \"stop\"",
    );
    let _x_lock = X_SERVER.lock().unwrap_or_else(|e| e.into_inner());
    let x = Xvfb::start(SCREEN);
    let mut cluster = Cluster::start(&x.display, &launch(&config_path, &[]), "info", &out);
    let pid = cluster.pid_of(1);
    cluster.wait_frame(0, 4, Duration::from_secs(240));
    signal(pid, "-KILL");
    cluster.wait_exit(Duration::from_secs(60));
    let log = cluster.log();
    // (mpirun --enable-recovery does not pass the ranks' exit status on: the log says it.)
    assert!(
        cluster
            .lines_of(0)
            .iter()
            .any(|l| l.contains("ERROR") && l.contains("stopping the cluster")),
        "the master ends with an error:\n{log}"
    );
    assert!(
        log.contains("node 1 (")
            && log.contains("wall left) lost")
            && log.contains("stopping the cluster"),
        "{log}"
    );
    assert_told_to_stop(&cluster, 2);
}

/// A node that loaded another config is refused at start-up, by node; so is a config whose
/// walls name a node the job does not have.
#[test]
fn a_node_with_another_config_or_a_missing_node_is_refused_by_name() {
    let out = out_dir("mismatch");
    let config_path = write_config(&out, "cluster.toml", "");
    let other = out.join("other.toml");
    let text = std::fs::read_to_string(&config_path)
        .unwrap()
        .replace("eye_separation = 0.064", "eye_separation = 0.07");
    assert_ne!(text, std::fs::read_to_string(&config_path).unwrap());
    std::fs::write(&other, text).unwrap();
    let _x_lock = X_SERVER.lock().unwrap_or_else(|e| e.into_inner());
    let x = Xvfb::start(SCREEN);
    // MPMD: ranks 0 and 1 load the config, rank 2 the other one.
    let mut args = launch(&config_path, &[]);
    args[1] = "2".into();
    args.push(":".into());
    let mut second = launch(&other, &[]);
    second[1] = "1".into();
    args.extend(second);
    let mut cluster = Cluster::start(&x.display, &args, "info", &out);
    cluster.wait_exit(Duration::from_secs(240));
    let log = cluster.log();
    assert_stopped_with_error(&cluster, 0..2);
    assert!(
        log.contains("node 2 (") && log.contains("its settings (config) differs from the master's"),
        "{log}"
    );
    // Every rank says why it stopped.
    for rank in 1..3 {
        assert!(
            cluster.lines_of(rank).iter().any(|l| l.contains("refused")),
            "rank {rank}:\n{log}"
        );
    }

    // Two processes for a config whose right wall is on node 2.
    let mut args = launch(&config_path, &[]);
    args[1] = "2".into();
    let mut cluster = Cluster::start(&x.display, &args, "info", &out);
    cluster.wait_exit(Duration::from_secs(240));
    let log = cluster.log();
    assert_stopped_with_error(&cluster, 0..2);
    assert!(
        log.contains("wall right is on node 2, but the cluster has 2 processes"),
        "{log}"
    );
}

/// `bench --cluster` under mpirun: three ranks render their walls in lockstep, then exchange
/// the messages alone; rank 0 writes what the cluster costs per frame.
#[test]
fn the_cluster_bench_reports_what_lockstep_costs_per_frame() {
    let out = out_dir("bench");
    let config_path = write_config(&out, "cluster.toml", "");
    let report = out.join("report");
    let output = Command::new(mpirun())
        .args(["--allow-run-as-root", "--oversubscribe", "-np", "3"])
        // As in `Cluster::start`: containers often forbid the cross-process copy (ptrace).
        .args(["--mca", "btl_vader_single_copy_mechanism", "none"])
        .arg(env!("CARGO_BIN_EXE_omnicave"))
        .args([
            "bench",
            "--cluster",
            "--quick",
            "--size",
            "64x36",
            "--config",
        ])
        .arg(&config_path)
        .arg("--out")
        .arg(&report)
        .env("NO_COLOR", "1")
        .output()
        .expect("mpirun");
    let log = String::from_utf8_lossy(&output.stderr);
    assert!(output.status.success(), "{log}");
    let md = std::fs::read_to_string(report.join("cluster.md")).expect("cluster.md");
    assert!(
        md.contains("3 processes") && md.contains("wall left"),
        "{md}"
    );
    let mut rows = csv::Reader::from_path(report.join("cluster.csv")).expect("cluster.csv");
    let headers = rows.headers().unwrap().clone();
    let column = |name: &str| headers.iter().position(|h| h == name).unwrap();
    let (phase, frame_ms, slowest, cost) = (
        column("phase"),
        column("frame_ms"),
        column("slowest_render_ms"),
        column("cluster_cost_ms"),
    );
    let mut counts = BTreeMap::new();
    for row in rows.records() {
        let row = row.unwrap();
        let value = |i: usize| row[i].parse::<f64>().unwrap();
        *counts.entry(row[phase].to_owned()).or_insert(0) += 1;
        // A frame takes at least its slowest render, and the cost is what is left.
        assert!(
            value(frame_ms) > 0.0 && value(frame_ms) + 1e-3 >= value(slowest),
            "{row:?}"
        );
        assert!(
            (value(frame_ms) - value(slowest) - value(cost)).abs() < 1e-3,
            "{row:?}"
        );
        if &row[phase] == "lockstep" {
            assert!(
                value(slowest) > 0.0,
                "every lockstep frame renders: {row:?}"
            );
        }
    }
    // --quick: 20 timed frames per phase.
    assert_eq!(counts.get("lockstep"), Some(&20));
    assert_eq!(counts.get("protocol"), Some(&20));
}

/// The windows themselves: the three wall windows of a three-rank cluster show, pixel for
/// pixel, what the single-process CAVE mode's windows show for the same (still) state.
#[test]
fn the_cluster_windows_equal_the_single_process_windows() {
    let out = out_dir("windows");
    let config_path = write_config_with_output(&out, "cluster.toml", "", "side-by-side-half");
    let _x_lock = X_SERVER.lock().unwrap_or_else(|e| e.into_inner());
    let mut shots = Vec::new();
    for cluster_mode in [true, false] {
        let x = Xvfb::start(SCREEN);
        let args = if cluster_mode {
            launch(&config_path, &[])
        } else {
            // One process, every wall: the same binary and config without --cluster.
            let mut a = launch(&config_path, &[]);
            a[1] = "1".into();
            a.retain(|s| s != "--cluster");
            a
        };
        let mut run = Cluster::start(&x.display, &args, "info", &out);
        let start = Instant::now();
        while run.frames_of(0) < 8 {
            assert!(start.elapsed() < Duration::from_secs(240), "{}", run.log());
            if let Ok(Some(status)) = run.child.try_wait() {
                panic!("exited {status}:\n{}", run.log());
            }
            std::thread::sleep(Duration::from_millis(100));
        }
        let shot = x.screenshot(&out.join(format!("screen-cluster-{cluster_mode}.png")));
        press_key(&x.display, [0, 260], 0xff1b);
        run.wait_exit(Duration::from_secs(60));
        shots.push(shot);
    }
    for (name, pos, _) in WALLS {
        let crop = |img: &image::RgbImage| {
            image::imageops::crop_imm(img, pos[0] as u32, pos[1] as u32, 320, 240).to_image()
        };
        let (cluster, single) = (crop(&shots[0]), crop(&shots[1]));
        assert!(
            single.pixels().any(|p| p.0 != [0, 0, 0]),
            "the {name} window is black in single-process mode"
        );
        let differing = cluster
            .pixels()
            .zip(single.pixels())
            .filter(|(a, b)| a != b)
            .count();
        // Exact: the same renderer, state and composition in both.
        assert_eq!(differing, 0, "wall {name}: {differing} pixels differ");
    }
}

/// A node that leaves by itself (its only window destroyed from outside) tells the master,
/// which reports it at once, long before its 20 s timeout; the others go on.
#[test]
fn a_node_whose_window_is_destroyed_leaves_and_is_reported_at_once() {
    use x11rb::connection::Connection;
    use x11rb::protocol::xproto::ConnectionExt;
    let out = out_dir("leave");
    let config_path = write_config(&out, "cluster.toml", "[cluster]\ntimeout_ms = 20000");
    let _x_lock = X_SERVER.lock().unwrap_or_else(|e| e.into_inner());
    let x = Xvfb::start_without_shm(SCREEN);
    let mut cluster = Cluster::start(&x.display, &launch(&config_path, &[]), "info", &out);
    cluster.wait_frame(0, 4, Duration::from_secs(240));
    let right = window_at(&x.display, [660, 0]);
    let (conn, _) = x11rb::connect(Some(&x.display)).expect("X connection");
    let destroyed_at = Instant::now();
    conn.destroy_window(right).unwrap();
    conn.flush().unwrap();
    let reported = cluster.wait_for(0, "the node's leaving", Duration::from_secs(60), |l| {
        l.contains("node 2 (").then_some(())?;
        l.contains("lost: left the cluster").then(|| l.to_owned())
    });
    assert!(reported.contains("destroyed from outside"), "{reported}");
    let after = destroyed_at.elapsed();
    assert!(after < Duration::from_secs(10), "reported after {after:?}");
    let m = cluster.frame_of(0).unwrap();
    cluster.wait_frame(0, m + 3, Duration::from_secs(120));
    press_key(&x.display, [0, 260], 0xff1b);
    cluster.wait_exit(Duration::from_secs(60));
}
