//! What a ray hits in a scene (the wand's selection): the nearest triangle along it, on the CPU,
//! run once per request (a button press), never per frame.

use glam::Vec3;

use super::Scene;

/// The nearest hit of a ray.
#[derive(Debug, Clone, PartialEq)]
pub struct Pick {
    /// Along the ray, in the ray's units (scene space).
    pub distance: f32,
    /// The triangle's index in the scene's index list (/ 3).
    pub triangle: usize,
    /// Its material's index and name.
    pub material: usize,
    pub material_name: String,
    /// Where, scene space.
    pub point: Vec3,
}

/// Möller–Trumbore: distance along `dir` (unit) to the triangle `a b c`, either side (the
/// panorama's CPU ray caster uses it too).
pub fn intersect([a, b, c]: [Vec3; 3], origin: Vec3, dir: Vec3) -> Option<f32> {
    let (e1, e2) = (b - a, c - a);
    let p = dir.cross(e2);
    let det = e1.dot(p);
    if det.abs() < 1e-12 {
        return None;
    }
    let inv = 1.0 / det;
    let s = origin - a;
    let u = s.dot(p) * inv;
    if !(0.0..=1.0).contains(&u) {
        return None;
    }
    let q = s.cross(e1);
    let v = dir.dot(q) * inv;
    if v < 0.0 || u + v > 1.0 {
        return None;
    }
    let t = e2.dot(q) * inv;
    (t > 0.0).then_some(t)
}

/// The nearest triangle of `scene` that the ray from `origin` along `dir` (unit length) meets
/// within `max`.
pub fn pick(scene: &Scene, origin: Vec3, dir: Vec3, max: f32) -> Option<Pick> {
    let mut best: Option<(f32, usize, usize)> = None;
    for draw in &scene.draws {
        let first = draw.first_index as usize / 3;
        let count = draw.index_count as usize / 3;
        for tri in first..first + count {
            let Some(idx) = scene.indices.get(3 * tri..3 * tri + 3) else {
                continue;
            };
            let corner = |k: usize| {
                scene
                    .vertices
                    .get(idx[k] as usize)
                    .map(|v| Vec3::from(v.position))
            };
            let (Some(a), Some(b), Some(c)) = (corner(0), corner(1), corner(2)) else {
                continue;
            };
            let limit = best.map_or(max, |(t, _, _)| t);
            if let Some(t) = intersect([a, b, c], origin, dir).filter(|t| *t <= limit) {
                best = Some((t, tri, draw.material));
            }
        }
    }
    best.map(|(distance, triangle, material)| Pick {
        distance,
        triangle,
        material,
        material_name: scene
            .materials
            .get(material)
            .map_or_else(String::new, |m| m.name.clone()),
        point: origin + distance * dir,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::Material;
    use crate::scene::build::uv_sphere;

    #[test]
    fn the_nearest_of_two_spheres_is_picked() {
        let mut scene = Scene::default();
        for (name, z) in [("far", -4.0), ("near", -2.0)] {
            let m = scene.add_material(Material::unlit(name, [1.0; 3]));
            let mut mesh = uv_sphere(0.5, 16, 8);
            for v in &mut mesh.vertices {
                v.position[2] += z;
            }
            scene.add_mesh(&mesh.vertices, &mesh.indices, m);
        }
        let p = pick(&scene, Vec3::ZERO, Vec3::NEG_Z, 10.0).expect("hit");
        assert_eq!(p.material_name, "near");
        assert!((p.distance - 1.5).abs() < 0.02, "{}", p.distance);
        assert!(pick(&scene, Vec3::ZERO, Vec3::Z, 10.0).is_none());
        assert!(
            pick(&scene, Vec3::ZERO, Vec3::NEG_Z, 1.0).is_none(),
            "beyond max"
        );
    }
}
