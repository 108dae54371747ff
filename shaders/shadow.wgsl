// Shadow maps: the scene's depth as each shadow-casting light sees it (scene space, no eye:
// exact in every render mode). Paired with src/render/shadow_pass.rs; the look-up is
// `shadow_visibility` in shaders/scene.wgsl.

// Keep in sync with `ShadowLayerUniforms` in src/render/shadow_pass.rs.
struct ShadowLayerUniforms {
    shadow_from_world: mat4x4<f32>,
}

@group(0) @binding(0) var<uniform> layer: ShadowLayerUniforms;

@vertex
fn vs_shadow(@location(0) position: vec3<f32>) -> @builtin(position) vec4<f32> {
    return layer.shadow_from_world * vec4<f32>(position, 1.0);
}
