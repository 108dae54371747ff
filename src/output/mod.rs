//! Composes eye images into viewable outputs (anaglyph, walls unfolded side by side), draws
//! charts, and writes PNG files. CPU-side: used by the headless `render` command, the bench and
//! `omnicave guests`, and as the reference for tests.

use std::path::{Path, PathBuf};

use image::{Rgba, RgbaImage};

pub mod chart;
pub mod formats;

/// Writing output files failed.
#[derive(Debug, thiserror::Error)]
pub enum OutputError {
    #[error("cannot create output folder {path}: {source}")]
    CreateDir {
        path: PathBuf,
        source: std::io::Error,
    },
    #[error("cannot write image {path}: {source}")]
    Write {
        path: PathBuf,
        source: image::ImageError,
    },
    #[error("left and right images differ in size: {left:?} vs {right:?}")]
    SizeMismatch { left: (u32, u32), right: (u32, u32) },
}

/// Red-cyan anaglyph: red from the left eye, green and blue from the right eye.
pub fn anaglyph(left: &RgbaImage, right: &RgbaImage) -> Result<RgbaImage, OutputError> {
    if left.dimensions() != right.dimensions() {
        return Err(OutputError::SizeMismatch {
            left: left.dimensions(),
            right: right.dimensions(),
        });
    }
    Ok(formats::compose(
        formats::StereoFormat::Anaglyph,
        left,
        right,
        0,
        false,
    ))
}

/// Places images side by side, left to right, top-aligned, on black (the thesis's figures show
/// the walls this way).
pub fn unfold(images: &[&RgbaImage]) -> RgbaImage {
    let width: u32 = images.iter().map(|i| i.width()).sum();
    let height = images.iter().map(|i| i.height()).max().unwrap_or(0);
    let mut out = RgbaImage::from_pixel(width.max(1), height.max(1), Rgba([0, 0, 0, 255]));
    let mut x = 0;
    for img in images {
        image::imageops::replace(&mut out, *img, i64::from(x), 0);
        x += img.width();
    }
    out
}

/// Creates `dir` (and parents) if needed.
pub fn ensure_dir(dir: &Path) -> Result<(), OutputError> {
    std::fs::create_dir_all(dir).map_err(|source| OutputError::CreateDir {
        path: dir.to_owned(),
        source,
    })
}

/// Writes a PNG.
pub fn write_png(path: &Path, image: &RgbaImage) -> Result<(), OutputError> {
    image.save(path).map_err(|source| OutputError::Write {
        path: path.to_owned(),
        source,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn anaglyph_takes_red_from_left_and_cyan_from_right() {
        let left = RgbaImage::from_pixel(2, 1, Rgba([200, 10, 20, 255]));
        let right = RgbaImage::from_pixel(2, 1, Rgba([30, 40, 50, 255]));
        let a = anaglyph(&left, &right).expect("same size");
        assert_eq!(a.get_pixel(1, 0), &Rgba([200, 40, 50, 255]));
        assert!(anaglyph(&left, &RgbaImage::new(3, 1)).is_err());
    }

    #[test]
    fn unfold_places_walls_side_by_side() {
        let a = RgbaImage::from_pixel(2, 2, Rgba([255, 0, 0, 255]));
        let b = RgbaImage::from_pixel(3, 1, Rgba([0, 255, 0, 255]));
        let u = unfold(&[&a, &b]);
        assert_eq!(u.dimensions(), (5, 2));
        assert_eq!(u.get_pixel(1, 1), &Rgba([255, 0, 0, 255]));
        assert_eq!(u.get_pixel(4, 0), &Rgba([0, 255, 0, 255]));
        assert_eq!(u.get_pixel(4, 1), &Rgba([0, 0, 0, 255]));
    }
}
