//! Per-wall, per-eye render targets ("quad-buffer style") and their read-back to CPU images.

use image::RgbaImage;

use super::error::RenderError;

/// Colour format of every eye image: shading is linear, storage sRGB.
pub const COLOR_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba8UnormSrgb;
pub const DEPTH_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Depth32Float;

/// The colour (+ optional MSAA) and depth attachments of one eye image.
#[derive(Debug)]
pub struct EyeTarget {
    pub color: wgpu::Texture,
    pub color_view: wgpu::TextureView,
    pub msaa_view: Option<wgpu::TextureView>,
    pub depth_view: wgpu::TextureView,
}

/// Both eyes' targets for one wall.
#[derive(Debug)]
pub struct WallTargets {
    pub size: [u32; 2],
    pub eyes: [EyeTarget; 2],
}

impl WallTargets {
    pub fn new(device: &wgpu::Device, wall_name: &str, size: [u32; 2], msaa: u32) -> Self {
        let make = |eye: &str| EyeTarget::new(device, &format!("{wall_name}-{eye}"), size, msaa);
        Self {
            size,
            eyes: [make("left"), make("right")],
        }
    }
}

impl EyeTarget {
    fn new(device: &wgpu::Device, name: &str, size: [u32; 2], msaa: u32) -> Self {
        let extent = wgpu::Extent3d {
            width: size[0],
            height: size[1],
            depth_or_array_layers: 1,
        };
        let texture = |label: String, format, samples, usage| {
            device.create_texture(&wgpu::TextureDescriptor {
                label: Some(&label),
                size: extent,
                mip_level_count: 1,
                sample_count: samples,
                dimension: wgpu::TextureDimension::D2,
                format,
                usage,
                view_formats: &[],
            })
        };
        let color = texture(
            format!("EyeTarget::color {name}"),
            COLOR_FORMAT,
            1,
            wgpu::TextureUsages::RENDER_ATTACHMENT
                | wgpu::TextureUsages::TEXTURE_BINDING
                | wgpu::TextureUsages::COPY_SRC,
        );
        let msaa_view = (msaa > 1).then(|| {
            texture(
                format!("EyeTarget::msaa {name}"),
                COLOR_FORMAT,
                msaa,
                wgpu::TextureUsages::RENDER_ATTACHMENT,
            )
            .create_view(&Default::default())
        });
        let depth = texture(
            format!("EyeTarget::depth {name}"),
            DEPTH_FORMAT,
            msaa,
            wgpu::TextureUsages::RENDER_ATTACHMENT,
        );
        Self {
            color_view: color.create_view(&Default::default()),
            color,
            msaa_view,
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

/// Copies textures back to CPU images (for the headless CLI and tests; never per frame in the
/// interactive render path).
pub fn read_textures(
    device: &wgpu::Device,
    queue: &wgpu::Queue,
    textures: &[&wgpu::Texture],
) -> Result<Vec<RgbaImage>, RenderError> {
    let mut encoder = device.create_command_encoder(&wgpu::CommandEncoderDescriptor {
        label: Some("read_textures"),
    });
    let mut staging = Vec::with_capacity(textures.len());
    for texture in textures {
        let (w, h) = (texture.width(), texture.height());
        let padded = (w * 4).div_ceil(wgpu::COPY_BYTES_PER_ROW_ALIGNMENT)
            * wgpu::COPY_BYTES_PER_ROW_ALIGNMENT;
        let buffer = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("read_textures::staging"),
            size: u64::from(padded) * u64::from(h),
            usage: wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::MAP_READ,
            mapped_at_creation: false,
        });
        encoder.copy_texture_to_buffer(
            wgpu::TexelCopyTextureInfo {
                texture,
                mip_level: 0,
                origin: wgpu::Origin3d::ZERO,
                aspect: wgpu::TextureAspect::All,
            },
            wgpu::TexelCopyBufferInfo {
                buffer: &buffer,
                layout: wgpu::TexelCopyBufferLayout {
                    offset: 0,
                    bytes_per_row: Some(padded),
                    rows_per_image: Some(h),
                },
            },
            texture.size(),
        );
        staging.push((buffer, w, h, padded));
    }
    queue.submit([encoder.finish()]);
    for (buffer, ..) in &staging {
        buffer.slice(..).map_async(wgpu::MapMode::Read, |_| {});
    }
    device
        .poll(wgpu::PollType::wait_indefinitely())
        .map_err(|e| RenderError::Readback(e.to_string()))?;
    let mut images = Vec::with_capacity(staging.len());
    for (buffer, w, h, padded) in staging {
        let data = buffer
            .get_mapped_range(..)
            .map_err(|e| RenderError::Readback(e.to_string()))?;
        let mut pixels = Vec::with_capacity((w * h * 4) as usize);
        for row in data.chunks_exact(padded as usize).take(h as usize) {
            pixels.extend_from_slice(&row[..(w * 4) as usize]);
        }
        drop(data);
        buffer.unmap();
        let image = RgbaImage::from_raw(w, h, pixels)
            .ok_or_else(|| RenderError::Readback("image size mismatch".into()))?;
        images.push(image);
    }
    Ok(images)
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
                store: wgpu::StoreOp::Store,
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
