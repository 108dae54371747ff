//! The scene points a map judges: what the assumed head sees of the scene (one ray per
//! direction of a Fibonacci sphere, its first hit), or shells of points at given distances.

use glam::{DMat4, DVec3, Mat4};

use crate::pano::raycast::RayCaster;
use crate::scene::Scene;

/// `count` directions spread evenly over the sphere (the Fibonacci lattice), unit length.
pub fn fibonacci_directions(count: usize) -> Vec<DVec3> {
    let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
    (0..count)
        .map(|i| {
            let y = 1.0 - 2.0 * (i as f64 + 0.5) / count as f64;
            let r = (1.0 - y * y).max(0.0).sqrt();
            let a = golden * i as f64;
            DVec3::new(r * a.cos(), y, r * a.sin())
        })
        .collect()
}

/// Points on spheres of the given radii (metres) around `centre`, `count` in all, shared
/// evenly between the shells (each shell's directions turned so the shells do not align).
pub fn shells(centre: DVec3, radii: &[f64], count: usize) -> Vec<DVec3> {
    if radii.is_empty() {
        return Vec::new();
    }
    let per_shell = count.div_ceil(radii.len()).max(1);
    let directions = fibonacci_directions(per_shell);
    radii
        .iter()
        .enumerate()
        .flat_map(|(k, &r)| {
            let turn = glam::DQuat::from_rotation_y(k as f64 * 0.7);
            directions.iter().map(move |&d| centre + r * (turn * d))
        })
        .take(count)
        .collect()
}

/// What `eye` sees of `scene` (CAVE space through `cave_from_world`): the first surface along
/// each of `count` evenly spread directions, within `far` metres.
pub fn visible_surface(
    scene: &Scene,
    cave_from_world: Mat4,
    eye: DVec3,
    count: usize,
    far: f64,
) -> Vec<DVec3> {
    visible_from(
        &RayCaster::new(scene, cave_from_world),
        eye,
        count,
        far,
        DMat4::IDENTITY,
    )
}

/// [`visible_surface`] with the scene's ray caster already built, in its own space: `eye` and
/// the returned points are in the caster's space, the directions spread evenly in the space
/// `caster_from_spread` maps from (the CAVE's, for a caster built in the scene's space).
pub fn visible_from(
    caster: &RayCaster,
    eye: DVec3,
    count: usize,
    far: f64,
    caster_from_spread: DMat4,
) -> Vec<DVec3> {
    let origin = eye.as_vec3();
    fibonacci_directions(count)
        .into_iter()
        .filter_map(|d| {
            let d = caster_from_spread.transform_vector3(d).try_normalize()?;
            let hit = caster.cast(origin, d.as_vec3(), 1e-4, far as f32)?;
            Some(eye + f64::from(hit.distance) * d)
        })
        .collect()
}
