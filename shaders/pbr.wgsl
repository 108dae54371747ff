// Physically based shading as glTF 2.0 defines it (Appendix B: metallic-roughness BRDF with
// GGX distribution, height-correlated Smith visibility and Schlick's Fresnel), in CAVE space,
// and the simple Blinn-Phong model it replaced (`[render] shading = "simple"`).
// Mirrored on the CPU by src/render/pbr.rs (keep the two in step). Prepended to
// shaders/scene.wgsl only: it reads that shader's module-scope `frame` (FrameUniforms) and
// calls its `light_visibility` (shadows) directly. WGSL cannot pass a uniform buffer by
// pointer; passing the 1.6 KB struct by value, or the lights' visibility as an array, makes
// lavapipe copy them through memory for every fragment (together a third of the desktop
// preview's frame).

const INV_PI: f32 = 0.31830988618379067;

// A surface point after its material's textures.
struct SurfacePoint {
    position: vec3<f32>,
    // Unit shading normal on the viewer's side.
    normal: vec3<f32>,
    base_color: vec3<f32>,
    metallic: f32,
    // Perceptual roughness.
    roughness: f32,
    // Ambient occlusion (1: none).
    occlusion: f32,
}

fn fresnel_schlick(f0: vec3<f32>, v_dot_h: f32) -> vec3<f32> {
    return f0 + (vec3<f32>(1.0) - f0) * pow(clamp(1.0 - v_dot_h, 0.0, 1.0), 5.0);
}

// Trowbridge-Reitz (GGX) normal distribution; alpha = roughness².
fn distribution_ggx(n_dot_h: f32, alpha: f32) -> f32 {
    let a2 = alpha * alpha;
    let d = n_dot_h * n_dot_h * (a2 - 1.0) + 1.0;
    return a2 * INV_PI / max(d * d, 1e-12);
}

// Height-correlated Smith visibility, V = G / (4 N·L N·V).
fn visibility_smith(n_dot_l: f32, n_dot_v: f32, alpha: f32) -> f32 {
    let a2 = alpha * alpha;
    let gv = n_dot_l * sqrt(n_dot_v * n_dot_v * (1.0 - a2) + a2);
    let gl = n_dot_v * sqrt(n_dot_l * n_dot_l * (1.0 - a2) + a2);
    let sum = gv + gl;
    return select(0.0, 0.5 / sum, sum > 0.0);
}

// Roughness below this is clamped: a perfect mirror lit by a point light is a single texel.
const MIN_ROUGHNESS: f32 = 0.03;

// The BRDF times N·L, for the unit directions towards the light (l) and the eye (v).
fn brdf_cos(s: SurfacePoint, v: vec3<f32>, l: vec3<f32>) -> vec3<f32> {
    let n_dot_l = dot(s.normal, l);
    if n_dot_l <= 0.0 {
        return vec3<f32>(0.0);
    }
    let n_dot_v = max(dot(s.normal, v), 1e-4);
    let h = normalize(l + v);
    let roughness = max(s.roughness, MIN_ROUGHNESS);
    let alpha = roughness * roughness;
    let f0 = mix(vec3<f32>(0.04), s.base_color, s.metallic);
    let f = fresnel_schlick(f0, max(dot(v, h), 0.0));
    let c_diff = mix(s.base_color, vec3<f32>(0.0), s.metallic);
    let diffuse = (vec3<f32>(1.0) - f) * c_diff * INV_PI;
    let specular = f * distribution_ggx(max(dot(s.normal, h), 0.0), alpha)
        * visibility_smith(n_dot_l, n_dot_v, alpha);
    return (diffuse + specular) * n_dot_l;
}

// Light arriving at a point: the unit direction towards the light and its radiance.
struct Incoming {
    direction: vec3<f32>,
    radiance: vec3<f32>,
}

fn light_incoming(light: Light, position: vec3<f32>) -> Incoming {
    var inc: Incoming;
    let kind = u32(light.direction.w + 0.5);
    if kind == 0u {
        inc.direction = -light.direction.xyz;
        inc.radiance = light.color.rgb;
        return inc;
    }
    let to_light = light.position.xyz - position;
    let d = length(to_light);
    inc.direction = to_light / max(d, 1e-6);
    let range = light.position.w;
    var attenuation = 0.0;
    if light.color.w > 0.5 {
        // The config's point light: a smooth fade to zero at its range.
        let fade = clamp(1.0 - d / max(range, 1e-6), 0.0, 1.0);
        attenuation = fade * fade;
    } else {
        // glTF: inverse square, windowed to zero at the range where one is given.
        attenuation = 1.0 / max(d * d, 1e-4);
        if range > 0.0 {
            let r = d / range;
            attenuation *= clamp(1.0 - r * r * r * r, 0.0, 1.0);
        }
    }
    if kind == 2u {
        let cos_angle = dot(light.direction.xyz, -inc.direction);
        let t = clamp((cos_angle - light.cone.x) * light.cone.y, 0.0, 1.0);
        attenuation *= t * t;
    }
    inc.radiance = light.color.rgb * attenuation;
    return inc;
}

// Karis' analytic fit of the split-sum environment BRDF: the specular response to light
// arriving evenly from every direction.
fn env_brdf_approx(f0: vec3<f32>, roughness: f32, n_dot_v: f32) -> vec3<f32> {
    let c0 = vec4<f32>(-1.0, -0.0275, -0.572, 0.022);
    let c1 = vec4<f32>(1.0, 0.0425, 1.04, -0.04);
    let r = roughness * c0 + c1;
    let a004 = min(r.x * r.x, exp2(-9.28 * n_dot_v)) * r.x + r.y;
    let ab = vec2<f32>(-1.04, 1.04) * a004 + r.zw;
    return f0 * ab.x + ab.y;
}

// The even radiance that gives the irradiance arriving at a surface facing CAVE-space unit
// direction `n`: the config's ambient plus the sky's light (E(n) / π).
fn ambient_radiance(n: vec3<f32>) -> vec3<f32> {
    var l = frame.ambient.rgb;
    if frame.sky_params.x > 0.5 {
        let d = normalize((frame.sky_from_cave * vec4<f32>(n, 0.0)).xyz);
        // The real spherical-harmonic basis up to band 2 (src/sky/irradiance.rs `sh_basis`),
        // written out: no local array to index.
        let e = frame.sky_sh[0].rgb * 0.282095
            + frame.sky_sh[1].rgb * (0.488603 * d.y)
            + frame.sky_sh[2].rgb * (0.488603 * d.z)
            + frame.sky_sh[3].rgb * (0.488603 * d.x)
            + frame.sky_sh[4].rgb * (1.092548 * d.x * d.y)
            + frame.sky_sh[5].rgb * (1.092548 * d.y * d.z)
            + frame.sky_sh[6].rgb * (0.315392 * (3.0 * d.z * d.z - 1.0))
            + frame.sky_sh[7].rgb * (1.092548 * d.x * d.z)
            + frame.sky_sh[8].rgb * (0.546274 * (d.x * d.x - d.y * d.y));
        l += max(e, vec3<f32>(0.0)) * INV_PI;
    }
    return l;
}

// What light k adds at a surface point seen along unit direction `v` (towards the eye): the
// BRDF times its radiance, shadowed only where it would add something (facing it, within its
// range).
fn pbr_light(k: u32, s: SurfacePoint, v: vec3<f32>, facing_normal: vec3<f32>) -> vec3<f32> {
    let inc = light_incoming(frame.lights[k], s.position);
    let lit = brdf_cos(s, v, inc.direction) * inc.radiance;
    if any(lit > vec3<f32>(0.0)) {
        return lit * light_visibility(k, s.position, facing_normal);
    }
    return vec3<f32>(0.0);
}

// The lit colour of a surface point seen from `eye` (emission is added by the caller). Light
// k reaches it as far as `light_visibility(k, s.position, facing_normal)` says (shadows: 0 to
// 1), where `facing_normal` is the interpolated unit normal on the viewer's side (not bent by
// a normal map) that shadow look-ups lift the point along.
//
// The lights are summed by constant index, not in a loop over a counter: with the counter,
// lavapipe spent 5–10 % more of the desktop preview's frame (the same picture; see the
// book's performance page), apparently fetching each light's uniforms pixel by pixel.
// `light_count` is uniform, so the guards cost nothing where a light is absent. One call per
// light up to MAX_LIGHTS (keep in sync; `tests/gltf_features.rs`
// `every_light_up_to_the_limit_lights_its_spot_and_the_one_past_it_none` fails otherwise).
// The CPU twin (src/render/pbr.rs) loops: the same sum in the same order.
fn shade_pbr(s: SurfacePoint, eye: vec3<f32>, facing_normal: vec3<f32>) -> vec3<f32> {
    let v = normalize(eye - s.position);
    let n = min(frame.light_count, MAX_LIGHTS);
    var color = vec3<f32>(0.0);
    if n > 0u { color += pbr_light(0u, s, v, facing_normal); }
    if n > 1u { color += pbr_light(1u, s, v, facing_normal); }
    if n > 2u { color += pbr_light(2u, s, v, facing_normal); }
    if n > 3u { color += pbr_light(3u, s, v, facing_normal); }
    if n > 4u { color += pbr_light(4u, s, v, facing_normal); }
    if n > 5u { color += pbr_light(5u, s, v, facing_normal); }
    if n > 6u { color += pbr_light(6u, s, v, facing_normal); }
    if n > 7u { color += pbr_light(7u, s, v, facing_normal); }
    // Ambient light: diffuse c_diff·L(n), specular the environment BRDF times the light
    // around the mirror direction (the sky's irradiance there: exact for rough surfaces, a
    // blur of the sky for glossy ones), both occluded.
    let f0 = mix(vec3<f32>(0.04), s.base_color, s.metallic);
    let c_diff = mix(s.base_color, vec3<f32>(0.0), s.metallic);
    let n_dot_v = max(dot(s.normal, v), 1e-4);
    let mirror = reflect(-v, s.normal);
    let ambient = c_diff * ambient_radiance(s.normal)
        + env_brdf_approx(f0, s.roughness, n_dot_v) * ambient_radiance(mirror);
    return color + ambient * s.occlusion;
}

// The simple model: Blinn-Phong with an exponent and strength fitted to the roughness and
// metallic factors, on the base colour (maps other than base colour and emission unused).
fn shade_simple(s: SurfacePoint, eye: vec3<f32>, facing_normal: vec3<f32>) -> vec3<f32> {
    let v = normalize(eye - s.position);
    let roughness = max(s.roughness, 0.02);
    let a = roughness * roughness;
    let shininess = clamp(2.0 / (a * a) - 2.0, 1.0, 512.0);
    let strength = 0.04 + 0.5 * (1.0 - roughness) + 0.4 * s.metallic;
    // By constant index, as in `shade_pbr`.
    let n = min(frame.light_count, MAX_LIGHTS);
    var sum: SimpleLight;
    sum.diffuse = ambient_radiance(s.normal);
    if n > 0u { sum = add_simple_light(sum, 0u, s, v, facing_normal, shininess); }
    if n > 1u { sum = add_simple_light(sum, 1u, s, v, facing_normal, shininess); }
    if n > 2u { sum = add_simple_light(sum, 2u, s, v, facing_normal, shininess); }
    if n > 3u { sum = add_simple_light(sum, 3u, s, v, facing_normal, shininess); }
    if n > 4u { sum = add_simple_light(sum, 4u, s, v, facing_normal, shininess); }
    if n > 5u { sum = add_simple_light(sum, 5u, s, v, facing_normal, shininess); }
    if n > 6u { sum = add_simple_light(sum, 6u, s, v, facing_normal, shininess); }
    if n > 7u { sum = add_simple_light(sum, 7u, s, v, facing_normal, shininess); }
    return s.base_color * sum.diffuse + strength * sum.specular;
}

// The simple model's diffuse and specular light, summed over the lights.
struct SimpleLight {
    diffuse: vec3<f32>,
    specular: vec3<f32>,
}

// `sum` with light k's diffuse and specular added.
fn add_simple_light(
    sum: SimpleLight,
    k: u32,
    s: SurfacePoint,
    v: vec3<f32>,
    facing_normal: vec3<f32>,
    shininess: f32,
) -> SimpleLight {
    var out = sum;
    let inc = light_incoming(frame.lights[k], s.position);
    let n_dot_l = dot(s.normal, inc.direction);
    if n_dot_l > 0.0 && any(inc.radiance > vec3<f32>(0.0)) {
        // Light colours carry π (a white matte surface facing a light of intensity 1 is
        // white in the physically based model): the simple model takes it out.
        let e = inc.radiance * INV_PI * light_visibility(k, s.position, facing_normal);
        out.diffuse += n_dot_l * e;
        let h = normalize(inc.direction + v);
        out.specular += pow(max(dot(s.normal, h), 0.0), shininess) * e;
    }
    return out;
}

// The lit colour in the frame's shading model.
fn shade_surface(s: SurfacePoint, eye: vec3<f32>, facing_normal: vec3<f32>) -> vec3<f32> {
    if frame.shading == 1u {
        return shade_simple(s, eye, facing_normal);
    }
    return shade_pbr(s, eye, facing_normal);
}
