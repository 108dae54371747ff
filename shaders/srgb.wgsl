// sRGB transfer functions, and what a colour pass writes: linear colour to an sRGB target (the
// hardware encodes), or colour the shader encodes itself into a plain 8-bit target (the
// multisampled eye images; src/render/resolve.rs says why). CPU twin: `linear_to_srgb` and
// `srgb_to_linear` in src/sky/cubemap.rs (keep in sync).

// Set per pipeline: true when the colour target stores sRGB bytes without converting them.
override ENCODE_SRGB_OUTPUT: bool = false;

fn srgb_encode(c: vec3<f32>) -> vec3<f32> {
    let v = clamp(c, vec3<f32>(0.0), vec3<f32>(1.0));
    return select(1.055 * pow(v, vec3<f32>(1.0 / 2.4)) - 0.055, v * 12.92, v <= vec3<f32>(0.0031308));
}

fn srgb_decode(c: vec3<f32>) -> vec3<f32> {
    return select(pow((c + 0.055) / 1.055, vec3<f32>(2.4)), c / 12.92, c <= vec3<f32>(0.04045));
}

// A fragment's linear colour as its pipeline's target takes it.
fn target_color(c: vec4<f32>) -> vec4<f32> {
    if ENCODE_SRGB_OUTPUT {
        return vec4<f32>(srgb_encode(c.rgb), c.a);
    }
    return c;
}
