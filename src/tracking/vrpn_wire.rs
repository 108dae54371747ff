//! VRPN's wire format (its `Format_Of_Protocol.txt`): the cookie, message framing, the system
//! messages and the tracker, button and analog payloads. Pure functions, no sockets; every
//! length read off the wire is checked against the bytes present and a budget.

/// The port a VRPN server listens on unless told otherwise (`vrpn_DEFAULT_LISTEN_PORT_NO`).
pub const DEFAULT_PORT: u16 = 3883;
/// The cookie both ends send first: the magic, two spaces, the log mode, padded to 8 bytes.
pub const COOKIE_SIZE: usize = 24;
/// The magic this client sends (VRPN 07.38, the peer's version; any 07.xx server accepts it).
const MAGIC: &[u8; 16] = b"vrpn: ver. 07.38";
/// What a compatible peer's cookie must start with: VRPN compares up to the last '.', so only
/// the major version has to match.
const MAJOR_PREFIX: &[u8] = b"vrpn: ver. 07.";
/// A message header: length, seconds, microseconds, sender, type, sequence number (six
/// big-endian 32-bit integers, already a multiple of 8).
pub const HEADER_SIZE: usize = 24;
/// Budget: the longest message accepted (VRPN's own TCP buffer is 64 KiB; a tracker report is
/// 64 bytes). A longer length field means a broken or hostile stream: the connection is dropped.
pub const MAX_MESSAGE: usize = 1 << 20;
/// Budget: the longest sender or type name (VRPN's `vrpn_CNAME` holds 100 characters).
pub const MAX_NAME: usize = 128;
/// Budget: the most sender and type ids remembered per connection (VRPN allows 2000 of each).
pub const MAX_IDS: usize = 4096;
/// VRPN's largest button and analog counts (`vrpn_BUTTON_MAX_BUTTONS`, `vrpn_CHANNEL_MAX`).
pub const MAX_WIRE_BUTTONS: usize = 256;
pub const MAX_WIRE_ANALOGS: usize = 128;

/// System message types (negative type ids).
pub const SENDER_DESCRIPTION: i32 = -1;
pub const TYPE_DESCRIPTION: i32 = -2;
pub const UDP_DESCRIPTION: i32 = -3;

/// The message type names of the devices omnicave reads.
pub const TRACKER_POS_QUAT: &str = "vrpn_Tracker Pos_Quat";
pub const BUTTON_CHANGE: &str = "vrpn_Button Change";
pub const BUTTON_STATES: &str = "vrpn_Button States";
pub const ANALOG_CHANNEL: &str = "vrpn_Analog Channel";

/// What is wrong with bytes off the wire.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum WireError {
    #[error("not a VRPN 07.xx server (its cookie reads {0:?})")]
    Cookie(String),
    #[error("a message length of {0} bytes is outside 24 to {MAX_MESSAGE}")]
    Length(u32),
    #[error("a {what} payload of {got} bytes is shorter than the {need} it needs")]
    Short {
        what: &'static str,
        got: usize,
        need: usize,
    },
    #[error("a {what} count of {count} is beyond {max}")]
    Count {
        what: &'static str,
        count: f64,
        max: usize,
    },
}

/// The cookie this client sends: magic, two spaces, log mode '0' (no remote logging), NULs.
pub fn cookie() -> [u8; COOKIE_SIZE] {
    let mut c = [0u8; COOKIE_SIZE];
    c[..16].copy_from_slice(MAGIC);
    c[16] = b' ';
    c[17] = b' ';
    c[18] = b'0';
    c
}

/// Checks the peer's cookie (major version 07, as VRPN itself checks).
pub fn check_cookie(bytes: &[u8]) -> Result<(), WireError> {
    if bytes.len() >= COOKIE_SIZE && bytes.starts_with(MAJOR_PREFIX) {
        Ok(())
    } else {
        let text: String = String::from_utf8_lossy(&bytes[..bytes.len().min(COOKIE_SIZE)])
            .trim_end_matches('\0')
            .chars()
            .take(40)
            .collect();
        Err(WireError::Cookie(text))
    }
}

/// A message's header.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Header {
    /// Header plus payload, without the payload's padding.
    pub length: u32,
    pub seconds: u32,
    pub microseconds: u32,
    pub sender: i32,
    pub kind: i32,
}

impl Header {
    pub fn payload_len(&self) -> usize {
        self.length as usize - HEADER_SIZE
    }

    /// The payload as sent: padded to a multiple of 8 bytes.
    pub fn padded_payload_len(&self) -> usize {
        padded(self.payload_len())
    }
}

/// `len` rounded up to VRPN's 8-byte alignment.
pub fn padded(len: usize) -> usize {
    len.div_ceil(8) * 8
}

fn be_u32(b: &[u8], at: usize) -> u32 {
    u32::from_be_bytes([b[at], b[at + 1], b[at + 2], b[at + 3]])
}

fn be_i32(b: &[u8], at: usize) -> i32 {
    be_u32(b, at) as i32
}

fn be_f64(b: &[u8], at: usize) -> f64 {
    let mut a = [0u8; 8];
    a.copy_from_slice(&b[at..at + 8]);
    f64::from_be_bytes(a)
}

/// Reads a header; refuses a length outside the budget.
pub fn parse_header(bytes: &[u8; HEADER_SIZE]) -> Result<Header, WireError> {
    let length = be_u32(bytes, 0);
    if (length as usize) < HEADER_SIZE || length as usize > MAX_MESSAGE {
        return Err(WireError::Length(length));
    }
    Ok(Header {
        length,
        seconds: be_u32(bytes, 4),
        microseconds: be_u32(bytes, 8),
        sender: be_i32(bytes, 12),
        kind: be_i32(bytes, 16),
    })
}

/// One message framed as VRPN sends it (header, payload, padding).
pub fn frame(sender: i32, kind: i32, seconds: u32, microseconds: u32, payload: &[u8]) -> Vec<u8> {
    let mut out = Vec::with_capacity(HEADER_SIZE + padded(payload.len()));
    let length = (HEADER_SIZE + payload.len()) as u32;
    for word in [length, seconds, microseconds, sender as u32, kind as u32, 0] {
        out.extend_from_slice(&word.to_be_bytes());
    }
    out.extend_from_slice(payload);
    out.resize(HEADER_SIZE + padded(payload.len()), 0);
    out
}

/// Splits a UDP datagram into its messages (each `(header, payload)`); stops at the first
/// broken one and says why.
pub fn split_datagram(mut bytes: &[u8]) -> (Vec<(Header, &[u8])>, Option<WireError>) {
    let mut out = Vec::new();
    while !bytes.is_empty() {
        let Some(head) = bytes.first_chunk::<HEADER_SIZE>() else {
            return (
                out,
                Some(WireError::Short {
                    what: "message header",
                    got: bytes.len(),
                    need: HEADER_SIZE,
                }),
            );
        };
        let header = match parse_header(head) {
            Ok(h) => h,
            Err(e) => return (out, Some(e)),
        };
        let len = header.payload_len();
        let rest = &bytes[HEADER_SIZE..];
        if rest.len() < len {
            return (
                out,
                Some(WireError::Short {
                    what: "message",
                    got: rest.len(),
                    need: len,
                }),
            );
        }
        out.push((header, &rest[..len]));
        bytes = &rest[header.padded_payload_len().min(rest.len())..];
    }
    (out, None)
}

fn need(what: &'static str, payload: &[u8], need: usize) -> Result<(), WireError> {
    if payload.len() < need {
        Err(WireError::Short {
            what,
            got: payload.len(),
            need,
        })
    } else {
        Ok(())
    }
}

/// A sender or type description: the id is the header's sender field, the payload a 32-bit
/// length (name + NUL) then the name.
pub fn parse_name(payload: &[u8]) -> Result<String, WireError> {
    need("name", payload, 4)?;
    let len = be_u32(payload, 0) as usize;
    if len > MAX_NAME + 1 {
        return Err(WireError::Count {
            what: "name length",
            count: len as f64,
            max: MAX_NAME + 1,
        });
    }
    need("name", payload, 4 + len)?;
    let name = &payload[4..4 + len];
    let end = name.iter().position(|&b| b == 0).unwrap_or(name.len());
    Ok(String::from_utf8_lossy(&name[..end]).into_owned())
}

/// A name description's payload, as VRPN writes it.
pub fn name_payload(name: &str) -> Vec<u8> {
    let mut p = ((name.len() + 1) as u32).to_be_bytes().to_vec();
    p.extend_from_slice(name.as_bytes());
    p.push(0);
    p
}

/// A tracker report: sensor, position, orientation quaternion (x, y, z, w).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PosQuat {
    pub sensor: i32,
    pub position: [f64; 3],
    pub quat_xyzw: [f64; 4],
}

/// `vrpn_Tracker Pos_Quat`: sensor, padding, three then four big-endian doubles.
pub fn parse_pos_quat(payload: &[u8]) -> Result<PosQuat, WireError> {
    need("tracker report", payload, 64)?;
    Ok(PosQuat {
        sensor: be_i32(payload, 0),
        position: [0, 1, 2].map(|i| be_f64(payload, 8 + 8 * i)),
        quat_xyzw: [0, 1, 2, 3].map(|i| be_f64(payload, 32 + 8 * i)),
    })
}

/// A tracker report's payload, as `vrpn_Tracker::encode_to` writes it.
pub fn pos_quat_payload(report: &PosQuat) -> Vec<u8> {
    let mut p = Vec::with_capacity(64);
    p.extend_from_slice(&report.sensor.to_be_bytes());
    p.extend_from_slice(&report.sensor.to_be_bytes());
    for v in report.position.iter().chain(&report.quat_xyzw) {
        p.extend_from_slice(&v.to_be_bytes());
    }
    p
}

/// `vrpn_Button Change`: button number, state (nonzero: pressed).
pub fn parse_button_change(payload: &[u8]) -> Result<(i32, bool), WireError> {
    need("button change", payload, 8)?;
    Ok((be_i32(payload, 0), be_i32(payload, 4) != 0))
}

/// `vrpn_Button States`: count, then one state per button.
pub fn parse_button_states(payload: &[u8]) -> Result<Vec<bool>, WireError> {
    need("button states", payload, 4)?;
    let n = be_i32(payload, 0);
    if n < 0 || n as usize > MAX_WIRE_BUTTONS {
        return Err(WireError::Count {
            what: "button",
            count: f64::from(n),
            max: MAX_WIRE_BUTTONS,
        });
    }
    let n = n as usize;
    need("button states", payload, 4 + 4 * n)?;
    Ok((0..n).map(|i| be_i32(payload, 4 + 4 * i) != 0).collect())
}

/// `vrpn_Analog Channel`: the count as a double, then one double per channel.
pub fn parse_analog(payload: &[u8]) -> Result<Vec<f64>, WireError> {
    need("analog report", payload, 8)?;
    let n = be_f64(payload, 0);
    if !(0.0..=MAX_WIRE_ANALOGS as f64).contains(&n) || n.fract() != 0.0 {
        return Err(WireError::Count {
            what: "analog channel",
            count: n,
            max: MAX_WIRE_ANALOGS,
        });
    }
    let n = n as usize;
    need("analog report", payload, 8 + 8 * n)?;
    Ok((0..n).map(|i| be_f64(payload, 8 + 8 * i)).collect())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cookie_matches_vrpns_own_layout() {
        let c = cookie();
        assert_eq!(&c[..19], b"vrpn: ver. 07.38  0");
        assert!(c[19..].iter().all(|&b| b == 0));
        check_cookie(&c).expect("own cookie");
        // A different minor version is fine (VRPN compares through the last '.').
        let mut minor = c;
        minor[14..16].copy_from_slice(b"35");
        check_cookie(&minor).expect("07.35");
        let mut major = c;
        major[11..13].copy_from_slice(b"08");
        assert!(check_cookie(&major).is_err());
        assert!(check_cookie(b"HTTP/1.1 400 Bad Request\r\n").is_err());
    }

    #[test]
    fn frames_round_trip_with_padding() {
        let report = PosQuat {
            sensor: 3,
            position: [0.5, -1.25, 2.0],
            quat_xyzw: [0.0, 0.0, 0.0, 1.0],
        };
        let mut datagram = frame(7, 12, 1, 2, &pos_quat_payload(&report));
        datagram.extend(frame(
            -1,
            SENDER_DESCRIPTION,
            0,
            0,
            &name_payload("Tracker0"),
        ));
        assert_eq!(datagram.len() % 8, 0);
        let (messages, error) = split_datagram(&datagram);
        assert!(error.is_none());
        assert_eq!(messages.len(), 2);
        assert_eq!(messages[0].0.sender, 7);
        assert_eq!(parse_pos_quat(messages[0].1), Ok(report));
        assert_eq!(parse_name(messages[1].1).as_deref(), Ok("Tracker0"));
    }

    #[test]
    fn broken_lengths_and_counts_are_refused_not_trusted() {
        let mut m = frame(0, 1, 0, 0, &[0; 8]);
        m[0..4].copy_from_slice(&u32::MAX.to_be_bytes());
        assert!(matches!(split_datagram(&m).1, Some(WireError::Length(_))));
        m[0..4].copy_from_slice(&10u32.to_be_bytes());
        assert!(matches!(split_datagram(&m).1, Some(WireError::Length(10))));
        // Length says 100 payload bytes, 8 are there.
        m[0..4].copy_from_slice(&124u32.to_be_bytes());
        assert!(matches!(
            split_datagram(&m).1,
            Some(WireError::Short { .. })
        ));
        assert!(parse_pos_quat(&[0; 63]).is_err());
        let mut states = (1_000_000i32).to_be_bytes().to_vec();
        states.extend([0; 8]);
        assert!(parse_button_states(&states).is_err());
        let analog = f64::NAN.to_be_bytes();
        assert!(parse_analog(&analog).is_err());
        let analog = 2.0f64.to_be_bytes();
        assert!(
            parse_analog(&analog).is_err(),
            "two channels announced, none sent"
        );
        assert!(parse_name(&[0, 0, 1, 0]).is_err());
    }
}
