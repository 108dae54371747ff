//! `omnicave monitors`: the monitors the window system reports, in the order and with the
//! names that `[[wall]] monitor` (an index or a name) refers to.

use winit::application::ApplicationHandler;
use winit::event::WindowEvent;
use winit::event_loop::{ActiveEventLoop, EventLoop};
use winit::window::WindowId;

use super::error::AppError;

/// One monitor as `[[wall]] monitor` can name it.
#[derive(Debug, Clone, PartialEq)]
pub struct MonitorInfo {
    pub index: usize,
    pub name: Option<String>,
    pub size: [u32; 2],
    pub position: [i32; 2],
    pub refresh_hz: Option<f64>,
    pub scale_factor: f64,
}

impl std::fmt::Display for MonitorInfo {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "{}: {} {}×{} at ({}, {})",
            self.index,
            self.name
                .as_deref()
                .map_or_else(|| "(no name)".to_owned(), |n| format!("\"{n}\"")),
            self.size[0],
            self.size[1],
            self.position[0],
            self.position[1]
        )?;
        if let Some(hz) = self.refresh_hz {
            write!(f, ", {hz:.2} Hz")?;
        }
        write!(f, ", scale {}", self.scale_factor)
    }
}

#[derive(Default)]
struct Lister {
    found: Option<Vec<MonitorInfo>>,
}

impl ApplicationHandler for Lister {
    fn resumed(&mut self, event_loop: &ActiveEventLoop) {
        let monitors = event_loop
            .available_monitors()
            .enumerate()
            .map(|(index, m)| {
                let size = m.size();
                let position = m.position();
                MonitorInfo {
                    index,
                    name: m.name(),
                    size: [size.width, size.height],
                    position: [position.x, position.y],
                    refresh_hz: m
                        .refresh_rate_millihertz()
                        .map(|mhz| f64::from(mhz) / 1000.0),
                    scale_factor: m.scale_factor(),
                }
            })
            .collect();
        self.found = Some(monitors);
        event_loop.exit();
    }

    fn window_event(&mut self, _: &ActiveEventLoop, _: WindowId, _: WindowEvent) {}
}

/// The monitors, as the window system lists them to `omnicave run`.
pub fn list_monitors() -> Result<Vec<MonitorInfo>, AppError> {
    let event_loop = EventLoop::new().map_err(|e| AppError::EventLoop(e.to_string()))?;
    let mut lister = Lister::default();
    event_loop
        .run_app(&mut lister)
        .map_err(|e| AppError::EventLoop(e.to_string()))?;
    lister
        .found
        .ok_or_else(|| AppError::EventLoop("the window system listed no monitors".into()))
}
