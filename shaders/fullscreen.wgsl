// One triangle over the whole target: vertex `index` 0, 1, 2 at (-1, -1), (3, -1), (-1, 3).
// Shared by the passes that work pixel by pixel (src/render/fullscreen.rs builds them).

@vertex
fn vs_fullscreen(@builtin(vertex_index) index: u32) -> @builtin(position) vec4<f32> {
    let ndc = vec2<f32>(f32((index << 1u) & 2u) * 2.0 - 1.0, f32(index & 2u) * 2.0 - 1.0);
    return vec4<f32>(ndc, 0.0, 1.0);
}
