//! What stops the benchmark.

use std::path::PathBuf;

use crate::config::ConfigError;
use crate::render::RenderError;
use crate::scene::SceneError;
use crate::sky::SkyError;

/// Anything that stops the benchmark.
#[derive(Debug, thiserror::Error)]
pub enum BenchError {
    #[error(transparent)]
    Config(#[from] ConfigError),
    #[error(transparent)]
    Scene(#[from] SceneError),
    #[error(transparent)]
    Sky(#[from] SkyError),
    #[error(transparent)]
    Render(#[from] RenderError),
    #[error("cannot write {path}: {source}")]
    Write {
        path: PathBuf,
        source: std::io::Error,
    },
    #[error("cannot write the table {path}: {message}")]
    Csv { path: PathBuf, message: String },
    #[error(
        "the reference render of scene {scene} is one flat colour {colour:?} on every wall and \
         eye: every method would read 0 % of pixels off it; is the model in view, lit and \
         placed (see [scene] fit)?"
    )]
    DegenerateRender { scene: String, colour: [u8; 3] },
    #[error("--method: no method is named '{name}'; the methods are {known}")]
    UnknownMethod { name: String, known: String },
    #[error(transparent)]
    Cluster(crate::cluster::ClusterError),
    #[error("cannot draw the chart {path}: {message}")]
    Chart { path: PathBuf, message: String },
}
