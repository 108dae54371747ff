//! How a scene's geometry goes into GPU buffers: whole when it fits the largest buffer, else
//! split at triangle boundaries into chunks that each fit (CPU only; `scene_pass.rs` uploads).

use std::collections::HashMap;

use crate::scene::Scene;

/// A run of one scene draw's triangles inside a chunk.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ChunkPiece {
    /// The scene draw (material run) the triangles come from.
    pub draw: usize,
    /// First index in the chunk's index list.
    pub first_index: u32,
    pub index_count: u32,
}

/// One buffer's share of a split scene.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Chunk {
    /// The scene vertices this chunk holds, in its order.
    pub vertices: Vec<u32>,
    /// Triangles as indices into `vertices`.
    pub indices: Vec<u32>,
    pub pieces: Vec<ChunkPiece>,
}

/// How a scene's geometry goes into buffers.
#[derive(Debug, Clone, PartialEq)]
pub enum ChunkPlan {
    /// One vertex and one index buffer, as the scene lays them out.
    Whole,
    Split(Vec<Chunk>),
}

/// A limit too small for even one triangle.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct TriangleTooLarge {
    pub bytes: u64,
    pub limit: u64,
}

/// Splits `scene` so that each chunk's vertices (`vertex_size` bytes each) and indices fit
/// `limit` bytes: the whole scene when it fits, else chunks filled triangle by triangle in
/// draw order (a material run larger than the limit is cut at a triangle boundary; shared
/// vertices are copied into every chunk that uses them). Draws whose material does not exist
/// are left out, as the renderer leaves them out.
pub fn plan_chunks(
    scene: &Scene,
    vertex_size: u64,
    limit: u64,
) -> Result<ChunkPlan, TriangleTooLarge> {
    let vertex_bytes = scene.vertices.len() as u64 * vertex_size;
    let index_bytes = scene.indices.len() as u64 * 4;
    if vertex_bytes <= limit && index_bytes <= limit {
        return Ok(ChunkPlan::Whole);
    }
    let triangle = 3 * vertex_size + 12;
    if triangle > limit {
        return Err(TriangleTooLarge {
            bytes: triangle,
            limit,
        });
    }
    let max_vertices = (limit / vertex_size) as usize;
    let max_indices = (limit / 4) as usize;
    let mut chunks = Vec::new();
    let mut current = Chunk::default();
    let mut local: HashMap<u32, u32> = HashMap::new();
    for (d, draw) in scene.draws.iter().enumerate() {
        if draw.material >= scene.materials.len() {
            continue;
        }
        let range = draw.first_index as usize..(draw.first_index + draw.index_count) as usize;
        for tri in scene.indices.get(range).unwrap_or(&[]).chunks_exact(3) {
            let new = tri
                .iter()
                .enumerate()
                .filter(|&(k, v)| !local.contains_key(v) && !tri[..k].contains(v))
                .count();
            if current.vertices.len() + new > max_vertices
                || current.indices.len() + 3 > max_indices
            {
                chunks.push(std::mem::take(&mut current));
                local.clear();
            }
            for &v in tri {
                let next = current.vertices.len() as u32;
                let at = *local.entry(v).or_insert_with(|| {
                    current.vertices.push(v);
                    next
                });
                current.indices.push(at);
            }
            let end = current.indices.len() as u32;
            match current.pieces.last_mut() {
                Some(p) if p.draw == d && p.first_index + p.index_count + 3 == end => {
                    p.index_count += 3;
                }
                _ => current.pieces.push(ChunkPiece {
                    draw: d,
                    first_index: end - 3,
                    index_count: 3,
                }),
            }
        }
    }
    if !current.indices.is_empty() {
        chunks.push(current);
    }
    Ok(ChunkPlan::Split(chunks))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::{Material, Vertex};

    /// A strip of `n` quads (2 triangles each) sharing edges, in one material.
    fn strip(n: u32) -> Scene {
        let mut scene = Scene::default();
        let m = scene.add_material(Material::default());
        let mut vertices = Vec::new();
        for i in 0..=n {
            for y in [0.0, 1.0] {
                vertices.push(Vertex::new([i as f32, y, 0.0], [0.0, 0.0, 1.0], [0.0, 0.0]));
            }
        }
        let mut indices = Vec::new();
        for i in 0..n {
            let a = 2 * i;
            indices.extend_from_slice(&[a, a + 2, a + 1, a + 1, a + 2, a + 3]);
        }
        scene.add_mesh(&vertices, &indices, m);
        scene
    }

    #[test]
    fn one_material_is_cut_at_triangles_and_every_triangle_kept() {
        let scene = strip(100);
        // 8-byte vertices: 24 of them per chunk.
        let ChunkPlan::Split(chunks) = plan_chunks(&scene, 8, 24 * 8).unwrap() else {
            panic!("expected a split");
        };
        assert!(chunks.len() > 5, "{}", chunks.len());
        let mut triangles = Vec::new();
        for c in &chunks {
            assert!(c.vertices.len() <= 24 && c.indices.len() * 4 <= 24 * 8);
            let covered: u32 = c.pieces.iter().map(|p| p.index_count).sum();
            assert_eq!(covered as usize, c.indices.len());
            for t in c.indices.chunks_exact(3) {
                triangles.push([
                    c.vertices[t[0] as usize],
                    c.vertices[t[1] as usize],
                    c.vertices[t[2] as usize],
                ]);
            }
        }
        let original: Vec<[u32; 3]> = scene
            .indices
            .chunks_exact(3)
            .map(|t| [t[0], t[1], t[2]])
            .collect();
        assert_eq!(triangles, original);
        // Fits: whole. Too small for a triangle: refused.
        assert_eq!(plan_chunks(&scene, 8, 1 << 20).unwrap(), ChunkPlan::Whole);
        assert!(plan_chunks(&scene, 8, 30).is_err());
    }
}
