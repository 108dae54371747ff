// Composites a cached overlay over a window's frame: the control panel, which egui paints
// into its own image only when it changes, in premultiplied alpha as egui paints it.
// Paired with src/render/overlay.rs.

@group(0) @binding(0) var overlay: texture_2d<f32>;

@fragment
fn fs_overlay(@builtin(position) position: vec4<f32>) -> @location(0) vec4<f32> {
    return textureLoad(overlay, vec2<i32>(floor(position.xy)), 0);
}
