//! Loads glTF 2.0 (`.gltf` + buffers/images, or `.glb`) into a [`Scene`], refusing bad files
//! with an error that names the file and the offending object instead of panicking.

use std::path::{Path, PathBuf};

use glam::{Mat3, Mat4, Vec3};
use gltf::accessor::{DataType, Dimensions};
use gltf::mesh::Mode;

use super::{Material, Scene, Texture, TextureRef, Vertex, Wrap, generate_normals};

/// Everything that can be wrong with a scene file.
#[derive(Debug, thiserror::Error)]
pub enum SceneError {
    #[error("cannot read scene file {path}: {source}")]
    Read {
        path: PathBuf,
        source: std::io::Error,
    },
    #[error("scene file {path} is not valid glTF: {source}")]
    Gltf { path: PathBuf, source: gltf::Error },
    #[error("scene file {path}: {what}")]
    Invalid { path: PathBuf, what: String },
}

/// Largest texture side accepted (wgpu's guaranteed minimum for 2D textures).
const MAX_TEXTURE_SIDE: u32 = 8192;
/// Deeper node nesting than this is treated as a cycle (the glTF spec forbids cycles).
const MAX_NODE_DEPTH: usize = 128;

/// Loads a `.gltf` or `.glb` file; external buffers and images are resolved next to it.
pub fn load_gltf(path: &Path) -> Result<Scene, SceneError> {
    let bytes = std::fs::read(path).map_err(|source| SceneError::Read {
        path: path.to_owned(),
        source,
    })?;
    load_gltf_bytes(&bytes, path)
}

/// Loads glTF from bytes; `path` names the file in errors and locates external resources.
pub fn load_gltf_bytes(bytes: &[u8], path: &Path) -> Result<Scene, SceneError> {
    let invalid = |what: String| SceneError::Invalid {
        path: path.to_owned(),
        what,
    };
    check_glb_header(bytes).map_err(&invalid)?;
    // The checks in this module cover every panic we know of in the gltf crate; this guard
    // turns one we do not know of into an error instead of taking the application down.
    let parsed = std::panic::catch_unwind(|| load_unguarded(bytes, path));
    match parsed {
        Ok(result) => result,
        Err(_) => Err(invalid(
            "the glTF parser failed on this file (malformed data it did not expect)".into(),
        )),
    }
}

fn load_unguarded(bytes: &[u8], path: &Path) -> Result<Scene, SceneError> {
    let gltf_err = |source| SceneError::Gltf {
        path: path.to_owned(),
        source,
    };
    let gltf::Gltf { document, blob } = gltf::Gltf::from_slice(bytes).map_err(gltf_err)?;
    let base = path.parent();
    check_external_files(&document, base.unwrap_or(Path::new(".")), path)?;
    let buffers = gltf::import_buffers(&document, base, blob).map_err(gltf_err)?;
    let images = gltf::import_images(&document, base, &buffers).map_err(gltf_err)?;
    let mut loader = Loader {
        path,
        buffers: &buffers,
        scene: Scene::default(),
        image_to_texture: vec![None; images.len()],
        images: &images,
        material_index: Vec::new(),
    };
    loader.load_materials(&document)?;
    let gltf_scene = document
        .default_scene()
        .or_else(|| document.scenes().next())
        .ok_or_else(|| loader.invalid("the file contains no scene".into()))?;
    for node in gltf_scene.nodes() {
        loader.visit_node(&node, Mat4::IDENTITY, 0)?;
    }
    if loader.scene.indices.is_empty() {
        return Err(loader.invalid("the scene contains no triangles".into()));
    }
    Ok(loader.scene)
}

/// Names a missing external buffer or image file (the gltf crate reports only "not found").
fn check_external_files(
    document: &gltf::Document,
    base: &Path,
    path: &Path,
) -> Result<(), SceneError> {
    let missing = |kind: &str, index: usize, uri: &str| SceneError::Invalid {
        path: path.to_owned(),
        what: format!("{kind} {index} refers to file '{uri}', which does not exist next to it"),
    };
    let exists = |uri: &str| uri.starts_with("data:") || base.join(percent_decode(uri)).is_file();
    for buffer in document.buffers() {
        if let gltf::buffer::Source::Uri(uri) = buffer.source()
            && !exists(uri)
        {
            return Err(missing("buffer", buffer.index(), uri));
        }
    }
    for image in document.images() {
        if let gltf::image::Source::Uri { uri, .. } = image.source()
            && !exists(uri)
        {
            return Err(missing("image", image.index(), uri));
        }
    }
    Ok(())
}

/// Decodes %XX escapes in a relative URI (glTF URIs are RFC 3986).
fn percent_decode(uri: &str) -> String {
    percent_encoding::percent_decode_str(uri)
        .decode_utf8_lossy()
        .into_owned()
}

/// Rejects GLB headers whose declared length would make the gltf crate underflow.
fn check_glb_header(bytes: &[u8]) -> Result<(), String> {
    if !bytes.starts_with(b"glTF") {
        return Ok(());
    }
    if bytes.len() < 20 {
        return Err(format!(
            "truncated GLB: {} bytes, shorter than its headers",
            bytes.len()
        ));
    }
    let declared = u32::from_le_bytes([bytes[8], bytes[9], bytes[10], bytes[11]]) as usize;
    if declared < 20 || declared > bytes.len() {
        return Err(format!(
            "truncated GLB: header declares {declared} bytes but the file has {}",
            bytes.len()
        ));
    }
    Ok(())
}

struct Loader<'a> {
    path: &'a Path,
    buffers: &'a [gltf::buffer::Data],
    images: &'a [gltf::image::Data],
    scene: Scene,
    image_to_texture: Vec<Option<usize>>,
    /// glTF material index → scene material index; the last scene material is the default.
    material_index: Vec<usize>,
}

impl Loader<'_> {
    fn invalid(&self, what: String) -> SceneError {
        SceneError::Invalid {
            path: self.path.to_owned(),
            what,
        }
    }

    fn load_materials(&mut self, document: &gltf::Document) -> Result<(), SceneError> {
        for m in document.materials() {
            let material = self.convert_material(&m)?;
            let index = self.scene.add_material(material);
            self.material_index.push(index);
        }
        Ok(())
    }

    fn convert_material(&mut self, m: &gltf::Material<'_>) -> Result<Material, SceneError> {
        let pbr = m.pbr_metallic_roughness();
        let base_color_texture = match pbr.base_color_texture() {
            Some(info) => {
                if info.tex_coord() != 0 {
                    tracing::warn!(
                        "{}: material {:?} uses TEXCOORD_{}; only TEXCOORD_0 is supported",
                        self.path.display(),
                        m.name(),
                        info.tex_coord()
                    );
                }
                let tex = info.texture();
                let sampler = tex.sampler();
                Some(TextureRef {
                    texture: self.texture_for_image(tex.source().index())?,
                    wrap_u: wrap(sampler.wrap_s()),
                    wrap_v: wrap(sampler.wrap_t()),
                    nearest: matches!(
                        sampler.mag_filter(),
                        Some(gltf::texture::MagFilter::Nearest)
                    ),
                })
            }
            None => None,
        };
        let strength = m.emissive_strength().unwrap_or(1.0);
        let emissive = m.emissive_factor().map(|c| c * strength);
        let roughness = pbr.roughness_factor().clamp(0.02, 1.0);
        let metallic = pbr.metallic_factor().clamp(0.0, 1.0);
        // Map roughness to a Blinn-Phong exponent (the usual α = r², n = 2/α² − 2 fit).
        let alpha = roughness * roughness;
        let shininess = (2.0 / (alpha * alpha) - 2.0).clamp(1.0, 512.0);
        let alpha_cutoff = match m.alpha_mode() {
            gltf::material::AlphaMode::Mask => Some(m.alpha_cutoff().unwrap_or(0.5)),
            gltf::material::AlphaMode::Blend => {
                tracing::warn!(
                    "{}: material {:?} is alpha-blended; drawn opaque",
                    self.path.display(),
                    m.name()
                );
                None
            }
            gltf::material::AlphaMode::Opaque => None,
        };
        Ok(Material {
            name: m.name().unwrap_or("unnamed").to_owned(),
            base_color: pbr.base_color_factor(),
            base_color_texture,
            emissive,
            unlit: m.unlit(),
            double_sided: m.double_sided(),
            alpha_cutoff,
            shininess,
            specular: 0.04 + 0.5 * (1.0 - roughness) + 0.4 * metallic,
        })
    }

    fn texture_for_image(&mut self, image: usize) -> Result<usize, SceneError> {
        if let Some(Some(index)) = self.image_to_texture.get(image) {
            return Ok(*index);
        }
        let data = self
            .images
            .get(image)
            .ok_or_else(|| self.invalid(format!("texture refers to missing image {image}")))?;
        if data.width == 0
            || data.height == 0
            || data.width > MAX_TEXTURE_SIDE
            || data.height > MAX_TEXTURE_SIDE
        {
            return Err(self.invalid(format!(
                "image {image} is {}×{}; sides must be 1..={MAX_TEXTURE_SIDE}",
                data.width, data.height
            )));
        }
        let rgba8 = to_rgba8(data).ok_or_else(|| {
            self.invalid(format!("image {image} has an unsupported pixel format"))
        })?;
        self.scene.textures.push(Texture {
            name: format!("image{image}"),
            width: data.width,
            height: data.height,
            rgba8,
        });
        let index = self.scene.textures.len() - 1;
        if let Some(slot) = self.image_to_texture.get_mut(image) {
            *slot = Some(index);
        }
        Ok(index)
    }

    fn default_material(&mut self) -> usize {
        // Created lazily, once, for primitives without a material.
        if self.material_index.len() < self.scene.materials.len() {
            return self.scene.materials.len() - 1;
        }
        self.scene.add_material(Material::default())
    }

    fn visit_node(
        &mut self,
        node: &gltf::Node<'_>,
        parent: Mat4,
        depth: usize,
    ) -> Result<(), SceneError> {
        if depth > MAX_NODE_DEPTH {
            return Err(self.invalid(format!(
                "node {} is nested more than {MAX_NODE_DEPTH} deep (cyclic hierarchy?)",
                node.index()
            )));
        }
        let local = Mat4::from_cols_array_2d(&node.transform().matrix());
        let world = parent * local;
        if !world.is_finite() {
            return Err(self.invalid(format!("node {} has a non-finite transform", node.index())));
        }
        if let Some(mesh) = node.mesh() {
            for (p, primitive) in mesh.primitives().enumerate() {
                let label = format!(
                    "mesh {} ({}) primitive {p}",
                    mesh.index(),
                    mesh.name().unwrap_or("unnamed")
                );
                self.add_primitive(&primitive, world, &label)?;
            }
        }
        for child in node.children() {
            self.visit_node(&child, world, depth + 1)?;
        }
        Ok(())
    }

    /// Checks that an accessor lies inside its buffer view and buffer, with the expected type.
    fn check_accessor(
        &self,
        accessor: &gltf::Accessor<'_>,
        what: &str,
        dims: &[Dimensions],
        types: &[DataType],
        label: &str,
    ) -> Result<usize, SceneError> {
        let fail = |why: String| {
            self.invalid(format!(
                "{label}: {what} accessor {}: {why}",
                accessor.index()
            ))
        };
        if !dims.contains(&accessor.dimensions()) || !types.contains(&accessor.data_type()) {
            return Err(fail(format!(
                "has type {:?} {:?}, expected one of {dims:?} × {types:?}",
                accessor.dimensions(),
                accessor.data_type()
            )));
        }
        let count = accessor.count();
        if count == 0 {
            return Err(fail("has count 0".into()));
        }
        if accessor.sparse().is_some() {
            return Err(fail("is sparse; sparse accessors are not supported".into()));
        }
        let view = accessor
            .view()
            .ok_or_else(|| fail("has no buffer view".into()))?;
        let elem = accessor.size();
        let stride = view.stride().unwrap_or(elem);
        let end = stride
            .checked_mul(count - 1)
            .and_then(|n| n.checked_add(elem))
            .and_then(|n| n.checked_add(accessor.offset()));
        if end.is_none_or(|end| end > view.length()) {
            return Err(fail(format!(
                "{count} elements at offset {} with stride {stride} read past the end of buffer \
                 view {} ({} bytes)",
                accessor.offset(),
                view.index(),
                view.length()
            )));
        }
        let buffer_len = self
            .buffers
            .get(view.buffer().index())
            .map_or(0, |b| b.0.len());
        if view
            .offset()
            .checked_add(view.length())
            .is_none_or(|e| e > buffer_len)
        {
            return Err(fail(format!(
                "buffer view {} (offset {}, {} bytes) lies outside buffer {} ({buffer_len} bytes)",
                view.index(),
                view.offset(),
                view.length(),
                view.buffer().index()
            )));
        }
        Ok(count)
    }

    fn add_primitive(
        &mut self,
        primitive: &gltf::Primitive<'_>,
        world: Mat4,
        label: &str,
    ) -> Result<(), SceneError> {
        let mode = primitive.mode();
        if !matches!(
            mode,
            Mode::Triangles | Mode::TriangleStrip | Mode::TriangleFan
        ) {
            tracing::warn!(
                "{}: {label} is drawn as {mode:?}; only triangles are rendered, skipped",
                self.path.display()
            );
            return Ok(());
        }
        let buffers = self.buffers;
        let reader = primitive.reader(|b| buffers.get(b.index()).map(|d| &d.0[..]));
        let unreadable = |what: &str| self.invalid(format!("{label}: cannot read {what}"));

        let pos_acc = primitive
            .get(&gltf::Semantic::Positions)
            .ok_or_else(|| self.invalid(format!("{label}: has no POSITION attribute")))?;
        let n = self.check_accessor(
            &pos_acc,
            "POSITION",
            &[Dimensions::Vec3],
            &[DataType::F32],
            label,
        )?;
        let positions: Vec<[f32; 3]> = reader
            .read_positions()
            .ok_or_else(|| unreadable("POSITION"))?
            .collect();
        if positions.iter().flatten().any(|c| !c.is_finite()) {
            return Err(self.invalid(format!("{label}: POSITION contains NaN or infinity")));
        }

        let normals: Option<Vec<[f32; 3]>> = match primitive.get(&gltf::Semantic::Normals) {
            Some(acc) => {
                let m = self.check_accessor(
                    &acc,
                    "NORMAL",
                    &[Dimensions::Vec3],
                    &[DataType::F32],
                    label,
                )?;
                if m != n {
                    return Err(self.invalid(format!(
                        "{label}: NORMAL has {m} elements but POSITION has {n}"
                    )));
                }
                Some(
                    reader
                        .read_normals()
                        .ok_or_else(|| unreadable("NORMAL"))?
                        .collect(),
                )
            }
            None => None,
        };

        let uvs: Vec<[f32; 2]> = match primitive.get(&gltf::Semantic::TexCoords(0)) {
            Some(acc) => {
                let m = self.check_accessor(
                    &acc,
                    "TEXCOORD_0",
                    &[Dimensions::Vec2],
                    &[DataType::F32, DataType::U8, DataType::U16],
                    label,
                )?;
                if m != n {
                    return Err(self.invalid(format!(
                        "{label}: TEXCOORD_0 has {m} elements but POSITION has {n}"
                    )));
                }
                reader
                    .read_tex_coords(0)
                    .ok_or_else(|| unreadable("TEXCOORD_0"))?
                    .into_f32()
                    .collect()
            }
            None => vec![[0.0; 2]; n],
        };

        let raw_indices: Vec<u32> = match primitive.indices() {
            Some(acc) => {
                self.check_accessor(
                    &acc,
                    "indices",
                    &[Dimensions::Scalar],
                    &[DataType::U8, DataType::U16, DataType::U32],
                    label,
                )?;
                reader
                    .read_indices()
                    .ok_or_else(|| unreadable("indices"))?
                    .into_u32()
                    .collect()
            }
            None => (0..n as u32).collect(),
        };
        if let Some(bad) = raw_indices.iter().find(|&&i| i as usize >= n) {
            return Err(self.invalid(format!(
                "{label}: index {bad} is out of range for {n} vertices"
            )));
        }
        let mut indices = triangle_list(mode, &raw_indices);
        if indices.is_empty() {
            return Ok(());
        }

        let normals = normals.unwrap_or_else(|| generate_normals(&positions, &indices));
        // Normals transform with the inverse transpose; a mirroring transform flips winding.
        let linear = Mat3::from_mat4(world);
        let normal_matrix = linear.inverse().transpose();
        if linear.determinant() < 0.0 {
            for tri in indices.chunks_exact_mut(3) {
                tri.swap(1, 2);
            }
        }
        let vertices: Vec<Vertex> = positions
            .iter()
            .zip(&normals)
            .zip(&uvs)
            .map(|((p, nrm), uv)| Vertex {
                position: world.transform_point3(Vec3::from(*p)).to_array(),
                normal: (normal_matrix * Vec3::from(*nrm))
                    .try_normalize()
                    .unwrap_or(Vec3::Y)
                    .to_array(),
                uv: *uv,
            })
            .collect();

        let material = match primitive.material().index() {
            Some(i) => *self
                .material_index
                .get(i)
                .ok_or_else(|| self.invalid(format!("{label}: refers to missing material {i}")))?,
            None => self.default_material(),
        };
        self.scene.add_mesh(&vertices, &indices, material);
        Ok(())
    }
}

/// Converts strips and fans to a plain triangle list (degenerate triangles dropped).
fn triangle_list(mode: Mode, idx: &[u32]) -> Vec<u32> {
    let mut out = Vec::with_capacity(idx.len().max(3) * 3);
    match mode {
        Mode::TriangleStrip => {
            for i in 2..idx.len() {
                let (a, b, c) = if i % 2 == 0 {
                    (idx[i - 2], idx[i - 1], idx[i])
                } else {
                    (idx[i - 1], idx[i - 2], idx[i])
                };
                if a != b && b != c && a != c {
                    out.extend_from_slice(&[a, b, c]);
                }
            }
        }
        Mode::TriangleFan => {
            for i in 2..idx.len() {
                out.extend_from_slice(&[idx[0], idx[i - 1], idx[i]]);
            }
        }
        _ => {
            let whole = idx.len() / 3 * 3;
            out.extend_from_slice(&idx[..whole]);
        }
    }
    out
}

fn wrap(mode: gltf::texture::WrappingMode) -> Wrap {
    match mode {
        gltf::texture::WrappingMode::ClampToEdge => Wrap::ClampToEdge,
        gltf::texture::WrappingMode::MirroredRepeat => Wrap::MirroredRepeat,
        gltf::texture::WrappingMode::Repeat => Wrap::Repeat,
    }
}

/// Converts decoded glTF image data of any 8/16/32-bit layout to RGBA8.
fn to_rgba8(data: &gltf::image::Data) -> Option<Vec<u8>> {
    use gltf::image::Format as F;
    let px = data.width as usize * data.height as usize;
    let p = &data.pixels;
    let u16_at = |i: usize| (u16::from_le_bytes([p[2 * i], p[2 * i + 1]]) >> 8) as u8;
    let f32_at = |i: usize| {
        let v = f32::from_le_bytes([p[4 * i], p[4 * i + 1], p[4 * i + 2], p[4 * i + 3]]);
        (v.clamp(0.0, 1.0) * 255.0 + 0.5) as u8
    };
    let (channels, bytes_per) = match data.format {
        F::R8 => (1, 1),
        F::R8G8 => (2, 1),
        F::R8G8B8 => (3, 1),
        F::R8G8B8A8 => (4, 1),
        F::R16 => (1, 2),
        F::R16G16 => (2, 2),
        F::R16G16B16 => (3, 2),
        F::R16G16B16A16 => (4, 2),
        F::R32G32B32FLOAT => (3, 4),
        F::R32G32B32A32FLOAT => (4, 4),
    };
    if p.len() < px * channels * bytes_per {
        return None;
    }
    let get = |i: usize| match bytes_per {
        1 => p[i],
        2 => u16_at(i),
        _ => f32_at(i),
    };
    let mut out = Vec::with_capacity(px * 4);
    for i in 0..px {
        let c = |k: usize| get(i * channels + k);
        let rgba = match channels {
            1 => [c(0), c(0), c(0), 255],
            2 => [c(0), c(0), c(0), c(1)],
            3 => [c(0), c(1), c(2), 255],
            _ => [c(0), c(1), c(2), c(3)],
        };
        out.extend_from_slice(&rgba);
    }
    Some(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn strips_and_fans_become_lists() {
        assert_eq!(
            triangle_list(Mode::TriangleStrip, &[0, 1, 2, 3]),
            vec![0, 1, 2, 2, 1, 3]
        );
        assert_eq!(
            triangle_list(Mode::TriangleFan, &[0, 1, 2, 3]),
            vec![0, 1, 2, 0, 2, 3]
        );
    }

    #[test]
    fn short_glb_headers_are_refused() {
        let mut glb = b"glTF".to_vec();
        glb.extend_from_slice(&2u32.to_le_bytes());
        glb.extend_from_slice(&4u32.to_le_bytes());
        glb.extend_from_slice(&[0; 8]);
        assert!(check_glb_header(&glb).is_err());
        assert!(check_glb_header(&glb[..10]).is_err());
    }
}
