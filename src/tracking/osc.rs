//! Decoding OSC packets from a tracking computer into head pose updates (tracker frame).
//!
//! Accepted forms, each with a configurable address (an empty address switches a form off):
//! - `position_address` `x y z` — or `x y z` + a quaternion (7 numbers), or `x y z` + yaw pitch
//!   roll in degrees (6 numbers);
//! - `orientation_address` a quaternion of 4 numbers, in the configured component order;
//! - `euler_address` `yaw pitch roll` in degrees (CAVE convention: + yaw turns left);
//! - the NatNet-to-OSC bridges' form: `/rigidbody <id> position x y z`,
//!   `/rigidbody <id> quat qx qy qz qw` and `/rigidbody <id> tracked 0|1`;
//! - any of these inside OSC bundles (nested up to [`MAX_BUNDLE_DEPTH`]).
//!
//! Numbers may be 32- or 64-bit floats or integers. A packet is taken whole or not at all: if
//! any message meant for us is malformed or not finite, the whole packet is dropped.

use glam::{DQuat, DVec3, Quat, Vec3};
use rosc::{OscMessage, OscPacket, OscType};

use crate::cave::Head;

/// Deepest bundle nesting accepted. Checked before decoding: the OSC decoder recurses once per
/// level, and a 64 KiB datagram could otherwise nest thousands of levels deep.
pub const MAX_BUNDLE_DEPTH: usize = 8;

/// Deepest nesting of OSC arrays (`[` … `]` in a message's type tags) accepted. No head message
/// uses arrays, but other senders' messages may; the decoder builds any depth, and dropping a
/// value tens of thousands of arrays deep would overflow the receiver's stack.
pub const MAX_ARRAY_DEPTH: usize = 4;

/// The order of a quaternion's four numbers in a message (trackers disagree).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum QuaternionOrder {
    /// `w x y z` (e.g. many Vicon and ART bridges).
    #[default]
    Wxyz,
    /// `x y z w` (e.g. NatNet, Unity, ROS).
    Xyzw,
}

crate::named_enum!(QuaternionOrder {
    Self::Wxyz => "wxyz",
    Self::Xyzw => "xyzw",
});

impl QuaternionOrder {
    /// The quaternion from four numbers in this order.
    pub fn quaternion(self, v: [f64; 4]) -> DQuat {
        match self {
            Self::Wxyz => DQuat::from_xyzw(v[1], v[2], v[3], v[0]),
            Self::Xyzw => DQuat::from_xyzw(v[0], v[1], v[2], v[3]),
        }
    }

    /// The four numbers of `q` in this order.
    pub fn components(self, q: Quat) -> [f32; 4] {
        match self {
            Self::Wxyz => [q.w, q.x, q.y, q.z],
            Self::Xyzw => [q.x, q.y, q.z, q.w],
        }
    }
}

/// One message form the decoder accepts: the `[tracking]` key naming its address, its
/// arguments, what it sets, and an example message's arguments (numbers with a `.` are floats,
/// others integers, `"…"` strings). The reference page `docs/src/reference/osc.md` is this
/// table; a test decodes every example.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct OscForm {
    /// The config key whose value is the address (`tracking.<key>`).
    pub config_key: &'static str,
    /// The arguments, as a user writes them.
    pub arguments: &'static str,
    /// What the message sets.
    pub meaning: &'static str,
    /// An example message's arguments.
    pub example: &'static str,
}

/// Every message form the decoder accepts, in the order the reference lists them.
pub const OSC_FORMS: &[OscForm] = &[
    OscForm {
        config_key: "position_address",
        arguments: "`x y z`",
        meaning: "head position (tracker frame and units)",
        example: "0.1 1.7 -0.2",
    },
    OscForm {
        config_key: "position_address",
        arguments: "`x y z` `qa qb qc qd`",
        meaning: "position and orientation (quaternion in `quaternion_order`)",
        example: "0.1 1.7 -0.2 1.0 0.0 0.0 0.0",
    },
    OscForm {
        config_key: "position_address",
        arguments: "`x y z` `yaw pitch roll`",
        meaning: "position and orientation in degrees (CAVE axes; + yaw turns left)",
        example: "0.1 1.7 -0.2 30.0 0.0 0.0",
    },
    OscForm {
        config_key: "orientation_address",
        arguments: "`qa qb qc qd`",
        meaning: "orientation: a quaternion in `quaternion_order` (`wxyz` or `xyzw`)",
        example: "1.0 0.0 0.0 0.0",
    },
    OscForm {
        config_key: "euler_address",
        arguments: "`yaw pitch roll`",
        meaning: "orientation in degrees (CAVE axes; + yaw turns left)",
        example: "30.0 0.0 0.0",
    },
    OscForm {
        config_key: "natnet_address",
        arguments: "`<id> \"position\" x y z`",
        meaning: "position of rigid body `<id>` (the head when it is `natnet_rigid_body`)",
        example: "1 \"position\" 0.1 1.7 -0.2",
    },
    OscForm {
        config_key: "natnet_address",
        arguments: "`<id> \"quat\" qx qy qz qw`",
        meaning: "orientation of rigid body `<id>`",
        example: "1 \"quat\" 0.0 0.0 0.0 1.0",
    },
    OscForm {
        config_key: "natnet_address",
        arguments: "`<id> \"tracked\" 0|1`",
        meaning: "whether the tracker sees rigid body `<id>`",
        example: "1 \"tracked\" 1",
    },
];

impl OscMapping {
    /// The address this mapping gives the form whose address is the config key `key`.
    pub fn address_of(&self, key: &str) -> Option<&str> {
        match key {
            "position_address" => Some(&self.position_address),
            "orientation_address" => Some(&self.orientation_address),
            "euler_address" => Some(&self.euler_address),
            "natnet_address" => Some(&self.natnet_address),
            _ => None,
        }
    }
}

/// Which OSC messages carry the head pose.
#[derive(Debug, Clone, PartialEq)]
pub struct OscMapping {
    pub position_address: String,
    pub orientation_address: String,
    pub euler_address: String,
    pub quaternion_order: QuaternionOrder,
    /// Address of the NatNet-to-OSC form (`/rigidbody`); empty: off.
    pub natnet_address: String,
    /// The rigid body id whose messages are the head.
    pub natnet_rigid_body: i64,
}

impl Default for OscMapping {
    fn default() -> Self {
        Self {
            position_address: "/head/position".into(),
            orientation_address: "/head/orientation".into(),
            euler_address: "/head/ypr".into(),
            quaternion_order: QuaternionOrder::Wxyz,
            natnet_address: "/rigidbody".into(),
            natnet_rigid_body: 1,
        }
    }
}

/// What one packet says about the head (tracker frame; fields not in the packet are `None`).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct PoseUpdate {
    /// Position in the tracker's frame and units.
    pub position: Option<Vec3>,
    /// Orientation as a rotation in the tracker's frame.
    pub orientation: Option<Quat>,
    /// Yaw/pitch/roll orientation, already in CAVE axes (only the calibration's rotation applies).
    pub orientation_cave_axes: Option<Quat>,
    /// The tracker's own "is the body tracked" flag (NatNet `tracked 0|1`).
    pub tracked: Option<bool>,
}

impl PoseUpdate {
    fn is_empty(&self) -> bool {
        *self == Self::default()
    }

    fn merge(&mut self, later: PoseUpdate) {
        if later.position.is_some() {
            self.position = later.position;
        }
        if later.orientation.is_some() {
            self.orientation = later.orientation;
            self.orientation_cave_axes = None;
        }
        if later.orientation_cave_axes.is_some() {
            self.orientation_cave_axes = later.orientation_cave_axes;
            self.orientation = None;
        }
        if later.tracked.is_some() {
            self.tracked = later.tracked;
        }
    }
}

/// The verdict on one packet.
#[derive(Debug, Clone, PartialEq)]
pub enum PacketOutcome {
    /// At least one message for us, all well-formed: the merged update (later messages win).
    Pose(PoseUpdate),
    /// Valid OSC with nothing for us (other addresses, other rigid bodies).
    Ignored,
    /// Not OSC, too deeply nested, or a message for us with wrong arguments.
    Malformed(String),
    /// A message for us with a NaN or infinite number (or one beyond f32's range).
    NonFinite(String),
}

/// Decodes one UDP datagram. Never panics on any input (fuzzed by `tests/tracking_fuzz.rs`).
pub fn decode_packet(bytes: &[u8], mapping: &OscMapping) -> PacketOutcome {
    if let Err(why) = check_nesting(bytes, 0) {
        return PacketOutcome::Malformed(why);
    }
    let packet = match rosc::decoder::decode_udp(bytes) {
        Ok((_, packet)) => packet,
        Err(e) => return PacketOutcome::Malformed(format!("not OSC: {e}")),
    };
    let mut update = PoseUpdate::default();
    match collect(&packet, mapping, &mut update) {
        Err(Problem::Malformed(why)) => PacketOutcome::Malformed(why),
        Err(Problem::NonFinite(why)) => PacketOutcome::NonFinite(why),
        Ok(()) if update.is_empty() => PacketOutcome::Ignored,
        Ok(()) => PacketOutcome::Pose(update),
    }
}

enum Problem {
    Malformed(String),
    NonFinite(String),
}

/// Refuses bundles nested deeper than [`MAX_BUNDLE_DEPTH`] and arrays deeper than
/// [`MAX_ARRAY_DEPTH`], reading only bundle headers, element sizes and type tags (the
/// structures the decoder would recurse into or build without bound). Anything else malformed
/// is left to the decoder.
fn check_nesting(bytes: &[u8], depth: usize) -> Result<(), String> {
    const TAG: &[u8] = b"#bundle\0";
    if !bytes.starts_with(TAG) {
        return check_arrays(bytes);
    }
    if depth >= MAX_BUNDLE_DEPTH {
        return Err(format!("bundles nested deeper than {MAX_BUNDLE_DEPTH}"));
    }
    // Tag (8 bytes) and time tag (8 bytes), then elements: a big-endian size and the element.
    let mut rest = bytes.get(16..).unwrap_or(&[]);
    while rest.len() >= 4 {
        let size = u32::from_be_bytes([rest[0], rest[1], rest[2], rest[3]]) as usize;
        let Some(element) = rest.get(4..4usize.saturating_add(size)) else {
            return Ok(()); // truncated: the decoder reports it
        };
        check_nesting(element, depth + 1)?;
        rest = &rest[4 + size..];
    }
    Ok(())
}

/// A message's array nesting, from its type tag string (after the padded address).
fn check_arrays(message: &[u8]) -> Result<(), String> {
    let Some(end) = message.iter().position(|&b| b == 0) else {
        return Ok(()); // no terminated address: the decoder reports it
    };
    let tags_start = (end / 4 + 1) * 4;
    let tags = message.get(tags_start..).unwrap_or(&[]);
    let tags = &tags[..tags.iter().position(|&b| b == 0).unwrap_or(tags.len())];
    let mut depth = 0usize;
    for &t in tags {
        match t {
            b'[' => {
                depth += 1;
                if depth > MAX_ARRAY_DEPTH {
                    return Err(format!("arrays nested deeper than {MAX_ARRAY_DEPTH}"));
                }
            }
            b']' => depth = depth.saturating_sub(1),
            _ => {}
        }
    }
    Ok(())
}

fn collect(
    packet: &OscPacket,
    mapping: &OscMapping,
    update: &mut PoseUpdate,
) -> Result<(), Problem> {
    match packet {
        OscPacket::Message(message) => {
            if let Some(u) = decode_message(message, mapping)? {
                update.merge(u);
            }
            Ok(())
        }
        OscPacket::Bundle(bundle) => {
            for p in &bundle.content {
                collect(p, mapping, update)?;
            }
            Ok(())
        }
    }
}

/// A number argument as f64 (floats, doubles and integers).
fn number(arg: &OscType) -> Option<f64> {
    match *arg {
        OscType::Float(v) => Some(f64::from(v)),
        OscType::Double(v) => Some(v),
        OscType::Int(v) => Some(f64::from(v)),
        OscType::Long(v) => Some(v as f64),
        _ => None,
    }
}

/// Largest magnitude of any number a tracker sends (positions in any unit, quaternions,
/// degrees, ids); larger ones count as non-finite.
pub const MAX_ABS_NUMBER: f64 = 1e9;

fn numbers(address: &str, args: &[OscType]) -> Result<Vec<f64>, Problem> {
    let mut out = Vec::with_capacity(args.len());
    for (i, a) in args.iter().enumerate() {
        let v = number(a).ok_or_else(|| {
            Problem::Malformed(format!(
                "{address}: argument {i} is {} (expected a number)",
                type_name(a)
            ))
        })?;
        // f32 is what we compute with: a double beyond its range is as unusable as inf.
        if !v.is_finite() || !(v as f32).is_finite() {
            return Err(Problem::NonFinite(format!(
                "{address}: argument {i} is {v}"
            )));
        }
        // Nor is any tracker's number this large (a kilometre in micrometres): a corrupt
        // packet (one flipped exponent bit makes 0.3 into 1.02e38) is dropped here, so it
        // never replaces the newest good sample the render loop reads.
        if v.abs() > MAX_ABS_NUMBER {
            return Err(Problem::NonFinite(format!(
                "{address}: argument {i} is {v:e}, beyond any tracker's range (±{MAX_ABS_NUMBER:e})"
            )));
        }
        out.push(v);
    }
    Ok(out)
}

fn type_name(arg: &OscType) -> &'static str {
    match arg {
        OscType::Int(_) => "an int",
        OscType::Float(_) => "a float",
        OscType::String(_) => "a string",
        OscType::Blob(_) => "a blob",
        OscType::Time(_) => "a time tag",
        OscType::Long(_) => "a long",
        OscType::Double(_) => "a double",
        OscType::Char(_) => "a char",
        OscType::Color(_) => "a colour",
        OscType::Midi(_) => "a MIDI message",
        OscType::Bool(_) => "a bool",
        OscType::Array(_) => "an array",
        OscType::Nil => "nil",
        OscType::Inf => "infinitum",
    }
}

fn quaternion(address: &str, order: QuaternionOrder, v: [f64; 4]) -> Result<Quat, Problem> {
    let q = order.quaternion(v);
    let length = q.length();
    if length.is_nan() || length <= 1e-6 {
        return Err(Problem::Malformed(format!(
            "{address}: quaternion {v:?} has no direction (length {length})"
        )));
    }
    Ok((q / length).as_quat())
}

fn euler(v: [f64; 3]) -> Quat {
    Head::orientation_from_degrees(v[0] as f32, v[1] as f32, v[2] as f32)
}

fn position(v: &[f64]) -> Vec3 {
    DVec3::new(v[0], v[1], v[2]).as_vec3()
}

fn wrong_count(address: &str, got: usize, expected: &str) -> Problem {
    Problem::Malformed(format!("{address}: {got} arguments (expected {expected})"))
}

fn decode_message(m: &OscMessage, mapping: &OscMapping) -> Result<Option<PoseUpdate>, Problem> {
    let addr = m.addr.as_str();
    if addr.is_empty() {
        return Ok(None);
    }
    let mut update = PoseUpdate::default();
    if addr == mapping.position_address {
        let v = numbers(addr, &m.args)?;
        match v.len() {
            3 => {}
            6 => update.orientation_cave_axes = Some(euler([v[3], v[4], v[5]])),
            7 => {
                update.orientation = Some(quaternion(
                    addr,
                    mapping.quaternion_order,
                    [v[3], v[4], v[5], v[6]],
                )?)
            }
            n => {
                return Err(wrong_count(
                    addr,
                    n,
                    "x y z, x y z + quaternion, or x y z + yaw pitch roll",
                ));
            }
        }
        update.position = Some(position(&v));
    } else if addr == mapping.orientation_address {
        let v = numbers(addr, &m.args)?;
        let [a, b, c, d] = v[..] else {
            return Err(wrong_count(addr, v.len(), "4 quaternion components"));
        };
        update.orientation = Some(quaternion(addr, mapping.quaternion_order, [a, b, c, d])?);
    } else if addr == mapping.euler_address {
        let v = numbers(addr, &m.args)?;
        let [yaw, pitch, roll] = v[..] else {
            return Err(wrong_count(addr, v.len(), "yaw pitch roll in degrees"));
        };
        update.orientation_cave_axes = Some(euler([yaw, pitch, roll]));
    } else if addr == mapping.natnet_address {
        return decode_natnet(m, mapping);
    } else {
        return Ok(None);
    }
    Ok(Some(update))
}

/// `/rigidbody <id> position x y z`, `… quat qx qy qz qw`, `… tracked 0|1`; other kinds
/// (`/rigidbody <id> name …` from some bridges) and other bodies are ignored.
fn decode_natnet(m: &OscMessage, mapping: &OscMapping) -> Result<Option<PoseUpdate>, Problem> {
    let addr = m.addr.as_str();
    let (Some(id), Some(OscType::String(kind))) = (m.args.first(), m.args.get(1)) else {
        return Err(Problem::Malformed(format!(
            "{addr}: expected <id> <kind> … (e.g. 1 position x y z)"
        )));
    };
    let id = match *id {
        OscType::Int(v) => i64::from(v),
        OscType::Long(v) => v,
        _ => {
            return Err(Problem::Malformed(format!(
                "{addr}: rigid body id is {} (expected an int)",
                type_name(id)
            )));
        }
    };
    if id != mapping.natnet_rigid_body {
        return Ok(None);
    }
    let mut update = PoseUpdate::default();
    let rest = &m.args[2..];
    match kind.as_str() {
        "position" => {
            let v = numbers(addr, rest)?;
            if v.len() != 3 {
                return Err(wrong_count(addr, v.len() + 2, "<id> position x y z"));
            }
            update.position = Some(position(&v));
        }
        "quat" => {
            let v = numbers(addr, rest)?;
            let [x, y, z, w] = v[..] else {
                return Err(wrong_count(addr, v.len() + 2, "<id> quat qx qy qz qw"));
            };
            update.orientation = Some(quaternion(addr, QuaternionOrder::Xyzw, [x, y, z, w])?);
        }
        "tracked" => {
            let v = numbers(addr, rest)?;
            let [flag] = v[..] else {
                return Err(wrong_count(addr, v.len() + 2, "<id> tracked 0|1"));
            };
            update.tracked = Some(flag != 0.0);
        }
        _ => return Ok(None),
    }
    Ok(Some(update))
}

/// Encodes OSC packets for the simulator and the tests (the receiver's inverse).
pub mod encode {
    use glam::{Quat, Vec3};
    use rosc::{OscBundle, OscMessage, OscPacket, OscTime, OscType};

    use super::{OscMapping, QuaternionOrder};

    pub fn message(addr: &str, args: Vec<OscType>) -> OscPacket {
        OscPacket::Message(OscMessage {
            addr: addr.to_owned(),
            args,
        })
    }

    pub fn floats(values: &[f32]) -> Vec<OscType> {
        values.iter().map(|&v| OscType::Float(v)).collect()
    }

    pub fn doubles(values: &[f64]) -> Vec<OscType> {
        values.iter().map(|&v| OscType::Double(v)).collect()
    }

    /// A bundle to be applied immediately.
    pub fn bundle(content: Vec<OscPacket>) -> OscPacket {
        OscPacket::Bundle(OscBundle {
            timetag: OscTime {
                seconds: 0,
                fractional: 1,
            },
            content,
        })
    }

    pub fn position(mapping: &OscMapping, p: Vec3) -> OscPacket {
        message(&mapping.position_address, floats(&p.to_array()))
    }

    pub fn orientation(mapping: &OscMapping, q: Quat, order: QuaternionOrder) -> OscPacket {
        message(&mapping.orientation_address, floats(&order.components(q)))
    }

    /// One message of the NatNet-to-OSC form: `<address> <id> <kind> <values…>` (kind
    /// `position`, `quat` or `tracked`).
    pub fn rigid_body(address: &str, id: i32, kind: &str, values: &[f32]) -> OscPacket {
        message(
            address,
            [OscType::Int(id), OscType::String(kind.into())]
                .into_iter()
                .chain(floats(values))
                .collect(),
        )
    }

    /// The NatNet-to-OSC bridges' messages for one rigid body.
    pub fn natnet(mapping: &OscMapping, p: Vec3, q: Option<Quat>) -> Vec<OscPacket> {
        let (address, id) = (&mapping.natnet_address, mapping.natnet_rigid_body as i32);
        let mut out = vec![rigid_body(address, id, "position", &p.to_array())];
        if let Some(q) = q {
            out.push(rigid_body(address, id, "quat", &[q.x, q.y, q.z, q.w]));
        }
        out
    }

    /// Bytes of a packet (encoding our own packets cannot fail; an empty vector if it did).
    pub fn bytes(packet: &OscPacket) -> Vec<u8> {
        rosc::encoder::encode(packet).unwrap_or_default()
    }
}

#[cfg(test)]
mod tests {
    /// Every form the reference documents decodes as a pose with its default address.
    #[test]
    fn every_documented_form_is_decoded() {
        let mapping = OscMapping::default();
        for form in OSC_FORMS {
            let args = form
                .example
                .split_whitespace()
                .map(|t| {
                    if let Some(s) = t.strip_prefix('"') {
                        OscType::String(s.trim_end_matches('"').to_string())
                    } else if t.contains('.') {
                        OscType::Float(t.parse().unwrap())
                    } else {
                        OscType::Int(t.parse().unwrap())
                    }
                })
                .collect();
            let address = mapping.address_of(form.config_key).unwrap();
            let packet = rosc::encoder::encode(&encode::message(address, args)).unwrap();
            assert!(
                matches!(decode_packet(&packet, &mapping), PacketOutcome::Pose(_)),
                "{form:?} is documented but not decoded"
            );
        }
    }

    use super::encode::{bundle, bytes, doubles, floats, message, natnet, orientation};
    use super::*;

    fn pose(bytes: &[u8]) -> PoseUpdate {
        match decode_packet(bytes, &OscMapping::default()) {
            PacketOutcome::Pose(p) => p,
            other => panic!("{other:?}"),
        }
    }

    #[test]
    fn position_as_floats_doubles_and_ints() {
        let m = OscMapping::default();
        let p = pose(&bytes(&message(
            &m.position_address,
            doubles(&[0.25, 1.5, -0.75]),
        )));
        assert_eq!(p.position, Some(Vec3::new(0.25, 1.5, -0.75)));
        let p = pose(&bytes(&message(
            &m.position_address,
            vec![OscType::Int(1), OscType::Long(2), OscType::Float(3.0)],
        )));
        assert_eq!(p.position, Some(Vec3::new(1.0, 2.0, 3.0)));
    }

    #[test]
    fn quaternion_orders_agree() {
        let q = Quat::from_rotation_y(0.7) * Quat::from_rotation_x(0.2);
        for order in QuaternionOrder::ALL {
            let mapping = OscMapping {
                quaternion_order: order,
                ..OscMapping::default()
            };
            let got = match decode_packet(&bytes(&orientation(&mapping, q, order)), &mapping) {
                PacketOutcome::Pose(p) => p.orientation.expect("orientation"),
                other => panic!("{other:?}"),
            };
            assert!(got.angle_between(q) < 1e-5, "{order:?}: {got} vs {q}");
        }
    }

    #[test]
    fn wrong_arguments_are_malformed_and_nan_is_not_finite() {
        let m = OscMapping::default();
        let two = bytes(&message(&m.position_address, floats(&[1.0, 2.0])));
        assert!(matches!(
            decode_packet(&two, &m),
            PacketOutcome::Malformed(_)
        ));
        let text = bytes(&message(
            &m.position_address,
            vec![OscType::String("1".into()); 3],
        ));
        assert!(matches!(
            decode_packet(&text, &m),
            PacketOutcome::Malformed(_)
        ));
        let nan = bytes(&message(&m.position_address, floats(&[1.0, f32::NAN, 0.0])));
        assert!(matches!(
            decode_packet(&nan, &m),
            PacketOutcome::NonFinite(_)
        ));
        let huge = bytes(&message(&m.position_address, doubles(&[1e300, 0.0, 0.0])));
        assert!(matches!(
            decode_packet(&huge, &m),
            PacketOutcome::NonFinite(_)
        ));
        let zero_q = bytes(&message(&m.orientation_address, floats(&[0.0; 4])));
        assert!(matches!(
            decode_packet(&zero_q, &m),
            PacketOutcome::Malformed(_)
        ));
        let other = bytes(&message("/something/else", floats(&[1.0])));
        assert_eq!(decode_packet(&other, &m), PacketOutcome::Ignored);
        assert!(matches!(
            decode_packet(b"garbage!", &m),
            PacketOutcome::Malformed(_)
        ));
    }

    #[test]
    fn deep_bundles_are_refused_before_decoding() {
        let m = OscMapping::default();
        let mut packet = encode::position(&m, Vec3::ONE);
        for _ in 0..MAX_BUNDLE_DEPTH {
            packet = bundle(vec![packet]);
        }
        assert!(matches!(
            decode_packet(&bytes(&packet), &m),
            PacketOutcome::Pose(_)
        ));
        let deeper = bundle(vec![packet]);
        assert!(matches!(
            decode_packet(&bytes(&deeper), &m),
            PacketOutcome::Malformed(_)
        ));
    }

    #[test]
    fn deep_arrays_are_refused_before_decoding() {
        // Arrays 30 000 deep are in tests/tracking_fuzz.rs (through the real thread too).
        let m = OscMapping::default();
        let nested = |depth: usize| {
            let mut value = OscType::Int(1);
            for _ in 0..depth {
                value = OscType::Array(rosc::OscArray {
                    content: vec![value],
                });
            }
            bytes(&message("/other", vec![value]))
        };
        assert_eq!(
            decode_packet(&nested(MAX_ARRAY_DEPTH), &m),
            PacketOutcome::Ignored
        );
        assert!(matches!(
            decode_packet(&nested(MAX_ARRAY_DEPTH + 1), &m),
            PacketOutcome::Malformed(_)
        ));
    }

    #[test]
    fn natnet_form_for_our_rigid_body_only() {
        let m = OscMapping::default();
        let q = Quat::from_rotation_y(0.3);
        let packets = natnet(&m, Vec3::new(0.1, 1.6, 0.2), Some(q));
        let p = pose(&bytes(&bundle(packets)));
        assert_eq!(p.position, Some(Vec3::new(0.1, 1.6, 0.2)));
        assert!(p.orientation.expect("quat").angle_between(q) < 1e-5);
        let other = OscMapping {
            natnet_rigid_body: 2,
            ..m.clone()
        };
        let packets = natnet(&other, Vec3::ONE, None);
        assert_eq!(
            decode_packet(&bytes(&packets[0]), &m),
            PacketOutcome::Ignored
        );
        let lost = message(
            &m.natnet_address,
            vec![
                OscType::Int(1),
                OscType::String("tracked".into()),
                OscType::Int(0),
            ],
        );
        assert_eq!(pose(&bytes(&lost)).tracked, Some(false));
    }
}
