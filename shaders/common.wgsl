// Shared declarations, prepended to every feature shader by `render::shaders::compose`.
// Keep the structs in sync with `src/render/uniforms.rs`.

// Per-frame data, CAVE space. Keep in sync with `FrameUniforms` in src/render/uniforms.rs.
struct FrameUniforms {
    cave_from_world: mat4x4<f32>,
    // Inverse transpose of cave_from_world's linear part (for normals).
    normal_from_world: mat4x4<f32>,
    // xyz: direction the sun's light travels (CAVE space, unit); w unused.
    sun_direction: vec4<f32>,
    // rgb: sun colour × intensity (linear); w unused.
    sun_color: vec4<f32>,
    // xyz: point light position (CAVE space); w: range in metres.
    point_position: vec4<f32>,
    // rgb: point light colour × intensity (linear); w unused.
    point_color: vec4<f32>,
    // rgb: ambient light (linear); w unused.
    ambient: vec4<f32>,
    // rgba: wireframe overlay colour (linear).
    wire_color: vec4<f32>,
    // x: warp (0 = none, 1 = similar triangles, 2 = intersection point);
    // y, z: pole-merge start and end elevation (radians); w: 1 if pole merging is on.
    omni: vec4<f32>,
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
// horizontal direction from the head to `v`.
fn omni_eye(v: vec3<f32>, view: ViewUniforms, omni: vec4<f32>) -> vec3<f32> {
    let head = view.omni_head.xyz;
    let d = v - head;
    let horizontal = vec2<f32>(d.x, d.z);
    let len = length(horizontal);
    let elevation = atan2(abs(d.y), len);
    var dir = vec3<f32>(0.0, 0.0, -1.0);
    if len > 1e-12 {
        dir = vec3<f32>(horizontal.x / len, 0.0, horizontal.y / len);
    }
    let right = cross(dir, vec3<f32>(0.0, 1.0, 0.0));
    return head + view.omni_head.w * pole_merge_factor(elevation, omni) * right;
}

// Moves `v` so that the projection from C = view.eye_position draws it where the ray e→v meets
// the wall plane. Similar triangles: v' = v − (s(v)/s(e))·(e − C).
fn omni_warp(v: vec3<f32>, e: vec3<f32>, view: ViewUniforms, variant: f32) -> vec3<f32> {
    let c = view.eye_position.xyz;
    let n = view.wall_plane.xyz;
    let sv = dot(n, v) + view.wall_plane.w;
    let se = dot(n, e) + view.wall_plane.w;
    if variant < 1.5 {
        return v - (sv / max(se, 1e-6)) * (e - c);
    }
    // Intersection point (unguarded on purpose: the unstable form kept for comparison).
    let i = e + (se / (se - sv)) * (v - e);
    return c + normalize(i - c) * length(v - c);
}

// Blinn-Phong lighting of a surface point, all vectors in CAVE space.
// `eye` is where the surface is seen from (per view, or per vertex in omnistereo).
fn blinn_phong(
    frame: FrameUniforms,
    albedo: vec3<f32>,
    position: vec3<f32>,
    normal: vec3<f32>,
    eye: vec3<f32>,
    shininess: f32,
    specular_strength: f32,
) -> vec3<f32> {
    let v = normalize(eye - position);
    var diffuse = frame.ambient.rgb;
    var specular = vec3<f32>(0.0);

    let l_sun = -frame.sun_direction.xyz;
    let n_dot_sun = dot(normal, l_sun);
    if n_dot_sun > 0.0 {
        diffuse += n_dot_sun * frame.sun_color.rgb;
        let h = normalize(l_sun + v);
        specular += pow(max(dot(normal, h), 0.0), shininess) * frame.sun_color.rgb;
    }

    let to_light = frame.point_position.xyz - position;
    let dist = length(to_light);
    let l_point = to_light / max(dist, 1e-4);
    let fade = clamp(1.0 - dist / frame.point_position.w, 0.0, 1.0);
    let attenuation = fade * fade;
    let n_dot_point = dot(normal, l_point);
    if n_dot_point > 0.0 && attenuation > 0.0 {
        diffuse += n_dot_point * attenuation * frame.point_color.rgb;
        let h = normalize(l_point + v);
        specular += pow(max(dot(normal, h), 0.0), shininess) * attenuation * frame.point_color.rgb;
    }
    return albedo * diffuse + specular_strength * specular;
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

fn interp2(plan: InterpPlan, v: array<vec2<f32>, 3>) -> vec2<f32> {
    if plan.mode == 0u {
        return v[plan.i];
    }
    if plan.mode == 1u {
        return v[plan.i] + plan.t * (v[plan.j] - v[plan.i]);
    }
    return plan.w.x * v[0] + plan.w.y * v[1] + plan.w.z * v[2];
}
