//! The key and gamepad maps and the OSC forms, from the tables the program itself uses.

use std::fmt::Write as _;

use super::{cell, generated_header};
use crate::gamepad::{BUTTON_NAMES, DEFAULT_BUTTONS, GamepadAction};
use crate::tracking::OscMapping;
use crate::tracking::osc::OSC_FORMS;

/// `reference/keys.md`: the keyboard map (what F1 shows) and the gamepad's default map.
pub fn keys_page() -> String {
    let mut out = generated_header(
        "the key map (`src/app/keys.rs`) and the gamepad's tables (`src/gamepad.rs`)",
    );
    out.push_str(
        "# Keys and gamepad\n\n\
         ## Keyboard\n\n\
         The application's keys (F1 shows this table in the application).\n\n\
         | key | does |\n|---|---|\n",
    );
    for (key, does) in crate::app::keys::KEY_MAP {
        let _ = writeln!(out, "| {} | {} |", cell(key), cell(does));
    }
    out.push_str(
        "\nMouse: drag with the right button to turn.\n\n\
         ## Gamepad\n\n\
         The default button map (Xbox labels). `[gamepad.buttons]` in the config overrides \
         single buttons (`A = \"toggle-wireframe\"`, `B = \"none\"` unbinds).\n\n\
         | button | action |\n|---|---|\n",
    );
    for (button, action) in DEFAULT_BUTTONS {
        let _ = writeln!(out, "| {button} | `{}` |", action.name());
    }
    out.push_str("\nEvery action a button (or a tracked device's button) can be bound to:\n\n");
    let actions: Vec<String> = GamepadAction::NAMES
        .iter()
        .map(|n| format!("`{n}`"))
        .collect();
    let _ = writeln!(out, "{}\n", actions.join(", "));
    out.push_str("Button names the config accepts (Xbox labels and gilrs's own names):\n\n");
    let buttons: Vec<String> = BUTTON_NAMES.iter().map(|(n, _)| format!("`{n}`")).collect();
    let _ = writeln!(out, "{}", buttons.join(", "));
    out
}

/// `reference/osc.md`: every OSC message form the head tracker accepts, with its default
/// address.
pub fn osc_page() -> String {
    let mapping = OscMapping::default();
    let mut out = generated_header("the OSC decoder's table (`src/tracking/osc.rs`)");
    out.push_str(
        "# OSC addresses\n\n\
         The messages the OSC tracking source accepts (`tracking.source = \"osc\"`). Each \
         address is a `[tracking]` key; an empty string switches that form off. Numbers may \
         be 32- or 64-bit floats or integers, alone or in OSC bundles; in a bundle, later \
         messages win. A packet is taken whole or not at all: one malformed or non-finite \
         message meant for the head drops the packet.\n\n\
         | address (default) | config key | arguments | sets | example |\n\
         |---|---|---|---|---|\n",
    );
    for form in OSC_FORMS {
        let address = mapping.address_of(form.config_key).unwrap_or("");
        let _ = writeln!(
            out,
            "| `{address}` | `tracking.{}` | {} | {} | `{address} {}` |",
            form.config_key,
            cell(form.arguments),
            cell(form.meaning),
            form.example,
        );
    }
    let _ = writeln!(
        out,
        "\n`tracking.natnet_rigid_body` (default {}) picks the rigid body that is the head; \
         `tracking.quaternion_order` (default `{}`) the order of a quaternion's numbers.",
        mapping.natnet_rigid_body, mapping.quaternion_order
    );
    out
}
