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
    receive_buf: Vec<u8>,
    /// No barrier passed yet: the first frame compiles shaders and gets the start-up timeout.
    first_frame: bool,
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
        for (rank, node) in nodes.iter_mut().enumerate().skip(1) {
            let left = deadline.saturating_duration_since(Instant::now());
            let got = wait_for(left, || {
                Ok(transport
                    .try_receive(rank, &mut buf)?
                    .then(|| Message::decode(&buf)))
            })?;
            let hello = match got {
                None => {
                    refusal = Some(ClusterError::NoHello {
                        node: rank,
                        seconds: timeouts.startup.as_secs_f64(),
                    });
                    break;
                }
                Some(Err(e)) => {
                    refusal = Some(ClusterError::Mismatch {
                        node: rank,
                        host: "host unknown".into(),
                        what: e.to_string(),
                    });
                    break;
                }
                Some(Ok(Message::Hello(id))) => id,
                Some(Ok(other)) => {
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
            receive_buf: buf,
            first_frame: true,
            figures: MasterFigures::default(),
        };
        if let Some(e) = refusal {
            master.stop(&format!("the cluster did not start: {e}"));
            return Err(e);
        }
        for rank in 1..size {
            master.send(rank, &Message::Start)?;
        }
        Ok(master)
    }

    /// Every node, the master included (index = rank).
    pub fn nodes(&self) -> &[NodeStatus] {
        &self.nodes
    }

    fn send(&mut self, rank: usize, message: &Message) -> Result<(), ClusterError> {
        message.encode(&mut self.send_buf);
        self.transport.send(rank, &self.send_buf)
    }

    fn live(&self) -> impl Iterator<Item = usize> + use<'_, T> {
        self.nodes
            .iter()
            .skip(1)
            .filter(|n| n.lost.is_none())
            .map(|n| n.rank)
    }

    /// Sends this frame's settings (when `settings` is given: they changed) and state to every
    /// live node.
    pub fn broadcast(
        &mut self,
        settings: Option<(u64, &str)>,
        state: &FrameState,
    ) -> Result<(), ClusterError> {
        let start = Instant::now();
        for rank in 1..self.nodes.len() {
            if self.nodes[rank].lost.is_some() {
                continue;
            }
            if let Some((generation, toml)) = settings {
                // Encoded per node only when settings change (rare); the frame state below
                // reuses one buffer.
                let message = Message::Settings {
                    generation,
                    toml: toml.to_owned(),
                };
                self.send(rank, &message)?;
            }
            self.send(rank, &Message::Frame(*state))?;
        }
        self.figures.broadcast_ms = start.elapsed().as_secs_f64() * 1e3;
        Ok(())
    }

    /// Waits until every live node has rendered `frame`, then tells them to present it.
    /// Nodes that do not report in time are lost: returned as events (and told to stop);
    /// with `on_node_loss = "stop"` the whole cluster stops and this is an error.
    pub fn barrier(&mut self, frame: u64) -> Result<Vec<NodeEvent>, ClusterError> {
        let start = Instant::now();
        let timeout = if self.first_frame {
            self.timeouts.startup
        } else {
            self.timeouts.frame
        };
        let mut events = Vec::new();
        for rank in 1..self.nodes.len() {
            if self.nodes[rank].lost.is_some() {
                continue;
            }
            let left = timeout.saturating_sub(start.elapsed());
            let (transport, buf) = (&mut self.transport, &mut self.receive_buf);
            let reply = wait_for(left, || {
                loop {
                    if !transport.try_receive(rank, buf)? {
                        return Ok(None);
                    }
                    match Message::decode(buf) {
                        Ok(Message::Rendered { frame: f, figures }) if f == frame => {
                            return Ok(Some(Ok(figures)));
                        }
                        // An older frame's report from a node that was slow: skip it.
                        Ok(Message::Rendered { frame: f, .. }) if f < frame => {}
                        Ok(other) => return Ok(Some(Err(format!("sent {other:?}")))),
                        Err(e) => return Ok(Some(Err(e.to_string()))),
                    }
                }
            })?;
            match reply {
                Some(Ok(figures)) => self.nodes[rank].figures = figures,
                Some(Err(why)) => events.push(self.lose(rank, &why)),
                None => events.push(self.lose(
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
        let live: Vec<usize> = self.live().collect();
        for rank in live {
            self.send(rank, &Message::Present { frame })?;
        }
        Ok(events)
    }

    /// Marks `rank` lost, tells it to stop (should it wake up), and stops talking to it.
    fn lose(&mut self, rank: usize, why: &str) -> NodeEvent {
        let message = format!("{} lost: {why}", self.nodes[rank].describe());
        tracing::error!(target: "omnicave::cluster", "{message}");
        let _ = self.send(
            rank,
            &Message::Stop {
                reason: format!("dropped by the master: {why}"),
                clean: false,
            },
        );
        self.transport.abandon(rank);
        self.nodes[rank].lost = Some(why.to_owned());
        NodeEvent::Lost { rank, message }
    }

    /// Tells every live node to stop (quit, or a refused start).
    pub fn stop(&mut self, reason: &str) {
        let clean = self.nodes.iter().all(|n| n.lost.is_none());
        let live: Vec<usize> = self.live().collect();
        for rank in live {
            let _ = self.send(
                rank,
                &Message::Stop {
                    reason: reason.to_owned(),
                    clean,
                },
            );
        }
    }

    /// Whether every node is still live.
    pub fn all_live(&self) -> bool {
        self.nodes.iter().all(|n| n.lost.is_none())
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
            figures: NodeFigures::default(),
        };
        // The master waits up to the start-up timeout for the slowest node, then answers.
        match node.receive(timeouts.startup * 2)? {
            Message::Start => Ok(node),
            Message::Stop { reason, .. } => Err(ClusterError::Refused(reason)),
            other => Err(ClusterError::Unexpected {
                from: "the master".into(),
                expected: "start or stop",
                got: format!("{other:?}"),
            }),
        }
    }

    fn receive(&mut self, timeout: Duration) -> Result<Message, ClusterError> {
        let (transport, buf) = (&mut self.transport, &mut self.receive_buf);
        let got = wait_for(timeout, || Ok(transport.try_receive(0, buf)?.then_some(())))?;
        match got {
            Some(()) => Message::decode(&self.receive_buf),
            None => {
                // MPI's finalize would wait for the lost master.
                self.transport.abandon(0);
                Err(ClusterError::MasterLost {
                    seconds: timeout.as_secs_f64(),
                })
            }
        }
    }

    fn frame_timeout(&self) -> Duration {
        if self.first_frame {
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
        let timeout = self.frame_timeout();
        loop {
            match self.receive(timeout)? {
                Message::Settings { generation, toml } => apply_settings(generation, &toml),
                Message::Frame(state) => {
                    self.figures.state_wait_ms =
                        (self.last_present.elapsed().as_secs_f64() * 1e3) as f32;
                    return Ok(NodeStep::Frame(state));
                }
                Message::Stop { reason, clean } => {
                    if !clean {
                        self.transport.abandon(0);
                    }
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
    /// the master's "present": `None` to present, or the master's reason to stop.
    pub fn barrier(&mut self, frame: u64, render_ms: f64) -> Result<Option<String>, ClusterError> {
        self.figures.render_ms = render_ms as f32;
        Message::Rendered {
            frame,
            figures: self.figures,
        }
        .encode(&mut self.send_buf);
        self.transport.send(0, &self.send_buf)?;
        let start = Instant::now();
        let timeout = self.frame_timeout();
        let answer = match self.receive(timeout)? {
            Message::Present { frame: f } if f == frame => None,
            Message::Stop { reason, clean } => {
                if !clean {
                    self.transport.abandon(0);
                }
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
    /// the settings it was handed (or stops when told).
    fn node_thread(
        t: MemoryTransport,
        identity: Identity,
        frames: usize,
        on_loss: NodeLoss,
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
                if let Some(why) = node.barrier(state.frame, 1.0).map_err(|e| e.to_string())? {
                    return Ok((seen, settings, Some(why)));
                }
            }
            Ok((seen, settings, None))
        })
    }

    #[test]
    fn every_node_renders_and_presents_the_masters_frames_in_order() {
        let mut ts = MemoryTransport::cluster(3).into_iter();
        let master_t = ts.next().unwrap();
        let nodes: Vec<_> = ts
            .map(|t| node_thread(t, id("n", 1), 5, NodeLoss::Continue))
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
            master.broadcast(settings, &state).unwrap();
            assert!(master.barrier(frame).unwrap().is_empty());
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
        let n1 = node_thread(ts.next().unwrap(), id("pc-1", 1), 1, NodeLoss::Continue);
        let n2 = node_thread(ts.next().unwrap(), id("pc-2", 2), 1, NodeLoss::Continue);
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
        let n1 = node_thread(ts.next().unwrap(), id("pc-1", 1), 1, NodeLoss::Continue);
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
            let n1 = node_thread(ts.next().unwrap(), id("pc-1", 1), 6, on_loss);
            // Node 2 renders two frames, then dies (its transport dropped).
            let n2 = node_thread(ts.next().unwrap(), id("pc-2", 1), 2, on_loss);
            let mut master =
                Master::start(master_t, &id("m", 1), walls(), timeouts(on_loss)).unwrap();
            let mut lost_at = None;
            let mut stopped = None;
            for frame in 0..6 {
                master
                    .broadcast(
                        None,
                        &FrameState {
                            frame,
                            ..Default::default()
                        },
                    )
                    .unwrap();
                let started = Instant::now();
                match master.barrier(frame) {
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
        let n1 = node_thread(ts.next().unwrap(), id("pc-1", 1), 5, NodeLoss::Continue);
        let mut master =
            Master::start(master_t, &id("m", 1), walls(), timeouts(NodeLoss::Continue)).unwrap();
        master.broadcast(None, &FrameState::default()).unwrap();
        master.barrier(0).unwrap();
        drop(master);
        let e = n1.join().unwrap().unwrap_err();
        assert!(e.contains("the master did not answer"), "{e}");
    }
}
