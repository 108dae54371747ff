// Panorama, image route (3DUI): every pixel's direction through the inverse map, looked up in
// the six cube faces the scene was rendered into; and the sky behind the panorama, both
// routes. Paired with src/render/panorama.rs (the geometric route's scene shaders are
// vs_pano/fs_pano in scene.wgsl).

// Keep in sync with `ResolveUniforms` in src/render/panorama.rs.
struct ResolveUniforms {
    // CAVE-space direction from view-space direction (rotation only).
    cave_from_view: mat4x4<f32>,
    // The sky's cube-map direction from a CAVE-space direction (as SkyUniforms').
    cube_from_cave: mat4x4<f32>,
    // The field of view's centre and half size in map coordinates.
    window: vec4<f32>,
    // x: projection code; y: the faces' half extent (tan of half their field of view,
    // a little over 1: a guard band for filtering across face edges); z: sky exposure;
    // w unused.
    params: vec4<f32>,
    // Linear colour outside the projection's outline (and where nothing is drawn, without a
    // sky).
    background: vec4<f32>,
}

@group(0) @binding(0) var<uniform> resolve: ResolveUniforms;
// The image route's cube faces (cleared to alpha 0: alpha is the scene's coverage).
@group(1) @binding(0) var faces: texture_2d_array<f32>;
@group(1) @binding(1) var face_sampler: sampler;
// The sky (the sky pass's own cube map and sampler).
@group(2) @binding(0) var sky_cube: texture_cube<f32>;
@group(2) @binding(1) var sky_sampler: sampler;

struct Varyings {
    @builtin(position) position: vec4<f32>,
    @location(0) ndc: vec2<f32>,
}

// One triangle over the whole target, at the far depth (the sky is drawn behind the scene
// with a less-equal test).
@vertex
fn vs_fullscreen(@builtin(vertex_index) i: u32) -> Varyings {
    let xy = vec2<f32>(f32((i << 1u) & 2u), f32(i & 2u)) * 2.0 - 1.0;
    var out: Varyings;
    out.position = vec4<f32>(xy, 1.0, 1.0);
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

// The CAVE-space direction shown at a pixel; w = 0 outside the projection's outline.
fn pixel_direction(ndc: vec2<f32>) -> vec4<f32> {
    let m = resolve.window.xy + ndc * resolve.window.zw;
    let unmapped = pano_unmap(u32(resolve.params.x), m);
    return vec4<f32>((resolve.cave_from_view * vec4<f32>(unmapped.xyz, 0.0)).xyz, unmapped.w);
}

// The scene in direction d (alpha: its coverage), from the cube faces.
fn face_color(d: vec3<f32>) -> vec4<f32> {
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
    return textureSampleLevel(faces, face_sampler, uv, face, 0.0);
}

// The sky in CAVE-space direction d (at infinity: one lookup serves every eye).
fn sky_color(d: vec3<f32>) -> vec3<f32> {
    let dir = (resolve.cube_from_cave * vec4<f32>(d, 0.0)).xyz;
    return textureSample(sky_cube, sky_sampler, dir).rgb * resolve.params.z;
}

@fragment
fn fs_resolve(in: Varyings) -> @location(0) vec4<f32> {
    let d = pixel_direction(in.ndc);
    let color = vec4<f32>(face_color(d.xyz).rgb, 1.0);
    return select(resolve.background, color, d.w > 0.5);
}

// With a sky: where the faces' coverage is partial (filtered edges) or none, the sky shows
// through in proportion: the faces hold scene·a + background·(1 − a).
@fragment
fn fs_resolve_sky(in: Varyings) -> @location(0) vec4<f32> {
    let d = pixel_direction(in.ndc);
    let sky = sky_color(d.xyz);
    let c = face_color(d.xyz);
    let color = vec4<f32>(c.rgb + (1.0 - c.a) * (sky - resolve.background.rgb), 1.0);
    return select(resolve.background, color, d.w > 0.5);
}

// The geometric route's sky: drawn after the scene at the far depth, so only pixels the
// scene left empty run it.
@fragment
fn fs_sky(in: Varyings) -> @location(0) vec4<f32> {
    let d = pixel_direction(in.ndc);
    let sky = sky_color(d.xyz);
    return select(resolve.background, vec4<f32>(sky, 1.0), d.w > 0.5);
}
