//! A CPU ray caster for panoramas: the independent reference the GPU routes are tested
//! against. One ray per pixel centre, through the inverse projection, against every triangle
//! of the scene (a bounding-volume hierarchy keeps that affordable); no rasteriser, no
//! tessellation, no pre-clip.

use glam::{Mat4, Vec2, Vec3};

use super::{PanoProjection, PanoSettings};
use crate::scene::{Material, Scene};

/// What the ray of one pixel hits first.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Hit {
    /// Index of the triangle in `scene.indices` (triangle `t` is indices `3t..3t+3`).
    pub triangle: usize,
    /// Distance from the viewpoint, metres.
    pub distance: f32,
}

/// Triangles in CAVE space with a bounding-volume hierarchy over them.
#[derive(Debug)]
pub struct RayCaster {
    triangles: Vec<[Vec3; 3]>,
    /// Per triangle: seen from one side only (its material is single-sided), as the GPU
    /// culls it.
    single_sided: Vec<bool>,
    /// Triangle indices, ordered so that each node's triangles are contiguous.
    order: Vec<u32>,
    nodes: Vec<Node>,
}

#[derive(Debug, Clone, Copy)]
struct Node {
    lo: Vec3,
    hi: Vec3,
    /// Leaf: `order[first..first + count]`; inner: children at `first` and `first + 1`.
    first: u32,
    count: u32,
}

const LEAF_SIZE: usize = 4;

impl RayCaster {
    /// The scene's triangles moved into CAVE space by `cave_from_world`.
    pub fn new(scene: &Scene, cave_from_world: Mat4) -> Self {
        let position = |i: u32| {
            let v = scene.vertices[i as usize].position;
            cave_from_world.transform_point3(Vec3::from(v))
        };
        let triangles: Vec<[Vec3; 3]> = scene
            .indices
            .chunks_exact(3)
            .map(|t| [position(t[0]), position(t[1]), position(t[2])])
            .collect();
        let mut single_sided = vec![false; triangles.len()];
        for d in &scene.draws {
            let sided = scene
                .materials
                .get(d.material)
                .is_some_and(|m| !m.double_sided);
            let first = (d.first_index / 3) as usize;
            let last = ((d.first_index + d.index_count) / 3) as usize;
            for s in single_sided.iter_mut().take(last).skip(first) {
                *s = sided;
            }
        }
        let mut caster = Self {
            order: (0..triangles.len() as u32).collect(),
            triangles,
            single_sided,
            nodes: Vec::new(),
        };
        if !caster.triangles.is_empty() {
            caster.nodes.push(Node {
                lo: Vec3::ZERO,
                hi: Vec3::ZERO,
                first: 0,
                count: caster.triangles.len() as u32,
            });
            caster.build(0);
        }
        caster
    }

    fn bounds(&self, first: usize, count: usize) -> (Vec3, Vec3) {
        let mut lo = Vec3::splat(f32::INFINITY);
        let mut hi = Vec3::splat(f32::NEG_INFINITY);
        for &t in &self.order[first..first + count] {
            for p in self.triangles[t as usize] {
                lo = lo.min(p);
                hi = hi.max(p);
            }
        }
        (lo, hi)
    }

    /// Splits node `n` at the median of its longest axis (by triangle centroid).
    fn build(&mut self, n: usize) {
        let (first, count) = (self.nodes[n].first as usize, self.nodes[n].count as usize);
        let (lo, hi) = self.bounds(first, count);
        self.nodes[n].lo = lo;
        self.nodes[n].hi = hi;
        if count <= LEAF_SIZE {
            return;
        }
        let axis = (hi - lo).max_position();
        let triangles = &self.triangles;
        let centroid = |t: &u32| {
            let [a, b, c] = triangles[*t as usize];
            (a + b + c)[axis]
        };
        let half = count / 2;
        self.order[first..first + count]
            .select_nth_unstable_by(half, |a, b| centroid(a).total_cmp(&centroid(b)));
        let left = self.nodes.len();
        self.nodes[n].first = left as u32;
        self.nodes[n].count = 0;
        self.nodes.push(Node {
            lo,
            hi,
            first: first as u32,
            count: half as u32,
        });
        self.nodes.push(Node {
            lo,
            hi,
            first: (first + half) as u32,
            count: (count - half) as u32,
        });
        self.build(left);
        self.build(left + 1);
    }

    /// The nearest triangle along the ray `origin + t·dir` (`min_t` < t < `max_t`), back faces
    /// of single-sided triangles left out.
    pub fn cast(&self, origin: Vec3, dir: Vec3, min_t: f32, max_t: f32) -> Option<Hit> {
        if self.nodes.is_empty() {
            return None;
        }
        let inv = dir.recip();
        let mut best: Option<Hit> = None;
        let mut stack = vec![0usize];
        while let Some(n) = stack.pop() {
            let node = self.nodes[n];
            let far = best.map_or(max_t, |h| h.distance);
            if !slab_hit(node.lo, node.hi, origin, inv, far) {
                continue;
            }
            if node.count == 0 {
                stack.push(node.first as usize);
                stack.push(node.first as usize + 1);
                continue;
            }
            let range = node.first as usize..(node.first + node.count) as usize;
            for &t in &self.order[range] {
                let corners = self.triangles[t as usize];
                // Counter-clockwise seen from the front: the ray runs against the normal.
                let back = (corners[1] - corners[0])
                    .cross(corners[2] - corners[0])
                    .dot(dir)
                    > 0.0;
                if self.single_sided[t as usize] && back {
                    continue;
                }
                if let Some(d) = crate::scene::pick::intersect(corners, origin, dir)
                    && d > min_t
                    && d < max_t
                    && best.is_none_or(|b| d < b.distance)
                {
                    best = Some(Hit {
                        triangle: t as usize,
                        distance: d,
                    });
                }
            }
        }
        best
    }

    /// One hit per pixel (row-major, top row first) of a mono panorama seen from `head`
    /// (CAVE space), between the clipping spheres `near` and `far`. Pixels outside the
    /// projection's outline are `None`.
    pub fn panorama(
        &self,
        settings: &PanoSettings,
        head: Vec3,
        near: f32,
        far: f32,
    ) -> Vec<Option<Hit>> {
        let projection: PanoProjection = settings.fitted();
        let cave_from_view = settings.view_from_cave(head).inverse();
        let [w, h] = settings.size;
        let mut out = Vec::with_capacity((w * h) as usize);
        for y in 0..h {
            for x in 0..w {
                let ndc = Vec2::new(
                    (x as f32 + 0.5) / w as f32 * 2.0 - 1.0,
                    1.0 - (y as f32 + 0.5) / h as f32 * 2.0,
                );
                out.push(projection.unproject(ndc).and_then(|d| {
                    let dir = cave_from_view.transform_vector3(d);
                    self.cast(head, dir, near, far)
                }));
            }
        }
        out
    }
}

/// The scene with every material unlit in its own flat colour and no textures (what the ray
/// caster can shade exactly), and the sRGB colour an sRGB target stores for each triangle.
pub fn flat_colours(scene: &Scene) -> (Scene, Vec<[u8; 3]>) {
    // Distinct linear colours (components 0, 0.2, 0.5 or 1; black is left for nothing).
    const LEVELS: [f32; 4] = [0.0, 0.2, 0.5, 1.0];
    let linear = |i: usize| -> [f32; 3] {
        let c = i % 63 + 1;
        [LEVELS[c % 4], LEVELS[(c / 4) % 4], LEVELS[(c / 16) % 4]]
    };
    let encode = |v: f32| -> u8 {
        let s = if v <= 0.003_130_8 {
            12.92 * v
        } else {
            1.055 * v.powf(1.0 / 2.4) - 0.055
        };
        (s * 255.0).round().clamp(0.0, 255.0) as u8
    };
    let mut flat = scene.clone();
    for (i, m) in flat.materials.iter_mut().enumerate() {
        let double_sided = m.double_sided;
        *m = Material::unlit(&m.name, linear(i));
        m.double_sided = double_sided;
    }
    flat.textures.clear();
    let mut colours = vec![[0u8; 3]; flat.triangle_count()];
    for d in &flat.draws {
        let first = (d.first_index / 3) as usize;
        let last = ((d.first_index + d.index_count) / 3) as usize;
        for c in colours.iter_mut().take(last).skip(first) {
            *c = linear(d.material).map(encode);
        }
    }
    (flat, colours)
}

/// The reference a GPU panorama of `scene` is compared with: the scene in flat colours (to
/// render) and the colour the ray caster sees at each pixel (`None`: nothing).
pub fn flat_reference(
    scene: &Scene,
    cave_from_world: Mat4,
    settings: &PanoSettings,
    head: Vec3,
    near: f32,
    far: f32,
) -> (Scene, Vec<Option<[u8; 3]>>) {
    let (flat, colours) = flat_colours(scene);
    let hits = RayCaster::new(&flat, cave_from_world).panorama(settings, head, near, far);
    let reference = hits
        .iter()
        .map(|h| h.map(|h| colours[h.triangle]))
        .collect();
    (flat, reference)
}

/// How a rendered panorama differs from the ray caster's.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Comparison {
    pub pixels: usize,
    /// Pixels whose colour differs by more than [`COLOUR_TOLERANCE`] in some channel.
    pub differ: usize,
    /// Of those, pixels that are not next to a colour edge of the reference (8-neighbours,
    /// wrapping across the rear meridian): what sampling at edges cannot explain.
    pub away_from_edges: usize,
}

impl Comparison {
    pub fn differ_pct(&self) -> f64 {
        100.0 * self.differ as f64 / self.pixels.max(1) as f64
    }

    pub fn away_pct(&self) -> f64 {
        100.0 * self.away_from_edges as f64 / self.pixels.max(1) as f64
    }
}

/// Largest channel difference still counted as the same flat colour: sRGB storage rounds.
pub const COLOUR_TOLERANCE: u8 = 2;

/// Compares `image` (row-major RGB pixels, `width` wide) with the reference colours (`None`:
/// nothing hit, shown as `background`).
pub fn compare(
    image: &[[u8; 3]],
    reference: &[Option<[u8; 3]>],
    width: usize,
    background: [u8; 3],
) -> Comparison {
    let width = width.max(1);
    let height = reference.len() / width;
    let mut c = Comparison {
        pixels: image.len().min(reference.len()),
        ..Comparison::default()
    };
    for (i, (got, expected)) in image.iter().zip(reference).enumerate() {
        let expected = expected.unwrap_or(background);
        let diff = (0..3)
            .map(|k| got[k].abs_diff(expected[k]))
            .max()
            .unwrap_or(0);
        if diff <= COLOUR_TOLERANCE {
            continue;
        }
        c.differ += 1;
        let (x, y) = ((i % width) as i64, (i / width) as i64);
        let edge = (-1..=1).any(|dy| {
            (-1..=1).any(|dx| {
                let ny = y + dy;
                let nx = (x + dx).rem_euclid(width as i64);
                ny >= 0
                    && (ny as usize) < height
                    && reference[ny as usize * width + nx as usize] != reference[i]
            })
        });
        if !edge {
            c.away_from_edges += 1;
        }
    }
    c
}

/// Whether the ray meets the box before `far` (slab test; `inv` = 1 / direction).
fn slab_hit(lo: Vec3, hi: Vec3, origin: Vec3, inv: Vec3, far: f32) -> bool {
    let a = (lo - origin) * inv;
    let b = (hi - origin) * inv;
    let t0 = a.min(b).max_element();
    let t1 = a.max(b).min_element();
    // NaN (a ray in a box's face plane) compares false: treat as a hit, the triangle test
    // decides.
    !(t0 > t1 || t1 < 0.0 || t0 > far)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::{Material, Vertex};

    fn quad_scene(centre: Vec3, half: f32) -> Scene {
        let mut scene = Scene::default();
        let m = scene.add_material(Material::unlit("red", [1.0, 0.0, 0.0]));
        let v = |x: f32, y: f32| Vertex {
            position: (centre + Vec3::new(x, y, 0.0)).to_array(),
            normal: [0.0, 0.0, 1.0],
            uv: [0.0, 0.0],
            ..Default::default()
        };
        scene.add_mesh(
            &[
                v(-half, -half),
                v(half, -half),
                v(half, half),
                v(-half, half),
            ],
            &[0, 1, 2, 0, 2, 3],
            m,
        );
        scene
    }

    #[test]
    fn a_ray_hits_the_nearest_triangle_at_its_distance() {
        let mut scene = quad_scene(Vec3::new(0.0, 0.0, -3.0), 1.0);
        let far = quad_scene(Vec3::new(0.0, 0.0, -5.0), 1.0);
        let m = scene.add_material(Material::unlit("blue", [0.0, 0.0, 1.0]));
        scene.add_mesh(&far.vertices, &far.indices, m);
        let caster = RayCaster::new(&scene, Mat4::IDENTITY);
        let hit = caster
            .cast(Vec3::ZERO, Vec3::NEG_Z, 0.0, f32::INFINITY)
            .expect("the ray ahead hits the quads");
        assert!((hit.distance - 3.0).abs() < 1e-5, "{hit:?}");
        assert!(hit.triangle < 2, "the near quad, not the far one: {hit:?}");
        assert!(
            caster
                .cast(Vec3::ZERO, Vec3::Z, 0.0, f32::INFINITY)
                .is_none()
        );
        // Beyond the far limit: nothing.
        assert!(caster.cast(Vec3::ZERO, Vec3::NEG_Z, 0.0, 2.5).is_none());
    }

    #[test]
    fn the_panorama_shows_a_quad_ahead_at_the_image_centre_only() {
        let scene = quad_scene(Vec3::new(0.0, 0.0, -2.0), 0.5);
        let caster = RayCaster::new(&scene, Mat4::IDENTITY);
        let settings = PanoSettings {
            size: [64, 32],
            ..Default::default()
        };
        let hits = caster.panorama(&settings, Vec3::ZERO, 0.01, 100.0);
        let at = |x: usize, y: usize| hits[y * 64 + x];
        assert!(at(31, 15).is_some() && at(32, 16).is_some());
        assert!(at(0, 16).is_none() && at(63, 16).is_none() && at(32, 0).is_none());
        // atan(0.5 / 2) = 14.04°: 64 px per 360° puts the quad's edge 2.5 px from the centre.
        let lit = hits.iter().filter(|h| h.is_some()).count();
        assert!((16..=36).contains(&lit), "{lit} pixels");
    }
}
