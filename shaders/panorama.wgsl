// Panorama, image route (3DUI): every pixel's direction through the inverse map, looked up in
// the six cube faces the scene was rendered into. Paired with src/render/panorama.rs (which
// also holds the geometric route; its shaders are vs_pano/fs_pano in scene.wgsl).

// Keep in sync with `ResolveUniforms` in src/render/panorama.rs.
struct ResolveUniforms {
    // CAVE-space direction from view-space direction (rotation only).
    cave_from_view: mat4x4<f32>,
    // The field of view's centre and half size in map coordinates.
    window: vec4<f32>,
    // x: projection code; y: the faces' half extent (tan of half their field of view,
    // a little over 1: a guard band for filtering across face edges); z, w unused.
    params: vec4<f32>,
    // Linear colour outside the projection's outline.
    background: vec4<f32>,
}

@group(0) @binding(0) var<uniform> resolve: ResolveUniforms;
@group(0) @binding(1) var faces: texture_2d_array<f32>;
@group(0) @binding(2) var face_sampler: sampler;

struct Varyings {
    @builtin(position) position: vec4<f32>,
    @location(0) ndc: vec2<f32>,
}

@vertex
fn vs_fullscreen(@builtin(vertex_index) i: u32) -> Varyings {
    // One triangle over the whole target.
    let xy = vec2<f32>(f32((i << 1u) & 2u), f32(i & 2u)) * 2.0 - 1.0;
    var out: Varyings;
    out.position = vec4<f32>(xy, 0.0, 1.0);
    out.ndc = xy;
    return out;
}

// Face order and axes; mirrors `CUBE_FACES` in src/render/panorama.rs (keep in step). A face
// looks along `forward` with `up` up; its right is cross(forward, up).
const FACE_FORWARD = array<vec3<f32>, 6>(
    vec3<f32>(1.0, 0.0, 0.0), vec3<f32>(-1.0, 0.0, 0.0),
    vec3<f32>(0.0, 1.0, 0.0), vec3<f32>(0.0, -1.0, 0.0),
    vec3<f32>(0.0, 0.0, 1.0), vec3<f32>(0.0, 0.0, -1.0),
);
const FACE_UP = array<vec3<f32>, 6>(
    vec3<f32>(0.0, 1.0, 0.0), vec3<f32>(0.0, 1.0, 0.0),
    vec3<f32>(0.0, 0.0, 1.0), vec3<f32>(0.0, 0.0, -1.0),
    vec3<f32>(0.0, 1.0, 0.0), vec3<f32>(0.0, 1.0, 0.0),
);

@fragment
fn fs_resolve(in: Varyings) -> @location(0) vec4<f32> {
    let m = resolve.window.xy + in.ndc * resolve.window.zw;
    let unmapped = pano_unmap(u32(resolve.params.x), m);
    let d = (resolve.cave_from_view * vec4<f32>(unmapped.xyz, 0.0)).xyz;
    let a = abs(d);
    var face = 0u;
    if a.x >= a.y && a.x >= a.z {
        face = select(1u, 0u, d.x > 0.0);
    } else if a.y >= a.z {
        face = select(3u, 2u, d.y > 0.0);
    } else {
        face = select(5u, 4u, d.z > 0.0);
    }
    let forward = FACE_FORWARD[face];
    let up = FACE_UP[face];
    let right = cross(forward, up);
    let depth = dot(d, forward);
    let c = vec2<f32>(dot(d, right), dot(d, up)) / (depth * resolve.params.y);
    let uv = vec2<f32>(0.5 + 0.5 * c.x, 0.5 - 0.5 * c.y);
    let color = textureSampleLevel(faces, face_sampler, uv, face, 0.0);
    return select(resolve.background, color, unmapped.w > 0.5);
}
