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
    /// `KHR_texture_transform` on the base colour texture: offset, rotation, scale.
    pub texture_transform: Option<([f32; 2], f32, [f32; 2])>,
    pub emissive: [f32; 3],
    pub roughness: f32,
    pub metallic: f32,
    pub maps: MaterialMaps,
    pub unlit: bool,
    pub double_sided: bool,
    /// `alphaMode: BLEND`.
    pub alpha_blend: bool,
}

/// A material's other texture maps (texture indices).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct MaterialMaps {
    pub metallic_roughness: Option<usize>,
    pub normal: Option<usize>,
    pub occlusion: Option<usize>,
    pub emissive: Option<usize>,
}

/// How a mesh's vertex data is stored, as different exporters write it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum AttributeEncoding {
    /// 32-bit floats (Blender's default).
    #[default]
    Float,
    /// `KHR_mesh_quantization` as gltfpack writes it: positions as 16-bit integers in units of
    /// [`quantization_step`] (the node must scale by it), normals as normalized bytes, texture
    /// coordinates as normalized unsigned shorts, colours as normalized unsigned bytes.
    Quantized,
    /// Positions as a sparse accessor: the first half of the vertices stored as zeros and
    /// substituted by the sparse values.
    Sparse,
    /// `EXT_meshopt_compression` on every vertex and index buffer view (gltfpack `-c`).
    Meshopt,
    /// `KHR_draco_mesh_compression` (Blender's "compress" export option): each primitive one
    /// Draco bitstream, positions quantized to 14 bits, normals 10, coordinates 12, colours 8.
    Draco,
}

/// Which attributes a mesh is written with, and how.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MeshOptions {
    pub encoding: AttributeEncoding,
    /// `TEXCOORD_0` (CAD exports often have none).
    pub uvs: bool,
    /// `COLOR_0` from the vertices' colours.
    pub colors: bool,
    /// `TANGENT` from the vertices' tangents.
    pub tangents: bool,
}

impl Default for MeshOptions {
    fn default() -> Self {
        Self {
            encoding: AttributeEncoding::Float,
            uvs: true,
            colors: false,
            tangents: false,
        }
    }
}

/// The step (metres per integer unit) of quantized positions: the largest coordinate maps to
/// 32 767.
pub fn quantization_step(mesh: &MeshData) -> f32 {
    let largest = mesh
        .vertices
        .iter()
        .flat_map(|v| v.position)
        .fold(0.0f32, |m, c| m.max(c.abs()));
    if largest > 0.0 {
        largest / 32767.0
    } else {
        1.0
    }
}

/// A punctual light (`KHR_lights_punctual`).
#[derive(Debug, Clone, PartialEq)]
pub struct LightDesc {
    pub name: String,
    /// "directional", "point" or "spot".
    pub kind: &'static str,
    pub color: [f32; 3],
    pub intensity: f32,
    pub range: Option<f32>,
    /// Spot: inner and outer cone half-angles, radians.
    pub cone: Option<(f32, f32)>,
}

impl MaterialDesc {
    /// A lit, non-metallic material of one colour.
    pub fn plain(name: &str, rgb: [f32; 3], roughness: f32) -> Self {
        Self {
            name: name.into(),
            base_color: [rgb[0], rgb[1], rgb[2], 1.0],
            texture: None,
            texture_transform: None,
            emissive: [0.0; 3],
            roughness,
            metallic: 0.0,
            maps: MaterialMaps::default(),
            unlit: false,
            double_sided: false,
            alpha_blend: false,
        }
    }
}

/// A node: transform, optional mesh, children.
#[derive(Debug, Clone, PartialEq)]
pub struct NodeDesc {
    pub name: String,
    pub mesh: Option<usize>,
    /// Index returned by [`GlbWriter::add_light`].
    pub light: Option<usize>,
    /// Index returned by [`GlbWriter::add_camera`].
    pub camera: Option<usize>,
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
            light: None,
            camera: None,
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

    pub fn with_camera(mut self, camera: usize) -> Self {
        self.camera = Some(camera);
        self
    }

    pub fn with_light(mut self, light: usize) -> Self {
        self.light = Some(light);
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
const SHORT: u32 = 5122;
const BYTE: u32 = 5120;
const UNSIGNED_BYTE: u32 = 5121;

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
    lights: Vec<Value>,
    cameras: Vec<Value>,
    extensions_used: std::collections::BTreeSet<&'static str>,
    extensions_required: std::collections::BTreeSet<&'static str>,
    /// Decoded size of the meshopt fallback buffer (0: none).
    fallback_len: usize,
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
            let mut info = json!({ "index": t });
            if let Some((offset, rotation, scale)) = m.texture_transform {
                info["extensions"] = json!({ "KHR_texture_transform": {
                    "offset": offset, "rotation": rotation, "scale": scale,
                }});
                self.extensions_used.insert("KHR_texture_transform");
            }
            pbr["baseColorTexture"] = info;
        }
        if let Some(t) = m.maps.metallic_roughness {
            pbr["metallicRoughnessTexture"] = json!({ "index": t });
        }
        let mut mat = json!({
            "name": m.name,
            "pbrMetallicRoughness": pbr,
        });
        if let Some(t) = m.maps.normal {
            mat["normalTexture"] = json!({ "index": t });
        }
        if let Some(t) = m.maps.occlusion {
            mat["occlusionTexture"] = json!({ "index": t });
        }
        if let Some(t) = m.maps.emissive {
            mat["emissiveTexture"] = json!({ "index": t });
        }
        if m.emissive.iter().any(|&c| c > 0.0) {
            mat["emissiveFactor"] = json!(m.emissive);
        }
        if m.double_sided {
            mat["doubleSided"] = json!(true);
        }
        if m.alpha_blend {
            mat["alphaMode"] = json!("BLEND");
        }
        if m.unlit {
            mat["extensions"] = json!({ "KHR_materials_unlit": {} });
            self.extensions_used.insert("KHR_materials_unlit");
        }
        self.materials.push(mat);
        self.materials.len() - 1
    }

    /// Adds a perspective camera (vertical field of view in radians); attach it to a node with
    /// [`NodeDesc::with_camera`] (it looks along the node's −z).
    pub fn add_camera(&mut self, name: &str, yfov: f32) -> usize {
        self.cameras.push(json!({
            "name": name,
            "type": "perspective",
            "perspective": { "yfov": yfov, "znear": 0.05 },
        }));
        self.cameras.len() - 1
    }

    /// Adds a punctual light; attach it to a node with [`NodeDesc::with_light`].
    pub fn add_light(&mut self, light: &LightDesc) -> usize {
        let mut v = json!({
            "name": light.name,
            "type": light.kind,
            "color": light.color,
            "intensity": light.intensity,
        });
        if let Some(range) = light.range {
            v["range"] = json!(range);
        }
        if let Some((inner, outer)) = light.cone {
            v["spot"] = json!({ "innerConeAngle": inner, "outerConeAngle": outer });
        }
        self.extensions_used.insert("KHR_lights_punctual");
        self.lights.push(v);
        self.lights.len() - 1
    }

    /// Adds a mesh with one primitive per (geometry, material) pair, float attributes with
    /// texture coordinates; returns the mesh index.
    pub fn add_mesh(&mut self, name: &str, primitives: &[(&MeshData, usize)]) -> usize {
        self.add_mesh_with(name, primitives, &MeshOptions::default())
    }

    /// Adds one vertex attribute: a buffer view (meshopt-compressed if asked) and its
    /// accessor.
    fn push_attribute(
        &mut self,
        bytes: &[u8],
        count: usize,
        stride: usize,
        accessor: Value,
        encoding: AttributeEncoding,
    ) -> usize {
        let view = if encoding == AttributeEncoding::Meshopt {
            self.push_meshopt_view(bytes, count, stride, "ATTRIBUTES", Some(ARRAY_BUFFER))
        } else {
            self.push_view(bytes, Some(ARRAY_BUFFER))
        };
        let mut accessor = accessor;
        accessor["bufferView"] = json!(view);
        accessor["count"] = json!(count);
        let components = match accessor["type"].as_str() {
            Some("VEC2") => 2,
            Some("VEC3") => 3,
            Some("VEC4") => 4,
            _ => 1,
        };
        let component_size = match accessor["componentType"].as_u64().map(|t| t as u32) {
            Some(BYTE | UNSIGNED_BYTE) => 1,
            Some(SHORT | UNSIGNED_SHORT) => 2,
            _ => 4,
        };
        if encoding == AttributeEncoding::Meshopt || stride != components * component_size {
            // Padded elements (quantized VEC3s are padded to 4 bytes), and meshopt views,
            // which need their stride.
            self.buffer_views[view]["byteStride"] = json!(stride);
        }
        self.push_accessor(accessor)
    }

    /// A buffer view compressed with meshoptimizer: its data in the binary chunk, the view in
    /// the (uninitialised) fallback buffer.
    fn push_meshopt_view(
        &mut self,
        bytes: &[u8],
        count: usize,
        stride: usize,
        mode: &str,
        target: Option<u32>,
    ) -> usize {
        let encoded = meshopt_encode(bytes, count, stride, mode);
        while !self.bin.len().is_multiple_of(4) {
            self.bin.push(0);
        }
        let offset = self.bin.len();
        self.bin.extend_from_slice(&encoded);
        let mut view = json!({
            "buffer": 1,
            "byteOffset": self.fallback_len,
            "byteLength": bytes.len(),
            "extensions": { "EXT_meshopt_compression": {
                "buffer": 0,
                "byteOffset": offset,
                "byteLength": encoded.len(),
                "byteStride": stride,
                "count": count,
                "mode": mode,
            }},
        });
        if let Some(t) = target {
            view["target"] = json!(t);
        }
        self.fallback_len += padded_to_4(bytes.len());
        self.extensions_used.insert("EXT_meshopt_compression");
        self.extensions_required.insert("EXT_meshopt_compression");
        self.buffer_views.push(view);
        self.buffer_views.len() - 1
    }

    /// As [`Self::add_mesh`], with the attributes and encoding `options` asks for.
    pub fn add_mesh_with(
        &mut self,
        name: &str,
        primitives: &[(&MeshData, usize)],
        options: &MeshOptions,
    ) -> usize {
        let enc = options.encoding;
        if enc == AttributeEncoding::Draco {
            return self.add_draco_mesh(name, primitives, options);
        }
        let quantized = enc == AttributeEncoding::Quantized;
        if quantized {
            self.extensions_used.insert("KHR_mesh_quantization");
            self.extensions_required.insert("KHR_mesh_quantization");
        }
        let mut prims = Vec::new();
        for (mesh, material) in primitives {
            let n = mesh.vertices.len();
            let bytes = VertexBytes::encode(mesh, quantized);
            let attributes = self.push_vertex_attributes(&bytes, n, options);
            let ia = self.push_indices(mesh, enc);
            prims.push(json!({
                "attributes": attributes,
                "indices": ia,
                "material": material,
            }));
        }
        self.meshes
            .push(json!({ "name": name, "primitives": prims }));
        self.meshes.len() - 1
    }

    /// Pushes a mesh's vertex attributes (positions and normals, then the texture
    /// coordinates, colours and tangents `options` asks for); returns the attribute map.
    fn push_vertex_attributes(
        &mut self,
        v: &VertexBytes,
        n: usize,
        options: &MeshOptions,
    ) -> serde_json::Map<String, Value> {
        let enc = options.encoding;
        let mut attributes = serde_json::Map::new();
        let pa = if enc == AttributeEncoding::Quantized {
            self.push_attribute(
                &v.pos,
                n,
                8,
                json!({
                    "componentType": SHORT, "type": "VEC3", "min": v.lo, "max": v.hi,
                }),
                enc,
            )
        } else if enc == AttributeEncoding::Sparse {
            self.push_sparse_positions(&v.pos, n, v.lo, v.hi)
        } else {
            self.push_attribute(
                &v.pos,
                n,
                12,
                json!({
                    "componentType": FLOAT, "type": "VEC3", "min": v.lo, "max": v.hi,
                }),
                enc,
            )
        };
        attributes.insert("POSITION".into(), json!(pa));
        let na = self.push_quantized_or_float(
            &v.nrm,
            n,
            (
                4,
                json!({ "componentType": BYTE, "normalized": true, "type": "VEC3" }),
            ),
            (12, json!({ "componentType": FLOAT, "type": "VEC3" })),
            enc,
        );
        attributes.insert("NORMAL".into(), json!(na));
        if options.uvs {
            let ua = self.push_quantized_or_float(
                &v.uv,
                n,
                (
                    4,
                    json!({ "componentType": UNSIGNED_SHORT, "normalized": true, "type": "VEC2" }),
                ),
                (8, json!({ "componentType": FLOAT, "type": "VEC2" })),
                enc,
            );
            attributes.insert("TEXCOORD_0".into(), json!(ua));
        }
        if options.colors {
            let ca = self.push_quantized_or_float(
                &v.col,
                n,
                (
                    4,
                    json!({ "componentType": UNSIGNED_BYTE, "normalized": true, "type": "VEC4" }),
                ),
                (16, json!({ "componentType": FLOAT, "type": "VEC4" })),
                enc,
            );
            attributes.insert("COLOR_0".into(), json!(ca));
        }
        if options.tangents {
            let ta = self.push_attribute(
                &v.tan,
                n,
                16,
                json!({ "componentType": FLOAT, "type": "VEC4" }),
                enc,
            );
            attributes.insert("TANGENT".into(), json!(ta));
        }
        attributes
    }

    /// Pushes one attribute with the quantized (stride, accessor) under
    /// `KHR_mesh_quantization`, else the float one.
    fn push_quantized_or_float(
        &mut self,
        bytes: &[u8],
        count: usize,
        quantized: (usize, Value),
        float: (usize, Value),
        encoding: AttributeEncoding,
    ) -> usize {
        let (stride, accessor) = if encoding == AttributeEncoding::Quantized {
            quantized
        } else {
            float
        };
        self.push_attribute(bytes, count, stride, accessor, encoding)
    }

    /// Pushes a primitive's indices (16-bit where they fit, except under meshopt) and their
    /// accessor; returns the accessor.
    fn push_indices(&mut self, mesh: &MeshData, enc: AttributeEncoding) -> usize {
        let n = mesh.vertices.len();
        // 16-bit indices where they fit: smaller files, and exercises both loader paths.
        let (bytes, ctype, size): (Vec<u8>, u32, usize) =
            if n <= u16::MAX as usize && enc != AttributeEncoding::Meshopt {
                (
                    mesh.indices
                        .iter()
                        .flat_map(|&i| (i as u16).to_le_bytes())
                        .collect(),
                    UNSIGNED_SHORT,
                    2,
                )
            } else {
                (
                    mesh.indices.iter().flat_map(|i| i.to_le_bytes()).collect(),
                    UNSIGNED_INT,
                    4,
                )
            };
        let iv = if enc == AttributeEncoding::Meshopt {
            self.push_meshopt_view(
                &bytes,
                mesh.indices.len(),
                size,
                "TRIANGLES",
                Some(ELEMENT_ARRAY_BUFFER),
            )
        } else {
            self.push_view(&bytes, Some(ELEMENT_ARRAY_BUFFER))
        };
        self.push_accessor(json!({
            "bufferView": iv, "componentType": ctype, "count": mesh.indices.len(),
            "type": "SCALAR",
        }))
    }

    /// A mesh whose primitives are Draco bitstreams; their accessors have no buffer views.
    fn add_draco_mesh(
        &mut self,
        name: &str,
        primitives: &[(&MeshData, usize)],
        options: &MeshOptions,
    ) -> usize {
        self.extensions_used.insert("KHR_draco_mesh_compression");
        self.extensions_required
            .insert("KHR_draco_mesh_compression");
        let mut prims = Vec::new();
        for (mesh, material) in primitives {
            let n = mesh.vertices.len();
            let (bytes, ids) = draco_encode(mesh, options);
            let view = self.push_view(&bytes, None);
            let mut lo = [f32::INFINITY; 3];
            let mut hi = [f32::NEG_INFINITY; 3];
            for v in &mesh.vertices {
                for k in 0..3 {
                    lo[k] = lo[k].min(v.position[k]);
                    hi[k] = hi[k].max(v.position[k]);
                }
            }
            let mut attributes = serde_json::Map::new();
            let mut extension = serde_json::Map::new();
            for (semantic, kind, id) in ids {
                let mut accessor = json!({ "componentType": FLOAT, "count": n, "type": kind });
                if semantic == "POSITION" {
                    accessor["min"] = json!(lo);
                    accessor["max"] = json!(hi);
                }
                let a = self.push_accessor(accessor);
                attributes.insert(semantic.into(), json!(a));
                extension.insert(semantic.into(), json!(id));
            }
            let ia = self.push_accessor(json!({
                "componentType": UNSIGNED_INT, "count": mesh.indices.len(), "type": "SCALAR",
            }));
            prims.push(json!({
                "attributes": attributes,
                "indices": ia,
                "material": material,
                "extensions": { "KHR_draco_mesh_compression": {
                    "bufferView": view,
                    "attributes": extension,
                }},
            }));
        }
        self.meshes
            .push(json!({ "name": name, "primitives": prims }));
        self.meshes.len() - 1
    }

    /// Float positions whose first half is stored as zeros and restored by a sparse accessor.
    fn push_sparse_positions(&mut self, pos: &[u8], n: usize, lo: [f32; 3], hi: [f32; 3]) -> usize {
        let replaced = n.div_ceil(2);
        let mut base = pos.to_vec();
        base[..replaced * 12].fill(0);
        let base_view = self.push_view(&base, Some(ARRAY_BUFFER));
        let indices: Vec<u8> = (0..replaced as u32).flat_map(|i| i.to_le_bytes()).collect();
        let index_view = self.push_view(&indices, None);
        let value_view = self.push_view(&pos[..replaced * 12], None);
        // The bounds hold the substituted values and the stored zeros alike.
        let lo = lo.map(|c| c.min(0.0));
        let hi = hi.map(|c| c.max(0.0));
        self.push_accessor(json!({
            "bufferView": base_view, "componentType": FLOAT, "count": n, "type": "VEC3",
            "min": lo, "max": hi,
            "sparse": {
                "count": replaced,
                "indices": { "bufferView": index_view, "componentType": UNSIGNED_INT },
                "values": { "bufferView": value_view },
            },
        }))
    }

    pub fn add_node(&mut self, node: NodeDesc) -> usize {
        let mut v = json!({ "name": node.name });
        if let Some(m) = node.mesh {
            v["mesh"] = json!(m);
        }
        if let Some(c) = node.camera {
            v["camera"] = json!(c);
        }
        if let Some(l) = node.light {
            v["extensions"] = json!({ "KHR_lights_punctual": { "light": l } });
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
        if self.fallback_len > 0
            && let Some(buffers) = doc["buffers"].as_array_mut()
        {
            buffers.push(json!({
                "byteLength": self.fallback_len,
                "extensions": { "EXT_meshopt_compression": { "fallback": true } },
            }));
        }
        if !self.cameras.is_empty() {
            doc["cameras"] = json!(self.cameras);
        }
        if !self.lights.is_empty() {
            doc["extensions"] = json!({ "KHR_lights_punctual": { "lights": self.lights } });
        }
        if !self.textures.is_empty() {
            doc["textures"] = json!(self.textures);
            doc["images"] = json!(self.images);
            doc["samplers"] = json!([{
                "magFilter": 9729, "minFilter": 9987, "wrapS": 10497, "wrapT": 10497
            }]);
        }
        if !self.extensions_used.is_empty() {
            doc["extensionsUsed"] = json!(self.extensions_used);
        }
        if !self.extensions_required.is_empty() {
            doc["extensionsRequired"] = json!(self.extensions_required);
        }
        doc
    }

    /// Serialises the whole file as GLB bytes with `roots` as the scene's root nodes.
    pub fn to_glb(&self, roots: &[usize]) -> Vec<u8> {
        glb_bytes(&self.json(roots), &self.bin)
    }
}

/// A binary glTF file of `document` and the binary chunk `bin` (each padded to 4 bytes, the
/// JSON with spaces, the binary with zeros).
pub fn glb_bytes(document: &Value, bin: &[u8]) -> Vec<u8> {
    let mut json_bytes = document.to_string().into_bytes();
    while !json_bytes.len().is_multiple_of(4) {
        json_bytes.push(b' ');
    }
    let mut bin = bin.to_vec();
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

/// A mesh's vertex attributes as buffer bytes (quantized or float), with the bounds of the
/// stored positions.
struct VertexBytes {
    pos: Vec<u8>,
    nrm: Vec<u8>,
    uv: Vec<u8>,
    col: Vec<u8>,
    tan: Vec<u8>,
    lo: [f32; 3],
    hi: [f32; 3],
}

impl VertexBytes {
    /// Encodes `mesh`'s vertices, quantized as `KHR_mesh_quantization` has them if asked.
    fn encode(mesh: &MeshData, quantized: bool) -> Self {
        let n = mesh.vertices.len();
        let step = quantization_step(mesh);
        let mut lo = [f32::INFINITY; 3];
        let mut hi = [f32::NEG_INFINITY; 3];
        let mut pos = Vec::with_capacity(n * 12);
        let mut nrm = Vec::with_capacity(n * 12);
        let mut uv = Vec::with_capacity(n * 8);
        let mut col = Vec::with_capacity(n * 16);
        let mut tan = Vec::with_capacity(n * 16);
        for v in &mesh.vertices {
            // Re-normalise so the validator's unit-length check passes after round-off.
            let unit = Vec3::from(v.normal).normalize_or(Vec3::Y);
            if quantized {
                // Positions on the integer grid (the node scales by the step), padded to
                // 4-byte elements as the specification requires.
                let q = v.position.map(|c| (c / step).round() as i16);
                for k in 0..3 {
                    lo[k] = lo[k].min(f32::from(q[k]));
                    hi[k] = hi[k].max(f32::from(q[k]));
                }
                pos.extend(q.iter().flat_map(|c| c.to_le_bytes()));
                pos.extend_from_slice(&[0, 0]);
                let b = unit.to_array().map(|c| (c * 127.0).round() as i8 as u8);
                nrm.extend_from_slice(&[b[0], b[1], b[2], 0]);
                uv.extend(
                    v.uv.iter()
                        .flat_map(|c| ((c.clamp(0.0, 1.0) * 65535.0).round() as u16).to_le_bytes()),
                );
                col.extend(
                    v.color
                        .iter()
                        .map(|c| (c.clamp(0.0, 1.0) * 255.0).round() as u8),
                );
            } else {
                for k in 0..3 {
                    lo[k] = lo[k].min(v.position[k]);
                    hi[k] = hi[k].max(v.position[k]);
                }
                pos.extend(v.position.iter().flat_map(|c| c.to_le_bytes()));
                nrm.extend(unit.to_array().iter().flat_map(|c| c.to_le_bytes()));
                uv.extend(v.uv.iter().flat_map(|c| c.to_le_bytes()));
                col.extend(v.color.iter().flat_map(|c| c.to_le_bytes()));
            }
            tan.extend(v.tangent.iter().flat_map(|c| c.to_le_bytes()));
        }
        Self {
            pos,
            nrm,
            uv,
            col,
            tan,
            lo,
            hi,
        }
    }
}

fn padded_to_4(len: usize) -> usize {
    len.div_ceil(4) * 4
}

/// meshoptimizer's encoders for one view: vertex data of `stride` bytes, or triangle indices.
fn meshopt_encode(bytes: &[u8], count: usize, stride: usize, mode: &str) -> Vec<u8> {
    let words: Vec<u32> = bytes
        .chunks_exact(4)
        .map(|w| u32::from_le_bytes([w[0], w[1], w[2], w[3]]))
        .collect();
    if mode == "TRIANGLES" {
        let vertex_count = words.iter().max().map_or(0, |&m| m as usize + 1);
        return meshopt::encoding::encode_index_buffer(&words, vertex_count).unwrap_or_default();
    }
    macro_rules! by_stride {
        ($($w:literal)+) => {
            match stride / 4 {
                $($w => meshopt::encoding::encode_vertex_buffer(
                    bytemuck::cast_slice::<u32, [u32; $w]>(&words[..count * $w]),
                ),)+
                // The writer's views are at most 16 bytes per element.
                _ => Ok(Vec::new()),
            }
        };
    }
    by_stride!(1 2 3 4 5 6 7 8).unwrap_or_default()
}

/// One primitive as a Draco bitstream (draco-core's encoder), and per glTF attribute its
/// accessor type and Draco unique id.
fn draco_encode(
    mesh: &MeshData,
    options: &MeshOptions,
) -> (Vec<u8>, Vec<(&'static str, &'static str, u32)>) {
    use draco_core::encoder_buffer::EncoderBuffer;
    use draco_core::encoder_options::EncoderOptions;
    use draco_core::mesh_encoder::MeshEncoder;
    use draco_core::{DataType, GeometryAttributeType, Mesh, PointAttribute, PointIndex};

    let n = mesh.vertices.len();
    let mut draco = Mesh::new();
    draco.set_num_points(n);
    let mut encoder_options = EncoderOptions::default();
    let mut ids = Vec::new();
    let mut add = |semantic: &'static str,
                   kind: &'static str,
                   ty: GeometryAttributeType,
                   bits: i32,
                   values: Vec<f32>| {
        let components = values.len() / n.max(1);
        let mut attribute = PointAttribute::new();
        attribute.init(ty, components as u8, DataType::Float32, false, n);
        let bytes: Vec<u8> = values.iter().flat_map(|v| v.to_le_bytes()).collect();
        attribute.buffer_mut().write(0, &bytes);
        let id = draco.add_attribute(attribute);
        encoder_options.set_attribute_int(id, "quantization_bits", bits);
        ids.push((semantic, kind, draco.attribute(id).unique_id()));
    };
    let flat = |f: &dyn Fn(&super::Vertex) -> Vec<f32>| -> Vec<f32> {
        mesh.vertices.iter().flat_map(f).collect()
    };
    add(
        "POSITION",
        "VEC3",
        GeometryAttributeType::Position,
        14,
        flat(&|v| v.position.to_vec()),
    );
    add(
        "NORMAL",
        "VEC3",
        GeometryAttributeType::Normal,
        10,
        flat(&|v| {
            Vec3::from(v.normal)
                .normalize_or(Vec3::Y)
                .to_array()
                .to_vec()
        }),
    );
    if options.uvs {
        add(
            "TEXCOORD_0",
            "VEC2",
            GeometryAttributeType::TexCoord,
            12,
            flat(&|v| v.uv.to_vec()),
        );
    }
    if options.colors {
        add(
            "COLOR_0",
            "VEC4",
            GeometryAttributeType::Color,
            8,
            flat(&|v| v.color.to_vec()),
        );
    }
    for tri in mesh.indices.chunks_exact(3) {
        draco.add_face([PointIndex(tri[0]), PointIndex(tri[1]), PointIndex(tri[2])]);
    }
    let mut encoder = MeshEncoder::new();
    encoder.set_mesh(draco);
    let mut out = EncoderBuffer::new();
    // A mesh the encoder refuses is written empty: the loader then names the bitstream.
    if encoder.encode(&encoder_options, &mut out).is_err() {
        return (Vec::new(), ids);
    }
    (out.data().to_vec(), ids)
}
