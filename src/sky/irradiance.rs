//! The light a sky sheds on a surface: its irradiance as nine spherical-harmonic coefficients
//! (Ramamoorthi & Hanrahan, "An Efficient Representation for Irradiance Environment Maps",
//! 2001), computed once per sky from a small mip level; the shader evaluates it per normal.

use glam::Vec3;

use super::cubemap::{CubeMap, Texels, face_direction, srgb_to_linear};

/// Irradiance E(n) = Σ coefficients[i] · Y_i(n) (scene-space directions), already convolved
/// with the clamped cosine; a constant radiance L gives E = π L everywhere.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SkyIrradiance {
    pub coefficients: [Vec3; 9],
}

/// The real spherical harmonics of bands 0–2 at unit direction `d`.
pub fn sh_basis(d: Vec3) -> [f32; 9] {
    let (x, y, z) = (d.x, d.y, d.z);
    [
        0.282_095,
        0.488_603 * y,
        0.488_603 * z,
        0.488_603 * x,
        1.092_548 * x * y,
        1.092_548 * y * z,
        0.315_392 * (3.0 * z * z - 1.0),
        1.092_548 * x * z,
        0.546_274 * (x * x - y * y),
    ]
}

/// Largest face size read: the irradiance is smooth, 32² texels per face resolve it.
const MAX_FACE: u32 = 32;

impl SkyIrradiance {
    /// Projects the sky's radiance onto the basis and convolves it with the cosine lobe.
    pub fn from_cube(cube: &CubeMap) -> Self {
        let level = cube
            .levels
            .iter()
            .find(|l| l.size <= MAX_FACE && l.size > 0)
            .or(cube.levels.last());
        let mut projected = [Vec3::ZERO; 9];
        if let Some(level) = level.filter(|l| l.size > 0) {
            let n = level.size;
            for face in 0..6u32 {
                for y in 0..n {
                    for x in 0..n {
                        let s = (x as f32 + 0.5) / n as f32;
                        let t = (y as f32 + 0.5) / n as f32;
                        let (u, v) = (2.0 * s - 1.0, 2.0 * t - 1.0);
                        // Solid angle of the texel on a cube of side 2.
                        let d_omega = (2.0 / n as f32).powi(2) / (1.0 + u * u + v * v).powf(1.5);
                        let i = ((face * n * n + y * n + x) * 4) as usize;
                        let radiance = match &level.texels {
                            Texels::Srgb8(b) => Vec3::new(
                                srgb_to_linear(b[i]),
                                srgb_to_linear(b[i + 1]),
                                srgb_to_linear(b[i + 2]),
                            ),
                            Texels::LinearF16(h) => Vec3::new(
                                half::f16::from_bits(h[i]).to_f32(),
                                half::f16::from_bits(h[i + 1]).to_f32(),
                                half::f16::from_bits(h[i + 2]).to_f32(),
                            ),
                        };
                        let dir = face_direction(face, s, t).normalize();
                        for (c, y_i) in projected.iter_mut().zip(sh_basis(dir)) {
                            *c += radiance * (y_i * d_omega);
                        }
                    }
                }
            }
        }
        // The clamped cosine's coefficients per band.
        let pi = std::f32::consts::PI;
        let band = [pi, 2.0 * pi / 3.0, 2.0 * pi / 3.0, 2.0 * pi / 3.0];
        let mut coefficients = projected;
        for (i, c) in coefficients.iter_mut().enumerate() {
            *c *= band.get(i).copied().unwrap_or(pi / 4.0);
        }
        Self { coefficients }
    }

    /// Irradiance arriving at a surface with unit normal `n` (scene space).
    pub fn eval(&self, n: Vec3) -> Vec3 {
        self.coefficients
            .iter()
            .zip(sh_basis(n))
            .map(|(c, y)| *c * y)
            .sum()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sky::cubemap::CubeLevel;

    fn cube(colour: impl Fn(Vec3) -> [u8; 3]) -> CubeMap {
        let n = 16u32;
        let mut bytes = Vec::new();
        for face in 0..6 {
            for y in 0..n {
                for x in 0..n {
                    let d = face_direction(face, (x as f32 + 0.5) / 16.0, (y as f32 + 0.5) / 16.0);
                    let [r, g, b] = colour(d.normalize());
                    bytes.extend_from_slice(&[r, g, b, 255]);
                }
            }
        }
        CubeMap {
            source: "test".into(),
            levels: vec![CubeLevel {
                size: n,
                texels: Texels::Srgb8(bytes),
            }],
        }
    }

    #[test]
    fn a_uniform_sky_gives_pi_times_its_radiance_everywhere() {
        let e = SkyIrradiance::from_cube(&cube(|_| [255, 255, 255]));
        for n in [Vec3::X, Vec3::Y, Vec3::NEG_Y, Vec3::new(0.6, 0.0, -0.8)] {
            let got = e.eval(n);
            // 1 %: the texel quadrature.
            assert!((got.x - std::f32::consts::PI).abs() < 0.03, "{n}: {got}");
        }
    }

    #[test]
    fn a_sky_bright_above_lights_upward_faces_only() {
        // Radiance 1 above the horizon, 0 below: E(up) = π, E(down) = 0, E(side) = π/2
        // exactly; three bands ring a little (Ramamoorthi–Hanrahan: within 9 % of π).
        let e = SkyIrradiance::from_cube(&cube(|d| if d.y > 0.0 { [255; 3] } else { [0; 3] }));
        let pi = std::f32::consts::PI;
        assert!(
            (e.eval(Vec3::Y).x - pi).abs() < 0.09 * pi,
            "{}",
            e.eval(Vec3::Y)
        );
        assert!(
            e.eval(Vec3::NEG_Y).x.abs() < 0.09 * pi,
            "{}",
            e.eval(Vec3::NEG_Y)
        );
        assert!(
            (e.eval(Vec3::X).x - pi / 2.0).abs() < 0.03,
            "{}",
            e.eval(Vec3::X)
        );
    }
}
