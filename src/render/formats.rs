//! The texture formats of the eye images and their depth, shared by every pass that draws
//! into them.

/// Colour format of every eye image: shading is linear, storage sRGB.
pub const COLOR_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba8UnormSrgb;
/// The multisampled images' format: the same bytes as [`COLOR_FORMAT`], written either
/// through an sRGB view (the hardware encodes each sample) or as bytes the shaders encoded
/// (`render::resolve` says when and why).
pub const ENCODED_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba8Unorm;
pub const DEPTH_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Depth32Float;
