//! The tracking simulator behind `omnicave track-sim`: a head moving on a circle, a figure
//! eight or a recorded path (CSV), sent over OSC in any form the receiver accepts, through the
//! inverse calibration so that the CAVE-space path is what the application shows.

use std::net::{SocketAddr, UdpSocket};
use std::path::Path;

use glam::{Quat, Vec3};
use rosc::OscPacket;

use super::TrackingError;
use super::calibration::Calibration;
use super::head::HeadPose;
use super::osc::{OscMapping, QuaternionOrder, encode};

/// One point of a recorded path.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Keyframe {
    /// Seconds from the start.
    pub t: f64,
    /// CAVE space, metres.
    pub position: Vec3,
    pub orientation: Option<Quat>,
}

/// How the simulated head moves (CAVE space).
#[derive(Debug, Clone, PartialEq)]
pub enum Pattern {
    /// Holds one pose.
    Still { centre: Vec3 },
    /// A horizontal circle of `radius` about `centre`, once per `period` seconds, the head
    /// turning ±30° as it goes.
    Circle {
        centre: Vec3,
        radius: f32,
        period: f32,
    },
    /// A horizontal figure eight (lemniscate of Gerono) of half-width `radius`.
    FigureEight {
        centre: Vec3,
        radius: f32,
        period: f32,
    },
    /// A recorded path, linearly interpolated (orientation: slerp), looping.
    Replay(Vec<Keyframe>),
}

impl Pattern {
    /// The pose at `t` seconds.
    pub fn pose_at(&self, t: f64) -> HeadPose {
        let sway = |phase: f32| Quat::from_rotation_y((30.0f32).to_radians() * phase.sin());
        match self {
            Pattern::Still { centre } => HeadPose {
                position: *centre,
                orientation: Some(Quat::IDENTITY),
            },
            Pattern::Circle {
                centre,
                radius,
                period,
            }
            | Pattern::FigureEight {
                centre,
                radius,
                period,
            } => {
                let a = (std::f64::consts::TAU * t / f64::from(period.max(1e-3))) as f32;
                let offset = match self {
                    Pattern::Circle { .. } => Vec3::new(a.cos(), 0.0, a.sin()),
                    _ => Vec3::new(a.sin(), 0.0, a.sin() * a.cos()),
                };
                HeadPose {
                    position: *centre + *radius * offset,
                    orientation: Some(sway(a)),
                }
            }
            Pattern::Replay(frames) => replay_at(frames, t),
        }
    }

    /// Seconds of one pass (replays), if the pattern ends.
    pub fn length(&self) -> Option<f64> {
        match self {
            Pattern::Replay(frames) => frames.last().map(|k| k.t),
            _ => None,
        }
    }
}

fn replay_at(frames: &[Keyframe], t: f64) -> HeadPose {
    let (Some(first), Some(last)) = (frames.first(), frames.last()) else {
        return HeadPose {
            position: Vec3::ZERO,
            orientation: None,
        };
    };
    let span = last.t - first.t;
    let t = if span > 0.0 {
        first.t + (t - first.t).rem_euclid(span)
    } else {
        first.t
    };
    let i = frames.partition_point(|k| k.t <= t).clamp(1, frames.len()) - 1;
    let a = frames[i];
    let Some(b) = frames.get(i + 1) else {
        return HeadPose {
            position: a.position,
            orientation: a.orientation,
        };
    };
    let s = if b.t > a.t {
        ((t - a.t) / (b.t - a.t)) as f32
    } else {
        0.0
    };
    HeadPose {
        position: a.position.lerp(b.position, s),
        orientation: match (a.orientation, b.orientation) {
            (Some(p), Some(q)) => Some(p.slerp(q, s)),
            (p, q) => p.or(q),
        },
    }
}

/// Reads a recorded path: lines `t,x,y,z` or `t,x,y,z,qw,qx,qy,qz` (seconds, CAVE metres, a
/// w-first quaternion); a header line and `#` comments are skipped; times must increase.
pub fn parse_csv(text: &str, path: &Path) -> Result<Vec<Keyframe>, TrackingError> {
    let fail = |line: usize, message: String| TrackingError::Csv {
        path: path.to_owned(),
        line,
        message,
    };
    let mut frames: Vec<Keyframe> = Vec::new();
    let mut reader = csv::ReaderBuilder::new()
        .has_headers(false)
        .flexible(true)
        .comment(Some(b'#'))
        .trim(csv::Trim::All)
        .from_reader(text.as_bytes());
    for record in reader.records() {
        let record = record.map_err(|e| {
            let line = e.position().map_or(0, |p| p.line() as usize);
            fail(line, e.to_string())
        })?;
        let line = record.position().map_or(0, |p| p.line() as usize);
        // A comment may also end a line.
        let mut fields: Vec<&str> = Vec::with_capacity(record.len());
        for field in &record {
            let value = field.split('#').next().unwrap_or("");
            fields.push(value.trim());
            if field.contains('#') {
                break;
            }
        }
        while fields.last() == Some(&"") {
            fields.pop();
        }
        if fields.is_empty() {
            continue;
        }
        let content = fields.join(",");
        let values: Result<Vec<f64>, _> = fields.iter().map(|f| f.parse::<f64>()).collect();
        let Ok(values) = values else {
            if frames.is_empty() && fields.first().is_some_and(|f| f.parse::<f64>().is_err()) {
                continue; // a header
            }
            return Err(fail(
                line,
                format!("'{content}' has a field that is not a number"),
            ));
        };
        if values.len() != 4 && values.len() != 8 {
            return Err(fail(
                line,
                format!(
                    "{} fields; expected t,x,y,z or t,x,y,z,qw,qx,qy,qz",
                    values.len()
                ),
            ));
        }
        if let Some(v) = values.iter().find(|v| !v.is_finite()) {
            return Err(fail(line, format!("{v} is not a finite number")));
        }
        let t = values[0];
        if let Some(prev) = frames.last()
            && t <= prev.t
        {
            return Err(fail(
                line,
                format!("time {t} s does not come after {} s", prev.t),
            ));
        }
        let orientation = if values.len() == 8 {
            let q = QuaternionOrder::Wxyz.quaternion([values[4], values[5], values[6], values[7]]);
            let length = q.length();
            if length < 1e-6 {
                return Err(fail(line, "the quaternion is zero".into()));
            }
            Some((q / length).as_quat())
        } else {
            None
        };
        frames.push(Keyframe {
            t,
            position: Vec3::new(values[1] as f32, values[2] as f32, values[3] as f32),
            orientation,
        });
    }
    if frames.is_empty() {
        return Err(fail(0, "no samples".into()));
    }
    Ok(frames)
}

/// Which messages the simulator sends for one pose.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SimForm {
    /// `position_address x y z` only.
    Position,
    /// `position_address x y z` + the quaternion (7 numbers, the configured order).
    Pose,
    /// A bundle of `position_address x y z` and `orientation_address` quaternion.
    Bundle,
    /// A bundle of `position_address x y z` and `euler_address yaw pitch roll`.
    Euler,
    /// A bundle of the NatNet-to-OSC `/rigidbody <id> position …` and `… quat …` messages.
    Natnet,
}

crate::named_enum!(SimForm {
    Self::Position => "position",
    Self::Pose => "pose",
    Self::Bundle => "bundle",
    Self::Euler => "euler",
    Self::Natnet => "natnet",
});

/// Builds the packet a tracker would send for a CAVE-space pose.
pub fn packet_for(
    pose: HeadPose,
    form: SimForm,
    mapping: &OscMapping,
    calibration: &Calibration,
) -> OscPacket {
    let p = calibration.tracker_position(pose.position);
    let q_cave = pose.orientation.unwrap_or(Quat::IDENTITY);
    let q = calibration.tracker_orientation(q_cave);
    let order = mapping.quaternion_order;
    match form {
        SimForm::Position => encode::position(mapping, p),
        SimForm::Pose => {
            let mut values = p.to_array().to_vec();
            values.extend(order.components(q));
            encode::message(&mapping.position_address, encode::floats(&values))
        }
        SimForm::Bundle => encode::bundle(vec![
            encode::position(mapping, p),
            encode::orientation(mapping, q, order),
        ]),
        SimForm::Euler => {
            // Yaw/pitch/roll are in CAVE axes: only the calibration's rotation is undone.
            let local = calibration.rotation.inverse() * q_cave;
            let (yaw, pitch, roll) = local.to_euler(glam::EulerRot::YXZ);
            encode::bundle(vec![
                encode::position(mapping, p),
                encode::message(
                    &mapping.euler_address,
                    encode::floats(&[yaw.to_degrees(), pitch.to_degrees(), roll.to_degrees()]),
                ),
            ])
        }
        SimForm::Natnet => encode::bundle(encode::natnet(mapping, p, Some(q))),
    }
}

/// A UDP socket that sends packets to the application.
#[derive(Debug)]
pub struct SimSender {
    socket: UdpSocket,
    target: SocketAddr,
}

impl SimSender {
    pub fn new(target: SocketAddr) -> Result<Self, TrackingError> {
        let local: SocketAddr = if target.is_ipv4() {
            SocketAddr::from(([0, 0, 0, 0], 0))
        } else {
            SocketAddr::from(([0u16; 8], 0))
        };
        let socket = UdpSocket::bind(local).map_err(|source| TrackingError::Bind {
            address: local,
            source,
        })?;
        Ok(Self { socket, target })
    }

    /// Sends one packet; a refused or unreachable target is reported, not fatal.
    pub fn send(&self, packet: &OscPacket) -> Result<(), TrackingError> {
        let bytes = encode::bytes(packet);
        self.send_bytes(&bytes)
    }

    pub fn send_bytes(&self, bytes: &[u8]) -> Result<(), TrackingError> {
        self.socket
            .send_to(bytes, self.target)
            .map(|_| ())
            .map_err(|source| TrackingError::Send {
                target: self.target,
                source,
            })
    }
}

/// What `omnicave track-sim` runs.
#[derive(Debug, Clone)]
pub struct SimOptions {
    pub target: SocketAddr,
    pub pattern: Pattern,
    /// Packets per second.
    pub rate_hz: f64,
    /// Stop after this many seconds (`None`: until stopped).
    pub duration: Option<f64>,
    pub form: SimForm,
    pub mapping: OscMapping,
    pub calibration: Calibration,
    /// Hostile datagrams sent after every pose packet (the soak's stress; 0: none).
    pub junk_per_packet: u32,
}

/// A hostile datagram for the soak, from a xorshift state: random bytes, a pose packet cut
/// short, a position with huge, subnormal or non-finite coordinates, or one with the wrong
/// number of arguments. The receiver must drop or refuse every one and keep the head.
pub fn junk_datagram(state: &mut u64, mapping: &OscMapping) -> Vec<u8> {
    let mut next = || {
        // xorshift64: deterministic, no dependency, plenty for noise.
        *state ^= *state << 13;
        *state ^= *state >> 7;
        *state ^= *state << 17;
        *state
    };
    let choice = next() % 5;
    let address = &mapping.position_address;
    match choice {
        0 => {
            let len = (next() % 512) as usize;
            (0..len).map(|_| next() as u8).collect()
        }
        1 => {
            let mut bytes =
                encode::bytes(&encode::message(address, encode::floats(&[0.1, 1.7, -0.2])));
            let keep = (next() as usize) % bytes.len().max(1);
            bytes.truncate(keep);
            bytes
        }
        2 => {
            let odd = [
                3e38,
                -f32::MAX,
                1.02e38,
                f32::MIN_POSITIVE / 4.0,
                40.0,
                -1e6,
            ];
            let v = odd[(next() % odd.len() as u64) as usize];
            let axis = (next() % 3) as usize;
            let mut p = [0.1f32, 1.7, -0.2];
            p[axis] = v;
            encode::bytes(&encode::message(address, encode::floats(&p)))
        }
        3 => {
            let odd = [f32::NAN, f32::INFINITY, f32::NEG_INFINITY];
            let v = odd[(next() % odd.len() as u64) as usize];
            encode::bytes(&encode::message(address, encode::floats(&[v, 1.7, 0.0])))
        }
        _ => encode::bytes(&encode::message(address, encode::floats(&[1.0]))),
    }
}

/// Sends the pattern at the rate until the duration ends or `stop` is set; returns the number
/// of packets sent. Send errors (nobody listening yet) are logged at a limited rate, not fatal.
pub fn run(
    options: &SimOptions,
    stop: &std::sync::atomic::AtomicBool,
) -> Result<u64, TrackingError> {
    use std::sync::atomic::Ordering;
    use std::time::{Duration, Instant};

    let sender = SimSender::new(options.target)?;
    let rate = if options.rate_hz.is_finite() {
        options.rate_hz.clamp(0.1, 10_000.0)
    } else {
        60.0
    };
    let period = Duration::from_secs_f64(1.0 / rate);
    let start = Instant::now();
    let mut sent = 0u64;
    let mut failed = super::receiver::LogLimiter::default();
    let mut progress = super::receiver::LogLimiter::default();
    let mut junk_state = 0x9E37_79B9_7F4A_7C15u64;
    let mut junk_sent = 0u64;
    tracing::info!(
        "track-sim: sending {} packets to {} at {} Hz",
        options.form.name(),
        options.target,
        options.rate_hz
    );
    for tick in 0u64.. {
        if stop.load(Ordering::SeqCst) {
            break;
        }
        let t = tick as f64 * period.as_secs_f64();
        if options.duration.is_some_and(|d| t > d) {
            break;
        }
        let due = start + period.mul_f64(tick as f64);
        if let Some(wait) = due.checked_duration_since(Instant::now()) {
            std::thread::sleep(wait);
        }
        let pose = options.pattern.pose_at(t);
        let packet = packet_for(pose, options.form, &options.mapping, &options.calibration);
        match sender.send(&packet) {
            Ok(()) => sent += 1,
            Err(e) => {
                if let Some(held) = failed.allow(Instant::now(), Duration::from_secs(2)) {
                    tracing::warn!("{e} ({held} more failures not logged)");
                }
            }
        }
        for _ in 0..options.junk_per_packet {
            let junk = junk_datagram(&mut junk_state, &options.mapping);
            if sender.send_bytes(&junk).is_ok() {
                junk_sent += 1;
            }
        }
        if progress
            .allow(Instant::now(), Duration::from_secs(5))
            .is_some()
        {
            let p = pose.position;
            tracing::info!(
                "track-sim: {sent} packets sent ({junk_sent} hostile); head at ({:.3}, {:.3}, \
                 {:.3}) m",
                p.x,
                p.y,
                p.z
            );
        }
    }
    tracing::info!("track-sim: done, {sent} packets sent ({junk_sent} hostile)");
    Ok(sent)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::tracking::osc::{PacketOutcome, decode_packet};

    #[test]
    fn csv_with_header_and_comments() {
        let text = "t,x,y,z,qw,qx,qy,qz\n# recorded\n0,0,1.7,0,1,0,0,0\n1,1,1.7,0,1,0,0,0\n";
        let frames = parse_csv(text, Path::new("p.csv")).expect("csv");
        assert_eq!(frames.len(), 2);
        let mid = Pattern::Replay(frames).pose_at(0.25);
        assert!((mid.position - Vec3::new(0.25, 1.7, 0.0)).length() < 1e-6);
    }

    #[test]
    fn csv_errors_name_file_and_line() {
        let e = parse_csv("0,0,1.7,0\n0,1,1.7\n", Path::new("p.csv")).expect_err("bad");
        let text = e.to_string();
        assert!(text.contains("p.csv") && text.contains("line 2"), "{text}");
        let e = parse_csv("1,0,1.7,0\n0.5,1,1.7,0\n", Path::new("p.csv")).expect_err("bad");
        assert!(e.to_string().contains("does not come after"), "{e}");
        let e = parse_csv("0,nan,1.7,0\n", Path::new("p.csv")).expect_err("bad");
        assert!(e.to_string().contains("not a finite"), "{e}");
    }

    #[test]
    fn euler_form_keeps_pitch_and_roll() {
        // The decoder reads yaw, pitch, roll as Ry·Rx·Rz (Head::orientation_from_degrees); the
        // simulator must write them in that order for any orientation, not only a yaw.
        let q =
            Quat::from_rotation_y(0.7) * Quat::from_rotation_x(-0.3) * Quat::from_rotation_z(0.2);
        let pose = HeadPose {
            position: Vec3::new(0.1, 1.6, -0.2),
            orientation: Some(q),
        };
        let calibration = Calibration {
            rotation: Quat::from_rotation_y(0.4),
            ..Calibration::default()
        };
        let mapping = OscMapping::default();
        let bytes = encode::bytes(&packet_for(pose, SimForm::Euler, &mapping, &calibration));
        let PacketOutcome::Pose(u) = decode_packet(&bytes, &mapping) else {
            panic!("euler packet");
        };
        let got = calibration.orientation_in_cave_axes(u.orientation_cave_axes.expect("ypr"));
        assert!(got.angle_between(q) < 1e-4, "{got} vs {q}");
    }

    #[test]
    fn every_form_decodes_back_to_the_pose() {
        let calibration = Calibration {
            remap: Calibration::remap_from_axes(&["x", "z", "-y"].map(str::to_owned))
                .expect("axes"),
            scale: 0.001,
            rotation: Quat::from_rotation_y(0.2),
            offset: Vec3::new(0.0, 0.1, 0.0),
        };
        let pose = Pattern::Circle {
            centre: Vec3::new(0.0, 1.7, 0.0),
            radius: 0.5,
            period: 4.0,
        }
        .pose_at(0.7);
        for form in SimForm::ALL {
            for order in QuaternionOrder::ALL {
                let mapping = OscMapping {
                    quaternion_order: order,
                    ..OscMapping::default()
                };
                let bytes = encode::bytes(&packet_for(pose, form, &mapping, &calibration));
                let PacketOutcome::Pose(u) = decode_packet(&bytes, &mapping) else {
                    panic!("{form:?}");
                };
                let p = calibration.position(u.position.expect("position"));
                // Millimetre tracker units in f32: within 0.1 mm.
                assert!((p - pose.position).length() < 1e-4, "{form:?}: {p}");
                let q = match (u.orientation, u.orientation_cave_axes) {
                    (Some(q), _) => Some(calibration.orientation(q)),
                    (None, Some(q)) => Some(calibration.orientation_in_cave_axes(q)),
                    _ => None,
                };
                if form != SimForm::Position {
                    let q = q.expect("orientation");
                    let expected = pose.orientation.expect("orientation");
                    assert!(q.angle_between(expected) < 1e-3, "{form:?} {order:?}");
                }
            }
        }
    }
}
