//! Keeps X errors about windows that are already gone from reaching winit as stale errors.
//!
//! When another client destroys one of our windows (`xdotool windowclose`, a window manager's
//! kill), the frame being drawn still presents to it. Without MIT-SHM (containers, remote
//! displays) Mesa's software swapchain presents with `PutImage`, and the server answers with
//! `BadDrawable`. That error arrives asynchronously, so winit's Xlib error handler stores it
//! as "the latest error", and winit's next checked call (destroying the window's input context
//! when it reads the `DestroyNotify`) takes it for its own failure and panics: the whole program
//! ended because one wall's window went. An error naming a window or drawable that does not
//! exist can only concern a window that is gone, which the application learns from the
//! `Destroyed` event (or from a failed present) and handles; so such errors are handled here.

// `register_xlib_error_hook` hands the hook raw pointers to Xlib's `XErrorEvent`: reading its
// codes is the one unsafe operation, on a pointer Xlib guarantees for the hook's duration.
#![allow(unsafe_code)]

use std::sync::Once;
use std::sync::atomic::{AtomicBool, Ordering};

/// X protocol error codes (X11 protocol, "Errors"): the resource named in the request is not
/// a window / not a window or pixmap.
const BAD_WINDOW: u8 = 3;
const BAD_DRAWABLE: u8 = 9;

/// Whether an X error with this code is about a window or drawable that no longer exists.
pub fn concerns_a_gone_window(error_code: u8) -> bool {
    matches!(error_code, BAD_WINDOW | BAD_DRAWABLE)
}

/// Registers the hook with winit, once per process (before or after the event loop starts).
pub fn install() {
    static INSTALLED: Once = Once::new();
    INSTALLED.call_once(|| {
        winit::platform::x11::register_xlib_error_hook(Box::new(|_display, event| {
            if event.is_null() {
                return false;
            }
            // SAFETY: winit passes Xlib's `XErrorEvent` for the duration of the call; the
            // pointer is non-null and only read.
            let event = unsafe { &*(event as *const x11_dl::xlib::XErrorEvent) };
            if !concerns_a_gone_window(event.error_code) {
                return false;
            }
            // The first one is worth seeing (a bug of ours would show here too); the rest of a
            // window's last frame repeats it.
            static SEEN: AtomicBool = AtomicBool::new(false);
            if SEEN.swap(true, Ordering::Relaxed) {
                tracing::debug!(
                    "X error {} (request {}.{}) on resource {:#x}: a window that is gone; \
                     ignored",
                    event.error_code,
                    event.request_code,
                    event.minor_code,
                    event.resourceid
                );
            } else {
                tracing::info!(
                    "X error {} (request {}.{}) on resource {:#x}: a window that is gone; \
                     ignored (further ones are logged at debug level)",
                    event.error_code,
                    event.request_code,
                    event.minor_code,
                    event.resourceid
                );
            }
            true
        }));
    });
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn only_errors_naming_a_missing_window_or_drawable_are_handled() {
        assert!(concerns_a_gone_window(BAD_WINDOW));
        assert!(concerns_a_gone_window(BAD_DRAWABLE));
        // BadRequest, BadValue, BadMatch, BadAlloc, BadImplementation: winit's to see.
        for code in [1, 2, 8, 11, 17] {
            assert!(!concerns_a_gone_window(code), "{code}");
        }
    }
}
