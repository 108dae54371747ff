//! The keyboard map: which key does what, as one table shown by F1 and in the book's keys reference.

use glam::Vec3;
use winit::keyboard::KeyCode;

use super::state::{Action, NavInput};
use crate::cave::RenderMode;

/// Head movement per key press, metres.
const HEAD_STEP_M: f32 = 0.05;
/// Eye separation change per key press, metres.
const IPD_STEP_M: f32 = 0.002;

/// Every key binding: key, what it does (shown by F1; the book's key reference is this table).
pub const KEY_MAP: &[(&str, &str)] = &[
    ("F1", "show / hide this key map"),
    ("Esc", "quit"),
    ("Tab", "show / hide the control panel"),
    (
        "1 … 5",
        "render mode: mono, stereo, tracked stereo, omni on-axis, omni off-axis",
    ),
    ("T", "adaptive tessellation on / off"),
    (
        "K",
        "next skybox mode (auto, offaxis, omni-quad, omni-exact, off)",
    ),
    ("G", "wireframe on / off"),
    ("P", "pole merge on / off"),
    ("V", "next warp variant"),
    ("F", "next output format (every window)"),
    ("X", "swap eyes"),
    ("[ / ]", "eye separation − / + 2 mm"),
    (
        "Shift + I J K L",
        "head forward, left, back, right 5 cm (when not tracked)",
    ),
    ("Shift + U / O", "head down / up 5 cm"),
    ("W A S D", "navigate: forward, left, back, right (hold)"),
    ("Q / E", "navigate: down / up (hold)"),
    (
        "← / →",
        "turn left / right (hold); or drag with the right mouse button",
    ),
    ("R", "reset navigation and head"),
    (
        "Ctrl+S",
        "save the settings to the save path shown in the panel",
    ),
    (
        "F12",
        "screenshot: every wall's eye images and the settings, to screenshots/",
    ),
];

/// The action of a key press, if it has one (`shift`/`ctrl`: modifier state).
pub fn action_for_key(key: KeyCode, shift: bool, ctrl: bool) -> Option<Action> {
    let head = |x: f32, y: f32, z: f32| Some(Action::MoveHead(Vec3::new(x, y, z) * HEAD_STEP_M));
    match key {
        KeyCode::F1 => Some(Action::ToggleHelp),
        KeyCode::F12 => Some(Action::Screenshot),
        KeyCode::Escape => Some(Action::Quit),
        KeyCode::Tab => Some(Action::TogglePanel),
        KeyCode::Digit1 => Some(Action::SetMode(RenderMode::Mono)),
        KeyCode::Digit2 => Some(Action::SetMode(RenderMode::Stereo)),
        KeyCode::Digit3 => Some(Action::SetMode(RenderMode::TrackedStereo)),
        KeyCode::Digit4 => Some(Action::SetMode(RenderMode::OmniOnAxis)),
        KeyCode::Digit5 => Some(Action::SetMode(RenderMode::OmniOffAxis)),
        KeyCode::KeyS if ctrl => Some(Action::Save),
        KeyCode::KeyT => Some(Action::ToggleTessellation),
        KeyCode::KeyK if shift => head(0.0, 0.0, 1.0),
        KeyCode::KeyK => Some(Action::CycleSky),
        KeyCode::KeyG => Some(Action::ToggleWireframe),
        KeyCode::KeyP => Some(Action::TogglePoleMerge),
        KeyCode::KeyV => Some(Action::CycleWarp),
        KeyCode::KeyF => Some(Action::CycleOutput),
        KeyCode::KeyX => Some(Action::SwapEyes),
        KeyCode::BracketLeft => Some(Action::EyeSeparation(-IPD_STEP_M)),
        KeyCode::BracketRight => Some(Action::EyeSeparation(IPD_STEP_M)),
        KeyCode::KeyI if shift => head(0.0, 0.0, -1.0),
        KeyCode::KeyJ if shift => head(-1.0, 0.0, 0.0),
        KeyCode::KeyL if shift => head(1.0, 0.0, 0.0),
        KeyCode::KeyU if shift => head(0.0, -1.0, 0.0),
        KeyCode::KeyO if shift => head(0.0, 1.0, 0.0),
        KeyCode::KeyR => Some(Action::ResetView),
        _ => None,
    }
}

/// Keys held for continuous navigation.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct HeldKeys {
    pub forward: bool,
    pub back: bool,
    pub left: bool,
    pub right: bool,
    pub up: bool,
    pub down: bool,
    pub turn_left: bool,
    pub turn_right: bool,
}

impl HeldKeys {
    /// Records a press or release; returns whether the key is a navigation key.
    pub fn set(&mut self, key: KeyCode, pressed: bool) -> bool {
        let slot = match key {
            KeyCode::KeyW => &mut self.forward,
            KeyCode::KeyS => &mut self.back,
            KeyCode::KeyA => &mut self.left,
            KeyCode::KeyD => &mut self.right,
            KeyCode::KeyE => &mut self.up,
            KeyCode::KeyQ => &mut self.down,
            KeyCode::ArrowLeft => &mut self.turn_left,
            KeyCode::ArrowRight => &mut self.turn_right,
            _ => return false,
        };
        *slot = pressed;
        true
    }

    pub fn input(&self) -> NavInput {
        let axis = |plus: bool, minus: bool| f32::from(u8::from(plus)) - f32::from(u8::from(minus));
        NavInput {
            forward: axis(self.forward, self.back),
            right: axis(self.right, self.left),
            up: axis(self.up, self.down),
            turn: axis(self.turn_left, self.turn_right),
        }
    }

    pub fn any(&self) -> bool {
        *self != Self::default()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn number_keys_select_every_render_mode() {
        let keys = [
            KeyCode::Digit1,
            KeyCode::Digit2,
            KeyCode::Digit3,
            KeyCode::Digit4,
            KeyCode::Digit5,
        ];
        for (key, mode) in keys.into_iter().zip(RenderMode::ALL) {
            assert_eq!(
                action_for_key(key, false, false),
                Some(Action::SetMode(mode))
            );
        }
    }

    #[test]
    fn held_keys_combine_into_axes() {
        let mut held = HeldKeys::default();
        assert!(held.set(KeyCode::KeyW, true));
        assert!(held.set(KeyCode::KeyA, true));
        assert!(!held.set(KeyCode::KeyZ, true));
        let input = held.input();
        assert_eq!((input.forward, input.right, input.up), (1.0, -1.0, 0.0));
        held.set(KeyCode::KeyW, false);
        held.set(KeyCode::KeyA, false);
        assert!(!held.any());
    }

    #[test]
    fn ctrl_s_saves_and_plain_s_does_not() {
        assert_eq!(
            action_for_key(KeyCode::KeyS, false, true),
            Some(Action::Save)
        );
        assert_eq!(action_for_key(KeyCode::KeyS, false, false), None);
    }
}
