//! The real application under Xvfb: CAVE mode (three wall windows and the operator window) and
//! the desktop preview, checked from screenshots of the virtual screen; quit by SIGTERM.

#![allow(clippy::unwrap_used, clippy::expect_used)]

mod common;

use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use image::{Rgb, RgbImage, RgbaImage};
use omnicave::config::Config;
use omnicave::output::formats::StereoFormat;
use omnicave::render::present::PresentParams;
use omnicave::scene::load_gltf;
use omnicave::setup;

const SCREEN: [u32; 2] = [1600, 1000];
const WALL: [u32; 2] = [320, 240];
/// Where each wall window goes (no window manager: X places them exactly) and its format.
const WALLS: [(&str, [i32; 2], &str); 3] = [
    ("left", [0, 0], "left-only"),
    ("front", [330, 0], "side-by-side-half"),
    ("right", [660, 0], "anaglyph"),
];
const OPERATOR_POS: [i32; 2] = [0, 300];
const OPERATOR_SIZE: [u32; 2] = [1300, 600];

fn repo() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// The desktop config at small walls, with window placement for the test screen. The left
/// wall names a monitor that does not exist, so its window falls back to its position.
fn write_config(dir: &Path, name: &str) -> PathBuf {
    let desktop = std::fs::read_to_string(repo().join("config/desktop.toml")).expect("config");
    // The test's own [app] section replaces the desktop one.
    let app_start = desktop.find("\n[app]").expect("[app] in desktop.toml");
    let app_end = app_start
        + desktop[app_start..]
            .find("\n[[wall]]")
            .expect("walls after [app]");
    let desktop = format!("{}{}", &desktop[..app_start], &desktop[app_end..]);
    let assets = repo().join("assets");
    let mut text = desktop
        .replace("resolution = [480, 422]", "resolution = [320, 240]")
        .replace("\"../assets/", &format!("\"{}/", assets.display()));
    let mut parts: Vec<String> = text.split("[[wall]]").map(str::to_owned).collect();
    for (part, (name, pos, output)) in parts.iter_mut().skip(1).zip(WALLS) {
        assert!(part.contains(&format!("\"{name}\"")));
        let monitor = if name == "left" {
            "monitor = \"NO-SUCH-MONITOR\"\n"
        } else {
            ""
        };
        *part = format!(
            "{}\nwindow_position = [{}, {}]\noutput = \"{output}\"\n{monitor}\n",
            part.trim_end(),
            pos[0],
            pos[1]
        );
    }
    text = format!(
        "{}[app]\nmode = \"cave\"\npanel = \"window\"\nwindow_position = [{}, {}]\n\
         window_size = [{}, {}]\n\n[[wall]]{}",
        parts[0],
        OPERATOR_POS[0],
        OPERATOR_POS[1],
        OPERATOR_SIZE[0],
        OPERATOR_SIZE[1],
        parts[1..].join("[[wall]]")
    );
    let path = dir.join(name);
    std::fs::write(&path, text).expect("write config");
    path
}

use common::xvfb::Xvfb;

/// The application with its log collected.
struct AppProcess {
    child: Child,
    log: Arc<Mutex<String>>,
}

impl AppProcess {
    fn start(display: &str, args: &[&str]) -> AppProcess {
        Self::start_with_log(display, args, "info")
    }

    /// Starts it with `RUST_LOG` set to `filter`.
    fn start_with_log(display: &str, args: &[&str], filter: &str) -> AppProcess {
        Self::start_in(display, args, filter, &repo())
    }

    /// Starts it in the folder `cwd`, with `RUST_LOG` set to `filter`.
    fn start_in(display: &str, args: &[&str], filter: &str, cwd: &Path) -> AppProcess {
        let runtime = std::env::temp_dir().join("omnicave-xdg");
        std::fs::create_dir_all(&runtime).expect("runtime dir");
        #[cfg(unix)]
        {
            use std::os::unix::fs::PermissionsExt;
            std::fs::set_permissions(&runtime, std::fs::Permissions::from_mode(0o700))
                .expect("chmod");
        }
        let mut child = Command::new(env!("CARGO_BIN_EXE_omnicave"))
            .arg("run")
            .args(args)
            .args(["--stats-every", "0.5"])
            .env("DISPLAY", display)
            .env("XDG_RUNTIME_DIR", &runtime)
            .current_dir(cwd)
            .env("RUST_LOG", filter)
            .env("NO_COLOR", "1")
            .env_remove("WAYLAND_DISPLAY")
            .stdout(Stdio::null())
            .stderr(Stdio::piped())
            .spawn()
            .expect("start omnicave");
        let log = Arc::new(Mutex::new(String::new()));
        let stderr = child.stderr.take().expect("stderr");
        let sink = log.clone();
        std::thread::spawn(move || {
            for line in BufReader::new(stderr).lines().map_while(Result::ok) {
                if let Ok(mut l) = sink.lock() {
                    l.push_str(&line);
                    l.push('\n');
                }
            }
        });
        AppProcess { child, log }
    }

    fn log(&self) -> String {
        self.log.lock().map(|l| l.clone()).unwrap_or_default()
    }

    /// Waits until the stats line reports at least `frames` frames.
    fn wait_frames(&mut self, frames: u64) {
        let start = Instant::now();
        loop {
            let log = self.log();
            let latest = log
                .lines()
                .filter_map(|l| l.split("| frames ").nth(1))
                .filter_map(|rest| rest.split_whitespace().next()?.parse::<u64>().ok())
                .max()
                .unwrap_or(0);
            if latest >= frames {
                return;
            }
            if let Ok(Some(status)) = self.child.try_wait() {
                panic!("omnicave exited early ({status}):\n{log}");
            }
            assert!(
                start.elapsed() < Duration::from_secs(240),
                "no {frames} frames within 240 s:\n{log}"
            );
            std::thread::sleep(Duration::from_millis(100));
        }
    }

    /// Waits until a log line satisfies `find` (at most `limit`); returns what it found.
    fn wait_for_line<T>(
        &mut self,
        what: &str,
        limit: Duration,
        find: impl Fn(&str) -> Option<T>,
    ) -> T {
        let start = Instant::now();
        loop {
            let log = self.log();
            if let Some(found) = log.lines().find_map(&find) {
                return found;
            }
            if let Ok(Some(status)) = self.child.try_wait() {
                panic!("omnicave exited early ({status}) waiting for {what}:\n{log}");
            }
            assert!(
                start.elapsed() < limit,
                "no {what} within {limit:?}:\n{log}"
            );
            std::thread::sleep(Duration::from_millis(50));
        }
    }

    /// Waits for the process to exit by itself (at most `limit`); its status.
    fn wait_exit(&mut self, limit: Duration) -> std::process::ExitStatus {
        let start = Instant::now();
        loop {
            if let Ok(Some(status)) = self.child.try_wait() {
                return status;
            }
            assert!(start.elapsed() < limit, "did not quit:\n{}", self.log());
            std::thread::sleep(Duration::from_millis(20));
        }
    }

    /// SIGTERM, then the exit status must be success within 30 s.
    fn quit(mut self) -> String {
        let status = Command::new("kill")
            .args(["-TERM", &self.child.id().to_string()])
            .status()
            .expect("kill");
        assert!(status.success());
        let start = Instant::now();
        loop {
            if let Ok(Some(status)) = self.child.try_wait() {
                let log = self.log();
                assert!(status.success(), "exit status {status}:\n{log}");
                return log;
            }
            assert!(start.elapsed() < Duration::from_secs(30), "did not quit");
            std::thread::sleep(Duration::from_millis(50));
        }
    }
}

fn crop(img: &RgbImage, x: u32, y: u32, w: u32, h: u32) -> RgbImage {
    image::imageops::crop_imm(img, x, y, w, h).to_image()
}

/// Per-channel absolute differences of two same-size images: (mean, share of pixels with any
/// channel off by more than `tolerance`).
fn difference(a: &RgbImage, b: &RgbaImage, tolerance: u8) -> (f64, f64) {
    assert_eq!(a.dimensions(), b.dimensions());
    let mut sum = 0u64;
    let mut off = 0usize;
    for (p, q) in a.pixels().zip(b.pixels()) {
        let mut worst = 0;
        for c in 0..3 {
            let d = p[c].abs_diff(q[c]);
            sum += u64::from(d);
            worst = worst.max(d);
        }
        off += usize::from(worst > tolerance);
    }
    let n = (a.width() * a.height()) as f64;
    (sum as f64 / (3.0 * n), off as f64 / n)
}

/// Signs of a drawn egui panel: its grey fill over most of the region and light text pixels.
fn assert_panel_drawn(region: &RgbImage, what: &str) {
    let n = f64::from(region.width() * region.height());
    let grey = region
        .pixels()
        .filter(|p| {
            let [r, g, b] = p.0;
            r == g && g == b && (20..=40).contains(&r)
        })
        .count() as f64
        / n;
    let text = region
        .pixels()
        .filter(|p| p.0.iter().all(|&c| c > 140))
        .count() as f64
        / n;
    // egui's dark panel fill is grey 27; text and widgets are light. Thresholds leave room
    // for theme tweaks but fail for an empty or black window.
    assert!(grey > 0.5, "{what}: only {:.0}% panel fill", grey * 100.0);
    assert!(
        text > 0.005,
        "{what}: no text ({:.2}% light pixels)",
        text * 100.0
    );
}

/// The preview window in a screenshot (placed at the configured position and size: Xvfb has
/// no window manager to move it).
fn preview_window(shot: &RgbImage) -> RgbImage {
    crop(
        shot,
        OPERATOR_POS[0] as u32,
        OPERATOR_POS[1] as u32,
        OPERATOR_SIZE[0],
        OPERATOR_SIZE[1],
    )
}

/// The unfolded walls in a preview window: the bounding box (x, y, w, h) of what is neither
/// background nor panel right of the docked panel. Asserts the walls meet without a gap.
fn preview_strip(window: &RgbImage, config: &Config) -> (u32, u32, u32, u32) {
    let (row, column) = beside_panel(window, config);
    let (x0, x1) = (row[0], row[row.len() - 1]);
    // The walls meet without a gap: every column of the strip shows the scene.
    assert_eq!(
        row.len() as u32,
        x1 - x0 + 1,
        "a gap between walls in the preview"
    );
    let (y0, y1) = (column[0], column[column.len() - 1]);
    (x0, y0, x1 - x0 + 1, y1 - y0 + 1)
}

/// What shows the scene (not the background) right of the docked panel: its columns along
/// the window's middle row, and its rows along the middle column of those.
fn beside_panel(window: &RgbImage, config: &Config) -> (Vec<u32>, Vec<u32>) {
    let (width, height) = window.dimensions();
    let bg = config
        .settings
        .render
        .background
        .map(|c| (c * 255.0).round() as u8);
    let is_scene = |p: &Rgb<u8>| p.0.iter().zip(bg).any(|(&a, b)| a.abs_diff(b) > 3);
    // The panel's right edge: its fill reaches the window's bottom row.
    let panel_edge = (0..width)
        .rev()
        .find(|&x| {
            let p = window.get_pixel(x, height - 2).0;
            p[0] == p[1] && p[1] == p[2] && (20..=40).contains(&p[0])
        })
        .expect("panel");
    // A separator line beside the panel is skipped by starting two columns further.
    let mid_y = height / 2;
    let row: Vec<u32> = (panel_edge + 2..width)
        .filter(|&x| is_scene(window.get_pixel(x, mid_y)))
        .collect();
    assert!(!row.is_empty(), "nothing shown beside the panel");
    let mid_x = (row[0] + row[row.len() - 1]) / 2;
    let column: Vec<u32> = (0..height)
        .filter(|&y| is_scene(window.get_pixel(mid_x, y)))
        .collect();
    (row, column)
}

/// Share of `strip` pixels that do not match `reference` scaled (nearest texel) to it. Two
/// nearest samplings of one image on slightly different grids pick neighbouring texels at
/// edges, so a pixel counts as matching if one of the 3×3 reference texels around its place
/// does (within 3 levels per channel).
fn unmatched_share(strip: &RgbImage, reference: &RgbaImage) -> f64 {
    let (w, h) = strip.dimensions();
    let (rw, rh) = reference.dimensions();
    let mut misses = 0usize;
    for (x, y, p) in strip.enumerate_pixels() {
        let cx = ((x as f32 + 0.5) * rw as f32 / w as f32) as i64;
        let cy = ((y as f32 + 0.5) * rh as f32 / h as f32) as i64;
        let hit = (-1..=1).any(|dy| {
            (-1..=1).any(|dx| {
                let (qx, qy) = (cx + dx, cy + dy);
                qx >= 0
                    && qy >= 0
                    && qx < i64::from(rw)
                    && qy < i64::from(rh)
                    && reference
                        .get_pixel(qx as u32, qy as u32)
                        .0
                        .iter()
                        .zip(p.0)
                        .all(|(&a, b)| a.abs_diff(b) <= 3)
            })
        });
        misses += usize::from(!hit);
    }
    misses as f64 / f64::from(w * h)
}

fn out_dir() -> PathBuf {
    let dir = repo().join("target/test-out/app_windows");
    std::fs::create_dir_all(&dir).expect("out dir");
    dir
}

#[test]
fn cave_mode_shows_each_wall_in_its_window_and_the_panel_and_quits_on_request() {
    let out = out_dir();
    let config_path = write_config(&out, "cave-test.toml");
    // The reference: the same config rendered headless, composed in each window's format.
    let config = Config::load(&config_path).expect("config");
    let scene = load_gltf(config.scene_path.as_ref().expect("scene")).expect("scene");
    let sky = setup::load_config_sky(&config);
    let mut renderer =
        setup::render_frame(common::gpu(), &config, &scene, sky.as_ref()).expect("render");

    let _one_at_a_time = common::xvfb::X_SERVER
        .lock()
        .unwrap_or_else(|e| e.into_inner());
    let x = Xvfb::start(SCREEN);
    let mut app = AppProcess::start(
        &x.display,
        &["--config", config_path.to_str().expect("utf8")],
    );
    app.wait_frames(3);
    let shot = x.screenshot(&out.join("cave-screen.png"));
    let log = app.quit();
    assert!(
        log.contains("monitor Name(\"NO-SUCH-MONITOR\") not found"),
        "{log}"
    );
    assert!(log.contains("quitting: signal"), "{log}");
    // --stats-every logs the frame time the panel shows.
    assert!(
        log.lines()
            .any(|l| l.contains("stats:") && l.contains(" fps, frame ") && l.contains("cpu ")),
        "{log}"
    );

    for (index, (name, pos, format)) in WALLS.iter().enumerate() {
        let format = StereoFormat::from_name(format).expect("format");
        let expected = renderer
            .compose(
                index,
                PresentParams {
                    format,
                    frame: 0,
                    swap_eyes: false,
                },
            )
            .expect("compose");
        let got = crop(&shot, pos[0] as u32, pos[1] as u32, WALL[0], WALL[1]);
        got.save(out.join(format!("cave-{name}.png")))
            .expect("save");
        // The window path encodes sRGB in the shader into a plain 8-bit surface, the
        // reference lets the sRGB texture format encode: rounding may differ by one level.
        // Anything else (wrong wall, eye, format or placement) moves most pixels by far more.
        let (mean, share) = difference(&got, &expected, 2);
        assert!(
            mean < 0.5 && share < 0.001,
            "wall {name}: mean {mean}, share {share}"
        );
    }
    // The operator window (placed without a window manager at its configured position).
    let panel = crop(
        &shot,
        OPERATOR_POS[0] as u32,
        OPERATOR_POS[1] as u32,
        OPERATOR_SIZE[0],
        OPERATOR_SIZE[1],
    );
    panel.save(out.join("cave-operator.png")).expect("save");
    // Text sits in the left part of the (wide) window; the fill covers all of it.
    assert_panel_drawn(
        &crop(&panel, 0, 0, 300, OPERATOR_SIZE[1]),
        "operator window",
    );
    // Nothing is drawn outside the windows (the root window stays black).
    let outside = crop(&shot, 1310, 0, 290, 1000);
    assert!(outside.pixels().all(|p| p.0 == [0, 0, 0]));
}

#[test]
fn preview_unfolds_the_walls_beside_the_docked_panel() {
    let out = out_dir();
    let config_path = write_config(&out, "preview-test.toml");
    let config = Config::load(&config_path).expect("config");
    let scene = load_gltf(config.scene_path.as_ref().expect("scene")).expect("scene");
    let sky = setup::load_config_sky(&config);
    let images =
        setup::render_images(common::gpu(), &config, &scene, sky.as_ref()).expect("render");
    // The unfolded anaglyph the headless renderer writes: the preview's default output.
    let anaglyphs: Vec<RgbaImage> = images
        .iter()
        .map(|w| omnicave::output::anaglyph(&w.left, &w.right).expect("anaglyph"))
        .collect();
    let reference = omnicave::output::unfold(&anaglyphs.iter().collect::<Vec<_>>());

    let _one_at_a_time = common::xvfb::X_SERVER
        .lock()
        .unwrap_or_else(|e| e.into_inner());
    let x = Xvfb::start(SCREEN);
    let mut app = AppProcess::start(
        &x.display,
        &["--config", config_path.to_str().expect("utf8"), "--preview"],
    );
    app.wait_frames(3);
    let shot = x.screenshot(&out.join("preview-screen.png"));
    let log = app.quit();
    assert!(log.contains("1 window(s) open in preview mode"), "{log}");

    let window = preview_window(&shot);
    window.save(out.join("preview-window.png")).expect("save");
    // The docked panel on the left.
    assert_panel_drawn(&crop(&window, 0, 0, 200, OPERATOR_SIZE[1]), "preview panel");
    let (x0, y0, w, h) = preview_strip(&window, &config);
    // Three 3.3 m walls 2.9 m high: aspect 9.9/2.9. One pixel of rounding per side.
    let aspect = w as f32 / h as f32;
    let expected_aspect = 9.9 / 2.9;
    assert!((aspect - expected_aspect).abs() < expected_aspect * 2.0 / h as f32 + 0.02);
    let strip = crop(&window, x0, y0, w, h);
    let unmatched = |reference: &RgbaImage| unmatched_share(&strip, reference);
    let share = unmatched(&reference);
    // For scale: the same strip against the left eyes alone (a wrong output format), which
    // differs from the anaglyph only where the eyes see different things.
    let lefts: Vec<&RgbaImage> = images.iter().map(|w| &w.left).collect();
    let wrong = unmatched(&omnicave::output::unfold(&lefts));
    assert!(
        share < 0.01,
        "{:.2}% of the strip does not match",
        share * 100.0
    );
    // The 1 % tolerance tells the right output from a wrong one: the left eyes alone miss a
    // quarter of the strip (measured 25 %); 10 % leaves room for another scene or rasteriser.
    assert!(
        wrong > 0.1,
        "the strip matches the left eyes alone but for {:.2}%: the comparison cannot tell \
         the output formats apart",
        wrong * 100.0
    );
}

/// The headless unfolded anaglyph (the preview's default output) for `config`.
fn unfolded_anaglyph(config: &Config, scene: &omnicave::scene::Scene) -> RgbaImage {
    let sky = setup::load_config_sky(config);
    let images = setup::render_images(common::gpu(), config, scene, sky.as_ref()).expect("render");
    let anaglyphs: Vec<RgbaImage> = images
        .iter()
        .map(|w| omnicave::output::anaglyph(&w.left, &w.right).expect("anaglyph"))
        .collect();
    omnicave::output::unfold(&anaglyphs.iter().collect::<Vec<_>>())
}

/// `omnicave track-sim` with these arguments, sending to `port`.
fn track_sim(port: u16, args: &[&str]) -> Child {
    Command::new(env!("CARGO_BIN_EXE_omnicave"))
        .arg("track-sim")
        .args(["--target", &format!("127.0.0.1:{port}"), "--rate", "60"])
        .args(args)
        .env("RUST_LOG", "warn")
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .expect("start track-sim")
}

/// Head position and latency (in frames) of a `tracking: tracking, …` stats line.
fn tracked_stats(line: &str) -> Option<(glam::Vec3, f64)> {
    let rest = line.split("tracking: tracking, ").nth(1)?;
    let head = rest.split("head (").nth(1)?.split(") m").next()?;
    let v: Vec<f32> = head
        .split(", ")
        .filter_map(|c| c.trim().parse().ok())
        .collect();
    let frames = rest
        .split(" ms (")
        .nth(1)?
        .split(" frame)")
        .next()?
        .parse()
        .ok()?;
    (v.len() == 3).then(|| (glam::Vec3::new(v[0], v[1], v[2]), frames))
}

#[test]
fn track_sim_moves_the_head_and_loss_of_tracking_is_reported_and_recovers() {
    let out = out_dir();
    let config_path = write_config(&out, "tracking-test.toml");
    // Unfiltered, so the rendered head is exactly the sent one; lost after 0.5 s of silence.
    let text = std::fs::read_to_string(&config_path).expect("config")
        + "\n[tracking]\ntimeout_seconds = 0.5\n\n[tracking.filter]\nenabled = false\n";
    std::fs::write(&config_path, text).expect("write config");
    let mut config = Config::load(&config_path).expect("config");
    let scene = load_gltf(config.scene_path.as_ref().expect("scene")).expect("scene");
    let at_start = unfolded_anaglyph(&config, &scene);
    let tracked_head = glam::Vec3::new(0.5, 1.5, -0.4);
    config.settings.head.position = tracked_head.to_array();
    let at_tracked = unfolded_anaglyph(&config, &scene);

    let _one_at_a_time = common::xvfb::X_SERVER
        .lock()
        .unwrap_or_else(|e| e.into_inner());
    let x = Xvfb::start(SCREEN);
    let mut app = AppProcess::start(
        &x.display,
        &[
            "--config",
            config_path.to_str().expect("utf8"),
            "--preview",
            "--osc-listen",
            "127.0.0.1:0",
        ],
    );
    let port: u16 = app.wait_for_line("the OSC port", Duration::from_secs(120), |l| {
        l.split("OSC head tracking: listening on 127.0.0.1:")
            .nth(1)?
            .trim()
            .parse()
            .ok()
    });
    app.wait_frames(3);
    let strip = |x: &Xvfb, name: &str| {
        let window = preview_window(&x.screenshot(&out.join(format!("tracking-{name}.png"))));
        let (x0, y0, w, h) = preview_strip(&window, &config);
        crop(&window, x0, y0, w, h)
    };
    let before = strip(&x, "before");

    // A still head sent as a tracker would (NatNet form): the walls show that head.
    let mut sim = track_sim(
        port,
        &[
            "--pattern",
            "still",
            "--centre",
            "0.5,1.5,-0.4",
            "--form",
            "natnet",
            "--duration",
            "4",
        ],
    );
    app.wait_for_line("the tracked head", Duration::from_secs(60), |l| {
        tracked_stats(l).filter(|(h, _)| (*h - tracked_head).length() < 1e-3)
    });
    // The stats line is logged after its frame was presented: this frame has the head.
    let tracked = strip(&x, "tracked");
    let matches_tracked = unmatched_share(&tracked, &at_tracked);
    let matches_start = unmatched_share(&tracked, &at_start);
    let before_vs_start = unmatched_share(&before, &at_start);
    // The same tolerance as the preview test; the other head must differ by far more.
    assert!(before_vs_start < 0.01 && matches_tracked < 0.01);
    assert!(matches_start > 0.2, "the head did not move the image");

    // The simulator stops: tracking is lost, reported, and the head holds.
    assert!(sim.wait().expect("track-sim").success());
    app.wait_for_line("tracking lost", Duration::from_secs(30), |l| {
        l.contains("tracking lost: no packet for 0.50 s")
            .then_some(())
    });
    app.wait_for_line("the lost status", Duration::from_secs(30), |l| {
        l.contains("tracking: tracking lost, ").then_some(())
    });
    let held = strip(&x, "lost");
    let held_share = unmatched_share(&held, &at_tracked);
    assert!(held_share < 0.01);

    // Packets resume on a circle: tracking recovers and the head follows it (the log is read
    // from here on: a starved simulator could have lost and resumed tracking before).
    let resume_from = app.log().len();
    let mut sim = track_sim(
        port,
        &[
            "--pattern",
            "circle",
            "--centre",
            "0,1.7,0",
            "--radius",
            "0.4",
            "--period",
            "3",
            "--form",
            "bundle",
            "--duration",
            "4",
        ],
    );
    let resumed = |log: &str| log[resume_from..].find("tracking resumed after");
    let start = Instant::now();
    while resumed(&app.log()).is_none() {
        assert!(start.elapsed() < Duration::from_secs(30), "{}", app.log());
        std::thread::sleep(Duration::from_millis(50));
    }
    assert!(sim.wait().expect("track-sim").success());
    let log = app.quit();
    let resumed_at = resume_from + resumed(&log).expect("resumed");
    let on_circle: Vec<(glam::Vec3, f64)> = log[resumed_at..]
        .lines()
        .filter_map(tracked_stats)
        .collect();
    assert!(on_circle.len() >= 3, "{log}");
    for (head, _) in &on_circle {
        let r = glam::Vec2::new(head.x, head.z).length();
        // The simulator's f32 circle, printed to the millimetre.
        assert!(
            (r - 0.4).abs() < 2e-3 && (head.y - 1.7).abs() < 2e-3,
            "{head}"
        );
    }
    let first = on_circle[0].0;
    assert!(on_circle.iter().any(|(h, _)| (*h - first).length() > 0.05));
    // Latency: every pose was used by the first frame that started after it was ready (the
    // frame fraction is measured from when the receiver stored it, so it is at most 1 unless a
    // frame skipped a ready pose; printed with two decimals).
    let worst = log
        .lines()
        .filter_map(tracked_stats)
        .map(|(_, f)| f)
        .fold(0.0, f64::max);
    assert!(worst <= 1.0, "latency {worst} frames");
}

#[test]
fn the_operator_window_shows_the_panorama_beside_the_panel() {
    let out = out_dir();
    let path = write_config(&out, "panorama-test.toml");
    // The panorama on (the test config keeps the desktop one's sections up to [app]), at a
    // size the operator window shows about 2:1 enlarged.
    let text = std::fs::read_to_string(&path).expect("config")
        + "\n[panorama]\nshow = true\nsize = [400, 200]\n";
    std::fs::write(&path, text).expect("write config");
    let config = Config::load(&path).expect("config");
    assert!(config.settings.panorama.show);
    let scene = load_gltf(config.scene_path.as_ref().expect("scene")).expect("scene");
    let sky = setup::load_config_sky(&config);
    let renderer = setup::render_panorama(common::gpu(), &config, &scene, sky.as_ref())
        .expect("headless panorama");
    let [reference, _] = renderer.read_panorama().expect("read back");

    let _one_at_a_time = common::xvfb::X_SERVER
        .lock()
        .unwrap_or_else(|e| e.into_inner());
    let x = Xvfb::start(SCREEN);
    let mut app = AppProcess::start(&x.display, &["--config", path.to_str().expect("utf8")]);
    app.wait_frames(3);
    let shot = x.screenshot(&out.join("panorama-screen.png"));
    let log = app.quit();
    assert!(log.contains("window(s) open in CAVE mode"), "{log}");
    assert!(!log.contains("closing the panorama view"), "{log}");

    let window = preview_window(&shot);
    window
        .save(out.join("panorama-operator.png"))
        .expect("save");
    assert_panel_drawn(
        &crop(&window, 0, 0, 200, OPERATOR_SIZE[1]),
        "operator panel",
    );
    // The panorama: what is not background right of the docked panel.
    let (row, column) = beside_panel(&window, &config);
    let (x0, x1) = (row[0], row[row.len() - 1]);
    let (y0, y1) = (column[0], column[column.len() - 1]);
    let (w, h) = (x1 - x0 + 1, y1 - y0 + 1);
    let aspect = w as f32 / h as f32;
    // 2:1 as configured, within a pixel of rounding on each side.
    assert!(
        (aspect - 2.0).abs() < 2.0 * 2.0 / h as f32 + 0.02,
        "aspect {aspect}"
    );
    let share = unmatched_share(&crop(&window, x0, y0, w, h), &reference);
    // The same image (mono, so its anaglyph is itself), scaled by the present pass.
    assert!(
        share < 0.01,
        "{:.2}% of the panorama does not match",
        share * 100.0
    );
}

/// A top-level window: its id, position and size.
type XWindow = (u32, [i32; 2], [u32; 2]);

/// The application's top-level windows on `display` (no window manager: children of the
/// root) with their positions, from another X client.
fn x_windows(display: &str) -> (x11rb::rust_connection::RustConnection, Vec<XWindow>) {
    use x11rb::connection::Connection;
    use x11rb::protocol::xproto::ConnectionExt;
    let (conn, screen) = x11rb::connect(Some(display)).expect("X connection");
    let root = conn.setup().roots[screen].root;
    let tree = conn.query_tree(root).unwrap().reply().unwrap();
    let mut windows = Vec::new();
    for w in tree.children {
        let attrs = conn.get_window_attributes(w).unwrap().reply().unwrap();
        if attrs.map_state != x11rb::protocol::xproto::MapState::VIEWABLE {
            continue;
        }
        let g = conn.get_geometry(w).unwrap().reply().unwrap();
        windows.push((
            w,
            [i32::from(g.x), i32::from(g.y)],
            [u32::from(g.width), u32::from(g.height)],
        ));
    }
    (conn, windows)
}

/// A wall window stretched past 16 384 pixels has its surface clamped (and the clamp logged)
/// instead of failing in `Surface::configure`; a window destroyed by another client
/// (XDestroyWindow, as `xdotool windowclose` does) goes while the others keep rendering, and
/// the operator window's loss ends the program with status 0. The server runs without MIT-SHM
/// (as CI's does): there the frame's present to the destroyed window comes back as a
/// `BadDrawable`, which must not be taken for winit's own failure (src/app/x11_errors.rs).
#[test]
fn windows_stretched_or_destroyed_from_outside_are_handled() {
    use x11rb::connection::Connection;
    use x11rb::protocol::xproto::{ConfigureWindowAux, ConnectionExt};
    let out = out_dir();
    let config_path = write_config(&out, "destroy-test.toml");
    let _one_at_a_time = common::xvfb::X_SERVER
        .lock()
        .unwrap_or_else(|e| e.into_inner());
    let x = Xvfb::start_without_shm(SCREEN);
    let mut app = AppProcess::start(
        &x.display,
        &["--config", config_path.to_str().expect("utf8")],
    );
    app.wait_frames(3);
    let (conn, windows) = x_windows(&x.display);
    let find = |pos: [i32; 2]| {
        windows
            .iter()
            .find(|(_, p, _)| *p == pos)
            .unwrap_or_else(|| panic!("no window at {pos:?}: {windows:?}"))
            .0
    };
    let front = find(WALLS[1].1);
    let left = find(WALLS[0].1);
    let operator = find(OPERATOR_POS);

    // The front wall's window stretched to 20 000 pixels wide.
    conn.configure_window(front, &ConfigureWindowAux::new().width(20_000).height(300))
        .unwrap();
    conn.flush().unwrap();
    app.wait_for_line("the clamp", Duration::from_secs(60), |l| {
        l.contains("is 20000×300; its surface is limited to 16384×300")
            .then_some(())
    });
    let frames_now = |app: &AppProcess| {
        app.log()
            .lines()
            .filter_map(|l| l.split("| frames ").nth(1))
            .filter_map(|rest| rest.split_whitespace().next()?.parse::<u64>().ok())
            .max()
            .unwrap_or(0)
    };
    let recoveries = |app: &AppProcess| {
        app.log()
            .lines()
            .filter_map(|l| l.split("surface recoveries ").nth(1))
            .filter_map(|rest| rest.split_whitespace().next()?.parse::<u64>().ok())
            .max()
            .unwrap_or(0)
    };
    let before = frames_now(&app);
    app.wait_frames(before + 3);
    // A clamped surface is suboptimal by design: not "recovered" every frame.
    let settled = recoveries(&app);
    let before = frames_now(&app);
    app.wait_frames(before + 4);
    assert!(recoveries(&app) <= settled + 1, "{}", app.log());

    // The left wall's window destroyed from outside; the others go on.
    conn.destroy_window(left).unwrap();
    conn.flush().unwrap();
    app.wait_for_line("the destroyed wall", Duration::from_secs(60), |l| {
        l.contains("window of wall left destroyed from outside")
            .then_some(())
    });
    let before = frames_now(&app);
    app.wait_frames(before + 3);

    // The operator window destroyed: the program ends cleanly.
    conn.destroy_window(operator).unwrap();
    conn.flush().unwrap();
    let status = app.wait_exit(Duration::from_secs(60));
    let log = app.log();
    assert!(status.success(), "exit status {status}:\n{log}");
    assert!(
        log.contains("quitting: window operator destroyed from outside"),
        "{log}"
    );
    // (A window destroyed between reading the events and drawing makes winit's size query
    // panic inside the frame; that panic is caught and logged as the same loss, so the log
    // may hold its message: the exit status and the loss's line are what count.)
}

/// The preview window destroyed from outside ends the program with 0.
#[test]
fn the_preview_window_destroyed_from_outside_ends_the_program_cleanly() {
    use x11rb::connection::Connection;
    use x11rb::protocol::xproto::ConnectionExt;
    let _one_at_a_time = common::xvfb::X_SERVER
        .lock()
        .unwrap_or_else(|e| e.into_inner());
    let x = Xvfb::start_without_shm(SCREEN);
    let desktop = repo().join("config/desktop.toml");
    let mut app = AppProcess::start(&x.display, &["--config", desktop.to_str().expect("utf8")]);
    app.wait_frames(2);
    let (conn, windows) = x_windows(&x.display);
    assert_eq!(windows.len(), 1, "{windows:?}");
    conn.destroy_window(windows[0].0).unwrap();
    conn.flush().unwrap();
    let status = app.wait_exit(Duration::from_secs(60));
    let log = app.log();
    assert!(status.success(), "exit status {status}:\n{log}");
    assert!(log.contains("destroyed from outside"), "{log}");
}

/// SIGTERM in the first moments (while the config and scene load) ends the program with 0,
/// not by the signal: the handler is installed first.
/// (The signal is sent once the process has logged its first line, i.e. once `main` runs: a
/// signal before the program's first instruction cannot be caught by it.)
#[test]
fn sigterm_while_starting_exits_cleanly() {
    let _one_at_a_time = common::xvfb::X_SERVER
        .lock()
        .unwrap_or_else(|e| e.into_inner());
    let x = Xvfb::start(SCREEN);
    let desktop = repo().join("config/desktop.toml");
    for delay_ms in [0, 50, 300] {
        let mut app = AppProcess::start(&x.display, &["--config", desktop.to_str().expect("utf8")]);
        app.wait_for_line("the first log line", Duration::from_secs(60), |l| {
            (!l.is_empty()).then_some(())
        });
        std::thread::sleep(Duration::from_millis(delay_ms));
        let status = Command::new("kill")
            .args(["-TERM", &app.child.id().to_string()])
            .status()
            .expect("kill");
        assert!(status.success());
        let status = app.wait_exit(Duration::from_secs(60));
        assert!(
            status.success(),
            "after {delay_ms} ms: {status}:\n{}",
            app.log()
        );
    }
}

/// The CAVE config with a window per eye for every wall (`[[wall.output]]`): left eyes in the
/// top row, right eyes below; the front wall's right projector moved by (3, −2) pixels and the
/// right wall's left projector cropped to the wall's top-left quarter. No panel.
fn write_eye_outputs_config(dir: &Path, name: &str) -> PathBuf {
    let base = std::fs::read_to_string(write_config(dir, &format!("base-{name}"))).expect("base");
    let mut parts: Vec<String> = base.split("[[wall]]").map(str::to_owned).collect();
    parts[0] = parts[0].replace("panel = \"window\"", "panel = \"hidden\"");
    for (i, part) in parts.iter_mut().skip(1).enumerate() {
        // The wall's own window settings give way to its outputs.
        let kept: Vec<&str> = part
            .lines()
            .filter(|l| {
                !(l.starts_with("window_position")
                    || l.starts_with("output")
                    || l.starts_with("monitor"))
            })
            .collect();
        let x = 330 * i as i32;
        let (left_extra, right_extra) = match i {
            1 => ("", "offset = [3, -2]\n"),
            2 => ("crop = [0, 0, 160, 120]\n", ""),
            _ => ("", ""),
        };
        *part = format!(
            "{}\n\n[[wall.output]]\neye = \"left\"\nwindow_position = [{x}, 0]\n{left_extra}\n\
             [[wall.output]]\neye = \"right\"\nwindow_position = [{x}, 300]\n{right_extra}\n",
            kept.join("\n").trim_end()
        );
    }
    let path = dir.join(name);
    std::fs::write(&path, parts.join("[[wall]]")).expect("write");
    path
}

/// `img` moved by `offset` pixels (right, down); what it uncovers is black.
fn shifted(img: &RgbaImage, offset: [i32; 2]) -> RgbaImage {
    RgbaImage::from_fn(img.width(), img.height(), |x, y| {
        let (sx, sy) = (x as i32 - offset[0], y as i32 - offset[1]);
        if sx < 0 || sy < 0 || sx >= img.width() as i32 || sy >= img.height() as i32 {
            image::Rgba([0, 0, 0, 255])
        } else {
            *img.get_pixel(sx as u32, sy as u32)
        }
    })
}

/// A passive wall fed by two projectors. Three walls with two outputs each open six
/// windows, each showing exactly its eye (as the headless render composes it), with a
/// projector's offset and crop applied; the eyes are still rendered once each per frame.
#[test]
fn two_outputs_per_wall_open_six_windows_each_showing_its_eye() {
    let out = out_dir();
    let config_path = write_eye_outputs_config(&out, "eyes-test.toml");
    let config = Config::load(&config_path).expect("config");
    let scene = load_gltf(config.scene_path.as_ref().expect("scene")).expect("scene");
    let sky = setup::load_config_sky(&config);
    let mut renderer =
        setup::render_frame(common::gpu(), &config, &scene, sky.as_ref()).expect("render");

    let _one_at_a_time = common::xvfb::X_SERVER
        .lock()
        .unwrap_or_else(|e| e.into_inner());
    let x = Xvfb::start(SCREEN);
    let mut app = AppProcess::start(
        &x.display,
        &["--config", config_path.to_str().expect("utf8")],
    );
    app.wait_frames(3);
    let shot = x.screenshot(&out.join("eyes-screen.png"));
    let (_conn, windows) = x_windows(&x.display);
    let log = app.quit();
    assert!(log.contains("6 window(s) open"), "{log}");
    assert_eq!(windows.len(), 6, "{windows:?}");
    // Each eye of each wall is rendered once per frame: six views, as three stereo walls.
    assert!(
        log.lines()
            .any(|l| l.contains("stats:") && l.contains("| views 6 |")),
        "{log}"
    );

    for (index, (name, _, _)) in WALLS.iter().enumerate() {
        for (row, (eye, format)) in [("left", "left-only"), ("right", "right-only")]
            .into_iter()
            .enumerate()
        {
            let format = StereoFormat::from_name(format).expect("format");
            let mut expected = renderer
                .compose(
                    index,
                    PresentParams {
                        format,
                        frame: 0,
                        swap_eyes: false,
                    },
                )
                .expect("compose");
            let (mut w, mut h) = (WALL[0], WALL[1]);
            if index == 1 && eye == "right" {
                expected = shifted(&expected, [3, -2]);
            }
            if index == 2 && eye == "left" {
                expected = image::imageops::crop_imm(&expected, 0, 0, 160, 120).to_image();
                (w, h) = (160, 120);
            }
            let (x0, y0) = (330 * index as u32, 300 * row as u32);
            assert!(
                windows
                    .iter()
                    .any(|(_, p, s)| *p == [x0 as i32, y0 as i32] && *s == [w, h]),
                "no {w}×{h} window at ({x0}, {y0}): {windows:?}"
            );
            let got = crop(&shot, x0, y0, w, h);
            got.save(out.join(format!("eyes-{name}-{eye}.png")))
                .expect("save");
            // As the CAVE-mode test: one level of sRGB rounding between the two paths.
            let (mean, share) = difference(&got, &expected, 2);
            assert!(
                mean < 0.5 && share < 0.001,
                "wall {name} {eye}: mean {mean}, share {share}"
            );
            // And not the other eye: the two differ by far more than the tolerance.
            let other = renderer
                .compose(
                    index,
                    PresentParams {
                        format: if eye == "left" {
                            StereoFormat::RightOnly
                        } else {
                            StereoFormat::LeftOnly
                        },
                        frame: 0,
                        swap_eyes: false,
                    },
                )
                .expect("compose");
            if index == 0 {
                let (_, other_share) = difference(&got, &other, 2);
                assert!(other_share > 0.01, "the two eyes look alike: {other_share}");
            }
        }
    }
}

/// Frame-sequential windows take their eye from one shared frame counter. Every
/// window presents the same eye in every frame; a window stalled from outside (resized, so
/// its surface goes out of date and it misses presents) is counted as a re-sync and presents
/// the others' eye from its next frame on.
#[test]
fn frame_sequential_windows_share_one_eye_phase_even_after_a_stall() {
    use x11rb::connection::Connection;
    use x11rb::protocol::xproto::{ConfigureWindowAux, ConnectionExt};
    let out = out_dir();
    let base = std::fs::read_to_string(write_config(&out, "phase-base.toml")).expect("base");
    let text = base
        .replace("panel = \"window\"", "panel = \"hidden\"")
        .replace("output = \"left-only\"", "output = \"frame-sequential\"")
        .replace(
            "output = \"side-by-side-half\"",
            "output = \"frame-sequential\"",
        )
        .replace("output = \"anaglyph\"", "output = \"frame-sequential\"");
    let config_path = out.join("phase-test.toml");
    std::fs::write(&config_path, text).expect("write");
    let _one_at_a_time = common::xvfb::X_SERVER
        .lock()
        .unwrap_or_else(|e| e.into_inner());
    let x = Xvfb::start(SCREEN);
    let runtime_log = "info,omnicave::eye_phase=debug";
    let mut app = AppProcess::start_with_log(
        &x.display,
        &["--config", config_path.to_str().expect("utf8")],
        runtime_log,
    );
    app.wait_frames(5);
    let (conn, windows) = x_windows(&x.display);
    let front = windows
        .iter()
        .find(|(_, p, _)| *p == WALLS[1].1)
        .expect("front window")
        .0;
    // Stall the front wall's window: stretched past the largest surface, its clamped surface
    // goes out of date frame after frame on Mesa's X11 swapchain and it misses presents while
    // the others go on; then back to its size.
    for (width, hold) in [(20_000, 2000), (WALL[0], 0)] {
        conn.configure_window(front, &ConfigureWindowAux::new().width(width))
            .unwrap();
        conn.flush().unwrap();
        std::thread::sleep(Duration::from_millis(hold));
    }
    let resyncs = |app: &AppProcess| {
        app.log()
            .lines()
            .filter_map(|l| l.split("eye re-syncs ").nth(1))
            .filter_map(|rest| rest.split_whitespace().next()?.parse::<u64>().ok())
            .max()
            .unwrap_or(0)
    };
    let start = Instant::now();
    while resyncs(&app) == 0 {
        assert!(
            start.elapsed() < Duration::from_secs(120),
            "no re-sync:\n{}",
            app.log()
        );
        std::thread::sleep(Duration::from_millis(100));
    }
    let frames = app
        .log()
        .lines()
        .filter_map(|l| l.split("| frames ").nth(1))
        .filter_map(|rest| rest.split_whitespace().next()?.parse::<u64>().ok())
        .max()
        .unwrap_or(0);
    app.wait_frames(frames + 5);
    let log = app.quit();
    // frame → (window, eye) of every present.
    let mut by_frame: std::collections::BTreeMap<u64, Vec<(String, String)>> = Default::default();
    let mut resynced_windows = Vec::new();
    for line in log.lines() {
        let Some(rest) = line.split("present window ").nth(1) else {
            continue;
        };
        let mut words = rest.split_whitespace();
        let window = words.next().expect("window").to_owned();
        assert_eq!(words.next(), Some("frame"));
        let frame: u64 = words.next().expect("n").parse().expect("frame number");
        assert_eq!(words.next(), Some("eye"));
        let eye = words.next().expect("eye").to_owned();
        if rest.contains("(re-sync)") {
            resynced_windows.push((window.clone(), frame));
        }
        by_frame.entry(frame).or_default().push((window, eye));
    }
    assert!(by_frame.len() > 10, "too few frames logged:\n{log}");
    let mut all_three = 0;
    for (frame, presents) in &by_frame {
        let want = if frame % 2 == 0 { "left" } else { "right" };
        for (window, eye) in presents {
            assert_eq!(eye, want, "frame {frame}: {window} shows the {eye} eye");
        }
        all_three += usize::from(presents.len() == 3);
    }
    assert!(all_three > 10, "frames with all three windows: {all_three}");
    // The stalled window was the one re-synced, and it presented again afterwards in phase.
    assert!(
        resynced_windows.iter().any(|(w, _)| w.contains("Wall(1)")),
        "{resynced_windows:?}"
    );
    let (_, at) = resynced_windows[0];
    assert!(
        by_frame
            .range(at + 1..)
            .any(|(_, p)| p.iter().any(|(w, _)| w.contains("Wall(1)"))),
        "the stalled window never presented again"
    );
}

/// The head pose and orientation (x, y, z, w) from a stats line, with the mode and the count
/// of tracked-button actions.
fn tracked_pose(line: &str) -> Option<(glam::Vec3, glam::Quat, u64)> {
    let rest = line.split("tracking: tracking, ").nth(1)?;
    let numbers = |text: &str| -> Vec<f32> {
        text.split(", ")
            .filter_map(|c| c.trim().parse().ok())
            .collect()
    };
    let p = numbers(rest.split("head (").nth(1)?.split(") m").next()?);
    let q = numbers(rest.split("orientation xyzw (").nth(1)?.split(')').next()?);
    let actions = rest
        .split(" button actions")
        .next()?
        .rsplit(", ")
        .next()?
        .parse()
        .ok()?;
    (p.len() == 3 && q.len() == 4).then(|| {
        (
            glam::Vec3::new(p[0], p[1], p[2]),
            glam::Quat::from_xyzw(q[0], q[1], q[2], q[3]),
            actions,
        )
    })
}

/// `omnicave run` in the preview, tracked by the real VRPN server (built from
/// ../shared/peers), whose DTrack driver we feed: the head follows the pose the server reports
/// through the calibration (1 mm, 0.1°), and a flystick button press triggers its action.
#[test]
fn the_preview_follows_a_vrpn_tracked_head_and_a_button_press() {
    use common::vrpn_peer::{VrpnServer, dtrack_frame, free_port, server_binary};
    let Some(binary) = server_binary() else {
        return;
    };
    let server = VrpnServer::start(&binary, free_port());
    let out = out_dir();
    let desktop = std::fs::read_to_string(repo().join("config/desktop.toml")).expect("config");
    let text = desktop.replace(
        "\"../assets/",
        &format!("\"{}/", repo().join("assets").display()),
    ) + &format!(
        r#"
[tracking]
enabled = true
source = "vrpn"
timeout_seconds = 5.0

[tracking.vrpn]
head = "DTrack@127.0.0.1:{port}"
buttons = "DTrack@127.0.0.1:{port}"
wand = "DTrack@127.0.0.1:{port}"
wand_sensor = 1
retry_seconds = 0.2

[tracking.calibration]
axes = ["x", "z", "-y"]
rotation_degrees = [90.0, 0.0, 0.0]
offset = [0.1, 0.0, -0.2]

[tracking.filter]
enabled = false
"#,
        port = server.port
    );
    let config_path = out.join("vrpn-preview.toml");
    std::fs::write(&config_path, text).expect("write");
    // DTrack frames at 60 Hz in the background: the head at (400, 300, 1600) mm in the z-up
    // room, turned 30° about z; the trigger held while `press` is set.
    use std::sync::atomic::{AtomicBool, AtomicU32, Ordering};
    let q = glam::DQuat::from_rotation_z(30f64.to_radians());
    let m = glam::DMat3::from_quat(q).to_cols_array();
    let stop = Arc::new(AtomicBool::new(false));
    let press = Arc::new(AtomicU32::new(0));
    let feeder = {
        let (stop, press) = (stop.clone(), press.clone());
        let dtrack_port = server.dtrack_port;
        std::thread::spawn(move || {
            let socket = std::net::UdpSocket::bind("127.0.0.1:0").expect("udp");
            let mut n = 0u64;
            while !stop.load(Ordering::Acquire) {
                n += 1;
                let buttons = press.load(Ordering::Acquire);
                let frame = dtrack_frame(
                    n,
                    [400.0, 300.0, 1600.0],
                    m,
                    [0.0, 0.0, 1000.0],
                    buttons,
                    [0.0; 2],
                );
                let _ = socket.send_to(frame.as_bytes(), ("127.0.0.1", dtrack_port));
                std::thread::sleep(Duration::from_millis(16));
            }
        })
    };
    let _one_at_a_time = common::xvfb::X_SERVER
        .lock()
        .unwrap_or_else(|e| e.into_inner());
    let x = Xvfb::start(SCREEN);
    let mut app = AppProcess::start(
        &x.display,
        &["--config", config_path.to_str().expect("utf8")],
    );
    // Hand-worked as in tests/lab_tracking.rs: (−0.2, 1.6, −0.6) m, yaw 30° + 90°.
    let want = glam::Vec3::new(-0.2, 1.6, -0.6);
    let (head, orientation, actions) =
        app.wait_for_line("the tracked head", Duration::from_secs(120), tracked_pose);
    assert_eq!(actions, 0, "no button pressed yet");
    let forward = orientation * glam::Vec3::NEG_Z;
    let yaw = (-forward.x).atan2(-forward.z).to_degrees();
    let error_mm = (head - want).length() * 1e3;
    // The stats line prints 0.1 mm and 1e-5 of a quaternion: well inside 1 mm and 0.1°.
    assert!(error_mm < 1.0, "head {head}, want {want}");
    assert!((yaw - 120.0).abs() < 0.1, "yaw {yaw}");
    // Press button 2 (by default the next render mode) for half a second.
    press.store(0b100, Ordering::Release);
    std::thread::sleep(Duration::from_millis(500));
    press.store(0, Ordering::Release);
    app.wait_for_line("the button's action", Duration::from_secs(120), |l| {
        l.contains("tracked button 2: next-render-mode")
            .then_some(())
    });
    app.wait_for_line("the action counted", Duration::from_secs(60), |l| {
        tracked_pose(l).filter(|(_, _, actions)| *actions >= 1)
    });
    // The flystick (sensor 1, 1 m above the floor) is the wand: button 1 selects what its ray
    // hits.
    press.store(0b010, Ordering::Release);
    std::thread::sleep(Duration::from_millis(500));
    press.store(0, Ordering::Release);
    let selected = app.wait_for_line("the selection", Duration::from_secs(60), |l| {
        l.split("selected: ").nth(1).map(str::to_owned)
    });
    // What the CPU pick says for that ray. The flystick's rotation is the identity, so, as a
    // head with that pose would look, it points along the calibration's 90° turn of the
    // CAVE's −z: −x, level, from (0.1, 1.0, −0.2) m; through the config's placement of the
    // CAVE in the scene.
    let config = Config::load(&config_path).expect("config");
    let scene = load_gltf(config.scene_path.as_ref().expect("scene")).expect("scene");
    let world = config.settings.world_from_cave();
    let origin = world.transform_point3(glam::Vec3::new(0.1, 1.0, -0.2));
    let far = world.transform_point3(glam::Vec3::new(0.1 - 4.0, 1.0, -0.2));
    let reach = (far - origin).length();
    let hit = omnicave::scene::pick::pick(&scene, origin, (far - origin) / reach, reach)
        .expect("the floor is under the wand");
    let want = format!(
        "{} (material {}), {:.2} m along the ray",
        hit.material_name,
        hit.material,
        hit.distance * 4.0 / reach
    );
    assert!(selected.starts_with(&want), "{selected} (CPU: {want})");
    stop.store(true, Ordering::Release);
    let _ = feeder.join();
    let log = app.quit();
    assert!(log.contains("VRPN 127.0.0.1:"), "{log}");
}

/// F12 writes every wall's eye images and the settings beside them. The key comes
/// from another X client (XTEST), as a keyboard would send it.
#[test]
fn f12_writes_every_walls_eye_images_and_the_settings() {
    let out = out_dir();
    let config_path = write_config(&out, "shot-base.toml");
    let text = std::fs::read_to_string(&config_path)
        .expect("config")
        .replace("mode = \"cave\"", "mode = \"preview\"");
    let config_path = out.join("shot-test.toml");
    std::fs::write(&config_path, text).expect("write");
    let cwd = out.join("shot-cwd");
    let _ = std::fs::remove_dir_all(&cwd);
    std::fs::create_dir_all(&cwd).expect("cwd");
    let _one_at_a_time = common::xvfb::X_SERVER
        .lock()
        .unwrap_or_else(|e| e.into_inner());
    let x = Xvfb::start(SCREEN);
    let mut app = AppProcess::start_in(
        &x.display,
        &["--config", config_path.to_str().expect("utf8")],
        "info",
        &cwd,
    );
    app.wait_frames(3);
    let (_conn, windows) = x_windows(&x.display);
    let preview = windows.first().expect("the preview window").0;
    // F12 (keysym 0xffc9).
    common::xvfb::press_key(&x.display, preview, 0xffc9);
    let dir = app.wait_for_line("the screenshot", Duration::from_secs(120), |l| {
        l.split("screenshot written to ").nth(1).map(str::to_owned)
    });
    let log = app.quit();
    let dir = cwd.join(dir.trim());
    let config = Config::load(&config_path).expect("config");
    for wall in &config.cave.walls {
        for eye in ["left", "right"] {
            let path = dir.join(format!("{}-{eye}.png", wall.name));
            let img = image::open(&path)
                .unwrap_or_else(|e| panic!("{}: {e}\n{log}", path.display()))
                .to_rgba8();
            assert_eq!(
                [img.width(), img.height()],
                wall.resolution,
                "{}",
                path.display()
            );
            assert!(
                img.pixels().any(|p| p.0[..3] != [0, 0, 0]),
                "{} is black",
                path.display()
            );
        }
    }
    // The settings side file loads back as a config with the same walls.
    let saved = Config::load(&dir.join("settings.toml")).expect("settings.toml loads");
    assert_eq!(saved.cave.walls.len(), config.cave.walls.len());
}
