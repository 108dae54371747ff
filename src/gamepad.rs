//! The gamepad mapping (Xbox layout): gilrs events → stick motion (navigation or head) and
//! button actions, with dead zones and a configurable button map. No windows, no device: the
//! application feeds it the events gilrs produces, the tests feed it the same event type.

use std::collections::BTreeMap;

use gilrs::{Axis, Button, EventType};
use glam::{Vec2, Vec3};

/// What the sticks drive.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum GamepadMode {
    /// Left stick moves and strafes, right stick turns, triggers move down/up.
    #[default]
    Navigate,
    /// The sticks move the head inside the CAVE (when OSC tracking is off).
    Head,
}

crate::named_enum!(GamepadMode {
    Self::Navigate => "navigate",
    Self::Head => "head",
});

/// What a button can do.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum GamepadAction {
    NextRenderMode,
    PreviousRenderMode,
    ToggleTessellation,
    NextSkybox,
    ToggleWireframe,
    TogglePoleMerge,
    NextWarp,
    NextOutput,
    SwapEyes,
    EyeSeparationUp,
    EyeSeparationDown,
    ResetView,
    ToggleGamepadMode,
    SpeedUp,
    SpeedDown,
    TogglePanel,
    ToggleTracking,
    Screenshot,
}

crate::named_enum!(GamepadAction {
    Self::NextRenderMode => "next-render-mode",
    Self::PreviousRenderMode => "previous-render-mode",
    Self::ToggleTessellation => "toggle-tessellation",
    Self::NextSkybox => "next-skybox",
    Self::ToggleWireframe => "toggle-wireframe",
    Self::TogglePoleMerge => "toggle-pole-merge",
    Self::NextWarp => "next-warp",
    Self::NextOutput => "next-output",
    Self::SwapEyes => "swap-eyes",
    Self::EyeSeparationUp => "eye-separation-up",
    Self::EyeSeparationDown => "eye-separation-down",
    Self::ResetView => "reset-view",
    Self::ToggleGamepadMode => "toggle-gamepad-mode",
    Self::SpeedUp => "speed-up",
    Self::SpeedDown => "speed-down",
    Self::TogglePanel => "toggle-panel",
    Self::ToggleTracking => "toggle-tracking",
    Self::Screenshot => "screenshot",
});

/// Button names in the config: the Xbox labels (and gilrs's own names).
pub const BUTTON_NAMES: &[(&str, Button)] = &[
    ("A", Button::South),
    ("B", Button::East),
    ("X", Button::West),
    ("Y", Button::North),
    ("LB", Button::LeftTrigger),
    ("RB", Button::RightTrigger),
    ("LT", Button::LeftTrigger2),
    ("RT", Button::RightTrigger2),
    ("Back", Button::Select),
    ("Start", Button::Start),
    ("Guide", Button::Mode),
    ("LS", Button::LeftThumb),
    ("RS", Button::RightThumb),
    ("DPadUp", Button::DPadUp),
    ("DPadDown", Button::DPadDown),
    ("DPadLeft", Button::DPadLeft),
    ("DPadRight", Button::DPadRight),
    ("South", Button::South),
    ("East", Button::East),
    ("West", Button::West),
    ("North", Button::North),
    ("Select", Button::Select),
    ("Mode", Button::Mode),
];

pub fn button_from_name(name: &str) -> Option<Button> {
    BUTTON_NAMES
        .iter()
        .find(|(n, _)| *n == name)
        .map(|(_, b)| *b)
}

/// The default button map (Xbox labels), shown in the book's keys reference and `config/cave.toml`.
pub const DEFAULT_BUTTONS: &[(&str, GamepadAction)] = &[
    ("A", GamepadAction::NextRenderMode),
    ("B", GamepadAction::ToggleTessellation),
    ("X", GamepadAction::NextSkybox),
    ("Y", GamepadAction::ToggleGamepadMode),
    ("LB", GamepadAction::SpeedDown),
    ("RB", GamepadAction::SpeedUp),
    ("DPadUp", GamepadAction::EyeSeparationUp),
    ("DPadDown", GamepadAction::EyeSeparationDown),
    ("DPadLeft", GamepadAction::PreviousRenderMode),
    ("DPadRight", GamepadAction::NextWarp),
    ("Back", GamepadAction::ToggleWireframe),
    ("Start", GamepadAction::ResetView),
    ("LS", GamepadAction::TogglePoleMerge),
];

/// A bad button map entry.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum ButtonMapError {
    #[error(
        "'{0}' is not a button (A, B, X, Y, LB, RB, LT, RT, Back, Start, Guide, LS, RS, DPadUp/Down/Left/Right)"
    )]
    Button(String),
    #[error("'{0}' is not an action (or \"none\")")]
    Action(String),
}

/// The default map with `overrides` (button name → action name, or "none" to unbind) applied.
pub fn button_map(
    overrides: &BTreeMap<String, String>,
) -> Result<Vec<(Button, GamepadAction)>, ButtonMapError> {
    let mut map: Vec<(Button, GamepadAction)> = DEFAULT_BUTTONS
        .iter()
        .filter_map(|(n, a)| Some((button_from_name(n)?, *a)))
        .collect();
    for (name, action) in overrides {
        let button = button_from_name(name).ok_or_else(|| ButtonMapError::Button(name.clone()))?;
        map.retain(|(b, _)| *b != button);
        if action != "none" {
            let action = GamepadAction::from_name(action)
                .ok_or_else(|| ButtonMapError::Action(action.clone()))?;
            map.push((button, action));
        }
    }
    Ok(map)
}

/// Gamepad settings (`[gamepad]` in the config).
#[derive(Debug, Clone, PartialEq)]
pub struct GamepadSettings {
    pub enabled: bool,
    pub mode: GamepadMode,
    /// Radial stick dead zone, 0..1 of full deflection.
    pub dead_zone: f32,
    /// Trigger dead zone, 0..1.
    pub trigger_dead_zone: f32,
    /// Head speed at full deflection (head mode), metres per second.
    pub head_speed: f32,
    pub buttons: Vec<(Button, GamepadAction)>,
}

impl Default for GamepadSettings {
    fn default() -> Self {
        Self {
            enabled: true,
            mode: GamepadMode::Navigate,
            dead_zone: 0.15,
            trigger_dead_zone: 0.05,
            head_speed: 0.5,
            buttons: button_map(&BTreeMap::new()).unwrap_or_default(),
        }
    }
}

/// Stick and trigger state after dead zones.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct PadAxes {
    /// x: right, y: up (pushed forward).
    pub left: Vec2,
    pub right: Vec2,
    /// Right trigger minus left trigger, −1..1.
    pub triggers: f32,
}

/// What the sticks ask for this frame, per unit of full deflection.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct PadMotion {
    /// Navigation: forward, right, up (−1..1) and turn (+1 turns left).
    pub forward: f32,
    pub right: f32,
    pub up: f32,
    pub turn: f32,
    /// Head mode: direction in CAVE space (x right, y up, z back), each −1..1.
    pub head: Vec3,
}

impl PadAxes {
    /// The motion these axes give in `mode`.
    pub fn motion(&self, mode: GamepadMode) -> PadMotion {
        match mode {
            GamepadMode::Navigate => PadMotion {
                forward: self.left.y,
                right: self.left.x,
                up: self.triggers,
                turn: -self.right.x,
                head: Vec3::ZERO,
            },
            GamepadMode::Head => PadMotion {
                head: Vec3::new(
                    self.left.x,
                    (self.right.y + self.triggers).clamp(-1.0, 1.0),
                    -self.left.y,
                ),
                ..PadMotion::default()
            },
        }
    }

    pub fn is_idle(&self) -> bool {
        *self == Self::default()
    }
}

/// Applies a radial dead zone, rescaled so output rises continuously from 0 at its edge to 1.
pub fn radial_dead_zone(v: Vec2, dead_zone: f32) -> Vec2 {
    let length = v.length();
    if !length.is_finite() || length <= dead_zone {
        return Vec2::ZERO;
    }
    let scaled = ((length - dead_zone) / (1.0 - dead_zone).max(1e-3)).min(1.0);
    v / length * scaled
}

/// Applies a dead zone to a 0..1 trigger.
pub fn trigger_dead_zone(t: f32, dead_zone: f32) -> f32 {
    if !t.is_finite() || t <= dead_zone {
        return 0.0;
    }
    ((t - dead_zone) / (1.0 - dead_zone).max(1e-3)).min(1.0)
}

/// Turns gilrs events into actions and stick state.
#[derive(Debug, Clone)]
pub struct GamepadMapper {
    pub settings: GamepadSettings,
    /// Raw stick values: left x, left y, right x, right y.
    sticks: [f32; 4],
    /// Raw triggers: left, right.
    triggers: [f32; 2],
}

impl GamepadMapper {
    pub fn new(settings: GamepadSettings) -> Self {
        Self {
            settings,
            sticks: [0.0; 4],
            triggers: [0.0; 2],
        }
    }

    /// Takes one event; returns the action of a pressed button, if it has one.
    pub fn handle(&mut self, event: &EventType) -> Option<GamepadAction> {
        let clean = |v: f32| {
            if v.is_finite() {
                v.clamp(-1.0, 1.0)
            } else {
                0.0
            }
        };
        match *event {
            EventType::ButtonPressed(button, _) => self
                .settings
                .buttons
                .iter()
                .find(|(b, _)| *b == button)
                .map(|(_, a)| *a),
            EventType::AxisChanged(axis, value, _) => {
                let v = clean(value);
                match axis {
                    Axis::LeftStickX => self.sticks[0] = v,
                    Axis::LeftStickY => self.sticks[1] = v,
                    Axis::RightStickX => self.sticks[2] = v,
                    Axis::RightStickY => self.sticks[3] = v,
                    // Some pads report the triggers as axes (−1 released … 1 pressed or 0 … 1).
                    Axis::LeftZ => self.triggers[0] = v.max(0.0),
                    Axis::RightZ => self.triggers[1] = v.max(0.0),
                    _ => {}
                }
                None
            }
            EventType::ButtonChanged(button, value, _) => {
                let v = clean(value).max(0.0);
                match button {
                    Button::LeftTrigger2 => self.triggers[0] = v,
                    Button::RightTrigger2 => self.triggers[1] = v,
                    _ => {}
                }
                None
            }
            EventType::Disconnected => {
                // A pad unplugged mid-push must not keep moving the viewer.
                self.sticks = [0.0; 4];
                self.triggers = [0.0; 2];
                None
            }
            _ => None,
        }
    }

    /// Sticks and triggers after dead zones.
    pub fn axes(&self) -> PadAxes {
        let s = &self.settings;
        PadAxes {
            left: radial_dead_zone(Vec2::new(self.sticks[0], self.sticks[1]), s.dead_zone),
            right: radial_dead_zone(Vec2::new(self.sticks[2], self.sticks[3]), s.dead_zone),
            triggers: trigger_dead_zone(self.triggers[1], s.trigger_dead_zone)
                - trigger_dead_zone(self.triggers[0], s.trigger_dead_zone),
        }
    }
}
