//! Per-wall, per-eye render targets ("quad-buffer style") and their read-back to CPU images.

use image::RgbaImage;

use super::error::RenderError;
use super::formats::{COLOR_FORMAT, DEPTH_FORMAT, ENCODED_FORMAT};
use super::resolve::ResolvePass;

/// The colour (+ optional MSAA) and depth attachments of one eye image.
#[derive(Debug)]
pub struct EyeTarget {
    pub color: wgpu::Texture,
    pub color_view: wgpu::TextureView,
    /// The multisampled image through an sRGB view (resolved by the pass).
    pub msaa_view: Option<wgpu::TextureView>,
    /// The same samples as plain bytes the shaders encode, and their binding for
    /// `ResolvePass` (when a resolve pass was given).
    pub encoded_samples: Option<(wgpu::TextureView, Option<wgpu::BindGroup>)>,
    /// The eye image's bytes, as `ResolvePass` writes them.
    pub encoded_view: wgpu::TextureView,
    pub depth_view: wgpu::TextureView,
}

/// Both eyes' targets for one wall.
#[derive(Debug)]
pub struct WallTargets {
    pub size: [u32; 2],
    pub eyes: [EyeTarget; 2],
}

impl WallTargets {
    /// Targets of `size` pixels with `msaa` samples; with `resolve`, the multisampled images
    /// are bound for it too.
    pub fn new(
        device: &wgpu::Device,
        wall_name: &str,
        size: [u32; 2],
        msaa: u32,
        resolve: Option<&ResolvePass>,
    ) -> Self {
        let make =
            |eye: &str| EyeTarget::new(device, &format!("{wall_name}-{eye}"), size, msaa, resolve);
        Self {
            size,
            eyes: [make("left"), make("right")],
        }
    }
}

impl EyeTarget {
    fn new(
        device: &wgpu::Device,
        name: &str,
        size: [u32; 2],
        msaa: u32,
        resolve: Option<&ResolvePass>,
    ) -> Self {
        let extent = wgpu::Extent3d {
            width: size[0],
            height: size[1],
            depth_or_array_layers: 1,
        };
        let texture = |label: String, format, samples, usage, view_formats| {
            device.create_texture(&wgpu::TextureDescriptor {
                label: Some(&label),
                size: extent,
                mip_level_count: 1,
                sample_count: samples,
                dimension: wgpu::TextureDimension::D2,
                format,
                usage,
                view_formats,
            })
        };
        let color = texture(
            format!("EyeTarget::color {name}"),
            COLOR_FORMAT,
            1,
            wgpu::TextureUsages::RENDER_ATTACHMENT
                | wgpu::TextureUsages::TEXTURE_BINDING
                | wgpu::TextureUsages::COPY_SRC,
            &[ENCODED_FORMAT],
        );
        let samples = (msaa > 1).then(|| {
            texture(
                format!("EyeTarget::msaa {name}"),
                ENCODED_FORMAT,
                msaa,
                wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::TEXTURE_BINDING,
                &[COLOR_FORMAT],
            )
        });
        let view_as = |t: &wgpu::Texture, format, what: &str| {
            t.create_view(&wgpu::TextureViewDescriptor {
                label: Some(&format!("EyeTarget::{what} {name}")),
                format: Some(format),
                ..Default::default()
            })
        };
        let msaa_view = samples
            .as_ref()
            .map(|t| view_as(t, COLOR_FORMAT, "msaa_view"));
        let encoded_samples = samples.as_ref().map(|t| {
            let view = view_as(t, ENCODED_FORMAT, "encoded_samples");
            let group = resolve.map(|r| r.bind(device, &view));
            (view, group)
        });
        let depth = texture(
            format!("EyeTarget::depth {name}"),
            DEPTH_FORMAT,
            msaa,
            wgpu::TextureUsages::RENDER_ATTACHMENT,
            &[],
        );
        Self {
            color_view: color.create_view(&Default::default()),
            encoded_view: view_as(&color, ENCODED_FORMAT, "encoded_view"),
            color,
            msaa_view,
            encoded_samples,
            depth_view: depth.create_view(&Default::default()),
        }
    }
}

/// Copies the first `size` bytes of a GPU buffer back to the CPU (blocking; for the headless
/// CLI and tests, never in the interactive render path).
pub fn read_buffer(
    device: &wgpu::Device,
    queue: &wgpu::Queue,
    source: &wgpu::Buffer,
    size: u64,
    label: &str,
) -> Result<Vec<u8>, RenderError> {
    let size = size.max(4).next_multiple_of(wgpu::COPY_BUFFER_ALIGNMENT);
    let staging = device.create_buffer(&wgpu::BufferDescriptor {
        label: Some(label),
        size,
        usage: wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::MAP_READ,
        mapped_at_creation: false,
    });
    let mut encoder =
        device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some(label) });
    encoder.copy_buffer_to_buffer(source, 0, &staging, 0, size);
    queue.submit([encoder.finish()]);
    read_staging(device, &staging)
}

/// Waits for the work submitted so far and copies a `MAP_READ` staging buffer's whole
/// contents to the CPU (blocking; for the headless CLI and tests).
pub fn read_staging(device: &wgpu::Device, staging: &wgpu::Buffer) -> Result<Vec<u8>, RenderError> {
    staging.slice(..).map_async(wgpu::MapMode::Read, |_| {});
    device
        .poll(wgpu::PollType::wait_indefinitely())
        .map_err(|e| RenderError::Readback(e.to_string()))?;
    let data = staging
        .get_mapped_range(..)
        .map_err(|e| RenderError::Readback(e.to_string()))?;
    let bytes = data.to_vec();
    drop(data);
    staging.unmap();
    Ok(bytes)
}

/// Refuses an image size the device cannot create (instead of wgpu's panic), naming it.
pub fn check_texture_size(
    device: &wgpu::Device,
    what: &str,
    width: u32,
    height: u32,
) -> Result<(), RenderError> {
    let max = device.limits().max_texture_dimension_2d;
    if width == 0 || height == 0 || width > max || height > max {
        return Err(RenderError::TextureLimit {
            what: what.to_owned(),
            width,
            height,
            max,
        });
    }
    Ok(())
}

/// Largest staging buffer [`read_textures`] uses: a texture larger than this (an 8192² image
/// is 256 MiB, a frame-packed 8192-high wall more) is read back in bands of rows, so that
/// every legal image can be read whatever the device's buffer limit.
const MAX_STAGING_BYTES: u64 = 64 << 20;

/// Copies textures back to CPU images (for the headless CLI and tests; never per frame in the
/// interactive render path), in bands of rows of at most [`MAX_STAGING_BYTES`].
pub fn read_textures(
    device: &wgpu::Device,
    queue: &wgpu::Queue,
    textures: &[&wgpu::Texture],
) -> Result<Vec<RgbaImage>, RenderError> {
    let band_limit = MAX_STAGING_BYTES.min(device.limits().max_buffer_size);
    let mut images: Vec<Vec<u8>> = textures
        .iter()
        .map(|t| Vec::with_capacity(t.width() as usize * t.height() as usize * 4))
        .collect();
    // Bands of every texture in order; flushed whenever the staging held passes the limit.
    let mut pending: Vec<Band<'_>> = Vec::new();
    let mut pending_bytes = 0;
    for (index, texture) in textures.iter().enumerate() {
        let (w, h) = (texture.width(), texture.height());
        let padded = (w * 4).div_ceil(wgpu::COPY_BYTES_PER_ROW_ALIGNMENT)
            * wgpu::COPY_BYTES_PER_ROW_ALIGNMENT;
        let rows_per_band = (band_limit / u64::from(padded)).clamp(1, u64::from(h.max(1))) as u32;
        let mut first_row = 0;
        while first_row < h {
            let rows = rows_per_band.min(h - first_row);
            let bytes = u64::from(padded) * u64::from(rows);
            if pending_bytes + bytes > band_limit && !pending.is_empty() {
                flush_bands(device, queue, &mut pending, &mut images)?;
                pending_bytes = 0;
            }
            pending.push(Band {
                index,
                texture,
                first_row,
                rows,
                width: w,
                padded,
                buffer: device.create_buffer(&wgpu::BufferDescriptor {
                    label: Some("read_textures::staging"),
                    size: bytes,
                    usage: wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::MAP_READ,
                    mapped_at_creation: false,
                }),
            });
            pending_bytes += bytes;
            first_row += rows;
        }
    }
    if !pending.is_empty() {
        flush_bands(device, queue, &mut pending, &mut images)?;
    }
    // `pending` was filled in texture order, so each image got its rows top to bottom.
    textures
        .iter()
        .zip(images)
        .map(|(t, pixels)| {
            RgbaImage::from_raw(t.width(), t.height(), pixels)
                .ok_or_else(|| RenderError::Readback("image size mismatch".into()))
        })
        .collect()
}

/// Rows `first_row..first_row + rows` of one texture, on their way back.
struct Band<'t> {
    index: usize,
    texture: &'t wgpu::Texture,
    first_row: u32,
    rows: u32,
    width: u32,
    padded: u32,
    buffer: wgpu::Buffer,
}

/// Copies the pending bands' rows into their staging buffers, waits, and appends the rows
/// to their images.
fn flush_bands(
    device: &wgpu::Device,
    queue: &wgpu::Queue,
    pending: &mut Vec<Band<'_>>,
    images: &mut [Vec<u8>],
) -> Result<(), RenderError> {
    let mut encoder = device.create_command_encoder(&wgpu::CommandEncoderDescriptor {
        label: Some("read_textures"),
    });
    for band in pending.iter() {
        encoder.copy_texture_to_buffer(
            wgpu::TexelCopyTextureInfo {
                texture: band.texture,
                mip_level: 0,
                origin: wgpu::Origin3d {
                    x: 0,
                    y: band.first_row,
                    z: 0,
                },
                aspect: wgpu::TextureAspect::All,
            },
            wgpu::TexelCopyBufferInfo {
                buffer: &band.buffer,
                layout: wgpu::TexelCopyBufferLayout {
                    offset: 0,
                    bytes_per_row: Some(band.padded),
                    rows_per_image: Some(band.rows),
                },
            },
            wgpu::Extent3d {
                width: band.width,
                height: band.rows,
                depth_or_array_layers: 1,
            },
        );
    }
    queue.submit([encoder.finish()]);
    for band in pending.iter() {
        band.buffer.slice(..).map_async(wgpu::MapMode::Read, |_| {});
    }
    device
        .poll(wgpu::PollType::wait_indefinitely())
        .map_err(|e| RenderError::Readback(e.to_string()))?;
    for band in pending.drain(..) {
        let data = band
            .buffer
            .get_mapped_range(..)
            .map_err(|e| RenderError::Readback(e.to_string()))?;
        let pixels = images
            .get_mut(band.index)
            .ok_or_else(|| RenderError::Readback("band of no texture".into()))?;
        for row in data
            .chunks_exact(band.padded as usize)
            .take(band.rows as usize)
        {
            pixels.extend_from_slice(&row[..(band.width * 4) as usize]);
        }
        drop(data);
        band.buffer.unmap();
    }
    Ok(())
}

/// A render pass as the scene pass draws into: `color` (resolved from `msaa` when there is
/// one) cleared to `clear`, depth cleared and discarded after.
pub fn begin_scene_pass<'e>(
    encoder: &'e mut wgpu::CommandEncoder,
    label: &str,
    color: &wgpu::TextureView,
    msaa: Option<&wgpu::TextureView>,
    depth: &wgpu::TextureView,
    clear: wgpu::Color,
) -> wgpu::RenderPass<'e> {
    let (attachment, resolve) = match msaa {
        Some(m) => (m, Some(color)),
        None => (color, None),
    };
    encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
        label: Some(label),
        color_attachments: &[Some(wgpu::RenderPassColorAttachment {
            view: attachment,
            depth_slice: None,
            resolve_target: resolve,
            ops: wgpu::Operations {
                load: wgpu::LoadOp::Clear(clear),
                // The samples are cleared by every pass and read by none after its resolve.
                store: if resolve.is_some() {
                    wgpu::StoreOp::Discard
                } else {
                    wgpu::StoreOp::Store
                },
            },
        })],
        depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
            view: depth,
            depth_ops: Some(wgpu::Operations {
                load: wgpu::LoadOp::Clear(1.0),
                store: wgpu::StoreOp::Discard,
            }),
            stencil_ops: None,
        }),
        timestamp_writes: None,
        occlusion_query_set: None,
        multiview_mask: None,
    })
}
