//! The generalized off-axis perspective projection (Kooima) of one wall from one eye.

use glam::{Mat4, Vec3, Vec4};

use super::Wall;

/// The pieces of a wall's off-axis projection, kept for inspection and tests.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WallProjection {
    /// Frustum extents at the near plane: left, right, bottom, top (metres, screen axes).
    pub extents: [f32; 4],
    /// Distance from the eye to the wall plane (metres); negative if the eye is behind it.
    pub eye_to_plane: f32,
    /// Clip space from CAVE space, wgpu conventions (depth 0..1, NDC y up).
    pub clip_from_cave: Mat4,
}

/// Off-axis projection of `wall` seen from `eye` (Kooima, "Generalized Perspective Projection").
///
/// The view is rotated into the wall's basis (right, up, normal) and translated to the eye; the
/// frustum is the wall rectangle scaled to the near plane. The image therefore fills the wall
/// exactly, whatever the eye position, which is what makes adjacent walls meet without a seam.
pub fn off_axis_projection(wall: &Wall, eye: Vec3, near: f32, far: f32) -> WallProjection {
    let vr = wall.right_axis();
    let vu = wall.up_axis();
    let vn = wall.normal();

    let va = wall.lower_left - eye;
    let vb = wall.lower_right - eye;
    let vc = wall.upper_left - eye;

    // Distance from the eye to the screen plane. Guard against an eye on (or behind) the plane:
    // config validation keeps the head inside, but a tracker may not, and a NaN matrix would
    // poison the whole frame. Clamping keeps the matrix finite; the image is then meaningless
    // for that wall, which is the honest outcome.
    let d = (-va.dot(vn)).max(1e-4);
    let scale = near / d;
    let l = vr.dot(va) * scale;
    let r = vr.dot(vb) * scale;
    let b = vu.dot(va) * scale;
    let t = vu.dot(vc) * scale;

    let projection = glam::camera::rh::proj::directx::frustum(l, r, b, t, near, far);
    // Rows of the rotation are the wall's basis vectors: CAVE space → wall-aligned eye space.
    let rotation = Mat4::from_cols(
        Vec4::new(vr.x, vu.x, vn.x, 0.0),
        Vec4::new(vr.y, vu.y, vn.y, 0.0),
        Vec4::new(vr.z, vu.z, vn.z, 0.0),
        Vec4::W,
    );
    let translation = Mat4::from_translation(-eye);
    WallProjection {
        extents: [l, r, b, t],
        eye_to_plane: -va.dot(vn),
        clip_from_cave: projection * rotation * translation,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cave::thesis_cave;
    use glam::Vec2;

    fn pixel_via_matrix(wall: &Wall, m: Mat4, p: Vec3) -> (Vec2, f32) {
        let clip = m * p.extend(1.0);
        let ndc = clip.truncate() / clip.w;
        let px = Vec2::new(
            (ndc.x * 0.5 + 0.5) * wall.resolution[0] as f32,
            (0.5 - ndc.y * 0.5) * wall.resolution[1] as f32,
        );
        (px, ndc.z)
    }

    #[test]
    fn matrix_agrees_with_ray_intersection() {
        let cave = thesis_cave();
        let eyes = [
            Vec3::new(0.0, 1.7, 0.0),
            Vec3::new(0.9, 1.2, -1.35),
            Vec3::new(-1.6, 0.3, 1.6),
        ];
        let points = [
            Vec3::new(-3.0, 2.0, -4.0),
            Vec3::new(0.5, 0.1, -2.0),
            Vec3::new(-5.0, 1.0, 2.0),
            Vec3::new(4.0, 2.5, 1.0),
        ];
        for wall in &cave.walls {
            for eye in eyes {
                let proj = off_axis_projection(wall, eye, 0.05, 100.0);
                for p in points {
                    let Some(expected) = wall.pixel_of_ray(eye, p) else {
                        continue;
                    };
                    let (got, depth) = pixel_via_matrix(wall, proj.clip_from_cave, p);
                    // Behind-the-eye points are rejected by pixel_of_ray; in-front ones have a
                    // depth in (0, 1) when further than the near plane.
                    assert!((0.0..=1.0).contains(&depth), "depth {depth}");
                    // f32 round-off over a few matrix products: far below a pixel.
                    assert!(
                        (got - expected).length() < 1e-2,
                        "{} eye {eye} point {p}: {got} vs {expected}",
                        wall.name
                    );
                }
            }
        }
    }

    #[test]
    fn wall_corners_map_to_image_corners() {
        let cave = thesis_cave();
        let wall = &cave.walls[0];
        let proj = off_axis_projection(wall, Vec3::new(0.4, 1.1, 0.7), 0.05, 100.0);
        let (ll, _) = pixel_via_matrix(wall, proj.clip_from_cave, wall.lower_left);
        let (ul, _) = pixel_via_matrix(wall, proj.clip_from_cave, wall.upper_left);
        assert!((ll - Vec2::new(0.0, 720.0)).length() < 1e-2, "{ll}");
        assert!(ul.length() < 1e-2, "{ul}");
    }

    #[test]
    fn eye_on_the_wall_plane_stays_finite() {
        let cave = thesis_cave();
        let wall = &cave.walls[1];
        let proj = off_axis_projection(wall, Vec3::new(0.0, 1.0, -1.65), 0.05, 100.0);
        assert!(proj.clip_from_cave.is_finite());
    }
}
