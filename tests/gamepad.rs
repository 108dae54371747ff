//! The gamepad mapping driven by real gilrs events (the `EventType` values gilrs hands the
//! application), without hardware: dead zones, navigation and head motion, the button map and
//! its configuration, and a pad unplugged mid-push.

#![allow(clippy::unwrap_used, clippy::expect_used)]

use std::path::{Path, PathBuf};

use gilrs::ev::Code;
use gilrs::{Axis, Button, EventType};
use glam::Vec3;

use omnicave::app::devices::app_action;
use omnicave::app::state::{AppState, NavInput};
use omnicave::cave::RenderMode;
use omnicave::config::Config;
use omnicave::gamepad::{GamepadAction, GamepadMapper, GamepadMode, PadAxes};

/// A platform event code as gilrs's Linux backend makes them (evdev type and code). gilrs has
/// no public constructor for it; its serde form is the documented way to get one.
fn code(kind: u16, code: u16) -> Code {
    serde_json::from_str(&format!("{{\"kind\":{kind},\"code\":{code}}}"))
        .expect("gilrs Code from its serde form")
}

fn axis(a: Axis, v: f32) -> EventType {
    EventType::AxisChanged(a, v, code(3, 0))
}

fn press(b: Button) -> EventType {
    EventType::ButtonPressed(b, code(1, 0x130))
}

fn desktop_config(extra: &str) -> Config {
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("config/desktop.toml");
    let text = std::fs::read_to_string(&path).expect("desktop.toml") + extra;
    Config::from_toml(&text, &path).expect("config")
}

fn mapper(config: &Config) -> GamepadMapper {
    GamepadMapper::new(config.gamepad.clone())
}

/// Feeds events; applies each resulting action to the state as the application does.
fn feed(m: &mut GamepadMapper, state: &mut AppState, events: &[EventType]) {
    for e in events {
        if let Some(action) = m.handle(e) {
            state.apply(app_action(action));
        }
    }
}

#[test]
fn sticks_inside_the_dead_zone_do_nothing_and_outside_rise_from_zero() {
    let config = desktop_config("");
    let mut m = mapper(&config);
    let dz = config.gamepad.dead_zone;
    // A resting stick drifts a little: inside the dead zone it must read exactly zero.
    m.handle(&axis(Axis::LeftStickX, dz * 0.9));
    m.handle(&axis(Axis::LeftStickY, -dz * 0.3));
    assert!(m.axes().is_idle(), "{:?}", m.axes());
    // Just outside, the output starts near zero (no jump), and full deflection gives 1.
    m.handle(&axis(Axis::LeftStickX, dz + 0.01));
    m.handle(&axis(Axis::LeftStickY, 0.0));
    let x = m.axes().left.x;
    assert!(x > 0.0 && x < 0.02, "{x}");
    m.handle(&axis(Axis::LeftStickX, 1.0));
    assert!((m.axes().left.x - 1.0).abs() < 1e-6);
    // Garbage values from a broken driver are ignored, not propagated.
    m.handle(&axis(Axis::RightStickX, f32::NAN));
    assert_eq!(m.axes().right.x, 0.0);
}

#[test]
fn navigate_mode_moves_strafes_turns_and_climbs() {
    let config = desktop_config("");
    let mut state = AppState::new(config.clone());
    let mut m = mapper(&config);
    assert_eq!(state.settings.gamepad.mode, GamepadMode::Navigate);
    // Left stick pushed forward for one second: the CAVE moves towards the front wall (−z).
    m.handle(&axis(Axis::LeftStickY, 1.0));
    let motion = m.axes().motion(state.settings.gamepad.mode);
    state.navigate(
        NavInput {
            forward: motion.forward,
            right: motion.right,
            up: motion.up,
            turn: motion.turn,
        },
        1.0,
    );
    let speed = config.app.navigation_speed;
    assert!(
        (state.navigation.position - Vec3::new(0.0, 0.0, -speed)).length() < 1e-5,
        "{}",
        state.navigation.position
    );
    m.handle(&axis(Axis::LeftStickY, 0.0));
    // Right stick to the right turns right (negative yaw); the right trigger climbs.
    m.handle(&axis(Axis::RightStickX, 1.0));
    m.handle(&EventType::ButtonChanged(
        Button::RightTrigger2,
        1.0,
        code(3, 5),
    ));
    let a: PadAxes = m.axes();
    let motion = a.motion(GamepadMode::Navigate);
    assert_eq!((motion.turn, motion.up), (-1.0, 1.0));
    // The left trigger cancels the right one.
    m.handle(&EventType::ButtonChanged(
        Button::LeftTrigger2,
        1.0,
        code(3, 2),
    ));
    assert_eq!(m.axes().motion(GamepadMode::Navigate).up, 0.0);
}

#[test]
fn head_mode_moves_the_head_inside_the_cave() {
    let config = desktop_config("[gamepad]\nmode = \"head\"\nhead_speed = 0.5\n");
    let mut state = AppState::new(config.clone());
    assert_eq!(state.settings.gamepad.mode, GamepadMode::Head);
    let mut m = mapper(&config);
    let start = state.head_position();
    m.handle(&axis(Axis::LeftStickX, 1.0));
    let step = m.axes().motion(GamepadMode::Head).head * config.gamepad.head_speed * 0.5;
    state.apply(omnicave::app::state::Action::MoveHead(step));
    // Half a second at full right deflection: 0.25 m to the right.
    assert!(
        (state.head_position() - (start + Vec3::new(0.25, 0.0, 0.0))).length() < 1e-5,
        "{}",
        state.head_position()
    );
    // Pushing on for a minute stops 5 cm inside the right wall.
    for _ in 0..120 {
        state.apply(omnicave::app::state::Action::MoveHead(step));
    }
    let (_, hi) = state.head_bounds();
    assert!((state.head_position().x - hi.x).abs() < 1e-6);
    assert!(hi.x < 1.65 - 0.049);
}

#[test]
fn default_buttons_cycle_modes_and_toggle_features() {
    let config = desktop_config("");
    let mut state = AppState::new(config.clone());
    let mut m = mapper(&config);
    let mode = state.settings.render.mode;
    feed(&mut m, &mut state, &[press(Button::South)]); // A
    let i = RenderMode::ALL.iter().position(|x| *x == mode).unwrap();
    assert_eq!(
        state.settings.render.mode,
        RenderMode::ALL[(i + 1) % RenderMode::ALL.len()]
    );
    feed(&mut m, &mut state, &[press(Button::DPadLeft)]);
    assert_eq!(state.settings.render.mode, mode);
    let tess = state.tess_on();
    feed(&mut m, &mut state, &[press(Button::East)]); // B
    assert_eq!(state.tess_on(), !tess);
    let sky = state.settings.skybox.mode;
    feed(&mut m, &mut state, &[press(Button::West)]); // X
    assert_ne!(state.settings.skybox.mode, sky);
    let ipd = state.settings.cave.eye_separation;
    feed(
        &mut m,
        &mut state,
        &[press(Button::DPadUp), press(Button::DPadUp)],
    );
    assert!((state.settings.cave.eye_separation - ipd - 0.004).abs() < 1e-6);
    feed(&mut m, &mut state, &[press(Button::North)]); // Y
    assert_eq!(state.settings.gamepad.mode, GamepadMode::Head);
    let speed = state.settings.app.navigation_speed;
    feed(&mut m, &mut state, &[press(Button::RightTrigger)]); // RB
    assert!(state.settings.app.navigation_speed > speed);
    state.navigation.position = Vec3::ONE;
    feed(&mut m, &mut state, &[press(Button::Start)]);
    assert_eq!(state.navigation.position, Vec3::ZERO);
    assert_eq!(state.settings.app.navigation_speed, speed);
    // Releases and buttons without a binding do nothing.
    assert_eq!(
        m.handle(&EventType::ButtonReleased(Button::South, code(1, 0x130))),
        None
    );
    assert_eq!(m.handle(&press(Button::RightThumb)), None);
}

#[test]
fn the_button_map_is_configurable_and_bad_entries_are_named() {
    let config = desktop_config(
        "[gamepad.buttons]\nA = \"toggle-wireframe\"\nB = \"none\"\nRS = \"swap-eyes\"\n",
    );
    let mut m = mapper(&config);
    assert_eq!(
        m.handle(&press(Button::South)),
        Some(GamepadAction::ToggleWireframe)
    );
    assert_eq!(m.handle(&press(Button::East)), None);
    assert_eq!(
        m.handle(&press(Button::RightThumb)),
        Some(GamepadAction::SwapEyes)
    );
    // Unchanged buttons keep their defaults.
    assert_eq!(
        m.handle(&press(Button::West)),
        Some(GamepadAction::NextSkybox)
    );

    let path = Path::new("pad.toml");
    let base = std::fs::read_to_string(
        PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("config/desktop.toml"),
    )
    .expect("desktop.toml");
    for (extra, field, value) in [
        (
            "[gamepad.buttons]\nQ = \"swap-eyes\"\n",
            "gamepad.buttons.Q",
            "Q",
        ),
        (
            "[gamepad.buttons]\nA = \"fly\"\n",
            "gamepad.buttons.A",
            "fly",
        ),
        ("[gamepad]\nmode = \"drive\"\n", "gamepad.mode", "drive"),
        ("[gamepad]\ndead_zone = 1.5\n", "gamepad.dead_zone", "1.5"),
    ] {
        let e = Config::from_toml(&format!("{base}{extra}"), path)
            .expect_err(extra)
            .to_string();
        assert!(
            e.contains("pad.toml") && e.contains(field) && e.contains(value),
            "{extra}: {e}"
        );
    }
}

#[test]
fn an_unplugged_pad_stops_moving_the_viewer() {
    let config = desktop_config("");
    let mut m = mapper(&config);
    m.handle(&axis(Axis::LeftStickY, 1.0));
    m.handle(&EventType::ButtonChanged(
        Button::RightTrigger2,
        1.0,
        code(3, 5),
    ));
    assert!(!m.axes().is_idle());
    m.handle(&EventType::Disconnected);
    assert!(m.axes().is_idle());
    // Connecting again starts from rest.
    m.handle(&EventType::Connected);
    assert!(m.axes().is_idle());
}
