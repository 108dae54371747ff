//! The renderer's per-frame data: the walls and the panorama keep their own uniforms and
//! tessellation output whatever the call order, and every frame's GPU time and tessellation
//! counts come back through the read-back ring without waiting.
#![allow(clippy::unwrap_used, clippy::expect_used)]

mod common;

use glam::Vec3;

use common::{NO_MSAA, cave_at, gpu, pano_settings, test_frame};
use omnicave::cave::omni::OmniSettings;
use omnicave::cave::{Cave, Head, RenderMode};
use omnicave::pano::{PanoRoute, PanoStereo, Projection};
use omnicave::render::{Renderer, ViewStage};
use omnicave::scene::load_gltf;
use omnicave::tess::{Criterion, TessSettings};

const HEAD: Vec3 = Vec3::new(0.2, 1.6, -0.3);

fn cave() -> Cave {
    cave_at(64, 36)
}

#[test]
fn walls_and_panorama_keep_their_own_frame_data_in_any_order() {
    // Each has its own uniforms and tessellation output: rendering the panorama between the
    // walls' frame and reading the walls back (images and tessellation counts) changes
    // nothing, and the panorama's counts describe its own eyes.
    let cave = cave();
    let scene = load_gltf(&repo_path("assets/living-room.glb")).expect("living room");
    let mut renderer = Renderer::new(gpu(), &cave, NO_MSAA).expect("renderer");
    renderer.set_scene(&scene).expect("scene upload");
    let tess = TessSettings {
        criterion: Some(Criterion::Error(1.0)),
        ..TessSettings::default()
    };
    let frame = test_frame(
        &cave,
        Head::at(HEAD),
        RenderMode::OmniOffAxis,
        OmniSettings::default(),
        tess,
    );
    renderer.render(&frame).expect("walls");
    let walls_alone = renderer.read_images().expect("read back");
    let stats_alone = renderer.read_tess_stats().expect("stats");
    assert_eq!(stats_alone.len(), cave.walls.len() * 2);

    let mut pano = pano_settings(
        Projection::Equirectangular,
        PanoRoute::Geometric,
        [360.0, 180.0],
    );
    pano.size = [128, 64];
    pano.stereo = PanoStereo::Omni;
    renderer.render_panorama(&frame, &pano).expect("panorama");
    let pano_stats = renderer.read_panorama_tess_stats().expect("panorama stats");
    assert_eq!(pano_stats.len(), 2, "one per panorama eye");
    assert_eq!(renderer.read_tess_stats().expect("stats"), stats_alone);
    let walls_after = renderer.read_images().expect("read back");
    for (a, b) in walls_alone.iter().zip(&walls_after) {
        assert!(a.left == b.left && a.right == b.right, "{} changed", a.wall);
    }
    // And the other order: the walls' frame leaves the panorama's counts as they were.
    renderer.render(&frame).expect("walls again");
    assert_eq!(
        renderer.read_panorama_tess_stats().expect("panorama stats"),
        pano_stats
    );
}

fn repo_path(rel: &str) -> std::path::PathBuf {
    std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join(rel)
}

#[test]
fn the_readback_ring_returns_each_frames_time_and_tessellation_counts_without_waiting() {
    // Every frame copies its timestamps and the walls' tessellation counts into a ring slot
    // mapped asynchronously: once the GPU has finished, polling returns them tagged with
    // their frame, equal to what a blocking read finds.
    let cave = cave();
    let scene = load_gltf(&repo_path("assets/living-room.glb")).expect("living room");
    let mut renderer = Renderer::new(gpu(), &cave, NO_MSAA).expect("renderer");
    let timed = renderer.enable_gpu_timing(gpu());
    renderer.set_scene(&scene).expect("scene upload");
    assert_eq!(renderer.poll_readbacks().frame, 0, "nothing rendered yet");
    let mut frame = test_frame(
        &cave,
        Head::at(HEAD),
        RenderMode::OmniOffAxis,
        OmniSettings::default(),
        TessSettings {
            criterion: Some(Criterion::Error(1.0)),
            ..TessSettings::default()
        },
    );
    // Alternate tessellated and plain frames: a plain frame reads back no counts (and, on a
    // device without timestamps, nothing at all: the newest read-back stays the previous one).
    for expected_frame in 1..=4 {
        let tessellated = expected_frame % 2 == 1;
        frame.tess.criterion = tessellated.then_some(Criterion::Error(1.0));
        renderer.render(&frame).expect("render");
        renderer.wait_idle().expect("idle");
        let blocking = renderer.read_tess_stats().expect("stats");
        let latest = renderer.poll_readbacks().clone();
        if !(timed || tessellated) {
            assert!(latest.frame < expected_frame);
            continue;
        }
        assert_eq!(latest.frame, expected_frame);
        assert_eq!(latest.tess, blocking, "frame {expected_frame}");
        assert_eq!(latest.gpu_ms.is_some(), timed);
        if timed {
            // The breakdown: the stages tile the frame (shadows + every view's six stages add
            // up to the whole, up to rounding of the sums), tessellation stages are empty in
            // a plain frame and not in a tessellated one, and the ring's copy is the one a
            // blocking read finds.
            let b = &latest.breakdown;
            assert_eq!(
                b.views.len(),
                cave.walls.len() * 2,
                "frame {expected_frame}"
            );
            let sum: f64 = b.pose_ms + b.shadows_ms + b.views.iter().flatten().sum::<f64>();
            assert!((sum - b.total_ms).abs() < 1e-6, "{sum} vs {}", b.total_ms);
            assert_eq!(Some(b.total_ms), latest.gpu_ms);
            let tess_ms = b.stage_ms(ViewStage::TessCull)
                + b.stage_ms(ViewStage::TessSplit)
                + b.stage_ms(ViewStage::TessSort);
            // Writing a timestamp itself takes microseconds, so an empty stage is not 0: a
            // plain frame's three tessellation stages per view stay within 5 % of its time
            // (measured here: 0.8 %), a tessellated frame's, with their 3 dispatches or more
            // per view, well above (measured: 15-25 % with 25 dispatches a view).
            if tessellated {
                assert!(tess_ms > 0.05 * b.total_ms, "frame {expected_frame}: {b:?}");
            } else {
                assert!(tess_ms < 0.05 * b.total_ms, "frame {expected_frame}: {b:?}");
            }
            assert!(b.stage_ms(ViewStage::Scene) > 0.0, "{b:?}");
            let blocking = renderer.read_gpu_breakdown().expect("read").expect("timed");
            assert_eq!(&blocking, b);
        }
        if tessellated {
            assert_eq!(latest.tess.len(), cave.walls.len() * 2);
            assert!(latest.tess.iter().all(|s| s.emitted > 0));
        } else {
            assert!(latest.tess.is_empty());
        }
    }
}
