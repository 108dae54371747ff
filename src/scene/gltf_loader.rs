//! Loads glTF 2.0 (`.gltf` + buffers/images, or `.glb`) into a [`Scene`], refusing bad files
//! with an error that names the file and the offending object instead of panicking.

use std::path::{Path, PathBuf};

use std::collections::HashMap;

use glam::{Mat3, Mat4, Vec3};
use gltf::accessor::Dimensions;
use gltf::mesh::Mode;

use super::budget::{SceneBudget, SceneTotals, fitted_size, texture_bytes};
use super::gltf_data::{BinaryData, load_buffers};
use super::gltf_rig::{RigBuilder, RigContext};
use super::rig::RestVertex;
use super::tangents::generate_tangents;
use super::{
    AlphaMode, Camera, ColorSpace, Light, LightKind, Material, Scene, TEXTURE_SLOT_NAMES,
    TEXTURE_SLOTS, Texture, TextureRef, UvTransform, Vertex, Wrap, generate_normals,
};
use crate::read_capped::{human_bytes, read_capped};

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

/// Largest image side decoded at all (larger ones are refused from their header; those
/// between `budgets.max_texture_side` and this are decoded and downscaled).
const MAX_IMAGE_SIDE: u32 = 65_536;
/// Deeper node nesting than this is treated as a cycle (the glTF spec forbids cycles).
const MAX_NODE_DEPTH: usize = 128;

/// Loads a `.gltf` or `.glb` file under the default [`SceneBudget`]; external buffers and
/// images are resolved next to it.
pub fn load_gltf(path: &Path) -> Result<Scene, SceneError> {
    load_gltf_within(path, &SceneBudget::default())
}

/// Loads a `.gltf` or `.glb` file under `budget` (refused with the budget named when over).
pub fn load_gltf_within(path: &Path, budget: &SceneBudget) -> Result<Scene, SceneError> {
    let bytes = read_capped(path, budget.max_file_bytes, FILE_BUDGET).map_err(|source| {
        SceneError::Read {
            path: path.to_owned(),
            source,
        }
    })?;
    load_gltf_bytes(&bytes, path, budget)
}

/// What the texture budget charges a texture at least (GPU allocations have a granularity
/// and an object behind each), bytes.
const MIN_TEXTURE_CHARGE: u64 = 64 << 10;
/// Most materials a file may define (each is a 256-byte uniform block and a bind group;
/// variants without some textures come on top).
const MAX_MATERIALS: usize = 65_536;

/// Where the file size cap is set (for messages).
const FILE_BUDGET: &str = "budgets.max_file_mb";
/// The same cap, for the files a glTF names (for messages).
const FILES_BUDGET: &str = "what is left of budgets.max_file_mb for the scene's files together";

/// Loads glTF from bytes under `budget`; `path` names the file in errors and locates
/// external resources.
pub fn load_gltf_bytes(
    bytes: &[u8],
    path: &Path,
    budget: &SceneBudget,
) -> Result<Scene, SceneError> {
    let invalid = |what: String| SceneError::Invalid {
        path: path.to_owned(),
        what,
    };
    check_glb_header(bytes).map_err(&invalid)?;
    // The checks in this module cover every panic we know of in the gltf crate; this guard
    // turns one we do not know of into an error instead of taking the application down.
    let parsed = std::panic::catch_unwind(|| load_unguarded(bytes, path, budget));
    match parsed {
        Ok(result) => result,
        Err(_) => Err(invalid(
            "the glTF parser failed on this file (malformed data it did not expect)".into(),
        )),
    }
}

/// Extensions read here; a file may require them.
const HANDLED_EXTENSIONS: &[&str] = &[
    "KHR_materials_unlit",
    "KHR_materials_emissive_strength",
    "KHR_texture_transform",
    "KHR_mesh_quantization",
    "EXT_meshopt_compression",
    "KHR_lights_punctual",
    "KHR_draco_mesh_compression",
];

/// Parses the JSON (and the GLB's BIN chunk), checks the extensions the file requires or uses,
/// then lets the gltf crate validate the document.
fn parse_document(
    bytes: &[u8],
    path: &Path,
) -> Result<(gltf::Document, Option<Vec<u8>>), SceneError> {
    let gltf_err = |source| SceneError::Gltf {
        path: path.to_owned(),
        source,
    };
    let invalid = |what: String| SceneError::Invalid {
        path: path.to_owned(),
        what,
    };
    let gltf::Gltf { document, blob } =
        gltf::Gltf::from_slice_without_validation(bytes).map_err(gltf_err)?;
    let mut root = document.into_json();
    for name in &root.extensions_required {
        if !HANDLED_EXTENSIONS.contains(&name.as_str()) {
            return Err(invalid(format!(
                "it requires the extension {name}, which omnicave does not support"
            )));
        }
    }
    for name in &root.extensions_used {
        if !HANDLED_EXTENSIONS.contains(&name.as_str()) {
            tracing::warn!(
                "{}: ignores the extension {name} (not supported); what it adds is not drawn",
                path.display()
            );
        }
    }
    // Checked above: the crate would refuse what it does not itself decode.
    root.extensions_required.clear();
    // The crate's `Image::source` unwraps what the specification requires: an image from a
    // buffer view without a MIME type (its bytes tell the format; it is guessed from them
    // anyway) gets a placeholder, and one with neither a URI nor a buffer view is refused.
    for (i, image) in root.images.iter_mut().enumerate() {
        match (&image.buffer_view, &image.uri) {
            (Some(_), _) if image.mime_type.is_none() => {
                image.mime_type = Some(gltf::json::image::MimeType(
                    "application/octet-stream".into(),
                ));
            }
            (None, None) => {
                return Err(invalid(format!(
                    "image {i} has neither a uri nor a bufferView"
                )));
            }
            _ => {}
        }
    }
    // The crate's validation indexes a primitive's POSITION accessor without a bounds check
    // (found by the glTF fuzzer): every accessor a primitive names is checked first.
    let accessors = root.accessors.len();
    for (m, mesh) in root.meshes.iter().enumerate() {
        for (p, primitive) in mesh.primitives.iter().enumerate() {
            let named = primitive
                .attributes
                .values()
                .chain(primitive.indices.iter())
                .chain(primitive.targets.iter().flatten().flat_map(|t| {
                    t.positions
                        .iter()
                        .chain(t.normals.iter())
                        .chain(t.tangents.iter())
                }));
            for index in named {
                if index.value() >= accessors {
                    return Err(invalid(format!(
                        "mesh {m} primitive {p} refers to accessor {}, but the file has {accessors}",
                        index.value()
                    )));
                }
            }
        }
    }
    // The crate's validation checks neither a channel's target node nor its path, and its
    // accessors unwrap both: checked here, naming the channel.
    let nodes = root.nodes.len();
    for (a, animation) in root.animations.iter().enumerate() {
        for (c, channel) in animation.channels.iter().enumerate() {
            let node = channel.target.node.value();
            if node >= nodes {
                return Err(invalid(format!(
                    "animation {a} channel {c} targets node {node}, but the file has {nodes}"
                )));
            }
            if !matches!(
                channel.target.path,
                gltf::json::validation::Checked::Valid(_)
            ) {
                return Err(invalid(format!(
                    "animation {a} channel {c} targets a path other than translation, \
                     rotation, scale or weights"
                )));
            }
        }
    }
    // The crate's own validation, but for one rule stricter than the specification: an
    // accessor without a buffer view is legal (zeros, or the data of a Draco primitive).
    let mut errors = Vec::new();
    {
        use gltf::json::validation::{Error, Validate};
        root.validate(&root, gltf::json::Path::new, &mut |path, error| {
            let path = path();
            let accessor_view =
                path.as_str().starts_with("accessors[") && path.as_str().ends_with("].bufferView");
            if !(error == Error::Missing && accessor_view) {
                errors.push((path, error));
            }
        });
    }
    if !errors.is_empty() {
        return Err(gltf_err(gltf::Error::Validation(errors)));
    }
    let document = gltf::Document::from_json_without_validation(root);
    Ok((document, blob))
}

fn load_unguarded(bytes: &[u8], path: &Path, budget: &SceneBudget) -> Result<Scene, SceneError> {
    let invalid = |what: String| SceneError::Invalid {
        path: path.to_owned(),
        what,
    };
    let (document, blob) = parse_document(bytes, path)?;
    let base = path.parent().unwrap_or(Path::new("."));
    check_external_files(&document, base, path)?;
    // The scene's files together (the file, its buffers, its images) are held to the file
    // budget: a hundred buffers naming one large file are not read a hundred times over.
    let read = std::cell::Cell::new(bytes.len() as u64);
    let buffers = load_buffers(&document, blob, &|uri| {
        let file = base.join(percent_decode(uri));
        let left = budget.max_file_bytes.saturating_sub(read.get());
        let data = read_capped(&file, left, FILES_BUDGET)
            .map_err(|e| format!("{}: {e}", file.display()))?;
        read.set(read.get() + data.len() as u64);
        Ok(data)
    })
    .map_err(&invalid)?;
    let data = BinaryData::new(&document, buffers);
    let rig = RigBuilder::new(
        &document,
        &RigContext {
            data: &data,
            budget,
            path,
        },
    )
    .map_err(&invalid)?;
    let mut loader = Loader {
        rig,
        path,
        base,
        data: &data,
        scene: Scene::default(),
        image_textures: HashMap::new(),
        material_index: Vec::new(),
        default_material: None,
        material_variants: HashMap::new(),
        document: &document,
        budget: *budget,
        texture_bytes: 0,
        files_read: read.get(),
    };
    let gltf_scene = document
        .default_scene()
        .or_else(|| document.scenes().next())
        .ok_or_else(|| loader.invalid("the file contains no scene".into()))?;
    // Counted before anything is built: a node graph that expands past the budget (a node
    // listed twice as a child doubles its subtree at every level) is refused up front.
    let mut totals = SceneTotals::default();
    for node in gltf_scene.nodes() {
        loader.count_node(&node, 0, &mut totals)?;
    }
    loader.load_materials(&document)?;
    for node in gltf_scene.nodes() {
        loader.visit_node(&node, Mat4::IDENTITY, 0)?;
    }
    if loader.scene.indices.is_empty() {
        return Err(loader.invalid("the scene contains no triangles".into()));
    }
    let rig = std::mem::take(&mut loader.rig);
    let mut scene = loader.scene;
    scene.rig = rig.finish(&mut scene.vertices);
    Ok(scene)
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
        let fallback = buffer.extension_value("EXT_meshopt_compression").is_some();
        if let gltf::buffer::Source::Uri(uri) = buffer.source()
            && !fallback
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

/// A texture as a material refers to it: the texture, its coordinate set, its transform.
struct TextureUse<'a> {
    texture: gltf::Texture<'a>,
    tex_coord: u32,
    /// The `KHR_texture_transform` object, if any.
    transform: Option<serde_json::Value>,
}

struct Loader<'a> {
    /// Animations, skins and morph targets, and the primitives they pose.
    rig: RigBuilder,
    path: &'a Path,
    base: &'a Path,
    document: &'a gltf::Document,
    data: &'a BinaryData,
    scene: Scene,
    /// (image, colour space) → scene texture: each image is decoded once, and only if used.
    image_textures: HashMap<(usize, ColorSpace), usize>,
    /// glTF material index → scene material index.
    material_index: Vec<usize>,
    /// The material of primitives without one, once needed.
    default_material: Option<usize>,
    /// (scene material, texture slots dropped) → scene material without those textures.
    material_variants: HashMap<(usize, u32), usize>,
    budget: SceneBudget,
    /// Texture memory taken so far (with mips).
    texture_bytes: u64,
    /// Bytes of the scene's files read so far (the file, its buffers and images).
    files_read: u64,
}

impl Loader<'_> {
    fn invalid(&self, what: String) -> SceneError {
        SceneError::Invalid {
            path: self.path.to_owned(),
            what,
        }
    }

    fn warn(&self, what: &str) {
        tracing::warn!("{}: {what}", self.path.display());
    }

    fn load_materials(&mut self, document: &gltf::Document) -> Result<(), SceneError> {
        let count = document.materials().len();
        if count > MAX_MATERIALS {
            return Err(self.invalid(format!(
                "it defines {count} materials; omnicave takes at most {MAX_MATERIALS}"
            )));
        }
        for m in document.materials() {
            let material = self.convert_material(&m)?;
            let index = self.scene.add_material(material);
            self.material_index.push(index);
        }
        Ok(())
    }

    fn convert_material(&mut self, m: &gltf::Material<'_>) -> Result<Material, SceneError> {
        let name = m.name().unwrap_or("unnamed").to_owned();
        let pbr = m.pbr_metallic_roughness();
        fn info_use(info: gltf::texture::Info<'_>) -> TextureUse<'_> {
            TextureUse {
                texture: info.texture(),
                tex_coord: info.tex_coord(),
                transform: info.extension_value("KHR_texture_transform").cloned(),
            }
        }
        let base_color_texture = pbr.base_color_texture().map(info_use);
        let mr_texture = pbr.metallic_roughness_texture().map(info_use);
        let emissive_texture = m.emissive_texture().map(info_use);
        let normal = m.normal_texture();
        let normal_scale = normal.as_ref().map_or(1.0, |n| n.scale());
        let normal_texture = normal.map(|n| TextureUse {
            texture: n.texture(),
            tex_coord: n.tex_coord(),
            transform: n.extension_value("KHR_texture_transform").cloned(),
        });
        let occlusion = m.occlusion_texture();
        let occlusion_strength = occlusion.as_ref().map_or(1.0, |o| o.strength());
        let occlusion_texture = occlusion.map(|o| TextureUse {
            texture: o.texture(),
            tex_coord: o.tex_coord(),
            transform: o.extension_value("KHR_texture_transform").cloned(),
        });
        let strength = m.emissive_strength().unwrap_or(1.0);
        let alpha_mode = match m.alpha_mode() {
            gltf::material::AlphaMode::Mask => AlphaMode::Mask(m.alpha_cutoff().unwrap_or(0.5)),
            gltf::material::AlphaMode::Blend => AlphaMode::Blend,
            gltf::material::AlphaMode::Opaque => AlphaMode::Opaque,
        };
        let mut material = Material {
            name: name.clone(),
            base_color: pbr.base_color_factor(),
            base_color_texture: None,
            metallic: pbr.metallic_factor().clamp(0.0, 1.0),
            roughness: pbr.roughness_factor().clamp(0.0, 1.0),
            metallic_roughness_texture: None,
            normal_texture: None,
            normal_scale,
            occlusion_texture: None,
            occlusion_strength: occlusion_strength.clamp(0.0, 1.0),
            emissive: m.emissive_factor().map(|c| c * strength),
            emissive_texture: None,
            unlit: m.unlit(),
            double_sided: m.double_sided(),
            alpha_mode,
        };
        let uses = [
            base_color_texture,
            mr_texture,
            normal_texture,
            occlusion_texture,
            emissive_texture,
        ];
        let spaces = [
            ColorSpace::Srgb,
            ColorSpace::Linear,
            ColorSpace::Linear,
            ColorSpace::Linear,
            ColorSpace::Srgb,
        ];
        for (slot, (texture_use, space)) in uses.into_iter().zip(spaces).enumerate() {
            let Some(texture_use) = texture_use else {
                continue;
            };
            let reference = self.texture_ref(&name, slot, &texture_use, space)?;
            *material.texture_slots_mut()[slot] = reference;
        }
        Ok(material)
    }

    /// A material's texture slot: the image decoded (once per colour space), the sampler,
    /// the coordinate set and `KHR_texture_transform`. `None` (with a warning) where the
    /// texture cannot be drawn.
    fn texture_ref(
        &mut self,
        material: &str,
        slot: usize,
        texture_use: &TextureUse<'_>,
        space: ColorSpace,
    ) -> Result<Option<TextureRef>, SceneError> {
        let slot_name = TEXTURE_SLOT_NAMES[slot];
        let transform = match &texture_use.transform {
            Some(t) => Some(parse_texture_transform(t).map_err(|why| {
                self.invalid(format!(
                    "material {material:?} {slot_name}: KHR_texture_transform {why}"
                ))
            })?),
            None => None,
        };
        let tex_coord = transform
            .and_then(|(_, set)| set)
            .unwrap_or(texture_use.tex_coord);
        if tex_coord > 1 {
            self.warn(&format!(
                "material {material:?} {slot_name} uses TEXCOORD_{tex_coord}; only TEXCOORD_0 \
                 and TEXCOORD_1 are read, the texture is not drawn"
            ));
            return Ok(None);
        }
        let texture = &texture_use.texture;
        let sampler = texture.sampler();
        Ok(Some(TextureRef {
            texture: self.texture_for_image(texture.source().index(), space)?,
            wrap_u: wrap(sampler.wrap_s()),
            wrap_v: wrap(sampler.wrap_t()),
            nearest: matches!(
                sampler.mag_filter(),
                Some(gltf::texture::MagFilter::Nearest)
            ),
            tex_coord,
            transform: transform.map_or(UvTransform::IDENTITY, |(t, _)| t),
        }))
    }

    fn texture_for_image(&mut self, image: usize, space: ColorSpace) -> Result<usize, SceneError> {
        if let Some(&index) = self.image_textures.get(&(image, space)) {
            return Ok(index);
        }
        // The same image in the other colour space: decoded already, only relabelled.
        let other = match space {
            ColorSpace::Srgb => ColorSpace::Linear,
            ColorSpace::Linear => ColorSpace::Srgb,
        };
        let (width, height, rgba8) = match self.image_textures.get(&(image, other)) {
            Some(&index) => {
                let (w, h) = (
                    self.scene.textures[index].width,
                    self.scene.textures[index].height,
                );
                self.take_texture_memory(image, w, h)?;
                let t = &self.scene.textures[index];
                (t.width, t.height, t.rgba8.clone())
            }
            None => self.decode_image(image)?,
        };
        self.scene.textures.push(Texture {
            name: format!("image{image}"),
            width,
            height,
            rgba8,
            color_space: space,
        });
        let index = self.scene.textures.len() - 1;
        self.image_textures.insert((image, space), index);
        Ok(index)
    }

    /// Counts a `width`×`height` texture (with mips) against `budgets.max_texture_memory_mb`.
    fn take_texture_memory(
        &mut self,
        image: usize,
        width: u32,
        height: u32,
    ) -> Result<(), SceneError> {
        // Every texture costs at least its GPU object's overhead: a million 1×1 images must
        // not pass as a few megabytes.
        let bytes = texture_bytes(width, height).max(MIN_TEXTURE_CHARGE);
        let total = self.texture_bytes.saturating_add(bytes);
        if total > self.budget.max_texture_bytes {
            return Err(self.invalid(format!(
                "image {image} ({width}×{height}, {} with mips) brings the textures to {}, \
                 over budgets.max_texture_memory_mb = {} (lower budgets.max_texture_side to \
                 downscale them, or raise the budget)",
                human_bytes(bytes),
                human_bytes(total),
                self.budget.max_texture_bytes >> 20
            )));
        }
        self.texture_bytes = total;
        Ok(())
    }

    /// Decodes one image (PNG or JPEG, from a buffer view, a data URI or a file) to RGBA8,
    /// checking its size from the header first: the texture memory it will take is counted
    /// against the budget before the pixels are decoded, and an image larger than
    /// `budgets.max_texture_side` is downscaled to it, with a warning.
    fn decode_image(&mut self, image: usize) -> Result<(u32, u32, Vec<u8>), SceneError> {
        let path = self.path;
        let fail = |why: String| SceneError::Invalid {
            path: path.to_owned(),
            what: format!("image {image}: {why}"),
        };
        let gltf_image = self
            .document
            .images()
            .nth(image)
            .ok_or_else(|| fail("does not exist".into()))?;
        let encoded: Vec<u8> = match gltf_image.source() {
            gltf::image::Source::View { view, .. } => {
                self.data.view_bytes(&view).map_err(&fail)?.to_vec()
            }
            gltf::image::Source::Uri { uri, .. } if uri.starts_with("data:") => {
                decode_data_uri(uri).map_err(&fail)?
            }
            gltf::image::Source::Uri { uri, .. } => {
                let file = self.base.join(percent_decode(uri));
                let left = self.budget.max_file_bytes.saturating_sub(self.files_read);
                let data = read_capped(&file, left, FILES_BUDGET)
                    .map_err(|e| fail(format!("{}: {e}", file.display())))?;
                self.files_read += data.len() as u64;
                data
            }
        };
        let reader = image::ImageReader::new(std::io::Cursor::new(&encoded))
            .with_guessed_format()
            .map_err(|e| fail(e.to_string()))?;
        let (w, h) = reader.into_dimensions().map_err(|e| fail(e.to_string()))?;
        check_image_size(w, h).map_err(&fail)?;
        // The full-size image is decoded first: it must fit the texture budget on its own.
        let decoded_bytes = u64::from(w) * u64::from(h) * 4;
        if decoded_bytes > self.budget.max_texture_bytes {
            return Err(fail(format!(
                "is {w}×{h}: {} decoded, over budgets.max_texture_memory_mb = {}",
                human_bytes(decoded_bytes),
                self.budget.max_texture_bytes >> 20
            )));
        }
        let (fw, fh) = fitted_size(w, h, self.budget.max_texture_side);
        self.take_texture_memory(image, fw, fh)?;
        // The decoder's own allocation limit follows the budget (its default, 512 MiB, would
        // refuse a 16384² image the budget allows).
        let mut reader = image::ImageReader::new(std::io::Cursor::new(&encoded))
            .with_guessed_format()
            .map_err(|e| fail(e.to_string()))?;
        let mut limits = image::Limits::default();
        limits.max_alloc = Some(self.budget.max_texture_bytes.max(decoded_bytes));
        reader.limits(limits);
        let decoded = reader.decode().map_err(|e| fail(e.to_string()))?;
        let rgba = decoded.to_rgba8();
        if (fw, fh) == (w, h) {
            return Ok((w, h, rgba.into_raw()));
        }
        self.warn(&format!(
            "image {image} is {w}×{h}; downscaled to {fw}×{fh} (budgets.max_texture_side = {})",
            self.budget.max_texture_side
        ));
        let small = image::imageops::resize(&rgba, fw, fh, image::imageops::FilterType::Triangle);
        Ok((fw, fh, small.into_raw()))
    }

    fn default_material(&mut self) -> usize {
        // Created lazily, once, for primitives without a material.
        if let Some(index) = self.default_material {
            return index;
        }
        let index = self.scene.add_material(Material::default());
        self.default_material = Some(index);
        index
    }

    /// `material` without the texture slots in `dropped` (a bit per slot): for primitives
    /// that lack the coordinates or tangents those textures need. Created once per pair.
    fn material_without(&mut self, material: usize, dropped: u32) -> usize {
        if dropped == 0 {
            return material;
        }
        if let Some(&index) = self.material_variants.get(&(material, dropped)) {
            return index;
        }
        let mut variant = self.scene.materials[material].clone();
        for (slot, texture) in variant.texture_slots_mut().into_iter().enumerate() {
            if dropped & (1 << slot) != 0 {
                *texture = None;
            }
        }
        let index = self.scene.add_material(variant);
        self.material_variants.insert((material, dropped), index);
        index
    }

    /// Counts what drawing `node` (and its subtree) adds, without building anything; stops
    /// at the first budget passed, naming the node and mesh.
    fn count_node(
        &self,
        node: &gltf::Node<'_>,
        depth: usize,
        totals: &mut SceneTotals,
    ) -> Result<(), SceneError> {
        if depth > MAX_NODE_DEPTH {
            return Err(self.invalid(format!(
                "node {} is nested more than {MAX_NODE_DEPTH} deep (cyclic hierarchy?)",
                node.index()
            )));
        }
        let over = |why: String, what: String| {
            self.invalid(format!(
                "{why} (at {what}); raise the budget in the config's [budgets] if the scene \
                 is meant to be this large"
            ))
        };
        let node_name = || {
            format!(
                "node {} ({})",
                node.index(),
                node.name().unwrap_or("unnamed")
            )
        };
        // The node itself is an instance: an empty node graph can explode too.
        totals
            .add(0, 0, &self.budget)
            .map_err(|why| over(why, node_name()))?;
        if let Some(mesh) = node.mesh() {
            for primitive in mesh.primitives() {
                let vertices = primitive
                    .get(&gltf::Semantic::Positions)
                    .map_or(0, |a| a.count() as u64);
                let corners = primitive.indices().map_or(vertices, |a| a.count() as u64);
                let triangles = match primitive.mode() {
                    Mode::Triangles => corners / 3,
                    Mode::TriangleStrip | Mode::TriangleFan => corners.saturating_sub(2),
                    _ => 0,
                };
                totals
                    .add(vertices, triangles, &self.budget)
                    .map_err(|why| {
                        over(
                            why,
                            format!(
                                "{}, mesh {} ({})",
                                node_name(),
                                mesh.index(),
                                mesh.name().unwrap_or("unnamed")
                            ),
                        )
                    })?;
            }
        }
        for child in node.children() {
            self.count_node(&child, depth + 1, totals)?;
        }
        Ok(())
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
                self.add_primitive(node, &primitive, world, &label)?;
            }
        }
        if let Some(light) = node.light() {
            self.add_light(&light, world);
        }
        if let Some(camera) = node.camera() {
            let yfov = match camera.projection() {
                gltf::camera::Projection::Perspective(p) => Some(p.yfov()),
                gltf::camera::Projection::Orthographic(_) => None,
            };
            self.scene.cameras.push(Camera {
                name: camera
                    .name()
                    .or(node.name())
                    .map_or_else(|| format!("camera {}", camera.index()), str::to_owned),
                position: world.transform_point3(Vec3::ZERO),
                forward: world
                    .transform_vector3(Vec3::NEG_Z)
                    .try_normalize()
                    .unwrap_or(Vec3::NEG_Z),
                yfov,
            });
        }
        for child in node.children() {
            self.visit_node(&child, world, depth + 1)?;
        }
        Ok(())
    }

    fn add_light(&mut self, light: &gltf::khr_lights_punctual::Light<'_>, world: Mat4) {
        let kind = match light.kind() {
            gltf::khr_lights_punctual::Kind::Directional => LightKind::Directional,
            gltf::khr_lights_punctual::Kind::Point => LightKind::Point,
            gltf::khr_lights_punctual::Kind::Spot {
                inner_cone_angle,
                outer_cone_angle,
            } => LightKind::Spot {
                inner_cone: inner_cone_angle.clamp(0.0, std::f32::consts::FRAC_PI_2),
                outer_cone: outer_cone_angle.clamp(0.0, std::f32::consts::FRAC_PI_2),
            },
        };
        let intensity = light.intensity().max(0.0);
        let color = Vec3::from(light.color()).max(Vec3::ZERO) * intensity;
        let range = light.range().filter(|r| r.is_finite() && *r > 0.0);
        if !color.is_finite() {
            self.warn(&format!(
                "light {} has a non-finite intensity, skipped",
                light.index()
            ));
            return;
        }
        self.scene.lights.push(Light {
            name: light
                .name()
                .map_or_else(|| format!("light {}", light.index()), str::to_owned),
            kind,
            position: world.transform_point3(Vec3::ZERO),
            direction: world
                .transform_vector3(Vec3::NEG_Z)
                .try_normalize()
                .unwrap_or(Vec3::NEG_Y),
            color,
            range,
            casts_shadows: true,
        });
    }

    /// Reads one attribute accessor with `N` components per element, checked to have one
    /// element per vertex and only finite values.
    fn attribute<const N: usize>(
        &self,
        accessor: &gltf::Accessor<'_>,
        what: &str,
        vertices: Option<usize>,
        label: &str,
    ) -> Result<Vec<[f32; N]>, SceneError> {
        let fail = |why: String| {
            self.invalid(format!(
                "{label}: {what} accessor {}: {why}",
                accessor.index()
            ))
        };
        let values = self.data.read_f32::<N>(accessor).map_err(fail)?;
        if let Some(n) = vertices
            && values.len() != n
        {
            return Err(self.invalid(format!(
                "{label}: {what} has {} elements but POSITION has {n}",
                values.len()
            )));
        }
        if values.iter().flatten().any(|c| !c.is_finite()) {
            return Err(self.invalid(format!("{label}: {what} contains NaN or infinity")));
        }
        Ok(values)
    }

    /// A primitive's attributes and indices from its accessors.
    fn accessor_attributes(
        &self,
        primitive: &gltf::Primitive<'_>,
        label: &str,
    ) -> Result<PrimitiveAttributes, SceneError> {
        let pos_acc = primitive
            .get(&gltf::Semantic::Positions)
            .ok_or_else(|| self.invalid(format!("{label}: has no POSITION attribute")))?;
        let positions = self.attribute::<3>(&pos_acc, "POSITION", None, label)?;
        let n = positions.len();
        let get = |semantic: gltf::Semantic| primitive.get(&semantic);
        let normals = match get(gltf::Semantic::Normals) {
            Some(acc) => Some(self.attribute::<3>(&acc, "NORMAL", Some(n), label)?),
            None => None,
        };
        let tangents = match get(gltf::Semantic::Tangents) {
            Some(acc) => Some(self.attribute::<4>(&acc, "TANGENT", Some(n), label)?),
            None => None,
        };
        let uv0 = match get(gltf::Semantic::TexCoords(0)) {
            Some(acc) => Some(self.attribute::<2>(&acc, "TEXCOORD_0", Some(n), label)?),
            None => None,
        };
        let uv1 = match get(gltf::Semantic::TexCoords(1)) {
            Some(acc) => Some(self.attribute::<2>(&acc, "TEXCOORD_1", Some(n), label)?),
            None => None,
        };
        let colors: Option<Vec<[f32; 4]>> = match get(gltf::Semantic::Colors(0)) {
            Some(acc) if acc.dimensions() == Dimensions::Vec3 => Some(
                self.attribute::<3>(&acc, "COLOR_0", Some(n), label)?
                    .into_iter()
                    .map(|[r, g, b]| [r, g, b, 1.0])
                    .collect(),
            ),
            Some(acc) => Some(self.attribute::<4>(&acc, "COLOR_0", Some(n), label)?),
            None => None,
        };

        let raw_indices: Vec<u32> = match primitive.indices() {
            Some(acc) => self.data.read_u32(&acc).map_err(|why| {
                self.invalid(format!("{label}: indices accessor {}: {why}", acc.index()))
            })?,
            None => (0..n as u32).collect(),
        };
        Ok((positions, normals, tangents, uv0, uv1, colors, raw_indices))
    }

    /// A Draco-compressed primitive's attributes and indices (`KHR_draco_mesh_compression`).
    fn draco_attributes(
        &self,
        primitive: &gltf::Primitive<'_>,
        ext: &serde_json::Value,
        label: &str,
    ) -> Result<PrimitiveAttributes, SceneError> {
        let fail =
            |why: String| self.invalid(format!("{label}: KHR_draco_mesh_compression: {why}"));
        let view_index = ext
            .get("bufferView")
            .and_then(serde_json::Value::as_u64)
            .ok_or_else(|| fail("has no bufferView".into()))?;
        let view = self
            .document
            .views()
            .nth(view_index as usize)
            .ok_or_else(|| fail(format!("buffer view {view_index} does not exist")))?;
        let bytes = self.data.view_bytes(&view).map_err(&fail)?;
        let attributes = ext
            .get("attributes")
            .and_then(serde_json::Value::as_object)
            .ok_or_else(|| fail("has no attributes".into()))?;
        // How the file's accessor says an attribute is stored: normalized integers are
        // mapped to 0..1 by the largest value of their type.
        let normalized = |name: &str| {
            let semantic = match name {
                "COLOR_0" => gltf::Semantic::Colors(0),
                "TEXCOORD_0" => gltf::Semantic::TexCoords(0),
                "TEXCOORD_1" => gltf::Semantic::TexCoords(1),
                _ => return None,
            };
            let accessor = primitive.get(&semantic)?;
            let max = match accessor.data_type() {
                gltf::accessor::DataType::U8 | gltf::accessor::DataType::I8 => 255,
                gltf::accessor::DataType::U16 | gltf::accessor::DataType::I16 => 65535,
                _ => return None,
            };
            Some((accessor.normalized(), max))
        };
        let p = super::gltf_draco::decode(bytes, attributes, normalized).map_err(fail)?;
        Ok((
            p.positions,
            p.normals,
            p.tangents,
            p.uv0,
            p.uv1,
            p.colors,
            p.indices,
        ))
    }

    fn add_primitive(
        &mut self,
        node: &gltf::Node<'_>,
        primitive: &gltf::Primitive<'_>,
        world: Mat4,
        label: &str,
    ) -> Result<(), SceneError> {
        let mode = primitive.mode();
        if !matches!(
            mode,
            Mode::Triangles | Mode::TriangleStrip | Mode::TriangleFan
        ) {
            self.warn(&format!(
                "{label} is drawn as {mode:?}; only triangles are rendered, skipped"
            ));
            return Ok(());
        }
        let draco = primitive.extension_value("KHR_draco_mesh_compression");
        let (positions, normals, tangents, uv0, uv1, colors, raw_indices) = match draco {
            Some(ext) => self.draco_attributes(primitive, ext, label)?,
            None => self.accessor_attributes(primitive, label)?,
        };
        let deformed = self.rig.deforms(node, primitive);
        if deformed && draco.is_some() {
            self.warn(&format!(
                "{label} is Draco-compressed: its skin and morph targets are not read, it is \
                 drawn static in its rest pose"
            ));
        }
        let deformed = deformed && draco.is_none();
        let n = positions.len();
        self.check_decoded_counts(primitive, label, n, &raw_indices)?;
        let mut indices = triangle_list(mode, &raw_indices);
        if indices.is_empty() {
            return Ok(());
        }

        let material = self.primitive_material(primitive, label)?;
        let slots = self.scene.materials[material].texture_slots();
        let mut dropped =
            self.textures_without_coordinates(&slots, label, [uv0.is_some(), uv1.is_some()]);

        let normals = normals.unwrap_or_else(|| generate_normals(&positions, &indices));
        let attributes = FilledAttributes {
            uvs: uv0.unwrap_or_else(|| vec![[0.0; 2]; n]),
            uvs1: uv1.unwrap_or_else(|| vec![[0.0; 2]; n]),
            colors: colors.unwrap_or_else(|| vec![[1.0; 4]; n]),
            positions,
            normals,
        };
        // A normal map needs tangents: the file's, else MikkTSpace's on the map's coordinates.
        let normal_map = slots[NORMAL_SLOT].filter(|_| dropped & (1 << NORMAL_SLOT) == 0);
        let tangents = match (tangents, normal_map) {
            (Some(t), _) => t,
            (None, Some(map)) => {
                self.generated_tangents(&attributes, map, &indices, label, &mut dropped)
            }
            (None, None) => vec![[0.0; 4]; n],
        };
        let material = self.material_without(material, dropped);
        if !deformed {
            let vertices = transformed_vertices(world, &attributes, &tangents, &mut indices);
            self.scene.add_mesh(&vertices, &indices, material);
            return Ok(());
        }
        // Posed per frame: kept in mesh space (the rig poses it at rest once all is read).
        let vertices = transformed_vertices(Mat4::IDENTITY, &attributes, &tangents, &mut indices);
        if self.rig.mirrors(node) {
            for tri in indices.chunks_exact_mut(3) {
                tri.swap(1, 2);
            }
        }
        let rest = vertices
            .iter()
            .map(|v| RestVertex {
                position: v.position,
                normal: v.normal,
                tangent: v.tangent,
            })
            .collect();
        let first_vertex = self.scene.vertices.len() as u32;
        let path = self.path;
        let cx = RigContext {
            data: self.data,
            budget: &self.budget,
            path,
        };
        self.rig
            .add(&cx, node, primitive, rest, first_vertex, label)
            .map_err(|what| SceneError::Invalid {
                path: path.to_owned(),
                what,
            })?;
        self.scene.add_mesh(&vertices, &indices, material);
        Ok(())
    }

    /// Refuses a primitive that decodes to more vertices or indices than its accessors
    /// declare (what the budget counted), or whose indices point past its vertices.
    fn check_decoded_counts(
        &self,
        primitive: &gltf::Primitive<'_>,
        label: &str,
        n: usize,
        raw_indices: &[u32],
    ) -> Result<(), SceneError> {
        // The budget counted what the accessors declare; a Draco bitstream decodes to what
        // it holds, which must not be more.
        let declared_vertices = primitive
            .get(&gltf::Semantic::Positions)
            .map_or(0, |a| a.count());
        let declared_indices = primitive.indices().map_or(n, |a| a.count());
        if n > declared_vertices || raw_indices.len() > declared_indices.max(n) {
            return Err(self.invalid(format!(
                "{label}: decodes to {n} vertices and {} indices, more than its accessors \
                 declare ({declared_vertices} and {declared_indices})",
                raw_indices.len()
            )));
        }
        if let Some(bad) = raw_indices.iter().find(|&&i| i as usize >= n) {
            return Err(self.invalid(format!(
                "{label}: index {bad} is out of range for {n} vertices"
            )));
        }
        Ok(())
    }

    /// The scene material a primitive uses (the default material where it names none).
    fn primitive_material(
        &mut self,
        primitive: &gltf::Primitive<'_>,
        label: &str,
    ) -> Result<usize, SceneError> {
        Ok(match primitive.material().index() {
            Some(i) => *self
                .material_index
                .get(i)
                .ok_or_else(|| self.invalid(format!("{label}: refers to missing material {i}")))?,
            None => self.default_material(),
        })
    }

    /// The texture slots (bits) of `slots` whose coordinates the primitive lacks (`has_uv`:
    /// whether it has `TEXCOORD_0` and `TEXCOORD_1`), with a warning naming them. Such
    /// textures are not sampled at all (sampling one texel everywhere is not what the author
    /// made, and at constant coordinates some drivers return black).
    fn textures_without_coordinates(
        &self,
        slots: &[Option<TextureRef>; TEXTURE_SLOTS],
        label: &str,
        has_uv: [bool; 2],
    ) -> u32 {
        let mut dropped = 0u32;
        for (slot, texture) in slots.iter().enumerate() {
            if let Some(t) = texture {
                let present = if t.tex_coord == 0 {
                    has_uv[0]
                } else {
                    has_uv[1]
                };
                if !present {
                    dropped |= 1 << slot;
                }
            }
        }
        if dropped != 0 {
            let names: Vec<String> = (0..TEXTURE_SLOTS)
                .filter(|s| dropped & (1 << s) != 0)
                .map(|s| {
                    format!(
                        "{} (TEXCOORD_{})",
                        TEXTURE_SLOT_NAMES[s],
                        slots[s].map_or(0, |t| t.tex_coord)
                    )
                })
                .collect();
            self.warn(&format!(
                "{label} has no texture coordinates for {}: drawn without {}",
                names.join(", "),
                if names.len() == 1 { "it" } else { "them" }
            ));
        }
        dropped
    }

    /// MikkTSpace tangents on the normal map's coordinates; where they cannot be generated,
    /// zero tangents and the normal map dropped (its bit set in `dropped`), with a warning.
    fn generated_tangents(
        &self,
        a: &FilledAttributes,
        map: TextureRef,
        indices: &[u32],
        label: &str,
        dropped: &mut u32,
    ) -> Vec<[f32; 4]> {
        let coords = if map.tex_coord == 0 { &a.uvs } else { &a.uvs1 };
        match generate_tangents(&a.positions, &a.normals, coords, indices) {
            Some(t) => t,
            None => {
                self.warn(&format!(
                    "{label}: tangents cannot be generated (degenerate texture \
                     coordinates): drawn without its normal map"
                ));
                *dropped |= 1 << NORMAL_SLOT;
                vec![[0.0; 4]; a.positions.len()]
            }
        }
    }
}

/// A primitive's vertex attributes with the missing ones filled in (generated normals,
/// zero texture coordinates, white).
struct FilledAttributes {
    positions: Vec<[f32; 3]>,
    normals: Vec<[f32; 3]>,
    uvs: Vec<[f32; 2]>,
    uvs1: Vec<[f32; 2]>,
    colors: Vec<[f32; 4]>,
}

/// The primitive's vertices placed by `world`. Normals transform with the inverse
/// transpose; a mirroring transform flips winding (swapped in `indices`) and the
/// bitangent's handedness.
fn transformed_vertices(
    world: Mat4,
    a: &FilledAttributes,
    tangents: &[[f32; 4]],
    indices: &mut [u32],
) -> Vec<Vertex> {
    let linear = Mat3::from_mat4(world);
    let normal_matrix = linear.inverse().transpose();
    let mirrored = linear.determinant() < 0.0;
    if mirrored {
        for tri in indices.chunks_exact_mut(3) {
            tri.swap(1, 2);
        }
    }
    (0..a.positions.len())
        .map(|i| {
            let t = Vec3::from_slice(&tangents[i][..3]);
            let tangent = match (linear * t).try_normalize() {
                Some(t) => {
                    let w = if tangents[i][3] < 0.0 { -1.0 } else { 1.0 };
                    [t.x, t.y, t.z, if mirrored { -w } else { w }]
                }
                None => [0.0; 4],
            };
            Vertex {
                position: world
                    .transform_point3(Vec3::from(a.positions[i]))
                    .to_array(),
                normal: (normal_matrix * Vec3::from(a.normals[i]))
                    .try_normalize()
                    .unwrap_or(Vec3::Y)
                    .to_array(),
                uv: a.uvs[i],
                uv1: a.uvs1[i],
                color: a.colors[i],
                tangent,
            }
        })
        .collect()
}

/// A primitive's positions, normals, tangents, two sets of texture coordinates, colours and
/// raw indices (before strips and fans are unrolled).
type PrimitiveAttributes = (
    Vec<[f32; 3]>,
    Option<Vec<[f32; 3]>>,
    Option<Vec<[f32; 4]>>,
    Option<Vec<[f32; 2]>>,
    Option<Vec<[f32; 2]>>,
    Option<Vec<[f32; 4]>>,
    Vec<u32>,
);

/// The slot of the normal map in [`Material::texture_slots`].
const NORMAL_SLOT: usize = 2;

/// Refuses image sizes that are not images, before their pixels are decoded.
fn check_image_size(width: u32, height: u32) -> Result<(), String> {
    if width == 0 || height == 0 || width > MAX_IMAGE_SIDE || height > MAX_IMAGE_SIDE {
        return Err(format!(
            "is {width}×{height}; sides must be 1..={MAX_IMAGE_SIDE}"
        ));
    }
    Ok(())
}

/// The bytes of a base64 `data:` URI (its size is bounded by the file's).
fn decode_data_uri(uri: &str) -> Result<Vec<u8>, String> {
    use base64::Engine as _;
    let (_, payload) = uri
        .split_once(";base64,")
        .ok_or("is a data URI without base64 content")?;
    base64::engine::general_purpose::STANDARD
        .decode(payload.trim())
        .map_err(|e| format!("its data URI is not valid base64: {e}"))
}

/// `KHR_texture_transform`: the transform and the coordinate set it overrides, if any.
fn parse_texture_transform(
    value: &serde_json::Value,
) -> Result<(UvTransform, Option<u32>), String> {
    let pair = |name: &str, default: [f32; 2]| -> Result<[f32; 2], String> {
        match value.get(name) {
            None => Ok(default),
            Some(v) => {
                let a = v.as_array().filter(|a| a.len() == 2);
                let nums: Option<Vec<f32>> = a.map(|a| {
                    a.iter()
                        .filter_map(|x| x.as_f64())
                        .map(|x| x as f32)
                        .collect()
                });
                match nums {
                    Some(n) if n.len() == 2 && n.iter().all(|x| x.is_finite()) => Ok([n[0], n[1]]),
                    _ => Err(format!("{name} must be two finite numbers")),
                }
            }
        }
    };
    let offset = pair("offset", [0.0, 0.0])?;
    let scale = pair("scale", [1.0, 1.0])?;
    let rotation = match value.get("rotation") {
        None => 0.0,
        Some(r) => r
            .as_f64()
            .map(|r| r as f32)
            .filter(|r| r.is_finite())
            .ok_or("rotation must be a finite number")?,
    };
    let tex_coord = match value.get("texCoord") {
        None => None,
        Some(t) => Some(
            t.as_u64()
                .and_then(|t| u32::try_from(t).ok())
                .ok_or("texCoord must be a non-negative integer")?,
        ),
    };
    Ok((
        UvTransform::from_offset_rotation_scale(offset, rotation, scale),
        tex_coord,
    ))
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
