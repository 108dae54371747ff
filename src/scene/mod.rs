//! Scenes as plain CPU data: baked triangle meshes, materials and textures (no GPU).
//!
//! Node transforms are baked into the vertices at load time, so every vertex is in scene
//! (world) space; the renderer only applies the per-frame CAVE-from-world transform. What
//! animations, skins and morph targets move is kept in mesh space too ([`rig`]) and posed
//! per frame over its range of the vertices.

pub mod animated_sample;
pub mod animation;
pub mod budget;
pub mod build;
pub mod glb_writer;
mod gltf_data;
mod gltf_draco;
mod gltf_loader;
mod gltf_rig;
mod lighting;
pub mod pick;
pub mod rig;
pub mod shadows;
mod tangents;
pub mod wand_mesh;

pub use budget::SceneBudget;
pub use gltf_data::{MAX_DECODED_VIEW_BYTES, MAX_SPARSE_BASE_ELEMENTS};
pub use gltf_draco::MAX_DRACO_POINTS;
pub use gltf_loader::{SceneError, load_gltf, load_gltf_bytes, load_gltf_within};
pub use lighting::{Lighting, Shading};
pub use tangents::generate_tangents;

use glam::{Mat3, Mat4, Vec3};

/// One vertex, everything in scene space.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Vertex {
    pub position: [f32; 3],
    pub normal: [f32; 3],
    /// `TEXCOORD_0` (zero where the file has none: materials then sample no texture).
    pub uv: [f32; 2],
    /// `TEXCOORD_1`, for the textures of a material that ask for it.
    pub uv1: [f32; 2],
    /// `COLOR_0`, linear RGBA; white where the file has none.
    pub color: [f32; 4],
    /// xyz: unit tangent (the direction of increasing u of the normal map's coordinates);
    /// w: ±1, the bitangent's handedness. Zero where no normal map needs one.
    pub tangent: [f32; 4],
}

impl Default for Vertex {
    fn default() -> Self {
        Self {
            position: [0.0; 3],
            normal: [0.0, 1.0, 0.0],
            uv: [0.0; 2],
            uv1: [0.0; 2],
            color: [1.0; 4],
            tangent: [0.0; 4],
        }
    }
}

impl Vertex {
    /// A white vertex with one set of texture coordinates and no tangent.
    pub fn new(position: [f32; 3], normal: [f32; 3], uv: [f32; 2]) -> Self {
        Self {
            position,
            normal,
            uv,
            ..Self::default()
        }
    }
}

/// How a texture is sampled outside 0..1.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub enum Wrap {
    #[default]
    Repeat,
    MirroredRepeat,
    ClampToEdge,
}

/// How a texture's bytes encode values: colour textures (base colour, emissive) are sRGB,
/// data textures (metallic-roughness, normal, occlusion) linear.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub enum ColorSpace {
    #[default]
    Srgb,
    Linear,
}

/// An RGBA8 texture.
#[derive(Debug, Clone, PartialEq)]
pub struct Texture {
    pub name: String,
    pub width: u32,
    pub height: u32,
    /// Tightly packed RGBA8 rows, top row first.
    pub rgba8: Vec<u8>,
    pub color_space: ColorSpace,
}

/// `KHR_texture_transform` as a 2×3 matrix applied to texture coordinates:
/// `uv' = [rows[0]·(u, v, 1), rows[1]·(u, v, 1)]`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct UvTransform {
    pub rows: [[f32; 3]; 2],
}

impl Default for UvTransform {
    fn default() -> Self {
        Self::IDENTITY
    }
}

impl UvTransform {
    pub const IDENTITY: Self = Self {
        rows: [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0]],
    };

    /// The extension's offset, rotation (radians, counter-clockwise in UV space) and scale,
    /// composed as it defines them: translation × rotation × scale.
    pub fn from_offset_rotation_scale(offset: [f32; 2], rotation: f32, scale: [f32; 2]) -> Self {
        let (s, c) = rotation.sin_cos();
        Self {
            rows: [
                [c * scale[0], s * scale[1], offset[0]],
                [-s * scale[0], c * scale[1], offset[1]],
            ],
        }
    }

    /// The transformed texture coordinates.
    pub fn apply(&self, uv: [f32; 2]) -> [f32; 2] {
        let [a, b] = self.rows;
        [
            a[0] * uv[0] + a[1] * uv[1] + a[2],
            b[0] * uv[0] + b[1] * uv[1] + b[2],
        ]
    }
}

/// A texture reference with its sampler settings, texture coordinate set and transform.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TextureRef {
    pub texture: usize,
    pub wrap_u: Wrap,
    pub wrap_v: Wrap,
    /// Nearest-neighbour magnification (glTF `NEAREST`), otherwise linear.
    pub nearest: bool,
    /// Which texture coordinates: 0 (`TEXCOORD_0`) or 1 (`TEXCOORD_1`).
    pub tex_coord: u32,
    pub transform: UvTransform,
}

impl TextureRef {
    /// A repeating, linearly filtered texture on `TEXCOORD_0`.
    pub fn new(texture: usize) -> Self {
        Self {
            texture,
            wrap_u: Wrap::Repeat,
            wrap_v: Wrap::Repeat,
            nearest: false,
            tex_coord: 0,
            transform: UvTransform::IDENTITY,
        }
    }
}

/// How a material's alpha is used (glTF `alphaMode`).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub enum AlphaMode {
    #[default]
    Opaque,
    /// Fragments below the cutoff are discarded, the rest drawn opaque.
    Mask(f32),
    /// Blended over what lies behind: drawn after opaque geometry, back to front.
    Blend,
}

/// A glTF metallic-roughness material.
#[derive(Debug, Clone, PartialEq)]
pub struct Material {
    pub name: String,
    /// Linear RGBA multiplier.
    pub base_color: [f32; 4],
    pub base_color_texture: Option<TextureRef>,
    pub metallic: f32,
    /// Perceptual roughness (0 mirror-like, 1 matte).
    pub roughness: f32,
    /// Blue: metallic, green: roughness (multiplying the factors).
    pub metallic_roughness_texture: Option<TextureRef>,
    /// Tangent-space normal map and its scale.
    pub normal_texture: Option<TextureRef>,
    pub normal_scale: f32,
    /// Ambient occlusion (red channel) and its strength.
    pub occlusion_texture: Option<TextureRef>,
    pub occlusion_strength: f32,
    /// Linear RGB emitted light (factor × `KHR_materials_emissive_strength`).
    pub emissive: [f32; 3],
    pub emissive_texture: Option<TextureRef>,
    /// `KHR_materials_unlit`: output exactly the base colour, no lighting.
    pub unlit: bool,
    pub double_sided: bool,
    pub alpha_mode: AlphaMode,
}

impl Default for Material {
    fn default() -> Self {
        Self {
            name: "default".into(),
            base_color: [1.0; 4],
            base_color_texture: None,
            // glTF's defaults are metallic 1, roughness 1; a material without any (the
            // default material, procedural content) reads better as a matte dielectric.
            metallic: 0.0,
            roughness: 0.6,
            metallic_roughness_texture: None,
            normal_texture: None,
            normal_scale: 1.0,
            occlusion_texture: None,
            occlusion_strength: 1.0,
            emissive: [0.0; 3],
            emissive_texture: None,
            unlit: false,
            double_sided: false,
            alpha_mode: AlphaMode::Opaque,
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

    /// Every texture slot with its reference, in the order the shader binds them.
    pub fn texture_slots(&self) -> [Option<TextureRef>; TEXTURE_SLOTS] {
        [
            self.base_color_texture,
            self.metallic_roughness_texture,
            self.normal_texture,
            self.occlusion_texture,
            self.emissive_texture,
        ]
    }

    /// Mutable access to the texture slots (same order as [`Self::texture_slots`]).
    pub fn texture_slots_mut(&mut self) -> [&mut Option<TextureRef>; TEXTURE_SLOTS] {
        [
            &mut self.base_color_texture,
            &mut self.metallic_roughness_texture,
            &mut self.normal_texture,
            &mut self.occlusion_texture,
            &mut self.emissive_texture,
        ]
    }
}

/// Texture slots of a material: base colour, metallic-roughness, normal, occlusion, emissive.
pub const TEXTURE_SLOTS: usize = 5;
/// Names of the texture slots, for messages.
pub const TEXTURE_SLOT_NAMES: [&str; TEXTURE_SLOTS] = [
    "baseColorTexture",
    "metallicRoughnessTexture",
    "normalTexture",
    "occlusionTexture",
    "emissiveTexture",
];

/// What kind of punctual light (`KHR_lights_punctual`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum LightKind {
    /// Parallel light travelling along `direction`; intensity in lux.
    Directional,
    /// From `position` in every direction; intensity in candela.
    Point,
    /// From `position` along `direction`, full inside `inner_cone`, none outside
    /// `outer_cone` (half-angles, radians); intensity in candela.
    Spot { inner_cone: f32, outer_cone: f32 },
}

/// A light the scene file brings, in scene space.
#[derive(Debug, Clone, PartialEq)]
pub struct Light {
    pub name: String,
    pub kind: LightKind,
    pub position: Vec3,
    /// Unit direction the light travels (directional and spot).
    pub direction: Vec3,
    /// Linear colour × intensity.
    pub color: Vec3,
    /// Distance where the light falls to zero (`None`: inverse square without a cut-off).
    pub range: Option<f32>,
    /// Casts shadows (when shadows are on).
    pub casts_shadows: bool,
}

/// A camera the scene file brings (a viewpoint), in scene space.
#[derive(Debug, Clone, PartialEq)]
pub struct Camera {
    pub name: String,
    pub position: Vec3,
    /// Unit direction the camera looks (its node's −z).
    pub forward: Vec3,
    /// Vertical field of view (radians) for perspective cameras.
    pub yfov: Option<f32>,
}

/// Where a loaded model is put before the CAVE is placed in the scene.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum SceneFit {
    /// Its own origin and units.
    #[default]
    AsAuthored,
    /// Its bounding box centred on the origin horizontally, its lowest point at height 0.
    Floor,
}

crate::named_enum!(SceneFit {
    Self::AsAuthored => "as-authored",
    Self::Floor => "floor",
});

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
    /// Lights from the file (`KHR_lights_punctual`).
    pub lights: Vec<Light>,
    /// Cameras from the file, in node order.
    pub cameras: Vec<Camera>,
    /// What moves: animations, skins, morph targets and the primitives they pose (empty for
    /// a static scene; its deformed vertices hold the rest pose).
    pub rig: rig::Rig,
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

    /// The transform that fits the scene as asked: scaled so that its largest side is `size_m`
    /// metres (0: unscaled), then moved as `fit` says. Identity for an empty scene.
    pub fn fit_transform(&self, fit: SceneFit, size_m: f32) -> Mat4 {
        let Some((lo, hi)) = self.bounds() else {
            return Mat4::IDENTITY;
        };
        let largest = (hi - lo).max_element();
        let scale = if size_m > 0.0 && largest > 0.0 {
            size_m / largest
        } else {
            1.0
        };
        let offset = match fit {
            SceneFit::AsAuthored => Vec3::ZERO,
            SceneFit::Floor => -Vec3::new(0.5 * (lo.x + hi.x), lo.y, 0.5 * (lo.z + hi.z)) * scale,
        };
        Mat4::from_translation(offset) * Mat4::from_scale(Vec3::splat(scale))
    }

    /// Moves the whole scene (vertices, lights, cameras) by `transform`, as placing a model
    /// in the CAVE does. A mirroring transform keeps faces facing out (winding flipped).
    pub fn transform(&mut self, transform: Mat4) {
        let linear = Mat3::from_mat4(transform);
        let normal_matrix = linear.inverse().transpose();
        // A mirror flips the bitangent's handedness, as loading a mirrored node does.
        let handedness = if linear.determinant() < 0.0 {
            -1.0
        } else {
            1.0
        };
        for v in &mut self.vertices {
            v.position = transform
                .transform_point3(Vec3::from(v.position))
                .to_array();
            v.normal = (normal_matrix * Vec3::from(v.normal))
                .try_normalize()
                .unwrap_or(Vec3::Y)
                .to_array();
            let t = Vec3::from_slice(&v.tangent[..3]);
            if t != Vec3::ZERO {
                let moved = (linear * t).try_normalize().unwrap_or(Vec3::X);
                v.tangent = [moved.x, moved.y, moved.z, v.tangent[3] * handedness];
            }
        }
        if linear.determinant() < 0.0 {
            for tri in self.indices.chunks_exact_mut(3) {
                tri.swap(1, 2);
            }
        }
        for light in &mut self.lights {
            light.position = transform.transform_point3(light.position);
            light.direction = (linear * light.direction)
                .try_normalize()
                .unwrap_or(Vec3::NEG_Y);
            if let Some(range) = &mut light.range {
                // A uniform scale scales the range with the scene; a non-uniform one by its
                // mean.
                *range *= linear.determinant().abs().cbrt();
            }
        }
        self.rig.placement = transform * self.rig.placement;
        for camera in &mut self.cameras {
            camera.position = transform.transform_point3(camera.position);
            camera.forward = (linear * camera.forward)
                .try_normalize()
                .unwrap_or(Vec3::NEG_Z);
        }
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
