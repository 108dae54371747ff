//! CPU twin of shaders/pbr.wgsl: the same BRDF, lights and shading models, function for
//! function, so that tests can compute what a pixel must show.

use glam::Vec3;

use super::uniforms::{FrameUniforms, GpuLight, MAX_LIGHTS};

const INV_PI: f32 = std::f32::consts::FRAC_1_PI;
/// Mirrors `MIN_ROUGHNESS` in shaders/pbr.wgsl.
const MIN_ROUGHNESS: f32 = 0.03;

/// A surface point after its material's textures (mirrors `SurfacePoint`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SurfacePoint {
    pub position: Vec3,
    /// Unit shading normal on the viewer's side.
    pub normal: Vec3,
    pub base_color: Vec3,
    pub metallic: f32,
    pub roughness: f32,
    pub occlusion: f32,
}

fn mix(a: Vec3, b: Vec3, t: f32) -> Vec3 {
    a + (b - a) * t
}

pub fn fresnel_schlick(f0: Vec3, v_dot_h: f32) -> Vec3 {
    f0 + (Vec3::ONE - f0) * (1.0 - v_dot_h).clamp(0.0, 1.0).powi(5)
}

pub fn distribution_ggx(n_dot_h: f32, alpha: f32) -> f32 {
    let a2 = alpha * alpha;
    let d = n_dot_h * n_dot_h * (a2 - 1.0) + 1.0;
    a2 * INV_PI / (d * d).max(1e-12)
}

pub fn visibility_smith(n_dot_l: f32, n_dot_v: f32, alpha: f32) -> f32 {
    let a2 = alpha * alpha;
    let gv = n_dot_l * (n_dot_v * n_dot_v * (1.0 - a2) + a2).sqrt();
    let gl = n_dot_v * (n_dot_l * n_dot_l * (1.0 - a2) + a2).sqrt();
    let sum = gv + gl;
    if sum > 0.0 { 0.5 / sum } else { 0.0 }
}

/// The BRDF times N·L for unit directions towards the light (`l`) and the eye (`v`).
pub fn brdf_cos(s: &SurfacePoint, v: Vec3, l: Vec3) -> Vec3 {
    let n_dot_l = s.normal.dot(l);
    if n_dot_l <= 0.0 {
        return Vec3::ZERO;
    }
    let n_dot_v = s.normal.dot(v).max(1e-4);
    let h = (l + v).normalize();
    let roughness = s.roughness.max(MIN_ROUGHNESS);
    let alpha = roughness * roughness;
    let f0 = mix(Vec3::splat(0.04), s.base_color, s.metallic);
    let f = fresnel_schlick(f0, v.dot(h).max(0.0));
    let c_diff = mix(s.base_color, Vec3::ZERO, s.metallic);
    let diffuse = (Vec3::ONE - f) * c_diff * INV_PI;
    let specular = f
        * distribution_ggx(s.normal.dot(h).max(0.0), alpha)
        * visibility_smith(n_dot_l, n_dot_v, alpha);
    (diffuse + specular) * n_dot_l
}

/// Light arriving at a point: the unit direction towards the light and its radiance.
pub fn light_incoming(light: &GpuLight, position: Vec3) -> (Vec3, Vec3) {
    let kind = (light.direction[3] + 0.5) as u32;
    let color = Vec3::from_slice(&light.color[..3]);
    if kind == 0 {
        return (-Vec3::from_slice(&light.direction[..3]), color);
    }
    let to_light = Vec3::from_slice(&light.position[..3]) - position;
    let d = to_light.length();
    let direction = to_light / d.max(1e-6);
    let range = light.position[3];
    let mut attenuation = if light.color[3] > 0.5 {
        let fade = (1.0 - d / range.max(1e-6)).clamp(0.0, 1.0);
        fade * fade
    } else {
        let mut a = 1.0 / (d * d).max(1e-4);
        if range > 0.0 {
            let r = d / range;
            a *= (1.0 - r * r * r * r).clamp(0.0, 1.0);
        }
        a
    };
    if kind == 2 {
        let cos_angle = Vec3::from_slice(&light.direction[..3]).dot(-direction);
        let t = ((cos_angle - light.cone[0]) * light.cone[1]).clamp(0.0, 1.0);
        attenuation *= t * t;
    }
    (direction, color * attenuation)
}

pub fn env_brdf_approx(f0: Vec3, roughness: f32, n_dot_v: f32) -> Vec3 {
    let c0 = [-1.0, -0.0275, -0.572, 0.022];
    let c1 = [1.0, 0.0425, 1.04, -0.04];
    let r: [f32; 4] = std::array::from_fn(|i| roughness * c0[i] + c1[i]);
    let a004 = (r[0] * r[0]).min((-9.28 * n_dot_v).exp2()) * r[0] + r[1];
    let ab = [-1.04 * a004 + r[2], 1.04 * a004 + r[3]];
    f0 * ab[0] + Vec3::splat(ab[1])
}

/// Mirrors `ambient_radiance`: the config's ambient plus the sky's E(n) / π.
pub fn ambient_radiance(frame: &FrameUniforms, n: Vec3) -> Vec3 {
    let mut l = Vec3::from_slice(&frame.ambient[..3]);
    if frame.sky_params[0] > 0.5 {
        let d = glam::Mat4::from_cols_array_2d(&frame.sky_from_cave)
            .transform_vector3(n)
            .normalize();
        let e: Vec3 = frame
            .sky_sh
            .iter()
            .map(|c| Vec3::from_slice(&c[..3]))
            .zip(crate::sky::irradiance::sh_basis(d))
            .map(|(c, y)| c * y)
            .sum();
        l += e.max(Vec3::ZERO) * INV_PI;
    }
    l
}

fn lights(frame: &FrameUniforms) -> &[GpuLight] {
    &frame.lights[..(frame.light_count as usize).min(MAX_LIGHTS)]
}

/// Every light reaching the point fully (no shadow).
pub const LIT: [f32; MAX_LIGHTS] = [1.0; MAX_LIGHTS];

/// The physically based colour of a surface point seen from `eye` (without emission);
/// `visibility[k]`: how much of light k reaches it (what the shader's `shade_pbr` asks
/// `light_visibility` for, light by light, instead of taking an array).
pub fn shade_pbr(
    frame: &FrameUniforms,
    s: &SurfacePoint,
    eye: Vec3,
    visibility: &[f32; MAX_LIGHTS],
) -> Vec3 {
    let v = (eye - s.position).normalize();
    let mut color = Vec3::ZERO;
    for (light, seen) in lights(frame).iter().zip(visibility) {
        let (l, radiance) = light_incoming(light, s.position);
        color += brdf_cos(s, v, l) * radiance * *seen;
    }
    let f0 = mix(Vec3::splat(0.04), s.base_color, s.metallic);
    let c_diff = mix(s.base_color, Vec3::ZERO, s.metallic);
    let n_dot_v = s.normal.dot(v).max(1e-4);
    let mirror = (-v).reflect(s.normal);
    let ambient = c_diff * ambient_radiance(frame, s.normal)
        + env_brdf_approx(f0, s.roughness, n_dot_v) * ambient_radiance(frame, mirror);
    color + ambient * s.occlusion
}

/// The simple Blinn-Phong colour (mirrors `shade_simple`).
pub fn shade_simple(
    frame: &FrameUniforms,
    s: &SurfacePoint,
    eye: Vec3,
    visibility: &[f32; MAX_LIGHTS],
) -> Vec3 {
    let v = (eye - s.position).normalize();
    let roughness = s.roughness.max(0.02);
    let a = roughness * roughness;
    let shininess = (2.0 / (a * a) - 2.0).clamp(1.0, 512.0);
    let strength = 0.04 + 0.5 * (1.0 - roughness) + 0.4 * s.metallic;
    let mut diffuse = ambient_radiance(frame, s.normal);
    let mut specular = Vec3::ZERO;
    for (light, seen) in lights(frame).iter().zip(visibility) {
        let (l, radiance) = light_incoming(light, s.position);
        let n_dot_l = s.normal.dot(l);
        if n_dot_l > 0.0 {
            let e = radiance * INV_PI * *seen;
            diffuse += n_dot_l * e;
            let h = (l + v).normalize();
            specular += s.normal.dot(h).max(0.0).powf(shininess) * e;
        }
    }
    s.base_color * diffuse + strength * specular
}

/// The lit colour in the frame's shading model (mirrors `shade_surface`).
pub fn shade_surface(
    frame: &FrameUniforms,
    s: &SurfacePoint,
    eye: Vec3,
    visibility: &[f32; MAX_LIGHTS],
) -> Vec3 {
    if frame.shading == 1 {
        shade_simple(frame, s, eye, visibility)
    } else {
        shade_pbr(frame, s, eye, visibility)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn surface(metallic: f32, roughness: f32) -> SurfacePoint {
        SurfacePoint {
            position: Vec3::ZERO,
            normal: Vec3::Y,
            base_color: Vec3::splat(0.8),
            metallic,
            roughness,
            occlusion: 1.0,
        }
    }

    #[test]
    fn a_white_furnace_conserves_energy() {
        // Integrated over the hemisphere of light directions, BRDF × cos stays about 1 for a
        // white surface (no energy is made), for any roughness, metal or not, from any view.
        for &(metallic, roughness) in &[(0.0, 0.05), (0.0, 0.5), (0.0, 1.0), (1.0, 0.2), (1.0, 1.0)]
        {
            let mut s = surface(metallic, roughness);
            s.base_color = Vec3::ONE;
            for &view_angle in &[0.0f32, 0.6, 1.2] {
                let v = Vec3::new(view_angle.sin(), view_angle.cos(), 0.0);
                let (n_theta, n_phi) = (200, 400);
                let mut total = Vec3::ZERO;
                for i in 0..n_theta {
                    let theta = (i as f32 + 0.5) / n_theta as f32 * std::f32::consts::FRAC_PI_2;
                    for j in 0..n_phi {
                        let phi = (j as f32 + 0.5) / n_phi as f32 * std::f32::consts::TAU;
                        let l = Vec3::new(
                            theta.sin() * phi.cos(),
                            theta.cos(),
                            theta.sin() * phi.sin(),
                        );
                        let d_omega = theta.sin()
                            * (std::f32::consts::FRAC_PI_2 / n_theta as f32)
                            * (std::f32::consts::TAU / n_phi as f32);
                        total += brdf_cos(&s, v, l) * d_omega;
                    }
                }
                // The glTF model weights the diffuse term by 1 − F(v·h) per light direction,
                // which is not exactly energy conserving at grazing views (3 % at 69° for a
                // rough dielectric); more than 5 % would be a wrong term, not the model.
                assert!(
                    total.max_element() <= 1.05,
                    "metallic {metallic} roughness {roughness} view {view_angle}: {total}"
                );
                // And a rough dielectric reflects most of it (diffuse ≈ 1 − F).
                if metallic == 0.0 && roughness == 1.0 {
                    assert!(total.x > 0.8, "{total}");
                }
            }
        }
    }

    #[test]
    fn a_matte_white_surface_facing_a_light_of_intensity_pi_is_white() {
        // The convention the config's lights rely on: radiance π, Lambert c/π.
        let mut s = surface(0.0, 1.0);
        s.base_color = Vec3::ONE;
        let c = brdf_cos(&s, Vec3::Y, Vec3::Y) * std::f32::consts::PI;
        // Fresnel takes 4 % at normal incidence into the (small, rough) specular lobe.
        assert!((c.x - 1.0).abs() < 0.05, "{c}");
    }

    #[test]
    fn the_highlight_peaks_at_the_mirror_direction() {
        let s = surface(1.0, 0.2);
        let l = Vec3::new(0.6, 0.8, 0.0);
        let mirror = Vec3::new(-0.6, 0.8, 0.0);
        let off = Vec3::new(-0.3, 0.95, 0.0).normalize();
        assert!(brdf_cos(&s, mirror, l).x > 10.0 * brdf_cos(&s, off, l).x);
    }
}
