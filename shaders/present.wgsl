// Stereo output formats: composes a wall's two eye images into the one image its projector
// takes. Paired with src/render/present.rs; the CPU twin is src/output/formats.rs (keep the
// format codes and the arithmetic in step).

// Keep in sync with `PresentUniforms` in src/render/present.rs.
struct PresentUniforms {
    // x: format code (`StereoFormat::code`), y: frame index parity (0 even, 1 odd),
    // z: 1 to swap the eyes, w: blank rows between the eyes in frame packing.
    params: vec4<u32>,
    // xy: eye image size in pixels; z: 1 if the target is not sRGB (the shader then encodes).
    size: vec4<u32>,
    // xy: top-left of the tile in target pixels; zw: composed pixels per target pixel (a window
    // or preview tile of another size than the format's output is scaled, nearest texel).
    viewport: vec4<f32>,
    // A projector's alignment (per-eye outputs): xy: offset of the image in composed pixels,
    // zw: top-left of the crop in the eye image.
    shift: vec4<i32>,
    // xy: the crop's size in pixels; z: 1 if the crop and shift apply.
    crop: vec4<u32>,
}

@group(0) @binding(0) var<uniform> present: PresentUniforms;
@group(0) @binding(1) var left_eye: texture_2d<f32>;
@group(0) @binding(2) var right_eye: texture_2d<f32>;

// Linear colour of an eye's texel (`right` before the swap), clamped to the image.
fn eye_texel(right: bool, p: vec2<i32>) -> vec3<f32> {
    let q = clamp(p, vec2<i32>(0), vec2<i32>(present.size.xy) - 1);
    if right != (present.params.z != 0u) {
        return textureLoad(right_eye, q, 0).rgb;
    }
    return textureLoad(left_eye, q, 0).rgb;
}

fn composed(p: vec2<i32>) -> vec3<f32> {
    let w = i32(present.size.x);
    let h = i32(present.size.y);
    switch present.params.x {
        // Frame-sequential: the left eye on even frames.
        case 0u: {
            return eye_texel(present.params.y == 1u, p);
        }
        // Side by side, full.
        case 1u: {
            if p.x < w {
                return eye_texel(false, p);
            }
            return eye_texel(true, vec2<i32>(p.x - w, p.y));
        }
        // Side by side, half: each output pixel is the mean of two eye pixels.
        case 2u: {
            let half_w = w / 2;
            let right = p.x >= half_w;
            let x = select(p.x, p.x - half_w, right);
            return 0.5 * (eye_texel(right, vec2<i32>(2 * x, p.y)) + eye_texel(right, vec2<i32>(2 * x + 1, p.y)));
        }
        // Top-bottom, full.
        case 3u: {
            if p.y < h {
                return eye_texel(false, p);
            }
            return eye_texel(true, vec2<i32>(p.x, p.y - h));
        }
        // Top-bottom, half.
        case 4u: {
            let half_h = h / 2;
            let right = p.y >= half_h;
            let y = select(p.y, p.y - half_h, right);
            return 0.5 * (eye_texel(right, vec2<i32>(p.x, 2 * y)) + eye_texel(right, vec2<i32>(p.x, 2 * y + 1)));
        }
        // HDMI frame packing: left, blank band, right.
        case 5u: {
            let gap = i32(present.params.w);
            if p.y < h {
                return eye_texel(false, p);
            }
            if p.y < h + gap {
                return vec3<f32>(0.0);
            }
            return eye_texel(true, vec2<i32>(p.x, p.y - h - gap));
        }
        // Row-interleaved: even rows left.
        case 6u: {
            return eye_texel((p.y & 1) == 1, p);
        }
        // Anaglyph red-cyan.
        case 7u: {
            let l = eye_texel(false, p);
            let r = eye_texel(true, p);
            return vec3<f32>(l.r, r.g, r.b);
        }
        // Anaglyph, colour-optimised: red from the left eye's green and blue.
        case 8u: {
            let l = eye_texel(false, p);
            let r = eye_texel(true, p);
            return vec3<f32>(0.7 * l.g + 0.3 * l.b, r.g, r.b);
        }
        // Right only.
        case 10u: {
            return eye_texel(true, p);
        }
        // Left only, mono.
        default: {
            return eye_texel(false, p);
        }
    }
}

@fragment
fn fs_present(@builtin(position) position: vec4<f32>) -> @location(0) vec4<f32> {
    let p = (position.xy - present.viewport.xy) * present.viewport.zw;
    var q = vec2<i32>(floor(p));
    var c = vec3<f32>(0.0);
    if present.crop.z == 0u {
        c = composed(q);
    } else {
        // Moved by the offset, then cut to the crop: what falls outside is black.
        q = q - present.shift.xy;
        if all(q >= vec2<i32>(0)) && all(q < vec2<i32>(present.crop.xy)) {
            c = composed(q + present.shift.zw);
        }
    }
    if present.size.z != 0u {
        c = srgb_encode(c);
    }
    return vec4<f32>(c, 1.0);
}
