// Skybox: a cube map behind the scene, per wall and eye, in three modes.
// Paired with src/render/sky_pass.rs; the eye model is mirrored on the CPU by
// src/sky/lookup.rs (keep the two in step).
//
// Drawn after the scene at depth 1 with a less-equal test, so only background pixels run the
// fragment shader.

// One wall seen from one eye. Keep in sync with `SkyUniforms` in src/render/sky_pass.rs.
struct SkyUniforms {
    // Hardware cube-map direction from a CAVE-space direction: the world rotation of the
    // CAVE, then z flipped (src/sky/cubemap.rs explains the convention).
    cube_from_cave: mat4x4<f32>,
    // The wall: lower-left corner, and the vectors to the lower-right and upper-left corners.
    wall_origin: vec4<f32>,
    wall_right: vec4<f32>,
    wall_up: vec4<f32>,
    // offaxis: xyz the view's eye.
    eye: vec4<f32>,
    // Omnistereo: xyz head; w signed half IPD (−IPD/2 left eye, +IPD/2 right, 0 mono).
    head: vec4<f32>,
    // Pole merge, encoded as FrameUniforms.omni: y, z start and end (radians); w 1 if on.
    pole: vec4<f32>,
    // x: exposure (multiplies the sky's linear colour).
    params: vec4<f32>,
}

@group(0) @binding(0) var<uniform> sky: SkyUniforms;
@group(1) @binding(0) var sky_cube: texture_cube<f32>;
@group(1) @binding(1) var sky_sampler: sampler;

fn wall_point(uv: vec2<f32>) -> vec3<f32> {
    return sky.wall_origin.xyz + uv.x * sky.wall_right.xyz + uv.y * sky.wall_up.xyz;
}

// The eye E whose view in direction d passes through wall point p, with E(d) the geometry's
// eye for a point at infinity: the ray E→p is tangent to the circle of radius |σ| around the
// head (σ = half IPD faded by the pole merge at the ray's elevation).
fn omni_sky_eye(p: vec3<f32>) -> vec3<f32> {
    let head = sky.head.xyz;
    let half_ipd = sky.head.w;
    let q = vec2<f32>(p.x - head.x, p.z - head.z);
    let l2 = dot(q, q);
    if l2 < 1e-18 {
        return head;
    }
    let dy = abs(p.y - head.y);
    var sigma = half_ipd * pole_merge_factor(atan2(dy, sqrt(l2)), sky.pole);
    for (var k = 0; k < 2; k++) {
        let t = sqrt(max(l2 - sigma * sigma, 0.0));
        sigma = half_ipd * pole_merge_factor(atan2(dy, t), sky.pole);
    }
    // Within |σ| of the vertical through the head (pole merging off): no tangent; clamp.
    sigma = clamp(sigma, -sqrt(l2), sqrt(l2));
    let t = sqrt(max(l2 - sigma * sigma, 0.0));
    let d = vec2<f32>(t * q.x + sigma * q.y, t * q.y - sigma * q.x) / l2;
    return head + sigma * vec3<f32>(-d.y, 0.0, d.x);
}

fn shade(cave_direction: vec3<f32>) -> vec4<f32> {
    let dir = (sky.cube_from_cave * vec4<f32>(cave_direction, 0.0)).xyz;
    let c = textureSample(sky_cube, sky_sampler, dir);
    return vec4<f32>(c.rgb * sky.params.x, 1.0);
}

struct FullScreenOutput {
    @builtin(position) clip: vec4<f32>,
    // The wall point under the pixel (CAVE space); affine in screen space, so interpolating
    // it is exact.
    @location(0) wall_point: vec3<f32>,
}

// One triangle covering the viewport; NDC (−1, −1) is the wall's lower-left corner.
@vertex
fn vs_fullscreen(@builtin(vertex_index) index: u32) -> FullScreenOutput {
    let ndc = vec2<f32>(f32((index << 1u) & 2u) * 2.0 - 1.0, f32(index & 2u) * 2.0 - 1.0);
    var out: FullScreenOutput;
    out.clip = vec4<f32>(ndc, 1.0, 1.0);
    out.wall_point = wall_point(0.5 * (ndc + 1.0));
    return out;
}

// offaxis: the direction from the view's one eye.
@fragment
fn fs_offaxis(in: FullScreenOutput) -> @location(0) vec4<f32> {
    return target_color(shade(in.wall_point - sky.eye.xyz));
}

// omni-exact: the omnistereo eye solved per pixel.
@fragment
fn fs_exact(in: FullScreenOutput) -> @location(0) vec4<f32> {
    return target_color(shade(in.wall_point - omni_sky_eye(in.wall_point)));
}

struct QuadOutput {
    @builtin(position) clip: vec4<f32>,
    // Unnormalised lookup vector p − E(p), interpolated across the mesh (thesis 6.3).
    @location(0) lookup: vec3<f32>,
}

// omni-quad: a mesh vertex at wall coordinates uv (0..1, v up) with its own eye.
@vertex
fn vs_quad(@location(0) uv: vec2<f32>) -> QuadOutput {
    let p = wall_point(uv);
    var out: QuadOutput;
    out.clip = vec4<f32>(2.0 * uv - 1.0, 1.0, 1.0);
    out.lookup = p - omni_sky_eye(p);
    return out;
}

@fragment
fn fs_quad(in: QuadOutput) -> @location(0) vec4<f32> {
    return target_color(shade(in.lookup));
}
