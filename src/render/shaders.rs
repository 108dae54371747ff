//! WGSL sources: every feature shader is compiled with the shared sources it names
//! (`common.wgsl`, `pbr.wgsl` for the scene, `srgb.wgsl` for what writes or reads colour)
//! prepended.

/// Shared structs and functions (uniforms, omnistereo, tessellation, projections).
pub const COMMON: &str = include_str!("../../shaders/common.wgsl");

/// Physically based shading (CPU twin: `src/render/pbr.rs`). It reads the including shader's
/// `frame` uniform, so only the scene shader includes it.
pub const PBR: &str = include_str!("../../shaders/pbr.wgsl");

/// sRGB encoding and decoding, and the colour a pass's target takes (`target_color`).
pub const SRGB: &str = include_str!("../../shaders/srgb.wgsl");

/// The full-screen triangle's vertex shader (`vs_fullscreen`).
pub const FULLSCREEN: &str = include_str!("../../shaders/fullscreen.wgsl");

/// The shared sources by file stem.
pub const SHARED: &[(&str, &str)] = &[
    ("common", COMMON),
    ("pbr", PBR),
    ("srgb", SRGB),
    ("fullscreen", FULLSCREEN),
];

/// A feature shader: its file stem, its own source and the shared sources compiled before it.
#[derive(Clone, Copy, Debug)]
pub struct Feature {
    /// File name in `shaders/` without `.wgsl`.
    pub stem: &'static str,
    /// The feature's own code.
    pub source: &'static str,
    /// Shared sources prepended, in this order.
    pub shared: &'static [&'static str],
}

/// Scene geometry (paired with `src/render/scene_pass.rs`).
pub const SCENE: Feature = Feature {
    stem: "scene",
    source: include_str!("../../shaders/scene.wgsl"),
    shared: &[COMMON, PBR, SRGB],
};

/// Shadow maps' depth pass (paired with `src/render/shadow_pass.rs`).
pub const SHADOW: Feature = Feature {
    stem: "shadow",
    source: include_str!("../../shaders/shadow.wgsl"),
    shared: &[COMMON],
};

/// Adaptive tessellation compute passes (paired with `src/render/tessellator.rs`).
pub const TESSELLATE: Feature = Feature {
    stem: "tessellate",
    source: include_str!("../../shaders/tessellate.wgsl"),
    shared: &[COMMON],
};

/// Skybox (paired with `src/render/sky_pass.rs`).
pub const SKY: Feature = Feature {
    stem: "sky",
    source: include_str!("../../shaders/sky.wgsl"),
    shared: &[COMMON, SRGB],
};

/// Stereo output formats (paired with `src/render/present.rs`).
pub const PRESENT: Feature = Feature {
    stem: "present",
    source: include_str!("../../shaders/present.wgsl"),
    shared: &[COMMON, SRGB, FULLSCREEN],
};

/// The panorama's image route (paired with `src/render/panorama.rs`).
pub const PANORAMA: Feature = Feature {
    stem: "panorama",
    source: include_str!("../../shaders/panorama.wgsl"),
    shared: &[COMMON],
};

/// The resolve of shader-encoded multisampled eye images (paired with `src/render/resolve.rs`).
pub const RESOLVE: Feature = Feature {
    stem: "resolve",
    source: include_str!("../../shaders/resolve.wgsl"),
    shared: &[SRGB, FULLSCREEN],
};

/// A cached overlay (the control panel) over a window's frame (paired with
/// `src/render/overlay.rs`).
pub const OVERLAY: Feature = Feature {
    stem: "overlay",
    source: include_str!("../../shaders/overlay.wgsl"),
    shared: &[FULLSCREEN],
};

/// The pose pass: skins and morph targets in compute (paired with
/// `src/render/pose_pass.rs`).
pub const POSE: Feature = Feature {
    stem: "pose",
    source: include_str!("../../shaders/pose.wgsl"),
    shared: &[COMMON],
};

/// Every feature shader, for validation.
pub const FEATURES: &[Feature] = &[
    SCENE, SHADOW, TESSELLATE, SKY, PRESENT, PANORAMA, RESOLVE, OVERLAY, POSE,
];

/// Full source of a feature shader: its shared sources followed by the feature's own code.
pub fn compose(feature: Feature) -> String {
    let mut s = String::new();
    for shared in feature.shared {
        s.push_str(shared);
        s.push('\n');
    }
    s.push_str(feature.source);
    s
}

/// Builds the shader module for a feature (once, at pipeline creation).
pub fn module(device: &wgpu::Device, label: &str, feature: Feature) -> wgpu::ShaderModule {
    device.create_shader_module(wgpu::ShaderModuleDescriptor {
        label: Some(label),
        source: wgpu::ShaderSource::Wgsl(compose(feature).into()),
    })
}
