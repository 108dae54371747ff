//! A virtual X server for the window tests (Xvfb), with whole-screen screenshots.

use std::path::Path;
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use image::RgbImage;

/// One virtual X server at a time (two starting at once could pick the same display).
pub static X_SERVER: std::sync::Mutex<()> = std::sync::Mutex::new(());

/// An Xvfb server on a free display, killed on drop.
pub struct Xvfb {
    child: Child,
    pub display: String,
}

impl Xvfb {
    /// Starts one with a screen of `size` pixels.
    pub fn start(size: [u32; 2]) -> Xvfb {
        Xvfb::start_with(size, &[])
    }

    /// Starts one without the MIT-SHM extension, as a container's or remote display's X
    /// server is: Mesa's software swapchain then presents with plain `PutImage`, whose errors
    /// on a destroyed window reach winit's error handler (CI's run showed this).
    #[allow(dead_code)] // used by some of the test binaries that include this module
    pub fn start_without_shm(size: [u32; 2]) -> Xvfb {
        Xvfb::start_with(size, &["-extension", "MIT-SHM"])
    }

    fn start_with(size: [u32; 2], extra_args: &[&str]) -> Xvfb {
        for n in 90..140 {
            if Path::new(&format!("/tmp/.X{n}-lock")).exists()
                || Path::new(&format!("/tmp/.X11-unix/X{n}")).exists()
            {
                continue;
            }
            #[allow(clippy::zombie_processes)] // killed and waited for on drop
            let child = Command::new("Xvfb")
                .arg(format!(":{n}"))
                .args(["-screen", "0", &format!("{}x{}x24", size[0], size[1])])
                .args(["-nolisten", "tcp"])
                .args(extra_args)
                .stdout(Stdio::null())
                .stderr(Stdio::null())
                .spawn()
                .expect("Xvfb must be installed (scripts/setup.sh installs it)");
            let socket = format!("/tmp/.X11-unix/X{n}");
            let start = Instant::now();
            while start.elapsed() < Duration::from_secs(10) {
                if Path::new(&socket).exists() {
                    return Xvfb {
                        child,
                        display: format!(":{n}"),
                    };
                }
                std::thread::sleep(Duration::from_millis(50));
            }
            panic!("Xvfb :{n} did not start");
        }
        panic!("no free X display");
    }

    /// The whole screen, through xwd and ImageMagick (written to `path`).
    pub fn screenshot(&self, path: &Path) -> RgbImage {
        let status = Command::new("sh")
            .arg("-c")
            .arg(format!(
                "xwd -root -silent -display {} | /usr/bin/convert xwd:- png:{}",
                self.display,
                path.display()
            ))
            .status()
            .expect("xwd and ImageMagick (x11-apps, imagemagick) must be installed");
        assert!(status.success(), "screenshot failed");
        image::open(path).expect("screenshot png").to_rgb8()
    }
}

impl Drop for Xvfb {
    fn drop(&mut self) {
        // SIGTERM lets Xvfb remove its lock file and socket (SIGKILL would leave them, and
        // repeated runs on one machine would use up the display numbers); SIGKILL if it hangs.
        let _ = Command::new("kill")
            .args(["-TERM", &self.child.id().to_string()])
            .status();
        let start = Instant::now();
        while start.elapsed() < Duration::from_secs(3) {
            if let Ok(Some(_)) = self.child.try_wait() {
                return;
            }
            std::thread::sleep(Duration::from_millis(20));
        }
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// Focuses `window` on `display` and presses the key of `keysym` in it through XTEST, as a
/// keyboard would (KeyPress, then KeyRelease).
pub fn press_key(display: &str, window: u32, keysym: u32) {
    use x11rb::connection::Connection;
    use x11rb::protocol::xproto::{ConnectionExt, InputFocus};
    use x11rb::protocol::xtest::ConnectionExt as _;
    let (conn, _) = x11rb::connect(Some(display)).expect("X connection");
    conn.set_input_focus(InputFocus::PARENT, window, x11rb::CURRENT_TIME)
        .expect("focus");
    // The key's code in the server's keymap.
    let setup = conn.setup();
    let (min, max) = (setup.min_keycode, setup.max_keycode);
    let map = conn
        .get_keyboard_mapping(min, max - min + 1)
        .expect("keymap")
        .reply()
        .expect("keymap");
    let per = usize::from(map.keysyms_per_keycode);
    let index = map
        .keysyms
        .iter()
        .position(|&k| k == keysym)
        .expect("the key in the keymap");
    let code = min + (index / per) as u8;
    for event in [2u8, 3] {
        conn.xtest_fake_input(event, code, x11rb::CURRENT_TIME, window, 0, 0, 0)
            .expect("XTEST");
        conn.flush().expect("flush");
        std::thread::sleep(Duration::from_millis(100));
    }
}
