//! The VRPN client: connects to VRPN servers as VRPN's own clients do (a UDP request to the
//! server's port, the server connects back over TCP, cookies, then a UDP channel for tracker
//! reports), reads trackers (several sensors), buttons and analogs, and reconnects whenever the
//! server goes away. One thread per server (and one for its UDP channel); nothing blocks the
//! render loop, which reads the same [`TrackerFeed`] as with OSC.

use std::collections::HashMap;
use std::io::{ErrorKind, Read, Write};
use std::net::UdpSocket;
use std::net::{IpAddr, Ipv4Addr, Ipv6Addr, SocketAddr, TcpListener, TcpStream, ToSocketAddrs};
use std::panic::AssertUnwindSafe;
use std::sync::atomic::{AtomicBool, AtomicU32, Ordering};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use glam::{Quat, Vec3};

use super::TrackingError;
use super::osc::MAX_ABS_NUMBER;
use super::receiver::{
    Fate, LOG_INTERVAL, LogLimiter, SentAt, TrackedOrientation, TrackerFeed, TrackerSample,
    held_back,
};
use super::vrpn_wire::{self as wire, HEADER_SIZE, Header, WireError};

/// How long a connection attempt waits for the server to call back.
const CALLBACK_WAIT: Duration = Duration::from_secs(1);
/// How long the server has to send its cookie.
const COOKIE_WAIT: Duration = Duration::from_secs(3);
/// How often the threads wake to see whether they should stop.
const POLL: Duration = Duration::from_millis(50);

/// A VRPN device as VRPN users write it: `Tracker0@host`, `Tracker0@host:port`.
#[derive(Debug, Clone, PartialEq, Eq, Hash)]
pub struct VrpnDevice {
    pub name: String,
    pub host: String,
    pub port: u16,
}

impl std::fmt::Display for VrpnDevice {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        if self.host.contains(':') {
            write!(f, "{}@[{}]:{}", self.name, self.host, self.port)
        } else {
            write!(f, "{}@{}:{}", self.name, self.host, self.port)
        }
    }
}

impl std::str::FromStr for VrpnDevice {
    type Err = String;

    fn from_str(s: &str) -> Result<Self, String> {
        let (name, at) = s
            .split_once('@')
            .ok_or("must be Device@host or Device@host:port (e.g. Tracker0@localhost)")?;
        if name.is_empty() || name.len() > wire::MAX_NAME || name.contains(char::is_whitespace) {
            return Err(format!(
                "the device name must be 1 to {} characters without spaces",
                wire::MAX_NAME
            ));
        }
        let at = at.strip_prefix("tcp://").unwrap_or(at);
        let (host, port) = if let Some(rest) = at.strip_prefix('[') {
            let (host, tail) = rest.split_once(']').ok_or("an IPv6 host needs its ']'")?;
            let port = match tail.strip_prefix(':') {
                Some(p) => Some(p),
                None if tail.is_empty() => None,
                None => return Err("expected ':port' after ']'".into()),
            };
            (host, port)
        } else {
            match at.rsplit_once(':') {
                Some((h, p)) => (h, Some(p)),
                None => (at, None),
            }
        };
        if host.is_empty() {
            return Err("the host is empty".into());
        }
        let port = match port {
            None => wire::DEFAULT_PORT,
            Some(p) => p
                .parse::<u16>()
                .ok()
                .filter(|&p| p != 0)
                .ok_or_else(|| format!("'{p}' is not a port (1 to 65535)"))?,
        };
        Ok(Self {
            name: name.to_owned(),
            host: host.to_owned(),
            port,
        })
    }
}

/// What omnicave reads from VRPN servers.
#[derive(Debug, Clone, PartialEq)]
pub struct VrpnSettings {
    /// The tracker whose sensor is the head.
    pub head: VrpnDevice,
    pub head_sensor: i32,
    /// The tracker and sensor of the wand, if there is one.
    pub wand: Option<(VrpnDevice, i32)>,
    /// The button device (a DTrack flystick served by VRPN has the tracker's name).
    pub buttons: Option<VrpnDevice>,
    /// The analog device (joystick axes).
    pub analogs: Option<VrpnDevice>,
    /// Wait between connection attempts while a server is absent.
    pub retry: Duration,
    /// Addresses a server may be at (`tracking.allowed_senders`; empty: any).
    pub allowed_senders: Vec<IpAddr>,
    /// A server that reports a tracker and sent nothing for this long
    /// (`tracking.timeout_seconds`) is reconnected: a connection can stay open with nobody
    /// at the other end (the server's machine rebooted, a cable pulled).
    pub idle: Duration,
}

/// Which of the configured roles a device name plays on one server.
#[derive(Debug, Clone, Default)]
struct Roles {
    head: Option<(String, i32)>,
    wand: Option<(String, i32)>,
    buttons: Option<String>,
    analogs: Option<String>,
}

impl Roles {
    fn describe(&self) -> String {
        let mut parts = Vec::new();
        if let Some((n, s)) = &self.head {
            parts.push(format!("head {n} sensor {s}"));
        }
        if let Some((n, s)) = &self.wand {
            parts.push(format!("wand {n} sensor {s}"));
        }
        if let Some(n) = &self.buttons {
            parts.push(format!("buttons {n}"));
        }
        if let Some(n) = &self.analogs {
            parts.push(format!("analogs {n}"));
        }
        parts.join(", ")
    }
}

/// A running client: one thread per server.
#[derive(Debug)]
pub struct VrpnClient {
    feed: TrackerFeed,
    stop: Arc<AtomicBool>,
    threads: Vec<JoinHandle<()>>,
    servers: Vec<String>,
    /// Each server's session's UDP data port (0: not connected).
    data_ports: Vec<Arc<AtomicU32>>,
}

impl VrpnClient {
    /// Starts connecting (in the background: an absent server is retried, not an error).
    pub fn start(settings: &VrpnSettings) -> Result<Self, TrackingError> {
        let mut by_server: Vec<((String, u16), Roles)> = Vec::new();
        let mut roles_of = |d: &VrpnDevice| -> usize {
            let key = (d.host.clone(), d.port);
            match by_server.iter().position(|(k, _)| *k == key) {
                Some(i) => i,
                None => {
                    by_server.push((key, Roles::default()));
                    by_server.len() - 1
                }
            }
        };
        let i = roles_of(&settings.head);
        let mut assign: Vec<(usize, RoleSet)> = vec![(
            i,
            RoleSet::Head(settings.head.name.clone(), settings.head_sensor),
        )];
        if let Some((d, s)) = &settings.wand {
            assign.push((roles_of(d), RoleSet::Wand(d.name.clone(), *s)));
        }
        if let Some(d) = &settings.buttons {
            assign.push((roles_of(d), RoleSet::Buttons(d.name.clone())));
        }
        if let Some(d) = &settings.analogs {
            assign.push((roles_of(d), RoleSet::Analogs(d.name.clone())));
        }
        for (i, role) in assign {
            let roles = &mut by_server[i].1;
            match role {
                RoleSet::Head(n, s) => roles.head = Some((n, s)),
                RoleSet::Wand(n, s) => roles.wand = Some((n, s)),
                RoleSet::Buttons(n) => roles.buttons = Some(n),
                RoleSet::Analogs(n) => roles.analogs = Some(n),
            }
        }
        let feed = TrackerFeed::default();
        let stop = Arc::new(AtomicBool::new(false));
        let mut threads = Vec::new();
        let mut servers = Vec::new();
        let mut data_ports = Vec::new();
        // Buttons and analogs may come from different servers: one stream, one client.
        let controls_sender = Arc::new(Mutex::new(None));
        for ((host, port), roles) in by_server {
            let data_port = Arc::new(AtomicU32::new(0));
            data_ports.push(data_port.clone());
            let server = ServerLink {
                host: host.clone(),
                port,
                roles,
                retry: settings.retry,
                idle: settings.idle,
                allowed: settings
                    .allowed_senders
                    .iter()
                    .map(|ip| ip.to_canonical())
                    .collect(),
                feed: feed.clone(),
                stop: stop.clone(),
                data_port,
                controls_sender: controls_sender.clone(),
            };
            servers.push(format!("{host}:{port}"));
            let thread = std::thread::Builder::new()
                .name(format!("vrpn-{host}:{port}"))
                .spawn(move || server.run())
                .map_err(|source| TrackingError::Thread { source })?;
            threads.push(thread);
        }
        tracing::info!("VRPN tracking: connecting to {}", servers.join(", "));
        Ok(Self {
            feed,
            stop,
            threads,
            servers,
            data_ports,
        })
    }

    pub fn feed(&self) -> &TrackerFeed {
        &self.feed
    }

    /// The servers, as `host:port`.
    pub fn servers(&self) -> &[String] {
        &self.servers
    }

    /// The UDP port each server's data arrives at now (`None`: not connected), in the order
    /// of [`Self::servers`]; only that server's address may send there.
    pub fn data_ports(&self) -> Vec<Option<u16>> {
        self.data_ports
            .iter()
            .map(|p| {
                u16::try_from(p.load(Ordering::Acquire))
                    .ok()
                    .filter(|&p| p != 0)
            })
            .collect()
    }
}

impl Drop for VrpnClient {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Release);
        for t in self.threads.drain(..) {
            let _ = t.join();
        }
    }
}

enum RoleSet {
    Head(String, i32),
    Wand(String, i32),
    Buttons(String),
    Analogs(String),
}

/// Why a connection attempt or a connection ended.
#[derive(Debug, thiserror::Error)]
enum LinkError {
    #[error("cannot resolve '{0}'")]
    Resolve(String),
    #[error("no answer (is vrpn_server running there?)")]
    NoAnswer,
    #[error("{0}")]
    Io(#[from] std::io::Error),
    #[error("{0}")]
    Wire(#[from] WireError),
    #[error("the server closed the connection")]
    Closed,
    /// Up, then silent; `after_reports`: reports had come on this connection before.
    #[error("no report for {:.1} s", .silent.as_secs_f64())]
    Idle {
        silent: Duration,
        after_reports: bool,
    },
    #[error("{0} is not in tracking.allowed_senders")]
    NotAllowed(IpAddr),
    #[error("stopped")]
    Stopped,
}

/// One server: connects, reads until the connection ends, waits, connects again.
struct ServerLink {
    host: String,
    port: u16,
    roles: Roles,
    retry: Duration,
    /// No message for this long ends a session whose server reports a tracker.
    idle: Duration,
    allowed: Vec<IpAddr>,
    feed: TrackerFeed,
    stop: Arc<AtomicBool>,
    /// This session's UDP data port (0 between sessions).
    data_port: Arc<AtomicU32>,
    /// The address the client's buttons and analogs are sent as, whichever server reports
    /// them (the first server resolved): they are one stream to the gate.
    controls_sender: Arc<Mutex<Option<SocketAddr>>>,
}

/// Whether a link whose session went silent waits one retry before connecting again. A server
/// that went silent after reporting (it may have restarted and forgotten us), or silent for the
/// first time, is asked again at once; one that answers but never reports, twice in a row
/// (`silent_before`), every retry.
fn wait_after_silence(after_reports: bool, silent_before: bool) -> bool {
    !after_reports && silent_before
}

impl ServerLink {
    fn run(self) {
        let mut absent_log = LogLimiter::default();
        let mut idle_log = LogLimiter::default();
        // The last session was up and ended silent without a single report.
        let mut silent_before = false;
        while !self.stopped() {
            let quiet = std::mem::take(&mut silent_before);
            let outcome = std::panic::catch_unwind(AssertUnwindSafe(|| self.session(quiet)));
            // However the session ended (an early error included), it is not connected now.
            self.data_port.store(0, Ordering::Release);
            match outcome {
                Ok(Err(LinkError::Stopped)) => break,
                // A connection that was up and ended (logged where it ended): try again now.
                Ok(Ok(())) => {
                    absent_log = LogLimiter::default();
                    continue;
                }
                Ok(Err(e @ LinkError::Idle { after_reports, .. })) => {
                    if let Some(held) = idle_log.allow(Instant::now(), LOG_INTERVAL * 5) {
                        tracing::warn!(
                            "VRPN {}:{}: {e}; reconnecting{}",
                            self.host,
                            self.port,
                            held_back(held)
                        );
                    }
                    absent_log = LogLimiter::default();
                    if wait_after_silence(after_reports, quiet) {
                        self.sleep(self.retry);
                    }
                    silent_before = !after_reports;
                    continue;
                }
                Ok(Err(e)) => {
                    if let Some(held) = absent_log.allow(Instant::now(), LOG_INTERVAL * 5) {
                        tracing::warn!(
                            "VRPN {}:{}: {e}; retrying every {:.1} s{}",
                            self.host,
                            self.port,
                            self.retry.as_secs_f32(),
                            held_back(held)
                        );
                    }
                }
                Err(_) => tracing::error!("VRPN {}:{}: the client panicked", self.host, self.port),
            }
            self.sleep(self.retry);
        }
    }

    fn stopped(&self) -> bool {
        self.stop.load(Ordering::Acquire)
    }

    fn sleep(&self, total: Duration) {
        let end = Instant::now() + total;
        while !self.stopped() && Instant::now() < end {
            std::thread::sleep(POLL.min(end.saturating_duration_since(Instant::now())));
        }
    }

    /// The server's address. A name is resolved in a thread of its own, so that a slow DNS
    /// server never keeps this link from honouring the stop flag (the lookup is abandoned).
    fn server_addr(&self) -> Result<SocketAddr, LinkError> {
        let name = format!("{}:{}", self.host, self.port);
        if let Ok(ip) = self.host.parse::<IpAddr>() {
            return Ok(SocketAddr::new(ip, self.port));
        }
        let (tx, rx) = std::sync::mpsc::channel();
        let (host, port) = (self.host.clone(), self.port);
        std::thread::Builder::new()
            .name(format!("vrpn-resolve-{host}"))
            .spawn(move || {
                let found = (host.as_str(), port)
                    .to_socket_addrs()
                    .map(|a| a.collect::<Vec<_>>());
                let _ = tx.send(found);
            })?;
        let mut addrs = loop {
            match rx.recv_timeout(POLL) {
                Ok(Ok(addrs)) => break addrs,
                Ok(Err(_)) | Err(std::sync::mpsc::RecvTimeoutError::Disconnected) => {
                    return Err(LinkError::Resolve(name));
                }
                Err(std::sync::mpsc::RecvTimeoutError::Timeout) if self.stopped() => {
                    return Err(LinkError::Stopped);
                }
                Err(std::sync::mpsc::RecvTimeoutError::Timeout) => {}
            }
        };
        // VRPN servers listen on IPv4 unless built otherwise.
        addrs.sort_by_key(|a| !a.is_ipv4());
        addrs.into_iter().next().ok_or(LinkError::Resolve(name))
    }

    /// One connection, from the request to its end; `quiet`: the last one was up but never reported (do not
    /// announce every retry of a server that answers and keeps silent).
    fn session(&self, quiet: bool) -> Result<(), LinkError> {
        let server = self.server_addr()?;
        let server_ip = server.ip().to_canonical();
        if !self.allowed.is_empty() && !self.allowed.contains(&server_ip) {
            return Err(LinkError::NotAllowed(server_ip));
        }
        let unspecified = if server.is_ipv4() {
            IpAddr::V4(Ipv4Addr::UNSPECIFIED)
        } else {
            IpAddr::V6(Ipv6Addr::UNSPECIFIED)
        };
        let listener = TcpListener::bind((unspecified, 0))?;
        listener.set_nonblocking(true)?;
        let callback_port = listener.local_addr()?.port();
        // The address the server can reach us at: the one the route to it leaves from.
        let lob = UdpSocket::bind((unspecified, 0))?;
        lob.connect(server)?;
        let my_ip = lob.local_addr()?.ip();
        let request = format!("{my_ip} {callback_port}\0");
        lob.send(request.as_bytes())?;
        let deadline = Instant::now() + CALLBACK_WAIT;
        let mut refused_log = LogLimiter::default();
        let mut stream = loop {
            if self.stopped() {
                return Err(LinkError::Stopped);
            }
            match listener.accept() {
                // Only the server calls back; anyone else is turned away.
                Ok((stream, peer)) if peer.ip().to_canonical() == server_ip => break stream,
                Ok((_, peer)) => {
                    self.feed.count(Fate::Refused);
                    if let Some(held) = refused_log.allow(Instant::now(), LOG_INTERVAL) {
                        tracing::warn!(
                            "VRPN {}:{}: refused a callback from {peer} (the server is \
                             {server_ip}){}",
                            self.host,
                            self.port,
                            held_back(held)
                        );
                    }
                }
                Err(e) if e.kind() == ErrorKind::WouldBlock => {
                    if Instant::now() >= deadline {
                        return Err(LinkError::NoAnswer);
                    }
                    std::thread::sleep(Duration::from_millis(5));
                }
                Err(e) => return Err(e.into()),
            }
        };
        drop(listener);
        drop(lob);
        stream.set_nonblocking(false)?;
        stream.set_nodelay(true)?;
        stream.set_read_timeout(Some(POLL))?;
        stream.write_all(&wire::cookie())?;
        let mut cookie = [0u8; wire::COOKIE_SIZE];
        self.read_full(
            &mut stream,
            &mut cookie,
            Some(Instant::now() + COOKIE_WAIT),
            None,
        )?;
        wire::check_cookie(&cookie)?;

        let udp = UdpSocket::bind((unspecified, 0))?;
        udp.set_read_timeout(Some(POLL))?;
        let udp_port = udp.local_addr()?.port();
        self.data_port.store(u32::from(udp_port), Ordering::Release);
        let mut ip = my_ip.to_string().into_bytes();
        ip.push(0);
        let (seconds, microseconds) = now_since_epoch();
        stream.write_all(&wire::frame(
            i32::from(udp_port),
            wire::UDP_DESCRIPTION,
            seconds,
            microseconds,
            &ip,
        ))?;

        if !quiet {
            tracing::info!(
                "VRPN {}:{}: connected ({})",
                self.host,
                self.port,
                self.roles.describe()
            );
        }
        let controls_from = *lock(&self.controls_sender).get_or_insert(server);
        let dispatch = Arc::new(Mutex::new(Dispatch::new(
            self.roles.clone(),
            self.feed.clone(),
            server,
            controls_from,
        )));
        let session_over = Arc::new(AtomicBool::new(false));
        let udp_thread = {
            let dispatch = dispatch.clone();
            let over = session_over.clone();
            let stop = self.stop.clone();
            let feed = self.feed.clone();
            std::thread::Builder::new()
                .name(format!("vrpn-udp-{}", self.port))
                .spawn(move || udp_loop(&udp, server_ip, &dispatch, &over, &stop, &feed))?
        };
        let result = self.tcp_loop(&mut stream, &dispatch);
        session_over.store(true, Ordering::Release);
        self.data_port.store(0, Ordering::Release);
        let _ = udp_thread.join();
        match result {
            Err(e @ (LinkError::Stopped | LinkError::Idle { .. })) => Err(e),
            Err(e) => {
                tracing::warn!(
                    "VRPN {}:{}: connection lost ({e}); reconnecting",
                    self.host,
                    self.port
                );
                Ok(())
            }
            Ok(()) => Ok(()),
        }
    }

    fn tcp_loop(
        &self,
        stream: &mut TcpStream,
        dispatch: &Mutex<Dispatch>,
    ) -> Result<(), LinkError> {
        let mut head = [0u8; HEADER_SIZE];
        let mut payload = Vec::new();
        // Trackers report at their rate; a server of buttons alone may be silent for hours.
        let idle = (self.roles.head.is_some() || self.roles.wand.is_some()).then_some(self.idle);
        let watch = idle.map(|limit| (dispatch, limit));
        loop {
            self.read_full(stream, &mut head, None, watch)?;
            let arrived = Instant::now();
            let header = wire::parse_header(&head)?;
            payload.resize(header.padded_payload_len(), 0);
            self.read_full(stream, &mut payload, None, watch)?;
            let body = &payload[..header.payload_len()];
            lock(dispatch).message(&header, body, arrived, Channel::Tcp);
        }
    }

    /// Fills `buf`, waking every [`POLL`] to honour the stop flag, the deadline and, where
    /// `idle` gives a limit, the time since the session's newest message (either channel).
    fn read_full(
        &self,
        stream: &mut TcpStream,
        buf: &mut [u8],
        deadline: Option<Instant>,
        idle: Option<(&Mutex<Dispatch>, Duration)>,
    ) -> Result<(), LinkError> {
        let mut at = 0;
        while at < buf.len() {
            if self.stopped() {
                return Err(LinkError::Stopped);
            }
            if deadline.is_some_and(|d| Instant::now() >= d) {
                return Err(LinkError::NoAnswer);
            }
            if let Some((dispatch, limit)) = idle {
                let (silent, after_reports) = {
                    let d = lock(dispatch);
                    (d.heard.elapsed(), d.reported)
                };
                if silent > limit {
                    return Err(LinkError::Idle {
                        silent,
                        after_reports,
                    });
                }
            }
            match stream.read(&mut buf[at..]) {
                Ok(0) => return Err(LinkError::Closed),
                Ok(n) => at += n,
                Err(e)
                    if matches!(
                        e.kind(),
                        ErrorKind::WouldBlock | ErrorKind::TimedOut | ErrorKind::Interrupted
                    ) => {}
                Err(e) => return Err(e.into()),
            }
        }
        Ok(())
    }
}

/// Where a message came: the TCP connection the server called back on, or UDP.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Channel {
    Tcp,
    Udp,
}

/// Reads the session's UDP channel: datagrams only from the server's address, and from the
/// first port it sends from (its data socket); anything else is refused and counted.
fn udp_loop(
    udp: &UdpSocket,
    server_ip: IpAddr,
    dispatch: &Mutex<Dispatch>,
    over: &AtomicBool,
    stop: &AtomicBool,
    feed: &TrackerFeed,
) {
    let mut buf = vec![0u8; 65_536];
    let mut error_log = LogLimiter::default();
    let mut refused_log = LogLimiter::default();
    let mut server_port: Option<u16> = None;
    while !over.load(Ordering::Acquire) && !stop.load(Ordering::Acquire) {
        match udp.recv_from(&mut buf) {
            Ok((n, from)) => {
                let arrived = Instant::now();
                // The address first: only the server's first datagram fixes the port.
                let from_server = from.ip().to_canonical() == server_ip;
                let port = match server_port {
                    Some(p) => p,
                    None if from_server => *server_port.insert(from.port()),
                    None => 0,
                };
                if !from_server || from.port() != port {
                    feed.count(Fate::Refused);
                    if let Some(held) = refused_log.allow(arrived, LOG_INTERVAL) {
                        tracing::warn!(
                            "VRPN: refused a datagram from {from} (the server sends from \
                             {server_ip}:{port}){}",
                            held_back(held)
                        );
                    }
                    continue;
                }
                let (messages, error) = wire::split_datagram(&buf[..n]);
                let mut d = lock(dispatch);
                for (header, payload) in messages {
                    d.message(&header, payload, arrived, Channel::Udp);
                }
                if let Some(e) = error {
                    d.bad(Fate::Malformed, &e.to_string(), arrived);
                }
            }
            Err(e)
                if matches!(
                    e.kind(),
                    ErrorKind::WouldBlock | ErrorKind::TimedOut | ErrorKind::Interrupted
                ) => {}
            Err(e) => {
                feed.count_socket_error();
                if let Some(held) = error_log.allow(Instant::now(), LOG_INTERVAL) {
                    tracing::warn!("VRPN: UDP socket error: {e}{}", held_back(held));
                }
                std::thread::sleep(Duration::from_millis(10));
            }
        }
    }
}

fn lock<T>(m: &Mutex<T>) -> std::sync::MutexGuard<'_, T> {
    m.lock().unwrap_or_else(std::sync::PoisonError::into_inner)
}

fn now_since_epoch() -> (u32, u32) {
    let t = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .unwrap_or_default();
    (t.as_secs() as u32, t.subsec_micros())
}

/// Turns one connection's messages into feed updates: remembers the server's sender and type
/// names, and publishes what the configured devices report.
struct Dispatch {
    roles: Roles,
    feed: TrackerFeed,
    server: SocketAddr,
    /// The sender buttons and analogs are counted as (one for the whole client).
    controls_from: SocketAddr,
    senders: HashMap<i32, String>,
    types: HashMap<i32, String>,
    head_seq: u64,
    wand_seq: u64,
    bad_log: LogLimiter,
    /// When the server's newest message arrived (or the session began).
    heard: Instant,
    /// A report was accepted on this connection.
    reported: bool,
}

impl Dispatch {
    fn new(roles: Roles, feed: TrackerFeed, server: SocketAddr, controls_from: SocketAddr) -> Self {
        Self {
            roles,
            feed,
            server,
            controls_from,
            senders: HashMap::new(),
            types: HashMap::new(),
            head_seq: 0,
            wand_seq: 0,
            bad_log: LogLimiter::default(),
            heard: Instant::now(),
            reported: false,
        }
    }

    fn bad(&mut self, fate: Fate, why: &str, now: Instant) {
        self.feed.count(fate);
        if let Some(held) = self.bad_log.allow(now, LOG_INTERVAL) {
            tracing::warn!(
                "VRPN {}: dropped a message: {why}{}",
                self.server,
                held_back(held)
            );
        }
    }

    fn message(&mut self, header: &Header, payload: &[u8], arrived: Instant, via: Channel) {
        self.heard = arrived;
        match header.kind {
            wire::SENDER_DESCRIPTION | wire::TYPE_DESCRIPTION => {
                // Names come from the server's own connection, once per id: a datagram cannot
                // rename an id to steer another device's reports into the head.
                if via == Channel::Udp {
                    self.bad(Fate::Refused, "a name description over UDP", arrived);
                    return;
                }
                let map = if header.kind == wire::SENDER_DESCRIPTION {
                    &mut self.senders
                } else {
                    &mut self.types
                };
                match wire::parse_name(payload) {
                    Ok(name) if map.get(&header.sender).is_some_and(|n| *n != name) => {
                        let why = format!(
                            "id {} is '{}' already, not '{name}'",
                            header.sender, map[&header.sender]
                        );
                        self.bad(Fate::Refused, &why, arrived);
                    }
                    Ok(name) if map.len() < wire::MAX_IDS || map.contains_key(&header.sender) => {
                        map.insert(header.sender, name);
                    }
                    Ok(_) => self.bad(Fate::Refused, "more names than the budget", arrived),
                    Err(e) => self.bad(Fate::Malformed, &e.to_string(), arrived),
                }
            }
            kind if kind < 0 => {} // UDP and log descriptions, disconnect marks: nothing to do
            kind => {
                let (Some(kind_name), Some(sender)) =
                    (self.types.get(&kind), self.senders.get(&header.sender))
                else {
                    self.feed.count(Fate::Ignored);
                    return;
                };
                let fate = match kind_name.as_str() {
                    wire::TRACKER_POS_QUAT => {
                        // The server's clock when it sent the report.
                        let sent =
                            f64::from(header.seconds) + f64::from(header.microseconds) * 1e-6;
                        self.tracker(sender.clone(), payload, arrived, SentAt::Seconds(sent))
                    }
                    wire::BUTTON_CHANGE | wire::BUTTON_STATES
                        if self.roles.buttons.as_ref() == Some(sender) =>
                    {
                        self.buttons(kind_name == wire::BUTTON_STATES, payload, arrived)
                    }
                    wire::ANALOG_CHANNEL if self.roles.analogs.as_ref() == Some(sender) => {
                        match wire::parse_analog(payload) {
                            Ok(values) => {
                                self.feed.update_controls(self.controls_from, arrived, |c| {
                                    c.set_analogs(values);
                                });
                                Ok(())
                            }
                            Err(e) => Err((Fate::Malformed, e.to_string())),
                        }
                    }
                    _ => {
                        self.feed.count(Fate::Ignored);
                        return;
                    }
                };
                match fate {
                    Ok(()) => {
                        self.reported = true;
                        self.feed.count(Fate::Accepted);
                    }
                    Err((fate, why)) => self.bad(fate, &why, arrived),
                }
            }
        }
    }

    fn tracker(
        &mut self,
        sender: String,
        payload: &[u8],
        arrived: Instant,
        sent: SentAt,
    ) -> Result<(), (Fate, String)> {
        let report = wire::parse_pos_quat(payload).map_err(|e| (Fate::Malformed, e.to_string()))?;
        let is = |role: &Option<(String, i32)>| {
            role.as_ref()
                .is_some_and(|(n, s)| *n == sender && *s == report.sensor)
        };
        let head = is(&self.roles.head);
        let wand = is(&self.roles.wand);
        if !head && !wand {
            return Ok(()); // another sensor: counted as accepted data, used by nobody
        }
        let numbers = report.position.iter().chain(&report.quat_xyzw);
        if numbers
            .clone()
            .any(|v| !v.is_finite() || v.abs() > MAX_ABS_NUMBER)
        {
            return Err((
                Fate::NonFinite,
                format!("sensor {} reported {:?}", report.sensor, report),
            ));
        }
        let [x, y, z] = report.position.map(|v| v as f32);
        let [qx, qy, qz, qw] = report.quat_xyzw.map(|v| v as f32);
        let mut sample = TrackerSample {
            seq: 0,
            arrived,
            stored: arrived,
            position: Some(Vec3::new(x, y, z)),
            orientation: Some(TrackedOrientation::Tracker(Quat::from_xyzw(qx, qy, qz, qw))),
            tracked: None,
            sender: self.server,
            sent: Some(sent),
            jumped: false,
        };
        if head {
            self.head_seq += 1;
            sample.seq = self.head_seq;
            sample.stored = Instant::now();
            self.feed.publish_head(sample);
        }
        if wand {
            self.wand_seq += 1;
            sample.seq = self.wand_seq;
            sample.stored = Instant::now();
            self.feed.publish_wand(sample);
        }
        Ok(())
    }

    fn buttons(
        &mut self,
        all: bool,
        payload: &[u8],
        arrived: Instant,
    ) -> Result<(), (Fate, String)> {
        if all {
            let states =
                wire::parse_button_states(payload).map_err(|e| (Fate::Malformed, e.to_string()))?;
            self.feed.update_controls(self.controls_from, arrived, |c| {
                for (i, down) in states.iter().enumerate() {
                    c.set_button(i, *down);
                }
            });
        } else {
            let (button, down) =
                wire::parse_button_change(payload).map_err(|e| (Fate::Malformed, e.to_string()))?;
            if !(0..wire::MAX_WIRE_BUTTONS as i32).contains(&button) {
                return Err((Fate::Malformed, format!("button number {button}")));
            }
            self.feed.update_controls(self.controls_from, arrived, |c| {
                c.set_button(button as usize, down);
            });
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_silent_server_is_asked_again_at_once_unless_it_never_reports() {
        // Gone silent after reports, however often it happened before: at once.
        assert!(!wait_after_silence(true, false));
        assert!(!wait_after_silence(true, true));
        // Silent from the start: at once the first time, then every retry.
        assert!(!wait_after_silence(false, false));
        assert!(wait_after_silence(false, true));
    }

    #[test]
    fn device_names_as_vrpn_users_write_them() {
        let d: VrpnDevice = "Tracker0@localhost".parse().expect("plain");
        assert_eq!(
            (d.name.as_str(), d.host.as_str(), d.port),
            ("Tracker0", "localhost", 3883)
        );
        let d: VrpnDevice = "DTrack@10.0.0.5:3884".parse().expect("port");
        assert_eq!((d.host.as_str(), d.port), ("10.0.0.5", 3884));
        let d: VrpnDevice = "Head@tcp://tracker:4000".parse().expect("tcp://");
        assert_eq!((d.host.as_str(), d.port), ("tracker", 4000));
        let d: VrpnDevice = "T@[::1]:5000".parse().expect("v6");
        assert_eq!((d.host.as_str(), d.port), ("::1", 5000));
        assert_eq!(d.to_string(), "T@[::1]:5000");
        for bad in [
            "Tracker0",
            "@host",
            "T@",
            "T@host:0",
            "T@host:99999",
            "T@[::1",
            "A B@h",
        ] {
            assert!(bad.parse::<VrpnDevice>().is_err(), "{bad}");
        }
    }

    fn dispatch() -> (Dispatch, TrackerFeed) {
        let feed = TrackerFeed::default();
        let roles = Roles {
            head: Some(("Tracker0".into(), 1)),
            wand: Some(("Tracker0".into(), 2)),
            buttons: Some("Button0".into()),
            analogs: Some("Button0".into()),
        };
        let server = SocketAddr::from(([127, 0, 0, 1], 3883));
        (Dispatch::new(roles, feed.clone(), server, server), feed)
    }

    fn send(d: &mut Dispatch, sender: i32, kind: i32, payload: &[u8]) {
        let bytes = wire::frame(sender, kind, 0, 0, payload);
        let (messages, error) = wire::split_datagram(&bytes);
        assert!(error.is_none());
        for (h, p) in messages {
            d.message(&h, p, Instant::now(), Channel::Tcp);
        }
    }

    #[test]
    fn sensors_buttons_and_analogs_reach_the_feed_by_name() {
        let (mut d, feed) = dispatch();
        send(
            &mut d,
            0,
            wire::SENDER_DESCRIPTION,
            &wire::name_payload("Tracker0"),
        );
        send(
            &mut d,
            1,
            wire::SENDER_DESCRIPTION,
            &wire::name_payload("Button0"),
        );
        send(
            &mut d,
            5,
            wire::TYPE_DESCRIPTION,
            &wire::name_payload(wire::TRACKER_POS_QUAT),
        );
        send(
            &mut d,
            6,
            wire::TYPE_DESCRIPTION,
            &wire::name_payload(wire::BUTTON_CHANGE),
        );
        send(
            &mut d,
            7,
            wire::TYPE_DESCRIPTION,
            &wire::name_payload(wire::ANALOG_CHANNEL),
        );
        let report = |sensor, x| {
            wire::pos_quat_payload(&wire::PosQuat {
                sensor,
                position: [x, 1.5, -0.25],
                quat_xyzw: [0.0, 0.0, 0.0, 1.0],
            })
        };
        send(&mut d, 0, 5, &report(0, 9.0)); // another sensor
        send(&mut d, 0, 5, &report(1, 0.5));
        send(&mut d, 0, 5, &report(2, -0.5));
        let head = feed.try_latest().expect("head");
        assert_eq!(head.position, Some(Vec3::new(0.5, 1.5, -0.25)));
        let wand = feed.try_wand().expect("wand");
        assert_eq!(wand.position, Some(Vec3::new(-0.5, 1.5, -0.25)));
        let mut change = 3i32.to_be_bytes().to_vec();
        change.extend(1i32.to_be_bytes());
        send(&mut d, 1, 6, &change);
        let mut analog = 2.0f64.to_be_bytes().to_vec();
        analog.extend(0.5f64.to_be_bytes());
        analog.extend((-1.0f64).to_be_bytes());
        send(&mut d, 1, 7, &analog);
        let c = feed.try_controls().expect("controls");
        assert!(c.is_held(3));
        assert_eq!(c.presses[3], 1);
        assert_eq!(c.analogs, vec![0.5, -1.0]);
        // Not finite: refused, the head stays.
        send(&mut d, 0, 5, &report(1, f64::NAN));
        assert_eq!(feed.try_latest().expect("head").position, head.position);
        let counts = feed.counters();
        assert_eq!(counts.non_finite, 1);
        assert!(counts.adds_up(), "{counts:?}");
    }
}
