//! Stereo output formats: how a wall's left and right eye images become the one image its
//! projector takes (wgpu has no quad-buffer swap chain). This is the CPU twin of
//! `shaders/present.wgsl`; tests compare the two.

use image::{Rgba, RgbaImage};

use crate::sky::cubemap::{linear_to_srgb, srgb_to_linear};

/// A stereo output format.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum StereoFormat {
    /// One eye per presented frame, alternating (active shutter glasses at 120 Hz).
    FrameSequential,
    /// Left | right; `half` squeezes each eye to half the width (the output keeps the eye size).
    SideBySide {
        half: bool,
    },
    /// Left over right; `half` squeezes each eye to half the height.
    TopBottom {
        half: bool,
    },
    /// HDMI 1.4 frame packing: left on top, a blank band of 1/24 of the height, right below
    /// (1280×720 → 1280×1470, 1920×1080 → 1920×2205).
    FramePacking,
    /// Alternate rows (passive polarised 3D monitors): even rows left, odd rows right.
    RowInterleaved,
    /// Red-cyan: red from the left eye, green and blue from the right.
    Anaglyph,
    /// Red-cyan with less retinal rivalry: red from the left eye's green and blue
    /// (0.7 G + 0.3 B, in linear light), green and blue from the right.
    AnaglyphOptimized,
    LeftOnly,
    RightOnly,
    /// The left image (for mono rendering, where both eyes are the same).
    Mono,
}

crate::named_enum!(StereoFormat {
    Self::FrameSequential => "frame-sequential",
    Self::SideBySide { half: false } => "side-by-side",
    Self::SideBySide { half: true } => "side-by-side-half",
    Self::TopBottom { half: false } => "top-bottom",
    Self::TopBottom { half: true } => "top-bottom-half",
    Self::FramePacking => "frame-packing",
    Self::RowInterleaved => "row-interleaved",
    Self::Anaglyph => "anaglyph",
    Self::AnaglyphOptimized => "anaglyph-optimized",
    Self::LeftOnly => "left-only",
    Self::RightOnly => "right-only",
    Self::Mono => "mono",
});

impl StereoFormat {
    /// The output image size for eye images of `eye` = [width, height].
    pub fn output_size(self, [w, h]: [u32; 2]) -> [u32; 2] {
        match self {
            Self::SideBySide { half: false } => [2 * w, h],
            Self::TopBottom { half: false } => [w, 2 * h],
            Self::FramePacking => [w, 2 * h + frame_packing_gap(h)],
            _ => [w, h],
        }
    }

    /// Shader code of the format (keep in sync with shaders/present.wgsl).
    pub fn code(self) -> u32 {
        match self {
            Self::FrameSequential => 0,
            Self::SideBySide { half: false } => 1,
            Self::SideBySide { half: true } => 2,
            Self::TopBottom { half: false } => 3,
            Self::TopBottom { half: true } => 4,
            Self::FramePacking => 5,
            Self::RowInterleaved => 6,
            Self::Anaglyph => 7,
            Self::AnaglyphOptimized => 8,
            Self::LeftOnly => 9,
            Self::RightOnly => 10,
            Self::Mono => 11,
        }
    }
}

/// The blank band of HDMI frame packing: 45 lines at 1080, 30 at 720 (1/24 of the height).
pub fn frame_packing_gap(height: u32) -> u32 {
    height / 24
}

/// Which eye image a source is, after the swap-eyes toggle.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Source {
    Left,
    Right,
}

fn linear(p: &Rgba<u8>) -> [f32; 3] {
    [
        srgb_to_linear(p[0]),
        srgb_to_linear(p[1]),
        srgb_to_linear(p[2]),
    ]
}

fn encode(c: [f32; 3]) -> Rgba<u8> {
    Rgba([
        linear_to_srgb(c[0]),
        linear_to_srgb(c[1]),
        linear_to_srgb(c[2]),
        255,
    ])
}

/// Mean of two pixels in linear light (what squeezing an eye to half size does).
fn average(a: &Rgba<u8>, b: &Rgba<u8>) -> Rgba<u8> {
    let (a, b) = (linear(a), linear(b));
    encode([
        0.5 * (a[0] + b[0]),
        0.5 * (a[1] + b[1]),
        0.5 * (a[2] + b[2]),
    ])
}

/// Composes a wall's eye images (same size) into `format`. `frame` is the index of the
/// presented frame (frame-sequential shows the left eye on even frames); `swap_eyes` exchanges
/// the eyes everywhere (for glasses or projectors wired the other way round).
pub fn compose(
    format: StereoFormat,
    left: &RgbaImage,
    right: &RgbaImage,
    frame: u64,
    swap_eyes: bool,
) -> RgbaImage {
    let (w, h) = left.dimensions();
    let [ow, oh] = format.output_size([w, h]);
    let (first, second) = if swap_eyes {
        (right, left)
    } else {
        (left, right)
    };
    let eye = |s: Source| match s {
        Source::Left => first,
        Source::Right => second,
    };
    let at = |s: Source, x: u32, y: u32| *eye(s).get_pixel(x.min(w - 1), y.min(h - 1));
    let gap = frame_packing_gap(h);
    RgbaImage::from_fn(ow, oh, |x, y| match format {
        StereoFormat::FrameSequential => at(
            if frame.is_multiple_of(2) {
                Source::Left
            } else {
                Source::Right
            },
            x,
            y,
        ),
        StereoFormat::SideBySide { half: false } => {
            if x < w {
                at(Source::Left, x, y)
            } else {
                at(Source::Right, x - w, y)
            }
        }
        StereoFormat::SideBySide { half: true } => {
            let half = w / 2;
            let (s, x) = if x < half {
                (Source::Left, x)
            } else {
                (Source::Right, x - half)
            };
            average(&at(s, 2 * x, y), &at(s, 2 * x + 1, y))
        }
        StereoFormat::TopBottom { half: false } => {
            if y < h {
                at(Source::Left, x, y)
            } else {
                at(Source::Right, x, y - h)
            }
        }
        StereoFormat::TopBottom { half: true } => {
            let half = h / 2;
            let (s, y) = if y < half {
                (Source::Left, y)
            } else {
                (Source::Right, y - half)
            };
            average(&at(s, x, 2 * y), &at(s, x, 2 * y + 1))
        }
        StereoFormat::FramePacking => {
            if y < h {
                at(Source::Left, x, y)
            } else if y < h + gap {
                Rgba([0, 0, 0, 255])
            } else {
                at(Source::Right, x, y - h - gap)
            }
        }
        StereoFormat::RowInterleaved => at(
            if y % 2 == 0 {
                Source::Left
            } else {
                Source::Right
            },
            x,
            y,
        ),
        StereoFormat::Anaglyph => {
            let (l, r) = (at(Source::Left, x, y), at(Source::Right, x, y));
            Rgba([l[0], r[1], r[2], 255])
        }
        StereoFormat::AnaglyphOptimized => {
            let (l, r) = (linear(&at(Source::Left, x, y)), at(Source::Right, x, y));
            Rgba([linear_to_srgb(0.7 * l[1] + 0.3 * l[2]), r[1], r[2], 255])
        }
        StereoFormat::LeftOnly | StereoFormat::Mono => at(Source::Left, x, y),
        StereoFormat::RightOnly => at(Source::Right, x, y),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn eye(rgb: [u8; 3], w: u32, h: u32) -> RgbaImage {
        RgbaImage::from_fn(w, h, |x, y| {
            Rgba([
                rgb[0],
                rgb[1].wrapping_add(x as u8),
                rgb[2].wrapping_add(y as u8),
                255,
            ])
        })
    }

    #[test]
    fn names_round_trip_and_sizes() {
        for f in StereoFormat::ALL {
            assert_eq!(StereoFormat::from_name(f.name()), Some(f));
        }
        assert_eq!(
            StereoFormat::FramePacking.output_size([1920, 1080]),
            [1920, 2205]
        );
        assert_eq!(
            StereoFormat::FramePacking.output_size([1280, 720]),
            [1280, 1470]
        );
        assert_eq!(
            StereoFormat::SideBySide { half: false }.output_size([640, 360]),
            [1280, 360]
        );
    }

    #[test]
    fn formats_take_each_pixel_from_the_right_eye() {
        let (l, r) = (eye([200, 0, 0], 8, 6), eye([10, 100, 50], 8, 6));
        let seq0 = compose(StereoFormat::FrameSequential, &l, &r, 0, false);
        let seq1 = compose(StereoFormat::FrameSequential, &l, &r, 1, false);
        assert_eq!((seq0, seq1), (l.clone(), r.clone()));
        let swapped = compose(StereoFormat::FrameSequential, &l, &r, 0, true);
        assert_eq!(swapped, r);
        let rows = compose(StereoFormat::RowInterleaved, &l, &r, 0, false);
        for y in 0..6 {
            let src = if y % 2 == 0 { &l } else { &r };
            assert_eq!(rows.get_pixel(3, y), src.get_pixel(3, y));
        }
        let packed = compose(StereoFormat::FramePacking, &l, &r, 0, false);
        assert_eq!(packed.height(), 12);
        let ana = compose(StereoFormat::Anaglyph, &l, &r, 0, false);
        assert_eq!(ana.get_pixel(2, 2)[0], l.get_pixel(2, 2)[0]);
        assert_eq!(ana.get_pixel(2, 2)[1], r.get_pixel(2, 2)[1]);
        let sbs = compose(StereoFormat::SideBySide { half: true }, &l, &r, 0, false);
        assert_eq!(sbs.dimensions(), (8, 6));
        assert_eq!(sbs.get_pixel(5, 1)[0], 10);
    }
}
