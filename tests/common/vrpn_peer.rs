//! The real VRPN server from `../shared/peers`, built by `scripts/vrpn-server.sh` (cached outside
//! the clone), run on a free port with a config of VRPN's own test devices and its DTrack
//! driver (which we feed DTrack frames, so it serves poses, buttons and analogs we chose).

use std::io::Write;
use std::net::{TcpListener, UdpSocket};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::sync::OnceLock;
use std::time::{Duration, Instant};

/// The built `vrpn_server`, or `None` (with a SKIPPED line) where `../shared/peers` is absent;
/// CI has it and must not skip.
pub fn server_binary() -> Option<PathBuf> {
    static BINARY: OnceLock<Option<PathBuf>> = OnceLock::new();
    BINARY
        .get_or_init(|| {
            let root = Path::new(env!("CARGO_MANIFEST_DIR"));
            let peers = root.join("../shared/peers");
            let has_tarball = std::fs::read_dir(&peers).is_ok_and(|d| {
                d.flatten()
                    .any(|e| e.file_name().to_string_lossy().starts_with("vrpn-"))
            });
            if !has_tarball {
                let msg = format!(
                    "SKIPPED: {} has no vrpn-*.tar.gz (the shared peers)",
                    peers.display()
                );
                assert!(
                    std::env::var_os("CI").is_none(),
                    "{msg}, and CI must not skip"
                );
                eprintln!("{msg}");
                return None;
            }
            let out = Command::new("bash")
                .arg(root.join("scripts/vrpn-server.sh"))
                .stderr(Stdio::inherit())
                .output()
                .expect("run scripts/vrpn-server.sh");
            assert!(out.status.success(), "scripts/vrpn-server.sh failed");
            let path = PathBuf::from(String::from_utf8_lossy(&out.stdout).trim());
            assert!(path.is_file(), "{} was not built", path.display());
            Some(path)
        })
        .clone()
}

/// A port free for both TCP and UDP (VRPN listens on both).
pub fn free_port() -> u16 {
    loop {
        let tcp = TcpListener::bind("127.0.0.1:0").expect("tcp");
        let port = tcp.local_addr().expect("addr").port();
        if UdpSocket::bind(("0.0.0.0", port)).is_ok() {
            return port;
        }
    }
}

/// A running `vrpn_server`, killed on drop.
pub struct VrpnServer {
    child: Child,
    pub port: u16,
    /// The UDP port its DTrack driver listens on.
    pub dtrack_port: u16,
    config: PathBuf,
    binary: PathBuf,
}

impl VrpnServer {
    /// Serves `Spin0` (2 sensors spinning about y at 0.25 Hz, 100 reports/s), `Button0` (two
    /// buttons toggling 4 times a second) and `DTrack` (fed by [`Self::send_dtrack`]).
    pub fn start(binary: &Path, port: u16) -> Self {
        let dtrack_port = free_port();
        let dir = std::env::temp_dir().join(format!("omnicave-vrpn-{}-{port}", std::process::id()));
        std::fs::create_dir_all(&dir).expect("config dir");
        let config = dir.join("vrpn.cfg");
        let mut f = std::fs::File::create(&config).expect("config");
        writeln!(f, "vrpn_Tracker_Spin\tSpin0\t2\t100.0\t0.0 1.0 0.0\t0.25").expect("write");
        writeln!(f, "vrpn_Button_Example\tButton0\t2\t4.0").expect("write");
        // Fixed numbers: 1 body then 1 flystick, so the flystick is sensor 1.
        writeln!(f, "vrpn_Tracker_DTrack\tDTrack\t{dtrack_port}\t0.5\t1 1").expect("write");
        drop(f);
        let mut server = Self {
            child: spawn(binary, &config, port),
            port,
            dtrack_port,
            config,
            binary: binary.to_owned(),
        };
        server.wait_listening();
        server
    }

    /// Kills the server and starts it again on the same port.
    pub fn restart(&mut self) {
        self.kill();
        self.child = spawn(&self.binary, &self.config, self.port);
        self.wait_listening();
    }

    /// Sends `signal` (`STOP`, `CONT`) to the server: a hung server, and its return.
    pub fn signal(&self, signal: &str) {
        let status = Command::new("kill")
            .arg(format!("-{signal}"))
            .arg(self.child.id().to_string())
            .status()
            .expect("kill");
        assert!(status.success(), "kill -{signal}");
    }

    pub fn kill(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }

    fn wait_listening(&mut self) {
        let start = Instant::now();
        // Its TCP port bound means the devices are set up (they are created first).
        while start.elapsed() < Duration::from_secs(10) {
            if let Ok(Some(status)) = self.child.try_wait() {
                panic!("vrpn_server exited: {status}");
            }
            if TcpListener::bind(("0.0.0.0", self.port)).is_err() {
                return;
            }
            std::thread::sleep(Duration::from_millis(20));
        }
        panic!("vrpn_server did not listen on {} within 10 s", self.port);
    }

    /// Sends one DTrack frame to the server's DTrack driver.
    pub fn send_dtrack(&self, frame: &str) {
        let s = UdpSocket::bind("127.0.0.1:0").expect("udp");
        s.send_to(frame.as_bytes(), ("127.0.0.1", self.dtrack_port))
            .expect("send dtrack");
    }
}

fn spawn(binary: &Path, config: &Path, port: u16) -> Child {
    Command::new(binary)
        .arg("-f")
        .arg(config)
        .arg("-quiet")
        .arg("-millisleep")
        .arg("1")
        .arg(port.to_string())
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .expect("start vrpn_server")
}

impl Drop for VrpnServer {
    fn drop(&mut self) {
        self.kill();
        if let Some(dir) = self.config.parent() {
            let _ = std::fs::remove_dir_all(dir);
        }
    }
}

/// A DTrack frame with one body and one flystick, as the manual writes them (mm; the rotation
/// matrix column by column).
pub fn dtrack_frame(
    frame: u64,
    body_mm: [f64; 3],
    body_rot: [f64; 9],
    stick_mm: [f64; 3],
    buttons: u32,
    joystick: [f64; 2],
) -> String {
    let m = |r: &[f64; 9]| {
        r.iter()
            .map(|v| format!("{v:.6}"))
            .collect::<Vec<_>>()
            .join(" ")
    };
    let identity = [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0];
    format!(
        "fr {frame}\r\nts 39596.024831\r\n6dcal 2\r\n6d 1 [0 1.000][{:.3} {:.3} {:.3}][{}]\r\n\
         6df2 1 1 [0 1.000 6 2][{:.3} {:.3} {:.3}][{}][{buttons} {:.2} {:.2}]\r\n",
        body_mm[0],
        body_mm[1],
        body_mm[2],
        m(&body_rot),
        stick_mm[0],
        stick_mm[1],
        stick_mm[2],
        m(&identity),
        joystick[0],
        joystick[1],
    )
}
