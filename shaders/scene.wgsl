// Scene geometry: Blinn-Phong shaded, textured triangles for one wall and eye.
// Paired with src/render/scene_pass.rs; shared structs come from common.wgsl.

// Keep in sync with `MaterialUniforms` in src/render/uniforms.rs.
struct MaterialUniforms {
    // Linear RGBA multiplier.
    base_color: vec4<f32>,
    // rgb: emitted light (linear); w: 1 for unlit materials.
    emissive: vec4<f32>,
    // x: shininess, y: specular strength, z: alpha cutoff (< 0 = opaque), w unused.
    params: vec4<f32>,
}

@group(0) @binding(0) var<uniform> frame: FrameUniforms;
@group(0) @binding(1) var<uniform> view: ViewUniforms;
@group(1) @binding(0) var<uniform> material: MaterialUniforms;
@group(1) @binding(1) var base_texture: texture_2d<f32>;
@group(1) @binding(2) var base_sampler: sampler;

struct VertexInput {
    @location(0) position: vec3<f32>,
    @location(1) normal: vec3<f32>,
    @location(2) uv: vec2<f32>,
}

struct VertexOutput {
    // Invariant: a vertex shared by triangles drawn with different pipeline variants must land
    // on the same position, or tessellated neighbours could show cracks.
    @invariant @builtin(position) clip: vec4<f32>,
    @location(0) cave_position: vec3<f32>,
    @location(1) normal: vec3<f32>,
    @location(2) uv: vec2<f32>,
    @location(3) eye: vec3<f32>,
}

// Tessellated geometry (src/render/tessellator.rs): the sorted output triangles and the
// scene's vertex and index buffers, read as storage.
@group(2) @binding(0) var<storage, read> tess_entries: array<TessEntry>;
@group(2) @binding(1) var<storage, read> tess_vertices: array<f32>;
@group(2) @binding(2) var<storage, read> tess_indices: array<u32>;

// Everything after fetching a vertex: CAVE space, omnistereo eye and warp, projection.
fn transform_vertex(position: vec3<f32>, normal: vec3<f32>, uv: vec2<f32>) -> VertexOutput {
    let p = (frame.cave_from_world * vec4<f32>(position, 1.0)).xyz;
    var eye = view.eye_position.xyz;
    var projected = p;
    if frame.omni.x > 0.5 {
        // Omnistereo: this vertex's own eye, and the warp that makes the projection from C
        // draw it where that eye sees it. Lighting uses the same eye (thesis 5.3).
        eye = omni_eye(p, view, frame.omni);
        projected = omni_warp(p, eye, view, frame.omni.x);
    }
    var out: VertexOutput;
    out.clip = view.clip_from_cave * vec4<f32>(projected, 1.0);
    out.cave_position = p;
    out.normal = (frame.normal_from_world * vec4<f32>(normal, 0.0)).xyz;
    out.uv = uv;
    out.eye = eye;
    return out;
}

@vertex
fn vs_main(in: VertexInput) -> VertexOutput {
    return transform_vertex(in.position, in.normal, in.uv);
}

fn tess_vec3(vertex: u32, offset: u32) -> vec3<f32> {
    let base = 8u * vertex + offset;
    return vec3<f32>(tess_vertices[base], tess_vertices[base + 1u], tess_vertices[base + 2u]);
}

// One corner of a tessellated triangle, interpolated canonically from its source triangle
// so that neighbours produce bit-identical points (watertight).
@vertex
fn vs_tess(@builtin(vertex_index) vertex_index: u32) -> VertexOutput {
    let e = tess_entries[vertex_index / 3u];
    let corners = array<vec2<u32>, 3>(e.c0, e.c1, e.c2);
    let b = corners[vertex_index % 3u];
    let i0 = tess_indices[3u * e.source];
    let i1 = tess_indices[3u * e.source + 1u];
    let i2 = tess_indices[3u * e.source + 2u];
    let p = array<vec3<f32>, 3>(tess_vec3(i0, 0u), tess_vec3(i1, 0u), tess_vec3(i2, 0u));
    let n = array<vec3<f32>, 3>(tess_vec3(i0, 3u), tess_vec3(i1, 3u), tess_vec3(i2, 3u));
    let uv = array<vec2<f32>, 3>(
        vec2<f32>(tess_vertices[8u * i0 + 6u], tess_vertices[8u * i0 + 7u]),
        vec2<f32>(tess_vertices[8u * i1 + 6u], tess_vertices[8u * i1 + 7u]),
        vec2<f32>(tess_vertices[8u * i2 + 6u], tess_vertices[8u * i2 + 7u]),
    );
    let plan = interp_plan(p, b);
    return transform_vertex(interp3(plan, p), interp3(plan, n), interp2(plan, uv));
}

@fragment
fn fs_main(in: VertexOutput, @builtin(front_facing) front_facing: bool) -> @location(0) vec4<f32> {
    // Materials without a texture are bound to a 1×1 white one, so this is always valid.
    let base = material.base_color * textureSample(base_texture, base_sampler, in.uv);
    if material.params.z >= 0.0 && base.a < material.params.z {
        discard;
    }
    if material.emissive.w > 0.5 {
        // KHR_materials_unlit: exactly the base colour.
        return vec4<f32>(base.rgb, 1.0);
    }
    var n = normalize(in.normal);
    if !front_facing {
        n = -n;
    }
    let lit = blinn_phong(
        frame, base.rgb, in.cave_position, n, in.eye, material.params.x, material.params.y,
    );
    return vec4<f32>(lit + material.emissive.rgb, 1.0);
}

@fragment
fn fs_wireframe() -> @location(0) vec4<f32> {
    return frame.wire_color;
}
