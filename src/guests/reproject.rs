//! What one eye of a viewer sees of the walls: a perspective image from the eye, each pixel
//! the wall image its ray meets (bilinear), so that images rendered for another head can be
//! shown as this viewer sees them (`render --viewer`).

use glam::{DVec2, DVec3};
use image::{Rgba, RgbaImage};

use super::WallGeometry;
use crate::cave::Cave;

/// A perspective camera at an eye, looking along a horizontal direction.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EyeCamera {
    pub eye: DVec3,
    forward: DVec3,
    right: DVec3,
    up: DVec3,
    /// tan of half the horizontal and vertical fields of view.
    tan_half: DVec2,
    pub size: [u32; 2],
}

impl EyeCamera {
    /// A camera at `eye` facing the horizontal part of `forward`, `fov_degrees` wide and high
    /// (each below 180), `size` pixels.
    pub fn new(eye: DVec3, forward: DVec3, fov_degrees: [f64; 2], size: [u32; 2]) -> Option<Self> {
        let forward = DVec3::new(forward.x, 0.0, forward.z).try_normalize()?;
        let right = forward.cross(DVec3::Y);
        let tan = |deg: f64| (0.5 * deg.clamp(1.0, 179.0)).to_radians().tan();
        Some(Self {
            eye,
            forward,
            right,
            up: right.cross(forward),
            tan_half: DVec2::new(tan(fov_degrees[0]), tan(fov_degrees[1])),
            size,
        })
    }

    /// The direction through the pixel position `pixel` (x right, y down, pixel centres at .5).
    pub fn ray(&self, pixel: DVec2) -> DVec3 {
        let x = (2.0 * pixel.x / f64::from(self.size[0]) - 1.0) * self.tan_half.x;
        let y = (1.0 - 2.0 * pixel.y / f64::from(self.size[1])) * self.tan_half.y;
        self.forward + x * self.right + y * self.up
    }

    /// Where `point` appears in the image, if in front of the eye.
    pub fn pixel_of(&self, point: DVec3) -> Option<DVec2> {
        let d = point - self.eye;
        let z = d.dot(self.forward);
        (z > 1e-9).then(|| {
            let x = d.dot(self.right) / z / self.tan_half.x;
            let y = d.dot(self.up) / z / self.tan_half.y;
            DVec2::new(
                (x + 1.0) * 0.5 * f64::from(self.size[0]),
                (1.0 - y) * 0.5 * f64::from(self.size[1]),
            )
        })
    }
}

/// Colour of eye pixels whose ray meets no wall.
pub const NO_WALL: Rgba<u8> = Rgba([0, 0, 0, 255]);

/// The image `camera` sees of `cave`'s walls showing `images` (one per wall, in wall order).
pub fn reproject(cave: &Cave, images: &[&RgbaImage], camera: &EyeCamera) -> RgbaImage {
    let walls: Vec<WallGeometry> = cave.walls.iter().map(WallGeometry::of).collect();
    RgbaImage::from_fn(camera.size[0], camera.size[1], |x, y| {
        let dir = camera.ray(DVec2::new(f64::from(x) + 0.5, f64::from(y) + 0.5));
        let target = camera.eye + dir;
        walls
            .iter()
            .zip(images)
            .filter_map(|(w, img)| w.hit(camera.eye, target).map(|(t, uv)| (t, uv, img)))
            .min_by(|a, b| a.0.total_cmp(&b.0))
            .map_or(NO_WALL, |(_, uv, img)| sample(img, uv))
    })
}

/// Bilinear sample of `img` at wall coordinates `uv` (u right, v up, 0..1).
fn sample(img: &RgbaImage, uv: [f64; 2]) -> Rgba<u8> {
    let (w, h) = (img.width(), img.height());
    if w == 0 || h == 0 {
        return NO_WALL;
    }
    let x = uv[0] * f64::from(w) - 0.5;
    let y = (1.0 - uv[1]) * f64::from(h) - 0.5;
    let (x0, y0) = (x.floor(), y.floor());
    let (fx, fy) = (x - x0, y - y0);
    let at = |xi: f64, yi: f64| {
        let xi = xi.clamp(0.0, f64::from(w - 1)) as u32;
        let yi = yi.clamp(0.0, f64::from(h - 1)) as u32;
        img.get_pixel(xi, yi).0
    };
    let (a, b, c, d) = (
        at(x0, y0),
        at(x0 + 1.0, y0),
        at(x0, y0 + 1.0),
        at(x0 + 1.0, y0 + 1.0),
    );
    let mut out = [0u8; 4];
    for k in 0..4 {
        let top = f64::from(a[k]) * (1.0 - fx) + f64::from(b[k]) * fx;
        let bottom = f64::from(c[k]) * (1.0 - fx) + f64::from(d[k]) * fx;
        out[k] = (top * (1.0 - fy) + bottom * fy).round() as u8;
    }
    Rgba(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cave::thesis_cave;

    #[test]
    fn a_point_projects_back_to_the_pixel_whose_ray_it_is_on() {
        let cam = EyeCamera::new(
            DVec3::new(0.2, 1.6, 0.4),
            DVec3::new(-0.3, 0.0, -1.0),
            [100.0, 75.0],
            [800, 600],
        )
        .unwrap();
        for px in [
            DVec2::new(0.5, 0.5),
            DVec2::new(400.0, 300.0),
            DVec2::new(731.25, 17.5),
        ] {
            let p = cam.eye + 2.7 * cam.ray(px);
            assert!(cam.pixel_of(p).unwrap().distance(px) < 1e-9);
        }
        assert!(cam.pixel_of(cam.eye - cam.forward).is_none());
    }

    #[test]
    fn each_eye_pixel_shows_the_wall_pixel_its_ray_meets() {
        // Wall images whose red is the pixel column and green the row (a linear ramp, which
        // bilinear sampling reproduces exactly), blue the wall: every eye pixel must read the
        // wall pixel that `Wall::pixel_of_ray` (the renderer's tests' own path) finds.
        let mut cave = thesis_cave();
        for wall in &mut cave.walls {
            wall.resolution = [256, 256];
        }
        let images: Vec<RgbaImage> = (0..3)
            .map(|w| RgbaImage::from_fn(256, 256, |x, y| Rgba([x as u8, y as u8, w * 100, 255])))
            .collect();
        let refs: Vec<&RgbaImage> = images.iter().collect();
        let eye = DVec3::new(0.3, 1.5, 0.4);
        let cam =
            EyeCamera::new(eye, DVec3::new(-0.2, 0.0, -1.0), [140.0, 90.0], [280, 180]).unwrap();
        let img = reproject(&cave, &refs, &cam);
        let mut checked = 0;
        for y in (5..180).step_by(7) {
            for x in (5..280).step_by(7) {
                let ray = cam.ray(DVec2::new(f64::from(x) + 0.5, f64::from(y) + 0.5));
                let target = (eye + ray).as_vec3();
                let Some((w, px)) = cave.walls.iter().enumerate().find_map(|(i, wall)| {
                    let px = wall.pixel_of_ray(eye.as_vec3(), target)?;
                    // Away from the wall's border, where sampling clamps.
                    (px.x > 1.0 && px.y > 1.0 && px.x < 255.0 && px.y < 255.0).then_some((i, px))
                }) else {
                    continue;
                };
                let p = img.get_pixel(x, y).0;
                // 1 level: the ramp's value rounded, and f32 against f64 paths.
                assert!(
                    (f32::from(p[0]) - (px.x - 0.5)).abs() <= 1.0
                        && (f32::from(p[1]) - (px.y - 0.5)).abs() <= 1.0
                        && usize::from(p[2]) == w * 100,
                    "eye pixel ({x}, {y}): {p:?}, wall {w} pixel {px}"
                );
                checked += 1;
            }
        }
        assert!(checked > 500, "{checked}");
    }

    #[test]
    fn each_wall_shows_its_own_image() {
        let cave = thesis_cave();
        let colours = [[200u8, 0, 0, 255], [0, 200, 0, 255], [0, 0, 200, 255]];
        let images: Vec<RgbaImage> = colours
            .iter()
            .map(|c| RgbaImage::from_pixel(64, 36, Rgba(*c)))
            .collect();
        let refs: Vec<&RgbaImage> = images.iter().collect();
        let cam = EyeCamera::new(
            DVec3::new(0.0, 1.7, 0.0),
            DVec3::NEG_Z,
            [150.0, 60.0],
            [300, 100],
        )
        .unwrap();
        let img = reproject(&cave, &refs, &cam);
        // Left edge: the left wall; centre: the front wall; right edge: the right wall.
        assert_eq!(img.get_pixel(2, 50).0, colours[0]);
        assert_eq!(img.get_pixel(150, 50).0, colours[1]);
        assert_eq!(img.get_pixel(297, 50).0, colours[2]);
    }
}
