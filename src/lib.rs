//! omnicave: omnidirectional stereo rendering of virtual environments for CAVEs.
//!
//! Layers, with dependencies pointing one way: [`scene`] (glTF → CPU meshes) and [`cave`]
//! (walls, head, eyes, projections) know nothing of the GPU; [`output`] composes eye images.

pub mod cave;
pub mod config;
pub mod output;
pub mod scene;
