//! Everything that can stop the application from starting or running.

use crate::cluster::ClusterError;
use crate::config::ConfigError;
use crate::render::RenderError;
use crate::scene::SceneError;

/// Everything that can stop the application from starting or running.
#[derive(Debug, thiserror::Error)]
pub enum AppError {
    #[error(transparent)]
    Config(#[from] ConfigError),
    #[error(transparent)]
    Scene(#[from] SceneError),
    #[error(transparent)]
    Render(#[from] RenderError),
    #[error(transparent)]
    Cluster(#[from] ClusterError),
    #[error("cannot open the window system: {0}")]
    EventLoop(String),
    #[error("cannot create window '{name}': {message}")]
    Window { name: String, message: String },
    #[error("cannot present to window '{name}': {message}")]
    Surface { name: String, message: String },
    #[error("head position {position} is not usable: {problem}")]
    Head {
        position: glam::Vec3,
        problem: String,
    },
}
