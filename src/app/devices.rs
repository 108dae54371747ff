//! The application's input devices: the tracking source (OSC, VRPN or DTrack) with its head
//! tracker and buttons, and gamepads (gilrs, hot-plug). Both are polled once per frame and never
//! block it.

use std::net::SocketAddr;
use std::time::Instant;

use super::state::WandPose;
use super::state::{Action, AppState, NavInput};
use crate::config::TrackingConfig;
use crate::gamepad::{GamepadAction, GamepadMapper, GamepadMode, GamepadSettings};
use crate::tracking::receiver::TrackedOrientation;
use crate::tracking::receiver::{LOG_INTERVAL, LogLimiter};
use crate::tracking::{
    ButtonAction, Controls, Counters, HeadTracker, LinkState, Stream, StreamSenders, TrackerSample,
    TrackingSource, TrackingStats, TrackingStatus,
};

/// Joystick deflection below which it does not fly (a resting stick reads a few hundredths).
const JOYSTICK_DEAD_ZONE: f64 = 0.1;

/// What the panel and the stats line show about tracking.
#[derive(Debug, Clone, Default)]
pub struct TrackingInfo {
    /// Where the receiver listens (None: not started, or VRPN).
    pub listening: Option<SocketAddr>,
    /// The running source in words ("VRPN from localhost:3883").
    pub source: Option<String>,
    /// Button presses of the tracked input device that triggered an action, since start.
    pub button_actions: u64,
    /// What the wand's ray hit at the last "select".
    pub selection: Option<String>,
    /// The tracked body's pose before the eye offset (CAVE space), for calibrating the offset.
    pub body: Option<(glam::Vec3, glam::Quat)>,
    /// Why the receiver could not start.
    pub error: Option<String>,
    pub status: Option<TrackingStatus>,
    /// Listening, connected, or reconnecting (and to what).
    pub link: Option<LinkState>,
    pub lost_for: Option<f64>,
    pub stats: TrackingStats,
    pub counters: Counters,
    /// Who drives the head, the wand and the buttons, and the newest second sender refused.
    pub senders: Vec<(Stream, StreamSenders)>,
    /// The source listens on a network address with no allowed senders: anyone there can send.
    pub open_warning: Option<String>,
    /// Names of connected gamepads.
    pub gamepads: Vec<String>,
    /// Why gamepads are unavailable, if they are.
    pub gamepad_error: Option<String>,
}

/// Tracking: the source (started when tracking is switched on), the head tracker and the
/// tracked input device's buttons.
#[derive(Debug)]
pub struct Tracking {
    config: TrackingConfig,
    receiver: Option<TrackingSource>,
    /// Presses of each button already acted on.
    presses_seen: Option<Controls>,
    button_actions: u64,
    /// The wand's newest sample used (its sequence number) and when it arrived.
    wand_seen: Option<(u64, Instant)>,
    /// The previous poll (for flying: distance = speed × time).
    last_poll: Option<Instant>,
    tracker: HeadTracker,
    error: Option<String>,
    /// Tracking was on last frame (a switch on retries a failed bind once).
    was_on: bool,
    refused_log: LogLimiter,
}

impl Tracking {
    pub fn new(config: TrackingConfig) -> Self {
        Self {
            tracker: HeadTracker::new(config.settings),
            config,
            receiver: None,
            presses_seen: None,
            button_actions: 0,
            wand_seen: None,
            last_poll: None,
            error: None,
            was_on: false,
            refused_log: LogLimiter::default(),
        }
    }

    /// Once per frame, at its start: applies the newest tracked pose to the state.
    pub fn poll(&mut self, state: &mut AppState, now: Instant) {
        if !state.settings.tracking.enabled {
            self.was_on = false;
            return;
        }
        if !self.was_on && self.receiver.is_none() {
            match TrackingSource::start(&self.config.source, &self.config.receiver) {
                Ok(r) => {
                    r.feed()
                        .configure(self.tracker.settings.gate(Some(state.head_bounds())));
                    if let Some(warning) = r.open_warning() {
                        tracing::warn!("{warning}");
                    }
                    self.receiver = Some(r);
                    self.error = None;
                }
                Err(e) => {
                    tracing::error!("{e}; head tracking stays off");
                    self.error = Some(e.to_string());
                }
            }
        }
        self.was_on = true;
        let Some(receiver) = &self.receiver else {
            return;
        };
        self.tracker.set_filter(state.tracking_filter());
        // The panel's eye offset (its calibration helper sets it at run time).
        let offset = glam::Vec3::from(state.settings.tracking.eye_offset);
        if offset.is_finite() && offset.length() <= 0.5 {
            self.tracker.settings.eye_offset = offset;
        }
        let feed = receiver.feed().clone();
        // The gate judges in CAVE space: it follows the calibration and the CAVE's box.
        feed.configure(self.tracker.settings.gate(Some(state.head_bounds())));
        let dt = self.last_poll.map_or(0.0, |t| {
            now.saturating_duration_since(t).as_secs_f32().min(0.25)
        });
        self.last_poll = Some(now);
        self.wand(feed.try_wand(), state, now);
        if let Some(controls) = feed.try_controls() {
            self.buttons(&controls, state, dt);
        }
        let sample = feed.try_latest();
        if let Some(pose) = self.tracker.update(sample, now, Some(state.head_bounds()))
            && let Err(problem) = state.apply_tracked_pose(pose)
            && let Some(held) = self.refused_log.allow(now, LOG_INTERVAL)
        {
            tracing::warn!(
                "tracked head refused: {problem}; the head holds ({held} more not logged)"
            );
        }
    }

    /// The wand's pose in CAVE space (the head's calibration; no eye offset), held until
    /// no sample came for the tracking timeout.
    fn wand(&mut self, sample: Option<TrackerSample>, state: &mut AppState, now: Instant) {
        if let Some(s) = sample
            && self.wand_seen.map(|(seq, _)| seq) != Some(s.seq)
        {
            self.wand_seen = Some((s.seq, s.arrived));
            let cal = &self.tracker.settings.calibration;
            let orientation = s.orientation.map(|o| match o {
                TrackedOrientation::Tracker(q) => cal.orientation(q),
                TrackedOrientation::CaveAxes(q) => cal.orientation_in_cave_axes(q),
            });
            if let (Some(p), Some(q), None | Some(true)) = (s.position, orientation, s.tracked) {
                let position = cal.position(p);
                let q = q.normalize();
                if position.is_finite() && q.is_finite() {
                    state.wand = Some(WandPose {
                        position,
                        orientation: q,
                    });
                }
            }
        }
        let stale = self.wand_seen.is_none_or(|(_, at)| {
            now.saturating_duration_since(at) > self.tracker.settings.timeout
        });
        if stale {
            state.wand = None;
        }
    }

    /// Applies the action of every button pressed since the last frame (each press once), and
    /// flies along the wand's ray while a "fly" button is held (`dt` seconds since the last
    /// frame) or the joystick is pushed (its second axis: forward and back).
    fn buttons(&mut self, controls: &Controls, state: &mut AppState, dt: f32) {
        if let Some(seen) = &self.presses_seen {
            for (&button, &action) in &self.config.buttons {
                let new = controls.presses[button].wrapping_sub(seen.presses[button]);
                // A burst is one action per press, but never more than a few per frame.
                for _ in 0..new.min(4) {
                    tracing::info!("tracked button {button}: {}", action.name());
                    self.button_actions += 1;
                    match action {
                        ButtonAction::Action(a) => state.apply(app_action(a)),
                        ButtonAction::Select => state.select_requested = true,
                        ButtonAction::Fly => {}
                    }
                }
            }
        }
        let flying = self
            .config
            .buttons
            .iter()
            .any(|(&b, &a)| a == ButtonAction::Fly && controls.is_held(b));
        // The joystick's forward axis, past a dead zone.
        let stick = controls
            .analogs
            .get(1)
            .copied()
            .filter(|v| v.abs() > JOYSTICK_DEAD_ZONE)
            .unwrap_or(0.0) as f32;
        let throttle = if flying { 1.0 } else { stick.clamp(-1.0, 1.0) };
        if throttle != 0.0
            && let Some(ray) = state.wand_ray()
        {
            state.fly(ray.direction * throttle, dt);
        }
        self.presses_seen = Some(controls.clone());
    }

    /// Whether the tracker is driving the head (gamepad head mode yields to it; while tracking
    /// is lost or not started, the pad may move the head).
    pub fn drives_head(&self, state: &AppState) -> bool {
        state.settings.tracking.enabled
            && self.receiver.is_some()
            && self.tracker.status() == TrackingStatus::Tracking
    }

    pub fn info(&self, now: Instant, into: &mut TrackingInfo) {
        into.listening = self.receiver.as_ref().and_then(TrackingSource::local_addr);
        if into.source.is_none() != self.receiver.is_none() {
            into.source = self.receiver.as_ref().map(TrackingSource::describe);
        }
        into.button_actions = self.button_actions;
        into.body = self.tracker.body();
        if into.error != self.error {
            into.error.clone_from(&self.error);
        }
        into.status = self.receiver.as_ref().map(|_| self.tracker.status());
        into.link = self.receiver.as_ref().map(TrackingSource::link);
        into.lost_for = self.tracker.lost_for(now);
        into.stats = self.tracker.stats();
        into.counters = self
            .receiver
            .as_ref()
            .map(|r| r.feed().counters())
            .unwrap_or_default();
        // Kept from the last frame should a source hold them this instant.
        match self.receiver.as_ref().map(|r| r.feed().try_senders()) {
            Some(Some(senders)) => {
                into.senders.clear();
                into.senders.extend(
                    Stream::ALL
                        .iter()
                        .map(|&s| (s, senders[s.index()]))
                        .filter(|(_, s)| s.owner.is_some()),
                );
            }
            Some(None) => {}
            None => into.senders.clear(),
        }
        into.open_warning = self
            .receiver
            .as_ref()
            .and_then(TrackingSource::open_warning);
    }
}

/// Gamepads through gilrs; absent (with a logged reason) where gilrs cannot start.
pub struct Gamepads {
    gilrs: gilrs::Gilrs,
    mapper: GamepadMapper,
    /// Names of the connected pads, rebuilt only when one comes or goes.
    names: Vec<String>,
}

impl std::fmt::Debug for Gamepads {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Gamepads")
            .field("mapper", &self.mapper)
            .finish_non_exhaustive()
    }
}

impl Gamepads {
    /// Starts gilrs if gamepads are enabled; `Err` says why there are none.
    pub fn start(settings: GamepadSettings) -> Result<Option<Self>, String> {
        if !settings.enabled {
            return Ok(None);
        }
        let gilrs = match gilrs::Gilrs::new() {
            Ok(g) => g,
            Err(gilrs::Error::NotImplemented(g)) => {
                tracing::info!("gamepads: not supported on this platform");
                g
            }
            Err(e) => return Err(format!("gamepads unavailable: {e}")),
        };
        let names: Vec<String> = gilrs
            .gamepads()
            .map(|(_, pad)| pad.name().to_owned())
            .collect();
        for name in &names {
            tracing::info!("gamepad connected: {name}");
        }
        Ok(Some(Self {
            gilrs,
            mapper: GamepadMapper::new(settings),
            names,
        }))
    }

    /// Once per frame: applies button actions and stick motion for `dt` seconds.
    pub fn poll(&mut self, state: &mut AppState, dt: f32, head_tracked: bool) {
        while let Some(event) = self.gilrs.next_event() {
            if matches!(
                event.event,
                gilrs::EventType::Connected | gilrs::EventType::Disconnected
            ) {
                let pad = self.gilrs.gamepad(event.id);
                let verb = if pad.is_connected() {
                    "connected"
                } else {
                    "disconnected"
                };
                tracing::info!("gamepad {verb}: {}", pad.name());
                self.names = self
                    .gilrs
                    .gamepads()
                    .map(|(_, pad)| pad.name().to_owned())
                    .collect();
            }
            if let Some(action) = self.mapper.handle(&event.event) {
                state.apply(app_action(action));
            }
        }
        let axes = self.mapper.axes();
        if axes.is_idle() {
            return;
        }
        let motion = axes.motion(state.settings.gamepad.mode);
        match state.settings.gamepad.mode {
            GamepadMode::Navigate => state.navigate(
                NavInput {
                    forward: motion.forward,
                    right: motion.right,
                    up: motion.up,
                    turn: motion.turn,
                },
                dt,
            ),
            GamepadMode::Head if !head_tracked => {
                let step = motion.head * self.mapper.settings.head_speed * dt.clamp(0.0, 0.25);
                state.apply(Action::MoveHead(step));
            }
            GamepadMode::Head => {}
        }
    }

    /// Names of the connected gamepads.
    pub fn names(&self) -> &[String] {
        &self.names
    }
}

/// Eye separation step of the D-pad, metres.
const IPD_STEP_M: f32 = 0.002;
/// Navigation speed factor of a bumper press.
const SPEED_STEP: f32 = 1.5;

/// The state action of a gamepad action.
pub fn app_action(action: GamepadAction) -> Action {
    match action {
        GamepadAction::NextRenderMode => Action::StepMode(1),
        GamepadAction::PreviousRenderMode => Action::StepMode(-1),
        GamepadAction::ToggleTessellation => Action::ToggleTessellation,
        GamepadAction::NextSkybox => Action::CycleSky,
        GamepadAction::ToggleWireframe => Action::ToggleWireframe,
        GamepadAction::TogglePoleMerge => Action::TogglePoleMerge,
        GamepadAction::NextWarp => Action::CycleWarp,
        GamepadAction::NextOutput => Action::CycleOutput,
        GamepadAction::SwapEyes => Action::SwapEyes,
        GamepadAction::EyeSeparationUp => Action::EyeSeparation(IPD_STEP_M),
        GamepadAction::EyeSeparationDown => Action::EyeSeparation(-IPD_STEP_M),
        GamepadAction::ResetView => Action::ResetView,
        GamepadAction::ToggleGamepadMode => Action::ToggleGamepadMode,
        GamepadAction::SpeedUp => Action::ScaleNavigationSpeed(SPEED_STEP),
        GamepadAction::SpeedDown => Action::ScaleNavigationSpeed(1.0 / SPEED_STEP),
        GamepadAction::TogglePanel => Action::TogglePanel,
        GamepadAction::ToggleTracking => Action::ToggleTracking,
        GamepadAction::Screenshot => Action::Screenshot,
    }
}
