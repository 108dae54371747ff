//! The panorama view (wide field of view up to 360°): cartographic projections of the
//! directions around the viewer onto one image, without GPU types (the render layer's
//! panorama passes use these as their CPU twin).

pub mod projection;

pub use projection::{PanoProjection, Projection, direction, lon_lat};
