//! Stereo output formats composed on the GPU (shaders/present.wgsl) from real eye images: each
//! equals its CPU twin (src/output/formats.rs) and has the structure a projector expects.
#![allow(clippy::unwrap_used, clippy::expect_used)]

mod common;

use glam::Vec3;
use image::RgbaImage;

use common::{NO_MSAA, cave_at, gpu, test_frame};
use omnicave::cave::omni::OmniSettings;
use omnicave::cave::{Head, RenderMode};
use omnicave::output::formats::{StereoFormat, compose, frame_packing_gap};
use omnicave::render::Renderer;
use omnicave::render::present::PresentParams;
use omnicave::tess::TessSettings;

/// Largest per-channel difference between two images of the same size.
fn max_diff(a: &RgbaImage, b: &RgbaImage) -> u8 {
    assert_eq!(a.dimensions(), b.dimensions());
    a.as_raw()
        .iter()
        .zip(b.as_raw())
        .map(|(x, y)| x.abs_diff(*y))
        .max()
        .unwrap_or(0)
}

#[test]
fn every_format_matches_its_cpu_twin_and_its_layout() {
    // Odd-free even sizes so the half formats divide exactly.
    let cave = cave_at(96, 54);
    let scene = omnicave::scene::load_gltf(std::path::Path::new(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/assets/living-room.glb"
    )))
    .unwrap();
    let mut renderer = Renderer::new(gpu(), &cave, NO_MSAA).unwrap();
    renderer.set_scene(&scene).expect("scene upload");
    renderer
        .render(&test_frame(
            &cave,
            Head::at(Vec3::new(0.2, 1.6, -0.2)),
            RenderMode::OmniOffAxis,
            OmniSettings::default(),
            TessSettings::default(),
        ))
        .unwrap();
    let walls = renderer.read_images().unwrap();
    for (index, wall) in walls.iter().enumerate() {
        let (l, r) = (&wall.left, &wall.right);
        assert_ne!(l, r, "the eyes must differ for the test to mean anything");
        for format in StereoFormat::ALL {
            for (frame, swap) in [(0u64, false), (1, false), (2, true)] {
                let params = PresentParams {
                    format,
                    frame,
                    swap_eyes: swap,
                };
                let gpu_img = renderer.compose(index, params).unwrap();
                let cpu_img = compose(format, l, r, frame, swap);
                // Copies are exact (sRGB decode and encode of 8-bit values round-trip); formats
                // that mix pixels in linear light may round differently by one step.
                let tolerance = match format {
                    StereoFormat::SideBySide { half: true }
                    | StereoFormat::TopBottom { half: true }
                    | StereoFormat::AnaglyphOptimized => 1,
                    _ => 0,
                };
                let d = max_diff(&gpu_img, &cpu_img);
                assert!(
                    d <= tolerance,
                    "{} {format} frame {frame} swap {swap}: GPU and CPU differ by {d}",
                    wall.wall
                );
            }
        }
        // The layouts, checked on the CPU twin (equal to the GPU above).
        let (w, h) = l.dimensions();
        let (first, second) = (l, r);
        let sbs = compose(StereoFormat::SideBySide { half: false }, l, r, 0, false);
        assert_eq!(
            image::imageops::crop_imm(&sbs, 0, 0, w, h).to_image(),
            *first
        );
        assert_eq!(
            image::imageops::crop_imm(&sbs, w, 0, w, h).to_image(),
            *second
        );
        let tb = compose(StereoFormat::TopBottom { half: false }, l, r, 0, false);
        assert_eq!(image::imageops::crop_imm(&tb, 0, h, w, h).to_image(), *r);
        // Side-by-side half: each half is the eye image downscaled 2:1 horizontally.
        let half = compose(StereoFormat::SideBySide { half: true }, l, r, 0, false);
        assert_eq!(half.dimensions(), (w, h));
        let squeezed_right = image::imageops::crop_imm(&half, w / 2, 0, w / 2, h).to_image();
        let downscaled =
            image::imageops::resize(r, w / 2, h, image::imageops::FilterType::Triangle);
        // `resize` filters in sRGB values and with a wider kernel: close, not equal.
        let mean_abs: f64 = squeezed_right
            .as_raw()
            .iter()
            .zip(downscaled.as_raw())
            .map(|(a, b)| f64::from(a.abs_diff(*b)))
            .sum::<f64>()
            / squeezed_right.as_raw().len() as f64;
        assert!(
            mean_abs < 6.0,
            "{}: half image vs downscaled right eye: {mean_abs}",
            wall.wall
        );
        // Frame-sequential alternates eyes on successive frames, and the swap toggle flips it.
        for frame in 0..4u64 {
            let img = compose(StereoFormat::FrameSequential, l, r, frame, false);
            assert_eq!(&img, if frame % 2 == 0 { l } else { r }, "frame {frame}");
            let swapped = compose(StereoFormat::FrameSequential, l, r, frame, true);
            assert_eq!(
                &swapped,
                if frame % 2 == 0 { r } else { l },
                "frame {frame} swapped"
            );
        }
        // Row-interleaved: even rows from the left eye, odd rows from the right.
        let rows = compose(StereoFormat::RowInterleaved, l, r, 0, false);
        for y in 0..h {
            for x in 0..w {
                let src = if y % 2 == 0 { l } else { r };
                assert_eq!(rows.get_pixel(x, y), src.get_pixel(x, y));
            }
        }
        // Anaglyphs: green and blue from the right eye, red from the left.
        for f in [StereoFormat::Anaglyph, StereoFormat::AnaglyphOptimized] {
            let a = compose(f, l, r, 0, false);
            for (x, y, p) in a.enumerate_pixels() {
                let (lp, rp) = (l.get_pixel(x, y), r.get_pixel(x, y));
                assert_eq!((p[1], p[2]), (rp[1], rp[2]), "{f}");
                if f == StereoFormat::Anaglyph {
                    assert_eq!(p[0], lp[0]);
                }
            }
        }
        // Frame packing: left, a black band of h/24 rows, right.
        let packed = compose(StereoFormat::FramePacking, l, r, 0, false);
        let gap = frame_packing_gap(h);
        assert_eq!(packed.dimensions(), (w, 2 * h + gap));
        assert!((h..h + gap).all(|y| (0..w).all(|x| packed.get_pixel(x, y).0 == [0, 0, 0, 255])));
        assert_eq!(
            image::imageops::crop_imm(&packed, 0, h + gap, w, h).to_image(),
            *r
        );
    }
}
