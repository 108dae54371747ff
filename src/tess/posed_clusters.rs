//! Cluster bounds that follow the pose: each frame, every cluster holding a deformed vertex
//! gets a box that provably holds its posed triangles, from boxes computed once at load.
//!
//! A posed vertex is M·p with M = Σᵢ wᵢ·Jᵢ (weights ≥ 0 summing to one) and p its morphed
//! mesh-space position, so it lies in the convex hull of the points Jᵢ·p, each inside Jᵢ
//! applied to a box holding p. Per cluster and per (deformer, matrix) that influences one of
//! its vertices, the box of those vertices' rest positions is kept; each frame it is grown by
//! the morph targets' largest displacement times |wₖ| and moved by its matrix (an exact
//! box of the moved box). The cluster's box is the union of those and of its static
//! vertices' box. Its edges lie inside it, so its longest edge is at most the box's
//! diagonal and each edge's extent along an axis at most the box's side: conservative for
//! the split criteria's bounds, which only ever send more clusters to the tessellator.

use glam::{Mat4, Vec3};

use super::clusters::Cluster;
use crate::scene::Scene;
use crate::scene::rig::{Pose, Rig};

/// A box that part of a cluster's vertices lie in, moved by one matrix of one deformer.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Piece {
    deformer: u32,
    matrix: u32,
    min: Vec3,
    max: Vec3,
}

/// One cluster with a deformed vertex.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Entry {
    cluster: u32,
    pieces: [u32; 2],
    /// Its static vertices' box (scene space), if it has any.
    fixed: Option<(Vec3, Vec3)>,
}

/// What the pose moves of the clusters, computed once per scene.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct PosedClusters {
    entries: Vec<Entry>,
    pieces: Vec<Piece>,
    /// Per deformer and morph target: the largest |Δposition| along each axis.
    morph_reach: Vec<Vec<Vec3>>,
    /// The box of every static vertex (scene space).
    static_bounds: Option<(Vec3, Vec3)>,
    /// Per deformer, the frame's morph growth (reused).
    growth: Vec<Vec3>,
}

fn grow(b: &mut Option<(Vec3, Vec3)>, lo: Vec3, hi: Vec3) {
    *b = Some(match *b {
        Some((a, c)) => (a.min(lo), c.max(hi)),
        None => (lo, hi),
    });
}

impl PosedClusters {
    /// The pieces of `clusters` (built over `scene.indices`) whose vertices `scene.rig` moves.
    pub fn new(scene: &Scene, clusters: &[Cluster]) -> Self {
        let rig = &scene.rig;
        // Vertex → deformer, by the deformers' ranges.
        let mut owner: Vec<Option<u32>> = vec![None; scene.vertices.len()];
        for (d, deformer) in rig.deformers.iter().enumerate() {
            let first = deformer.first_vertex as usize;
            for slot in owner.iter_mut().skip(first).take(deformer.rest.len()) {
                *slot = Some(d as u32);
            }
        }
        let mut static_bounds = None;
        for (v, o) in scene.vertices.iter().zip(&owner) {
            if o.is_none() {
                let p = Vec3::from(v.position);
                grow(&mut static_bounds, p, p);
            }
        }
        let mut entries = Vec::new();
        let mut pieces: Vec<Piece> = Vec::new();
        for (c, cluster) in clusters.iter().enumerate() {
            let first = 3 * cluster.first_triangle as usize;
            let count = 3 * cluster.triangle_count as usize;
            let Some(corners) = scene.indices.get(first..first + count) else {
                continue;
            };
            let start = pieces.len();
            let mut fixed = None;
            for &i in corners {
                let i = i as usize;
                let Some(vertex) = scene.vertices.get(i) else {
                    continue;
                };
                let Some(d) = owner[i] else {
                    let p = Vec3::from(vertex.position);
                    grow(&mut fixed, p, p);
                    continue;
                };
                let deformer = &rig.deformers[d as usize];
                let local = i - deformer.first_vertex as usize;
                let p = Vec3::from(deformer.rest[local].position);
                let per = deformer.influences_per_vertex as usize;
                let mut add = |matrix: u32| match pieces[start..]
                    .iter_mut()
                    .find(|x| x.deformer == d && x.matrix == matrix)
                {
                    Some(piece) => {
                        piece.min = piece.min.min(p);
                        piece.max = piece.max.max(p);
                    }
                    None => pieces.push(Piece {
                        deformer: d,
                        matrix,
                        min: p,
                        max: p,
                    }),
                };
                if per == 0 {
                    add(0);
                } else {
                    for &(joint, weight) in &deformer.influences[local * per..(local + 1) * per] {
                        if weight > 0.0 {
                            add(joint);
                        }
                    }
                }
            }
            if pieces.len() > start {
                entries.push(Entry {
                    cluster: c as u32,
                    pieces: [start as u32, pieces.len() as u32],
                    fixed,
                });
            }
        }
        let morph_reach = rig
            .deformers
            .iter()
            .map(|d| {
                d.targets
                    .iter()
                    .map(|t| {
                        t.positions
                            .iter()
                            .fold(Vec3::ZERO, |m, p| m.max(Vec3::from(*p).abs()))
                    })
                    .collect()
            })
            .collect();
        Self {
            entries,
            pieces,
            morph_reach,
            static_bounds,
            growth: vec![Vec3::ZERO; rig.deformers.len()],
        }
    }

    /// Whether any cluster moves.
    pub fn is_empty(&self) -> bool {
        self.entries.is_empty()
    }

    /// Rewrites the moving clusters' bounds for `pose` (evaluated by `rig`); returns the
    /// scene's bounds in that pose.
    pub fn update(
        &mut self,
        rig: &Rig,
        pose: &Pose,
        clusters: &mut [Cluster],
    ) -> Option<(Vec3, Vec3)> {
        for (d, growth) in self.growth.iter_mut().enumerate() {
            let weights = rig.morph_weights(d, pose);
            *growth = self.morph_reach[d]
                .iter()
                .zip(weights)
                .fold(Vec3::ZERO, |g, (reach, w)| g + *reach * w.abs());
        }
        let mut bounds = self.static_bounds;
        for entry in &self.entries {
            let mut b = entry.fixed;
            for piece in &self.pieces[entry.pieces[0] as usize..entry.pieces[1] as usize] {
                let m = pose
                    .matrices
                    .get(piece.deformer as usize)
                    .and_then(|m| m.get(piece.matrix as usize))
                    .copied()
                    .unwrap_or(Mat4::IDENTITY);
                let g = self.growth[piece.deformer as usize];
                let (lo, hi) = moved_box(m, piece.min - g, piece.max + g);
                grow(&mut b, lo, hi);
            }
            let (Some((lo, hi)), Some(cluster)) = (b, clusters.get_mut(entry.cluster as usize))
            else {
                continue;
            };
            grow(&mut bounds, lo, hi);
            let half = 0.5 * (hi - lo);
            cluster.centre = 0.5 * (lo + hi);
            cluster.half_size = half;
            cluster.radius = half.length();
            cluster.max_edge = 2.0 * half.length();
            cluster.edge_extent = 2.0 * half;
        }
        bounds
    }
}

/// The box holding `m` applied to the box `lo..hi`.
fn moved_box(m: Mat4, lo: Vec3, hi: Vec3) -> (Vec3, Vec3) {
    let centre = m.transform_point3(0.5 * (lo + hi));
    let half = 0.5 * (hi - lo);
    let extent = m.x_axis.truncate().abs() * half.x
        + m.y_axis.truncate().abs() * half.y
        + m.z_axis.truncate().abs() * half.z;
    (centre - extent, centre + extent)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_moved_box_holds_every_moved_corner() {
        let m = Mat4::from_scale_rotation_translation(
            Vec3::new(1.0, 2.0, 0.5),
            glam::Quat::from_euler(glam::EulerRot::XYZ, 0.3, -1.1, 2.0),
            Vec3::new(4.0, -2.0, 1.0),
        );
        let (lo, hi) = (Vec3::new(-1.0, 0.0, 2.0), Vec3::new(0.5, 3.0, 2.5));
        let (a, b) = moved_box(m, lo, hi);
        for k in 0..8 {
            let corner = Vec3::new(
                if k & 1 == 0 { lo.x } else { hi.x },
                if k & 2 == 0 { lo.y } else { hi.y },
                if k & 4 == 0 { lo.z } else { hi.z },
            );
            let p = m.transform_point3(corner);
            assert!(
                p.cmpge(a - 1e-5).all() && p.cmple(b + 1e-5).all(),
                "{p} {a} {b}"
            );
        }
    }
}
