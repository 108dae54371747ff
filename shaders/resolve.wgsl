// Resolves a multisampled eye image whose samples the scene and sky shaders stored
// sRGB-encoded (`target_color`) into the eye image's bytes: where the samples differ, each is
// decoded, the mean taken in linear light and encoded again, as the hardware resolves an
// sRGB attachment. Paired with src/render/resolve.rs.

override SAMPLE_COUNT: u32 = 4u;

@group(0) @binding(0) var samples: texture_multisampled_2d<f32>;

@fragment
fn fs_resolve(@builtin(position) position: vec4<f32>) -> @location(0) vec4<f32> {
    let p = vec2<i32>(floor(position.xy));
    // Inside a surface every sample holds the same bytes: they are the pixel's, exactly.
    let first = textureLoad(samples, p, 0);
    var same = true;
    for (var s = 1u; s < SAMPLE_COUNT; s++) {
        same = same && all(textureLoad(samples, p, i32(s)) == first);
    }
    if same {
        return first;
    }
    var sum = vec4<f32>(0.0);
    for (var s = 0u; s < SAMPLE_COUNT; s++) {
        let c = textureLoad(samples, p, i32(s));
        sum += vec4<f32>(srgb_decode(c.rgb), c.a);
    }
    let mean = sum / f32(SAMPLE_COUNT);
    return vec4<f32>(srgb_encode(mean.rgb), mean.a);
}
