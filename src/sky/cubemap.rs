//! Cube maps on the CPU: the face convention, loading from six images or one equirectangular
//! image (PNG/JPEG/Radiance HDR), and the mip chain. No GPU here; `render::sky_pass` uploads.
//!
//! Convention (right-handed CAVE/world space, y up, −z forward). A direction `d` is looked up
//! in the hardware cube map as `(d.x, d.y, −d.z)`: the hardware convention (OpenGL, Vulkan,
//! D3D agree) is left-handed, and this flip makes every face read unmirrored from inside.
//! Faces, in layer order: 0 right (+x), 1 left (−x), 2 top (+y), 3 bottom (−y), 4 front (−z),
//! 5 back (+z); file names `right left top bottom front back` (or `px nx py ny pz nz`, which
//! mean the same layers: note pz = front = −z, as in the hardware's left-handed frame; packs
//! made for a right-handed −z-forward viewer that call the front `nz` need their pz/nz swapped).
//! The top face's lower edge joins the front face's upper edge.
//!
//! Equirectangular images: column 0.5·width looks at the front (−z), longitude grows to the
//! right (+x at 0.75·width), row 0 is straight up.

use std::path::{Path, PathBuf};

use glam::Vec3;

/// Face names in layer order, and their `px…nz` aliases.
pub const FACE_NAMES: [&str; 6] = ["right", "left", "top", "bottom", "front", "back"];
pub const FACE_ALIASES: [&str; 6] = ["px", "nx", "py", "ny", "pz", "nz"];
const EXTENSIONS: [&str; 4] = ["png", "jpg", "jpeg", "hdr"];

/// Largest face side made from an equirectangular image.
pub const MAX_EQUIRECT_FACE_SIZE: u32 = 2048;
/// Largest face side accepted from face images (4096²×6 RGBA16F is 800 MiB with mips).
pub const MAX_FACE_SIZE: u32 = 4096;

/// Why a sky could not be loaded.
#[derive(Debug, thiserror::Error)]
pub enum SkyError {
    #[error("sky file {path}: cannot read: {source}")]
    Read {
        path: PathBuf,
        source: std::io::Error,
    },
    #[error("sky file {path}: not a readable PNG, JPEG or HDR image: {message}")]
    Decode { path: PathBuf, message: String },
    #[error(
        "sky folder {path}: no {face} face (looked for {face}.png/.jpg/.jpeg/.hdr and {alias}.*)"
    )]
    MissingFace {
        path: PathBuf,
        face: &'static str,
        alias: &'static str,
    },
    #[error(
        "sky face {path}: is {width}×{height}; every face must be square, the same size ({expected}×{expected}) and at most {MAX_FACE_SIZE} pixels"
    )]
    FaceSize {
        path: PathBuf,
        width: u32,
        height: u32,
        expected: u32,
    },
    #[error(
        "sky image {path}: is {width}×{height}; an equirectangular sky must be twice as wide as high (at least 8×4)"
    )]
    EquirectSize {
        path: PathBuf,
        width: u32,
        height: u32,
    },
}

/// Texel storage of a cube map: sRGB bytes for PNG/JPEG, linear half floats for HDR.
#[derive(Debug, Clone, PartialEq)]
pub enum Texels {
    /// RGBA8, sRGB-encoded.
    Srgb8(Vec<u8>),
    /// RGBA16F bits, linear.
    LinearF16(Vec<u16>),
}

/// One mip level of all six faces (face after face, rows top first).
#[derive(Debug, Clone, PartialEq)]
pub struct CubeLevel {
    pub size: u32,
    pub texels: Texels,
}

/// A cube map with its full mip chain, ready to upload.
#[derive(Debug, Clone, PartialEq)]
pub struct CubeMap {
    /// Where it came from (for messages).
    pub source: PathBuf,
    /// Level 0 first, down to 1×1.
    pub levels: Vec<CubeLevel>,
}

impl CubeMap {
    pub fn size(&self) -> u32 {
        self.levels.first().map_or(0, |l| l.size)
    }

    pub fn is_hdr(&self) -> bool {
        matches!(
            self.levels.first().map(|l| &l.texels),
            Some(Texels::LinearF16(_))
        )
    }

    /// Linear RGB of level 0 at the texel nearest to `dir` (tests and tools).
    pub fn sample_nearest(&self, dir: Vec3) -> [f32; 3] {
        let Some(level) = self.levels.first().filter(|l| l.size > 0) else {
            return [0.0; 3];
        };
        let (face, s, t) = face_coordinates(dir);
        let n = level.size as f32;
        let x = ((s * n) as u32).min(level.size - 1);
        let y = ((t * n) as u32).min(level.size - 1);
        let i = (face as usize * (level.size * level.size) as usize
            + (y * level.size + x) as usize)
            * 4;
        match &level.texels {
            Texels::Srgb8(b) => [
                srgb_to_linear(b[i]),
                srgb_to_linear(b[i + 1]),
                srgb_to_linear(b[i + 2]),
            ],
            Texels::LinearF16(h) => [
                half::f16::from_bits(h[i]).to_f32(),
                half::f16::from_bits(h[i + 1]).to_f32(),
                half::f16::from_bits(h[i + 2]).to_f32(),
            ],
        }
    }
}

/// The face and the (s, t) ∈ [0, 1]² coordinates (s right, t down the face image) that the
/// hardware samples for world direction `dir`, under this module's convention.
pub fn face_coordinates(dir: Vec3) -> (u32, f32, f32) {
    // Hardware direction (left-handed flip of z).
    let (x, y, z) = (dir.x, dir.y, -dir.z);
    let (ax, ay, az) = (x.abs(), y.abs(), z.abs());
    // Major axis selection and (sc, tc, ma) per the cube-map table of the Vulkan/GL specs.
    let (face, sc, tc, ma) = if ax >= ay && ax >= az {
        if x >= 0.0 {
            (0, -z, -y, ax)
        } else {
            (1, z, -y, ax)
        }
    } else if ay >= az {
        if y >= 0.0 {
            (2, x, z, ay)
        } else {
            (3, x, -z, ay)
        }
    } else if z >= 0.0 {
        (4, x, -y, az)
    } else {
        (5, -x, -y, az)
    };
    let ma = ma.max(f32::MIN_POSITIVE);
    (face, 0.5 * (sc / ma + 1.0), 0.5 * (tc / ma + 1.0))
}

/// The world direction (not normalised) through point (s, t) of a face: the inverse of
/// [`face_coordinates`].
pub fn face_direction(face: u32, s: f32, t: f32) -> Vec3 {
    let (sc, tc) = (2.0 * s - 1.0, 2.0 * t - 1.0);
    // Hardware direction, then the z flip back to world space.
    let (x, y, z) = match face {
        0 => (1.0, -tc, -sc),
        1 => (-1.0, -tc, sc),
        2 => (sc, 1.0, tc),
        3 => (sc, -1.0, -tc),
        4 => (sc, -tc, 1.0),
        _ => (-sc, -tc, -1.0),
    };
    Vec3::new(x, y, -z)
}

/// World direction of an equirectangular image point (u, v) ∈ [0, 1]² (u right, v down).
pub fn equirect_direction(u: f32, v: f32) -> Vec3 {
    crate::pano::direction(
        (u - 0.5) * std::f32::consts::TAU,
        (0.5 - v) * std::f32::consts::PI,
    )
}

/// Equirectangular image point (u, v) of a world direction: the inverse of
/// [`equirect_direction`].
pub fn equirect_coordinates(dir: Vec3) -> (f32, f32) {
    let (lon, lat) = crate::pano::lon_lat(dir.normalize_or(Vec3::NEG_Z));
    (
        0.5 + lon / std::f32::consts::TAU,
        0.5 - lat / std::f32::consts::PI,
    )
}

/// Loads a sky: an equirectangular image file, or a folder holding six face images; each
/// file is read up to the default `budgets.max_file_mb`.
pub fn load_sky(path: &Path) -> Result<CubeMap, SkyError> {
    load_sky_within(path, crate::scene::SceneBudget::default().max_file_bytes)
}

/// [`load_sky`], reading no file past `max_file_bytes`.
pub fn load_sky_within(path: &Path, max_file_bytes: u64) -> Result<CubeMap, SkyError> {
    if path.is_dir() {
        load_faces(path, max_file_bytes)
    } else {
        let image = open_image(path, max_file_bytes)?;
        from_equirect(path, &image)
    }
}

/// A decoded image: sRGB bytes or linear floats (RGBA, rows top first).
enum Decoded {
    Srgb(image::RgbaImage),
    Linear(image::Rgba32FImage),
}

impl Decoded {
    fn dimensions(&self) -> (u32, u32) {
        match self {
            Self::Srgb(i) => i.dimensions(),
            Self::Linear(i) => i.dimensions(),
        }
    }

    /// Linear RGBA at integer texel (x, y).
    fn linear(&self, x: u32, y: u32) -> [f32; 4] {
        match self {
            Self::Srgb(i) => {
                let p = i.get_pixel(x, y).0;
                [
                    srgb_to_linear(p[0]),
                    srgb_to_linear(p[1]),
                    srgb_to_linear(p[2]),
                    f32::from(p[3]) / 255.0,
                ]
            }
            Self::Linear(i) => i.get_pixel(x, y).0,
        }
    }
}

fn open_image(path: &Path, max_file_bytes: u64) -> Result<Decoded, SkyError> {
    let bytes = crate::read_capped::read_capped(path, max_file_bytes, "budgets.max_file_mb")
        .map_err(|source| SkyError::Read {
            path: path.to_owned(),
            source,
        })?;
    let decoded = image::ImageReader::new(std::io::Cursor::new(bytes))
        .with_guessed_format()
        .map_err(|e| SkyError::Decode {
            path: path.to_owned(),
            message: e.to_string(),
        })?
        .decode()
        .map_err(|e| SkyError::Decode {
            path: path.to_owned(),
            message: e.to_string(),
        })?;
    Ok(match decoded {
        image::DynamicImage::ImageRgb32F(_) | image::DynamicImage::ImageRgba32F(_) => {
            Decoded::Linear(decoded.to_rgba32f())
        }
        other => Decoded::Srgb(other.to_rgba8()),
    })
}

fn load_faces(dir: &Path, max_file_bytes: u64) -> Result<CubeMap, SkyError> {
    let mut faces = Vec::with_capacity(6);
    let mut size = None;
    for (face, alias) in FACE_NAMES.into_iter().zip(FACE_ALIASES) {
        let path = [face, alias]
            .iter()
            .flat_map(|stem| {
                EXTENSIONS
                    .iter()
                    .map(move |ext| dir.join(format!("{stem}.{ext}")))
            })
            .find(|p| p.is_file())
            .ok_or_else(|| SkyError::MissingFace {
                path: dir.to_owned(),
                face,
                alias,
            })?;
        let image = open_image(&path, max_file_bytes)?;
        let (w, h) = image.dimensions();
        let expected = *size.get_or_insert(w);
        if w != h || w != expected || w == 0 || w > MAX_FACE_SIZE {
            return Err(SkyError::FaceSize {
                path,
                width: w,
                height: h,
                expected,
            });
        }
        faces.push(image);
    }
    let size = size.unwrap_or(1);
    let hdr = faces.iter().any(|f| matches!(f, Decoded::Linear(_)));
    let mut linear = Vec::with_capacity((6 * size * size) as usize * 4);
    for face in &faces {
        for y in 0..size {
            for x in 0..size {
                linear.extend_from_slice(&face.linear(x, y));
            }
        }
    }
    Ok(build(dir, size, linear, hdr))
}

/// Resamples an equirectangular image into a cube map (bilinear, longitude wraps).
fn from_equirect(path: &Path, image: &Decoded) -> Result<CubeMap, SkyError> {
    let (w, h) = image.dimensions();
    if w != 2 * h || h < 4 {
        return Err(SkyError::EquirectSize {
            path: path.to_owned(),
            width: w,
            height: h,
        });
    }
    // A quarter of the width covers a face's 90° at the equator at the image's resolution.
    let size = (w / 4).next_power_of_two().clamp(4, MAX_EQUIRECT_FACE_SIZE);
    let mut linear = Vec::with_capacity((6 * size * size) as usize * 4);
    for face in 0..6 {
        for y in 0..size {
            for x in 0..size {
                let s = (x as f32 + 0.5) / size as f32;
                let t = (y as f32 + 0.5) / size as f32;
                let (u, v) = equirect_coordinates(face_direction(face, s, t));
                linear.extend_from_slice(&bilinear(image, u, v));
            }
        }
    }
    Ok(build(
        path,
        size,
        linear,
        matches!(image, Decoded::Linear(_)),
    ))
}

fn bilinear(image: &Decoded, u: f32, v: f32) -> [f32; 4] {
    let (w, h) = image.dimensions();
    let taps = equirect_taps(w, h, u, v);
    std::array::from_fn(|c| {
        taps.iter()
            .map(|&(x, y, weight)| weight * image.linear(x, y)[c])
            .sum()
    })
}

/// The four texels and weights of a bilinear sample at (u, v) ∈ [0, 1]² of a `w`×`h`
/// equirectangular image: longitude wraps, latitude clamps.
pub fn equirect_taps(w: u32, h: u32, u: f32, v: f32) -> [(u32, u32, f32); 4] {
    let (w, h) = (w.max(1), h.max(1));
    let fx = u * w as f32 - 0.5;
    let fy = (v * h as f32 - 0.5).clamp(0.0, (h - 1) as f32);
    let (x0, y0) = (fx.floor(), fy.floor());
    let (ax, ay) = (fx - x0, fy - y0);
    let wrap = |x: f32| (x as i64).rem_euclid(i64::from(w)) as u32;
    let (xa, xb) = (wrap(x0), wrap(x0 + 1.0));
    let (ya, yb) = (y0 as u32, (y0 as u32 + 1).min(h - 1));
    [
        (xa, ya, (1.0 - ax) * (1.0 - ay)),
        (xb, ya, ax * (1.0 - ay)),
        (xa, yb, (1.0 - ax) * ay),
        (xb, yb, ax * ay),
    ]
}

/// Builds the mip chain (2×2 box filter in linear light, per face) and encodes the texels.
fn build(source: &Path, size: u32, mut linear: Vec<f32>, hdr: bool) -> CubeMap {
    let mut levels = Vec::new();
    let mut n = size;
    loop {
        levels.push(CubeLevel {
            size: n,
            texels: encode(&linear, hdr),
        });
        if n == 1 {
            break;
        }
        let half_n = n / 2;
        let mut next = Vec::with_capacity((6 * half_n * half_n) as usize * 4);
        for face in 0..6usize {
            let base = face * (n * n) as usize;
            for y in 0..half_n as usize {
                for x in 0..half_n as usize {
                    for c in 0..4 {
                        let at = |dx: usize, dy: usize| {
                            linear[(base + (2 * y + dy) * n as usize + 2 * x + dx) * 4 + c]
                        };
                        next.push(0.25 * (at(0, 0) + at(1, 0) + at(0, 1) + at(1, 1)));
                    }
                }
            }
        }
        linear = next;
        n = half_n;
    }
    CubeMap {
        source: source.to_owned(),
        levels,
    }
}

fn encode(linear: &[f32], hdr: bool) -> Texels {
    if hdr {
        Texels::LinearF16(
            linear
                .iter()
                .map(|&v| {
                    half::f16::from_f32(if v.is_finite() { v.max(0.0) } else { 0.0 }).to_bits()
                })
                .collect(),
        )
    } else {
        Texels::Srgb8(
            linear
                .chunks_exact(4)
                .flat_map(|p| {
                    [
                        linear_to_srgb(p[0]),
                        linear_to_srgb(p[1]),
                        linear_to_srgb(p[2]),
                        (p[3].clamp(0.0, 1.0) * 255.0).round() as u8,
                    ]
                })
                .collect(),
        )
    }
}

pub fn srgb_to_linear(v: u8) -> f32 {
    let v = f32::from(v) / 255.0;
    if v <= 0.04045 {
        v / 12.92
    } else {
        ((v + 0.055) / 1.055).powf(2.4)
    }
}

pub fn linear_to_srgb(v: f32) -> u8 {
    let v = v.clamp(0.0, 1.0);
    let s = if v <= 0.003_130_8 {
        v * 12.92
    } else {
        1.055 * v.powf(1.0 / 2.4) - 0.055
    };
    (s * 255.0).round() as u8
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn face_coordinates_invert_face_direction() {
        for face in 0..6 {
            for (s, t) in [(0.5, 0.5), (0.1, 0.2), (0.9, 0.7), (0.3, 0.95)] {
                let d = face_direction(face, s, t);
                let (f, s2, t2) = face_coordinates(d);
                assert_eq!(f, face);
                assert!(
                    (s - s2).abs() < 1e-6 && (t - t2).abs() < 1e-6,
                    "{face} {s} {t}"
                );
            }
        }
    }

    #[test]
    fn faces_are_where_their_names_say_and_unmirrored() {
        // Centre of each face looks along its named axis.
        let axes = [
            Vec3::X,
            Vec3::NEG_X,
            Vec3::Y,
            Vec3::NEG_Y,
            Vec3::NEG_Z,
            Vec3::Z,
        ];
        for (face, axis) in axes.into_iter().enumerate() {
            assert!(face_direction(face as u32, 0.5, 0.5).normalize().dot(axis) > 0.9999);
        }
        // Front face: s grows to the viewer's right (+x), t grows downwards.
        assert!(face_direction(4, 0.9, 0.5).x > 0.0);
        assert!(face_direction(4, 0.5, 0.9).y < 0.0);
        // Right face (looking along +x, right is +z).
        assert!(face_direction(0, 0.9, 0.5).z > 0.0);
        // Top face: its lower edge (t = 1) borders the front face (−z).
        assert!(face_direction(2, 0.5, 1.0).z < 0.0);
        assert!(face_direction(2, 0.9, 0.5).x > 0.0);
    }

    #[test]
    fn equirect_round_trip_and_orientation() {
        assert!(equirect_direction(0.5, 0.5).dot(Vec3::NEG_Z) > 0.9999);
        assert!(equirect_direction(0.75, 0.5).dot(Vec3::X) > 0.9999);
        assert!(equirect_direction(0.3, 0.0).dot(Vec3::Y) > 0.9999);
        for (u, v) in [(0.1, 0.3), (0.6, 0.8), (0.9, 0.45)] {
            let (u2, v2) = equirect_coordinates(equirect_direction(u, v));
            assert!((u - u2).abs() < 1e-5 && (v - v2).abs() < 1e-5);
        }
    }

    #[test]
    fn mip_chain_goes_to_one_texel_and_averages() {
        let size = 8;
        let linear: Vec<f32> = (0..6 * size * size)
            .flat_map(|i| [if i % 2 == 0 { 1.0 } else { 0.0 }, 0.5, 0.0, 1.0])
            .collect();
        let cube = build(Path::new("test"), size, linear, true);
        assert_eq!(cube.levels.len(), 4);
        let Texels::LinearF16(last) = &cube.levels[3].texels else {
            panic!("hdr expected")
        };
        assert_eq!(last.len(), 6 * 4);
        assert!((half::f16::from_bits(last[0]).to_f32() - 0.5).abs() < 1e-3);
    }
}
