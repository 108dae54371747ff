//! The sky's eye model on the CPU: which direction each wall point shows, per sky mode. The
//! sky shader (shaders/sky.wgsl) computes the same; tests compare the GPU against these.
//!
//! The sky is at infinity. In omnistereo a direction d is seen by the eye
//! E(d) = H + σ(d)·right(d_xz), σ = ±IPD/2 faded by the pole merge at d's elevation: exactly
//! the eye the geometry warp gives a vertex infinitely far away in direction d
//! (`cave::omni::omni_eye`), so sky and scene agree. A wall point P therefore shows the
//! direction d with E(d) + t·d = P. The ray E→P is tangent to the circle of radius |σ| around
//! the head, which is solved in closed form (the fade is resolved by a fixed-point iteration
//! that converges in two steps, since it only depends on the elevation).
//!
//! The thesis (6.3) instead takes the eye of P's own head direction (`omni_eye(H, P)`); that
//! is off by about the tangent angle |σ|/|P − H| and shifts the sky by up to a pixel near a
//! wall, so the exact tangent form is used by both omnistereo sky modes here.

use glam::{Vec2, Vec3};

use crate::cave::omni::{PoleMerge, omni_eye, pole_merge_factor};
use crate::cave::{Eye, Wall};

/// The eye that sees the sky in direction `dir` (forward model, as the geometry warp has it).
pub fn sky_eye(head: Vec3, dir: Vec3, ipd: f32, eye: Eye, pole: Option<PoleMerge>) -> Vec3 {
    omni_eye(head, head + dir, ipd, eye, pole)
}

/// Omnistereo lookup vector for wall point `p`: `p − E` with E the eye whose direction of view
/// passes through `p` (not normalised). `signed_half_ipd` is −IPD/2 for the left eye, +IPD/2
/// for the right, 0 for mono.
pub fn omni_lookup(p: Vec3, head: Vec3, signed_half_ipd: f32, pole: Option<PoleMerge>) -> Vec3 {
    p - omni_sky_eye_of_point(p, head, signed_half_ipd, pole)
}

/// The eye E with E + t·d = p for d the direction E sees through `p` (see the module text).
pub fn omni_sky_eye_of_point(
    p: Vec3,
    head: Vec3,
    signed_half_ipd: f32,
    pole: Option<PoleMerge>,
) -> Vec3 {
    let q = Vec2::new(p.x - head.x, p.z - head.z);
    let l2 = q.length_squared();
    if l2 < 1e-18 {
        return head;
    }
    let dy = (p.y - head.y).abs();
    // Fixed point on the elevation: start from the head's, refine twice.
    let mut sigma = signed_half_ipd * pole_merge_factor(dy.atan2(l2.sqrt()), pole);
    for _ in 0..2 {
        let t = (l2 - sigma * sigma).max(0.0).sqrt();
        sigma = signed_half_ipd * pole_merge_factor(dy.atan2(t), pole);
    }
    // Within |σ| of the vertical through the head (pole merging off) no tangent exists: clamp
    // the eye onto the point's own distance, so the eye stays on the viewing circle's inside.
    sigma = sigma.clamp(-l2.sqrt(), l2.sqrt());
    let t = (l2 - sigma * sigma).max(0.0).sqrt();
    // q = t·d + σ·right(d), right(d) = (−d_z, d_x) in (x, z): invert the rotation-scale.
    let d = Vec2::new(t * q.x + sigma * q.y, t * q.y - sigma * q.x) / l2;
    head + sigma * Vec3::new(-d.y, 0.0, d.x)
}

/// The columns and rows of the omni-quad mesh of a wall: one slice per `pixels_per_slice`
/// across (the eye changes with the azimuth), and down too where the eye changes with height:
/// on floors, ceilings and tilted walls, and on vertical walls when pole merging fades the IPD
/// with elevation.
pub fn quad_slices(wall: &Wall, pixels_per_slice: f32, pole_merge: bool) -> (u32, u32) {
    let per = pixels_per_slice.max(1.0);
    let cols = (wall.resolution[0] as f32 / per)
        .ceil()
        .clamp(1.0, MAX_SLICES as f32) as u32;
    let vertical = wall.normal().y.abs() < 1e-3;
    let rows = if vertical && !pole_merge {
        1
    } else {
        (wall.resolution[1] as f32 / per)
            .ceil()
            .clamp(1.0, MAX_SLICES as f32) as u32
    };
    (cols, rows)
}

/// Most slices in either direction of a wall's mesh (512² cells: 6 MiB of indices).
pub const MAX_SLICES: u32 = 512;

/// Wall point at normalised wall coordinates (u right, v up, both 0..1).
pub fn wall_point(wall: &Wall, u: f32, v: f32) -> Vec3 {
    wall.lower_left
        + u * (wall.lower_right - wall.lower_left)
        + v * (wall.upper_left - wall.lower_left)
}

/// What the omni-quad mesh interpolates at (u, v): the lookups at the corners of the mesh cell,
/// blended linearly over the triangle that holds (u, v). Cells split along the diagonal from
/// (u0, v0) to (u1, v1), as `render::sky_pass` builds them.
pub fn quad_lookup(
    wall: &Wall,
    (cols, rows): (u32, u32),
    u: f32,
    v: f32,
    head: Vec3,
    signed_half_ipd: f32,
    pole: Option<PoleMerge>,
) -> Vec3 {
    let (cols, rows) = (cols.max(1), rows.max(1));
    let fx = (u * cols as f32).clamp(0.0, cols as f32);
    let fy = (v * rows as f32).clamp(0.0, rows as f32);
    let (i, j) = (
        (fx.floor() as u32).min(cols - 1),
        (fy.floor() as u32).min(rows - 1),
    );
    let (a, b) = (fx - i as f32, fy - j as f32);
    let at = |di: u32, dj: u32| {
        let p = wall_point(
            wall,
            (i + di) as f32 / cols as f32,
            (j + dj) as f32 / rows as f32,
        );
        omni_lookup(p, head, signed_half_ipd, pole)
    };
    let (l00, l10, l11) = (at(0, 0), at(1, 0), at(1, 1));
    if a >= b {
        // Triangle (00, 10, 11).
        l00 + a * (l10 - l00) + b * (l11 - l10)
    } else {
        // Triangle (00, 11, 01).
        let l01 = at(0, 1);
        l00 + b * (l01 - l00) + a * (l11 - l01)
    }
}

/// How far the omni-quad sky strays from the exact one over a wall.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct QuadError {
    /// Largest angle between the interpolated and the exact lookup (degrees).
    pub max_degrees: f32,
    /// Largest distance on the wall, in pixels, between where the interpolated direction is
    /// shown and where the exact model shows it.
    pub max_pixels: f32,
}

/// Measures the omni-quad interpolation error of one wall and eye at every `step`-th pixel
/// centre (and along the cell edges, where it is zero, implicitly).
pub fn quad_error(
    wall: &Wall,
    slices: (u32, u32),
    head: Vec3,
    signed_half_ipd: f32,
    pole: Option<PoleMerge>,
    step: u32,
) -> QuadError {
    let [w, h] = wall.resolution;
    let n = wall.normal();
    let mut err = QuadError::default();
    let step = step.max(1) as usize;
    for y in (0..h).step_by(step) {
        for x in (0..w).step_by(step) {
            let (u, v) = (
                (x as f32 + 0.5) / w as f32,
                1.0 - (y as f32 + 0.5) / h as f32,
            );
            let p = wall_point(wall, u, v);
            let e = omni_sky_eye_of_point(p, head, signed_half_ipd, pole);
            let exact = p - e;
            let approx = quad_lookup(wall, slices, u, v, head, signed_half_ipd, pole);
            // atan2 of |cross| and dot: acos loses everything below ~0.04° in f32.
            let angle = exact.cross(approx).length().atan2(exact.dot(approx));
            err.max_degrees = err.max_degrees.max(angle.to_degrees());
            // Where the eye's ray along the interpolated direction meets the wall.
            let denom = approx.dot(n);
            if denom < -1e-9 {
                let t = (wall.lower_left - e).dot(n) / denom;
                let hit = wall.pixel_of_wall_point(e + t * approx);
                let exact_px = wall.pixel_of_wall_point(p);
                err.max_pixels = err.max_pixels.max(hit.distance(exact_px));
            }
        }
    }
    err
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cave::omni::PoleMerge;
    use crate::cave::thesis_cave;

    /// The inverse solve agrees with the forward model: the eye for the solved direction is
    /// the eye returned, and its ray along that direction passes through the wall point.
    #[test]
    fn lookup_inverts_the_forward_eye_model() {
        let cave = thesis_cave();
        let pole = Some(PoleMerge::default());
        for head in [
            Vec3::new(0.0, 1.7, 0.0),
            Vec3::new(-1.3, 1.6, -1.35),
            Vec3::new(0.9, 0.4, 1.0),
        ] {
            for wall in &cave.walls {
                for (u, v) in [(0.5, 0.5), (0.02, 0.9), (0.97, 0.05), (0.3, 0.99)] {
                    let p = wall_point(wall, u, v);
                    for eye in Eye::BOTH {
                        let half = eye.sign() * 0.032;
                        let e = omni_sky_eye_of_point(p, head, half, pole);
                        let d = p - e;
                        let forward = sky_eye(head, d, 0.064, eye, pole);
                        assert!(
                            forward.distance(e) < 2e-6,
                            "{head} {u} {v}: {forward} vs {e}"
                        );
                    }
                }
            }
        }
    }

    #[test]
    fn mono_lookup_is_the_plain_direction_from_the_head() {
        let head = Vec3::new(0.2, 1.5, -0.4);
        let p = Vec3::new(-1.65, 2.0, 0.7);
        assert!(omni_lookup(p, head, 0.0, None).distance(p - head) < 1e-6);
    }

    #[test]
    fn quad_interpolation_is_exact_at_mesh_vertices_and_converges() {
        let cave = thesis_cave();
        let wall = &cave.walls[1];
        let head = Vec3::new(0.0, 1.7, -1.2);
        let coarse = quad_error(wall, (2, 1), head, 0.032, None, 16);
        let fine = quad_error(wall, (64, 1), head, 0.032, None, 16);
        assert!(
            coarse.max_pixels > 4.0 * fine.max_pixels,
            "{coarse:?} {fine:?}"
        );
        let p = wall_point(wall, 0.5, 1.0);
        let l = quad_lookup(wall, (2, 1), 0.5, 1.0, head, 0.032, None);
        assert!(l.distance(omni_lookup(p, head, 0.032, None)) < 1e-5);
    }
}
