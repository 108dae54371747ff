//! Writes binary glTF (`.glb`) from procedural meshes: used by the asset generator and by tests
//! that need real files to load.

use glam::{Quat, Vec3};
use serde_json::{Value, json};

use super::build::MeshData;

/// A material as written to glTF (metallic-roughness, optionally unlit).
#[derive(Debug, Clone, PartialEq)]
pub struct MaterialDesc {
    pub name: String,
    pub base_color: [f32; 4],
    /// Index returned by [`GlbWriter::add_png_texture`].
    pub texture: Option<usize>,
    pub emissive: [f32; 3],
    pub roughness: f32,
    pub metallic: f32,
    pub unlit: bool,
    pub double_sided: bool,
}

impl MaterialDesc {
    /// A lit, non-metallic material of one colour.
    pub fn plain(name: &str, rgb: [f32; 3], roughness: f32) -> Self {
        Self {
            name: name.into(),
            base_color: [rgb[0], rgb[1], rgb[2], 1.0],
            texture: None,
            emissive: [0.0; 3],
            roughness,
            metallic: 0.0,
            unlit: false,
            double_sided: false,
        }
    }
}

/// A node: transform, optional mesh, children.
#[derive(Debug, Clone, PartialEq)]
pub struct NodeDesc {
    pub name: String,
    pub mesh: Option<usize>,
    pub translation: Vec3,
    pub rotation: Quat,
    pub scale: Vec3,
    pub children: Vec<usize>,
}

impl NodeDesc {
    pub fn new(name: &str) -> Self {
        Self {
            name: name.into(),
            mesh: None,
            translation: Vec3::ZERO,
            rotation: Quat::IDENTITY,
            scale: Vec3::ONE,
            children: Vec::new(),
        }
    }

    pub fn with_mesh(mut self, mesh: usize) -> Self {
        self.mesh = Some(mesh);
        self
    }

    pub fn at(mut self, translation: Vec3) -> Self {
        self.translation = translation;
        self
    }

    pub fn rotated_y_degrees(mut self, degrees: f32) -> Self {
        self.rotation = Quat::from_rotation_y(degrees.to_radians());
        self
    }

    pub fn scaled(mut self, scale: Vec3) -> Self {
        self.scale = scale;
        self
    }

    pub fn with_children(mut self, children: Vec<usize>) -> Self {
        self.children = children;
        self
    }
}

const ARRAY_BUFFER: u32 = 34962;
const ELEMENT_ARRAY_BUFFER: u32 = 34963;
const FLOAT: u32 = 5126;
const UNSIGNED_INT: u32 = 5125;
const UNSIGNED_SHORT: u32 = 5123;

/// Accumulates glTF objects and one binary buffer, then writes a `.glb`.
#[derive(Debug, Default)]
pub struct GlbWriter {
    bin: Vec<u8>,
    buffer_views: Vec<Value>,
    accessors: Vec<Value>,
    images: Vec<Value>,
    textures: Vec<Value>,
    materials: Vec<Value>,
    meshes: Vec<Value>,
    nodes: Vec<Value>,
    uses_unlit: bool,
}

impl GlbWriter {
    pub fn new() -> Self {
        Self::default()
    }

    fn push_view(&mut self, bytes: &[u8], target: Option<u32>) -> usize {
        while !self.bin.len().is_multiple_of(4) {
            self.bin.push(0);
        }
        let mut view = json!({
            "buffer": 0,
            "byteOffset": self.bin.len(),
            "byteLength": bytes.len(),
        });
        if let Some(t) = target {
            view["target"] = json!(t);
        }
        self.bin.extend_from_slice(bytes);
        self.buffer_views.push(view);
        self.buffer_views.len() - 1
    }

    fn push_accessor(&mut self, accessor: Value) -> usize {
        self.accessors.push(accessor);
        self.accessors.len() - 1
    }

    /// Embeds a PNG image and returns the texture index (repeat-wrapped, trilinear).
    pub fn add_png_texture(&mut self, name: &str, png: &[u8]) -> usize {
        let view = self.push_view(png, None);
        self.images.push(json!({
            "name": name,
            "bufferView": view,
            "mimeType": "image/png",
        }));
        self.textures.push(json!({
            "sampler": 0,
            "source": self.images.len() - 1,
        }));
        self.textures.len() - 1
    }

    pub fn add_material(&mut self, m: &MaterialDesc) -> usize {
        let mut pbr = json!({
            "baseColorFactor": m.base_color,
            "metallicFactor": m.metallic,
            "roughnessFactor": m.roughness,
        });
        if let Some(t) = m.texture {
            pbr["baseColorTexture"] = json!({ "index": t });
        }
        let mut mat = json!({
            "name": m.name,
            "pbrMetallicRoughness": pbr,
        });
        if m.emissive.iter().any(|&c| c > 0.0) {
            mat["emissiveFactor"] = json!(m.emissive);
        }
        if m.double_sided {
            mat["doubleSided"] = json!(true);
        }
        if m.unlit {
            mat["extensions"] = json!({ "KHR_materials_unlit": {} });
            self.uses_unlit = true;
        }
        self.materials.push(mat);
        self.materials.len() - 1
    }

    /// Adds a mesh with one primitive per (geometry, material) pair; returns the mesh index.
    pub fn add_mesh(&mut self, name: &str, primitives: &[(&MeshData, usize)]) -> usize {
        let mut prims = Vec::new();
        for (mesh, material) in primitives {
            let n = mesh.vertices.len();
            let mut lo = [f32::INFINITY; 3];
            let mut hi = [f32::NEG_INFINITY; 3];
            let mut pos = Vec::with_capacity(n * 12);
            let mut nrm = Vec::with_capacity(n * 12);
            let mut uv = Vec::with_capacity(n * 8);
            for v in &mesh.vertices {
                for k in 0..3 {
                    lo[k] = lo[k].min(v.position[k]);
                    hi[k] = hi[k].max(v.position[k]);
                }
                pos.extend(v.position.iter().flat_map(|c| c.to_le_bytes()));
                // Re-normalise so the validator's unit-length check passes after f32 round-off.
                let unit = Vec3::from(v.normal).normalize_or(Vec3::Y);
                nrm.extend(unit.to_array().iter().flat_map(|c| c.to_le_bytes()));
                uv.extend(v.uv.iter().flat_map(|c| c.to_le_bytes()));
            }
            let pv = self.push_view(&pos, Some(ARRAY_BUFFER));
            let pa = self.push_accessor(json!({
                "bufferView": pv, "componentType": FLOAT, "count": n, "type": "VEC3",
                "min": lo, "max": hi,
            }));
            let nv = self.push_view(&nrm, Some(ARRAY_BUFFER));
            let na = self.push_accessor(json!({
                "bufferView": nv, "componentType": FLOAT, "count": n, "type": "VEC3",
            }));
            let uvv = self.push_view(&uv, Some(ARRAY_BUFFER));
            let uva = self.push_accessor(json!({
                "bufferView": uvv, "componentType": FLOAT, "count": n, "type": "VEC2",
            }));
            // 16-bit indices where they fit: smaller files, and exercises both loader paths.
            let (bytes, ctype): (Vec<u8>, u32) = if n <= u16::MAX as usize {
                (
                    mesh.indices
                        .iter()
                        .flat_map(|&i| (i as u16).to_le_bytes())
                        .collect(),
                    UNSIGNED_SHORT,
                )
            } else {
                (
                    mesh.indices.iter().flat_map(|i| i.to_le_bytes()).collect(),
                    UNSIGNED_INT,
                )
            };
            let iv = self.push_view(&bytes, Some(ELEMENT_ARRAY_BUFFER));
            let ia = self.push_accessor(json!({
                "bufferView": iv, "componentType": ctype, "count": mesh.indices.len(),
                "type": "SCALAR",
            }));
            prims.push(json!({
                "attributes": { "POSITION": pa, "NORMAL": na, "TEXCOORD_0": uva },
                "indices": ia,
                "material": material,
            }));
        }
        self.meshes
            .push(json!({ "name": name, "primitives": prims }));
        self.meshes.len() - 1
    }

    pub fn add_node(&mut self, node: NodeDesc) -> usize {
        let mut v = json!({ "name": node.name });
        if let Some(m) = node.mesh {
            v["mesh"] = json!(m);
        }
        if node.translation != Vec3::ZERO {
            v["translation"] = json!(node.translation.to_array());
        }
        if node.rotation != Quat::IDENTITY {
            v["rotation"] = json!(node.rotation.normalize().to_array());
        }
        if node.scale != Vec3::ONE {
            v["scale"] = json!(node.scale.to_array());
        }
        if !node.children.is_empty() {
            v["children"] = json!(node.children);
        }
        self.nodes.push(v);
        self.nodes.len() - 1
    }

    /// The glTF JSON document (without the binary chunk).
    pub fn json(&self, roots: &[usize]) -> Value {
        let mut doc = json!({
            "asset": { "version": "2.0", "generator": "omnicave gen-assets" },
            "scene": 0,
            "scenes": [ { "nodes": roots } ],
            "nodes": self.nodes,
            "meshes": self.meshes,
            "materials": self.materials,
            "accessors": self.accessors,
            "bufferViews": self.buffer_views,
            "buffers": [ { "byteLength": padded_to_4(self.bin.len()) } ],
        });
        if !self.textures.is_empty() {
            doc["textures"] = json!(self.textures);
            doc["images"] = json!(self.images);
            doc["samplers"] = json!([{
                "magFilter": 9729, "minFilter": 9987, "wrapS": 10497, "wrapT": 10497
            }]);
        }
        if self.uses_unlit {
            doc["extensionsUsed"] = json!(["KHR_materials_unlit"]);
        }
        doc
    }

    /// Serialises the whole file as GLB bytes with `roots` as the scene's root nodes.
    pub fn to_glb(&self, roots: &[usize]) -> Vec<u8> {
        let mut json_bytes = self.json(roots).to_string().into_bytes();
        while !json_bytes.len().is_multiple_of(4) {
            json_bytes.push(b' ');
        }
        let mut bin = self.bin.clone();
        bin.resize(padded_to_4(bin.len()), 0);
        let total = 12 + 8 + json_bytes.len() + 8 + bin.len();
        let mut out = Vec::with_capacity(total);
        out.extend_from_slice(b"glTF");
        out.extend_from_slice(&2u32.to_le_bytes());
        out.extend_from_slice(&(total as u32).to_le_bytes());
        out.extend_from_slice(&(json_bytes.len() as u32).to_le_bytes());
        out.extend_from_slice(b"JSON");
        out.extend_from_slice(&json_bytes);
        out.extend_from_slice(&(bin.len() as u32).to_le_bytes());
        out.extend_from_slice(b"BIN\0");
        out.extend_from_slice(&bin);
        out
    }
}

fn padded_to_4(len: usize) -> usize {
    len.div_ceil(4) * 4
}
