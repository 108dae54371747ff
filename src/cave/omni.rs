//! Omnidirectional stereo on the CPU: per-vertex eyes with pole merge, and the object warp of
//! Meindl (2015) ch. 5 in both variants. The vertex shader (shaders/common.wgsl) computes the
//! same; tests compare the GPU against these functions.
//!
//! Notation: V a vertex, H the head, E = E(V) the eye that should see V, C the projective
//! viewpoint (centre of projection) of the wall's projection, s(X) the signed distance of X
//! from the wall plane (positive on the viewer's side). The wall shows V where the ray E→V
//! meets the plane, at I. The warp moves V to V' on the line C→I so that the ordinary
//! projection from C draws it at I.
//!
//! Similar triangles (thesis eqs. 5.1–5.3, generalised from view space to any wall): the
//! homothety about I that maps E to V has ratio k = s(V)/s(E) and maps C to V', so
//! V' = V − k·(E − C). Only s(E) is divided by, and the eye is always well inside the CAVE, so
//! this never blows up. The intersection-point variant computes I = E + λ(V − E) with
//! λ = s(E)/(s(E) − s(V)) and places V' along C→I at V's distance from C: it fails when E→V is
//! (nearly) parallel to the wall and puts points behind the eye on the wall.

use glam::{Vec2, Vec3, Vec4};

use super::{Eye, UP, Wall};

/// Where the IPD fades to zero near the vertical axis through the head.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PoleMerge {
    /// Elevation (degrees above or below the horizontal) where fading starts.
    pub start_degrees: f32,
    /// Elevation where the eyes have merged into the head.
    pub end_degrees: f32,
}

impl Default for PoleMerge {
    /// 60°–75°, as offline ODS renderers (e.g. Cycles) default to.
    fn default() -> Self {
        Self {
            start_degrees: 60.0,
            end_degrees: 75.0,
        }
    }
}

/// How vertices are moved so the ordinary projection draws them where E(V) sees them.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub enum WarpVariant {
    /// Similar triangles (eqs. 5.1–5.3): stable everywhere. The default.
    #[default]
    SimilarTriangles,
    /// Through the intersection point I: kept to demonstrate and measure its failures.
    IntersectionPoint,
}

crate::named_enum!(WarpVariant {
    Self::SimilarTriangles => "similar-triangles",
    Self::IntersectionPoint => "intersection-point",
});

/// The omnistereo settings of a frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OmniSettings {
    pub warp: WarpVariant,
    /// `None` switches pole merging off (the eyes then flip across the pole).
    pub pole_merge: Option<PoleMerge>,
}

impl Default for OmniSettings {
    /// Similar triangles with pole merging on at 60°–75°, as the config defaults to.
    fn default() -> Self {
        Self {
            warp: WarpVariant::default(),
            pole_merge: Some(PoleMerge::default()),
        }
    }
}

/// Fraction of the IPD kept at elevation `elevation_rad` (1 below the start angle, 0 above the
/// end angle, smoothstep between).
pub fn pole_merge_factor(elevation_rad: f32, pole: Option<PoleMerge>) -> f32 {
    let Some(pole) = pole else { return 1.0 };
    let (a, b) = (
        pole.start_degrees.to_radians(),
        pole.end_degrees.to_radians(),
    );
    if b <= a {
        return if elevation_rad < a { 1.0 } else { 0.0 };
    }
    let t = ((elevation_rad - a) / (b - a)).clamp(0.0, 1.0);
    1.0 - t * t * (3.0 - 2.0 * t)
}

/// The eye that should see `v`: the head moved sideways by half the IPD, perpendicular to the
/// horizontal direction from the head to `v` (left eye to the left), faded near the pole.
pub fn omni_eye(head: Vec3, v: Vec3, ipd: f32, eye: Eye, pole: Option<PoleMerge>) -> Vec3 {
    let d = v - head;
    let horizontal = Vec2::new(d.x, d.z);
    let len = horizontal.length();
    let elevation = d.y.abs().atan2(len);
    // Exactly on the axis the direction is undefined; any horizontal direction will do, and
    // with pole merging on the offset is zero there anyway.
    let dir = if len > 1e-12 {
        Vec3::new(horizontal.x / len, 0.0, horizontal.y / len)
    } else {
        Vec3::NEG_Z
    };
    let right = dir.cross(UP);
    head + eye.sign() * 0.5 * ipd * pole_merge_factor(elevation, pole) * right
}

/// The wall's plane as (n, d) with s(X) = n·X + d, n pointing towards the viewer.
pub fn wall_plane(wall: &Wall) -> Vec4 {
    let n = wall.normal();
    n.extend(-n.dot(wall.lower_left))
}

fn signed_distance(plane: Vec4, x: Vec3) -> f32 {
    plane.truncate().dot(x) + plane.w
}

/// Smallest eye-to-wall distance divided by (1 µm): keeps the warp finite for an eye on the
/// wall plane, which only a broken tracker can produce.
const MIN_EYE_DISTANCE: f32 = 1e-6;

/// Similar-triangle warp: V' = V − (s(V)/s(E))·(E − C).
pub fn warp_similar(v: Vec3, e: Vec3, c: Vec3, plane: Vec4) -> Vec3 {
    let k = signed_distance(plane, v) / signed_distance(plane, e).max(MIN_EYE_DISTANCE);
    v - k * (e - c)
}

/// Intersection-point warp: I from the ray E→V, then V' on C→I at |V − C| from C. Unguarded on
/// purpose (it is the form the thesis reports as unstable); may return non-finite values.
pub fn warp_intersection(v: Vec3, e: Vec3, c: Vec3, plane: Vec4) -> Vec3 {
    let se = signed_distance(plane, e);
    let sv = signed_distance(plane, v);
    let lambda = se / (se - sv);
    let i = e + lambda * (v - e);
    c + (i - c).normalize() * (v - c).length()
}

/// Applies the chosen warp.
pub fn warp(variant: WarpVariant, v: Vec3, e: Vec3, c: Vec3, plane: Vec4) -> Vec3 {
    match variant {
        WarpVariant::SimilarTriangles => warp_similar(v, e, c, plane),
        WarpVariant::IntersectionPoint => warp_intersection(v, e, c, plane),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cave::{off_axis_projection, thesis_cave};

    fn pixel(wall: &Wall, c: Vec3, p: Vec3) -> Option<Vec2> {
        let m = off_axis_projection(wall, c, 0.05, 1000.0).clip_from_cave;
        let clip = m * p.extend(1.0);
        (clip.w > 0.0).then(|| {
            let ndc = clip.truncate() / clip.w;
            Vec2::new(
                (ndc.x * 0.5 + 0.5) * wall.resolution[0] as f32,
                (0.5 - ndc.y * 0.5) * wall.resolution[1] as f32,
            )
        })
    }

    #[test]
    fn both_warps_put_a_vertex_where_its_eye_sees_it() {
        let cave = thesis_cave();
        let head = Vec3::new(0.3, 1.6, -0.4);
        let c = Vec3::new(0.0, 1.45, 0.0);
        for wall in &cave.walls {
            let plane = wall_plane(wall);
            for v in [
                Vec3::new(-3.0, 2.0, -4.0),
                Vec3::new(2.5, 0.5, 1.0),
                Vec3::new(-0.5, 1.0, -1.0),
            ] {
                for eye in Eye::BOTH {
                    let e = omni_eye(head, v, 0.064, eye, Some(PoleMerge::default()));
                    let Some(expected) = wall.pixel_of_ray(e, v) else {
                        continue;
                    };
                    for variant in WarpVariant::ALL {
                        let got = pixel(wall, c, warp(variant, v, e, c, plane)).unwrap();
                        assert!(
                            (got - expected).length() < 0.05,
                            "{variant:?} {v}: {got} vs {expected}"
                        );
                    }
                }
            }
        }
    }

    #[test]
    fn eyes_are_split_perpendicular_to_the_view_direction() {
        let head = Vec3::new(0.0, 1.7, 0.0);
        // Looking at a point on the left (−x): the left eye is towards +z (behind).
        let l = omni_eye(head, Vec3::new(-2.0, 1.7, 0.0), 0.064, Eye::Left, None);
        assert!((l - Vec3::new(0.0, 1.7, 0.032)).length() < 1e-6, "{l}");
        // Looking ahead (−z): left eye towards −x, as in fixed-direction stereo.
        let l = omni_eye(head, Vec3::new(0.0, 1.0, -3.0), 0.064, Eye::Left, None);
        assert!((l - Vec3::new(-0.032, 1.7, 0.0)).length() < 1e-6, "{l}");
    }

    #[test]
    fn pole_merge_fades_the_eyes_together() {
        let pole = Some(PoleMerge::default());
        assert_eq!(pole_merge_factor(50f32.to_radians(), pole), 1.0);
        assert_eq!(pole_merge_factor(80f32.to_radians(), pole), 0.0);
        let mid = pole_merge_factor(67.5f32.to_radians(), pole);
        assert!((mid - 0.5).abs() < 1e-4);
        // Two points 2 cm apart on either side of the axis above the head.
        let head = Vec3::new(0.0, 1.7, 0.0);
        let a = Vec3::new(0.01, 2.7, 0.0);
        let b = Vec3::new(-0.01, 2.7, 0.0);
        let flip =
            omni_eye(head, a, 0.064, Eye::Left, None) - omni_eye(head, b, 0.064, Eye::Left, None);
        assert!(
            (flip.length() - 0.064).abs() < 1e-5,
            "without merging the eye flips by the IPD"
        );
        let merged =
            omni_eye(head, a, 0.064, Eye::Left, pole) - omni_eye(head, b, 0.064, Eye::Left, pole);
        assert!(merged.length() < 1e-6);
    }

    #[test]
    fn intersection_variant_breaks_where_similar_triangles_do_not() {
        let cave = thesis_cave();
        let front = &cave.walls[1];
        let plane = wall_plane(front);
        let c = Vec3::new(0.0, 1.45, 0.0);
        let e = Vec3::new(0.0, 1.7, 0.0);
        // V at the eye's distance from the wall: E→V parallel to the wall.
        let v = Vec3::new(1.0, 1.7, 0.0);
        assert!(!warp_intersection(v, e, c, plane).is_finite());
        assert!(warp_similar(v, e, c, plane).is_finite());
    }

    /// The scene shader shades an omnistereo fragment from its corners' eyes, interpolated
    /// across the triangle (`fs_main` in shaders/scene.wgsl), not from the point's own eye. The bound it states: within one IPD always, and within
    /// IPD·sin(Δ/2) where every point keeps the full IPD and the triangle spans Δ < 180° of
    /// azimuth round the head (it does not surround the head's vertical).
    #[test]
    fn an_interpolated_shading_eye_stays_within_its_bound() {
        // xorshift: the same triangles every run.
        let mut state = 0x9e37_79b9_7f4a_7c15_u64;
        let mut unit = move || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state >> 40) as f32 / (1u64 << 24) as f32
        };
        let ipd = 0.064;
        let mut tight_cases = 0;
        let mut worst_tight = 0.0_f32;
        for case in 0..4000 {
            let head = Vec3::new(unit() - 0.5, 1.2 + 0.6 * unit(), unit() - 0.5);
            // Triangles from 5 cm to 6 m wide, anywhere from beside the head to 5 m away.
            let size = 0.05 + 6.0 * unit() * unit();
            let centre = head + 5.0 * Vec3::new(unit() - 0.5, 0.6 * (unit() - 0.5), unit() - 0.5);
            let mut corner = || centre + size * Vec3::new(unit() - 0.5, unit() - 0.5, unit() - 0.5);
            let corners = [corner(), corner(), corner()];
            let pole = (case % 2 == 0).then(PoleMerge::default);
            let eye = if case % 4 < 2 { Eye::Left } else { Eye::Right };
            let eyes = corners.map(|c| omni_eye(head, c, ipd, eye, pole));
            // Azimuth round the head: horizontal directions, and whether the triangle's
            // horizontal shadow keeps the head's vertical outside (then its points' azimuths
            // lie between its corners').
            let flat = corners.map(|c| Vec2::new(c.x - head.x, c.z - head.z));
            let side = |a: Vec2, b: Vec2| a.perp_dot(b);
            let s = [
                side(flat[0], flat[1]),
                side(flat[1], flat[2]),
                side(flat[2], flat[0]),
            ];
            let surrounds = s.iter().all(|&x| x >= 0.0) || s.iter().all(|&x| x <= 0.0);
            let span = (0..3)
                .flat_map(|i| (0..3).map(move |j| (i, j)))
                .map(|(i, j)| flat[i].angle_to(flat[j]).abs())
                .fold(0.0_f32, f32::max);
            // Inside the triangle, perspective-correct interpolation gives non-negative
            // weights summing to one, the same for the point and its eye.
            for _ in 0..16 {
                let (a, b) = (unit(), unit());
                let (a, b) = if a + b > 1.0 {
                    (1.0 - a, 1.0 - b)
                } else {
                    (a, b)
                };
                let w = [1.0 - a - b, a, b];
                let p = w[0] * corners[0] + w[1] * corners[1] + w[2] * corners[2];
                let interpolated = w[0] * eyes[0] + w[1] * eyes[1] + w[2] * eyes[2];
                let off = interpolated.distance(omni_eye(head, p, ipd, eye, pole));
                // 1e-5 m: f32 rounding of positions a few metres from the origin.
                assert!(off <= ipd + 1e-5, "case {case}: {off} m off, over one IPD");
                if pole.is_none() && !surrounds && flat.iter().all(|f| f.length() > 1e-3) {
                    let bound = ipd * (0.5 * span).sin();
                    assert!(
                        off <= bound + 1e-5,
                        "case {case}: {off} m off, bound {bound} m (span {span} rad)"
                    );
                    tight_cases += 1;
                    worst_tight = worst_tight.max(off / bound.max(1e-9));
                }
            }
        }
        // The tight bound was exercised.
        assert!(tight_cases > 10_000, "{tight_cases} tight cases");
        assert!(worst_tight > 0.5, "at most {worst_tight} of the bound");
        // And it is reached: one corner 1 mm beside the head's vertical, two 5 m away at 118°
        // and 120° round. A point 1 % of the way from the near corner to the far one lies in
        // the far corner's direction (its eye nearly the far eye), while 99 % of its
        // interpolated eye is the near corner's.
        let head = Vec3::new(0.0, 1.6, 0.0);
        let round = |degrees: f32| {
            let a = degrees.to_radians();
            head + Vec3::new(5.0 * a.cos(), -1.0, 5.0 * a.sin())
        };
        let corners = [
            head + Vec3::new(0.001, -0.5, 0.0),
            round(120.0),
            round(118.0),
        ];
        let eyes = corners.map(|c| omni_eye(head, c, ipd, Eye::Left, None));
        let p = 0.99 * corners[0] + 0.01 * corners[1];
        let off =
            (0.99 * eyes[0] + 0.01 * eyes[1]).distance(omni_eye(head, p, ipd, Eye::Left, None));
        let bound = ipd * 60.0_f32.to_radians().sin();
        assert!(
            (0.97 * bound..=bound).contains(&off),
            "{off} m off, bound {bound} m"
        );
    }
}
