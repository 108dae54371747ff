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
