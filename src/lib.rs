//! omnicave: omnidirectional stereo rendering of virtual environments for CAVEs.
//!
//! Layers, with dependencies pointing one way: [`scene`] (glTF → CPU meshes) and [`cave`]
//! (walls, head, eyes, projections) and [`tess`] (tessellation criteria, CPU twin) and [`sky`]
//! (cube maps, the sky's eye model) and [`tracking`] (OSC head tracking, calibration, filter,
//! simulator) and [`gamepad`] (the gamepad mapping) and [`pano`] (the panorama view's
//! cartographic projections) and [`guests`] (the disparity distortion guests see) know nothing
//! of the GPU or windows;
//! [`render`] owns GPU resources; [`output`] composes eye images and draws charts;
//! [`headless`], [`bench`] and `guests::report` tie them together for the CLI; [`app`] owns
//! windows, the control panel and input devices.

pub mod app;
pub mod bench;
pub mod cave;
pub mod cluster;
pub mod config;
pub mod docs;
pub mod gamepad;
pub mod guests;
pub mod headless;
pub mod messages;
pub mod named;
pub mod output;
pub mod pano;
pub mod read_capped;
pub mod render;
pub mod scene;
pub mod setup;
pub mod signals;
pub mod sky;
pub mod tess;
pub mod tracking;
