//! WGSL sources: every feature shader is compiled with the shared sources (`common.wgsl`,
//! `pbr.wgsl`) prepended.

/// Shared structs and functions (uniforms, omnistereo, tessellation, projections).
pub const COMMON: &str = include_str!("../../shaders/common.wgsl");

/// Physically based shading (CPU twin: `src/pbr.rs`).
pub const PBR: &str = include_str!("../../shaders/pbr.wgsl");

/// The shared sources by file stem, in the order they are prepended.
pub const SHARED: &[(&str, &str)] = &[("common", COMMON), ("pbr", PBR)];

/// Scene geometry (paired with `src/render/scene_pass.rs`).
pub const SCENE: &str = include_str!("../../shaders/scene.wgsl");

/// Shadow maps' depth pass (paired with `src/render/shadow_pass.rs`).
pub const SHADOW: &str = include_str!("../../shaders/shadow.wgsl");

/// Adaptive tessellation compute passes (paired with `src/render/tessellator.rs`).
pub const TESSELLATE: &str = include_str!("../../shaders/tessellate.wgsl");

/// Skybox (paired with `src/render/sky_pass.rs`).
pub const SKY: &str = include_str!("../../shaders/sky.wgsl");

/// Stereo output formats (paired with `src/render/present.rs`).
pub const PRESENT: &str = include_str!("../../shaders/present.wgsl");

/// The panorama's image route (paired with `src/render/panorama.rs`).
pub const PANORAMA: &str = include_str!("../../shaders/panorama.wgsl");

/// Every feature shader by file stem, for validation.
pub const FEATURES: &[(&str, &str)] = &[
    ("scene", SCENE),
    ("shadow", SHADOW),
    ("tessellate", TESSELLATE),
    ("sky", SKY),
    ("present", PRESENT),
    ("panorama", PANORAMA),
];

/// Full source of a feature shader: the shared sources followed by the feature's own code.
pub fn compose(feature_source: &str) -> String {
    let mut s = String::new();
    for (_, shared) in SHARED {
        s.push_str(shared);
        s.push('\n');
    }
    s.push_str(feature_source);
    s
}

/// Builds the shader module for a feature (once, at pipeline creation).
pub fn module(device: &wgpu::Device, label: &str, feature_source: &str) -> wgpu::ShaderModule {
    device.create_shader_module(wgpu::ShaderModuleDescriptor {
        label: Some(label),
        source: wgpu::ShaderSource::Wgsl(compose(feature_source).into()),
    })
}
