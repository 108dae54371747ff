//! The benchmark (`omnicave bench`), one job per file: the methods compared (`methods`), the
//! situations measured (`cases`), measuring them (`measure`), running it all (`run`), the
//! reports (`report`, and `chart` from the output layer), the accuracy against the omnistereo ideal (`accuracy`), the
//! panorama methods (`panorama`), the tracking source heard during the run (`tracking`) and the stability sweep (`stability`, run by
//! `stability_run`). No file imports this one; each imports the siblings it uses.

pub mod accuracy;
pub mod cases;
/// The charts the reports draw (in the output layer, shared with `omnicave guests`).
pub use crate::output::chart;

pub mod cluster;
pub mod error;
pub mod measure;
pub mod methods;
pub mod options;
pub mod panorama;
pub mod report;
pub mod run;
pub mod stability;
pub mod stability_run;
pub mod tracking;

pub use error::BenchError;
pub use measure::{Row, VISIBLE_DIFFERENCE, image_difference_pct, percentile};
pub use methods::{Method, Timer, family, methods, reference_method};
pub use options::{BenchOptions, QUICK_SIZE};
pub use report::{
    MethodSummary, SceneSummary, TARGET_MAX_PX, TARGET_P99_PX, chart_points, summarise,
};
pub use run::{BenchReport, run};
pub use stability_run::{STABILITY_SIZE, StabilityOptions, run_stability};
