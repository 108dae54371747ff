//! The config's tracking source running beside the bench: what it received, accepted and
//! refused (per reason), and whether it lost the head, while the bench loads the machine.

use std::path::Path;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use super::error::BenchError;
use super::report::write_csv;
use crate::cave::Cave;
use crate::config::Config;
use crate::tracking::{Counters, GateCounters, HeadTracker, TrackingSource, TrackingStats};

/// How often the watch takes the newest sample, as a 120 Hz render loop would.
const POLL_INTERVAL: Duration = Duration::from_micros(8_333);

/// What the tracking source did during the run.
#[derive(Debug, Clone)]
pub struct TrackingFigures {
    /// The source in words ("OSC on 0.0.0.0:7000").
    pub source: String,
    /// How long it ran, seconds.
    pub seconds: f64,
    pub counters: Counters,
    pub stats: TrackingStats,
    /// Its link when the run ended ("listening", "connected", "reconnecting to …").
    pub link: String,
    /// It listens on a network address and takes tracking from anyone.
    pub open_warning: Option<String>,
}

/// Why there are no figures, or what they are.
#[derive(Debug, Clone)]
pub enum TrackingOutcome {
    /// `[tracking] enabled = false`: the bench ran without a source.
    Off,
    /// The source could not start (the reason).
    Failed(String),
    Ran(Box<TrackingFigures>),
}

/// The source running on its own threads, polled by a watch thread until [`Self::finish`].
#[derive(Debug)]
pub struct TrackingWatch {
    stop: Arc<AtomicBool>,
    thread: JoinHandle<TrackingFigures>,
}

/// A started watch, or why there is none.
#[derive(Debug)]
pub enum Watching {
    Started(TrackingWatch),
    NotStarted(TrackingOutcome),
}

impl Watching {
    /// Starts the config's tracking source when `[tracking] enabled`; a source that cannot start
    /// (its port taken, say) is reported, not fatal: the bench still measures the walls.
    pub fn start(config: &Config) -> Self {
        let tracking = &config.tracking;
        if !tracking.enabled {
            return Self::NotStarted(TrackingOutcome::Off);
        }
        let source = match TrackingSource::start(&tracking.source, &tracking.receiver) {
            Ok(source) => source,
            Err(e) => {
                tracing::warn!("the bench runs without tracking: {e}");
                return Self::NotStarted(TrackingOutcome::Failed(e.to_string()));
            }
        };
        let bounds = Cave::head_bounds(&config.cave.walls);
        source
            .feed()
            .configure(tracking.settings.gate(Some(bounds)));
        let stop = Arc::new(AtomicBool::new(false));
        let mut tracker = HeadTracker::new(tracking.settings);
        let stop_flag = Arc::clone(&stop);
        let thread = std::thread::Builder::new()
            .name("bench tracking watch".into())
            .spawn(move || {
                let start = Instant::now();
                while !stop_flag.load(Ordering::Relaxed) {
                    let sample = source.feed().try_latest();
                    let _ = tracker.update(sample, Instant::now(), Some(bounds));
                    std::thread::sleep(POLL_INTERVAL);
                }
                TrackingFigures {
                    source: source.describe(),
                    seconds: start.elapsed().as_secs_f64(),
                    counters: source.feed().counters(),
                    stats: tracker.stats(),
                    link: source.link().describe(),
                    open_warning: source.open_warning(),
                }
            });
        match thread {
            Ok(thread) => Self::Started(TrackingWatch { stop, thread }),
            Err(e) => Self::NotStarted(TrackingOutcome::Failed(format!(
                "cannot start the tracking watch thread: {e}"
            ))),
        }
    }

    /// Stops the source and gives what it did.
    pub fn finish(self) -> TrackingOutcome {
        match self {
            Self::NotStarted(outcome) => outcome,
            Self::Started(watch) => {
                watch.stop.store(true, Ordering::Relaxed);
                match watch.thread.join() {
                    Ok(figures) => TrackingOutcome::Ran(Box::new(figures)),
                    Err(_) => TrackingOutcome::Failed("the tracking watch thread panicked".into()),
                }
            }
        }
    }
}

/// The columns of `tracking.csv`: the packets, then every gate refusal by reason
/// (`unconfirmed_jump`: the reason's words joined by `_`).
fn csv_header() -> Vec<String> {
    let mut header: Vec<String> = [
        "source",
        "seconds",
        "received",
        "accepted",
        "ignored",
        "malformed",
        "non_finite",
        "refused",
        "socket_errors",
    ]
    .map(String::from)
    .to_vec();
    header.extend(
        GateCounters::default()
            .by_reason()
            .map(|(name, _)| name.replace([' ', '-'], "_")),
    );
    header.extend(["rate_hz", "lost_events", "clamped", "link"].map(String::from));
    header
}

/// `tracking.csv`: one row for the source that ran (none when tracking was off or failed).
pub fn write_tracking_csv(path: &Path, outcome: &TrackingOutcome) -> Result<(), BenchError> {
    let rows = match outcome {
        TrackingOutcome::Ran(f) => {
            let c = &f.counters;
            let mut row = vec![
                f.source.clone(),
                format!("{:.1}", f.seconds),
                c.received.to_string(),
                c.accepted.to_string(),
                c.ignored.to_string(),
                c.malformed.to_string(),
                c.non_finite.to_string(),
                c.refused.to_string(),
                c.socket_errors.to_string(),
            ];
            row.extend(c.gate.by_reason().map(|(_, n)| n.to_string()));
            row.extend([
                format!("{:.1}", f.stats.rate_hz),
                f.stats.lost_events.to_string(),
                f.stats.clamped.to_string(),
                f.link.clone(),
            ]);
            vec![row]
        }
        TrackingOutcome::Off | TrackingOutcome::Failed(_) => Vec::new(),
    };
    let header = csv_header();
    let header: Vec<&str> = header.iter().map(String::as_str).collect();
    write_csv(path, &header, rows)
}

/// The report's tracking section.
pub fn tracking_markdown(outcome: &TrackingOutcome) -> String {
    let mut md = String::from("\n## Tracking during the run\n\n");
    match outcome {
        TrackingOutcome::Off => md.push_str(
            "Tracking is off in this config (`[tracking] enabled = false`): no source ran. \
             Switch it on to see what the tracker sent, and what the gate refused, while the \
             machine renders at full load.\n",
        ),
        TrackingOutcome::Failed(why) => {
            md.push_str(&format!("The tracking source could not start: {why}.\n"));
        }
        TrackingOutcome::Ran(f) => {
            let c = &f.counters;
            md.push_str(&format!(
                "{} ran for {:.1} s beside the bench, {} at the end (`tracking.csv`).\n\n\
                 | packets received | accepted | ignored | malformed | non-finite | not allowed \
                 | head lost | head samples, last second |\n\
                 |---:|---:|---:|---:|---:|---:|---:|---:|\n\
                 | {} | {} | {} | {} | {} | {} | {} times | {:.1} Hz |\n\n",
                f.source,
                f.seconds,
                f.link,
                c.received,
                c.accepted,
                c.ignored,
                c.malformed,
                c.non_finite,
                c.refused,
                f.stats.lost_events,
                f.stats.rate_hz
            ));
            md.push_str(&format!(
                "Samples the gate refused: {} ({} in all).\n",
                c.gate.describe(),
                c.gate.total()
            ));
            if c.received == 0 {
                md.push_str(
                    "\nNothing arrived: is the tracker sending to this address, and is the \
                     port open in the firewall?\n",
                );
            }
            if let Some(warning) = &f.open_warning {
                md.push_str(&format!("\n**Open to the network**: {warning}.\n"));
            }
        }
    }
    md
}
