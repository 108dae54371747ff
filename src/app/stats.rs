//! Frame-time statistics: CPU and GPU time and frame rate over the last second, shown by the
//! panel and logged by `--stats-every`.

use std::time::{Duration, Instant};

/// Rolling frame statistics.
#[derive(Debug, Clone)]
pub struct FrameClock {
    window_start: Instant,
    frames: u32,
    cpu_ms_sum: f64,
    gpu_ms_sum: f64,
    gpu_samples: u32,
    /// Figures of the last completed window.
    pub summary: StatsSummary,
    /// Frames rendered since start.
    pub total_frames: u64,
}

/// Averages over one window (about a second).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct StatsSummary {
    pub fps: f64,
    /// CPU time to record and submit a frame (all walls and windows), ms.
    pub cpu_ms: f64,
    /// GPU time of the walls' rendering, ms (`None` without timestamps).
    pub gpu_ms: Option<f64>,
    /// Time between frames, ms.
    pub frame_ms: f64,
}

/// Length of the averaging window.
const WINDOW: Duration = Duration::from_secs(1);

impl Default for FrameClock {
    fn default() -> Self {
        Self::new()
    }
}

impl FrameClock {
    pub fn new() -> Self {
        Self {
            window_start: Instant::now(),
            frames: 0,
            cpu_ms_sum: 0.0,
            gpu_ms_sum: 0.0,
            gpu_samples: 0,
            summary: StatsSummary::default(),
            total_frames: 0,
        }
    }

    /// Records a finished frame: its CPU time and the newest GPU time available.
    pub fn record(&mut self, now: Instant, cpu: Duration, gpu_ms: Option<f64>) {
        self.frames += 1;
        self.total_frames += 1;
        self.cpu_ms_sum += cpu.as_secs_f64() * 1e3;
        if let Some(g) = gpu_ms {
            self.gpu_ms_sum += g;
            self.gpu_samples += 1;
        }
        let elapsed = now.duration_since(self.window_start);
        if elapsed >= WINDOW {
            let n = f64::from(self.frames);
            let secs = elapsed.as_secs_f64();
            self.summary = StatsSummary {
                fps: n / secs,
                cpu_ms: self.cpu_ms_sum / n,
                gpu_ms: (self.gpu_samples > 0)
                    .then(|| self.gpu_ms_sum / f64::from(self.gpu_samples)),
                frame_ms: secs * 1e3 / n,
            };
            self.window_start = now;
            self.frames = 0;
            self.cpu_ms_sum = 0.0;
            self.gpu_ms_sum = 0.0;
            self.gpu_samples = 0;
        }
    }
}

impl std::fmt::Display for StatsSummary {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "{:.1} fps, frame {:.1} ms, cpu {:.2} ms, gpu {}",
            self.fps,
            self.frame_ms,
            self.cpu_ms,
            self.gpu_ms
                .map_or_else(|| "n/a".to_owned(), |g| format!("{g:.2} ms"))
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn summary_averages_over_the_window() {
        let mut clock = FrameClock::new();
        let t0 = clock.window_start;
        for i in 1..=10 {
            clock.record(
                t0 + Duration::from_millis(110 * i),
                Duration::from_millis(4),
                Some(20.0),
            );
        }
        let s = clock.summary;
        // 10 frames over 1.1 s.
        assert!((s.fps - 10.0 / 1.1).abs() < 1e-6, "{s}");
        assert!((s.cpu_ms - 4.0).abs() < 1e-9);
        assert_eq!(s.gpu_ms, Some(20.0));
        assert!((s.frame_ms - 110.0).abs() < 1e-6);
    }
}

/// Frames kept in the panel's timing plot.
pub const HISTORY_FRAMES: usize = 300;

/// The last [`HISTORY_FRAMES`] frames' times and tracking latencies (x: seconds since start),
/// for the panel's plot. Fixed capacity: recording a frame allocates nothing.
#[derive(Debug, Clone)]
pub struct TimingHistory {
    pub frame_ms: Vec<egui_plot::PlotPoint>,
    pub latency_ms: Vec<egui_plot::PlotPoint>,
}

impl Default for TimingHistory {
    fn default() -> Self {
        Self {
            frame_ms: Vec::with_capacity(HISTORY_FRAMES),
            latency_ms: Vec::with_capacity(HISTORY_FRAMES),
        }
    }
}

impl TimingHistory {
    /// Records a frame at `t` seconds: its time, and the tracking latency of the pose it used
    /// (`None` without tracking).
    pub fn record(&mut self, t: f64, frame_ms: f64, latency_ms: Option<f64>) {
        let push = |series: &mut Vec<egui_plot::PlotPoint>, y: f64| {
            if series.len() == HISTORY_FRAMES {
                series.remove(0);
            }
            series.push(egui_plot::PlotPoint::new(t, y));
        };
        if frame_ms.is_finite() {
            push(&mut self.frame_ms, frame_ms);
        }
        if let Some(l) = latency_ms.filter(|l| l.is_finite()) {
            push(&mut self.latency_ms, l);
        }
    }
}

#[cfg(test)]
mod history_tests {
    use super::*;

    #[test]
    fn the_history_keeps_the_last_frames_without_growing() {
        let mut h = TimingHistory::default();
        for i in 0..1000 {
            h.record(f64::from(i), 16.0, (i % 2 == 0).then_some(5.0));
        }
        assert_eq!(h.frame_ms.len(), HISTORY_FRAMES);
        assert_eq!(h.frame_ms.capacity(), HISTORY_FRAMES);
        assert_eq!(h.frame_ms[0].x, 700.0);
        assert_eq!(h.latency_ms.len(), HISTORY_FRAMES);
    }
}
