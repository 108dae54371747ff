//! omnicave's VRPN client against the real VRPN server (built from `../shared/peers`): tracker
//! sensors, pose values, buttons and analogs, a server that restarts and a server that is not
//! there. The server's DTrack driver is fed DTrack frames, so the poses it serves are ours to
//! choose and compare; its test devices (a spinning tracker, toggling buttons) move on their own.

#![allow(clippy::unwrap_used, clippy::expect_used)]

mod common;

use std::time::{Duration, Instant};

use common::vrpn_peer::{VrpnServer, dtrack_frame, free_port, server_binary};
use glam::{DMat3, DQuat, Vec3};
use omnicave::tracking::{TrackerFeed, VrpnClient, VrpnDevice, VrpnSettings};

fn device(name: &str, port: u16) -> VrpnDevice {
    format!("{name}@127.0.0.1:{port}").parse().expect("device")
}

fn settings(port: u16, head: &str, head_sensor: i32) -> VrpnSettings {
    VrpnSettings {
        head: device(head, port),
        head_sensor,
        wand: None,
        buttons: None,
        analogs: None,
        retry: Duration::from_millis(200),
        allowed_senders: Vec::new(),
        idle: Duration::from_millis(500),
    }
}

/// Waits (up to `limit`) until `done` holds for the feed.
fn wait_for(feed: &TrackerFeed, limit: Duration, what: &str, done: impl Fn(&TrackerFeed) -> bool) {
    let start = Instant::now();
    while !done(feed) {
        assert!(
            start.elapsed() < limit,
            "{what}: not within {limit:?}; counters {:?}, head {:?}",
            feed.counters(),
            feed.try_latest()
        );
        std::thread::sleep(Duration::from_millis(10));
    }
}

/// DTrack's rotation matrix b0…b8 (column by column) of a quaternion.
fn matrix(q: DQuat) -> [f64; 9] {
    DMat3::from_quat(q).to_cols_array()
}

#[test]
fn poses_buttons_and_analogs_from_the_real_server() {
    let Some(binary) = server_binary() else {
        return;
    };
    let server = VrpnServer::start(&binary, free_port());
    let port = server.port;
    let mut s = settings(port, "DTrack", 0);
    s.wand = Some((device("DTrack", port), 1));
    s.buttons = Some(device("DTrack", port));
    s.analogs = Some(device("DTrack", port));
    let client = VrpnClient::start(&s).expect("client");
    let feed = client.feed().clone();

    // A head turned 30° left and 20° up, 1.2 m right, 1.6 m up, 0.4 m back (DTrack's mm).
    let q = DQuat::from_rotation_y(30f64.to_radians()) * DQuat::from_rotation_x(20f64.to_radians());
    let body_mm = [1200.0, 1600.0, -400.0];
    let stick_mm = [300.5, 1100.25, -650.0];
    // Buttons 0 and 2 held, the joystick at (0.5, -0.25).
    let frame = |n| dtrack_frame(n, body_mm, matrix(q), stick_mm, 0b101, [0.5, -0.25]);
    let mut n = 0;
    let start = Instant::now();
    // The server reports a body for every frame, but buttons and analogs only when they
    // change: send frames at rest (DTrack's 60 Hz) until the client is connected, then move.
    let rest = |n| dtrack_frame(n, body_mm, matrix(q), stick_mm, 0, [0.0, 0.0]);
    while feed.try_latest().is_none() {
        assert!(
            start.elapsed() < Duration::from_secs(20),
            "no reports; {:?}",
            feed.counters()
        );
        n += 1;
        server.send_dtrack(&rest(n));
        std::thread::sleep(Duration::from_millis(16));
    }
    while feed.try_wand().is_none() || feed.try_controls().is_none_or(|c| c.analogs.len() < 2) {
        assert!(
            start.elapsed() < Duration::from_secs(20),
            "no wand or analogs; {:?}, wand {:?}, controls {:?}",
            feed.counters(),
            feed.try_wand(),
            feed.try_controls()
        );
        n += 1;
        server.send_dtrack(&frame(n));
        std::thread::sleep(Duration::from_millis(16));
    }
    // Let a few more frames through, then compare.
    for _ in 0..10 {
        n += 1;
        server.send_dtrack(&frame(n));
        std::thread::sleep(Duration::from_millis(16));
    }
    let head = feed.try_latest().expect("head");
    let position = head.position.expect("position");
    // VRPN's DTrack driver reads floats (7 digits): within 0.01 mm of what we sent.
    let want = Vec3::new(1.2, 1.6, -0.4);
    assert!(
        (position - want).length() < 1e-5,
        "head at {position}, sent {want}"
    );
    let Some(omnicave::tracking::receiver::TrackedOrientation::Tracker(got)) = head.orientation
    else {
        panic!("no orientation: {head:?}");
    };
    let angle = got.angle_between(q.as_quat()).to_degrees();
    assert!(angle < 0.01, "head orientation off by {angle}°");
    let wand = feed
        .try_wand()
        .expect("wand")
        .position
        .expect("wand position");
    assert!(
        (wand - Vec3::new(0.3005, 1.10025, -0.65)).length() < 1e-5,
        "wand at {wand}"
    );
    let c = feed.try_controls().expect("controls");
    assert!(
        c.is_held(0) && !c.is_held(1) && c.is_held(2),
        "buttons {:#b}",
        c.held
    );
    assert_eq!(&c.analogs[..2], &[0.5, -0.25]);

    // Release button 0: the release reaches us, the press count stays.
    for _ in 0..10 {
        n += 1;
        server.send_dtrack(&dtrack_frame(
            n,
            body_mm,
            matrix(q),
            stick_mm,
            0b100,
            [0.0, 0.0],
        ));
        std::thread::sleep(Duration::from_millis(16));
    }
    wait_for(&feed, Duration::from_secs(5), "button 0 released", |f| {
        f.try_controls().is_some_and(|c| !c.is_held(0))
    });
    let c = feed.try_controls().expect("controls");
    assert_eq!(c.presses[0], 1, "one press of button 0");
    let counters = feed.counters();
    assert!(counters.adds_up(), "{counters:?}");
    assert_eq!(counters.malformed + counters.non_finite, 0, "{counters:?}");
}

#[test]
fn test_devices_sensor_numbers_and_a_server_that_restarts() {
    let Some(binary) = server_binary() else {
        return;
    };
    let mut server = VrpnServer::start(&binary, free_port());
    let port = server.port;
    // Sensor 1 of the spinning tracker; the toggling buttons.
    let mut s = settings(port, "Spin0", 1);
    s.buttons = Some(device("Button0", port));
    let client = VrpnClient::start(&s).expect("client");
    let feed = client.feed().clone();
    wait_for(&feed, Duration::from_secs(10), "spin reports", |f| {
        f.try_latest().is_some_and(|s| s.seq > 20)
    });
    // It spins about +y at the origin: a unit quaternion with no x or z part, turning.
    let orientation = |f: &TrackerFeed| match f.try_latest().and_then(|s| s.orientation) {
        Some(omnicave::tracking::receiver::TrackedOrientation::Tracker(q)) => q,
        other => panic!("no orientation: {other:?}"),
    };
    let a = orientation(&feed);
    assert!(a.x.abs() < 1e-6 && a.z.abs() < 1e-6, "{a}");
    assert!((a.length() - 1.0).abs() < 1e-5);
    assert_eq!(feed.try_latest().and_then(|s| s.position), Some(Vec3::ZERO));
    std::thread::sleep(Duration::from_millis(300));
    let b = orientation(&feed);
    let turned = a.angle_between(b).to_degrees();
    // 0.25 Hz is 90°/s: about 27° in 0.3 s (generous bounds: the machine may be busy).
    assert!(turned > 5.0 && turned < 90.0, "turned {turned}° in 0.3 s");
    wait_for(&feed, Duration::from_secs(5), "button presses", |f| {
        f.try_controls().is_some_and(|c| c.presses[0] >= 2)
    });

    // The server goes away: the client keeps the last pose and keeps trying; it comes back.
    server.kill();
    std::thread::sleep(Duration::from_millis(500));
    let seq = feed.try_latest().expect("held").seq;
    std::thread::sleep(Duration::from_millis(500));
    assert_eq!(
        feed.try_latest().expect("held").seq,
        seq,
        "no reports while down"
    );
    server.restart();
    wait_for(
        &feed,
        Duration::from_secs(15),
        "reports after the restart",
        |f| f.try_latest().is_some_and(|s| s.seq > seq + 20),
    );
}

#[test]
fn an_absent_server_is_retried_and_never_blocks() {
    // No server on this port (the peer is not needed for this one).
    let port = free_port();
    let client = VrpnClient::start(&settings(port, "Tracker0", 0)).expect("client starts anyway");
    let feed = client.feed().clone();
    let start = Instant::now();
    for _ in 0..100 {
        assert!(feed.try_latest().is_none());
        std::thread::sleep(Duration::from_millis(10));
    }
    assert!(
        start.elapsed() < Duration::from_secs(3),
        "reading the feed blocked"
    );
    // Dropping the client stops its threads promptly even while it retries.
    let t = Instant::now();
    drop(client);
    assert!(
        t.elapsed() < Duration::from_secs(3),
        "stopping took {:?}",
        t.elapsed()
    );
    if let Some(binary) = server_binary() {
        // A client started before its server connects once the server appears.
        let client = VrpnClient::start(&settings(port, "Spin0", 0)).expect("client");
        std::thread::sleep(Duration::from_millis(500));
        let _server = VrpnServer::start(&binary, port);
        wait_for(client.feed(), Duration::from_secs(15), "late server", |f| {
            f.try_latest().is_some()
        });
    }
}
