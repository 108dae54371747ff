// Scene geometry: physically based (shaders/pbr.wgsl), textured triangles for one wall and eye.
// Paired with src/render/scene_pass.rs; shared structs come from common.wgsl.

// Keep in sync with `MaterialUniforms` in src/render/uniforms.rs (tests/gpu_layout.rs checks).
struct MaterialUniforms {
    // Linear RGBA multiplier.
    base_color: vec4<f32>,
    // Emitted light (linear).
    emissive: vec3<f32>,
    // Bit k: texture slot k is bound; bit 8 + k: slot k reads TEXCOORD_1. Slots: 0 base
    // colour, 1 metallic-roughness, 2 normal, 3 occlusion, 4 emissive.
    texture_flags: u32,
    metallic: f32,
    roughness: f32,
    normal_scale: f32,
    occlusion_strength: f32,
    // Alpha cutoff (< 0: no mask).
    alpha_cutoff: f32,
    // 1: alpha-blended (the colour keeps its alpha); 0: opaque.
    alpha_blend: u32,
    // 1 for unlit materials (KHR_materials_unlit).
    unlit: u32,
    material_pad: u32,
    // KHR_texture_transform of slot k: rows 2k and 2k + 1 map (u, v, 1) to its coordinates.
    uv_transforms: array<vec4<f32>, 10>,
}

@group(0) @binding(0) var<uniform> frame: FrameUniforms;
@group(0) @binding(1) var<uniform> view: ViewUniforms;
@group(1) @binding(0) var<uniform> material: MaterialUniforms;
@group(1) @binding(1) var base_color_texture: texture_2d<f32>;
@group(1) @binding(2) var metallic_roughness_texture: texture_2d<f32>;
@group(1) @binding(3) var normal_texture: texture_2d<f32>;
@group(1) @binding(4) var occlusion_texture: texture_2d<f32>;
@group(1) @binding(5) var emissive_texture: texture_2d<f32>;
@group(1) @binding(6) var base_color_sampler: sampler;
@group(1) @binding(7) var metallic_roughness_sampler: sampler;
@group(1) @binding(8) var normal_sampler: sampler;
@group(1) @binding(9) var occlusion_sampler: sampler;
@group(1) @binding(10) var emissive_sampler: sampler;
// The lights' shadow maps (src/render/shadow_pass.rs), one layer per directional or spot
// light, six per point light.
@group(3) @binding(0) var shadow_maps: texture_depth_2d_array;
@group(3) @binding(1) var shadow_sampler: sampler_comparison;
// Per shadow-map layer, tile by tile (SHADOW_TILE texels a side, row by row): the least and
// greatest depth the 3×3 filter can read from a corner in the tile (shaders/shadow.wgsl).
@group(3) @binding(2) var<storage, read> shadow_ranges: array<vec2<f32>>;
// Keep in sync with `SHADOW_TILE` in src/render/shadow_pass.rs and shaders/shadow.wgsl.
const SHADOW_TILE: u32 = 4u;

// Keep in sync with `GpuVertex` in src/render/scene_pass.rs.
struct VertexInput {
    @location(0) position: vec3<f32>,
    @location(1) normal: vec3<f32>,
    @location(2) uv: vec2<f32>,
    @location(3) uv1: vec2<f32>,
    @location(4) color: vec4<f32>,
    @location(5) tangent: vec4<f32>,
}

// Everything a vertex carries besides its position (world space as read, CAVE space once
// transformed).
struct Attributes {
    normal: vec3<f32>,
    // xy: TEXCOORD_0, zw: TEXCOORD_1.
    uvs: vec4<f32>,
    color: vec4<f32>,
    // xyz: tangent; w: the bitangent's sign (0 everywhere: no tangent).
    tangent: vec4<f32>,
}

struct VertexOutput {
    // Invariant: a vertex shared by triangles drawn with different pipeline variants must land
    // on the same position, or tessellated neighbours could show cracks.
    @invariant @builtin(position) clip: vec4<f32>,
    @location(0) cave_position: vec3<f32>,
    @location(1) normal: vec3<f32>,
    @location(2) uvs: vec4<f32>,
    @location(3) color: vec4<f32>,
    @location(4) tangent: vec4<f32>,
    // Omnistereo: the vertex's own eye, for the specular term, interpolated across the
    // triangle (see fs_main for how far that can be from the fragment's own eye). At the
    // centroid: where MSAA covers a pixel only partly, its centre can lie outside the
    // triangle, and an eye extrapolated there could leave the eyes' circle.
    @location(5) @interpolate(perspective, centroid) shading_eye: vec3<f32>,
}

// Tessellated geometry (src/render/tessellator.rs): the sorted output triangles and the
// scene's vertex and index buffers, read as storage (the vertices in windows, see
// `vertex_window` in common.wgsl).
@group(2) @binding(0) var<storage, read> tess_entries: array<TessEntry>;
@group(2) @binding(1) var<storage, read> tess_vertices: array<f32>;
@group(2) @binding(2) var<storage, read> tess_indices: array<u32>;
@group(2) @binding(3) var<storage, read> tess_vertices_1: array<f32>;
@group(2) @binding(4) var<storage, read> tess_vertices_2: array<f32>;
@group(2) @binding(5) var<storage, read> tess_vertices_3: array<f32>;

// Attributes moved from world into CAVE space.
fn cave_attributes(a: Attributes) -> Attributes {
    var out = a;
    out.normal = (frame.normal_from_world * vec4<f32>(a.normal, 0.0)).xyz;
    out.tangent = vec4<f32>((frame.cave_from_world * vec4<f32>(a.tangent.xyz, 0.0)).xyz,
        a.tangent.w);
    return out;
}

// Everything after fetching a vertex: CAVE space, omnistereo warp, projection.
fn transform_vertex(position: vec3<f32>, a: Attributes) -> VertexOutput {
    let p = (frame.cave_from_world * vec4<f32>(position, 1.0)).xyz;
    var projected = p;
    var shading_eye = view.eye_position.xyz;
    if frame.omni.x > 0.5 {
        // Omnistereo: the warp that makes the projection from C draw this vertex where its
        // own eye sees it.
        let e = omni_eye(p, view.omni_head, frame.omni);
        projected = omni_warp(p, e, view.eye_position.xyz, view.wall_plane, frame.omni.x);
        shading_eye = e;
    }
    let c = cave_attributes(a);
    var out: VertexOutput;
    out.clip = view.clip_from_cave * vec4<f32>(projected, 1.0);
    out.cave_position = p;
    out.normal = c.normal;
    out.uvs = c.uvs;
    out.color = c.color;
    out.tangent = c.tangent;
    out.shading_eye = shading_eye;
    return out;
}

@vertex
fn vs_main(in: VertexInput) -> VertexOutput {
    var a: Attributes;
    a.normal = in.normal;
    a.uvs = vec4<f32>(in.uv, in.uv1);
    a.color = in.color;
    a.tangent = in.tangent;
    return transform_vertex(in.position, a);
}

fn tess_vec3(vertex: u32, offset: u32) -> vec3<f32> {
    return tess_vec4(vertex, offset).xyz;
}

// The four floats at `offset` of source vertex `vertex` (at most 14: the tangent ends the
// vertex), from its window.
fn tess_vec4(vertex: u32, offset: u32) -> vec4<f32> {
    let at = vertex_window(vertex, arrayLength(&tess_vertices) / VERTEX_FLOATS);
    let b = VERTEX_FLOATS * at.y + offset;
    switch at.x {
        case 0u: {
            return vec4<f32>(tess_vertices[b], tess_vertices[b + 1u], tess_vertices[b + 2u],
                tess_vertices[b + 3u]);
        }
        case 1u: {
            return vec4<f32>(tess_vertices_1[b], tess_vertices_1[b + 1u],
                tess_vertices_1[b + 2u], tess_vertices_1[b + 3u]);
        }
        case 2u: {
            return vec4<f32>(tess_vertices_2[b], tess_vertices_2[b + 1u],
                tess_vertices_2[b + 2u], tess_vertices_2[b + 3u]);
        }
        default: {
            return vec4<f32>(tess_vertices_3[b], tess_vertices_3[b + 1u],
                tess_vertices_3[b + 2u], tess_vertices_3[b + 3u]);
        }
    }
}

// One corner of a tessellated triangle (world space), interpolated canonically from its
// source triangle so that neighbours produce bit-identical points (watertight).
struct Corner {
    position: vec3<f32>,
    attributes: Attributes,
}

fn tess_corner(e: TessEntry, k: u32) -> Corner {
    let corners = array<vec2<u32>, 3>(e.c0, e.c1, e.c2);
    let b = corners[k];
    let i = array<u32, 3>(
        tess_indices[3u * e.source], tess_indices[3u * e.source + 1u],
        tess_indices[3u * e.source + 2u],
    );
    let p = array<vec3<f32>, 3>(tess_vec3(i[0], 0u), tess_vec3(i[1], 0u), tess_vec3(i[2], 0u));
    let plan = interp_plan(p, b);
    var c: Corner;
    c.position = interp3(plan, p);
    // Attributes of only the vertices the plan uses (a corner: one, an edge point: two), as
    // interp3/interp4 would combine them: the same arithmetic, a third of the loads.
    // (The normal as the first three of four floats: the same arithmetic per component.)
    c.attributes.normal = plan_vec4(plan, i, 3u).xyz;
    c.attributes.uvs = plan_vec4(plan, i, 6u);
    c.attributes.color = plan_vec4(plan, i, 10u);
    c.attributes.tangent = plan_vec4(plan, i, 14u);
    return c;
}

// The four floats at `offset` of source vertices `i`, interpolated by `plan` (mirrors
// interp3 and interp4).
fn plan_vec4(plan: InterpPlan, i: array<u32, 3>, offset: u32) -> vec4<f32> {
    if plan.mode == 0u {
        return tess_vec4(i[plan.i], offset);
    }
    if plan.mode == 1u {
        let a = tess_vec4(i[plan.i], offset);
        return a + plan.t * (tess_vec4(i[plan.j], offset) - a);
    }
    return plan.w.x * tess_vec4(i[0], offset) + plan.w.y * tess_vec4(i[1], offset)
        + plan.w.z * tess_vec4(i[2], offset);
}

@vertex
fn vs_tess(@builtin(vertex_index) vertex_index: u32) -> VertexOutput {
    let c = tess_corner(tess_entries[vertex_index / 3u], vertex_index % 3u);
    return transform_vertex(c.position, c.attributes);
}

// ---- Panorama, geometric route (VR'14), paired with src/render/panorama.rs ----
//
// Every vertex is projected with the map itself (pano_map) into the unit cube; depth is the
// distance from the eye between the two clipping spheres. A triangle across the map's
// discontinuities (the rear meridian, a pole) cannot be drawn that way: the pre-clip finds
// those (they are few and small after tessellation) and draws each over the band of latitudes
// it can cover, where every fragment casts its own ray at the triangle and keeps only the
// pixels whose direction meets it. That is the exact pre-clipped shape for any projection of
// the family, pieces at the left and right edges and around the pole included.

// Single-sided triangles facing away from the head are dropped (the pipeline's rasteriser
// cannot cull: a pre-clipped triangle's band has no meaningful winding).
override PANO_CULL_BACK: bool = true;

struct PanoOutput {
    @builtin(position) clip: vec4<f32>,
    // The triangle itself (CAVE space), for every fragment's own ray, and its corners'
    // attributes (CAVE space): nothing is interpolated. p0.w: 1 for a pre-clipped triangle
    // (drawn over a band of latitudes).
    @location(0) @interpolate(flat) p0: vec4<f32>,
    @location(1) @interpolate(flat) p1: vec3<f32>,
    @location(2) @interpolate(flat) p2: vec3<f32>,
    @location(3) @interpolate(flat) n0: vec3<f32>,
    @location(4) @interpolate(flat) n1: vec3<f32>,
    @location(5) @interpolate(flat) n2: vec3<f32>,
    @location(6) @interpolate(flat) uv0: vec4<f32>,
    @location(7) @interpolate(flat) uv1: vec4<f32>,
    @location(8) @interpolate(flat) uv2: vec4<f32>,
    @location(9) @interpolate(flat) color0: vec4<f32>,
    @location(10) @interpolate(flat) color1: vec4<f32>,
    @location(11) @interpolate(flat) color2: vec4<f32>,
    @location(12) @interpolate(flat) tangent0: vec4<f32>,
    @location(13) @interpolate(flat) tangent1: vec4<f32>,
    @location(14) @interpolate(flat) tangent2: vec4<f32>,
}

// The eye a CAVE-space point is seen from: the head, or in omnistereo its own eye.
fn pano_eye(p: vec3<f32>) -> vec3<f32> {
    if view.pano_stereo == 2u {
        return omni_eye(p, view.omni_head, frame.omni);
    }
    return view.eye_position.xyz;
}

// View-space direction of a CAVE-space vector (the view only turns about the vertical).
fn pano_view_dir(v: vec3<f32>) -> vec3<f32> {
    return (view.clip_from_cave * vec4<f32>(v, 0.0)).xyz;
}

// Normalised depth of a distance between the clipping spheres.
fn pano_depth(distance: f32) -> f32 {
    return (distance - view.pano_near) / (view.pano_far - view.pano_near);
}

// VR'14's volume stereo: the horizontal parallax of a point at normalised depth `depth`.
fn volume_parallax(depth: f32) -> f32 {
    if view.pano_stereo != 1u {
        return 0.0;
    }
    let z = 2.0 * depth - 1.0;
    let d = view.volume_distance;
    return view.volume_half_ioid * (1.0 - (view.volume_zero_parallax + d) / (z + d));
}

// Largest distance (pixels) between an edge's image and its chord (sampled) for a
// triangle to be drawn as its grown chord triangle; beyond it (too little tessellation, the
// neighbourhood of a pole) the midpoint no longer tells how far the curve strays, and the
// triangle is drawn over the band of latitudes it can cover.
const MAX_STRAY_PX: f32 = 2.0;

fn cross2(a: vec2<f32>, b: vec2<f32>) -> f32 {
    return a.x * b.y - a.y * b.x;
}

// Unit normal of edge a→b pointing out of a triangle of signed area `area`.
fn outward(a: vec2<f32>, b: vec2<f32>, area: f32) -> vec2<f32> {
    let d = normalize(b - a);
    let n = vec2<f32>(d.y, -d.x);
    return select(-n, n, area > 0.0);
}

// Image position (clip space, w = 1) of a longitude, latitude and distance.
fn pano_clip(lon: f32, lat: f32, distance: f32) -> vec4<f32> {
    let code = view.pano_projection - 1u;
    var ndc = (pano_map(code, lon, lat) - view.pano_window.xy) / view.pano_window.zw;
    let depth = pano_depth(distance);
    ndc.x += volume_parallax(depth);
    // The rasteriser must not clip along chords at the clipping spheres: every fragment
    // writes its exact depth and is discarded outside them.
    return vec4<f32>(ndc, clamp(depth, 0.0, 1.0), 1.0);
}

// Whether the vertical ray from the origin (+y if `up`) meets triangle a, b, c.
fn meets_vertical(a: vec3<f32>, b: vec3<f32>, c: vec3<f32>, up: bool) -> bool {
    // The ray meets the triangle where its projection onto the horizontal plane contains the
    // origin and the plane lies on the ray's side.
    let s0 = a.x * b.z - a.z * b.x;
    let s1 = b.x * c.z - b.z * c.x;
    let s2 = c.x * a.z - c.z * a.x;
    let inside = (s0 >= 0.0 && s1 >= 0.0 && s2 >= 0.0) || (s0 <= 0.0 && s1 <= 0.0 && s2 <= 0.0);
    if !inside {
        return false;
    }
    let sum = s0 + s1 + s2;
    if abs(sum) < 1e-20 {
        // Edge-on to the vertical: the ray runs along it if any corner is on its side.
        return select((min(a.y, min(b.y, c.y)) < 0.0), (max(a.y, max(b.y, c.y)) > 0.0), up);
    }
    // Height of the plane over the origin: barycentric mix of the corners' heights.
    let y = (s1 * a.y + s2 * b.y + s0 * c.y) / sum;
    return select((y < 0.0), (y > 0.0), up);
}

// Sine of the highest latitude on the arc between unit directions a and b (the arc of a
// straight edge bulges towards the pole); `lowest` for the other way.
fn arc_sin_lat(a: vec3<f32>, b: vec3<f32>, lowest: bool) -> f32 {
    let half_cos = sqrt(max(0.5 * (1.0 + dot(a, b)), 1e-6));
    if lowest {
        let m = min(a.y, b.y);
        return select(m, m / half_cos, (m < 0.0));
    }
    let m = max(a.y, b.y);
    return select(m, m / half_cos, (m > 0.0));
}

// The band of image rows (NDC y, low and high) that latitudes lo..hi can reach at any
// longitude.
fn pano_band(lo: f32, hi: f32) -> vec2<f32> {
    let code = view.pano_projection - 1u;
    var y = vec2<f32>(lo, hi);
    if code == 2u {
        // Hammer: |y| grows from the central meridian to the rear one.
        let a = pano_hammer(0.0, lo).y;
        let b = pano_hammer(PI, lo).y;
        let c = pano_hammer(0.0, hi).y;
        let d = pano_hammer(PI, hi).y;
        y = vec2<f32>(min(a, b), max(c, d));
    }
    return (y - view.pano_window.y) / view.pano_window.w;
}

@vertex
fn vs_pano(@builtin(vertex_index) vertex_index: u32) -> PanoOutput {
    let entry = tess_entries[vertex_index / 3u];
    let k = vertex_index % 3u;
    let corners = array<Corner, 3>(
        tess_corner(entry, 0u), tess_corner(entry, 1u), tess_corner(entry, 2u),
    );
    var p: array<vec3<f32>, 3>;
    var eyes: array<vec3<f32>, 3>;
    var dirs: array<vec3<f32>, 3>;
    var dist: array<f32, 3>;
    var ll: array<vec2<f32>, 3>;
    let head = view.eye_position.xyz;
    var attrs: array<Attributes, 3>;
    for (var i = 0u; i < 3u; i++) {
        p[i] = (frame.cave_from_world * vec4<f32>(corners[i].position, 1.0)).xyz;
        attrs[i] = cave_attributes(corners[i].attributes);
        eyes[i] = pano_eye(p[i]);
        let v = pano_view_dir(p[i] - eyes[i]);
        dist[i] = length(v);
        dirs[i] = v / max(dist[i], 1e-20);
        ll[i] = pano_lon_lat(dirs[i]);
    }
    var out: PanoOutput;
    out.p0 = vec4<f32>(p[0], 0.0);
    out.p1 = p[1];
    out.p2 = p[2];
    out.n0 = attrs[0].normal;
    out.n1 = attrs[1].normal;
    out.n2 = attrs[2].normal;
    out.uv0 = attrs[0].uvs;
    out.uv1 = attrs[1].uvs;
    out.uv2 = attrs[2].uvs;
    out.color0 = attrs[0].color;
    out.color1 = attrs[1].color;
    out.color2 = attrs[2].color;
    out.tangent0 = attrs[0].tangent;
    out.tangent1 = attrs[1].tangent;
    out.tangent2 = attrs[2].tangent;

    let geometric = cross(p[1] - p[0], p[2] - p[0]);
    let g_len = length(geometric);
    if PANO_CULL_BACK && g_len > 0.0
        && dot(geometric, head - p[0]) / g_len < -(abs(view.omni_head.w) + 1e-4) {
        // Facing away: a point outside the image (clipped).
        out.clip = vec4<f32>(2.0, 2.0, 2.0, 1.0);
        return out;
    }

    // Longitudes unwrapped along the edges from corner 0.
    let d01 = wrap_angle(ll[1].x - ll[0].x);
    let d12 = wrap_angle(ll[2].x - ll[1].x);
    let d20 = wrap_angle(ll[0].x - ll[2].x);
    let lon = array<f32, 3>(ll[0].x, ll[0].x + d01, ll[0].x + d01 + d12);
    // Head-relative view-space corners for the pole test.
    let a = pano_view_dir(p[0] - head);
    let b = pano_view_dir(p[1] - head);
    let c = pano_view_dir(p[2] - head);
    let north = meets_vertical(a, b, c, true);
    let south = meets_vertical(a, b, c, false);
    var near_pole = false;
    for (var i = 0u; i < 3u; i++) {
        near_pole = near_pole || length(dirs[i].xz) < 1e-4;
    }
    let rear = max(lon[0], max(lon[1], lon[2])) > PI || min(lon[0], min(lon[1], lon[2])) < -PI;
    let wide = max(abs(d01), max(abs(d12), abs(d20))) > 0.75 * PI;
    // How far each edge's image strays from its chord (at its midpoint).
    var stray = 0.0;
    if !(north || south || near_pole || rear || wide) {
        let lat = array<f32, 3>(ll[0].y, ll[1].y, ll[2].y);
        for (var i = 0u; i < 3u; i++) {
            let j = (i + 1u) % 3u;
            let a = pano_pixel(view, lon[i], lat[i]);
            let b = pano_pixel(view, lon[j], lat[j]);
            // At a quarter, half and three quarters of the edge: near a pole the curve is
            // far from symmetric about its midpoint.
            for (var q = 1u; q < 4u; q++) {
                let t = f32(q) * 0.25;
                let m = mix(p[i], p[j], t);
                let v = pano_view_dir(m - pano_eye(m));
                let lm = pano_lon_lat(v / max(length(v), 1e-20));
                let curve = pano_pixel(view, lon[i] + wrap_angle(lm.x - lon[i]), lm.y);
                stray = max(stray, length(curve - mix(a, b, t)));
            }
        }
    }
    if !(north || south || near_pole || rear || wide || stray > MAX_STRAY_PX) {
        // Drawn by its vertices, the chord triangle grown by how far the edges stray and a
        // pixel's reach: it holds every pixel centre of the curved footprint, and the
        // fragments keep exactly those whose rays meet the triangle.
        var clip = array<vec4<f32>, 3>(
            pano_clip(lon[0], ll[0].y, dist[0]),
            pano_clip(lon[1], ll[1].y, dist[1]),
            pano_clip(lon[2], ll[2].y, dist[2]),
        );
        out.clip = clip[k];
        let half_size = 0.5 * view.pano_size;
        let s = array<vec2<f32>, 3>(
            clip[0].xy * half_size, clip[1].xy * half_size, clip[2].xy * half_size,
        );
        let area = cross2(s[1] - s[0], s[2] - s[0]);
        if abs(area) > 1e-6 {
            // Half as much again as the largest sampled stray: the curve between samples.
            let grow = 1.5 * stray + 0.75;
            let prev = s[(k + 2u) % 3u];
            let next = s[(k + 1u) % 3u];
            // Outward normals of the two edges at corner k (image y up, area's sign gives
            // the winding).
            let na = outward(prev, s[k], area);
            let nb = outward(s[k], next, area);
            // Uncapped but for exact slivers: near a pole, tessellated triangles are long
            // slivers whose sharp corners need long miters to stay covered.
            let miter = (na + nb) / max(1.0 + dot(na, nb), 1e-4);
            out.clip = vec4<f32>((s[k] + grow * miter) / half_size, clip[k].z, 1.0);
        }
        return out;
    }

    // Pre-clipped: the band of latitudes the triangle can cover, full width.
    var lo = min(arc_sin_lat(dirs[0], dirs[1], true),
        min(arc_sin_lat(dirs[1], dirs[2], true), arc_sin_lat(dirs[2], dirs[0], true)));
    var hi = max(arc_sin_lat(dirs[0], dirs[1], false),
        max(arc_sin_lat(dirs[1], dirs[2], false), arc_sin_lat(dirs[2], dirs[0], false)));
    var lat_lo = asin(clamp(lo, -1.0, 1.0));
    var lat_hi = asin(clamp(hi, -1.0, 1.0));
    if north {
        lat_hi = HALF_PI;
    }
    if south {
        lat_lo = -HALF_PI;
    }
    // Omnistereo rays start up to half the IPD from the head: widen by the angle that subtends
    // from the nearest corner, and by two pixels.
    let nearest = max(min(dist[0], min(dist[1], dist[2])), 1e-4);
    let pad = asin(min(abs(view.omni_head.w) / nearest, 1.0)) + 2.0 * PI / view.pano_size.y;
    let band = pano_band(max(lat_lo - pad, -HALF_PI), min(lat_hi + pad, HALF_PI));
    // A triangle that holds the rectangle [-1, 1] × band (and the volume stereo's shifts).
    let height = band.y - band.x;
    let shape = array<vec2<f32>, 3>(
        vec2<f32>(-4.0, band.x),
        vec2<f32>(4.0, band.x),
        vec2<f32>(0.0, band.x + 2.0 * height),
    );
    out.p0.w = 1.0;
    out.clip = vec4<f32>(shape[k], 0.5, 1.0);
    return out;
}

struct PanoFragment {
    @location(0) color: vec4<f32>,
    @builtin(frag_depth) depth: f32,
    @builtin(sample_mask) mask: u32,
}

// Where the ray origin + t·dir meets the plane of triangle a, b, c: (t, u, v) with the
// barycentrics of b and c (Möller–Trumbore without the inside test); t = −1 if parallel.
fn ray_plane(origin: vec3<f32>, dir: vec3<f32>, a: vec3<f32>, b: vec3<f32>, c: vec3<f32>)
    -> vec3<f32> {
    let e1 = b - a;
    let e2 = c - a;
    let q = cross(dir, e2);
    let det = dot(e1, q);
    if abs(det) < 1e-20 {
        return vec3<f32>(-1.0, 0.0, 0.0);
    }
    let inv = 1.0 / det;
    let s = origin - a;
    let r = cross(s, e1);
    return vec3<f32>(dot(e2, r) * inv, dot(s, q) * inv, dot(dir, r) * inv);
}

// A pre-clipped fragment's own ray.
struct PanoRay {
    origin: vec3<f32>,
    dir: vec3<f32>,
    // Whether the projection shows a direction at this pixel.
    shown: bool,
}

// The ray through framebuffer position `pixel` (centres at +0.5), for a point at normalised
// depth `depth` (the volume stereo's parallax depends on it): through the inverse map, from
// the head, or in omnistereo from the eye for its direction.
fn pano_ray(pixel: vec2<f32>, depth: f32) -> PanoRay {
    let size = view.pano_size;
    let ndc = vec2<f32>(pixel.x / size.x * 2.0 - 1.0, 1.0 - pixel.y / size.y * 2.0);
    let m = view.pano_window.xy + vec2<f32>(ndc.x - volume_parallax(depth), ndc.y)
        * view.pano_window.zw;
    let unmapped = pano_unmap(view.pano_projection - 1u, m);
    let rotation = mat3x3<f32>(
        view.clip_from_cave[0].xyz, view.clip_from_cave[1].xyz, view.clip_from_cave[2].xyz,
    );
    var ray: PanoRay;
    ray.dir = transpose(rotation) * unmapped.xyz;
    ray.origin = view.eye_position.xyz;
    if view.pano_stereo == 2u {
        ray.origin = omni_eye(ray.origin + 1000.0 * ray.dir, view.omni_head, frame.omni);
    }
    ray.shown = unmapped.w > 0.5;
    return ray;
}

@fragment
fn fs_pano(in: PanoOutput) -> PanoFragment {
    // Every fragment casts its own ray at its triangle's plane: exact depth (no fighting
    // between a picture and the wall 1 cm behind it, which interpolating the distance
    // linearly across a curved triangle would cause) and exact texture coordinates. The
    // rasterised shape decides coverage only: the chords for ordinary triangles, the whole
    // band for pre-clipped ones (where the ray must also meet the triangle itself).
    // The volume stereo's parallax depends on the depth found: a few rounds from the
    // rasterised depth converge far below a pixel (the parallax is smooth in depth).
    var depth = in.clip.z;
    if in.p0.w > 0.5 {
        depth = pano_depth(length((in.p0.xyz + in.p1 + in.p2) / 3.0 - view.eye_position.xyz));
    }
    var hit = vec3<f32>(-1.0, 0.0, 0.0);
    var ray: PanoRay;
    for (var round = 0u; round < 3u; round++) {
        ray = pano_ray(in.clip.xy, depth);
        hit = ray_plane(ray.origin, ray.dir, in.p0.xyz, in.p1, in.p2);
        depth = pano_depth(hit.x);
        if view.pano_stereo != 1u {
            break;
        }
    }
    let inside = hit.y >= 0.0 && hit.z >= 0.0 && hit.y + hit.z <= 1.0;
    let met = ray.shown && hit.x > 0.0;
    // Coverage: where the rays meet the triangle, between the clipping spheres (an edge-on
    // triangle covers nothing). With MSAA, each sample's own ray decides its bit, so edges
    // are antialiased as the walls' are; shading stays once per pixel, from the centre's
    // ray, or from the first covered sample's where the centre's misses.
    var mask = select(0u, 1u, met && inside);
    let samples = view.pano_msaa;
    if samples == 4u {
        mask = 0u;
        let corner = floor(in.clip.xy);
        var first = true;
        for (var k = 0u; k < 4u; k++) {
            let r = pano_ray(corner + SAMPLE_POSITIONS_4[k], depth);
            let h = ray_plane(r.origin, r.dir, in.p0.xyz, in.p1, in.p2);
            if r.shown && h.x > 0.0 && h.y >= 0.0 && h.z >= 0.0 && h.y + h.z <= 1.0 {
                mask |= 1u << k;
                if first && !(met && inside) {
                    ray = r;
                    hit = h;
                    depth = pano_depth(h.x);
                }
                first = false;
            }
        }
    }
    // Everything from the exact hit, in uniform control flow (so that the texture's
    // gradients come from the neighbouring pixels' exact coordinates; a pixel whose rays
    // miss is discarded below, but still lends its neighbours a gradient).
    let w = vec3<f32>(1.0 - hit.y - hit.z, hit.y, hit.z);
    var surface: SurfaceInput;
    surface.position = w.x * in.p0.xyz + w.y * in.p1 + w.z * in.p2;
    surface.normal = w.x * in.n0 + w.y * in.n1 + w.z * in.n2;
    surface.uvs = w.x * in.uv0 + w.y * in.uv1 + w.z * in.uv2;
    surface.color = w.x * in.color0 + w.y * in.color1 + w.z * in.color2;
    surface.tangent = w.x * in.tangent0 + w.y * in.tangent1 + w.z * in.tangent2;
    // Explicit gradients: those of the exact coordinates, not of the rasterised varyings.
    let ddx = dpdx(surface.uvs);
    let ddy = dpdy(surface.uvs);
    let eye = ray.origin;
    let facing = dot(cross(in.p1 - in.p0.xyz, in.p2 - in.p0.xyz), ray.origin - in.p0.xyz)
        >= 0.0;
    let keep = mask != 0u && depth >= 0.0 && depth <= 1.0;
    let color = surface_color(surface, ddx, ddy, eye, facing);
    if !keep || color.a < 0.0 {
        discard;
    }
    var out: PanoFragment;
    out.color = color;
    out.depth = depth;
    out.mask = select(mask, 0xffffffffu, samples < 2u);
    return out;
}

// Vulkan's (and D3D's) standard positions of 4 samples within a pixel.
const SAMPLE_POSITIONS_4 = array<vec2<f32>, 4>(
    vec2<f32>(0.375, 0.125),
    vec2<f32>(0.875, 0.375),
    vec2<f32>(0.125, 0.625),
    vec2<f32>(0.625, 0.875),
);

// A surface point as the rasteriser or a panorama ray finds it (CAVE space).
struct SurfaceInput {
    position: vec3<f32>,
    // Interpolated, not normalised.
    normal: vec3<f32>,
    // xy: TEXCOORD_0, zw: TEXCOORD_1.
    uvs: vec4<f32>,
    color: vec4<f32>,
    tangent: vec4<f32>,
}

// Texture slot `slot`'s coordinates (its set, then KHR_texture_transform) and their screen
// gradients.
struct SlotCoords {
    uv: vec2<f32>,
    ddx: vec2<f32>,
    ddy: vec2<f32>,
}

fn slot_coords(slot: u32, uvs: vec4<f32>, ddx: vec4<f32>, ddy: vec4<f32>) -> SlotCoords {
    var uv = uvs.xy;
    var dx = ddx.xy;
    var dy = ddy.xy;
    if ((material.texture_flags >> (8u + slot)) & 1u) != 0u {
        uv = uvs.zw;
        dx = ddx.zw;
        dy = ddy.zw;
    }
    let r0 = material.uv_transforms[2u * slot];
    let r1 = material.uv_transforms[2u * slot + 1u];
    var c: SlotCoords;
    c.uv = vec2<f32>(dot(r0.xyz, vec3<f32>(uv, 1.0)), dot(r1.xyz, vec3<f32>(uv, 1.0)));
    c.ddx = vec2<f32>(dot(r0.xy, dx), dot(r1.xy, dx));
    c.ddy = vec2<f32>(dot(r0.xy, dy), dot(r1.xy, dy));
    return c;
}

// A texture slot's texel, or white where the material has no texture in that slot (a
// primitive without the coordinates a texture needs gets a material without it: nothing is
// sampled at made-up coordinates). Explicit gradients, so that it may run in non-uniform
// control flow and the panorama can give the exact coordinates' own.
fn sample_slot(
    t: texture_2d<f32>,
    s: sampler,
    slot: u32,
    uvs: vec4<f32>,
    ddx: vec4<f32>,
    ddy: vec4<f32>,
) -> vec4<f32> {
    if ((material.texture_flags >> slot) & 1u) == 0u {
        return vec4<f32>(1.0);
    }
    let c = slot_coords(slot, uvs, ddx, ddy);
    return textureSampleGrad(t, s, c.uv, c.ddx, c.ddy);
}

// The unit shading normal on the viewer's side, bent by the normal map where there is one.
fn shading_normal(in: SurfaceInput, ddx: vec4<f32>, ddy: vec4<f32>, front_facing: bool)
    -> vec3<f32> {
    let side = select(-1.0, 1.0, front_facing);
    let n = side * normalize(in.normal);
    let t_raw = side * (in.tangent.xyz - n * dot(n, in.tangent.xyz));
    if ((material.texture_flags >> 2u) & 1u) == 0u || dot(t_raw, t_raw) < 1e-12 {
        return n;
    }
    let t = normalize(t_raw);
    // The bitangent flips with the face (n and t did) only through its sign: b = w (n × t).
    let b = select(-1.0, 1.0, in.tangent.w >= 0.0) * cross(n, t) * side;
    let texel = sample_slot(normal_texture, normal_sampler, 2u, in.uvs, ddx, ddy).xyz;
    var m = texel * 2.0 - 1.0;
    m = vec3<f32>(m.xy * material.normal_scale, m.z);
    let bent = m.x * t + m.y * b + m.z * n;
    return select(n, normalize(bent), dot(bent, bent) > 1e-12);
}

// 3×3 percentage-closer filtering: the mean of nine bilinear comparisons one texel apart
// around `uv`. Together they weigh the 4×4 texels around `uv` separably, (1 - f, 1, 1, f) along
// each axis (f: where `uv` lies between texel centres), so four gathers of 2×2 comparisons
// give the same sum from 16 comparisons instead of 36 (and 4 fetches instead of 9).
fn pcf_3x3(uv: vec2<f32>, layer: u32, depth: f32) -> f32 {
    let size = 1.0 / frame.shadow_params.z;
    let st = uv * size - 0.5;
    let f = fract(st);
    // The corner between texels (i - 1, i) and (i + 1, i + 2) along each axis, i = floor(st).
    let corner = floor(st);
    // Where every texel the gathers read is at or beyond `depth` (all lit) or every one
    // before it (all shadowed), the filter's answer is known from the tile's depth range:
    // one read instead of four gathers. The weights sum to 9, so that answer is 1 or 0.
    let tiles = frame.shadow_tiles;
    if tiles != 0u {
        let tile = vec2<u32>(clamp(corner, vec2<f32>(0.0), vec2<f32>(size - 1.0))) / SHADOW_TILE;
        let range = shadow_ranges[(layer * tiles + tile.y) * tiles + tile.x];
        if depth <= range.x {
            return 1.0;
        }
        if depth > range.y {
            return 0.0;
        }
    }
    // Each gather returns the 2×2 texels around a corner: x (u min, v max), y (u max,
    // v max), z (u max, v min), w (u min, v min); the outer texels weigh 1 - f and f.
    let h = frame.shadow_params.z;
    let g00 = textureGatherCompare(shadow_maps, shadow_sampler, corner * h, layer, depth);
    let g10 = textureGatherCompare(
        shadow_maps, shadow_sampler, (corner + vec2<f32>(2.0, 0.0)) * h, layer, depth,
    );
    let g01 = textureGatherCompare(
        shadow_maps, shadow_sampler, (corner + vec2<f32>(0.0, 2.0)) * h, layer, depth,
    );
    let g11 = textureGatherCompare(
        shadow_maps, shadow_sampler, (corner + vec2<f32>(2.0, 2.0)) * h, layer, depth,
    );
    let gx = 1.0 - f.x;
    let gy = 1.0 - f.y;
    let lit = (g00.w * gx + g00.z) * gy + (g00.x * gx + g00.y)
        + (g10.w + g10.z * f.x) * gy + (g10.x + g10.y * f.x)
        + (g01.w * gx + g01.z) + (g01.x * gx + g01.y) * f.y
        + (g11.w + g11.z * f.x) + (g11.x + g11.y * f.x) * f.y;
    return lit / 9.0;
}

// How much of light k reaches CAVE-space point `p` with unit normal `n` (on the viewer's
// side): 1 where its shadow maps do not see it occluded, 0 where they do, between at a
// filtered edge. Shadows depend only on the point, not on the eye: exact in every mode.
fn light_visibility(k: u32, p: vec3<f32>, n: vec3<f32>) -> f32 {
    let light = frame.lights[k];
    if frame.shadow_params.w < 0.5 || light.shadow.x < 0.0 {
        return 1.0;
    }
    // Off the surface by a few texels of the map at this point (against self-shadowing).
    let distance = length(light.position.xyz - p);
    let texel = light.shadow.w + light.shadow.z * distance;
    let lifted = p + n * frame.shadow_params.x * texel;
    let first = u32(light.shadow.x);
    let count = u32(light.shadow.y);
    let h = vec4<f32>(lifted, 1.0);
    if count == 6u && u32(light.direction.w + 0.5) == 1u {
        // A point light's cube: only the face whose axis the direction from the light is
        // nearest can hold the point, so one projection instead of searching up to six.
        // That face has the largest clip w (the distance along its axis); the faces come in
        // the order +X, -X, +Y, -Y, +Z, -Z of `plan_shadows` (src/render/shadow_pass.rs;
        // keep in sync: its test `a_point_lights_largest_w_names_the_face_that_holds_the_point`
        // checks this rule), so -X's w is +X's negated, and three w's decide. Each face spans
        // a hair over 90°, so it holds every point nearest its axis. (Searching the six costs
        // lavapipe about 5 % of the desktop preview's scene pass.)
        let mx = frame.shadow_from_cave[first];
        let my = frame.shadow_from_cave[first + 2u];
        let mz = frame.shadow_from_cave[first + 4u];
        let w = vec3<f32>(
            dot(vec4<f32>(mx[0].w, mx[1].w, mx[2].w, mx[3].w), h),
            dot(vec4<f32>(my[0].w, my[1].w, my[2].w, my[3].w), h),
            dot(vec4<f32>(mz[0].w, mz[1].w, mz[2].w, mz[3].w), h),
        );
        let a = abs(w);
        var face = select(0u, 1u, w.x < 0.0);
        if a.y > a.x && a.y >= a.z {
            face = select(2u, 3u, w.y < 0.0);
        } else if a.z > a.x && a.z > a.y {
            face = select(4u, 5u, w.z < 0.0);
        }
        let v = shadow_in_layer(first + face, frame.shadow_from_cave[first + face] * h);
        return select(1.0, v, v >= 0.0);
    }
    for (var i = 0u; i < count; i++) {
        let v = shadow_in_layer(first + i, frame.shadow_from_cave[first + i] * h);
        if v >= 0.0 {
            return v;
        }
    }
    return 1.0;
}

// How much light reaches a point at `clip` in shadow map `layer` (0 to 1), or -1 where the
// point lies outside that map's frustum (another layer may hold it).
fn shadow_in_layer(layer: u32, clip: vec4<f32>) -> f32 {
    if clip.w <= 0.0 {
        return -1.0;
    }
    let ndc = clip.xyz / clip.w;
    if abs(ndc.x) > 1.0 || abs(ndc.y) > 1.0 || ndc.z < 0.0 {
        return -1.0;
    }
    if ndc.z > 1.0 {
        // Beyond the map's far plane: nothing there casts onto it.
        return 1.0;
    }
    let uv = vec2<f32>(0.5 * ndc.x + 0.5, 0.5 - 0.5 * ndc.y);
    if frame.shadow_params.y < 0.5 {
        return textureSampleCompareLevel(shadow_maps, shadow_sampler, uv, layer, ndc.z);
    }
    return pcf_3x3(uv, layer, ndc.z);
}

// The lit colour of a surface point seen from `eye`; alpha < 0 where the material's alpha
// cutoff removes it.
fn surface_color(
    in: SurfaceInput,
    ddx: vec4<f32>,
    ddy: vec4<f32>,
    eye: vec3<f32>,
    front_facing: bool,
) -> vec4<f32> {
    let base_texel = sample_slot(base_color_texture, base_color_sampler, 0u, in.uvs, ddx, ddy);
    let base = material.base_color * in.color * base_texel;
    if material.alpha_cutoff >= 0.0 && base.a < material.alpha_cutoff {
        return vec4<f32>(0.0, 0.0, 0.0, -1.0);
    }
    let alpha = select(1.0, clamp(base.a, 0.0, 1.0), material.alpha_blend != 0u);
    if material.unlit != 0u {
        // KHR_materials_unlit: exactly the base colour.
        return vec4<f32>(base.rgb, alpha);
    }
    let mr = sample_slot(
        metallic_roughness_texture, metallic_roughness_sampler, 1u, in.uvs, ddx, ddy,
    );
    let occlusion = sample_slot(occlusion_texture, occlusion_sampler, 3u, in.uvs, ddx, ddy).r;
    let emissive = sample_slot(emissive_texture, emissive_sampler, 4u, in.uvs, ddx, ddy).rgb;
    var s: SurfacePoint;
    s.position = in.position;
    s.normal = shading_normal(in, ddx, ddy, front_facing);
    s.base_color = base.rgb;
    s.metallic = clamp(material.metallic * mr.b, 0.0, 1.0);
    s.roughness = clamp(material.roughness * mr.g, 0.0, 1.0);
    s.occlusion = 1.0 + material.occlusion_strength * (occlusion - 1.0);
    let facing_n = select(-1.0, 1.0, front_facing) * normalize(in.normal);
    let lit = shade_surface(s, eye, facing_n);
    return vec4<f32>(lit + material.emissive * emissive, alpha);
}

@fragment
fn fs_main(in: VertexOutput, @builtin(front_facing) front_facing: bool) -> @location(0) vec4<f32> {
    var surface: SurfaceInput;
    surface.position = in.cave_position;
    surface.normal = in.normal;
    surface.uvs = in.uvs;
    surface.color = in.color;
    surface.tangent = in.tangent;
    // The eye this fragment is seen from: the view's, or in omnistereo its corners' eyes
    // interpolated across the triangle, at a point of it (the centroid of the covered samples;
    // the pixel's centre where every sample is covered). Every omnistereo eye lies on the
    // circle of half the IPD round the head (inside it with pole merge), so this is within one
    // IPD of the fragment's own eye, and within IPD·sin(Δ/2) for a triangle spanning Δ < 180°
    // of azimuth round the head at the full IPD (src/cave/omni.rs tests the bound). Computing
    // the fragment's own eye instead cost 2–8 % of the omnistereo frame in paired runs on a
    // software rasteriser.
    let eye = select(view.eye_position.xyz, in.shading_eye, frame.omni.x > 0.5);
    let color = surface_color(surface, dpdx(in.uvs), dpdy(in.uvs), eye, front_facing);
    if color.a < 0.0 {
        discard;
    }
    return target_color(color);
}

@fragment
fn fs_wireframe() -> @location(0) vec4<f32> {
    return target_color(frame.wire_color);
}
