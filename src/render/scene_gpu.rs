//! The scene on the GPU: its vertex and index buffers (split over several where one would pass
//! the device's limit), materials, textures with their mip chains and the draws, uploaded once
//! and read by every pass (scene, shadows, tessellator).

use std::collections::HashMap;

use bytemuck::{Pod, Zeroable};

use super::bindings::UNIFORM_STRIDE;
use super::error::RenderError;
use super::scene_chunks::ChunkPlan;
use super::uniforms::MaterialUniforms;
use crate::scene::{
    AlphaMode, ColorSpace, Light, Scene, TEXTURE_SLOTS, Texture, TextureRef, Vertex, Wrap,
};
use crate::sky::cubemap::{linear_to_srgb, srgb_to_linear};

/// Vertex layout on the GPU. Keep in sync with `VertexInput` in shaders/scene.wgsl and with
/// `VERTEX_FLOATS` in shaders/common.wgsl (the tessellator reads it as storage).
#[repr(C)]
#[derive(Debug, Clone, Copy, Pod, Zeroable)]
pub struct GpuVertex {
    pub position: [f32; 3],
    pub normal: [f32; 3],
    pub uv: [f32; 2],
    pub uv1: [f32; 2],
    pub color: [f32; 4],
    pub tangent: [f32; 4],
}

impl From<&Vertex> for GpuVertex {
    fn from(v: &Vertex) -> Self {
        Self {
            position: v.position,
            normal: v.normal,
            uv: v.uv,
            uv1: v.uv1,
            color: v.color,
            tangent: v.tangent,
        }
    }
}

pub(super) const VERTEX_ATTRIBUTES: [wgpu::VertexAttribute; 6] = wgpu::vertex_attr_array![
    0 => Float32x3, 1 => Float32x3, 2 => Float32x2, 3 => Float32x2, 4 => Float32x4,
    5 => Float32x4
];

/// Vertex and index buffers holding a run of draws.
#[derive(Debug)]
pub(crate) struct SceneChunk {
    pub(crate) vertex_buffer: wgpu::Buffer,
    pub(crate) index_buffer: wgpu::Buffer,
}

/// A scene uploaded to the GPU.
#[derive(Debug)]
pub struct SceneGpu {
    /// One chunk holding the whole scene (as the file laid it out) when it fits the device's
    /// largest buffer; else runs of whole draws, each under the limit (see [`plan_chunks`]).
    pub(super) chunks: Vec<SceneChunk>,
    pub(super) draws: Vec<GpuDraw>,
    /// The order draws are issued in: opaque ones, then blended ones back to front (sorted
    /// each frame by [`SceneGpu::sort_blended`]).
    pub(super) order: Vec<usize>,
    /// Draws before this position in `order` are opaque.
    pub(super) opaque_count: usize,
    /// The scene file's lights (scene space), for the frame uniforms.
    pub(crate) lights: Vec<Light>,
    /// Axis-aligned bounds (scene space), for the shadow maps' extent.
    pub(crate) bounds: Option<(glam::Vec3, glam::Vec3)>,
    /// Per source triangle: its draw index (or `NO_DRAW`), bit 31 set when double-sided.
    pub(crate) tri_info: Vec<u32>,
    /// Clusters of the draws' triangles with their bounds (empty for a split scene, which is
    /// not tessellated): each frame, those provably fine in a view are drawn directly.
    pub(crate) clusters: Vec<crate::tess::clusters::Cluster>,
    pub(super) material_bind_groups: Vec<wgpu::BindGroup>,
    /// Kept alive for the bind groups.
    _material_buffer: wgpu::Buffer,
    _textures: Vec<wgpu::Texture>,
    pub triangle_count: usize,
}

#[derive(Debug, Clone, Copy)]
pub(super) struct GpuDraw {
    /// The chunk whose buffers hold it; `first_index` counts in that chunk's index buffer.
    pub(super) chunk: usize,
    pub(super) first_index: u32,
    pub(super) index_count: u32,
    pub(super) material: usize,
    pub(super) double_sided: bool,
    pub(super) blend: bool,
    /// Drawn into the shadow maps: not blended (glass) and not emitting light (a bulb around
    /// its own light must not shadow the room).
    pub(super) casts_shadow: bool,
    /// Centre of the draw's bounding box (scene space): blended draws are sorted by its
    /// distance from the head.
    pub(super) centre: glam::Vec3,
}

impl SceneGpu {
    /// Records the shadow casters into a depth-only pass whose pipeline is bound.
    pub(crate) fn draw_casters(&self, pass: &mut wgpu::RenderPass<'_>) {
        let bound = std::cell::Cell::new(None);
        for draw in self.draws.iter().filter(|d| d.casts_shadow) {
            self.bind_chunk(pass, draw.chunk, &bound);
            pass.draw_indexed(
                draw.first_index..draw.first_index + draw.index_count,
                0,
                0..1,
            );
        }
    }

    /// Binds chunk `chunk`'s buffers unless they are bound already (`bound`).
    pub(super) fn bind_chunk(
        &self,
        pass: &mut wgpu::RenderPass<'_>,
        chunk: usize,
        bound: &std::cell::Cell<Option<usize>>,
    ) {
        if bound.get() == Some(chunk) {
            return;
        }
        if let Some(c) = self.chunks.get(chunk) {
            pass.set_vertex_buffer(0, c.vertex_buffer.slice(..));
            pass.set_index_buffer(c.index_buffer.slice(..), wgpu::IndexFormat::Uint32);
            bound.set(Some(chunk));
        }
    }

    /// Overwrites the first vertices of the first buffer (the wand ray's per-frame positions;
    /// the counts never change, so nothing is allocated).
    pub(crate) fn write_vertices(&self, queue: &wgpu::Queue, vertices: &[GpuVertex]) {
        if let Some(c) = self.chunks.first() {
            queue.write_buffer(&c.vertex_buffer, 0, bytemuck::cast_slice(vertices));
        }
    }

    /// The buffers of the whole scene, if it is one chunk (the tessellator binds them whole).
    pub(crate) fn whole(&self) -> Result<&SceneChunk, super::error::TessError> {
        match self.chunks.as_slice() {
            [one] => Ok(one),
            chunks => Err(super::error::TessError::SplitScene(chunks.len())),
        }
    }

    /// How many buffers the scene is split over (1 when it fits the largest buffer).
    pub fn chunk_count(&self) -> usize {
        self.chunks.len()
    }

    /// Whether any draw is alpha-blended (blending needs linear colour in the target, so
    /// such a scene is not drawn into shader-encoded samples).
    pub fn has_blended_draws(&self) -> bool {
        self.opaque_count < self.order.len()
    }

    /// Number of draws (materials runs) the scene is drawn with.
    pub fn draw_count(&self) -> usize {
        self.draws.len()
    }

    /// Orders the blended draws back to front as seen from `head` (scene space): the farthest
    /// first, so that each is blended over what lies behind it. Sorting whole draws (a mesh
    /// primitive each: the loader never merges blended ones) is exact for separate
    /// transparent objects such as panes, visors and glass; crossing or self-overlapping
    /// transparent surfaces inside one primitive are not sorted. One order serves every view
    /// of a frame: the eyes differ from the head by millimetres.
    pub fn sort_blended(&mut self, head: glam::Vec3) {
        let draws = &self.draws;
        self.order[self.opaque_count..].sort_by(|&a, &b| {
            let da = draws[a].centre.distance_squared(head);
            let db = draws[b].centre.distance_squared(head);
            db.total_cmp(&da)
        });
    }
}

/// A piece of a scene draw as uploaded: the chunk holding it, the scene draw, and its first
/// index and index count in that chunk's index buffer.
#[derive(Debug, Clone, Copy)]
struct Piece {
    chunk: usize,
    draw: usize,
    first_index: u32,
    index_count: u32,
}

/// The scene's textures on the GPU, with a white one for empty slots.
struct SceneTextures {
    textures: Vec<wgpu::Texture>,
    views: Vec<wgpu::TextureView>,
    white: wgpu::Texture,
    white_view: wgpu::TextureView,
}

impl SceneGpu {
    /// Uploads `scene` as `plan` lays it out, in the caller's error scopes.
    pub(super) fn upload_checked(
        material_layout: &wgpu::BindGroupLayout,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        scene: &Scene,
        plan: ChunkPlan,
    ) -> SceneGpu {
        let (chunks, pieces) = upload_geometry(device, queue, scene, &plan);
        let textures = SceneTextures::upload(device, queue, scene);
        let material_buffer = upload_materials(device, queue, scene);
        let material_bind_groups =
            material_bind_groups(device, material_layout, scene, &textures, &material_buffer);
        let draws = gpu_draws(scene, &plan, &pieces);
        // A split scene is not tessellated: it has no single buffer to bind.
        let whole = chunks.len() == 1;
        let tri_info = triangle_draws(scene, &draws, whole);
        let clusters = if whole {
            crate::tess::clusters::build_clusters(
                scene,
                draws
                    .iter()
                    .enumerate()
                    .map(|(d, g)| (d as u32, g.first_index, g.index_count)),
            )
        } else {
            Vec::new()
        };
        let mut order: Vec<usize> = (0..draws.len()).filter(|&d| !draws[d].blend).collect();
        let opaque_count = order.len();
        order.extend((0..draws.len()).filter(|&d| draws[d].blend));
        let mut all_textures = textures.textures;
        all_textures.push(textures.white);
        SceneGpu {
            chunks,
            draws,
            order,
            opaque_count,
            lights: scene.lights.clone(),
            bounds: scene.bounds(),
            tri_info,
            clusters,
            material_bind_groups,
            _material_buffer: material_buffer,
            _textures: all_textures,
            triangle_count: scene.triangle_count(),
        }
    }
}

/// The vertex and index buffers of every chunk of `plan`, and the pieces of draws each holds.
fn upload_geometry(
    device: &wgpu::Device,
    queue: &wgpu::Queue,
    scene: &Scene,
    plan: &ChunkPlan,
) -> (Vec<SceneChunk>, Vec<Piece>) {
    let mut pieces = Vec::new();
    let chunks = match plan {
        ChunkPlan::Whole => {
            for (d, draw) in scene.draws.iter().enumerate() {
                pieces.push(Piece {
                    chunk: 0,
                    draw: d,
                    first_index: draw.first_index,
                    index_count: draw.index_count,
                });
            }
            vec![upload_chunk(
                device,
                queue,
                "SceneGpu",
                &scene.vertices,
                &scene.indices,
            )]
        }
        ChunkPlan::Split(split) => split
            .iter()
            .enumerate()
            .map(|(c, chunk)| {
                for p in &chunk.pieces {
                    pieces.push(Piece {
                        chunk: c,
                        draw: p.draw,
                        first_index: p.first_index,
                        index_count: p.index_count,
                    });
                }
                let vertices: Vec<Vertex> = chunk
                    .vertices
                    .iter()
                    .filter_map(|&v| scene.vertices.get(v as usize).copied())
                    .collect();
                let label = format!("SceneGpu::chunk {c}");
                upload_chunk(device, queue, &label, &vertices, &chunk.indices)
            })
            .collect(),
    };
    (chunks, pieces)
}

impl SceneTextures {
    /// Every texture of `scene` with its mip chain, and the white one.
    fn upload(device: &wgpu::Device, queue: &wgpu::Queue, scene: &Scene) -> Self {
        let textures: Vec<wgpu::Texture> = scene
            .textures
            .iter()
            .map(|t| upload_texture(device, queue, t))
            .collect();
        let white = upload_texture(
            device,
            queue,
            &Texture {
                name: "white".into(),
                width: 1,
                height: 1,
                rgba8: vec![255; 4],
                color_space: ColorSpace::Linear,
            },
        );
        let views = textures
            .iter()
            .map(|t| t.create_view(&Default::default()))
            .collect();
        let white_view = white.create_view(&Default::default());
        Self {
            textures,
            views,
            white,
            white_view,
        }
    }
}

/// Every material's uniforms, one [`UNIFORM_STRIDE`] slot each (one slot for none).
fn upload_materials(device: &wgpu::Device, queue: &wgpu::Queue, scene: &Scene) -> wgpu::Buffer {
    let mut material_bytes = Vec::with_capacity(scene.materials.len() * UNIFORM_STRIDE as usize);
    for m in &scene.materials {
        material_bytes.extend_from_slice(bytemuck::bytes_of(&MaterialUniforms::from(m)));
        material_bytes.resize(
            material_bytes
                .len()
                .next_multiple_of(UNIFORM_STRIDE as usize),
            0,
        );
    }
    if material_bytes.is_empty() {
        material_bytes.resize(UNIFORM_STRIDE as usize, 0);
    }
    buffer_with(
        device,
        queue,
        "SceneGpu::material_buffer",
        &material_bytes,
        wgpu::BufferUsages::UNIFORM,
    )
}

/// One bind group per material: its uniforms, and a texture and sampler per slot (white
/// where a slot has no valid texture; samplers shared between slots that wrap alike).
fn material_bind_groups(
    device: &wgpu::Device,
    layout: &wgpu::BindGroupLayout,
    scene: &Scene,
    textures: &SceneTextures,
    material_buffer: &wgpu::Buffer,
) -> Vec<wgpu::BindGroup> {
    let mut samplers: HashMap<(Wrap, Wrap, bool), wgpu::Sampler> = HashMap::new();
    let mut groups = Vec::with_capacity(scene.materials.len());
    for m in &scene.materials {
        let slots = m.texture_slots();
        // A slot without a (valid) texture binds white; the shader does not sample it.
        let bound = |t: &Option<TextureRef>| t.filter(|t| t.texture < textures.views.len());
        let views: Vec<&wgpu::TextureView> = slots
            .iter()
            .map(|t| bound(t).map_or(&textures.white_view, |t| &textures.views[t.texture]))
            .collect();
        let keys: Vec<(Wrap, Wrap, bool)> = slots
            .iter()
            .map(|t| {
                bound(t).map_or((Wrap::Repeat, Wrap::Repeat, false), |t| {
                    (t.wrap_u, t.wrap_v, t.nearest)
                })
            })
            .collect();
        for &key in &keys {
            samplers
                .entry(key)
                .or_insert_with(|| make_sampler(device, key));
        }
        let mut entries = vec![wgpu::BindGroupEntry {
            binding: 0,
            resource: wgpu::BindingResource::Buffer(wgpu::BufferBinding {
                buffer: material_buffer,
                offset: 0,
                size: wgpu::BufferSize::new(std::mem::size_of::<MaterialUniforms>() as u64),
            }),
        }];
        for (slot, view) in views.iter().enumerate() {
            entries.push(wgpu::BindGroupEntry {
                binding: 1 + slot as u32,
                resource: wgpu::BindingResource::TextureView(view),
            });
        }
        for (slot, key) in keys.iter().enumerate() {
            if let Some(sampler) = samplers.get(key) {
                entries.push(wgpu::BindGroupEntry {
                    binding: 1 + (TEXTURE_SLOTS + slot) as u32,
                    resource: wgpu::BindingResource::Sampler(sampler),
                });
            }
        }
        groups.push(device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some(&format!("SceneGpu::material {}", m.name)),
            layout,
            entries: &entries,
        }));
    }
    groups
}

/// The draws of every piece with a valid draw and material, with their bounding boxes'
/// centres (blended draws are sorted by them).
fn gpu_draws(scene: &Scene, plan: &ChunkPlan, pieces: &[Piece]) -> Vec<GpuDraw> {
    // A piece's corner positions, for its bounding box.
    let corner = |chunk: usize, index: u32| -> glam::Vec3 {
        let vertex = match plan {
            ChunkPlan::Whole => Some(index),
            ChunkPlan::Split(split) => split
                .get(chunk)
                .and_then(|c| c.vertices.get(index as usize).copied()),
        };
        vertex
            .and_then(|v| scene.vertices.get(v as usize))
            .map_or(glam::Vec3::ZERO, |v| glam::Vec3::from(v.position))
    };
    let chunk_indices = |chunk: usize| -> &[u32] {
        match plan {
            ChunkPlan::Whole => &scene.indices,
            ChunkPlan::Split(split) => split.get(chunk).map_or(&[], |c| &c.indices),
        }
    };
    pieces
        .iter()
        .filter_map(|piece| {
            let scene_draw = scene.draws.get(piece.draw)?;
            let material = scene.materials.get(scene_draw.material)?;
            let range =
                piece.first_index as usize..(piece.first_index + piece.index_count) as usize;
            let (lo, hi) = chunk_indices(piece.chunk)
                .get(range)
                .unwrap_or(&[])
                .iter()
                .fold(
                    (glam::Vec3::INFINITY, glam::Vec3::NEG_INFINITY),
                    |(lo, hi), &i| {
                        let p = corner(piece.chunk, i);
                        (lo.min(p), hi.max(p))
                    },
                );
            Some(GpuDraw {
                chunk: piece.chunk,
                first_index: piece.first_index,
                index_count: piece.index_count,
                material: scene_draw.material,
                double_sided: material.double_sided,
                blend: material.alpha_mode == AlphaMode::Blend,
                casts_shadow: material.alpha_mode != AlphaMode::Blend
                    && material.emissive == [0.0; 3],
                centre: 0.5 * (lo + hi),
            })
        })
        .collect()
}

/// Per source triangle of a whole scene: its draw index, bit 31 set when double-sided.
/// Triangles no valid draw covers get a draw index no draw has: never drawn. Empty for a
/// split scene.
fn triangle_draws(scene: &Scene, draws: &[GpuDraw], whole: bool) -> Vec<u32> {
    let mut tri_info =
        vec![super::tessellator::NO_DRAW; if whole { scene.triangle_count() } else { 0 }];
    for (d, draw) in draws.iter().enumerate() {
        let flag = if draw.double_sided { 1 << 31 } else { 0 };
        let first = draw.first_index as usize / 3;
        let count = draw.index_count as usize / 3;
        for info in tri_info.iter_mut().skip(first).take(count) {
            *info = d as u32 | flag;
        }
    }
    tri_info
}

fn address_mode(w: Wrap) -> wgpu::AddressMode {
    match w {
        Wrap::Repeat => wgpu::AddressMode::Repeat,
        Wrap::MirroredRepeat => wgpu::AddressMode::MirrorRepeat,
        Wrap::ClampToEdge => wgpu::AddressMode::ClampToEdge,
    }
}

fn make_sampler(device: &wgpu::Device, (u, v, nearest): (Wrap, Wrap, bool)) -> wgpu::Sampler {
    device.create_sampler(&wgpu::SamplerDescriptor {
        label: Some("SceneGpu::sampler"),
        address_mode_u: address_mode(u),
        address_mode_v: address_mode(v),
        mag_filter: if nearest {
            wgpu::FilterMode::Nearest
        } else {
            wgpu::FilterMode::Linear
        },
        min_filter: wgpu::FilterMode::Linear,
        mipmap_filter: wgpu::MipmapFilterMode::Linear,
        anisotropy_clamp: 8,
        ..Default::default()
    })
}

/// Uploads a texture with a full mip chain, box-filtered on the CPU once at load: in linear
/// light for sRGB textures (averaging the encoded bytes would darken every mip level).
/// Vertex and index buffers for `vertices` and `indices` (wgpu refuses empty buffers: an
/// empty scene gets valid, unused ones).
fn upload_chunk(
    device: &wgpu::Device,
    queue: &wgpu::Queue,
    label: &str,
    vertices: &[Vertex],
    indices: &[u32],
) -> SceneChunk {
    let mut gpu: Vec<GpuVertex> = vertices.iter().map(GpuVertex::from).collect();
    if gpu.is_empty() {
        gpu.push(GpuVertex::zeroed());
    }
    let index_bytes: &[u8] = if indices.is_empty() {
        &[0; 12]
    } else {
        bytemuck::cast_slice(indices)
    };
    SceneChunk {
        vertex_buffer: buffer_with(
            device,
            queue,
            &format!("{label}::vertex_buffer"),
            bytemuck::cast_slice(&gpu),
            // Storage: the tessellator reads it, the pose pass writes deformed vertices;
            // copy source: tests read the posed vertices back.
            wgpu::BufferUsages::VERTEX | wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
        ),
        index_buffer: buffer_with(
            device,
            queue,
            &format!("{label}::index_buffer"),
            index_bytes,
            wgpu::BufferUsages::INDEX | wgpu::BufferUsages::STORAGE,
        ),
    }
}

/// A buffer holding `contents`, created unmapped and filled through the queue: should the
/// device be out of memory, the failure lands in the caller's error scope (wgpu's
/// `create_buffer_init` maps at creation and panics when the buffer could not be made).
pub(super) fn buffer_with(
    device: &wgpu::Device,
    queue: &wgpu::Queue,
    label: &str,
    contents: &[u8],
    usage: wgpu::BufferUsages,
) -> wgpu::Buffer {
    let align = wgpu::COPY_BUFFER_ALIGNMENT;
    let size = (contents.len() as u64).next_multiple_of(align).max(align);
    let buffer = device.create_buffer(&wgpu::BufferDescriptor {
        label: Some(label),
        size,
        usage: usage | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    });
    let aligned = contents.len() - contents.len() % align as usize;
    if aligned > 0 {
        queue.write_buffer(&buffer, 0, &contents[..aligned]);
    }
    if aligned < contents.len() {
        let mut tail = [0u8; wgpu::COPY_BUFFER_ALIGNMENT as usize];
        tail[..contents.len() - aligned].copy_from_slice(&contents[aligned..]);
        queue.write_buffer(&buffer, aligned as u64, &tail);
    }
    buffer
}

/// Refuses a scene whose textures pass this device's limits, naming the limit (its geometry
/// is split over buffers by [`plan_chunks`]).
pub(super) fn check_scene_limits(device: &wgpu::Device, scene: &Scene) -> Result<(), RenderError> {
    let limits = device.limits();
    let material_bytes = scene.materials.len() as u64 * UNIFORM_STRIDE;
    if material_bytes > limits.max_buffer_size {
        return Err(RenderError::SceneTooLarge {
            what: "materials",
            bytes: material_bytes,
            limit: limits.max_buffer_size,
        });
    }
    let max_side = limits.max_texture_dimension_2d;
    if let Some(t) = scene
        .textures
        .iter()
        .find(|t| t.width > max_side || t.height > max_side)
    {
        return Err(RenderError::TextureTooLarge {
            name: t.name.clone(),
            width: t.width,
            height: t.height,
            max: max_side,
        });
    }
    Ok(())
}

fn upload_texture(device: &wgpu::Device, queue: &wgpu::Queue, t: &Texture) -> wgpu::Texture {
    let mip_count = 32 - t.width.max(t.height).max(1).leading_zeros();
    let texture = device.create_texture(&wgpu::TextureDescriptor {
        label: Some(&format!("SceneGpu::texture {}", t.name)),
        size: wgpu::Extent3d {
            width: t.width,
            height: t.height,
            depth_or_array_layers: 1,
        },
        mip_level_count: mip_count,
        sample_count: 1,
        dimension: wgpu::TextureDimension::D2,
        format: match t.color_space {
            ColorSpace::Srgb => wgpu::TextureFormat::Rgba8UnormSrgb,
            ColorSpace::Linear => wgpu::TextureFormat::Rgba8Unorm,
        },
        usage: wgpu::TextureUsages::TEXTURE_BINDING | wgpu::TextureUsages::COPY_DST,
        view_formats: &[],
    });
    for (mip, (width, height, bytes)) in mip_chain(t).iter().enumerate() {
        queue.write_texture(
            wgpu::TexelCopyTextureInfo {
                texture: &texture,
                mip_level: mip as u32,
                origin: wgpu::Origin3d::ZERO,
                aspect: wgpu::TextureAspect::All,
            },
            bytes,
            wgpu::TexelCopyBufferLayout {
                offset: 0,
                bytes_per_row: Some(width * 4),
                rows_per_image: Some(*height),
            },
            wgpu::Extent3d {
                width: *width,
                height: *height,
                depth_or_array_layers: 1,
            },
        );
    }
    texture
}

/// Every mip level of a texture (width, height, RGBA8), level 0 first down to 1×1, each
/// filtered from the one above in linear light.
pub fn mip_chain(t: &Texture) -> Vec<(u32, u32, Vec<u8>)> {
    let mut out = Vec::new();
    let mut level = image::Rgba32FImage::from_raw(
        t.width,
        t.height,
        t.rgba8
            .chunks_exact(4)
            .flat_map(|px| decode_texel(px, t.color_space))
            .collect(),
    );
    while let Some(img) = level.take() {
        let bytes: Vec<u8> = img
            .as_raw()
            .chunks_exact(4)
            .flat_map(|px| encode_texel(px, t.color_space))
            .collect();
        out.push((img.width(), img.height(), bytes));
        if img.width() == 1 && img.height() == 1 {
            break;
        }
        let (w, h) = ((img.width() / 2).max(1), (img.height() / 2).max(1));
        level = Some(image::imageops::resize(
            &img,
            w,
            h,
            image::imageops::FilterType::Triangle,
        ));
    }
    out
}

/// One RGBA8 texel as linear-light floats (alpha is always linear).
fn decode_texel(px: &[u8], space: ColorSpace) -> [f32; 4] {
    let unit = |b: u8| f32::from(b) / 255.0;
    let colour = |b: u8| match space {
        ColorSpace::Srgb => srgb_to_linear(b),
        ColorSpace::Linear => unit(b),
    };
    [colour(px[0]), colour(px[1]), colour(px[2]), unit(px[3])]
}

/// The inverse of [`decode_texel`], rounded to the nearest byte.
fn encode_texel(px: &[f32], space: ColorSpace) -> [u8; 4] {
    let byte = |v: f32| (v.clamp(0.0, 1.0) * 255.0).round() as u8;
    let colour = |v: f32| match space {
        ColorSpace::Srgb => linear_to_srgb(v),
        ColorSpace::Linear => byte(v),
    };
    [colour(px[0]), colour(px[1]), colour(px[2]), byte(px[3])]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn mipmaps_average_light_not_srgb_bytes() {
        // Black and white stripes: their average is half the light, sRGB 188, not the byte
        // average 128 (which is 22 % of the light: every distant texture would darken).
        let stripes = |space| Texture {
            name: "stripes".into(),
            width: 4,
            height: 2,
            rgba8: (0..8)
                .flat_map(|i| if i % 2 == 0 { [0, 0, 0, 255] } else { [255; 4] })
                .collect(),
            color_space: space,
        };
        let chain = mip_chain(&stripes(ColorSpace::Srgb));
        assert_eq!(
            chain.iter().map(|(w, h, _)| (*w, *h)).collect::<Vec<_>>(),
            vec![(4, 2), (2, 1), (1, 1)]
        );
        let last = &chain[2].2;
        assert!((i32::from(last[0]) - 188).abs() <= 1, "{last:?}");
        assert_eq!(last[3], 255);
        // Data (a normal or roughness map) is averaged as it is.
        let data = mip_chain(&stripes(ColorSpace::Linear));
        assert!(
            (i32::from(data[2].2[0]) - 128).abs() <= 1,
            "{:?}",
            data[2].2
        );
    }
}
