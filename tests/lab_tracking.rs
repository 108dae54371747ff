//! The lab's trackers through the application's tracking, as `omnicave run` uses it: DTrack
//! frames written as the DTrack manual shows them, the real VRPN server, and NatNet from a
//! stand-in for Motive (the `natnet` crate's synthetic server), each through the
//! calibration, the eye offset and the head tracker to the head and eyes the renderer is given,
//! with the tracked device's buttons triggering their actions.

#![allow(clippy::unwrap_used, clippy::expect_used)]

mod common;

use std::net::{SocketAddr, UdpSocket};
use std::path::PathBuf;
use std::time::{Duration, Instant};

use common::vrpn_peer::{VrpnServer, dtrack_frame, free_port, server_binary};
use glam::{DMat3, DQuat, DVec3, Vec3};
use omnicave::app::devices::{Tracking, TrackingInfo};
use omnicave::app::state::AppState;
use omnicave::cave::{RenderMode, eye_positions};
use omnicave::config::Config;

/// The desktop config with a `[tracking]` section (`extra` lines added to it), no filter and
/// a speed gate wide enough for poses that jump between hand-worked values.
fn config(extra: &str, calibration: &str) -> Config {
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("config/desktop.toml");
    let text = std::fs::read_to_string(&path).expect("desktop.toml")
        + &format!(
            r#"
[tracking]
enabled = true
timeout_seconds = 2.0
{extra}
[tracking.calibration]
{calibration}

[tracking.filter]
enabled = false

[tracking.plausibility]
max_speed_mps = 1000.0
max_turn_dps = 100000.0
"#
        );
    Config::from_toml(&text, &path).expect("config")
}

struct Rig {
    state: AppState,
    tracking: Tracking,
}

impl Rig {
    fn new(config: Config) -> Rig {
        let mut state = AppState::new(config.clone());
        let mut tracking = Tracking::new(config.tracking.clone());
        tracking.poll(&mut state, Instant::now());
        Rig { state, tracking }
    }

    fn info(&self) -> TrackingInfo {
        let mut info = TrackingInfo::default();
        self.tracking.info(Instant::now(), &mut info);
        info
    }

    /// Frames (polls every 5 ms) while `step` runs each frame, until `done`, at most `limit`.
    fn frames_until(
        &mut self,
        what: &str,
        limit: Duration,
        mut step: impl FnMut(u64),
        done: impl Fn(&Rig) -> bool,
    ) {
        let start = Instant::now();
        let mut n = 0;
        while !done(self) {
            assert!(
                start.elapsed() < limit,
                "{what}: not within {limit:?}; {:?}, head {}",
                self.info(),
                self.state.head_position()
            );
            n += 1;
            step(n);
            std::thread::sleep(Duration::from_millis(5));
            self.tracking.poll(&mut self.state, Instant::now());
        }
    }
}

/// The render mode after `mode` (what "next-render-mode" does).
fn next_mode(mode: RenderMode) -> RenderMode {
    let all = RenderMode::ALL;
    let i = all.iter().position(|m| *m == mode).expect("mode");
    all[(i + 1) % all.len()]
}

/// DTrack's b0…b8 (column by column) of a rotation.
fn matrix(q: DQuat) -> [f64; 9] {
    DMat3::from_quat(q).to_cols_array()
}

/// A head turned `yaw` about +y then pitched `pitch` about its x (y up, as DTrack rooms are
/// set up here), as a quaternion.
fn head_turn(yaw: f64, pitch: f64) -> DQuat {
    DQuat::from_rotation_y(yaw.to_radians()) * DQuat::from_rotation_x(pitch.to_radians())
}

/// The hand-worked eye midpoint: R_y(ψ)·R_x(θ)·o for the offset o = (ox, oy, oz), written out:
/// R_x(θ)·o = (ox, oy cos θ − oz sin θ, oy sin θ + oz cos θ); then R_y(ψ)·(x, y, z) =
/// (x cos ψ + z sin ψ, y, −x sin ψ + z cos ψ).
fn hand_worked_midpoint(body: DVec3, yaw: f64, pitch: f64, o: DVec3) -> DVec3 {
    let (sy, cy) = yaw.to_radians().sin_cos();
    let (sp, cp) = pitch.to_radians().sin_cos();
    let (x, y, z) = (o.x, o.y * cp - o.z * sp, o.y * sp + o.z * cp);
    body + DVec3::new(x * cy + z * sy, y, -x * sy + z * cy)
}

fn dtrack_socket() -> UdpSocket {
    UdpSocket::bind("127.0.0.1:0").expect("sender")
}

fn listening(rig: &Rig) -> SocketAddr {
    rig.info().listening.expect("DTrack receiver started")
}

#[test]
fn a_turned_and_tilted_head_puts_the_eyes_where_the_cave_says() {
    // 10 cm from the marker tree to the eyes: 8 cm down and 6 cm forward (−z) of it.
    let offset = DVec3::new(0.0, -0.08, -0.06);
    let mut rig = Rig::new(config(
        &format!(
            "source = \"dtrack\"\neye_offset = [{}, {}, {}]\n[tracking.dtrack]\nlisten = \
             \"127.0.0.1:0\"\nhead_body = 0\nflystick = -1\n",
            offset.x, offset.y, offset.z
        ),
        "axes = [\"x\", \"y\", \"z\"]",
    ));
    rig.state.settings.render.mode = RenderMode::TrackedStereo;
    let target = listening(&rig);
    let socket = dtrack_socket();
    let body_mm = DVec3::new(150.0, 1650.0, -250.0);
    let ipd = f64::from(rig.state.settings.cave.eye_separation);
    for (yaw, pitch) in [
        (30.0, 20.0),
        (-30.0, 20.0),
        (30.0, -20.0),
        (-30.0, -20.0),
        (0.0, 0.0),
    ] {
        let q = head_turn(yaw, pitch);
        let m = matrix(q)
            .iter()
            .map(|v| format!("{v:.6}"))
            .collect::<Vec<_>>()
            .join(" ");
        let frame = format!(
            "fr 1\r\nts 39596.024831\r\n6dcal 1\r\n6d 1 [0 1.000][{:.3} {:.3} {:.3} 0.0 0.0 \
             0.0][{m}]\r\n",
            body_mm.x, body_mm.y, body_mm.z
        );
        let want_mid = hand_worked_midpoint(body_mm / 1000.0, yaw, pitch, offset);
        let (sy, cy) = f64::to_radians(yaw).sin_cos();
        let right = DVec3::new(cy, 0.0, -sy); // R_y(ψ)·R_x(θ)·x̂: pitch leaves x̂ alone
        let want = [want_mid - 0.5 * ipd * right, want_mid + 0.5 * ipd * right];
        rig.frames_until(
            &format!("head at yaw {yaw}, pitch {pitch}"),
            Duration::from_secs(5),
            |_| {
                socket.send_to(frame.as_bytes(), target).expect("send");
            },
            |r| (r.state.head_position().as_dvec3() - want_mid).length() < 1e-4,
        );
        let head = rig.state.head();
        let eyes = eye_positions(RenderMode::TrackedStereo, &head, ipd as f32, Vec3::NEG_Z);
        for (eye, want) in eyes.iter().zip(want) {
            let error_mm = (eye.as_dvec3() - want).length() * 1e3;
            // 0.1 mm: DTrack's 3-decimal millimetres and 6-decimal matrix carry about 1e-3 mm.
            assert!(
                error_mm < 0.1,
                "yaw {yaw}, pitch {pitch}: eye at {eye}, hand-worked {want} ({error_mm:.4} mm)"
            );
        }
    }
}

#[test]
fn dtrack_frames_drive_the_head_and_the_flystick_buttons() {
    let mut rig = Rig::new(config(
        "source = \"dtrack\"\n[tracking.dtrack]\nlisten = \"127.0.0.1:0\"\nhead_body = 1\n\
         flystick = 0\n",
        // DTrack's room: z up, millimetres (the receiver gives metres).
        "axes = [\"x\", \"z\", \"-y\"]",
    ));
    let target = listening(&rig);
    let socket = dtrack_socket();
    let mode = rig.state.settings.render.mode;
    // Body 0 is someone else; body 1 is the head at (400, 300, 1600) mm, z up.
    let frame = |buttons: u32| {
        format!(
            "fr 5\r\nts 1.5\r\n6dcal 2\r\n6d 2 [0 1.000][9.0 9.0 9.0 0 0 0][1 0 0 0 1 0 0 0 1] \
             [1 1.000][400.000 300.000 1600.000 0 0 0][1 0 0 0 1 0 0 0 1]\r\n6df2 1 1 [0 1.000 \
             6 2][100.0 200.0 1000.0][1 0 0 0 1 0 0 0 1][{buttons} 0.00 0.00]\r\n"
        )
    };
    rig.frames_until(
        "head from body 1",
        Duration::from_secs(5),
        |_| {
            socket.send_to(frame(0).as_bytes(), target).expect("send");
        },
        |r| (r.state.head_position() - Vec3::new(0.4, 1.6, -0.3)).length() < 1e-5,
    );
    // Button 2: its action (next render mode) once per press.
    rig.frames_until(
        "button 2 press",
        Duration::from_secs(5),
        |_| {
            socket
                .send_to(frame(0b100).as_bytes(), target)
                .expect("send");
        },
        |r| r.info().button_actions == 1,
    );
    assert_eq!(
        rig.state.settings.render.mode,
        next_mode(mode),
        "one step per press"
    );
    // The flystick is the wand: at (0.1, 1.0, −0.2) m in CAVE space, pointing along −z.
    let wand = rig.state.wand.expect("the wand is tracked");
    assert!(
        (wand.position - Vec3::new(0.1, 1.0, -0.2)).length() < 1e-5,
        "{wand:?}"
    );
    let ray = rig.state.wand_ray().expect("ray");
    assert!((ray.direction - Vec3::NEG_Z).length() < 1e-5);
    assert!(
        rig.state.frame_params().wand_ray.is_some(),
        "the ray is drawn"
    );
    // Button 1 asks for a selection (the application answers it with the scene).
    rig.frames_until(
        "button 1: select",
        Duration::from_secs(5),
        |_| {
            socket
                .send_to(frame(0b010).as_bytes(), target)
                .expect("send");
        },
        |r| r.state.select_requested,
    );
    // Hold the trigger (button 0, "fly"): the CAVE flies along the ray (−z) at the
    // navigation speed.
    let before = rig.state.world_from_cave().transform_point3(Vec3::ZERO);
    let start = Instant::now();
    rig.frames_until(
        "flying",
        Duration::from_secs(5),
        |_| {
            socket
                .send_to(frame(0b001).as_bytes(), target)
                .expect("send");
        },
        |_| start.elapsed() > Duration::from_millis(500),
    );
    let moved = rig.state.world_from_cave().transform_point3(Vec3::ZERO) - before;
    assert!(
        moved.z < -0.1 && moved.x.abs() < 1e-3 && moved.y.abs() < 1e-3,
        "moved {moved}"
    );
    let counters = rig.info().counters;
    assert!(
        counters.adds_up() && counters.malformed == 0,
        "{counters:?}"
    );
}

#[test]
fn the_real_vrpn_server_drives_the_calibrated_head_and_a_button_action() {
    let Some(binary) = server_binary() else {
        return;
    };
    let server = VrpnServer::start(&binary, free_port());
    let port = server.port;
    // VRPN's DTrack driver serves DTrack's z-up room in metres; the calibration turns the room
    // 90° and moves its origin, so every part of it shows.
    let mut rig = Rig::new(config(
        &format!(
            "source = \"vrpn\"\n[tracking.vrpn]\nhead = \"DTrack@127.0.0.1:{port}\"\n\
             head_sensor = 0\nbuttons = \"DTrack@127.0.0.1:{port}\"\nretry_seconds = 0.2\n"
        ),
        "axes = [\"x\", \"z\", \"-y\"]\nrotation_degrees = [90.0, 0.0, 0.0]\noffset = [0.1, \
         0.0, -0.2]",
    ));
    let mode = rig.state.settings.render.mode;
    // Tracker (400, 300, 1600) mm, turned 30° about its up axis z. Hand-worked: remap (x, z, −y)
    // gives (0.4, 1.6, −0.3); a 90° yaw takes (x, y, z) to (z, y, −x): (−0.3, 1.6, −0.4); plus
    // the offset: (−0.2, 1.6, −0.6). The yaw is 30° + 90° = 120°.
    let q = DQuat::from_rotation_z(30f64.to_radians());
    let frame = |n, buttons| {
        dtrack_frame(
            n,
            [400.0, 300.0, 1600.0],
            matrix(q),
            [0.0, 0.0, 1000.0],
            buttons,
            [0.0, 0.0],
        )
    };
    let want = Vec3::new(-0.2, 1.6, -0.6);
    rig.frames_until(
        "VRPN head",
        Duration::from_secs(20),
        |n| server.send_dtrack(&frame(n, 0)),
        |r| (r.state.head_position() - want).length() < 1e-3,
    );
    let head = rig.state.head();
    let error_mm = (head.position - want).length() * 1e3;
    let forward = head.orientation * Vec3::NEG_Z;
    let yaw = (-forward.x).atan2(-forward.z).to_degrees();
    // 1 mm and 0.1°, as the issue asks (the chain carries about 0.01 mm and 0.001°).
    assert!(
        error_mm < 1.0,
        "head {} vs {want}: {error_mm} mm",
        head.position
    );
    assert!((yaw - 120.0).abs() < 0.1, "yaw {yaw}°");
    rig.frames_until(
        "VRPN button action",
        Duration::from_secs(10),
        |n| server.send_dtrack(&frame(n, 0b100)),
        |r| r.info().button_actions >= 1,
    );
    assert_eq!(rig.state.settings.render.mode, next_mode(mode));
    assert_eq!(
        rig.info().source.as_deref(),
        Some(&*format!("VRPN from 127.0.0.1:{port}"))
    );
}

/// A stand-in for Motive, unicast: it answers the NatNet handshake with its server info and
/// then streams frames of the crate's synthetic server to whoever connected, until dropped.
struct FakeMotive {
    port: u16,
    stop: std::sync::Arc<std::sync::atomic::AtomicBool>,
    thread: Option<std::thread::JoinHandle<()>>,
}

impl FakeMotive {
    /// Streams `bodies(frame_number)` at 120 Hz once a client has connected.
    fn start(bodies: impl Fn(i32) -> Vec<natnet::PlannedBody> + Send + 'static) -> FakeMotive {
        use natnet::serverinfo::{ConnectionInfo, ServerInfo};
        use natnet::{MessageHeader, NAT_CONNECT, SyntheticServer, Version};
        use std::sync::atomic::Ordering;
        let socket = UdpSocket::bind("127.0.0.1:0").expect("command socket");
        socket
            .set_read_timeout(Some(Duration::from_millis(5)))
            .expect("timeout");
        let port = socket.local_addr().expect("addr").port();
        let stop = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
        let thread_stop = stop.clone();
        let thread = std::thread::spawn(move || {
            let info = ServerInfo {
                application_name: "Motive".into(),
                server_version: Version::new(3, 1, 0, 0),
                protocol_version: Version::V4_1,
                high_res_clock_frequency: 10_000_000,
                connection: ConnectionInfo {
                    data_port: 1511,
                    multicast: false,
                    multicast_group: [239, 255, 42, 99],
                },
            };
            let server = SyntheticServer::new(Version::V4_1, 10_000_000);
            let mut client = None;
            let mut frame = 0;
            let mut buf = [0u8; 2048];
            while !thread_stop.load(Ordering::Acquire) {
                if let Ok((n, from)) = socket.recv_from(&mut buf)
                    && MessageHeader::parse(&buf[..n]).is_ok_and(|h| h.message_id == NAT_CONNECT)
                {
                    let reply = info.to_datagram().expect("server info");
                    socket.send_to(&reply, from).expect("reply");
                    client = Some(from);
                }
                if let Some(to) = client {
                    frame += 1;
                    let d = server
                        .datagram(frame, f64::from(frame) / 120.0, &bodies(frame))
                        .expect("frame");
                    let _ = socket.send_to(&d, to);
                    std::thread::sleep(Duration::from_millis(8));
                }
            }
        });
        FakeMotive {
            port,
            stop,
            thread: Some(thread),
        }
    }
}

impl Drop for FakeMotive {
    fn drop(&mut self) {
        self.stop.store(true, std::sync::atomic::Ordering::Release);
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

fn natnet_config(port: u16) -> Config {
    // Motive streams metres, y up: the calibration only turns the room 90° and moves it.
    config(
        &format!(
            "source = \"natnet\"\n[tracking.natnet]\nserver = \"127.0.0.1:{port}\"\ninterface = \
             \"127.0.0.1\"\nhead_rigid_body = 7\nwand_rigid_body = 3\nretry_seconds = 0.2\n"
        ),
        "rotation_degrees = [90.0, 0.0, 0.0]\noffset = [0.1, 0.0, -0.2]",
    )
}

#[test]
fn natnet_from_motive_drives_the_head_and_the_wand() {
    // Rigid body 7 is the head at (0.3, 1.6, 0.4) m turned 30° about y; 3 is the wand; 5 is
    // someone else. From frame 400 on, the head is present but untracked.
    let q = glam::Quat::from_rotation_y(30f32.to_radians());
    let motive = FakeMotive::start(move |frame| {
        let head = if frame < 400 {
            natnet::PlannedBody::tracked(7, [0.3, 1.6, 0.4], q.to_array())
        } else {
            natnet::PlannedBody::dropout(7)
        };
        vec![
            natnet::PlannedBody::tracked(5, [9.0, 9.0, 9.0], [0.0, 0.0, 0.0, 1.0]),
            head,
            natnet::PlannedBody::tracked(3, [0.0, 1.0, 0.0], [0.0, 0.0, 0.0, 1.0]),
        ]
    });
    let mut rig = Rig::new(natnet_config(motive.port));
    // Hand-worked: a 90° yaw takes (x, y, z) to (z, y, −x): (0.4, 1.6, −0.3); plus the offset:
    // (0.5, 1.6, −0.5). The yaw is 30° + 90°.
    let want = Vec3::new(0.5, 1.6, -0.5);
    rig.frames_until(
        "the NatNet head",
        Duration::from_secs(10),
        |_| {},
        |r| (r.state.head_position() - want).length() < 1e-5,
    );
    let forward = rig.state.head().orientation * Vec3::NEG_Z;
    let yaw = (-forward.x).atan2(-forward.z).to_degrees();
    assert!((yaw - 120.0).abs() < 0.01, "yaw {yaw}");
    let wand = rig.state.wand.expect("rigid body 3 is the wand");
    assert!(
        (wand.position - Vec3::new(0.1, 1.0, -0.2)).length() < 1e-5,
        "{wand:?}"
    );
    assert_eq!(
        rig.info().source.as_deref(),
        Some(&*format!("NatNet from 127.0.0.1:{}", motive.port))
    );
    // Motive loses the head: "tracker cannot see the head", the head holds.
    rig.frames_until(
        "the head untracked",
        Duration::from_secs(10),
        |_| {},
        |r| r.info().status == Some(omnicave::tracking::TrackingStatus::NotVisible),
    );
    assert!((rig.state.head_position() - want).length() < 1e-5);
    let c = rig.info().counters;
    assert!(c.adds_up() && c.malformed == 0 && c.accepted > 100, "{c:?}");
}

#[test]
fn natnet_without_motive_retries_and_never_blocks() {
    // A port nothing answers on: the handshake times out, the client retries, frames go on.
    let port = UdpSocket::bind("127.0.0.1:0")
        .expect("probe")
        .local_addr()
        .expect("addr")
        .port();
    let mut rig = Rig::new(natnet_config(port));
    let head = rig.state.head_position();
    let start = Instant::now();
    for _ in 0..100 {
        rig.tracking.poll(&mut rig.state, Instant::now());
        std::thread::sleep(Duration::from_millis(10));
    }
    assert!(
        start.elapsed() < Duration::from_secs(5),
        "a frame waited on the client"
    );
    assert_eq!(rig.state.head_position(), head);
    assert_eq!(
        rig.info().status,
        Some(omnicave::tracking::TrackingStatus::Waiting)
    );
    // Dropping the client stops its thread promptly, handshake or not.
    let t = Instant::now();
    drop(rig);
    assert!(
        t.elapsed() < Duration::from_secs(3),
        "stopping took {:?}",
        t.elapsed()
    );
}
