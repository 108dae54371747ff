//! The cluster's messages and their byte layout (little-endian, versioned, size-capped).
//!
//! Every message starts with [`MAGIC`] and a kind byte. Decoding never trusts a length or a
//! count from the wire: a message shorter than its layout, longer than
//! [`MAX_MESSAGE_BYTES`], of an unknown kind, or with text that is not UTF-8 is refused with
//! what was wrong.

use glam::{Quat, Vec3};

use super::ClusterError;

/// "OCL1": omnicave cluster, layout version 1. A process of another version is refused.
pub const MAGIC: u32 = u32::from_le_bytes(*b"OCL1");
/// Largest message accepted (the settings message carries the whole settings as TOML; a
/// config of 1024 walls is about 300 KiB).
pub const MAX_MESSAGE_BYTES: usize = 1 << 20;
/// Longest host name or reason text carried.
pub const MAX_TEXT_BYTES: usize = 4096;

/// One frame's state, from the master to every node: all that, with the settings of
/// `settings_generation`, decides what every wall shows. Fixed size (124 bytes on the wire).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct FrameState {
    /// The master's frame number: every node renders and presents this frame, and
    /// frame-sequential windows take their eye from it (left on even frames).
    pub frame: u64,
    /// The settings message this frame uses (bumped by the master whenever a live setting
    /// changes).
    pub settings_generation: u64,
    /// Head position, CAVE metres (tracked, or set from the panel or keys).
    pub head_position: Vec3,
    /// The tracked head orientation, when the tracker gives one.
    pub tracked_orientation: Option<Quat>,
    /// The tracked wand, CAVE space.
    pub wand: Option<(Vec3, Quat)>,
    /// Navigation: the CAVE's offset in the scene and its turn about +y (radians).
    pub navigation_position: Vec3,
    pub navigation_yaw: f32,
    /// The walls' bounding-box size as set from the panel (metres).
    pub cave_size: Vec3,
    pub swap_eyes: bool,
    /// The animation clock, seconds: every wall shows the scene's animation at this instant.
    pub animation_clock: f64,
    /// Non-zero: every process writes its walls' eye images to the screenshot folder of
    /// this id this frame.
    pub screenshot: u64,
}

/// A message between the master and a node.
#[derive(Debug, Clone, PartialEq)]
pub enum Message {
    /// Node → master after loading: what it loaded, to check it is what the master loaded.
    Hello(Identity),
    /// Master → node: the identities match; the cluster starts.
    Start,
    /// Master → node: the live settings as TOML (a whole config file), with their generation.
    Settings { generation: u64, toml: String },
    /// Master → node: the frame to render.
    Frame(FrameState),
    /// Node → master: frame `frame` is rendered (submitted); with the node's figures.
    Rendered { frame: u64, figures: NodeFigures },
    /// Master → node: every live process has rendered `frame`: present it.
    Present { frame: u64 },
    /// Master → node: stop now (quit, a refused start, or a policy stop), and why. `clean`:
    /// every process is alive and ends together (MPI may finalize).
    Stop { reason: String, clean: bool },
    /// Node → master: a clean stop received; this node finalizes MPI and ends.
    Bye,
    /// Node → master: this node is leaving by itself (its window closed, a signal, an
    /// error), and why.
    Leave { reason: String },
}

/// What a process loaded, compared at start-up: CRC-32 and length of the settings (as
/// validated, so a comment or layout change does not count), the scene's geometry and
/// textures, and the sky file.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct Identity {
    pub host: String,
    pub config: Digest,
    pub scene: Digest,
    pub sky: Digest,
}

/// A CRC-32 and a byte count.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Digest {
    pub crc: u32,
    pub bytes: u64,
}

impl Digest {
    /// Starts a digest to which byte slices are added in order.
    pub fn builder() -> DigestBuilder {
        DigestBuilder {
            hasher: crc32fast::Hasher::new(),
            bytes: 0,
        }
    }

    pub fn of(bytes: &[u8]) -> Self {
        let mut b = Self::builder();
        b.add(bytes);
        b.finish()
    }
}

impl std::fmt::Display for Digest {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "CRC-32 {:08x} over {} bytes", self.crc, self.bytes)
    }
}

/// Accumulates a [`Digest`].
pub struct DigestBuilder {
    hasher: crc32fast::Hasher,
    bytes: u64,
}

impl DigestBuilder {
    pub fn add(&mut self, bytes: &[u8]) {
        self.hasher.update(bytes);
        self.bytes += bytes.len() as u64;
    }

    pub fn finish(self) -> Digest {
        Digest {
            crc: self.hasher.finalize(),
            bytes: self.bytes,
        }
    }
}

/// A node's per-frame costs, reported to the master with each "rendered".
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct NodeFigures {
    /// From the end of its previous frame until this frame's state arrived, ms.
    pub state_wait_ms: f32,
    /// Its wait at the previous frame's barrier (from "rendered" to "present"), ms.
    pub barrier_ms: f32,
    /// Its CPU time to record and submit this frame's walls, ms.
    pub render_ms: f32,
}

const KIND_HELLO: u8 = 1;
const KIND_START: u8 = 2;
const KIND_SETTINGS: u8 = 3;
const KIND_FRAME: u8 = 4;
const KIND_RENDERED: u8 = 5;
const KIND_PRESENT: u8 = 6;
const KIND_STOP: u8 = 7;
const KIND_BYE: u8 = 8;
const KIND_LEAVE: u8 = 9;

impl Message {
    /// Writes the message into `out` (cleared first; its capacity is reused, so the
    /// per-frame messages allocate nothing once it has grown to their size).
    pub fn encode(&self, out: &mut Vec<u8>) {
        out.clear();
        out.extend_from_slice(&MAGIC.to_le_bytes());
        match self {
            Message::Hello(id) => {
                out.push(KIND_HELLO);
                for d in [id.config, id.scene, id.sky] {
                    put_u32(out, d.crc);
                    put_u64(out, d.bytes);
                }
                put_text(out, &id.host);
            }
            Message::Start => out.push(KIND_START),
            Message::Settings { generation, toml } => {
                out.push(KIND_SETTINGS);
                put_u64(out, *generation);
                out.extend_from_slice(toml.as_bytes());
            }
            Message::Frame(s) => {
                out.push(KIND_FRAME);
                put_u64(out, s.frame);
                put_u64(out, s.settings_generation);
                put_vec3(out, s.head_position);
                put_quat_option(out, s.tracked_orientation);
                out.push(u8::from(s.wand.is_some()));
                let (wand_position, wand_orientation) =
                    s.wand.unwrap_or((Vec3::ZERO, Quat::IDENTITY));
                put_vec3(out, wand_position);
                put_quat(out, wand_orientation);
                put_vec3(out, s.navigation_position);
                put_f32(out, s.navigation_yaw);
                put_vec3(out, s.cave_size);
                out.push(u8::from(s.swap_eyes));
                put_u64(out, s.animation_clock.to_bits());
                put_u64(out, s.screenshot);
            }
            Message::Rendered { frame, figures } => {
                out.push(KIND_RENDERED);
                put_u64(out, *frame);
                put_f32(out, figures.state_wait_ms);
                put_f32(out, figures.barrier_ms);
                put_f32(out, figures.render_ms);
            }
            Message::Present { frame } => {
                out.push(KIND_PRESENT);
                put_u64(out, *frame);
            }
            Message::Stop { reason, clean } => {
                out.push(KIND_STOP);
                out.push(u8::from(*clean));
                put_text(out, reason);
            }
            Message::Bye => out.push(KIND_BYE),
            Message::Leave { reason } => {
                out.push(KIND_LEAVE);
                put_text(out, reason);
            }
        }
    }

    /// Reads a message (see the module documentation for what is refused).
    pub fn decode(bytes: &[u8]) -> Result<Message, ClusterError> {
        if bytes.len() > MAX_MESSAGE_BYTES {
            return Err(ClusterError::Malformed(format!(
                "{} bytes, over the {MAX_MESSAGE_BYTES}-byte budget",
                bytes.len()
            )));
        }
        let mut r = Reader { bytes, at: 0 };
        let magic = r.u32()?;
        if magic != MAGIC {
            return Err(ClusterError::Malformed(format!(
                "starts with {magic:#010x}, not omnicave's cluster layout {MAGIC:#010x} (another \
                 version of omnicave, or not omnicave)"
            )));
        }
        let kind = r.u8()?;
        let message = match kind {
            KIND_HELLO => {
                let mut digest = || -> Result<Digest, ClusterError> {
                    Ok(Digest {
                        crc: r.u32()?,
                        bytes: r.u64()?,
                    })
                };
                let (config, scene, sky) = (digest()?, digest()?, digest()?);
                Message::Hello(Identity {
                    config,
                    scene,
                    sky,
                    host: r.text()?,
                })
            }
            KIND_START => Message::Start,
            KIND_SETTINGS => {
                let generation = r.u64()?;
                let toml = std::str::from_utf8(r.rest())
                    .map_err(|e| ClusterError::Malformed(format!("settings not UTF-8: {e}")))?
                    .to_owned();
                Message::Settings { generation, toml }
            }
            KIND_FRAME => {
                let frame = r.u64()?;
                let settings_generation = r.u64()?;
                let head_position = r.vec3()?;
                let tracked_orientation = r.quat_option()?;
                let has_wand = r.flag()?;
                let wand = (r.vec3()?, r.quat()?);
                Message::Frame(FrameState {
                    frame,
                    settings_generation,
                    head_position,
                    tracked_orientation,
                    wand: has_wand.then_some(wand),
                    navigation_position: r.vec3()?,
                    navigation_yaw: r.f32()?,
                    cave_size: r.vec3()?,
                    swap_eyes: r.flag()?,
                    animation_clock: r.f64()?,
                    screenshot: r.u64()?,
                })
            }
            KIND_RENDERED => Message::Rendered {
                frame: r.u64()?,
                figures: NodeFigures {
                    state_wait_ms: r.f32()?,
                    barrier_ms: r.f32()?,
                    render_ms: r.f32()?,
                },
            },
            KIND_PRESENT => Message::Present { frame: r.u64()? },
            KIND_BYE => Message::Bye,
            KIND_LEAVE => Message::Leave { reason: r.text()? },
            KIND_STOP => Message::Stop {
                clean: r.flag()?,
                reason: r.text()?,
            },
            other => {
                return Err(ClusterError::Malformed(format!(
                    "unknown message kind {other}"
                )));
            }
        };
        if r.at != bytes.len() && kind != KIND_SETTINGS {
            return Err(ClusterError::Malformed(format!(
                "{} bytes after the end of a kind-{kind} message",
                bytes.len() - r.at
            )));
        }
        Ok(message)
    }
}

fn put_u32(out: &mut Vec<u8>, v: u32) {
    out.extend_from_slice(&v.to_le_bytes());
}
fn put_u64(out: &mut Vec<u8>, v: u64) {
    out.extend_from_slice(&v.to_le_bytes());
}
fn put_f32(out: &mut Vec<u8>, v: f32) {
    out.extend_from_slice(&v.to_le_bytes());
}
fn put_vec3(out: &mut Vec<u8>, v: Vec3) {
    for c in v.to_array() {
        put_f32(out, c);
    }
}
fn put_quat(out: &mut Vec<u8>, q: Quat) {
    for c in q.to_array() {
        put_f32(out, c);
    }
}
fn put_quat_option(out: &mut Vec<u8>, q: Option<Quat>) {
    out.push(u8::from(q.is_some()));
    put_quat(out, q.unwrap_or(Quat::IDENTITY));
}
/// Text, cut to [`MAX_TEXT_BYTES`] at a character boundary.
fn put_text(out: &mut Vec<u8>, text: &str) {
    let mut end = text.len().min(MAX_TEXT_BYTES);
    while !text.is_char_boundary(end) {
        end -= 1;
    }
    put_u32(out, end as u32);
    out.extend_from_slice(&text.as_bytes()[..end]);
}

struct Reader<'a> {
    bytes: &'a [u8],
    at: usize,
}

impl<'a> Reader<'a> {
    fn take(&mut self, n: usize) -> Result<&'a [u8], ClusterError> {
        let end = self.at.checked_add(n).filter(|e| *e <= self.bytes.len());
        let Some(end) = end else {
            return Err(ClusterError::Malformed(format!(
                "{} bytes, cut short at byte {} (wanted {n} more)",
                self.bytes.len(),
                self.at
            )));
        };
        let s = &self.bytes[self.at..end];
        self.at = end;
        Ok(s)
    }
    fn array<const N: usize>(&mut self) -> Result<[u8; N], ClusterError> {
        let mut a = [0; N];
        a.copy_from_slice(self.take(N)?);
        Ok(a)
    }
    fn u8(&mut self) -> Result<u8, ClusterError> {
        Ok(self.array::<1>()?[0])
    }
    fn flag(&mut self) -> Result<bool, ClusterError> {
        match self.u8()? {
            0 => Ok(false),
            1 => Ok(true),
            v => Err(ClusterError::Malformed(format!("flag byte {v} (0 or 1)"))),
        }
    }
    fn u32(&mut self) -> Result<u32, ClusterError> {
        Ok(u32::from_le_bytes(self.array()?))
    }
    fn u64(&mut self) -> Result<u64, ClusterError> {
        Ok(u64::from_le_bytes(self.array()?))
    }
    /// A finite float (NaN or infinity would poison the head, the warp or the navigation).
    fn f32(&mut self) -> Result<f32, ClusterError> {
        let v = f32::from_le_bytes(self.array()?);
        if v.is_finite() {
            Ok(v)
        } else {
            Err(ClusterError::Malformed(format!(
                "non-finite number {v} at byte {}",
                self.at - 4
            )))
        }
    }
    /// A finite double (the animation clock).
    fn f64(&mut self) -> Result<f64, ClusterError> {
        let v = f64::from_bits(self.u64()?);
        if v.is_finite() {
            Ok(v)
        } else {
            Err(ClusterError::Malformed(format!(
                "non-finite number {v} at byte {}",
                self.at - 8
            )))
        }
    }
    fn vec3(&mut self) -> Result<Vec3, ClusterError> {
        Ok(Vec3::new(self.f32()?, self.f32()?, self.f32()?))
    }
    fn quat(&mut self) -> Result<Quat, ClusterError> {
        let q = Quat::from_xyzw(self.f32()?, self.f32()?, self.f32()?, self.f32()?);
        // The master sends unit quaternions; anything far from one is not from it.
        if (q.length() - 1.0).abs() > 1e-3 {
            return Err(ClusterError::Malformed(format!(
                "orientation {q} is not a unit quaternion"
            )));
        }
        Ok(q)
    }
    fn quat_option(&mut self) -> Result<Option<Quat>, ClusterError> {
        let some = self.flag()?;
        let q = self.quat()?;
        Ok(some.then_some(q))
    }
    fn text(&mut self) -> Result<String, ClusterError> {
        let n = self.u32()? as usize;
        if n > MAX_TEXT_BYTES {
            return Err(ClusterError::Malformed(format!(
                "text of {n} bytes, over the {MAX_TEXT_BYTES}-byte budget"
            )));
        }
        let bytes = self.take(n)?;
        std::str::from_utf8(bytes)
            .map(str::to_owned)
            .map_err(|e| ClusterError::Malformed(format!("text not UTF-8: {e}")))
    }
    fn rest(&mut self) -> &'a [u8] {
        let s = &self.bytes[self.at..];
        self.at = self.bytes.len();
        s
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn samples() -> Vec<Message> {
        vec![
            Message::Hello(Identity {
                host: "wall-pc-2".into(),
                config: Digest { crc: 1, bytes: 2 },
                scene: Digest { crc: 3, bytes: 4 },
                sky: Digest::of(b"sky"),
            }),
            Message::Start,
            Message::Settings {
                generation: 7,
                toml: "[render]\nmode = \"omni-offaxis\"\n".into(),
            },
            Message::Frame(FrameState {
                frame: 12345,
                settings_generation: 7,
                head_position: Vec3::new(0.1, 1.7, -0.2),
                tracked_orientation: Some(Quat::from_rotation_y(0.3)),
                wand: Some((Vec3::ONE, Quat::from_rotation_x(-0.5))),
                navigation_position: Vec3::new(10.0, 0.0, -3.0),
                navigation_yaw: 1.25,
                cave_size: Vec3::new(3.3, 2.9, 3.3),
                swap_eyes: true,
                animation_clock: 12.375,
                screenshot: 99,
            }),
            Message::Frame(FrameState::default()),
            Message::Rendered {
                frame: 3,
                figures: NodeFigures {
                    state_wait_ms: 1.5,
                    barrier_ms: 0.25,
                    render_ms: 12.0,
                },
            },
            Message::Present { frame: 3 },
            Message::Stop {
                reason: "quit from the master's panel".into(),
                clean: true,
            },
            Message::Bye,
            Message::Leave {
                reason: "its window was closed".into(),
            },
        ]
    }

    #[test]
    fn every_message_round_trips() {
        let mut buf = Vec::new();
        for m in samples() {
            m.encode(&mut buf);
            assert_eq!(Message::decode(&buf).unwrap(), m);
        }
    }

    #[test]
    fn the_frame_state_is_a_fixed_few_hundred_bytes() {
        let mut buf = Vec::new();
        Message::Frame(FrameState::default()).encode(&mut buf);
        // The budget: "the state is a few hundred bytes".
        assert_eq!(buf.len(), 124);
    }

    #[test]
    fn damaged_messages_are_refused_with_what_was_wrong() {
        let mut buf = Vec::new();
        for m in samples() {
            m.encode(&mut buf);
            // Every truncation of a fixed-layout message is refused, never a panic.
            if !matches!(m, Message::Settings { .. }) {
                for cut in 0..buf.len() {
                    assert!(Message::decode(&buf[..cut]).is_err(), "{m:?} cut at {cut}");
                }
                let mut longer = buf.clone();
                longer.push(0);
                assert!(Message::decode(&longer).is_err());
            }
        }
        let err = |bytes: &[u8]| Message::decode(bytes).unwrap_err().to_string();
        assert!(err(b"XXXX\x01").contains("not omnicave's cluster layout"));
        let mut unknown = MAGIC.to_le_bytes().to_vec();
        unknown.push(200);
        assert!(err(&unknown).contains("unknown message kind 200"));
        // A NaN head position.
        Message::Frame(FrameState::default()).encode(&mut buf);
        buf[4 + 1 + 16..4 + 1 + 20].copy_from_slice(&f32::NAN.to_le_bytes());
        assert!(err(&buf).contains("non-finite"));
        // A text length past its budget.
        let mut stop = MAGIC.to_le_bytes().to_vec();
        stop.push(KIND_STOP);
        stop.push(1);
        stop.extend_from_slice(&u32::MAX.to_le_bytes());
        assert!(err(&stop).contains("budget"));
        // Over the message budget.
        assert!(err(&vec![0; MAX_MESSAGE_BYTES + 1]).contains("budget"));
        // Random bytes never panic.
        let mut seed = 0x2545_f491_4f6c_dd1du64;
        for _ in 0..20_000 {
            seed ^= seed << 13;
            seed ^= seed >> 7;
            seed ^= seed << 17;
            let len = (seed % 160) as usize;
            let mut bytes: Vec<u8> = (0..len).map(|i| (seed >> (i % 56)) as u8).collect();
            if bytes.len() >= 5 {
                bytes[..4].copy_from_slice(&MAGIC.to_le_bytes());
                bytes[4] = (seed % 11) as u8;
            }
            let _ = Message::decode(&bytes);
        }
    }
}
