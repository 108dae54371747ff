//! Termination signals (SIGINT, SIGTERM, SIGHUP) caught from the first instruction of `main`:
//! the interactive commands poll [`stop_requested`] and shut down cleanly (exit 0), a second
//! signal ending them at once; the batch commands, which do not poll, exit at once with 143
//! (128 + SIGTERM), as if killed.

use std::sync::atomic::{AtomicBool, Ordering};

static STOP: AtomicBool = AtomicBool::new(false);

/// Exit status of a batch command stopped by a signal (the shell's 128 + 15).
pub const STOPPED_BY_SIGNAL: i32 = 143;

/// Installs the handler. `polled`: the command checks [`stop_requested`] (the application and
/// the tracker simulator); otherwise a signal ends the process with [`STOPPED_BY_SIGNAL`].
pub fn install(polled: bool) -> Result<(), ctrlc::Error> {
    ctrlc::set_handler(move || {
        // A second signal ends a polling command too: it may be stuck (a hung driver).
        let again = STOP.swap(true, Ordering::SeqCst);
        if !polled || again {
            std::process::exit(STOPPED_BY_SIGNAL);
        }
    })
}

/// The flag the handler sets, for loops that take one.
pub fn flag() -> &'static AtomicBool {
    &STOP
}

/// Whether a termination signal has arrived since [`install`].
pub fn stop_requested() -> bool {
    STOP.load(Ordering::SeqCst)
}

/// Whether the command line runs a command that polls for signals (`run`, `track-sim`, or no
/// command at all, which runs the application), from the raw arguments (before they are
/// parsed, so the handler is in place from the start).
pub fn command_polls(args: impl IntoIterator<Item = String>) -> bool {
    args.into_iter()
        .skip(1)
        .find(|a| !a.starts_with('-'))
        .is_none_or(|command| command == "run" || command == "track-sim")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_polling_commands_are_found_before_parsing() {
        let args = |a: &[&str]| a.iter().map(|s| (*s).to_owned()).collect::<Vec<_>>();
        assert!(command_polls(args(&["omnicave", "run", "--config", "x"])));
        assert!(command_polls(args(&["omnicave", "track-sim"])));
        assert!(!command_polls(args(&[
            "omnicave", "render", "--config", "run"
        ])));
        assert!(command_polls(args(&["omnicave"])));
        assert!(!command_polls(args(&["omnicave", "bench", "--quick"])));
    }
}
