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
}

// One wall seen from one eye. Keep in sync with `ViewUniforms` in src/render/uniforms.rs.
struct ViewUniforms {
    clip_from_cave: mat4x4<f32>,
    // xyz: centre of projection (CAVE space); w unused.
    eye_position: vec4<f32>,
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
