// Adaptive tessellation before the warp, in compute: conforming edge bisection.
// Paired with src/render/tessellator.rs; the CPU twin is src/tess/ (keep the three in step).
//
// Per view: cs_init culls source triangles and splits each one it keeps SPLIT_LEVELS levels
// deep; beyond that depth, each round cs_prepare sizes the next indirect dispatch and cs_split
// splits every live triangle's edges by the criterion, SPLIT_LEVELS levels deep (what is left
// to split to the other live list, finished triangles and those at the maximum depth to the
// output, so the last round leaves nothing); cs_fallback refines the view again, shallower,
// if the budget ran out (a second cs_init, indirect, with no workgroups otherwise); cs_prefix
// and cs_scatter sort the output by draw (material) and write one indirect draw per draw. No
// CPU read-back anywhere.

// Keep in sync with `TessUniforms` in src/render/tessellator.rs (tests/gpu_layout.rs checks).
struct TessUniforms {
    // 0 none, 1 uniform, 2 edge, 3 sphere, 4 error.
    criterion: u32,
    // The criterion's parameter: levels (uniform) or pixels.
    criterion_value: f32,
    // Split rounds (the maximum depth).
    rounds: u32,
    // 1 if edge lengths count along x only (a vertical wall).
    x_length_only: u32,
    // Target pixels: the wall's or the panorama's.
    target_width: f32,
    target_height: f32,
    // Pixels per metre on the wall, or per radian in a panorama.
    pixels_per_unit: f32,
    // Distance of the centre of projection from the wall plane (1 in a panorama).
    eye_wall_distance: f32,
    near: f32,
    // 1 = back-face culling, 1 = frustum culling.
    backface_cull: u32,
    frustum_cull: u32,
    // The ball the eyes lie on: the head in omnistereo (radius IPD/2), else the eye (0).
    eye_ball_radius: f32,
    eye_ball_centre: vec3<f32>,
    eye_ball_pad: u32,
    source_triangles: u32,
    live_capacity: u32,
    output_capacity: u32,
    draws: u32,
    // 1: cs_init runs one workgroup per cluster of `needy` (this view's from `needy_offset`,
    // `needy_count` of them); 0: one thread per source triangle.
    cluster_mode: u32,
    needy_offset: u32,
    needy_count: u32,
    // Source triangles cs_init may keep: splits leave an output slot for each of them.
    root_bound: u32,
    // 1: one refinement serves this view and its wall's other eye (`partner_view`): an edge
    // splits where either eye's criterion asks, a triangle is culled only where both cull it.
    partner: u32,
    // The partner's distance from the wall plane and near plane.
    partner_eye_wall_distance: f32,
    partner_near: f32,
    partner_pad: u32,
}

const WORKGROUP: u32 = 64u;

// Counter slots (keep in sync with src/render/tessellator.rs).
const C_OUT: u32 = 0u;
const C_BACK: u32 = 1u;
const C_FRUSTUM: u32 = 2u;
const C_OVERFLOW: u32 = 3u;
// 0, or 1 + the maximum depth of the fallback refinement (see cs_fallback).
const C_FALLBACK: u32 = 4u;
// Triangles added by splits: a split happens only if they and every source triangle cs_init
// may keep (tess.root_bound, reserved up front since cs_init splits before all are kept) still
// fit the output, so running out of budget means "less refined", never "missing". A refused
// split can leave a T-junction, so a view whose budget ran out is refined again by cs_fallback.
const C_BUDGET: u32 = 5u;
// Source triangles cs_init kept for splitting, and those of them the criterion left whole (the
// fallback's depth comes from them).
const C_ROOTS: u32 = 6u;
const C_FLAT_ROOTS: u32 = 7u;
const C_DRAWS: u32 = 8u; // per-draw counts from here

// Argument slots: [0..3) split dispatch, [3..6) scatter dispatch, [6..9) fallback refinement,
// then 4 per draw (keep in sync with src/render/tessellator.rs).
const ARGS_FALLBACK: u32 = 6u;
const ARGS_DRAWS: u32 = 9u;

// Deepest a fallback refinement goes: cs_init's own levels, so that it needs no split dispatch
// (keep in sync with tess::FALLBACK_DEPTH_LIMIT; tests/gpu_layout.rs checks).
const FALLBACK_DEPTH_LIMIT: u32 = 12u;

// The refinement this invocation does (set by begin_refinement): the maximum depth, and the
// triangles splits may add.
var<private> depth_cap: u32;
var<private> split_room: u32;

@group(0) @binding(0) var<uniform> frame: FrameUniforms;
@group(0) @binding(1) var<uniform> view: ViewUniforms;
@group(0) @binding(2) var<uniform> tess: TessUniforms;
// The scene's vertices in windows (see `vertex_window` in common.wgsl).
@group(0) @binding(3) var<storage, read> vertices: array<f32>;
@group(0) @binding(4) var<storage, read> indices: array<u32>;
// Per source triangle: draw index, bit 31 set if double-sided.
@group(0) @binding(5) var<storage, read> tri_info: array<u32>;
@group(0) @binding(6) var<storage, read_write> counters: array<atomic<u32>>;
@group(0) @binding(7) var<storage, read_write> output: array<TessEntry>;
@group(0) @binding(8) var<storage, read_write> sorted: array<TessEntry>;
// Clusters to refine, all views one after the other: (first source triangle, count ≤ 64).
@group(0) @binding(9) var<storage, read> needy: array<vec2<u32>>;
// The other eye of a shared refinement (the view itself when there is none).
@group(0) @binding(10) var<uniform> partner_view: ViewUniforms;
@group(0) @binding(11) var<storage, read> vertices_1: array<f32>;
@group(0) @binding(12) var<storage, read> vertices_2: array<f32>;
@group(0) @binding(13) var<storage, read> vertices_3: array<f32>;

// Which eye `project`, the criteria and the culling measure for: the view's (false) or its
// partner's (true).
var<private> second_eye: bool;

fn eye_near() -> f32 {
    return select(tess.near, tess.partner_near, second_eye);
}

fn eye_wall_distance() -> f32 {
    return select(tess.eye_wall_distance, tess.partner_eye_wall_distance, second_eye);
}

@group(1) @binding(0) var<storage, read_write> live_in: array<TessEntry>;
@group(1) @binding(1) var<storage, read_write> live_out: array<TessEntry>;
@group(1) @binding(2) var<storage, read_write> count_in: atomic<u32>;
@group(1) @binding(3) var<storage, read_write> count_out: atomic<u32>;

// Indirect arguments: [0..3) split dispatch, [3..6) scatter dispatch, then 4 per draw.
// Bound only for the passes that write them: an indirect dispatch may not also bind its
// argument buffer as writable storage.
@group(2) @binding(0) var<storage, read_write> args: array<u32>;

fn vertex_position(i: u32) -> vec3<f32> {
    let at = vertex_window(i, arrayLength(&vertices) / VERTEX_FLOATS);
    let b = VERTEX_FLOATS * at.y;
    switch at.x {
        case 0u: {
            return vec3<f32>(vertices[b], vertices[b + 1u], vertices[b + 2u]);
        }
        case 1u: {
            return vec3<f32>(vertices_1[b], vertices_1[b + 1u], vertices_1[b + 2u]);
        }
        case 2u: {
            return vec3<f32>(vertices_2[b], vertices_2[b + 1u], vertices_2[b + 2u]);
        }
        default: {
            return vec3<f32>(vertices_3[b], vertices_3[b + 1u], vertices_3[b + 2u]);
        }
    }
}

fn source_positions(t: u32) -> array<vec3<f32>, 3> {
    return array<vec3<f32>, 3>(
        vertex_position(indices[3u * t]),
        vertex_position(indices[3u * t + 1u]),
        vertex_position(indices[3u * t + 2u]),
    );
}

// Canonical interpolation of a position (mirrors tess::point_position).
fn point_position(p: array<vec3<f32>, 3>, b: vec2<u32>) -> vec3<f32> {
    return interp3(interp_plan(p, b), p);
}

struct Projected {
    clip: vec4<f32>,
    pixel: vec2<f32>,
}

// Mirrors tess::project: CAVE space, omnistereo eye and warp, projection, pixels.
fn project(world: vec3<f32>) -> Projected {
    let p = (frame.cave_from_world * vec4<f32>(world, 1.0)).xyz;
    var clip_from_cave = view.clip_from_cave;
    var omni_head = view.omni_head;
    var centre = view.eye_position.xyz;
    var wall_plane = view.wall_plane;
    if second_eye {
        clip_from_cave = partner_view.clip_from_cave;
        omni_head = partner_view.omni_head;
        centre = partner_view.eye_position.xyz;
        wall_plane = partner_view.wall_plane;
    }
    var warped = p;
    if frame.omni.x > 0.5 {
        let e = omni_eye(p, omni_head, frame.omni);
        warped = omni_warp(p, e, centre, wall_plane, frame.omni.x);
    }
    var out: Projected;
    out.clip = clip_from_cave * vec4<f32>(warped, 1.0);
    out.pixel = clip_to_pixel(out.clip);
    return out;
}

// Pixel coordinates (x right, y down) of a clip-space point (mirrors tess::clip_to_pixel).
fn clip_to_pixel(c: vec4<f32>) -> vec2<f32> {
    return vec2<f32>(
        (c.x / c.w * 0.5 + 0.5) * tess.target_width,
        (0.5 - c.y / c.w * 0.5) * tess.target_height,
    );
}

fn midpoint(a: vec2<u32>, b: vec2<u32>) -> vec2<u32> {
    return (a + b) / 2u;
}

// Panorama view (view.pano_projection > 0): longitude, latitude and distance of a world point from
// its eye (the head, or its omnistereo eye), in the panorama's view space.
fn pano_point(world: vec3<f32>) -> vec3<f32> {
    let p = (frame.cave_from_world * vec4<f32>(world, 1.0)).xyz;
    var eye = view.eye_position.xyz;
    if view.pano_stereo == 2u {
        eye = omni_eye(p, view.omni_head, frame.omni);
    }
    let v = (view.clip_from_cave * vec4<f32>(p - eye, 0.0)).xyz;
    let len = length(v);
    return vec3<f32>(pano_lon_lat(v / max(len, 1e-20)), len);
}

// The split criteria measured in the panorama's pixels. Longitudes are unwrapped along the
// edge, so an edge across the rear meridian is measured as the continuous curve it is, and
// one passing near a pole shows its large curvature. Endpoints in a canonical order (as
// `interp_plan`), so that both triangles sharing an edge decide alike, bit for bit.
fn pano_split_edge(p: array<vec3<f32>, 3>, a_in: vec2<u32>, b_in: vec2<u32>) -> bool {
    let code = tess.criterion;
    let value = tess.criterion_value;
    var a = a_in;
    var b = b_in;
    if sorts_before(point_position(p, b), point_position(p, a)) {
        a = b_in;
        b = a_in;
    }
    let pa = point_position(p, a);
    let pb = point_position(p, b);
    let la = pano_point(pa);
    let lb = pano_point(pb);
    let near = view.pano_near;
    if la.z < near && lb.z < near {
        return false;
    }
    let lon_b = la.x + wrap_angle(lb.x - la.x);
    let ja = pano_pixel(view, la.x, la.y);
    let jb = pano_pixel(view, lon_b, lb.y);
    if code == 2u {
        return length(jb - ja) > value;
    }
    if code == 3u {
        let ca = (frame.cave_from_world * vec4<f32>(pa, 1.0)).xyz;
        let cb = (frame.cave_from_world * vec4<f32>(pb, 1.0)).xyz;
        let centre = pano_point(0.5 * (pa + pb));
        // Angular diameter of the edge's bounding sphere, in pixels per radian.
        return length(cb - ca) / max(centre.z, 1e-6) * tess.pixels_per_unit > value;
    }
    let lm = pano_point(point_position(p, midpoint(a, b)));
    let jm = pano_pixel(view, la.x + wrap_angle(lm.x - la.x), lm.y);
    return length(jm - 0.5 * (ja + jb)) > value;
}

// Which of the triangle's edges (corners c[k] to c[k + 1]) split: mirrors
// tess::criteria::split_edge for each, where the view's criterion asks or its partner's.
fn split_edges(p: array<vec3<f32>, 3>, depth: u32, c: array<vec2<u32>, 3>) -> array<bool, 3> {
    second_eye = false;
    var s = split_edges_for_eye(p, depth, c, array<bool, 3>(false, false, false));
    if tess.partner != 0u && !(s[0] && s[1] && s[2]) {
        second_eye = true;
        s = split_edges_for_eye(p, depth, c, s);
        second_eye = false;
    }
    return s;
}

// The criterion for one eye (`second_eye` says which) on the edges `already` does not split.
// Each corner is projected once for its two edges: the same value either edge would compute,
// so neighbours sharing an edge still agree bit for bit.
fn split_edges_for_eye(
    p: array<vec3<f32>, 3>,
    depth: u32,
    c: array<vec2<u32>, 3>,
    already: array<bool, 3>,
) -> array<bool, 3> {
    var s = already;
    if tess.criterion == 1u {
        let deeper = f32(depth) < tess.criterion_value;
        return array<bool, 3>(deeper || s[0], deeper || s[1], deeper || s[2]);
    }
    if view.pano_projection != 0u {
        for (var k = 0u; k < 3u; k++) {
            if !s[k] {
                s[k] = pano_split_edge(p, c[k], c[(k + 1u) % 3u]);
            }
        }
        return s;
    }
    let corners = array<vec3<f32>, 3>(
        point_position(p, c[0]),
        point_position(p, c[1]),
        point_position(p, c[2]),
    );
    let projected = array<Projected, 3>(
        project(corners[0]),
        project(corners[1]),
        project(corners[2]),
    );
    for (var k = 0u; k < 3u; k++) {
        let k1 = (k + 1u) % 3u;
        if !s[k] {
            s[k] = split_projected_edge(
                p, c[k], c[k1], corners[k], corners[k1], projected[k], projected[k1],
            );
        }
    }
    return s;
}

// The criterion (edge, sphere or error) for one eye on the edge a–b of scene points pa, pb,
// projected ja, jb.
fn split_projected_edge(
    p: array<vec3<f32>, 3>,
    a: vec2<u32>,
    b: vec2<u32>,
    pa: vec3<f32>,
    pb: vec3<f32>,
    ja: Projected,
    jb: Projected,
) -> bool {
    let code = tess.criterion;
    let value = tess.criterion_value;
    let near = eye_near();
    let va = ja.clip.w > near;
    let vb = jb.clip.w > near;
    if !va && !vb {
        return false;
    }
    if va != vb {
        // Crosses behind the viewpoint: refine towards the clip boundary, unless the part in
        // front is wholly beyond one side of the view (mirrors the CPU twin).
        // From the visible end, whichever order the edge comes in (both triangles sharing it
        // must agree bit for bit).
        let seen = select(jb.clip, ja.clip, va);
        let hidden = select(ja.clip, jb.clip, va);
        let t = (near - seen.w) / (hidden.w - seen.w);
        let cut = seen + t * (hidden - seen);
        let m = project(point_position(p, midpoint(a, b))).clip;
        let m_seen = select(seen, m, m.w > near);
        return !outside_all(array(seen, cut, m_seen, seen, seen, seen), near, CULL_MARGIN);
    }
    // Entirely beyond one side of the view: never split (mirrors the CPU twin).
    let mid = project(point_position(p, midpoint(a, b)));
    if outside_same_plane(ja.clip, jb.clip, mid.clip, near) {
        return false;
    }
    if code == 2u {
        let d = jb.pixel - ja.pixel;
        var len = length(d);
        if tess.x_length_only != 0u {
            len = abs(d.x);
        }
        return len > value;
    }
    if code == 3u {
        let ca = (frame.cave_from_world * vec4<f32>(pa, 1.0)).xyz;
        let cb = (frame.cave_from_world * vec4<f32>(pb, 1.0)).xyz;
        let radius = 0.5 * length(cb - ca);
        let centre = project(0.5 * (pa + pb));
        if centre.clip.w <= near {
            return true;
        }
        return 2.0 * radius * eye_wall_distance() / centre.clip.w * tess.pixels_per_unit > value;
    }
    if mid.clip.w <= near {
        return true;
    }
    // The midpoint against the chord's middle (what the cluster bound proves small), then
    // where points are drawn against where their eyes see them (mirrors the CPU twin).
    if length(mid.pixel - 0.5 * (ja.pixel + jb.pixel)) <= value {
        return false;
    }
    return drawn_off_by_more_than(pa, pb, ja.clip, jb.clip, value);
}

// Fractions of the drawn edge on screen where the error criterion compares the drawn point with
// the seen one. Keep in sync with tess::criteria::ERROR_SAMPLES (tests/gpu_layout.rs checks).
const ERROR_SAMPLES = array<f32, 3>(0.25, 0.5, 0.75);

// Whether a point of the edge a quarter, half or three quarters of the way along the drawn
// edge on screen is drawn (clip-space interpolation at s = σ·w0 / ((1 − σ)·w1 + σ·w0)) more
// than `value` pixels from where its eye sees the scene point at s; from the endpoint that
// sorts first, so both triangles sharing the edge agree bit for bit (mirrors
// tess::criteria::drawn_off_by_more_than).
fn drawn_off_by_more_than(pa: vec3<f32>, pb: vec3<f32>, ca: vec4<f32>, cb: vec4<f32>, value: f32) -> bool {
    let swap = sorts_before(pb, pa);
    let p0 = select(pa, pb, swap);
    let p1 = select(pb, pa, swap);
    let c0 = select(ca, cb, swap);
    let c1 = select(cb, ca, swap);
    var samples = ERROR_SAMPLES;
    for (var k = 0u; k < 3u; k++) {
        let sigma = samples[k];
        let s = sigma * c0.w / ((1.0 - sigma) * c1.w + sigma * c0.w);
        let seen = project(p0 + s * (p1 - p0));
        if seen.clip.w <= eye_near() {
            return true;
        }
        if length(seen.pixel - clip_to_pixel(c0 + s * (c1 - c0))) > value {
            return true;
        }
    }
    return false;
}

// Three points all behind the viewpoint or all beyond one frustum side (mirrors
// tess::all_outside).
fn outside_same_plane(a: vec4<f32>, b: vec4<f32>, c: vec4<f32>, near: f32) -> bool {
    if a.w < near && b.w < near && c.w < near {
        return true;
    }
    if a.w <= 0.0 || b.w <= 0.0 || c.w <= 0.0 {
        return false;
    }
    return (a.x > a.w && b.x > b.w && c.x > c.w) || (a.x < -a.w && b.x < -b.w && c.x < -c.w)
        || (a.y > a.w && b.y > b.w && c.y > c.w) || (a.y < -a.w && b.y < -b.w && c.y < -c.w);
}

fn make_entry(source: u32, depth: u32, c0: vec2<u32>, c1: vec2<u32>, c2: vec2<u32>) -> TessEntry {
    var e: TessEntry;
    e.source = source;
    e.depth = depth;
    e.c0 = c0;
    e.c1 = c1;
    e.c2 = c2;
    return e;
}

// A finished triangle goes to the output; dropped (and flagged) if the output is full.
fn emit(e: TessEntry) {
    let slot = atomicAdd(&counters[C_OUT], 1u);
    if slot < tess.output_capacity {
        output[slot] = e;
        let draw = tri_info[e.source] & 0x7fffffffu;
        atomicAdd(&counters[C_DRAWS + draw], 1u);
    } else {
        atomicStore(&counters[C_OVERFLOW], 1u);
    }
}

// Triangles are culled only when their sampled points are beyond a frustum side by this
// fraction of w: warped edges are curves, so the samples can miss a bulge into the view
// (mirrors tess::CULL_MARGIN).
const CULL_MARGIN: f32 = 0.25;

fn outside_all(pts: array<vec4<f32>, 6>, near: f32, margin: f32) -> bool {
    var behind = true;
    var any_behind = false;
    var px = true;
    var nx = true;
    var py = true;
    var ny = true;
    for (var k = 0u; k < 6u; k++) {
        let c = pts[k];
        behind = behind && c.w < near;
        any_behind = any_behind || c.w <= 0.0;
        let m = c.w * (1.0 + margin);
        px = px && c.x > m;
        nx = nx && c.x < -m;
        py = py && c.y > m;
        ny = ny && c.y < -m;
    }
    if behind {
        return true;
    }
    if any_behind {
        return false;
    }
    return px || nx || py || ny;
}

// Whether this is the fallback refinement of a view whose budget ran out (see cs_fallback).
fn in_fallback() -> bool {
    return atomicLoad(&counters[C_FALLBACK]) != 0u;
}

// Sets this invocation's maximum depth and split room: the view's, or the fallback's (a depth
// at which every kept triangle fits the output fully refined, so no split is ever refused:
// the flat roots stay one triangle each, the others become at most 4^depth).
fn begin_refinement() {
    let fallback = atomicLoad(&counters[C_FALLBACK]);
    if fallback != 0u {
        depth_cap = fallback - 1u;
        split_room = tess.output_capacity - min(atomicLoad(&counters[C_ROOTS]), tess.output_capacity);
    } else {
        depth_cap = tess.rounds;
        split_room = tess.output_capacity - min(tess.root_bound, tess.output_capacity);
    }
}

// The deepest depth d <= most at which `roots` triangles, each split into at most 4^d, fit
// `capacity` (mirrors tess::fallback_depth; called with the roots the criterion splits and
// the capacity the others leave).
fn fallback_depth(roots: u32, capacity: u32, most: u32) -> u32 {
    var d = 0u;
    while d < most && 2u * (d + 1u) < 32u && roots <= (capacity >> (2u * (d + 1u))) {
        d += 1u;
    }
    return d;
}

// Largest workgroup count of one dispatch dimension (keep in sync with
// src/render/tessellator.rs).
const MAX_GROUPS_X: u32 = 65535u;

// Whether a source triangle's corners and edge midpoints lie outside the view, with the
// margin, for every eye the refinement serves (mirrors TessRun::cull).
fn outside_view(p: array<vec3<f32>, 3>, v0: vec2<u32>, v1: vec2<u32>, v2: vec2<u32>) -> bool {
    var outside = true;
    for (var eye = 0u; eye <= min(tess.partner, 1u) && outside; eye++) {
        second_eye = eye == 1u;
        let pts = array<vec4<f32>, 6>(
            project(p[0]).clip,
            project(p[1]).clip,
            project(p[2]).clip,
            project(point_position(p, midpoint(v0, v1))).clip,
            project(point_position(p, midpoint(v1, v2))).clip,
            project(point_position(p, midpoint(v2, v0))).clip,
        );
        outside = outside_all(pts, eye_near(), CULL_MARGIN);
    }
    second_eye = false;
    return outside;
}

@compute @workgroup_size(64)
fn cs_init(
    @builtin(workgroup_id) group: vec3<u32>,
    @builtin(local_invocation_index) lane: u32,
) {
    begin_refinement();
    // A thread per source triangle, over a two-dimensional grid of workgroups (a scene of
    // more than 65 535 × 64 triangles needs more than one row).
    var t = (group.y * MAX_GROUPS_X + group.x) * WORKGROUP + lane;
    if tess.cluster_mode != 0u {
        let c = group.y * MAX_GROUPS_X + group.x;
        if c >= tess.needy_count {
            return;
        }
        let cluster = needy[tess.needy_offset + c];
        if lane >= cluster.y {
            return;
        }
        t = cluster.x + lane;
    }
    if t >= tess.source_triangles {
        return;
    }
    if (tri_info[t] & 0x7fffffffu) >= tess.draws {
        // Not part of any draw (the scene pass dropped its draw): nothing to draw it with.
        return;
    }
    let p = source_positions(t);
    let double_sided = (tri_info[t] & 0x80000000u) != 0u;
    if tess.backface_cull != 0u && !double_sided {
        let a = (frame.cave_from_world * vec4<f32>(p[0], 1.0)).xyz;
        let b = (frame.cave_from_world * vec4<f32>(p[1], 1.0)).xyz;
        let c = (frame.cave_from_world * vec4<f32>(p[2], 1.0)).xyz;
        let n = cross(b - a, c - a);
        let len = length(n);
        if len > 0.0 && dot(n, tess.eye_ball_centre - a) / len < -(tess.eye_ball_radius + 1e-4) {
            atomicAdd(&counters[C_BACK], 1u);
            return;
        }
    }
    let v0 = vec2<u32>(0u, 0u);
    let v1 = vec2<u32>(BARY_ONE, 0u);
    let v2 = vec2<u32>(0u, BARY_ONE);
    if tess.frustum_cull != 0u && outside_view(p, v0, v1, v2) {
        atomicAdd(&counters[C_FRUSTUM], 1u);
        return;
    }
    let e = make_entry(t, 0u, v0, v1, v2);
    if tess.criterion == 0u || tess.rounds == 0u {
        emit(e);
        return;
    }
    if !in_fallback() {
        atomicAdd(&counters[C_ROOTS], 1u);
    }
    // Split here, SPLIT_LEVELS levels deep, rather than in a dispatch of its own: what is
    // left goes to the live list (list A) for the split dispatches beyond that depth.
    split_tree(e);
}

// One thread: size the split dispatch (args 0..3) from the live count, and reset the next
// list.
@compute @workgroup_size(1)
fn cs_prepare() {
    let n = min(atomicLoad(&count_in), tess.live_capacity);
    let groups = (n + WORKGROUP - 1u) / WORKGROUP;
    args[0] = groups;
    args[1] = 1u;
    args[2] = 1u;
    atomicStore(&count_out, 0u);
}

// Levels one invocation splits (cs_init for each source triangle it keeps, then cs_split for
// each live triangle): its triangle's children are tested and split again in the same
// invocation, down to this many levels, so `rounds` levels take cs_init and then
// ceil(rounds / SPLIT_LEVELS) - 1 split dispatches: none at the default depth of 12 (each
// dispatch and its preparation cost a fixed time, about 50 µs on a software rasteriser).
// Keep in sync with src/render/tessellator.rs.
const SPLIT_LEVELS: u32 = 12u;
// Depth-first, each triangle popped pushes at most 4: 3 more entries per level.
const SPLIT_STACK: u32 = 3u * SPLIT_LEVELS + 1u;

var<private> kids: array<TessEntry, 4>;

// How much shorter (squared) the quadrilateral's other diagonal must be to be cut instead:
// far above rounding, so that GPU and CPU agree on ties. Keep in sync with
// tess::DIAGONAL_MARGIN.
const DIAGONAL_MARGIN: f32 = 1.0 / 1024.0;

// Whether a two-edge split's quadrilateral a, m0, m1, cc is cut along a–m1 rather than m0–cc:
// the shorter in the scene, so that the children stay well shaped (mirrors
// tess::cut_from_corner).
fn cut_from_corner(p: array<vec3<f32>, 3>, a: vec2<u32>, m0: vec2<u32>, m1: vec2<u32>, cc: vec2<u32>) -> bool {
    let corner = point_position(p, a) - point_position(p, m1);
    let default_cut = point_position(p, m0) - point_position(p, cc);
    return dot(corner, corner) < dot(default_cut, default_cut) * (1.0 - DIAGONAL_MARGIN);
}

// Splits `e` once by the criterion into `kids` and returns how many there are: 0 when no
// edge splits, REFUSED when the budget refuses (then `e` is finished as it is and the overflow
// flagged).
const REFUSED: u32 = 0xffffffffu;

fn split_once(e: TessEntry) -> u32 {
    let p = source_positions(e.source);
    let c = array<vec2<u32>, 3>(e.c0, e.c1, e.c2);
    let s = split_edges(p, e.depth, c);
    var n_split = 0u;
    for (var k = 0u; k < 3u; k++) {
        if s[k] {
            n_split += 1u;
        }
    }
    if n_split == 0u {
        return 0u;
    }
    let m = array<vec2<u32>, 3>(midpoint(c[0], c[1]), midpoint(c[1], c[2]), midpoint(c[2], c[0]));
    let d = e.depth + 1u;
    var count = 0u;
    if n_split == 3u {
        kids[0] = make_entry(e.source, d, c[0], m[0], m[2]);
        kids[1] = make_entry(e.source, d, m[0], c[1], m[1]);
        kids[2] = make_entry(e.source, d, m[2], m[1], c[2]);
        kids[3] = make_entry(e.source, d, m[0], m[1], m[2]);
        count = 4u;
    } else {
        // Rotate so the split edges start at edge r (mirrors tess::children).
        var r = 3u;
        for (var k = 0u; k < 3u; k++) {
            let ok = select(s[k] && s[(k + 1u) % 3u], s[k], n_split == 1u);
            if r == 3u && ok {
                r = k;
            }
        }
        let a = c[r];
        let b = c[(r + 1u) % 3u];
        let cc = c[(r + 2u) % 3u];
        let m0 = m[r];
        let m1 = m[(r + 1u) % 3u];
        if n_split == 1u {
            kids[0] = make_entry(e.source, d, a, m0, cc);
            kids[1] = make_entry(e.source, d, m0, b, cc);
            count = 2u;
        } else if cut_from_corner(p, a, m0, m1, cc) {
            kids[0] = make_entry(e.source, d, a, m0, m1);
            kids[1] = make_entry(e.source, d, m0, b, m1);
            kids[2] = make_entry(e.source, d, a, m1, cc);
            count = 3u;
        } else {
            kids[0] = make_entry(e.source, d, a, m0, cc);
            kids[1] = make_entry(e.source, d, m0, b, m1);
            kids[2] = make_entry(e.source, d, m0, m1, cc);
            count = 3u;
        }
    }
    let extra = count - 1u;
    if atomicAdd(&counters[C_BUDGET], extra) + extra > split_room {
        // Budget: draw this triangle unrefined and report it.
        atomicSub(&counters[C_BUDGET], extra);
        atomicStore(&counters[C_OVERFLOW], 1u);
        return REFUSED;
    }
    return count;
}

// Leaves a triangle for the next split dispatch.
fn push_live(e: TessEntry) {
    let slot = atomicAdd(&count_out, 1u);
    if slot < tess.live_capacity {
        live_out[slot] = e;
        return;
    }
    // Cannot happen while live capacity >= output capacity (the budget bounds both); kept so
    // that a smaller live list degrades like the budget: the triangle is drawn unrefined.
    atomicStore(&counters[C_OVERFLOW], 1u);
    emit(e);
}

@compute @workgroup_size(64)
fn cs_split(@builtin(global_invocation_id) id: vec3<u32>) {
    let n = min(atomicLoad(&count_in), tess.live_capacity);
    if id.x >= n {
        return;
    }
    begin_refinement();
    split_tree(live_in[id.x]);
}

// Splits `root` and its descendants SPLIT_LEVELS levels down: finished triangles and those at
// the maximum depth to the output, the rest to the live list for the next split dispatch.
fn split_tree(root: TessEntry) {
    // Depth first over the triangle's descendants, SPLIT_LEVELS levels down.
    var stack: array<TessEntry, SPLIT_STACK>;
    var level: array<u32, SPLIT_STACK>;
    stack[0] = root;
    level[0] = 0u;
    var top = 1u;
    while top > 0u {
        top -= 1u;
        let e = stack[top];
        let l = level[top];
        if e.depth >= depth_cap {
            // At the maximum depth: finished here, so the last split dispatch leaves nothing
            // for another dispatch to flush.
            emit(e);
            continue;
        }
        if l == SPLIT_LEVELS {
            push_live(e);
            continue;
        }
        let count = split_once(e);
        if count == 0u || count == REFUSED {
            if count == 0u && e.depth == 0u && !in_fallback() {
                // Finished at depth 0 by the criterion alone: one triangle at any depth.
                atomicAdd(&counters[C_FLAT_ROOTS], 1u);
            }
            emit(e);
            continue;
        }
        for (var k = 0u; k < count; k++) {
            stack[top] = kids[k];
            level[top] = l + 1u;
            top += 1u;
        }
    }
}

// One thread, after the split rounds: if the budget refused a split (or the live list ran
// out), the view's output may hold T-junctions, since a refused triangle keeps an edge whole
// that its neighbour halved. Then the view is refined again from scratch (args ARGS_FALLBACK
// size a second cs_init), with the same criterion but a maximum depth at which every kept
// triangle fits fully refined: no split is refused, neighbours agree on every edge, and the
// picture is conforming, only less refined. Otherwise the second cs_init has no workgroups.
@compute @workgroup_size(1)
fn cs_fallback() {
    args[ARGS_FALLBACK] = 0u;
    args[ARGS_FALLBACK + 1u] = 1u;
    args[ARGS_FALLBACK + 2u] = 1u;
    if atomicLoad(&counters[C_OVERFLOW]) == 0u {
        return;
    }
    let most = min(tess.rounds, FALLBACK_DEPTH_LIMIT);
    let roots = atomicLoad(&counters[C_ROOTS]);
    let flat = min(atomicLoad(&counters[C_FLAT_ROOTS]), roots);
    let depth = fallback_depth(roots - flat, tess.output_capacity - min(flat, tess.output_capacity), most);
    atomicStore(&counters[C_OUT], 0u);
    atomicStore(&counters[C_BACK], 0u);
    atomicStore(&counters[C_FRUSTUM], 0u);
    atomicStore(&counters[C_BUDGET], 0u);
    for (var d = 0u; d < tess.draws; d++) {
        atomicStore(&counters[C_DRAWS + d], 0u);
    }
    atomicStore(&counters[C_FALLBACK], depth + 1u);
    if tess.cluster_mode != 0u {
        let n = tess.needy_count;
        args[ARGS_FALLBACK] = min(n, MAX_GROUPS_X);
        args[ARGS_FALLBACK + 1u] = (n + MAX_GROUPS_X - 1u) / MAX_GROUPS_X;
    } else {
        let groups = (tess.source_triangles + WORKGROUP - 1u) / WORKGROUP;
        args[ARGS_FALLBACK] = min(groups, MAX_GROUPS_X);
        args[ARGS_FALLBACK + 1u] = (groups + MAX_GROUPS_X - 1u) / MAX_GROUPS_X;
    }
}

// One thread: per-draw offsets (prefix sum), indirect draw arguments, and the scatter
// dispatch size. Draw counts become cursors for cs_scatter.
@compute @workgroup_size(1)
fn cs_prefix() {
    var offset = 0u;
    for (var d = 0u; d < tess.draws; d++) {
        let n = atomicLoad(&counters[C_DRAWS + d]);
        let a = ARGS_DRAWS + 4u * d;
        args[a] = 3u * n;
        args[a + 1u] = 1u;
        args[a + 2u] = 3u * offset;
        args[a + 3u] = 0u;
        atomicStore(&counters[C_DRAWS + d], offset);
        offset += n;
    }
    let total = min(atomicLoad(&counters[C_OUT]), tess.output_capacity);
    args[3] = (total + WORKGROUP - 1u) / WORKGROUP;
    args[4] = 1u;
    args[5] = 1u;
}

@compute @workgroup_size(64)
fn cs_scatter(@builtin(global_invocation_id) id: vec3<u32>) {
    let total = min(atomicLoad(&counters[C_OUT]), tess.output_capacity);
    if id.x >= total {
        return;
    }
    let e = output[id.x];
    let draw = tri_info[e.source] & 0x7fffffffu;
    let slot = atomicAdd(&counters[C_DRAWS + draw], 1u);
    sorted[slot] = e;
}
