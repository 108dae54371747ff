//! ART DTrack's native output: ASCII frames over UDP as the DTrack2/DTRACK3 manuals specify
//! (`fr`, `ts`, `6d` standard bodies with position in mm and a rotation matrix, `6df2`
//! flysticks with buttons and joystick; every other line is ignored), and the receiver thread
//! that turns them into head, wand and button updates on the same [`TrackerFeed`] as OSC.

use std::net::{IpAddr, SocketAddr};
use std::time::Instant;

use glam::{DMat3, DQuat, Quat, Vec3};

use super::TrackingError;
use super::osc::MAX_ABS_NUMBER;
use super::receiver::{
    Fate, LOG_INTERVAL, LogLimiter, SentAt, TrackedOrientation, TrackerFeed, TrackerSample,
    UdpThread, held_back,
};

/// The UDP port DTrack sends to unless configured otherwise (the manuals' examples use 5000).
pub const DEFAULT_DTRACK_PORT: u16 = 5000;
/// Budget: bodies or flysticks in one line (DTrack licenses stop far below).
pub const MAX_TARGETS: usize = 1024;
/// Budget: buttons and controllers of one flystick (a Flystick3 has 4 buttons and 2 axes).
pub const MAX_FLYSTICK_BUTTONS: usize = 256;
pub const MAX_FLYSTICK_CONTROLLERS: usize = 32;

/// A 6DOF body (`6d`) or flystick (`6df2`) as DTrack sends it, in DTrack's room frame.
#[derive(Debug, Clone, PartialEq)]
pub struct Target {
    /// The id in the frames: 0-based (DTrack's GUI counts from 1).
    pub id: u32,
    /// Quality; a flystick DTrack cannot see has −1 (and zero position and matrix).
    pub quality: f64,
    pub position_mm: [f64; 3],
    /// The rotation matrix's b0…b8: column by column (R = [b0 b3 b6; b1 b4 b7; b2 b5 b8]).
    pub rotation: [f64; 9],
}

impl Target {
    /// The orientation as a quaternion (`None` for a zero or non-rotation matrix).
    pub fn orientation(&self) -> Option<Quat> {
        let m = DMat3::from_cols_array(&self.rotation);
        let det = m.determinant();
        if !(0.9..1.1).contains(&det) {
            return None;
        }
        let q = DQuat::from_mat3(&m).normalize();
        q.is_finite().then(|| q.as_quat())
    }

    pub fn is_visible(&self) -> bool {
        self.quality >= 0.0
    }
}

/// A flystick: its target, buttons (bit i: button i) and controllers (joystick axes, −1 to 1).
#[derive(Debug, Clone, PartialEq)]
pub struct Flystick {
    pub target: Target,
    pub buttons: Vec<bool>,
    pub controllers: Vec<f64>,
}

/// One frame: what omnicave reads of a datagram.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct DTrackFrame {
    pub frame_counter: Option<u64>,
    /// Seconds since midnight (UTC), as DTrack stamps it.
    pub timestamp: Option<f64>,
    /// Tracked standard bodies (a body DTrack cannot see is not listed).
    pub bodies: Vec<Target>,
    pub flysticks: Vec<Flystick>,
}

/// What is wrong with a frame: the line's identifier and the reason.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("DTrack '{line}' line: {why}")]
pub struct FrameError {
    pub line: String,
    pub why: String,
}

/// Reads the `[...]` blocks of a line after its counts.
struct Blocks<'a> {
    rest: &'a str,
}

impl<'a> Blocks<'a> {
    fn next(&mut self) -> Result<Vec<f64>, String> {
        let start = self.rest.find('[').ok_or("a block is missing")?;
        if !self.rest[..start].trim().is_empty() {
            return Err(format!(
                "unexpected '{}' between blocks",
                self.rest[..start].trim()
            ));
        }
        let end = self.rest[start..]
            .find(']')
            .ok_or("a block has no closing ']'")?
            + start;
        let inside = &self.rest[start + 1..end];
        self.rest = &self.rest[end + 1..];
        inside
            .split_ascii_whitespace()
            .map(|t| {
                t.parse::<f64>()
                    .ok()
                    .filter(|v| v.is_finite() && v.abs() <= MAX_ABS_NUMBER)
                    .ok_or_else(|| format!("'{t}' is not a finite number"))
            })
            .collect()
    }

    fn exact(&mut self, n: usize, what: &str) -> Result<Vec<f64>, String> {
        let b = self.next()?;
        if b.len() < n {
            return Err(format!("the {what} block has {} numbers, not {n}", b.len()));
        }
        Ok(b)
    }
}

fn count(token: Option<&str>, what: &str) -> Result<usize, String> {
    let t = token.ok_or_else(|| format!("no {what}"))?;
    let n: usize = t
        .parse()
        .map_err(|_| format!("the {what} '{t}' is not a count"))?;
    if n > MAX_TARGETS {
        return Err(format!("the {what} {n} is beyond {MAX_TARGETS}"));
    }
    Ok(n)
}

fn id(v: f64, what: &str) -> Result<u32, String> {
    if v >= 0.0 && v.fract() == 0.0 && v <= f64::from(u32::MAX) {
        Ok(v as u32)
    } else {
        Err(format!("the {what} {v} is not an id"))
    }
}

fn target(id: u32, quality: f64, position: &[f64], rotation: &[f64]) -> Target {
    Target {
        id,
        quality,
        position_mm: [position[0], position[1], position[2]],
        rotation: std::array::from_fn(|i| rotation[i]),
    }
}

/// The counts and the blocks of a line, split at the first '['.
fn split_counts(rest: &str) -> (std::str::SplitAsciiWhitespace<'_>, Blocks<'_>) {
    let at = rest.find('[').unwrap_or(rest.len());
    (
        rest[..at].split_ascii_whitespace(),
        Blocks { rest: &rest[at..] },
    )
}

fn parse_6d(rest: &str) -> Result<Vec<Target>, String> {
    let (mut counts, mut blocks) = split_counts(rest);
    let n = count(counts.next(), "body count")?;
    let mut bodies = Vec::with_capacity(n);
    for _ in 0..n {
        let head = blocks.exact(2, "id and quality")?;
        // DTrack2 writes [x y z η θ φ]; later versions [x y z]: the angles are not used.
        let position = blocks.exact(3, "position")?;
        let rotation = blocks.exact(9, "rotation matrix")?;
        bodies.push(target(
            id(head[0], "body id")?,
            head[1],
            &position,
            &rotation,
        ));
    }
    Ok(bodies)
}

fn parse_6df2(rest: &str) -> Result<Vec<Flystick>, String> {
    let (mut counts, mut blocks) = split_counts(rest);
    let _defined = count(counts.next(), "number of defined flysticks")?;
    let n = count(counts.next(), "flystick count")?;
    let mut sticks = Vec::with_capacity(n);
    for _ in 0..n {
        let head = blocks.exact(4, "id, quality, buttons and controllers")?;
        let buttons = head[2];
        let controllers = head[3];
        let (Ok(buttons), Ok(controllers)) = (
            id(buttons, "button count"),
            id(controllers, "controller count"),
        ) else {
            return Err(format!(
                "button and controller counts {buttons} {controllers}"
            ));
        };
        let (buttons, controllers) = (buttons as usize, controllers as usize);
        if buttons > MAX_FLYSTICK_BUTTONS || controllers > MAX_FLYSTICK_CONTROLLERS {
            return Err(format!(
                "{buttons} buttons and {controllers} controllers (at most {MAX_FLYSTICK_BUTTONS} \
                 and {MAX_FLYSTICK_CONTROLLERS})"
            ));
        }
        let position = blocks.exact(3, "position")?;
        let rotation = blocks.exact(9, "rotation matrix")?;
        // Buttons as 32-bit integers, 32 buttons each, then the controllers.
        let words = buttons.div_ceil(32);
        let inputs = blocks.exact(words + controllers, "buttons and controllers")?;
        let mut states = Vec::with_capacity(buttons);
        for b in 0..buttons {
            let word = inputs[b / 32];
            if !(0.0..=f64::from(u32::MAX)).contains(&word) || word.fract() != 0.0 {
                return Err(format!("button word {word} is not a 32-bit number"));
            }
            states.push((word as u32 >> (b % 32)) & 1 == 1);
        }
        sticks.push(Flystick {
            target: target(id(head[0], "flystick id")?, head[1], &position, &rotation),
            buttons: states,
            controllers: inputs[words..words + controllers].to_vec(),
        });
    }
    Ok(sticks)
}

/// Parses one datagram. Lines DTrack may send but omnicave does not use (`6dcal`, `3d`, `6di`,
/// `6dmt2`, `gl`, …) are skipped; a broken line of a kind omnicave reads refuses the frame.
pub fn parse_frame(text: &str) -> Result<DTrackFrame, FrameError> {
    let mut frame = DTrackFrame::default();
    for line in text
        .split(['\r', '\n'])
        .map(str::trim)
        .filter(|l| !l.is_empty())
    {
        let (kind, rest) = line.split_once(' ').unwrap_or((line, ""));
        let fail = |why: String| FrameError {
            line: kind.chars().take(16).collect(),
            why,
        };
        match kind {
            "fr" => {
                frame.frame_counter = Some(
                    rest.trim()
                        .parse()
                        .map_err(|_| fail(format!("'{}' is not a frame counter", rest.trim())))?,
                );
            }
            "ts" => {
                let t: f64 = rest
                    .trim()
                    .parse()
                    .map_err(|_| fail(format!("'{}' is not a time stamp", rest.trim())))?;
                frame.timestamp = Some(t).filter(|t| t.is_finite());
            }
            "6d" => frame.bodies = parse_6d(rest).map_err(fail)?,
            "6df2" => frame.flysticks = parse_6df2(rest).map_err(fail)?,
            _ => {}
        }
    }
    Ok(frame)
}

/// Which DTrack targets omnicave reads, and where it listens.
#[derive(Debug, Clone, PartialEq)]
pub struct DTrackSettings {
    pub listen: SocketAddr,
    /// Senders allowed (empty: any).
    pub allowed_senders: Vec<IpAddr>,
    /// The `6d` body that is the head (id as in the frames, from 0).
    pub head_body: u32,
    /// The `6df2` flystick that is the wand and gives the buttons (`None`: no wand).
    pub flystick: Option<u32>,
}

/// What one frame does to the feed.
#[derive(Debug)]
pub struct FrameSink {
    settings: DTrackSettings,
    feed: TrackerFeed,
    head_seq: u64,
    wand_seq: u64,
    bad_log: LogLimiter,
}

impl FrameSink {
    pub fn new(settings: DTrackSettings) -> Self {
        Self {
            settings,
            feed: TrackerFeed::default(),
            head_seq: 0,
            wand_seq: 0,
            bad_log: LogLimiter::default(),
        }
    }

    pub fn feed(&self) -> TrackerFeed {
        self.feed.clone()
    }

    /// Handles one datagram from `from`, received at `arrived`.
    pub fn handle(&mut self, bytes: &[u8], from: SocketAddr, arrived: Instant) {
        let allowed = &self.settings.allowed_senders;
        if !allowed.is_empty() && !allowed.contains(&from.ip().to_canonical()) {
            self.feed.count(Fate::Refused);
            return;
        }
        let frame = match std::str::from_utf8(bytes) {
            Ok(text) => parse_frame(text).map_err(|e| e.to_string()),
            Err(_) => Err("not ASCII text".to_owned()),
        };
        let frame = match frame {
            Ok(f) => f,
            Err(why) => {
                self.feed.count(Fate::Malformed);
                if let Some(held) = self.bad_log.allow(arrived, LOG_INTERVAL) {
                    tracing::warn!(
                        "DTrack: dropped a frame from {from}: {why}{}",
                        held_back(held)
                    );
                }
                return;
            }
        };
        // The frame counter, else the time stamp: what orders this tracker's frames.
        let sent = frame
            .frame_counter
            .map(SentAt::Frame)
            .or(frame.timestamp.map(SentAt::Seconds));
        let sample = |t: &Target, seq: u64| TrackerSample {
            seq,
            arrived,
            stored: Instant::now(),
            position: Some(Vec3::from_array(t.position_mm.map(|v| (v * 1e-3) as f32))),
            orientation: t.orientation().map(TrackedOrientation::Tracker),
            tracked: Some(true),
            sender: from,
            sent,
            jumped: false,
        };
        let mut used = false;
        // A frame without the head body: DTrack cannot see it now.
        self.head_seq += 1;
        match frame
            .bodies
            .iter()
            .find(|b| b.id == self.settings.head_body)
        {
            Some(body) => self.feed.publish_head(sample(body, self.head_seq)),
            None => {
                let mut lost = sample(&empty_target(), self.head_seq);
                lost.position = None;
                lost.orientation = None;
                lost.tracked = Some(false);
                self.feed.publish_head(lost);
            }
        }
        used |= !frame.bodies.is_empty();
        if let Some(want) = self.settings.flystick
            && let Some(stick) = frame.flysticks.iter().find(|f| f.target.id == want)
        {
            used = true;
            if stick.target.is_visible() {
                self.wand_seq += 1;
                self.feed.publish_wand(sample(&stick.target, self.wand_seq));
            }
            self.feed.update_controls(from, arrived, |c| {
                for (i, down) in stick.buttons.iter().enumerate() {
                    c.set_button(i, *down);
                }
                c.set_analogs(stick.controllers.iter().copied());
            });
        }
        self.feed
            .count(if used { Fate::Accepted } else { Fate::Ignored });
    }
}

fn empty_target() -> Target {
    Target {
        id: 0,
        quality: -1.0,
        position_mm: [0.0; 3],
        rotation: [0.0; 9],
    }
}

/// A running DTrack receiver: its socket's thread and the feed.
#[derive(Debug)]
pub struct DTrackReceiver {
    feed: TrackerFeed,
    udp: UdpThread,
    allowed_senders: Vec<IpAddr>,
}

impl DTrackReceiver {
    pub fn start(settings: &DTrackSettings) -> Result<Self, TrackingError> {
        let mut sink = FrameSink::new(settings.clone());
        let feed = sink.feed();
        let udp = UdpThread::start(
            "dtrack-receiver",
            "DTrack",
            settings.listen,
            feed.clone(),
            move |bytes, from, arrived| sink.handle(bytes, from, arrived),
        )?;
        tracing::info!("DTrack tracking: listening on {}", udp.local_addr());
        Ok(Self {
            feed,
            udp,
            allowed_senders: settings.allowed_senders.clone(),
        })
    }

    /// The senders allowed (empty: any).
    pub fn allowed_senders(&self) -> &[IpAddr] {
        &self.allowed_senders
    }

    pub fn local_addr(&self) -> SocketAddr {
        self.udp.local_addr()
    }

    pub fn feed(&self) -> &TrackerFeed {
        &self.feed
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The manual's `6d` example (DTrack2 form, with the Euler angles in the position block).
    const MANUAL_6D: &str = "6d 1 [0 1.000][326.848 -187.216 109.503 -160.4704 -3.6963 \
        -7.0913][-0.940508 -0.339238 -0.019025 0.333599 -0.932599 0.137735 -0.064467 0.123194 \
        0.990286]";

    #[test]
    fn the_manuals_body_line() {
        let f = parse_frame(&format!(
            "fr 21753\r\nts 39596.024831\r\n6dcal 2\r\n{MANUAL_6D}\r\n"
        ))
        .expect("manual frame");
        assert_eq!(f.frame_counter, Some(21753));
        assert_eq!(f.timestamp, Some(39596.024831));
        assert_eq!(f.bodies.len(), 1);
        let b = &f.bodies[0];
        assert_eq!(b.position_mm, [326.848, -187.216, 109.503]);
        // R's first column is (b0, b1, b2): the body's x axis in room coordinates.
        let q = b.orientation().expect("rotation");
        let x = q * Vec3::X;
        assert!(
            (x - Vec3::new(-0.940508, -0.339238, -0.019025)).length() < 1e-4,
            "{x}"
        );
    }

    #[test]
    fn flysticks_with_buttons_and_joystick() {
        let line = "6df2 2 2 [0 1.000 6 2][261.103 116.520 41.085][-0.241543 0.968868 \
            -0.054332 -0.482366 -0.168461 -0.859619 -0.842010 -0.181427 0.508039][5 -0.70 \
            1.00] [1 -1.000 4 2][0.000 0.000 0.000][0 0 0 0 0 0 0 0 0][0 0.00 0.00]";
        let f = parse_frame(line).expect("flysticks");
        assert_eq!(f.flysticks.len(), 2);
        let s = &f.flysticks[0];
        assert_eq!(s.buttons, vec![true, false, true, false, false, false]);
        assert_eq!(s.controllers, vec![-0.7, 1.0]);
        assert!(!f.flysticks[1].target.is_visible());
        assert_eq!(f.flysticks[1].target.orientation(), None);
    }

    #[test]
    fn broken_lines_are_refused_with_their_identifier() {
        for bad in [
            "6d 2 [0 1.000][1 2 3][1 0 0 0 1 0 0 0 1]",
            "6d 1 [0 1.000][1 2][1 0 0 0 1 0 0 0 1]",
            "6d 1 [0 1.000][1 2 nan][1 0 0 0 1 0 0 0 1]",
            "6d 99999999 [0 1]",
            "6df2 1 1 [0 1.000 99999 2][0 0 0][1 0 0 0 1 0 0 0 1][0]",
            "6df2 1 1 [0 1.000 6 2][0 0 0][1 0 0 0 1 0 0 0 1][0 0.5]",
            "fr twelve",
        ] {
            let e = parse_frame(bad).expect_err(bad);
            assert!(bad.starts_with(&e.line), "{bad}: {e}");
        }
        // Lines omnicave does not read are skipped, not refused.
        let f = parse_frame("fr 1\n3d 1 [0 1.000][1 2 3]\ngl 0\n6dmt2 0 0\n").expect("others");
        assert_eq!(f.frame_counter, Some(1));
    }
}
