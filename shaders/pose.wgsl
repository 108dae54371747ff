// The pose pass (paired with src/render/pose_pass.rs; CPU twin: `Rig::deform` in
// src/scene/rig.rs): every deformed vertex morphed, then skinned (or moved by its node),
// written over its place in the scene's vertex buffer before shadows, tessellation and the
// warp read it. Static vertices are not touched.

// Keep in sync with `PoseUniforms` in src/render/pose_pass.rs (tests/gpu_layout.rs checks).
struct PoseUniforms {
    // Deformed vertices, all deformers together.
    vertex_count: u32,
    // Workgroups along x (the dispatch is two-dimensional past the device's limit).
    groups_x: u32,
    pad0: u32,
    pad1: u32,
}

// Keep in sync with `PoseDeformer` in src/render/pose_pass.rs (tests/gpu_layout.rs checks).
struct PoseDeformer {
    // Its first vertex in the scene's vertex buffer.
    first_vertex: u32,
    // Its first entry in `rest`.
    rest_offset: u32,
    // Its first matrix in `matrices` (joints in skin order, or the node's one).
    first_matrix: u32,
    // Influences per vertex (0: the one matrix moves every vertex).
    influences_per_vertex: u32,
    influence_offset: u32,
    target_count: u32,
    // Its first float in `deltas`: per vertex, per target, position, normal and tangent.
    delta_offset: u32,
    first_weight: u32,
}

// Keep in sync with `PoseRestVertex` in src/render/pose_pass.rs (tests/gpu_layout.rs
// checks). Mesh space.
struct PoseRestVertex {
    position: vec3<f32>,
    // Which deformer it belongs to.
    deformer: u32,
    normal: vec4<f32>,
    tangent: vec4<f32>,
}

@group(0) @binding(0) var<uniform> params: PoseUniforms;
@group(0) @binding(1) var<storage, read> deformers: array<PoseDeformer>;
@group(0) @binding(2) var<storage, read> rest: array<PoseRestVertex>;
// (joint of the skin, weight bits).
@group(0) @binding(3) var<storage, read> influences: array<vec2<u32>>;
@group(0) @binding(4) var<storage, read> deltas: array<f32>;
@group(0) @binding(5) var<storage, read> matrices: array<mat4x4<f32>>;
@group(0) @binding(6) var<storage, read> weights: array<f32>;
@group(0) @binding(7) var<storage, read_write> posed: array<f32>;

const POSE_WORKGROUP: u32 = 64u;
// Offsets of the posed attributes in a scene vertex (`GpuVertex`).
const NORMAL_FLOAT: u32 = 3u;
const TANGENT_FLOAT: u32 = 14u;

fn delta(base: u32) -> vec3<f32> {
    return vec3<f32>(deltas[base], deltas[base + 1u], deltas[base + 2u]);
}

// The unit vector along v, or `fallback` where it has no length.
fn unit_or(v: vec3<f32>, fallback: vec3<f32>) -> vec3<f32> {
    let len = length(v);
    if len > 0.0 && len < 3.0e38 {
        return v / len;
    }
    return fallback;
}

@compute @workgroup_size(64)
fn cs_pose(
    @builtin(workgroup_id) group: vec3<u32>,
    @builtin(local_invocation_index) local: u32,
) {
    let index = (group.y * params.groups_x + group.x) * POSE_WORKGROUP + local;
    if index >= params.vertex_count {
        return;
    }
    let r = rest[index];
    let d = deformers[r.deformer];
    let i = index - d.rest_offset;

    // Morph targets first.
    var p = r.position;
    var n = r.normal.xyz;
    var t = r.tangent.xyz;
    for (var k = 0u; k < d.target_count; k++) {
        let w = weights[d.first_weight + k];
        let base = d.delta_offset + (i * d.target_count + k) * 9u;
        p += w * delta(base);
        n += w * delta(base + 3u);
        t += w * delta(base + 6u);
    }

    // Then the skin's blended matrix, or the node's.
    var m = matrices[d.first_matrix];
    if d.influences_per_vertex > 0u {
        m = mat4x4<f32>(vec4<f32>(0.0), vec4<f32>(0.0), vec4<f32>(0.0), vec4<f32>(0.0));
        let first = d.influence_offset + i * d.influences_per_vertex;
        for (var s = 0u; s < d.influences_per_vertex; s++) {
            let influence = influences[first + s];
            m += matrices[d.first_matrix + influence.x] * bitcast<f32>(influence.y);
        }
    }
    let linear = mat3x3<f32>(m[0].xyz, m[1].xyz, m[2].xyz);
    let det = determinant(linear);
    let flip = select(1.0, -1.0, det < 0.0);
    // The inverse transpose up to a positive factor: the cofactor matrix times sign(det).
    let cofactor = mat3x3<f32>(
        cross(linear[1], linear[2]),
        cross(linear[2], linear[0]),
        cross(linear[0], linear[1]),
    );
    let position = (m * vec4<f32>(p, 1.0)).xyz;
    let normal = unit_or(cofactor * n * flip, vec3<f32>(0.0, 1.0, 0.0));
    var tangent = vec4<f32>(0.0);
    let moved = linear * t;
    let len = length(moved);
    if r.tangent.w != 0.0 && len > 0.0 && len < 3.0e38 {
        tangent = vec4<f32>(moved / len, select(1.0, -1.0, r.tangent.w < 0.0) * flip);
    }

    let out = (d.first_vertex + i) * VERTEX_FLOATS;
    posed[out] = position.x;
    posed[out + 1u] = position.y;
    posed[out + 2u] = position.z;
    posed[out + NORMAL_FLOAT] = normal.x;
    posed[out + NORMAL_FLOAT + 1u] = normal.y;
    posed[out + NORMAL_FLOAT + 2u] = normal.z;
    posed[out + TANGENT_FLOAT] = tangent.x;
    posed[out + TANGENT_FLOAT + 1u] = tangent.y;
    posed[out + TANGENT_FLOAT + 2u] = tangent.z;
    posed[out + TANGENT_FLOAT + 3u] = tangent.w;
}
