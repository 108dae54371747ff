//! The wand ray's mesh: a thin square beam along the ray, cut into short segments (so the
//! omnistereo warp, applied per vertex, bends it as it bends the scene), with a small cube at
//! its tip, a little beyond the beam's end. Fixed counts: the renderer rewrites the same buffer every frame, allocating nothing.

use glam::{Mat4, Vec3};

use super::{Material, Scene, Vertex};
use crate::cave::wand::WandRay;

/// Segments along the beam.
pub const SEGMENTS: usize = 64;
/// The beam's half width, metres (2 cm wide: a few pixels at arm's length on a wall).
pub const BEAM_HALF_WIDTH_M: f32 = 0.01;
/// The tip cube's half side, metres.
pub const TIP_HALF_SIDE_M: f32 = 0.03;
/// The beam stops this far before the tip (at most half the ray), so that it never hides the
/// tip from an eye behind the wand.
pub const TIP_GAP_M: f32 = 0.1;

/// How far along the ray the beam runs.
pub fn beam_length(ray: &WandRay) -> f32 {
    (ray.length - TIP_GAP_M).max(0.5 * ray.length)
}
/// The colours the beam and the tip are drawn in (linear RGB, unlit): green and magenta.
pub const RAY_COLOR: [f32; 3] = [0.05, 1.0, 0.2];
pub const TIP_COLOR: [f32; 3] = [1.0, 0.05, 0.9];
/// Vertices of the mesh: four per ring along the beam, eight for the tip cube.
pub const VERTICES: usize = 4 * (SEGMENTS + 1) + 8;

/// Two unit vectors perpendicular to `d` and to each other.
fn frame(d: Vec3) -> (Vec3, Vec3) {
    let helper = if d.y.abs() < 0.9 { Vec3::Y } else { Vec3::X };
    let u = d.cross(helper).normalize();
    (u, d.cross(u))
}

/// The beam's triangles (indices into its `4 * (SEGMENTS + 1)` vertices).
pub fn beam_indices() -> Vec<u32> {
    let mut out = Vec::with_capacity(SEGMENTS * 4 * 6);
    for s in 0..SEGMENTS as u32 {
        for side in 0..4u32 {
            let (a, b) = (4 * s + side, 4 * s + (side + 1) % 4);
            let (c, d) = (a + 4, b + 4);
            out.extend([a, b, d, a, d, c]);
        }
    }
    out
}

/// The tip cube's triangles (indices into its 8 corners, numbered by bits x, y, z).
pub fn tip_indices() -> Vec<u32> {
    let mut out = Vec::with_capacity(36);
    for [a, b, c, d] in [
        [0, 1, 3, 2],
        [4, 6, 7, 5],
        [0, 4, 5, 1],
        [2, 3, 7, 6],
        [0, 2, 6, 4],
        [1, 5, 7, 3],
    ] {
        out.extend([a, b, c, a, c, d]);
    }
    out
}

/// Writes the mesh's vertex positions for `ray` (CAVE space) in scene space into `out`
/// ([`VERTICES`] long), through `world_from_cave`.
pub fn positions(ray: &WandRay, world_from_cave: Mat4, out: &mut [Vec3]) {
    let (u, v) = frame(ray.direction);
    let corners = [u + v, u - v, -u - v, -u + v].map(|c| c * BEAM_HALF_WIDTH_M);
    let mut k = 0;
    for s in 0..=SEGMENTS {
        let centre = ray.at(beam_length(ray) * s as f32 / SEGMENTS as f32);
        for c in corners {
            if let Some(slot) = out.get_mut(k) {
                *slot = world_from_cave.transform_point3(centre + c);
            }
            k += 1;
        }
    }
    let tip = ray.tip();
    for i in 0..8 {
        let sign = |bit: usize| if i & bit != 0 { 1.0 } else { -1.0 };
        let corner = tip + TIP_HALF_SIDE_M * Vec3::new(sign(1), sign(2), sign(4));
        if let Some(slot) = out.get_mut(k) {
            *slot = world_from_cave.transform_point3(corner);
        }
        k += 1;
    }
}

/// The ray as a scene of its own (unlit, double-sided), laid out as the renderer uploads it
/// once; its positions are rewritten every frame.
pub fn template() -> Scene {
    let mut scene = Scene::default();
    let beam = scene.add_material(Material::unlit("wand ray", RAY_COLOR));
    let tip = scene.add_material(Material::unlit("wand ray tip", TIP_COLOR));
    let vertices = vec![Vertex::default(); 4 * (SEGMENTS + 1)];
    scene.add_mesh(&vertices, &beam_indices(), beam);
    scene.add_mesh(&[Vertex::default(); 8], &tip_indices(), tip);
    scene
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_beam_follows_the_ray_and_ends_in_the_tip_cube() {
        let ray = WandRay {
            origin: Vec3::new(0.0, 1.0, 0.0),
            direction: Vec3::NEG_Z,
            length: 2.0,
        };
        let mut p = vec![Vec3::ZERO; VERTICES];
        positions(&ray, Mat4::IDENTITY, &mut p);
        for ring in 0..=SEGMENTS {
            let centre: Vec3 = p[4 * ring..4 * ring + 4].iter().sum::<Vec3>() / 4.0;
            let want = ray.at(beam_length(&ray) * ring as f32 / SEGMENTS as f32);
            assert!(
                (centre - want).length() < 1e-5,
                "ring {ring}: {centre} vs {want}"
            );
        }
        let tip: Vec3 = p[VERTICES - 8..].iter().sum::<Vec3>() / 8.0;
        assert!((tip - ray.tip()).length() < 1e-5);
        let scene = template();
        assert_eq!(scene.vertices.len(), VERTICES);
        assert!(scene.indices.iter().all(|&i| (i as usize) < VERTICES));
        assert_eq!(scene.indices.len(), SEGMENTS * 24 + 36);
    }
}
