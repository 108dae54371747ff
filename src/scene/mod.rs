//! Scenes as plain CPU data: baked triangle meshes, materials and textures (no GPU).
//!
//! Node transforms are baked into the vertices at load time, so every vertex is in scene
//! (world) space; the renderer only applies the per-frame CAVE-from-world transform.

pub mod build;
pub mod glb_writer;
mod gltf_loader;
mod lighting;

pub use gltf_loader::{SceneError, load_gltf};
pub use lighting::Lighting;

use glam::Vec3;

/// One vertex: position and normal in scene space, texture coordinate.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Vertex {
    pub position: [f32; 3],
    pub normal: [f32; 3],
    pub uv: [f32; 2],
}

/// How a texture is sampled outside 0..1.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub enum Wrap {
    #[default]
    Repeat,
    MirroredRepeat,
    ClampToEdge,
}

/// An RGBA8 texture (sRGB-encoded when used as base colour).
#[derive(Debug, Clone, PartialEq)]
pub struct Texture {
    pub name: String,
    pub width: u32,
    pub height: u32,
    /// Tightly packed RGBA8 rows, top row first.
    pub rgba8: Vec<u8>,
}

/// A base-colour texture reference with its sampler settings.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct TextureRef {
    pub texture: usize,
    pub wrap_u: Wrap,
    pub wrap_v: Wrap,
    /// Nearest-neighbour magnification (glTF `NEAREST`), otherwise linear.
    pub nearest: bool,
}

/// A metallic-roughness glTF material reduced to what a Blinn-Phong shader uses.
#[derive(Debug, Clone, PartialEq)]
pub struct Material {
    pub name: String,
    /// Linear RGBA multiplier.
    pub base_color: [f32; 4],
    pub base_color_texture: Option<TextureRef>,
    /// Linear RGB emitted light (factor × strength).
    pub emissive: [f32; 3],
    /// `KHR_materials_unlit`: output exactly the base colour, no lighting.
    pub unlit: bool,
    pub double_sided: bool,
    /// `Some(cutoff)` for alpha-mask materials.
    pub alpha_cutoff: Option<f32>,
    /// Blinn-Phong exponent and strength, derived from roughness/metallic.
    pub shininess: f32,
    pub specular: f32,
}

impl Default for Material {
    fn default() -> Self {
        Self {
            name: "default".into(),
            base_color: [1.0; 4],
            base_color_texture: None,
            emissive: [0.0; 3],
            unlit: false,
            double_sided: false,
            alpha_cutoff: None,
            shininess: 32.0,
            specular: 0.25,
        }
    }
}

impl Material {
    /// An unlit material of one colour (test markers, annotations).
    pub fn unlit(name: &str, rgb: [f32; 3]) -> Self {
        Self {
            name: name.into(),
            base_color: [rgb[0], rgb[1], rgb[2], 1.0],
            unlit: true,
            double_sided: true,
            ..Self::default()
        }
    }
}

/// A contiguous range of indices drawn with one material.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Draw {
    pub first_index: u32,
    pub index_count: u32,
    pub material: usize,
}

/// A whole scene: one vertex and index pool, draws into it, materials and textures.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Scene {
    pub vertices: Vec<Vertex>,
    /// Triangle list, counter-clockwise front faces.
    pub indices: Vec<u32>,
    pub draws: Vec<Draw>,
    pub materials: Vec<Material>,
    pub textures: Vec<Texture>,
}

impl Scene {
    /// Number of triangles.
    pub fn triangle_count(&self) -> usize {
        self.indices.len() / 3
    }

    /// Axis-aligned bounds of all vertices, or `None` for an empty scene.
    pub fn bounds(&self) -> Option<(Vec3, Vec3)> {
        let mut it = self.vertices.iter().map(|v| Vec3::from(v.position));
        let first = it.next()?;
        Some(it.fold((first, first), |(lo, hi), p| (lo.min(p), hi.max(p))))
    }

    /// Appends a material and returns its index.
    pub fn add_material(&mut self, material: Material) -> usize {
        self.materials.push(material);
        self.materials.len() - 1
    }

    /// Appends triangles (indices relative to `vertices`) drawn with `material`.
    pub fn add_mesh(&mut self, vertices: &[Vertex], indices: &[u32], material: usize) {
        let base = self.vertices.len() as u32;
        let first_index = self.indices.len() as u32;
        self.vertices.extend_from_slice(vertices);
        self.indices.extend(indices.iter().map(|i| i + base));
        self.push_draw(first_index, indices.len() as u32, material);
    }

    /// Records a draw, merging it with the previous one when contiguous with the same material.
    fn push_draw(&mut self, first_index: u32, index_count: u32, material: usize) {
        if index_count == 0 {
            return;
        }
        if let Some(last) = self.draws.last_mut()
            && last.material == material
            && last.first_index + last.index_count == first_index
        {
            last.index_count += index_count;
            return;
        }
        self.draws.push(Draw {
            first_index,
            index_count,
            material,
        });
    }
}

/// Area-weighted smooth vertex normals for a triangle list (used when a mesh has none).
pub fn generate_normals(positions: &[[f32; 3]], indices: &[u32]) -> Vec<[f32; 3]> {
    let mut acc = vec![Vec3::ZERO; positions.len()];
    for tri in indices.chunks_exact(3) {
        let [a, b, c] = [tri[0], tri[1], tri[2]].map(|i| Vec3::from(positions[i as usize]));
        // Cross product length is twice the area: larger faces weigh more.
        let n = (b - a).cross(c - a);
        for &i in tri {
            acc[i as usize] += n;
        }
    }
    acc.into_iter()
        .map(|n| n.try_normalize().unwrap_or(Vec3::Y).to_array())
        .collect()
}
