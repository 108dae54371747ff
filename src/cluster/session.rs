//! The master's and a node's side of the cluster protocol: start-up check, per-frame
//! broadcast, barrier before present, and lost nodes (see the module above for the order).

use std::time::{Duration, Instant};

use super::messages::{FrameState, Identity, Message, NodeFigures};
use super::{ClusterError, Transport};
use crate::config::NodeLoss;

/// How long a wait sleeps between polls once the first millisecond has passed (short waits
/// spin with `yield_now`, so a barrier on loopback costs microseconds, not a sleep).
const POLL_SLEEP: Duration = Duration::from_micros(100);
const SPIN: Duration = Duration::from_millis(1);

/// Polls `poll` until it yields a value or `timeout` passes.
fn wait_for<T>(
    timeout: Duration,
    mut poll: impl FnMut() -> Result<Option<T>, ClusterError>,
) -> Result<Option<T>, ClusterError> {
    let start = Instant::now();
    loop {
        if let Some(v) = poll()? {
            return Ok(Some(v));
        }
        let waited = start.elapsed();
        if waited >= timeout {
            return Ok(None);
        }
        if waited < SPIN {
            std::thread::yield_now();
        } else {
            std::thread::sleep(POLL_SLEEP.min(timeout - waited));
        }
    }
}

/// How long the cluster waits, and what it does when a node is lost.
#[derive(Debug, Clone, Copy)]
pub struct Timeouts {
    pub frame: Duration,
    pub startup: Duration,
    pub on_loss: NodeLoss,
}

impl Timeouts {
    pub fn from_settings(s: &crate::config::ClusterSection) -> Self {
        Self {
            frame: Duration::from_millis(u64::from(s.timeout_ms)),
            startup: Duration::from_secs(u64::from(s.startup_timeout_s)),
            on_loss: s.on_node_loss,
        }
    }
}

/// A render node as the master sees it.
#[derive(Debug, Clone)]
pub struct NodeStatus {
    pub rank: usize,
    pub host: String,
    /// The walls it drives (names).
    pub walls: Vec<String>,
    /// `Some(why)` once lost.
    pub lost: Option<String>,
    /// Its latest figures.
    pub figures: NodeFigures,
}

impl NodeStatus {
    /// "node 2 (wall-pc-2, walls right)".
    pub fn describe(&self) -> String {
        format!(
            "node {} ({}, wall{} {})",
            self.rank,
            if self.host.is_empty() {
                "host unknown"
            } else {
                &self.host
            },
            if self.walls.len() == 1 { "" } else { "s" },
            if self.walls.is_empty() {
                "none".to_owned()
            } else {
                self.walls.join(", ")
            }
        )
    }
}

/// Something the master noticed in a frame.
#[derive(Debug, Clone, PartialEq)]
pub enum NodeEvent {
    /// The node was lost; the text names it, its walls, and why.
    Lost { rank: usize, message: String },
}

/// The master's figures of the latest frame.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct MasterFigures {
    /// Sending the settings (when changed) and the frame state to every node, ms.
    pub broadcast_ms: f64,
    /// From the master's own walls submitted until every live node had reported, ms.
    pub barrier_ms: f64,
    /// Frame number of the latest barrier passed.
    pub frame: u64,
}

/// The master's side (rank 0).
pub struct Master<T: Transport> {
    transport: T,
    nodes: Vec<NodeStatus>,
    timeouts: Timeouts,
    send_buf: Vec<u8>,
    /// The settings message of the latest generation, encoded once for every node.
    settings_buf: Vec<u8>,
    receive_buf: Vec<u8>,
    /// No barrier passed yet: the first frame compiles shaders and gets the start-up timeout.
    first_frame: bool,
    /// Every node has been told to stop.
    stopped: bool,
    pub figures: MasterFigures,
}

impl<T: Transport> Master<T> {
    /// Waits for every node's start-up report, compares what each loaded with `identity`,
    /// and starts the cluster, or refuses it (every node told why) with the first
    /// difference. `walls[rank]` names the walls each rank drives.
    pub fn start(
        mut transport: T,
        identity: &Identity,
        walls: Vec<Vec<String>>,
        timeouts: Timeouts,
    ) -> Result<Self, ClusterError> {
        let size = transport.size();
        if size < 2 {
            return Err(ClusterError::TooFewProcesses(size));
        }
        let mut nodes: Vec<NodeStatus> = (0..size)
            .map(|rank| NodeStatus {
                rank,
                host: String::new(),
                walls: walls.get(rank).cloned().unwrap_or_default(),
                lost: None,
                figures: NodeFigures::default(),
            })
            .collect();
        nodes[0].host = identity.host.clone();
        let mut buf = Vec::new();
        let deadline = Instant::now() + timeouts.startup;
        let mut refusal = None;
        // A node that never reported may be alive and slow: it is left out of the stop.
        let mut silent = None;
        for (rank, node) in nodes.iter_mut().enumerate().skip(1) {
            let left = deadline.saturating_duration_since(Instant::now());
            let got = wait_for(left, || {
                Ok(transport
                    .try_receive(rank, &mut buf)?
                    .then(|| Message::decode(&buf)))
            });
            let hello = match got {
                Ok(Some(Ok(Message::Hello(id)))) => id,
                Ok(None) => {
                    silent = Some(rank);
                    refusal = Some(ClusterError::NoHello {
                        node: rank,
                        seconds: timeouts.startup.as_secs_f64(),
                    });
                    break;
                }
                Err(e) | Ok(Some(Err(e))) => {
                    refusal = Some(ClusterError::Mismatch {
                        node: rank,
                        host: "host unknown".into(),
                        what: e.to_string(),
                    });
                    break;
                }
                Ok(Some(Ok(other))) => {
                    refusal = Some(ClusterError::Unexpected {
                        from: format!("node {rank}"),
                        expected: "its start-up report",
                        got: format!("{other:?}"),
                    });
                    break;
                }
            };
            node.host = hello.host.clone();
            if let Some(what) = difference(identity, &hello) {
                refusal = Some(ClusterError::Mismatch {
                    node: rank,
                    host: hello.host,
                    what,
                });
                break;
            }
        }
        let mut master = Master {
            transport,
            nodes,
            timeouts,
            send_buf: Vec::new(),
            settings_buf: Vec::new(),
            receive_buf: buf,
            first_frame: true,
            stopped: false,
            figures: MasterFigures::default(),
        };
        if let Some(e) = refusal {
            if let Some(rank) = silent {
                master.lose(rank, "did not report at start-up");
            }
            master.stop(&format!("the cluster did not start: {e}"));
            return Err(e);
        }
        for rank in 1..size {
            master.send(rank, &Message::Start);
        }
        Ok(master)
    }

    /// Every node, the master included (index = rank).
    pub fn nodes(&self) -> &[NodeStatus] {
        &self.nodes
    }

    /// Sends `message` to `rank`; a node the transport fails to reach is lost.
    fn send(&mut self, rank: usize, message: &Message) -> Option<NodeEvent> {
        message.encode(&mut self.send_buf);
        match self.transport.send(rank, &self.send_buf) {
            Ok(()) => None,
            Err(e) => Some(self.lose(rank, &format!("cannot be reached: {e}"))),
        }
    }

    fn live(&self) -> impl Iterator<Item = usize> + use<'_, T> {
        self.nodes
            .iter()
            .skip(1)
            .filter(|n| n.lost.is_none())
            .map(|n| n.rank)
    }

    /// Sends this frame's settings (when `settings` is given: they changed) and state to every
    /// live node. Nodes that cannot be reached are lost (returned).
    pub fn broadcast(
        &mut self,
        settings: Option<(u64, &str)>,
        state: &FrameState,
    ) -> Vec<NodeEvent> {
        let start = Instant::now();
        let mut events = Vec::new();
        if let Some((generation, toml)) = settings {
            // Encoded once per change (rare), the same bytes for every node.
            Message::Settings {
                generation,
                toml: toml.to_owned(),
            }
            .encode(&mut self.settings_buf);
        }
        Message::Frame(*state).encode(&mut self.send_buf);
        for rank in 1..self.nodes.len() {
            if self.nodes[rank].lost.is_some() {
                continue;
            }
            let mut sent = Ok(());
            if settings.is_some() {
                sent = self.transport.send(rank, &self.settings_buf);
            }
            if sent.is_ok() {
                sent = self.transport.send(rank, &self.send_buf);
            }
            if let Err(e) = sent {
                events.push(self.lose(rank, &format!("cannot be reached: {e}")));
                // `lose` used the send buffer for its stop message.
                Message::Frame(*state).encode(&mut self.send_buf);
            }
        }
        self.figures.broadcast_ms = start.elapsed().as_secs_f64() * 1e3;
        events
    }

    /// Waits until every live node has rendered `frame`, then tells them to present it.
    /// Nodes that do not report in time, leave, or send anything else are lost: returned as
    /// events (and told to stop); with `on_node_loss = "stop"` (`lost_so_far` counts the
    /// broadcast's losses too) the whole cluster stops and this is an error. `slow`: a frame
    /// known to take long (new settings compiling pipelines, a screenshot or a recorded
    /// frame read back), given the start-up timeout.
    pub fn barrier(
        &mut self,
        frame: u64,
        slow: bool,
        mut events: Vec<NodeEvent>,
    ) -> Result<Vec<NodeEvent>, ClusterError> {
        let start = Instant::now();
        let timeout = if self.first_frame || slow {
            self.timeouts.startup
        } else {
            self.timeouts.frame
        };
        for rank in 1..self.nodes.len() {
            if self.nodes[rank].lost.is_some() {
                continue;
            }
            let left = timeout.saturating_sub(start.elapsed());
            let (transport, buf) = (&mut self.transport, &mut self.receive_buf);
            let reply = wait_for(left, || {
                if !transport.try_receive(rank, buf)? {
                    return Ok(None);
                }
                Ok(Some(match Message::decode(buf) {
                    Ok(Message::Rendered { frame: f, figures }) if f == frame => Ok(figures),
                    Ok(Message::Leave { reason }) => Err(format!("left the cluster: {reason}")),
                    Ok(other) => Err(format!("sent {other:?} instead of its frame {frame}")),
                    Err(e) => Err(e.to_string()),
                }))
            });
            match reply {
                Ok(Some(Ok(figures))) => self.nodes[rank].figures = figures,
                Ok(Some(Err(why))) => events.push(self.lose(rank, &why)),
                Err(e) => events.push(self.lose(rank, &format!("cannot be reached: {e}"))),
                Ok(None) => events.push(self.lose(
                    rank,
                    &format!(
                        "did not report frame {frame} within {} ms (died or stalled)",
                        timeout.as_millis()
                    ),
                )),
            }
        }
        self.figures.barrier_ms = start.elapsed().as_secs_f64() * 1e3;
        self.figures.frame = frame;
        self.first_frame = false;
        if !events.is_empty() && self.timeouts.on_loss == NodeLoss::Stop {
            let what = events
                .iter()
                .map(|NodeEvent::Lost { message, .. }| message.clone())
                .collect::<Vec<_>>()
                .join("; ");
            self.stop(&format!("the cluster stops: {what}"));
            return Err(ClusterError::NodeLostStop(what));
        }
        for rank in 1..self.nodes.len() {
            if self.nodes[rank].lost.is_none()
                && let Some(e) = self.send(rank, &Message::Present { frame })
            {
                events.push(e);
            }
        }
        Ok(events)
    }

    /// Marks `rank` lost, tells it to stop (should it wake up), and stops talking to it.
    fn lose(&mut self, rank: usize, why: &str) -> NodeEvent {
        let message = format!("{} lost: {why}", self.nodes[rank].describe());
        tracing::error!(target: "omnicave::cluster", "{message}");
        Message::Stop {
            reason: format!("dropped by the master: {why}"),
            clean: false,
        }
        .encode(&mut self.send_buf);
        let _ = self.transport.send(rank, &self.send_buf);
        self.transport.abandon(rank);
        self.nodes[rank].lost = Some(why.to_owned());
        NodeEvent::Lost { rank, message }
    }

    /// Tells every live node to stop (quit, or a refused start). A clean stop (no node
    /// lost) waits, at most the frame timeout, for every node's goodbye; a node that does not
    /// answer is abandoned (and MPI is then left without finalizing, which would wait for it).
    pub fn stop(&mut self, reason: &str) {
        if self.stopped {
            return;
        }
        self.stopped = true;
        let clean = self.all_live();
        let live: Vec<usize> = self.live().collect();
        for &rank in &live {
            Message::Stop {
                reason: reason.to_owned(),
                clean,
            }
            .encode(&mut self.send_buf);
            if self.transport.send(rank, &self.send_buf).is_err() {
                self.transport.abandon(rank);
            }
        }
        if !clean {
            return;
        }
        let start = Instant::now();
        for rank in live {
            let left = self.timeouts.frame.saturating_sub(start.elapsed());
            let (transport, buf) = (&mut self.transport, &mut self.receive_buf);
            let bye = wait_for(left, || {
                loop {
                    if !transport.try_receive(rank, buf)? {
                        return Ok(None);
                    }
                    // A frame's report or a goodbye may come first.
                    if let Ok(Message::Bye | Message::Leave { .. }) = Message::decode(buf) {
                        return Ok(Some(()));
                    }
                }
            });
            if !matches!(bye, Ok(Some(()))) {
                tracing::warn!(
                    target: "omnicave::cluster",
                    "{} did not acknowledge the stop",
                    self.nodes[rank].describe()
                );
                self.transport.abandon(rank);
            }
        }
    }

    /// Whether every node is still live.
    pub fn all_live(&self) -> bool {
        self.nodes.iter().all(|n| n.lost.is_none())
    }
}

impl<T: Transport> Drop for Master<T> {
    /// A master that ends without a word (an error, a signal before the first frame) still
    /// tells the nodes, so none waits for it.
    fn drop(&mut self) {
        self.stop("the master ended");
    }
}

/// The first difference between what the master and a node loaded, in words.
fn difference(master: &Identity, node: &Identity) -> Option<String> {
    for (what, a, b) in [
        ("settings (config)", master.config, node.config),
        ("scene", master.scene, node.scene),
        ("sky", master.sky, node.sky),
    ] {
        if a != b {
            return Some(format!(
                "its {what} differs from the master's: {b} on the node, {a} on the master \
                 ({}); every node must load the same config and scene",
                master.host
            ));
        }
    }
    None
}

/// What a node does next.
#[derive(Debug, Clone, PartialEq)]
pub enum NodeStep {
    /// Render this frame (after applying any settings handed over with it).
    Frame(FrameState),
    /// The master said stop, and why.
    Stop(String),
}

/// A render node's side (rank ≥ 1).
pub struct Node<T: Transport> {
    transport: T,
    timeouts: Timeouts,
    send_buf: Vec<u8>,
    receive_buf: Vec<u8>,
    /// When this node last presented (its wait for the next state starts there).
    last_present: Instant,
    first_frame: bool,
    /// The master said stop (or is gone): nothing more is sent to it.
    ended: bool,
    pub figures: NodeFigures,
}

impl<T: Transport> Node<T> {
    /// Reports what this node loaded and waits for the master's verdict.
    pub fn start(
        mut transport: T,
        identity: &Identity,
        timeouts: Timeouts,
    ) -> Result<Self, ClusterError> {
        let mut send_buf = Vec::new();
        Message::Hello(identity.clone()).encode(&mut send_buf);
        transport.send(0, &send_buf)?;
        let mut node = Node {
            transport,
            timeouts,
            send_buf,
            receive_buf: Vec::new(),
            last_present: Instant::now(),
            first_frame: true,
            ended: false,
            figures: NodeFigures::default(),
        };
        // The master waits up to the start-up timeout for the slowest node, then answers.
        match node.receive(timeouts.startup * 2)? {
            Message::Start => Ok(node),
            Message::Stop { reason, clean } => {
                node.stopped(clean);
                Err(ClusterError::Refused(reason))
            }
            other => Err(ClusterError::Unexpected {
                from: "the master".into(),
                expected: "start or stop",
                got: format!("{other:?}"),
            }),
        }
    }

    fn receive(&mut self, timeout: Duration) -> Result<Message, ClusterError> {
        let (transport, buf) = (&mut self.transport, &mut self.receive_buf);
        let got = wait_for(timeout, || Ok(transport.try_receive(0, buf)?.then_some(())));
        match got {
            Ok(Some(())) => Message::decode(&self.receive_buf),
            Ok(None) => {
                self.master_gone();
                Err(ClusterError::MasterLost {
                    seconds: timeout.as_secs_f64(),
                })
            }
            Err(e) => {
                self.master_gone();
                Err(e)
            }
        }
    }

    /// The master is gone: nothing more goes to it, and MPI is not finalized (that would
    /// wait for it).
    fn master_gone(&mut self) {
        self.ended = true;
        self.transport.abandon(0);
    }

    /// The master said stop: a clean stop is acknowledged (both then finalize MPI); after
    /// a lost node, nobody finalizes.
    fn stopped(&mut self, clean: bool) {
        if clean {
            Message::Bye.encode(&mut self.send_buf);
            if self.transport.send(0, &self.send_buf).is_err() {
                self.transport.abandon(0);
            }
        } else {
            self.transport.abandon(0);
        }
        self.ended = true;
    }

    fn frame_timeout(&self, slow: bool) -> Duration {
        if self.first_frame || slow {
            self.timeouts.startup * 2
        } else {
            // The master's own frame (input, panel, its walls) plus its wait for the others.
            self.timeouts.frame * 2
        }
    }

    /// Waits for the next frame, handing each settings message that comes first to
    /// `apply_settings(generation, toml)`.
    pub fn next_frame(
        &mut self,
        mut apply_settings: impl FnMut(u64, &str),
    ) -> Result<NodeStep, ClusterError> {
        let deadline = Instant::now() + self.frame_timeout(false);
        loop {
            let left = deadline.saturating_duration_since(Instant::now());
            match self.receive(left)? {
                Message::Settings { generation, toml } => apply_settings(generation, &toml),
                Message::Frame(state) => {
                    self.figures.state_wait_ms =
                        (self.last_present.elapsed().as_secs_f64() * 1e3) as f32;
                    return Ok(NodeStep::Frame(state));
                }
                Message::Stop { reason, clean } => {
                    self.stopped(clean);
                    return Ok(NodeStep::Stop(reason));
                }
                other => {
                    return Err(ClusterError::Unexpected {
                        from: "the master".into(),
                        expected: "settings or a frame",
                        got: format!("{other:?}"),
                    });
                }
            }
        }
    }

    /// Reports `frame` rendered (`render_ms` of CPU to record and submit it) and waits for
    /// the master's "present": `None` to present, or the master's reason to stop. `slow`:
    /// a frame known to take long (see [`Master::barrier`]).
    pub fn barrier(
        &mut self,
        frame: u64,
        render_ms: f64,
        slow: bool,
    ) -> Result<Option<String>, ClusterError> {
        self.figures.render_ms = render_ms as f32;
        Message::Rendered {
            frame,
            figures: self.figures,
        }
        .encode(&mut self.send_buf);
        self.transport.send(0, &self.send_buf)?;
        let start = Instant::now();
        let timeout = self.frame_timeout(slow);
        let answer = match self.receive(timeout)? {
            Message::Present { frame: f } if f == frame => None,
            Message::Stop { reason, clean } => {
                self.stopped(clean);
                Some(reason)
            }
            other => {
                return Err(ClusterError::Unexpected {
                    from: "the master".into(),
                    expected: "present",
                    got: format!("{other:?}"),
                });
            }
        };
        self.figures.barrier_ms = (start.elapsed().as_secs_f64() * 1e3) as f32;
        self.last_present = Instant::now();
        self.first_frame = false;
        Ok(answer)
    }

    /// This node leaves by itself (window closed, a signal, an error): the master hears why
    /// at once instead of waiting out its timeout, and MPI is not finalized.
    pub fn leave(&mut self, reason: &str) {
        if self.ended {
            return;
        }
        self.ended = true;
        Message::Leave {
            reason: reason.to_owned(),
        }
        .encode(&mut self.send_buf);
        let _ = self.transport.send(0, &self.send_buf);
        self.transport.abandon(0);
    }
}

impl<T: Transport> Drop for Node<T> {
    fn drop(&mut self) {
        self.leave("the node ended");
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cluster::{Digest, MemoryTransport};
    use glam::Vec3;

    fn id(host: &str, scene: u32) -> Identity {
        Identity {
            host: host.into(),
            config: Digest::of(b"config"),
            scene: Digest {
                crc: scene,
                bytes: 10,
            },
            sky: Digest::default(),
        }
    }

    fn timeouts(on_loss: NodeLoss) -> Timeouts {
        Timeouts {
            frame: Duration::from_millis(200),
            startup: Duration::from_millis(500),
            on_loss,
        }
    }

    fn walls() -> Vec<Vec<String>> {
        vec![
            vec!["front".into()],
            vec!["left".into()],
            vec!["right".into()],
        ]
    }

    /// What a test node saw: frames rendered, settings handed over, and why it stopped.
    type NodeRun = Result<(Vec<u64>, Vec<String>, Option<String>), String>;

    /// A node thread that runs `frames` frames and returns the frame numbers it rendered and
    /// the settings it was handed (or stops when told). After its frames it leaves (as a
    /// closed window does), or with `vanish` goes silent (as a killed process).
    fn node_thread(
        t: MemoryTransport,
        identity: Identity,
        frames: usize,
        on_loss: NodeLoss,
        vanish: bool,
    ) -> std::thread::JoinHandle<NodeRun> {
        std::thread::spawn(move || {
            let mut node =
                Node::start(t, &identity, timeouts(on_loss)).map_err(|e| e.to_string())?;
            let (mut seen, mut settings) = (Vec::new(), Vec::new());
            for _ in 0..frames {
                let step = node
                    .next_frame(|g, s| settings.push(format!("{g}:{s}")))
                    .map_err(|e| e.to_string())?;
                let state = match step {
                    NodeStep::Frame(s) => s,
                    NodeStep::Stop(why) => return Ok((seen, settings, Some(why))),
                };
                seen.push(state.frame);
                if let Some(why) = node
                    .barrier(state.frame, 1.0, false)
                    .map_err(|e| e.to_string())?
                {
                    return Ok((seen, settings, Some(why)));
                }
            }
            if vanish {
                std::mem::forget(node);
            }
            Ok((seen, settings, None))
        })
    }

    #[test]
    fn every_node_renders_and_presents_the_masters_frames_in_order() {
        let mut ts = MemoryTransport::cluster(3).into_iter();
        let master_t = ts.next().unwrap();
        let nodes: Vec<_> = ts
            .map(|t| node_thread(t, id("n", 1), 5, NodeLoss::Continue, false))
            .collect();
        let mut master =
            Master::start(master_t, &id("m", 1), walls(), timeouts(NodeLoss::Continue)).unwrap();
        for frame in 10..15 {
            let settings = (frame == 10 || frame == 12).then_some((frame, "x = 1"));
            let state = FrameState {
                frame,
                head_position: Vec3::Y,
                ..Default::default()
            };
            let lost = master.broadcast(settings, &state);
            assert!(master.barrier(frame, false, lost).unwrap().is_empty());
        }
        for n in nodes {
            let (seen, settings, stop) = n.join().unwrap().unwrap();
            assert_eq!(seen, vec![10, 11, 12, 13, 14]);
            assert_eq!(settings, vec!["10:x = 1", "12:x = 1"]);
            assert_eq!(stop, None);
        }
        assert_eq!(master.figures.frame, 14);
        assert!(master.nodes()[1].figures.render_ms == 1.0);
    }

    #[test]
    fn a_node_that_loaded_another_scene_is_refused_by_name() {
        let mut ts = MemoryTransport::cluster(3).into_iter();
        let master_t = ts.next().unwrap();
        let n1 = node_thread(
            ts.next().unwrap(),
            id("pc-1", 1),
            1,
            NodeLoss::Continue,
            false,
        );
        let n2 = node_thread(
            ts.next().unwrap(),
            id("pc-2", 2),
            1,
            NodeLoss::Continue,
            false,
        );
        let err = Master::start(master_t, &id("m", 1), walls(), timeouts(NodeLoss::Continue))
            .err()
            .unwrap()
            .to_string();
        assert!(
            err.contains("node 2 (pc-2)") && err.contains("scene differs"),
            "{err}"
        );
        // Both nodes are told, and end (no hang).
        for n in [n1, n2] {
            let e = n.join().unwrap().unwrap_err();
            assert!(
                e.contains("refused by the master") && e.contains("node 2"),
                "{e}"
            );
        }
    }

    #[test]
    fn a_node_that_never_reports_is_named_at_start_up() {
        let mut ts = MemoryTransport::cluster(3).into_iter();
        let master_t = ts.next().unwrap();
        let n1 = node_thread(
            ts.next().unwrap(),
            id("pc-1", 1),
            1,
            NodeLoss::Continue,
            false,
        );
        let _silent = ts.next().unwrap();
        let err = Master::start(master_t, &id("m", 1), walls(), timeouts(NodeLoss::Continue))
            .err()
            .unwrap()
            .to_string();
        assert!(err.contains("node 2 did not report"), "{err}");
        assert!(n1.join().unwrap().is_err());
    }

    #[test]
    fn a_dead_node_is_reported_and_the_others_go_on_or_all_stop() {
        for on_loss in [NodeLoss::Continue, NodeLoss::Stop] {
            let mut ts = MemoryTransport::cluster(3).into_iter();
            let master_t = ts.next().unwrap();
            let n1 = node_thread(ts.next().unwrap(), id("pc-1", 1), 6, on_loss, false);
            // Node 2 renders two frames, then goes silent.
            let n2 = node_thread(ts.next().unwrap(), id("pc-2", 1), 2, on_loss, true);
            let mut master =
                Master::start(master_t, &id("m", 1), walls(), timeouts(on_loss)).unwrap();
            let mut lost_at = None;
            let mut stopped = None;
            for frame in 0..6 {
                let lost = master.broadcast(
                    None,
                    &FrameState {
                        frame,
                        ..Default::default()
                    },
                );
                let started = Instant::now();
                match master.barrier(frame, false, lost) {
                    Ok(events) => {
                        if let Some(NodeEvent::Lost { rank, message }) = events.first() {
                            assert_eq!(*rank, 2);
                            assert!(
                                message.contains("node 2 (pc-2, wall right) lost"),
                                "{message}"
                            );
                            // Reported within the timeout (plus scheduling slack).
                            assert!(started.elapsed() < Duration::from_millis(600));
                            lost_at = Some(frame);
                        }
                    }
                    Err(e) => {
                        stopped = Some(e.to_string());
                        break;
                    }
                }
            }
            n2.join().unwrap().unwrap();
            let (seen, _, stop) = n1.join().unwrap().unwrap();
            match on_loss {
                NodeLoss::Continue => {
                    assert_eq!(lost_at, Some(2));
                    assert_eq!(seen, vec![0, 1, 2, 3, 4, 5], "node 1 goes on");
                    assert!(master.nodes()[2].lost.is_some());
                }
                NodeLoss::Stop => {
                    let e = stopped.unwrap();
                    assert!(
                        e.contains("node 2") && e.contains("stopping the cluster"),
                        "{e}"
                    );
                    assert_eq!(seen, vec![0, 1, 2]);
                    assert!(stop.unwrap().contains("node 2"));
                }
            }
        }
    }

    #[test]
    fn a_node_whose_master_is_gone_ends_instead_of_hanging() {
        let mut ts = MemoryTransport::cluster(2).into_iter();
        let master_t = ts.next().unwrap();
        let n1 = node_thread(
            ts.next().unwrap(),
            id("pc-1", 1),
            5,
            NodeLoss::Continue,
            false,
        );
        let mut master =
            Master::start(master_t, &id("m", 1), walls(), timeouts(NodeLoss::Continue)).unwrap();
        let lost = master.broadcast(None, &FrameState::default());
        master.barrier(0, false, lost).unwrap();
        // Gone without a word (as a killed process): its channels stay open, silent.
        std::mem::forget(master);
        let e = n1.join().unwrap().unwrap_err();
        assert!(e.contains("the master did not answer"), "{e}");
    }

    #[test]
    fn a_node_that_leaves_is_reported_at_once_and_a_clean_stop_is_acknowledged() {
        let mut ts = MemoryTransport::cluster(3).into_iter();
        let master_t = ts.next().unwrap();
        let n1 = node_thread(
            ts.next().unwrap(),
            id("pc-1", 1),
            4,
            NodeLoss::Continue,
            false,
        );
        let n2 = node_thread(
            ts.next().unwrap(),
            id("pc-2", 1),
            1,
            NodeLoss::Continue,
            false,
        );
        let mut master =
            Master::start(master_t, &id("m", 1), walls(), timeouts(NodeLoss::Continue)).unwrap();
        for frame in 0..3 {
            let lost = master.broadcast(
                None,
                &FrameState {
                    frame,
                    ..Default::default()
                },
            );
            let started = Instant::now();
            let events = master.barrier(frame, false, lost).unwrap();
            if frame == 1 {
                let [NodeEvent::Lost { rank: 2, message }] = &events[..] else {
                    panic!("{events:?}");
                };
                assert!(
                    message.contains("left the cluster: the node ended"),
                    "{message}"
                );
                // At once, not after the 200 ms timeout.
                assert!(started.elapsed() < Duration::from_millis(150));
            }
        }
        n2.join().unwrap().unwrap();
        master.stop("done");
        let (seen, _, stop) = n1.join().unwrap().unwrap();
        assert_eq!((seen, stop.as_deref()), (vec![0, 1, 2], Some("done")));
    }
}
