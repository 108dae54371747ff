//! Procedural meshes (boxes, planes, cylinders, spheres) for the asset generator and tests.

use glam::{Mat3, Mat4, Vec2, Vec3};

use super::Vertex;

/// An indexed triangle mesh in its own local space.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct MeshData {
    pub vertices: Vec<Vertex>,
    pub indices: Vec<u32>,
}

impl MeshData {
    /// Appends another mesh's triangles.
    pub fn append(&mut self, other: &MeshData) {
        let base = self.vertices.len() as u32;
        self.vertices.extend_from_slice(&other.vertices);
        self.indices.extend(other.indices.iter().map(|i| i + base));
    }

    /// Returns the mesh with every vertex transformed by `m` (normals by its inverse transpose).
    pub fn transformed(mut self, m: Mat4) -> MeshData {
        let normal_matrix = Mat3::from_mat4(m).inverse().transpose();
        for v in &mut self.vertices {
            v.position = m.transform_point3(Vec3::from(v.position)).to_array();
            v.normal = (normal_matrix * Vec3::from(v.normal))
                .normalize_or(Vec3::Y)
                .to_array();
        }
        if m.determinant() < 0.0 {
            for tri in self.indices.chunks_exact_mut(3) {
                tri.swap(1, 2);
            }
        }
        self
    }

    /// Returns the mesh with every coordinate moved to the nearer of the box's bounds `lo`,
    /// `hi` on its axis: for a box built by adding half sizes and offsets, faces meeting at
    /// an edge then share its ends bit for bit (`o + u` may differ from `hi` in the last bit),
    /// so the mesh is watertight. Only for meshes whose vertices are all the box's corners.
    pub fn snapped_to_box(self, lo: Vec3, hi: Vec3) -> MeshData {
        self.snapped_to_lattice(lo, hi, 1)
    }

    /// Returns the mesh with every coordinate moved to the nearest of `steps` + 1 evenly
    /// spaced values from `lo` to `hi` on its axis, each computed one way (the bounds
    /// exactly): the faces of a box built as grids of `steps` × `steps` cells then share
    /// their edges' vertices bit for bit, so the mesh is watertight. Only for meshes whose
    /// vertices all lie on that lattice (`steps` = 1: the box's corners).
    pub fn snapped_to_lattice(mut self, lo: Vec3, hi: Vec3, steps: u32) -> MeshData {
        let steps = steps.max(1);
        let snap = |x: f32, l: f32, h: f32| {
            let q = ((x - l) / (h - l) * steps as f32).round();
            // A NaN (a box of no size on this axis) takes the lower bound.
            if q.is_nan() || q <= 0.0 {
                l
            } else if q >= steps as f32 {
                h
            } else {
                l + (h - l) * (q / steps as f32)
            }
        };
        for v in &mut self.vertices {
            let [x, y, z] = v.position;
            v.position = [
                snap(x, lo.x, hi.x),
                snap(y, lo.y, hi.y),
                snap(z, lo.z, hi.z),
            ];
        }
        self
    }

    /// Reverses every triangle and normal (to see a closed shape from inside).
    pub fn flipped(mut self) -> MeshData {
        for tri in self.indices.chunks_exact_mut(3) {
            tri.swap(1, 2);
        }
        for v in &mut self.vertices {
            v.normal = (-Vec3::from(v.normal)).to_array();
        }
        self
    }

    fn push_quad(&mut self, corners: [Vec3; 4], normal: Vec3, uvs: [Vec2; 4]) {
        let base = self.vertices.len() as u32;
        for (p, uv) in corners.iter().zip(uvs) {
            self.vertices.push(Vertex {
                position: p.to_array(),
                normal: normal.to_array(),
                uv: uv.to_array(),
                ..Default::default()
            });
        }
        self.indices
            .extend_from_slice(&[base, base + 1, base + 2, base, base + 2, base + 3]);
    }
}

/// A rectangle in its own plane, subdivided `nx × ny` times: `origin + s·u + t·v` for s, t in
/// 0..1, facing `u × v`. UVs are in metres × `uv_per_m` so textures tile at a physical size.
pub fn grid(origin: Vec3, u: Vec3, v: Vec3, nx: u32, ny: u32, uv_per_m: f32) -> MeshData {
    let nx = nx.max(1);
    let ny = ny.max(1);
    let normal = u.cross(v).normalize_or(Vec3::Y);
    let (lu, lv) = (u.length(), v.length());
    let mut mesh = MeshData::default();
    for j in 0..=ny {
        for i in 0..=nx {
            let s = i as f32 / nx as f32;
            let t = j as f32 / ny as f32;
            mesh.vertices.push(Vertex {
                position: (origin + s * u + t * v).to_array(),
                normal: normal.to_array(),
                uv: [s * lu * uv_per_m, (1.0 - t) * lv * uv_per_m],
                ..Default::default()
            });
        }
    }
    let row = nx + 1;
    for j in 0..ny {
        for i in 0..nx {
            let a = j * row + i;
            mesh.indices
                .extend_from_slice(&[a, a + 1, a + row + 1, a, a + row + 1, a + row]);
        }
    }
    mesh
}

/// An axis-aligned box centred at the origin with outward faces; UVs in metres × `uv_per_m`.
pub fn cuboid(size: Vec3, uv_per_m: f32) -> MeshData {
    let h = size * 0.5;
    let mut mesh = MeshData::default();
    // (normal, right, up) per face; corners are n·h ± r·h ± u·h.
    let faces = [
        (Vec3::X, Vec3::NEG_Z, Vec3::Y),
        (Vec3::NEG_X, Vec3::Z, Vec3::Y),
        (Vec3::Y, Vec3::X, Vec3::NEG_Z),
        (Vec3::NEG_Y, Vec3::X, Vec3::Z),
        (Vec3::Z, Vec3::X, Vec3::Y),
        (Vec3::NEG_Z, Vec3::NEG_X, Vec3::Y),
    ];
    for (n, r, u) in faces {
        let c = n * h;
        let rr = r * h;
        let uu = u * h;
        let w = rr.length() * 2.0 * uv_per_m;
        let t = uu.length() * 2.0 * uv_per_m;
        mesh.push_quad(
            [c - rr - uu, c + rr - uu, c + rr + uu, c - rr + uu],
            n,
            [
                Vec2::new(0.0, t),
                Vec2::new(w, t),
                Vec2::new(w, 0.0),
                Vec2::ZERO,
            ],
        );
    }
    mesh
}

/// A (truncated) cone or cylinder around +y from y = 0 to `height`, with optional caps.
pub fn frustum_shell(
    radius_bottom: f32,
    radius_top: f32,
    height: f32,
    segments: u32,
    caps: bool,
) -> MeshData {
    let segments = segments.max(3);
    let mut mesh = MeshData::default();
    let slope = (radius_bottom - radius_top) / height.max(1e-6);
    for i in 0..=segments {
        let a = i as f32 / segments as f32 * std::f32::consts::TAU;
        let (s, c) = a.sin_cos();
        let n = Vec3::new(s, slope, c).normalize();
        for (y, r, v) in [(0.0, radius_bottom, 1.0), (height, radius_top, 0.0)] {
            mesh.vertices.push(Vertex {
                position: [r * s, y, r * c],
                normal: n.to_array(),
                uv: [i as f32 / segments as f32, v],
                ..Default::default()
            });
        }
    }
    for i in 0..segments {
        let a = 2 * i;
        mesh.indices
            .extend_from_slice(&[a, a + 2, a + 3, a, a + 3, a + 1]);
    }
    if caps {
        for (y, r, n) in [
            (0.0, radius_bottom, Vec3::NEG_Y),
            (height, radius_top, Vec3::Y),
        ] {
            if r <= 0.0 {
                continue;
            }
            let centre = mesh.vertices.len() as u32;
            mesh.vertices.push(Vertex {
                position: [0.0, y, 0.0],
                normal: n.to_array(),
                uv: [0.5, 0.5],
                ..Default::default()
            });
            for i in 0..segments {
                let a = i as f32 / segments as f32 * std::f32::consts::TAU;
                let (s, c) = a.sin_cos();
                mesh.vertices.push(Vertex {
                    position: [r * s, y, r * c],
                    normal: n.to_array(),
                    uv: [0.5 + 0.5 * s, 0.5 + 0.5 * c],
                    ..Default::default()
                });
            }
            for i in 0..segments {
                let a = centre + 1 + i;
                let b = centre + 1 + (i + 1) % segments;
                if n.y > 0.0 {
                    mesh.indices.extend_from_slice(&[centre, a, b]);
                } else {
                    mesh.indices.extend_from_slice(&[centre, b, a]);
                }
            }
        }
    }
    mesh
}

/// A surface of revolution around +y through `profile` ((radius, height) from bottom to top),
/// `segments` around; normals from the profile's slope, outward. No caps.
pub fn lathe(profile: &[(f32, f32)], segments: u32) -> MeshData {
    let segments = segments.max(3);
    let mut mesh = MeshData::default();
    if profile.len() < 2 {
        return mesh;
    }
    let rows = profile.len() as u32;
    for i in 0..=segments {
        let a = i as f32 / segments as f32 * std::f32::consts::TAU;
        let (s, c) = a.sin_cos();
        for (k, &(r, y)) in profile.iter().enumerate() {
            // The profile's tangent at this row (one-sided at the ends).
            let (r0, y0) = profile[k.saturating_sub(1)];
            let (r1, y1) = profile[(k + 1).min(profile.len() - 1)];
            let (dr, dy) = (r1 - r0, y1 - y0);
            let n = Vec3::new(dy * s, -dr, dy * c).normalize_or(Vec3::new(s, 0.0, c));
            mesh.vertices.push(Vertex {
                position: [r * s, y, r * c],
                normal: n.to_array(),
                uv: [i as f32 / segments as f32, y],
                ..Default::default()
            });
        }
    }
    for i in 0..segments {
        for k in 0..rows - 1 {
            let a = i * rows + k;
            let b = a + rows;
            mesh.indices
                .extend_from_slice(&[a, b, b + 1, a, b + 1, a + 1]);
        }
    }
    mesh
}

/// A semicircular arch band in the xy plane, centred at the origin (springing at y = 0), from
/// radius `inner` to `outer`, `depth` thick along z: intrados, extrados and both faces,
/// `segments` along the half circle.
pub fn arch(inner: f32, outer: f32, depth: f32, segments: u32) -> MeshData {
    let segments = segments.max(2);
    let mut mesh = MeshData::default();
    let dz = 0.5 * depth;
    let point = |r: f32, i: u32, z: f32| {
        let a = i as f32 / segments as f32 * std::f32::consts::PI;
        Vec3::new(r * a.cos(), r * a.sin(), z)
    };
    for i in 0..segments {
        let (p, q) = (i, i + 1);
        let mid = (i as f32 + 0.5) / segments as f32 * std::f32::consts::PI;
        let radial = Vec3::new(mid.cos(), mid.sin(), 0.0);
        let uv = [Vec2::ZERO, Vec2::X, Vec2::ONE, Vec2::Y];
        // Extrados (outward) and intrados (towards the centre).
        mesh.push_quad(
            [
                point(outer, p, dz),
                point(outer, p, -dz),
                point(outer, q, -dz),
                point(outer, q, dz),
            ],
            radial,
            uv,
        );
        mesh.push_quad(
            [
                point(inner, q, dz),
                point(inner, q, -dz),
                point(inner, p, -dz),
                point(inner, p, dz),
            ],
            -radial,
            uv,
        );
        // Front (+z) and back (−z) faces.
        mesh.push_quad(
            [
                point(inner, p, dz),
                point(outer, p, dz),
                point(outer, q, dz),
                point(inner, q, dz),
            ],
            Vec3::Z,
            uv,
        );
        mesh.push_quad(
            [
                point(inner, q, -dz),
                point(outer, q, -dz),
                point(outer, p, -dz),
                point(inner, p, -dz),
            ],
            Vec3::NEG_Z,
            uv,
        );
    }
    mesh
}

/// A UV sphere centred at the origin.
pub fn uv_sphere(radius: f32, rings: u32, segments: u32) -> MeshData {
    let rings = rings.max(2);
    let segments = segments.max(3);
    let mut mesh = MeshData::default();
    for j in 0..=rings {
        let theta = j as f32 / rings as f32 * std::f32::consts::PI;
        let (st, ct) = theta.sin_cos();
        for i in 0..=segments {
            let phi = i as f32 / segments as f32 * std::f32::consts::TAU;
            let (sp, cp) = phi.sin_cos();
            let n = Vec3::new(st * sp, ct, st * cp);
            mesh.vertices.push(Vertex {
                position: (n * radius).to_array(),
                normal: n.to_array(),
                uv: [i as f32 / segments as f32, j as f32 / rings as f32],
                ..Default::default()
            });
        }
    }
    let row = segments + 1;
    for j in 0..rings {
        for i in 0..segments {
            let a = j * row + i;
            let b = a + row;
            if j != 0 {
                mesh.indices.extend_from_slice(&[a, b, a + 1]);
            }
            if j != rings - 1 {
                mesh.indices.extend_from_slice(&[a + 1, b, b + 1]);
            }
        }
    }
    mesh
}

/// A generated scene of about `triangles` triangles, for measuring how the renderer scales
/// with scene size (CAD models a lab brings run to millions): a hall 8 m × 4 m × 8 m around
/// the CAVE whose six inward faces are dense grids (three quarters of the triangles), and a
/// dense sphere 0.6 m across ahead of the viewer (the rest). Faces meeting at an edge share
/// its ends bit for bit (watertight). Returns the shell and the sphere.
pub fn dense_hall(triangles: u64) -> (MeshData, MeshData) {
    let (lo, hi) = (Vec3::new(-4.0, -0.01, -4.0), Vec3::new(4.0, 4.0, 4.0));
    let d = hi - lo;
    let faces = [
        (Vec3::new(lo.x, lo.y, lo.z), Vec3::X * d.x, Vec3::Y * d.y),
        (
            Vec3::new(hi.x, lo.y, hi.z),
            Vec3::NEG_X * d.x,
            Vec3::Y * d.y,
        ),
        (
            Vec3::new(lo.x, lo.y, hi.z),
            Vec3::NEG_Z * d.z,
            Vec3::Y * d.y,
        ),
        (Vec3::new(hi.x, lo.y, lo.z), Vec3::Z * d.z, Vec3::Y * d.y),
        (
            Vec3::new(lo.x, lo.y, hi.z),
            Vec3::X * d.x,
            Vec3::NEG_Z * d.z,
        ),
        (Vec3::new(lo.x, hi.y, lo.z), Vec3::X * d.x, Vec3::Z * d.z),
    ];
    // Each face n × n quads, 2n² triangles: six of them hold 3/4 of the total.
    let n = ((triangles as f64 * 0.75 / 12.0).sqrt().round() as u32).max(1);
    let mut shell = MeshData::default();
    for (o, u, v) in faces {
        shell.append(&grid(o, u, v, n, n, 1.0).snapped_to_lattice(lo, hi, n));
    }
    // rings × 2·rings quads, 4·rings² triangles: the other quarter.
    let rings = ((triangles as f64 * 0.25 / 4.0).sqrt().round() as u32).max(2);
    let sphere = uv_sphere(0.3, rings, 2 * rings)
        .transformed(Mat4::from_translation(Vec3::new(0.0, 1.4, -1.2)));
    (shell, sphere)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_dense_hall_has_about_the_triangles_asked_for_facing_as_its_normals_say() {
        for asked in [10_000u64, 1_000_000] {
            let (shell, sphere) = dense_hall(asked);
            let got = (shell.indices.len() + sphere.indices.len()) as f64 / 3.0;
            // Rounded to whole grids and rings: within 2 % of what was asked.
            assert!((got / asked as f64 - 1.0).abs() < 0.02, "{asked}: {got}");
            assert_outward(&shell);
            assert_outward(&sphere);
        }
    }

    /// The hall's shell is its box's six faces in n × n cells: no triangle collapsed (a snap
    /// to the box's corners once left all but twelve of them without area), the faces' area
    /// the box's, and every edge shared by exactly two triangles (watertight).
    #[test]
    fn the_dense_halls_shell_is_its_box_in_whole_cells_and_watertight() {
        let (lo, hi) = (Vec3::new(-4.0, -0.01, -4.0), Vec3::new(4.0, 4.0, 4.0));
        let (shell, _) = dense_hall(10_000);
        let n = 25.0f32; // sqrt(10 000 × 3/4 / 12)
        let d = hi - lo;
        let box_area = 2.0 * (d.x * d.y + d.y * d.z + d.z * d.x);
        // The smallest cell: a face's two extents over n each (the walls' 8 m × 4.01 m).
        let smallest_cell = (d.x * d.y).min(d.y * d.z).min(d.z * d.x) / (n * n);
        let mut area = 0.0f64;
        let mut edges = std::collections::HashMap::new();
        let key = |p: [f32; 3]| p.map(f32::to_bits);
        for tri in shell.indices.chunks_exact(3) {
            let p = [tri[0], tri[1], tri[2]].map(|i| shell.vertices[i as usize].position);
            let [a, b, c] = p.map(Vec3::from);
            let twice = (b - a).cross(c - a).length();
            // Every triangle is half a cell; 1 % below half the smallest cell is far above the
            // corners' rounding (1e-6 of a cell), and a collapsed triangle has no area.
            assert!(
                0.5 * twice > 0.495 * smallest_cell,
                "triangle {tri:?} collapsed: {p:?}"
            );
            area += 0.5 * f64::from(twice);
            for k in 0..3 {
                let (u, v) = (key(p[k]), key(p[(k + 1) % 3]));
                *edges
                    .entry(if u < v { (u, v) } else { (v, u) })
                    .or_insert(0) += 1;
            }
        }
        // Summed in f64 over 7 500 triangles of f32 corners: 1e-4 relative is rounding.
        let box_area = f64::from(box_area);
        assert!(
            (area - box_area).abs() < 1e-4 * box_area,
            "{area} against {box_area}"
        );
        let open = edges.values().filter(|&&k| k != 2).count();
        assert_eq!(open, 0, "{open} edges not shared by exactly two triangles");
    }

    /// Every triangle's winding agrees with its vertex normals (front faces point outwards).
    fn assert_outward(mesh: &MeshData) {
        for tri in mesh.indices.chunks_exact(3) {
            let [a, b, c] = [tri[0], tri[1], tri[2]].map(|i| mesh.vertices[i as usize]);
            let face = (Vec3::from(b.position) - Vec3::from(a.position))
                .cross(Vec3::from(c.position) - Vec3::from(a.position));
            if face.length() < 1e-9 {
                continue;
            }
            let n = Vec3::from(a.normal) + Vec3::from(b.normal) + Vec3::from(c.normal);
            assert!(
                face.dot(n) > 0.0,
                "triangle {tri:?} winds against its normal"
            );
        }
    }

    #[test]
    fn builders_wind_outwards() {
        assert_outward(&cuboid(Vec3::new(1.0, 2.0, 3.0), 1.0));
        assert_outward(&uv_sphere(1.0, 8, 12));
        assert_outward(&frustum_shell(1.0, 0.5, 1.0, 12, true));
        assert_outward(&grid(Vec3::ZERO, Vec3::X, Vec3::NEG_Z, 3, 2, 1.0));
        assert_outward(&lathe(
            &[(1.0, 0.0), (0.8, 0.5), (0.9, 1.0), (0.3, 2.0)],
            16,
        ));
        assert_outward(&arch(1.0, 1.5, 0.5, 12));
        assert_outward(
            &cuboid(Vec3::ONE, 1.0).transformed(Mat4::from_scale(Vec3::new(-1.0, 1.0, 1.0))),
        );
    }

    #[test]
    fn grid_faces_u_cross_v() {
        let g = grid(Vec3::ZERO, Vec3::X, Vec3::NEG_Z, 1, 1, 1.0);
        assert_eq!(g.vertices[0].normal, [0.0, 1.0, 0.0]);
        assert_eq!(g.indices.len(), 6);
    }
}
