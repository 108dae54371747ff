// Shadow maps: the scene's depth as each shadow-casting light sees it (scene space, no eye:
// exact in every render mode), and each map tile's depth range for the filter's shortcut.
// Paired with src/render/shadow_pass.rs; the look-up is `light_visibility` in
// shaders/scene.wgsl.

// Keep in sync with `ShadowLayerUniforms` in src/render/shadow_pass.rs.
struct ShadowLayerUniforms {
    shadow_from_world: mat4x4<f32>,
}

@group(0) @binding(0) var<uniform> layer: ShadowLayerUniforms;

@vertex
fn vs_shadow(@location(0) position: vec3<f32>) -> @builtin(position) vec4<f32> {
    return layer.shadow_from_world * vec4<f32>(position, 1.0);
}

// Side of a range tile, texels. Keep in sync with `SHADOW_TILE` in src/render/shadow_pass.rs
// and shaders/scene.wgsl.
const SHADOW_TILE: u32 = 4u;

@group(0) @binding(1) var range_maps: texture_depth_2d_array;
// Per layer, row by row: the least and greatest depth a 3×3 filter can read from a point
// whose filter corner lies in the tile (see `pcf_3x3` in shaders/scene.wgsl).
@group(0) @binding(2) var<storage, read_write> ranges: array<vec2<f32>>;

// One tile of one layer (z): its texels and one more row and column before it and two after,
// clamped to the map as the sampler clamps. A filter whose corner c (floor of the texel
// coordinate minus ½) lies in the tile gathers texels c - 1 ..= c + 2 on each axis.
@compute @workgroup_size(8, 8)
fn cs_ranges(@builtin(global_invocation_id) id: vec3<u32>) {
    let size = textureDimensions(range_maps);
    let tiles = (size + SHADOW_TILE - 1u) / SHADOW_TILE;
    if id.x >= tiles.x || id.y >= tiles.y {
        return;
    }
    let first = vec2<i32>(id.xy * SHADOW_TILE);
    let lo = max(first - 1, vec2<i32>(0));
    let hi = min(first + i32(SHADOW_TILE) + 1, vec2<i32>(size) - 1);
    var least = 3.4e38;
    var most = -3.4e38;
    for (var y = lo.y; y <= hi.y; y++) {
        for (var x = lo.x; x <= hi.x; x++) {
            let d = textureLoad(range_maps, vec2<i32>(x, y), i32(id.z), 0);
            least = min(least, d);
            most = max(most, d);
        }
    }
    ranges[(id.z * tiles.y + id.y) * tiles.x + id.x] = vec2<f32>(least, most);
}
