//! OSC head tracking end to end over real UDP on loopback: packets in every accepted form go
//! through the receiver thread, the calibration, the head tracker and the application state to
//! the head the renderer is given; bad and foreign packets are counted and dropped; the newest
//! pose wins a burst; loss of tracking holds the head and recovers.

#![allow(clippy::unwrap_used, clippy::expect_used)]

mod common;

use std::net::{SocketAddr, UdpSocket};
use std::path::PathBuf;
use std::time::{Duration, Instant};

use glam::{Quat, Vec3};
use rosc::{OscPacket, OscType};

use omnicave::app::devices::{Tracking, TrackingInfo};
use omnicave::app::state::AppState;
use omnicave::config::Config;
use omnicave::tracking::osc::encode;
use omnicave::tracking::{OscMapping, OscReceiver, QuaternionOrder, TrackingStatus};

/// The desktop config with a `[tracking]` section listening on a free loopback port. The
/// calibration is a right-handed z-up tracker in millimetres, turned 90° and offset, so that
/// every part of it shows in the result.
fn config(order: &str, extra: &str) -> Config {
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("config/desktop.toml");
    let text = std::fs::read_to_string(&path).expect("desktop.toml")
        + &format!(
            r#"
[tracking]
enabled = true
listen = "127.0.0.1:0"
quaternion_order = "{order}"
timeout_seconds = 0.3
{extra}
[tracking.calibration]
axes = ["x", "z", "-y"]
scale = 0.001
rotation_degrees = [90.0, 0.0, 0.0]
offset = [0.1, 0.0, -0.2]

[tracking.filter]
enabled = false

# These tests move the head between hand-worked poses within milliseconds, faster than a head
# moves: the speed gate would refuse them (it is tested in tracking_fuzz.rs and below).
[tracking.plausibility]
max_speed_mps = 1000.0
max_turn_dps = 100000.0
"#
        );
    Config::from_toml(&text, &path).expect("config")
}

/// Tracker position (mm, z up) and what the calibration makes of it, worked by hand:
/// remap (x, z, −y)·0.001 = (0.4, 1.6, −0.3); a 90° yaw takes (x, y, z) to (z, y, −x):
/// (−0.3, 1.6, −0.4); plus the offset (0.1, 0, −0.2): (−0.2, 1.6, −0.6).
const TRACKER_MM: [f32; 3] = [400.0, 300.0, 1600.0];
const EXPECTED_CAVE: Vec3 = Vec3::new(-0.2, 1.6, -0.6);
/// A 30° turn about the tracker's up axis (z) is a 30° yaw in the CAVE, plus the
/// calibration's 90°.
const TRACKER_YAW_DEGREES: f32 = 30.0;
const EXPECTED_YAW_DEGREES: f32 = 120.0;

/// The application's tracking, stepped like frames.
struct Rig {
    state: AppState,
    tracking: Tracking,
    mapping: OscMapping,
    target: SocketAddr,
    socket: UdpSocket,
    /// When `deliver` last sent.
    last_delivery: Option<Instant>,
}

/// Least time between two delivered poses. The speed gate (at its widest: 1000 m/s and
/// 100 000°/s, the settings' limits) refuses a jump made faster than a head moves, and these
/// tests jump between hand-worked poses: 30° takes 0.3 ms, a 1.5 m jump 1.5 ms. Packets sent
/// back to back can arrive 50 µs apart, so each delivery waits this long after the last.
const DELIVERY_GAP: Duration = Duration::from_millis(5);

impl Rig {
    fn new(config: Config) -> Rig {
        let mut state = AppState::new(config.clone());
        let mut tracking = Tracking::new(config.tracking.clone());
        tracking.poll(&mut state, Instant::now());
        let mut info = TrackingInfo::default();
        tracking.info(Instant::now(), &mut info);
        let target = info.listening.expect("receiver started");
        let socket = UdpSocket::bind("127.0.0.1:0").expect("sender socket");
        Rig {
            state,
            tracking,
            mapping: config.tracking.receiver.mapping.clone(),
            target,
            socket,
            last_delivery: None,
        }
    }

    /// A rig listening with the test calibration (and `extra` lines in `[tracking]`).
    fn start(order: &str, extra: &str) -> Rig {
        Rig::new(config(order, extra))
    }

    /// Delivers a position message (tracker millimetres).
    fn position(&mut self, mm: [f32; 3]) {
        let packet = encode::message(&self.mapping.position_address, encode::floats(&mm));
        self.deliver(&packet);
    }

    fn send(&self, packet: &OscPacket) {
        self.socket
            .send_to(&encode::bytes(packet), self.target)
            .expect("send");
    }

    fn info(&self) -> TrackingInfo {
        let mut info = TrackingInfo::default();
        self.tracking.info(Instant::now(), &mut info);
        info
    }

    /// Frames (polls) until `done` holds, at most 5 s.
    fn frames_until(&mut self, what: &str, done: impl Fn(&Rig) -> bool) {
        let start = Instant::now();
        while !done(self) {
            assert!(
                start.elapsed() < Duration::from_secs(5),
                "{what}: not within 5 s; {:?}, head {}",
                self.info(),
                self.state.head_position()
            );
            std::thread::sleep(Duration::from_millis(2));
            self.tracking.poll(&mut self.state, Instant::now());
        }
    }

    fn accepted(&self) -> u64 {
        self.info().counters.accepted
    }

    /// Sends and frames until the receiver has accepted one more packet and a frame used it.
    fn deliver(&mut self, packet: &OscPacket) {
        let before = self.info().counters.received;
        if let Some(wait) = self
            .last_delivery
            .and_then(|t| DELIVERY_GAP.checked_sub(t.elapsed()))
        {
            std::thread::sleep(wait);
        }
        self.last_delivery = Some(Instant::now());
        self.send(packet);
        self.frames_until("packet handled", |r| r.info().counters.received > before);
        self.tracking.poll(&mut self.state, Instant::now());
    }

    /// The head the renderer is given this frame.
    fn head(&self) -> omnicave::cave::Head {
        self.state.frame_params().head
    }
}

fn yaw_degrees(q: Quat) -> f32 {
    let f = q * Vec3::NEG_Z;
    (-f.x).atan2(-f.z).to_degrees()
}

fn tracker_quat() -> Quat {
    Quat::from_rotation_z(TRACKER_YAW_DEGREES.to_radians())
}

/// Position within 0.1 mm (f32 millimetres through the calibration), yaw within 0.01°.
fn assert_calibrated(rig: &Rig, with_orientation: bool, what: &str) {
    let head = rig.head();
    assert!(
        (head.position - EXPECTED_CAVE).length() < 1e-4,
        "{what}: head at {} (expected {EXPECTED_CAVE})",
        head.position
    );
    if with_orientation {
        let yaw = yaw_degrees(head.orientation);
        assert!(
            (yaw - EXPECTED_YAW_DEGREES).abs() < 0.01,
            "{what}: yaw {yaw}° (expected {EXPECTED_YAW_DEGREES}°)"
        );
    }
}

#[test]
fn calibrated_pose_from_position_and_both_quaternion_orders() {
    for order in QuaternionOrder::ALL {
        let mut config = config(order.name(), "");
        // tracked-stereo uses the orientation.
        config.settings.render.mode = omnicave::cave::RenderMode::TrackedStereo;
        let mut rig = Rig::new(config.clone());
        let mapping = &config.tracking.receiver.mapping;
        assert_eq!(rig.info().status, Some(TrackingStatus::Waiting));

        // Position alone: doubles this time.
        rig.deliver(&encode::message(
            &mapping.position_address,
            encode::doubles(&TRACKER_MM.map(f64::from)),
        ));
        assert_eq!(rig.info().status, Some(TrackingStatus::Tracking));
        assert_calibrated(&rig, false, "position");

        // Orientation as a separate message in this order.
        rig.deliver(&encode::orientation(mapping, tracker_quat(), order));
        assert_calibrated(&rig, true, order.name());

        // The 7-number pose message.
        let mut values = TRACKER_MM.to_vec();
        values.extend(order.components(Quat::IDENTITY));
        rig.deliver(&encode::message(
            &mapping.position_address,
            encode::floats(&values),
        ));
        assert!((yaw_degrees(rig.head().orientation) - 90.0).abs() < 0.01);

        // The wrong order is not silently equivalent: the same numbers read the other way
        // give another orientation.
        let other = QuaternionOrder::ALL
            .into_iter()
            .find(|o| *o != order)
            .unwrap();
        rig.deliver(&encode::orientation(mapping, tracker_quat(), other));
        let yaw = yaw_degrees(rig.head().orientation);
        assert!((yaw - EXPECTED_YAW_DEGREES).abs() > 1.0, "{order:?}: {yaw}");
        let c = rig.info().counters;
        assert_eq!((c.accepted, c.received), (4, 4), "{c:?}");
    }
}

#[test]
fn bundles_and_nested_bundles() {
    let mut rig = Rig::start("wxyz", "");
    let m = &rig.mapping.clone();
    let inner = encode::bundle(vec![
        encode::message("/frame/start", vec![OscType::Int(7)]),
        encode::orientation(m, tracker_quat(), QuaternionOrder::Wxyz),
    ]);
    rig.deliver(&encode::bundle(vec![
        encode::message(&m.position_address, encode::floats(&TRACKER_MM)),
        inner,
    ]));
    assert_calibrated(&rig, true, "bundle");
    // Later messages in a bundle win.
    rig.deliver(&encode::bundle(vec![
        encode::message(&m.position_address, encode::floats(&[0.0, 0.0, 1500.0])),
        encode::message(&m.position_address, encode::floats(&TRACKER_MM)),
    ]));
    assert_calibrated(&rig, true, "last message in a bundle");
}

#[test]
fn natnet_form_with_other_bodies_and_the_tracked_flag() {
    let config = config("wxyz", "natnet_rigid_body = 3\n");
    let mut rig = Rig::new(config.clone());
    let m = &config.tracking.receiver.mapping;
    let body =
        |id: i32, kind: &str, values: &[f32]| encode::rigid_body("/rigidbody", id, kind, values);
    let q = tracker_quat();
    rig.deliver(&encode::bundle(vec![
        encode::message("/frame/start", vec![OscType::Int(1)]),
        body(3, "tracked", &[1.0]),
        body(3, "position", &TRACKER_MM),
        body(3, "quat", &[q.x, q.y, q.z, q.w]),
        // Another rigid body after ours must not move the head.
        body(4, "position", &[0.0, 0.0, 0.0]),
        encode::message("/frame/end", vec![OscType::Int(1)]),
    ]));
    assert_eq!(m.natnet_rigid_body, 3);
    assert_calibrated(&rig, true, "natnet");
    // Only another body: valid OSC, nothing for us.
    rig.deliver(&body(4, "position", &[1.0, 2.0, 3.0]));
    assert_eq!(rig.info().counters.ignored, 1);
    // The tracker loses sight of the head. One packet is a claim, not yet a loss; said for
    // 40 ms (the gate's confirmation time), the status says so, and the head holds.
    rig.deliver(&body(3, "tracked", &[0.0]));
    assert_eq!(rig.info().status, Some(TrackingStatus::Tracking));
    let start = Instant::now();
    while rig.info().status != Some(TrackingStatus::NotVisible) {
        assert!(start.elapsed() < Duration::from_secs(2), "{:?}", rig.info());
        rig.deliver(&body(3, "tracked", &[0.0]));
    }
    // The first claim was delivered at least one gap before `start`.
    assert!(start.elapsed() + DELIVERY_GAP >= Duration::from_millis(40));
    assert_calibrated(&rig, true, "held while not visible");
    rig.deliver(&encode::bundle(vec![
        body(3, "tracked", &[1.0]),
        body(3, "position", &TRACKER_MM),
    ]));
    assert_eq!(rig.info().status, Some(TrackingStatus::Tracking));
}

#[test]
// Packets the kernel drops from a full socket buffer are counted from /proc/net/udp.
#[cfg_attr(not(target_os = "linux"), ignore = "needs Linux's /proc/net/udp")]
fn the_newest_pose_wins_a_burst_of_ten_thousand_packets() {
    let mut rig = Rig::start("wxyz", "");
    let m = &rig.mapping.clone();
    const BURST: u32 = 10_000;
    // Packet i has tracker x = i/10 mm, which the calibration's 90° turn sends to CAVE
    // z = −0.2 − 0.0001·i m (inside the CAVE for every i).
    for i in 0..BURST {
        let p = [i as f32 * 0.1, 300.0, 1600.0];
        rig.send(&encode::message(&m.position_address, encode::floats(&p)));
    }
    let sent = u64::from(BURST);
    let drops_at = |rig: &Rig| common::udp_kernel_drops(rig.target.port());
    // Wait until every packet is either handled or known dropped by the kernel.
    rig.frames_until("burst handled", |r| {
        r.info().counters.received + drops_at(r).unwrap_or(0) >= sent
    });
    // One frame after the burst: the head is the newest packet's, not a queued old one.
    rig.tracking.poll(&mut rig.state, Instant::now());
    let c = rig.info().counters;
    let drops = drops_at(&rig).unwrap_or(0);
    assert!(c.adds_up(), "{c:?}");
    assert_eq!(c.received + drops, sent, "{c:?}, kernel drops {drops}");
    // The packet index, back from the head's z.
    let index = ((-0.2 - rig.head().position.z) / 0.0001).round() as i64;
    if drops == 0 {
        assert_eq!(index, i64::from(BURST) - 1);
    } else {
        // Dropped packets can be the last ones; the head is still at least as new as the
        // number of packets received says (packets arrive in order on loopback).
        assert!(index + 1 >= c.received as i64, "head from packet {index}");
    }
    // The frame after that sees nothing new: no backlog is replayed.
    let before = rig.head().position;
    rig.tracking.poll(&mut rig.state, Instant::now());
    assert_eq!(rig.head().position, before);
}

#[test]
fn bad_packets_are_counted_and_dropped_and_the_head_stays() {
    let mut rig = Rig::start("wxyz", "");
    let m = &rig.mapping.clone();
    rig.position(TRACKER_MM);
    let bad: Vec<Vec<u8>> = vec![
        b"not osc at all".to_vec(),
        vec![],
        encode::bytes(&encode::message(
            &m.position_address,
            encode::floats(&[1.0, f32::NAN, 2.0]),
        )),
        encode::bytes(&encode::message(
            &m.position_address,
            encode::floats(&[f32::INFINITY, 0.0, 2.0]),
        )),
        encode::bytes(&encode::message(
            &m.position_address,
            encode::floats(&[1.0]),
        )),
        encode::bytes(&encode::message(
            &m.position_address,
            vec![OscType::String("x".into()); 3],
        )),
        // A valid position bundled with a malformed orientation: the whole packet goes.
        encode::bytes(&encode::bundle(vec![
            encode::message(&m.position_address, encode::floats(&[0.0, 0.0, 0.0])),
            encode::message(&m.orientation_address, encode::floats(&[0.0; 4])),
        ])),
    ];
    for b in &bad {
        rig.socket.send_to(b, rig.target).expect("send");
    }
    let n = bad.len() as u64;
    rig.frames_until("bad packets handled", |r| {
        // The good packet before them and every bad one.
        r.info().counters.received > n
    });
    let c = rig.info().counters;
    assert_eq!(c.accepted, 1, "{c:?}");
    assert_eq!(c.non_finite, 2, "{c:?}");
    // An empty datagram is not OSC: malformed like the rest.
    assert_eq!(c.malformed, n - 2, "{c:?}");
    assert!(c.adds_up(), "{c:?}");
    assert_calibrated(&rig, false, "after bad packets");
    // The receiver still works.
    rig.position([0.0, 0.0, 1500.0]);
    assert!((rig.head().position - Vec3::new(0.1, 1.5, -0.2)).length() < 1e-4);
}

#[test]
fn senders_outside_the_allowed_list_are_refused() {
    let config = config("wxyz", "allowed_senders = [\"127.0.0.2\"]\n");
    let mut rig = Rig::new(config.clone());
    let m = &config.tracking.receiver.mapping;
    let start = rig.head().position;
    rig.position(TRACKER_MM);
    let c = rig.info().counters;
    assert_eq!((c.refused, c.accepted), (1, 0), "{c:?}");
    assert_eq!(rig.head().position, start);
    // From the allowed address (127.0.0.2 is loopback on Linux).
    let allowed = UdpSocket::bind("127.0.0.2:0").expect("bind 127.0.0.2");
    allowed
        .send_to(
            &encode::bytes(&encode::message(
                &m.position_address,
                encode::floats(&TRACKER_MM),
            )),
            rig.target,
        )
        .expect("send");
    rig.frames_until("allowed sender accepted", |r| r.accepted() == 1);
    rig.tracking.poll(&mut rig.state, Instant::now());
    assert_calibrated(&rig, false, "allowed sender");
}

#[test]
fn lost_tracking_holds_the_head_and_recovers() {
    let mut rig = Rig::start("wxyz", "");
    rig.position(TRACKER_MM);
    assert_eq!(rig.info().status, Some(TrackingStatus::Tracking));
    // No packets for longer than the 0.3 s timeout.
    let quiet = Instant::now();
    rig.frames_until("lost", |r| r.info().status == Some(TrackingStatus::Lost));
    let waited = quiet.elapsed();
    assert!(
        waited >= Duration::from_millis(250),
        "lost after {waited:?}"
    );
    assert_calibrated(&rig, false, "held while lost");
    assert!(rig.info().lost_for.is_some());
    // Packets resume: tracking resumes with the new pose.
    rig.position([0.0, 0.0, 1500.0]);
    assert_eq!(rig.info().status, Some(TrackingStatus::Tracking));
    assert!((rig.head().position - Vec3::new(0.1, 1.5, -0.2)).length() < 1e-4);
}

#[test]
fn positions_outside_the_cave_are_clamped_inside_or_refused() {
    let mut rig = Rig::start("wxyz", "");
    // Tracker (0, 0, 3200) mm → 3.2 m up: above the 2.9 m walls, within the 0.5 m margin.
    rig.position([0.0, 0.0, 3200.0]);
    let (_, hi) = rig.state.head_bounds();
    let head = rig.head().position;
    assert!((head.y - hi.y).abs() < 1e-6, "{head}");
    assert!(head.y < 2.9);
    assert_eq!(rig.info().stats.clamped, 1);
    // 5 m up is farther outside than the margin: refused, counted, and the head stays.
    rig.position([0.0, 0.0, 5000.0]);
    assert_eq!(rig.head().position, head);
    assert_eq!(rig.info().counters.gate.implausible, 1);
    assert_eq!(
        rig.info().counters.accepted,
        2,
        "the packet itself is valid OSC"
    );
}

#[test]
fn a_busy_port_is_an_error_naming_the_address() {
    let taken = UdpSocket::bind("127.0.0.1:0").expect("bind");
    let address = taken.local_addr().expect("addr");
    let mut config = config("wxyz", "");
    config.tracking.receiver.listen = address;
    let e = OscReceiver::start(&config.tracking.receiver).expect_err("port in use");
    assert!(e.to_string().contains(&address.to_string()), "{e}");
    // In the application this is reported and rendering goes on without tracking.
    let mut state = AppState::new(config.clone());
    let mut tracking = Tracking::new(config.tracking.clone());
    let head = state.head_position();
    tracking.poll(&mut state, Instant::now());
    let mut info = TrackingInfo::default();
    tracking.info(Instant::now(), &mut info);
    assert!(info.error.is_some() && info.listening.is_none(), "{info:?}");
    assert_eq!(state.head_position(), head);
}

#[test]
fn bad_tracking_config_is_named() {
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("config/desktop.toml");
    let base = std::fs::read_to_string(&path).expect("desktop.toml");
    for (extra, field) in [
        ("[tracking]\nlisten = \"localhost\"\n", "tracking.listen"),
        (
            "[tracking]\nallowed_senders = [\"10.0.0.300\"]\n",
            "tracking.allowed_senders[0]",
        ),
        (
            "[tracking]\nquaternion_order = \"zyxw\"\n",
            "tracking.quaternion_order",
        ),
        (
            "[tracking]\nposition_address = \"head\"\n",
            "tracking.position_address",
        ),
        (
            "[tracking]\ntimeout_seconds = 0\n",
            "tracking.timeout_seconds",
        ),
        (
            "[tracking.calibration]\naxes = [\"x\", \"y\", \"y\"]\n",
            "tracking.calibration.axes",
        ),
        (
            "[tracking.calibration]\nscale = -1\n",
            "tracking.calibration.scale",
        ),
        ("[tracking.filter]\nbeta = nan\n", "tracking.filter.beta"),
        // The tracking settings: each bad value named by its field.
        ("[tracking]\nsource = \"artrack\"\n", "tracking.source"),
        (
            "[tracking]\neye_offset = [0.0, 3.0, 0.0]\n",
            "tracking.eye_offset",
        ),
        ("[tracking.buttons]\n99 = \"fly\"\n", "tracking.buttons.99"),
        (
            "[tracking.buttons]\n0 = \"teleport\"\n",
            "tracking.buttons.0",
        ),
        (
            "[tracking]\nsource = \"vrpn\"\n[tracking.vrpn]\nhead = \"Tracker0\"\n",
            "tracking.vrpn.head",
        ),
        (
            "[tracking]\nsource = \"vrpn\"\n[tracking.vrpn]\nretry_seconds = 1e9\n",
            "tracking.vrpn.retry_seconds",
        ),
        (
            "[tracking]\nsource = \"dtrack\"\n[tracking.dtrack]\nlisten = \"5000\"\n",
            "tracking.dtrack.listen",
        ),
        (
            "[tracking]\nsource = \"natnet\"\n[tracking.natnet]\nserver = \"motive\"\n",
            "tracking.natnet.server",
        ),
        (
            "[tracking]\nsource = \"natnet\"\n[tracking.natnet]\nretry_seconds = 0\n",
            "tracking.natnet.retry_seconds",
        ),
    ] {
        let e = Config::from_toml(&format!("{base}{extra}"), &path)
            .expect_err(extra)
            .to_string();
        assert!(
            e.contains("desktop.toml") && e.contains(field),
            "{extra}: {e}"
        );
    }
}
