//! The application's side of cluster mode: the state as a frame state and back, and the
//! master's or a node's session as the frame loop runs it.

use std::time::Instant;

use super::state::{AppState, Navigation, WandPose};
pub use crate::cluster::roles::{node_of, walls_by_node};
use crate::cluster::session::Timeouts;
use crate::cluster::settings_text;
use crate::cluster::{
    ClusterError, FrameState, Identity, Master, Node, NodeEvent, NodeStep, Transport,
};
use crate::config::{Config, ConfigFile};

/// The frame state the master broadcasts for `frame` (settings of `settings_generation`).
pub fn frame_state(
    state: &AppState,
    frame: u64,
    settings_generation: u64,
    screenshot: u64,
) -> FrameState {
    FrameState {
        frame,
        settings_generation,
        head_position: state.head_position(),
        tracked_orientation: state.tracked_orientation,
        wand: state.wand.map(|w| (w.position, w.orientation)),
        navigation_position: state.navigation.position,
        navigation_yaw: state.navigation.yaw,
        cave_size: state.cave_size,
        swap_eyes: state.swap_eyes,
        animation_clock: state.animation_clock,
        screenshot,
    }
}

/// Makes `state` the master's for this frame (after [`apply_settings`] of its generation).
pub fn apply_frame_state(state: &mut AppState, s: &FrameState) {
    if state.cave_size != s.cave_size {
        state.set_cave_size(s.cave_size);
    }
    // The master kept the head inside the walls; taken as sent so that both render alike.
    state.settings.head.position = s.head_position.to_array();
    state.tracked_orientation = s.tracked_orientation;
    state.wand = s.wand.map(|(position, orientation)| WandPose {
        position,
        orientation,
    });
    state.navigation = Navigation {
        position: s.navigation_position,
        yaw: s.navigation_yaw,
    };
    state.swap_eyes = s.swap_eyes;
    state.animation_clock = s.animation_clock;
}

/// Takes the master's settings (a whole config file as TOML), validated as a config file
/// is, so that nothing a node renders with escapes the model's ranges.
pub fn apply_settings(state: &mut AppState, text: &str) -> Result<(), String> {
    let file: ConfigFile =
        toml::from_str(text).map_err(|e| format!("the master's settings do not parse: {e}"))?;
    file.validate(&state.config.source)
        .map_err(|e| format!("the master's settings are not valid: {e}"))?;
    state.settings = file;
    Ok(())
}

/// A running cluster session, master or node.
pub enum ClusterLink {
    // Boxed: the master's session holds every node's status.
    Master(Box<MasterLink>),
    Node(NodeLink),
}

/// The master's session and what it last sent.
pub struct MasterLink {
    pub session: Master<Box<dyn Transport>>,
    /// The settings as last sent (their head position is ignored: it travels per frame).
    sent: Option<ConfigFile>,
    generation: u64,
    /// Nodes lost while broadcasting this frame (reported with the barrier's).
    pending: Vec<NodeEvent>,
    /// This frame is known to take long (see [`Master::barrier`]).
    slow: bool,
}

/// A node's session.
pub struct NodeLink {
    pub session: Node<Box<dyn Transport>>,
    pub rank: usize,
    /// The frame being rendered (from the master), and when its state arrived.
    pub frame: u64,
    pub render_started: Option<Instant>,
    /// The generation of the settings applied.
    pub generation: u64,
    /// This frame is known to take long (new settings or a screenshot).
    slow: bool,
}

/// What the node loop does next.
pub enum NodeNext {
    Render(FrameState),
    Stop(String),
}

impl ClusterLink {
    /// Starts this process's side: rank 0 the master, any other a node. `identity` is what
    /// this process loaded.
    pub fn start(
        transport: Box<dyn Transport>,
        config: &Config,
        identity: &Identity,
    ) -> Result<Self, ClusterError> {
        let timeouts = Timeouts::from_settings(&config.settings.cluster);
        let size = transport.size();
        let walls = walls_by_node(config, size)?;
        let rank = transport.rank();
        if rank == 0 {
            let session = Master::start(transport, identity, walls, timeouts)?;
            tracing::info!(
                target: "omnicave::cluster",
                "cluster started: {}",
                session
                    .nodes()
                    .iter()
                    .map(|n| n.describe())
                    .collect::<Vec<_>>()
                    .join("; ")
            );
            Ok(ClusterLink::Master(Box::new(MasterLink {
                session,
                sent: None,
                generation: 0,
                pending: Vec::new(),
                slow: false,
            })))
        } else {
            let session = Node::start(transport, identity, timeouts)?;
            Ok(ClusterLink::Node(NodeLink {
                session,
                rank,
                frame: 0,
                render_started: None,
                generation: 0,
                slow: false,
            }))
        }
    }

    /// This process's rank.
    pub fn rank(&self) -> usize {
        match self {
            ClusterLink::Master(_) => 0,
            ClusterLink::Node(n) => n.rank,
        }
    }
}

impl MasterLink {
    /// Sends this frame's settings (when any live setting changed since the last send) and
    /// state to every live node.
    pub fn broadcast(
        &mut self,
        state: &AppState,
        frame: u64,
        screenshot: u64,
    ) -> Result<(), ClusterError> {
        let changed = match self.sent.as_mut() {
            Some(sent) => {
                sent.head.position = state.settings.head.position;
                *sent != state.settings
            }
            None => true,
        };
        let text = if changed {
            self.generation += 1;
            self.sent = Some(state.settings.clone());
            Some(settings_text(&state.settings).map_err(ClusterError::Malformed)?)
        } else {
            None
        };
        let fs = frame_state(state, frame, self.generation, screenshot);
        // New settings may compile pipelines, and a screenshot reads walls back: such a
        // frame gets the start-up timeout at the barrier.
        self.slow = changed || screenshot != 0;
        self.pending = self
            .session
            .broadcast(text.as_deref().map(|t| (self.generation, t)), &fs);
        Ok(())
    }

    /// The barrier before present (`recorded`: this frame was read back for `--record`).
    /// Lost nodes were logged when lost; the panel and the stats line show them from the
    /// session's node list.
    pub fn barrier(&mut self, frame: u64, recorded: bool) -> Result<(), ClusterError> {
        let pending = std::mem::take(&mut self.pending);
        let slow = self.slow || recorded;
        self.session.barrier(frame, slow, pending)?;
        Ok(())
    }
}

impl NodeLink {
    /// Waits for the master's next frame; applies its settings on the way.
    pub fn next(&mut self, state: &mut AppState) -> Result<NodeNext, ClusterError> {
        let mut failure = None;
        let before = self.generation;
        let generation = &mut self.generation;
        let step = self.session.next_frame(|g, text| {
            if let Err(e) = apply_settings(state, text) {
                failure = Some(e);
            }
            *generation = g;
        })?;
        if let Some(e) = failure {
            return Err(ClusterError::Malformed(e));
        }
        match step {
            NodeStep::Frame(s) => {
                if s.settings_generation != self.generation {
                    return Err(ClusterError::Malformed(format!(
                        "frame {} uses settings {} but this node has {}",
                        s.frame, s.settings_generation, self.generation
                    )));
                }
                apply_frame_state(state, &s);
                self.frame = s.frame;
                self.slow = self.generation != before || s.screenshot != 0;
                self.render_started = Some(Instant::now());
                Ok(NodeNext::Render(s))
            }
            NodeStep::Stop(why) => Ok(NodeNext::Stop(why)),
        }
    }

    /// Reports the frame rendered and waits for "present" (`Some(reason)`: stop instead;
    /// `recorded`: this frame was read back for `--record`).
    pub fn barrier(&mut self, recorded: bool) -> Result<Option<String>, ClusterError> {
        let render_ms = self
            .render_started
            .map_or(0.0, |t| t.elapsed().as_secs_f64() * 1e3);
        self.session
            .barrier(self.frame, render_ms, self.slow || recorded)
    }
}
