// Shared declarations, prepended to every feature shader by `render::shaders::compose`.
// Keep the structs in sync with `src/render/uniforms.rs`.

// One light, CAVE space. Keep in sync with `GpuLight` in src/render/uniforms.rs.
struct Light {
    // xyz: position; w: range in metres (0: no cut-off).
    position: vec4<f32>,
    // xyz: unit direction the light travels; w: kind (0 directional, 1 point, 2 spot).
    direction: vec4<f32>,
    // rgb: linear colour × intensity (radiance scale); w: falloff (0 inverse square with the
    // glTF range window, 1 the config's smooth fade to the range).
    color: vec4<f32>,
    // Spot: x cos(outer cone), y 1 / (cos(inner) − cos(outer)).
    cone: vec4<f32>,
    // x: its first shadow-map layer (< 0: casts no shadow); y: layers (1, or 6 for a point
    // light); z: texel size at 1 m (perspective maps); w: texel size (orthographic maps).
    shadow: vec4<f32>,
}

// Lights a frame holds at most (the config's and the scene file's, in that order).
const MAX_LIGHTS: u32 = 8u;
// Shadow-map layers. Keep in sync with `MAX_SHADOW_LAYERS` in src/render/shadow_pass.rs.
const MAX_SHADOW_LAYERS: u32 = 8u;

// Per-frame data, CAVE space. Keep in sync with `FrameUniforms` in src/render/uniforms.rs.
struct FrameUniforms {
    cave_from_world: mat4x4<f32>,
    // Inverse transpose of cave_from_world's linear part (for normals).
    normal_from_world: mat4x4<f32>,
    // rgb: ambient radiance (linear); w unused.
    ambient: vec4<f32>,
    // rgba: wireframe overlay colour (linear).
    wire_color: vec4<f32>,
    // x: warp (0 = none, 1 = similar triangles, 2 = intersection point);
    // y, z: pole-merge start and end elevation (radians); w: 1 if pole merging is on.
    omni: vec4<f32>,
    // Lights in use (0..=MAX_LIGHTS).
    light_count: u32,
    // 0: physically based (shaders/pbr.wgsl); 1: the simple Blinn-Phong model.
    shading: u32,
    // Shadow-map range tiles per side (shaders/shadow.wgsl); 0: the filter always gathers.
    shadow_tiles: u32,
    frame_pad: u32,
    // x: normal offset of shadow look-ups, texels; y: 1 for 3×3 filtering; z: 1 / map size;
    // w: 1 when shadows are on.
    shadow_params: vec4<f32>,
    // x: 1 when the sky lights the scene (its irradiance in sky_sh); yzw unused.
    sky_params: vec4<f32>,
    // CAVE → scene directions (the placement's rotation), for the sky's irradiance.
    sky_from_cave: mat4x4<f32>,
    // The sky's irradiance as 9 spherical-harmonic coefficients (rgb), light strength and
    // exposure applied (src/sky/irradiance.rs).
    sky_sh: array<vec4<f32>, 9>,
    lights: array<Light, MAX_LIGHTS>,
    // CAVE space → each shadow-map layer's clip space.
    shadow_from_cave: array<mat4x4<f32>, MAX_SHADOW_LAYERS>,
}

// One wall seen from one eye. Keep in sync with `ViewUniforms` in src/render/uniforms.rs.
struct ViewUniforms {
    clip_from_cave: mat4x4<f32>,
    // xyz: centre of projection (CAVE space; the projective viewpoint C in omnistereo).
    eye_position: vec4<f32>,
    // Omnistereo: the wall plane (n, d) with s(X) = dot(n, X) + d, n towards the viewer.
    wall_plane: vec4<f32>,
    // Omnistereo: xyz head position; w: signed half IPD (−IPD/2 left eye, +IPD/2 right eye).
    omni_head: vec4<f32>,
    // The fields below are for panorama views only (zero for walls). The projection's code
    // + 1 (0: not a panorama).
    pano_projection: u32,
    // Near and far clipping sphere radius, metres.
    pano_near: f32,
    pano_far: f32,
    // 0 mono, 1 volume, 2 omni.
    pano_stereo: u32,
    // The field of view's centre and half size in map coordinates.
    pano_window: vec4<f32>,
    // Image pixels.
    pano_size: vec2<f32>,
    // Volume stereo: signed half inter-ocular distance, viewing distance and zero-parallax
    // depth (normalised device units).
    volume_half_ioid: f32,
    volume_distance: f32,
    volume_zero_parallax: f32,
    // The panorama target's MSAA sample count.
    pano_msaa: u32,
    pano_pad: vec2<u32>,
}

// Omnistereo, mirrored on the CPU by src/cave/omni.rs (keep the two in step).

// Fraction of the IPD kept at an elevation (smoothstep fade between the pole-merge angles).
fn pole_merge_factor(elevation: f32, omni: vec4<f32>) -> f32 {
    if omni.w < 0.5 {
        return 1.0;
    }
    if omni.z <= omni.y {
        return select(0.0, 1.0, elevation < omni.y);
    }
    let t = clamp((elevation - omni.y) / (omni.z - omni.y), 0.0, 1.0);
    return 1.0 - t * t * (3.0 - 2.0 * t);
}

// The eye that should see `v`: the head moved sideways by half the IPD, perpendicular to the
// horizontal direction from the head to `v`. `omni_head` is the view's (xyz head, w signed half
// IPD). Views and frames are passed by the fields used, never whole: lavapipe copies a struct
// argument through memory for every invocation.
fn omni_eye(v: vec3<f32>, omni_head: vec4<f32>, omni: vec4<f32>) -> vec3<f32> {
    let head = omni_head.xyz;
    let d = v - head;
    let horizontal = vec2<f32>(d.x, d.z);
    let len = length(horizontal);
    let elevation = atan2(abs(d.y), len);
    var dir = vec3<f32>(0.0, 0.0, -1.0);
    if len > 1e-12 {
        dir = vec3<f32>(horizontal.x / len, 0.0, horizontal.y / len);
    }
    let right = cross(dir, vec3<f32>(0.0, 1.0, 0.0));
    return head + omni_head.w * pole_merge_factor(elevation, omni) * right;
}

// Moves `v` so that the projection from C (the view's eye_position) draws it where the ray e→v
// meets the wall plane (the view's wall_plane). Similar triangles: v' = v − (s(v)/s(e))·(e − C).
fn omni_warp(v: vec3<f32>, e: vec3<f32>, c: vec3<f32>, wall_plane: vec4<f32>, variant: f32)
    -> vec3<f32> {
    let n = wall_plane.xyz;
    let sv = dot(n, v) + wall_plane.w;
    let se = dot(n, e) + wall_plane.w;
    if variant < 1.5 {
        return v - (sv / max(se, 1e-6)) * (e - c);
    }
    // Intersection point (unguarded on purpose: the unstable form kept for comparison).
    let i = e + (se / (se - sv)) * (v - e);
    return c + normalize(i - c) * length(v - c);
}

// Scene vertices as the tessellator and the tessellated draws read them (f32 each): position
// 0..3, normal 3..6, uv 6..8, uv1 8..10, colour 10..14, tangent 14..18. Keep in sync with
// `GpuVertex` in src/render/scene_pass.rs.
const VERTEX_FLOATS: u32 = 18u;

// The tessellator and the tessellated draws bind the scene's vertex buffer as storage in
// VERTEX_WINDOWS windows (a GPU binds at most max_storage_buffer_binding_size bytes at once):
// window k holds vertices k·W … k·W + W − 1, W being window 0's length in vertices (a buffer
// within the limit is window 0 whole). Returns (window, vertex within it). Keep in sync with
// src/render/vertex_windows.rs.
const VERTEX_WINDOWS: u32 = 4u;

fn vertex_window(vertex: u32, window_vertices: u32) -> vec2<u32> {
    if vertex < window_vertices {
        return vec2<u32>(0u, vertex);
    }
    let k = min(vertex / max(window_vertices, 1u), VERTEX_WINDOWS - 1u);
    return vec2<u32>(k, vertex - k * window_vertices);
}

// Tessellation, shared by shaders/tessellate.wgsl (splitting) and shaders/scene.wgsl (drawing);
// mirrored on the CPU by src/tess/mod.rs.

// Fixed-point 1.0 of barycentric coordinates.
const BARY_ONE: u32 = 65536u;

// A triangle inside a source triangle: corners as fixed-point barycentrics (b1, b2 per
// corner; b0 = BARY_ONE − b1 − b2). Keep in sync with `GpuTessEntry` in
// src/render/tessellator.rs.
struct TessEntry {
    source: u32,
    // Round in which it was made; 0xffffffff marks a padding slot left by an overflow.
    depth: u32,
    c0: vec2<u32>,
    c1: vec2<u32>,
    c2: vec2<u32>,
}

// Lexicographic (x, y, z) order: true if a sorts before b.
fn sorts_before(a: vec3<f32>, b: vec3<f32>) -> bool {
    if a.x != b.x {
        return a.x < b.x;
    }
    if a.y != b.y {
        return a.y < b.y;
    }
    return a.z < b.z;
}

// How to interpolate at a barycentric point, canonically: a corner as is; a point on an edge
// as v[i] + t·(v[j] − v[i]) with i the endpoint whose position sorts first (so triangles
// sharing the edge compute bit-identical points); an interior point with weights w.
struct InterpPlan {
    // 0: corner i; 1: edge i→j at t; 2: interior with weights w.
    mode: u32,
    i: u32,
    j: u32,
    t: f32,
    w: vec3<f32>,
}

fn interp_plan(p: array<vec3<f32>, 3>, b: vec2<u32>) -> InterpPlan {
    let w = array<u32, 3>(BARY_ONE - b.x - b.y, b.x, b.y);
    var plan: InterpPlan;
    var zeros = 0u;
    var z = 0u;
    var nz = 0u;
    for (var k = 0u; k < 3u; k++) {
        if w[k] == 0u {
            zeros += 1u;
            z = k;
        } else {
            nz = k;
        }
    }
    if zeros == 2u {
        plan.mode = 0u;
        plan.i = nz;
        return plan;
    }
    if zeros == 1u {
        var i = (z + 1u) % 3u;
        var j = (z + 2u) % 3u;
        if sorts_before(p[j], p[i]) {
            let s = i;
            i = j;
            j = s;
        }
        plan.mode = 1u;
        plan.i = i;
        plan.j = j;
        plan.t = f32(w[j]) / f32(BARY_ONE);
        return plan;
    }
    let inv = 1.0 / f32(BARY_ONE);
    plan.mode = 2u;
    plan.w = vec3<f32>(f32(w[0]) * inv, f32(w[1]) * inv, f32(w[2]) * inv);
    return plan;
}

fn interp3(plan: InterpPlan, v: array<vec3<f32>, 3>) -> vec3<f32> {
    if plan.mode == 0u {
        return v[plan.i];
    }
    if plan.mode == 1u {
        return v[plan.i] + plan.t * (v[plan.j] - v[plan.i]);
    }
    return plan.w.x * v[0] + plan.w.y * v[1] + plan.w.z * v[2];
}

fn interp4(plan: InterpPlan, v: array<vec4<f32>, 3>) -> vec4<f32> {
    if plan.mode == 0u {
        return v[plan.i];
    }
    if plan.mode == 1u {
        return v[plan.i] + plan.t * (v[plan.j] - v[plan.i]);
    }
    return plan.w.x * v[0] + plan.w.y * v[1] + plan.w.z * v[2];
}

// Panorama projections, mirrored on the CPU by src/pano/projection.rs (keep the two in step).
// View space: x right, y up, −z ahead. Codes: 0 perspective, 1 equirectangular, 2 Hammer,
// 3 Albers equal-area conic, 4 azimuthal equidistant (`Projection::code`).

const PI: f32 = 3.14159265358979;
const HALF_PI: f32 = 1.57079632679490;
const SQRT2: f32 = 1.41421356237310;

// Albers' constants for standard parallels 0° and 45° (`albers_constants`): n, C, ρ0. Keep in
// sync with `ALBERS_PARALLELS_DEG` in src/pano/projection.rs.
const ALBERS_N: f32 = 0.35355339059327;
const ALBERS_C: f32 = 1.0;
const ALBERS_RHO0: f32 = 2.82842712474619;

// Longitude (0 ahead, positive right) and latitude of a unit direction.
fn pano_lon_lat(d: vec3<f32>) -> vec2<f32> {
    return vec2<f32>(atan2(d.x, -d.z), asin(clamp(d.y, -1.0, 1.0)));
}

// An angle wrapped into [−π, π].
fn wrap_angle(a: f32) -> f32 {
    return a - 2.0 * PI * round(a / (2.0 * PI));
}

fn pano_direction(lon: f32, lat: f32) -> vec3<f32> {
    return vec3<f32>(cos(lat) * sin(lon), sin(lat), -cos(lat) * cos(lon));
}

fn pano_hammer(lon: f32, lat: f32) -> vec2<f32> {
    let den = sqrt(1.0 + cos(lat) * cos(0.5 * lon));
    return vec2<f32>(2.0 * SQRT2 * cos(lat) * sin(0.5 * lon) / den, SQRT2 * sin(lat) / den);
}

// Map coordinates of a longitude and latitude (equirectangular and Hammer accept longitudes
// beyond ±π: the geometric route unwraps them across the rear seam).
fn pano_map(code: u32, lon: f32, lat: f32) -> vec2<f32> {
    if code == 1u {
        return vec2<f32>(lon, lat);
    }
    if code == 2u {
        return pano_hammer(lon, lat);
    }
    let d = pano_direction(lon, lat);
    if code == 0u {
        return d.xy / max(-d.z, 1e-6);
    }
    if code == 3u {
        let rho = sqrt(max(ALBERS_C - 2.0 * ALBERS_N * sin(lat), 0.0)) / ALBERS_N;
        let theta = ALBERS_N * lon;
        return vec2<f32>(rho * sin(theta), ALBERS_RHO0 - rho * cos(theta));
    }
    let angle = acos(clamp(-d.z, -1.0, 1.0));
    let len = length(d.xy);
    if len > 1e-12 {
        return d.xy * (angle / len);
    }
    return vec2<f32>(0.0);
}

// Pixel position (x right, y up, from the image centre) of a longitude and latitude in a
// panorama view.
fn pano_pixel(pv: ViewUniforms, lon: f32, lat: f32) -> vec2<f32> {
    let ndc = (pano_map(pv.pano_projection - 1u, lon, lat) - pv.pano_window.xy) / pv.pano_window.zw;
    return 0.5 * ndc * pv.pano_size;
}

// The unit direction at map coordinates; w = 0 where the projection shows nothing.
fn pano_unmap(code: u32, m: vec2<f32>) -> vec4<f32> {
    if code == 0u {
        return vec4<f32>(normalize(vec3<f32>(m, -1.0)), 1.0);
    }
    if code == 1u {
        let inside = abs(m.x) <= PI && abs(m.y) <= HALF_PI;
        return vec4<f32>(pano_direction(m.x, m.y), select(0.0, 1.0, inside));
    }
    if code == 2u {
        if m.x * m.x / 8.0 + m.y * m.y / 2.0 > 1.0 {
            return vec4<f32>(0.0);
        }
        let z = sqrt(max(1.0 - m.x * m.x / 16.0 - m.y * m.y / 4.0, 0.0));
        let lon = 2.0 * atan2(z * m.x, 2.0 * (2.0 * z * z - 1.0));
        let lat = asin(clamp(z * m.y, -1.0, 1.0));
        return vec4<f32>(pano_direction(lon, lat), 1.0);
    }
    if code == 3u {
        let dy = ALBERS_RHO0 - m.y;
        let rho = length(vec2<f32>(m.x, dy));
        let lon = atan2(m.x, dy) / ALBERS_N;
        let s = (ALBERS_C - rho * rho * ALBERS_N * ALBERS_N) / (2.0 * ALBERS_N);
        let inside = abs(lon) <= PI && abs(s) <= 1.0;
        return vec4<f32>(pano_direction(lon, asin(clamp(s, -1.0, 1.0))), select(0.0, 1.0, inside));
    }
    let angle = length(m);
    if angle > PI {
        return vec4<f32>(0.0);
    }
    var sideways = vec2<f32>(0.0);
    if angle > 0.0 {
        sideways = m / angle;
    }
    let s = sin(angle);
    return vec4<f32>(s * sideways.x, s * sideways.y, -cos(angle), 1.0);
}
