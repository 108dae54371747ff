//! Adaptive tessellation: the compute tessellator against its CPU twin, watertightness, the
//! geometric and seam error it leaves, triangle counts per criterion, the output budget, and
//! scenes whose vertices exceed one storage binding.
#![allow(clippy::unwrap_used, clippy::expect_used)]

mod common;

use std::path::Path;

use common::*;
use glam::{Mat4, Vec3, Vec3Swizzles};
use omnicave::cave::omni::OmniSettings;
use omnicave::cave::{Cave, Head, RenderMode, ViewSetup, view_setups};
use omnicave::render::tessellator::GpuTessEntry;
use omnicave::render::{Renderer, WallImages};
use omnicave::scene::build::grid;
use omnicave::scene::{Scene, load_gltf};
use omnicave::tess::error::{ErrorStats, drawn_point, edge_errors};
use omnicave::tess::{
    Bary, Criterion, TessOutput, TessSettings, TessTriangle, double_sided_flags, point_position,
    shared_partner, tess_view, tessellate,
};

const CAPACITY: usize = 1 << 20;

fn settings(criterion: Option<Criterion>) -> TessSettings {
    TessSettings {
        criterion,
        ..TessSettings::default()
    }
}

/// The GPU's output entries as the twin's triangles, sorted (the GPU's order is not fixed).
fn sorted_triangles(entries: &[GpuTessEntry]) -> Vec<TessTriangle> {
    let mut triangles: Vec<TessTriangle> = entries
        .iter()
        .map(|e| TessTriangle {
            source: e.source,
            corners: e.corners.map(|[b1, b2]| Bary { b1, b2 }),
        })
        .collect();
    triangles.sort();
    triangles
}

/// The CPU twin for every view of a frame: (view, output).
fn cpu_views(
    cave: &Cave,
    head: Vec3,
    mode: RenderMode,
    scene: &Scene,
    tess: &TessSettings,
) -> Vec<(ViewSetup, TessOutput)> {
    cpu_views_in(cave, head, mode, scene, tess, CAPACITY)
}

/// [`cpu_views`] with an output budget of `capacity`.
fn cpu_views_in(
    cave: &Cave,
    head: Vec3,
    mode: RenderMode,
    scene: &Scene,
    tess: &TessSettings,
    capacity: usize,
) -> Vec<(ViewSetup, TessOutput)> {
    let flags = double_sided_flags(scene);
    let views = view_setups(cave, &Head::at(head), mode, 0.064);
    views
        .iter()
        .enumerate()
        .map(|(i, v)| {
            let tv = tess_view(
                v,
                &cave.walls[v.wall],
                Mat4::IDENTITY,
                Some(OmniSettings::default()),
            );
            // Both eyes of a wall share one refinement, as the renderer draws them.
            let tv = match shared_partner(&views, i, tess) {
                Some(other) => tv.paired_with(other),
                None => tv,
            };
            let out = tessellate(scene, &flags, &tv, tess, capacity);
            (*v, out)
        })
        .collect()
}

fn living_room() -> Scene {
    load_gltf(&Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/living-room.glb")).unwrap()
}

fn city() -> Scene {
    load_gltf(&Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/city.glb")).unwrap()
}

/// A box room around the CAVE, each face its own primitive and colour (unlit, inward-facing,
/// single-sided), its faces crossing two CAVE walls each.
fn box_room() -> Scene {
    let (lo, hi) = (Vec3::new(-2.6, -0.4, -2.4), Vec3::new(2.2, 3.3, 2.8));
    let d = hi - lo;
    let faces = [
        (Vec3::new(lo.x, lo.y, lo.z), Vec3::X * d.x, Vec3::Y * d.y), // front (z = lo)
        (
            Vec3::new(hi.x, lo.y, hi.z),
            Vec3::NEG_X * d.x,
            Vec3::Y * d.y,
        ), // back
        (
            Vec3::new(lo.x, lo.y, hi.z),
            Vec3::NEG_Z * d.z,
            Vec3::Y * d.y,
        ), // left
        (Vec3::new(hi.x, lo.y, lo.z), Vec3::Z * d.z, Vec3::Y * d.y), // right
        (
            Vec3::new(lo.x, lo.y, hi.z),
            Vec3::X * d.x,
            Vec3::NEG_Z * d.z,
        ), // floor
        (Vec3::new(lo.x, hi.y, lo.z), Vec3::X * d.x, Vec3::Z * d.z), // ceiling
    ];
    // Six distinct exact colours (the marker palette).
    let colours = &MARKER_COLOURS[..6];
    let mut scene = Scene::default();
    for ((o, u, v), c) in faces.iter().zip(colours.iter().copied()) {
        // Snapped: faces meeting at an edge share its ends bit for bit (watertight).
        let mesh = grid(*o, *u, *v, 1, 1, 1.0).snapped_to_box(lo, hi);
        let m = scene.add_material(omnicave::scene::Material {
            double_sided: false,
            ..omnicave::scene::Material::unlit("face", c.map(|x| f32::from(x) / 255.0))
        });
        scene.add_mesh(&mesh.vertices, &mesh.indices, m);
    }
    scene
}

#[test]
fn gpu_and_cpu_subdivision_agree_exactly() {
    // One wall, omnistereo: the last view rendered is the right eye, whose output the GPU
    // buffers still hold after the frame.
    let mut cave = cave_at(640, 360);
    cave.walls.truncate(2); // left and front walls
    let head = Vec3::new(-0.4, 1.5, 0.3);
    let room = box_room();
    let city = city();
    // (criterion, max depth, scene): uniform:3 capped at depth 2 reaches the maximum depth
    // inside the culling dispatch, which splits SPLIT_LEVELS = 12 levels itself and emits the
    // triangles that reach it; on the city at depth 14, error:0.05 splits the ground near the
    // viewer beyond 12 levels, in a split dispatch of its own (asserted below).
    for (criterion, max_depth, scene) in [
        (Criterion::Uniform(3), 6, &room),
        (Criterion::Uniform(3), 2, &room),
        (Criterion::Uniform(5), 6, &room),
        (Criterion::Edge(40.0), 6, &room),
        (Criterion::Sphere(60.0), 6, &room),
        (Criterion::Error(1.0), 6, &room),
        (Criterion::Error(0.05), 14, &city),
    ] {
        let tess = TessSettings {
            max_depth,
            ..settings(Some(criterion))
        };
        let (_, stats, entries) = render_tess(
            &cave,
            Head::at(head),
            RenderMode::OmniOnAxis,
            scene,
            tess,
            None,
        );
        let cpu = cpu_views(&cave, head, RenderMode::OmniOnAxis, scene, &tess);
        let (_, last) = cpu.last().unwrap();
        let gpu = sorted_triangles(&entries);
        let mut expected = last.triangles.clone();
        expected.sort();
        let gpu_stats = stats.last().unwrap();
        assert_eq!(
            gpu_stats.culled_backface, last.stats.culled_backface,
            "{criterion}"
        );
        assert_eq!(
            gpu_stats.culled_frustum, last.stats.culled_frustum,
            "{criterion}"
        );
        assert_eq!(
            gpu.len(),
            expected.len(),
            "{criterion}: triangle counts differ"
        );
        assert!(gpu == expected, "{criterion}: GPU and CPU triangles differ");
        // More output triangles than the source triangles they come from: something split.
        let sources: std::collections::HashSet<u32> = gpu.iter().map(|t| t.source).collect();
        assert!(gpu.len() > sources.len(), "{criterion}: nothing was split");
        if max_depth > omnicave::render::tessellator::SPLIT_LEVELS {
            // The split dispatches after the culling dispatch's own levels did run.
            let deepest = entries.iter().map(|e| e.depth).max().unwrap_or(0);
            assert!(
                deepest > omnicave::render::tessellator::SPLIT_LEVELS,
                "{criterion} depth {max_depth}: deepest output triangle at depth {deepest}"
            );
        }
        // Every view's statistics add up.
        for s in &stats {
            assert!(s.culled_backface + s.culled_frustum <= s.input);
            assert!(!s.overflowed);
        }
    }
}

/// Background pixels (cracks) in every wall's eye images of a scene that surrounds the viewer.
fn background_pixels(images: &[WallImages]) -> usize {
    images
        .iter()
        .flat_map(|wall| [&wall.left, &wall.right])
        .map(|img| {
            img.pixels()
                .filter(|p| p[0] == 0 && p[1] == 0 && p[2] == 0)
                .count()
        })
        .sum()
}

/// No crack at any criterion and depth, whether the output budget holds the refinement or not:
/// the room surrounds the viewer, so every pixel of every wall and eye lies inside its
/// silhouette and any background pixel is a crack (the tolerance is zero pixels). Every
/// criterion runs in a budget of 2¹⁶ triangles a view, which `uniform:7` and deeper overflow;
/// the adaptive ones also in budgets of 3 000 and 40, which they overflow; `uniform:10` and
/// `uniform:16` also in the default budget (2²⁰), where they cracked before the fallback
/// existed. A view whose budget ran out must say so, with the depth it fell back to, and its
/// triangles must be exactly the CPU twin's (the fallback refuses no split: deterministic).
#[test]
fn a_closed_room_has_no_cracks_with_any_criterion_in_or_over_budget() {
    let cave = cave_at(480, 270);
    let scene = box_room();
    let uniform = |n| Some(Criterion::Uniform(n));
    let adaptive = [
        Some(Criterion::Edge(12.0)),
        Some(Criterion::Sphere(20.0)),
        Some(Criterion::Error(0.5)),
    ];
    let mut medium = vec![None];
    medium.extend((1..=16).map(uniform));
    medium.extend(adaptive);
    let budgets: [(u32, Vec<Option<Criterion>>); 4] = [
        (CAPACITY as u32, vec![uniform(10), uniform(16)]),
        (1 << 16, medium),
        (3_000, adaptive.to_vec()),
        (40, adaptive.to_vec()),
    ];
    let mut overflowed = Vec::new();
    for (budget, criteria) in &budgets {
        // One renderer per budget (building one costs more than a frame).
        let mut renderer = Renderer::new(gpu(), &cave, NO_MSAA).unwrap();
        renderer.set_tess_capacity(*budget);
        renderer.set_scene(&scene).unwrap();
        // The centre, 0.35 m from the front wall, and (outside the long medium sweep) 5 cm
        // from the right wall, where the warp bends hardest.
        let mut heads = vec![Vec3::new(0.0, 1.7, 0.0), Vec3::new(1.2, 1.0, -1.3)];
        if *budget != 1 << 16 {
            heads.push(Vec3::new(1.6, 1.6, 0.3));
        }
        for head in heads {
            for &criterion in criteria {
                let mut tess = settings(criterion);
                if let Some(Criterion::Uniform(n)) = criterion {
                    tess.max_depth = n;
                }
                let mode = RenderMode::OmniOnAxis;
                let frame = test_frame(&cave, Head::at(head), mode, OmniSettings::default(), tess);
                renderer.render(&frame).unwrap();
                let label = format!("{criterion:?} in a budget of {budget} from {head}");
                let cracks = background_pixels(&renderer.read_images().unwrap());
                assert_eq!(cracks, 0, "cracks with {label}");
                let stats = renderer.read_tess_stats().unwrap();
                for s in &stats {
                    assert!(s.emitted <= *budget, "{label}: {} emitted", s.emitted);
                    assert_eq!(s.overflowed, s.fallback_depth.is_some(), "{label}: {s:?}");
                }
                if stats.iter().any(|s| s.overflowed) {
                    overflowed.push((criterion, *budget));
                }
                // The last view (the one whose triangles can be read) against the twin.
                let Some(last) = stats.last() else { continue };
                let Some(depth) = last.fallback_depth else {
                    continue;
                };
                assert!(
                    depth < tess.max_depth,
                    "{label}: fell back to depth {depth}"
                );
                let note = last.shortfall(&tess, *budget).unwrap();
                assert!(
                    note.contains(&budget.to_string()) && note.contains(&format!("depth {depth}")),
                    "{label}: {note}"
                );
                let cpu = cpu_views_in(&cave, head, mode, &scene, &tess, *budget as usize);
                let (_, twin) = cpu.last().unwrap();
                assert_eq!(twin.stats.fallback_depth, Some(depth), "{label}");
                let gpu = sorted_triangles(&renderer.read_tess_entries().unwrap());
                let mut expected = twin.triangles.clone();
                expected.sort();
                assert!(gpu == expected, "{label}: GPU and CPU fallbacks differ");
            }
        }
    }
    // The corners this test exists for were reached: every uniform depth the budget cannot
    // hold, at both heads, and every adaptive criterion in the smallest budget.
    for n in [10, 16] {
        let hits = overflowed
            .iter()
            .filter(|c| **c == (uniform(n), CAPACITY as u32));
        assert_eq!(
            hits.count(),
            3,
            "uniform:{n} in the default budget: {overflowed:?}"
        );
    }
    for n in 7..=16 {
        let hits = overflowed.iter().filter(|c| **c == (uniform(n), 1 << 16));
        assert_eq!(hits.count(), 2, "uniform:{n} in 2^16: {overflowed:?}");
    }
    for c in adaptive {
        assert!(overflowed.contains(&(c, 40)), "{c:?} in 40: {overflowed:?}");
    }
}

/// Geometric error of a whole frame (all views) with the CPU twin.
fn frame_error(cave: &Cave, head: Vec3, scene: &Scene, tess: &TessSettings) -> (ErrorStats, u32) {
    let mut all = Vec::new();
    let mut emitted = 0;
    for (view, out) in cpu_views(cave, head, RenderMode::OmniOnAxis, scene, tess) {
        let tv = tess_view(
            &view,
            &cave.walls[view.wall],
            Mat4::IDENTITY,
            Some(OmniSettings::default()),
        );
        all.extend(edge_errors(scene, &tv, &out, 8));
        emitted += out.stats.emitted;
    }
    (ErrorStats::from_samples(all), emitted)
}

#[test]
fn the_error_criterion_bounds_the_geometric_error() {
    let cave = cave_at(1280, 720);
    let heads = [
        Vec3::new(0.0, 1.7, 0.0),
        Vec3::new(0.8, 1.3, -0.6),
        Vec3::new(-1.35, 1.6, 0.2), // 0.3 m from the left wall
    ];
    let error = |depth| TessSettings {
        criterion: Some(Criterion::Error(0.5)),
        max_depth: depth,
        ..TessSettings::default()
    };
    for (name, scene) in [("living room", living_room()), ("city", city())] {
        for head in heads {
            let (plain, _) = frame_error(&cave, head, &scene, &settings(None));
            let (dd, _) = frame_error(
                &cave,
                head,
                &scene,
                &error(TessSettings::default().max_depth),
            );
            // At the default depth the criterion bounds what the viewer sees: its threshold at
            // three points along each edge that fails the chord test, and at most about twice
            // that anywhere along an edge.
            assert!(dd.p99 <= 0.5, "{name} {head}: p99 {}", dd.p99);
            assert!(dd.max <= 1.0, "{name} {head}: max {}", dd.max);
            // The plain warp is visibly wrong everywhere; most of all in the living room, whose
            // floor and walls are single large quads (the city's far geometry bends less).
            let visibly_wrong = if name == "city" { 2.0 } else { 10.0 };
            assert!(
                plain.max > visibly_wrong,
                "{name} {head}: plain warp max {}",
                plain.max
            );
        }
    }
}

/// Largest jump, where the left wall meets the front wall, of straight lines drawn across the
/// living room's floor (the parquet pattern follows such lines): each line is followed
/// through the floor's drawn triangles on both walls and intersected with the shared border.
fn floor_seam_jump(cave: &Cave, scene: &Scene, head: Vec3, tess: &TessSettings) -> f32 {
    let (left, front) = (
        cave.wall_index("left").unwrap(),
        cave.wall_index("front").unwrap(),
    );
    // The floor: the two large triangles at y = 0.
    let floor: Vec<u32> = (0..scene.triangle_count() as u32)
        .filter(|&t| {
            let p = [0, 1, 2].map(|k| {
                Vec3::from(scene.vertices[scene.indices[3 * t as usize + k] as usize].position)
            });
            p.iter().all(|q| q.y == 0.0) && (p[1] - p[0]).cross(p[2] - p[0]).length() > 10.0
        })
        .collect();
    assert_eq!(floor.len(), 2, "the living room's floor is one quad");
    let views = cpu_views(cave, head, RenderMode::OmniOnAxis, scene, tess);
    let drawn = |wall: usize, eye, q: Vec3| -> Option<glam::Vec2> {
        let (view, out) = views
            .iter()
            .find(|(v, _)| v.wall == wall && v.eye == Some(eye))?;
        let tv = tess_view(
            view,
            &cave.walls[wall],
            Mat4::IDENTITY,
            Some(OmniSettings::default()),
        );
        floor.iter().find_map(|&t| {
            let p = [0, 1, 2].map(|k| {
                Vec3::from(scene.vertices[scene.indices[3 * t as usize + k] as usize].position)
            });
            let (a, b, c) = (p[0].xz(), p[1].xz(), p[2].xz());
            let area = (b - a).perp_dot(c - a);
            let w1 = (q.xz() - a).perp_dot(c - a) / area;
            let w2 = (b - a).perp_dot(q.xz() - a) / area;
            (w1 >= 0.0 && w2 >= 0.0 && w1 + w2 <= 1.0)
                .then(|| drawn_point(scene, &tv, out, t, w1, w2))
                .flatten()
        })
    };
    let border = |wall: usize, eye, a: Vec3, b: Vec3, x: f32| -> Option<f32> {
        let steps = 600;
        let mut prev: Option<glam::Vec2> = None;
        for i in 0..=steps {
            let cur = drawn(wall, eye, a.lerp(b, i as f32 / steps as f32));
            if let (Some(p), Some(c)) = (prev, cur) {
                let (pa, pb) = (p.x - x, c.x - x);
                if pa * pb <= 0.0 && pa != pb {
                    return Some(p.y + pa / (pa - pb) * (c.y - p.y));
                }
            }
            prev = cur;
        }
        None
    };
    let mut worst: f32 = 0.0;
    let lines = [
        (Vec3::new(-2.95, 0.0, -2.2), Vec3::new(-1.0, 0.0, -2.2)),
        (Vec3::new(-2.95, 0.0, -2.7), Vec3::new(-1.0, 0.0, -2.7)),
        (Vec3::new(-2.95, 0.0, -3.3), Vec3::new(-1.0, 0.0, -3.3)),
        (Vec3::new(-2.2, 0.0, -1.0), Vec3::new(-2.2, 0.0, -3.45)),
        (Vec3::new(-2.8, 0.0, -1.0), Vec3::new(-2.8, 0.0, -3.45)),
    ];
    for eye in [omnicave::cave::Eye::Left, omnicave::cave::Eye::Right] {
        for (a, b) in lines {
            let on_left = border(left, eye, a, b, cave.walls[left].resolution[0] as f32);
            let on_front = border(front, eye, a, b, 0.0);
            if let (Some(l), Some(f)) = (on_left, on_front) {
                worst = worst.max((l - f).abs());
            }
        }
    }
    worst
}

#[test]
fn tessellation_closes_the_seams_of_the_plain_warp() {
    let cave = cave_at(1280, 720);
    let scene = living_room();
    for head in [Vec3::new(0.0, 1.7, 0.0), Vec3::new(0.5, 1.5, 0.4)] {
        let plain = floor_seam_jump(&cave, &scene, head, &settings(None));
        let tess = floor_seam_jump(&cave, &scene, head, &settings(Some(Criterion::Error(0.5))));
        assert!(plain > 2.0, "the plain warp should show the jump");
        // 1 px: the acceptance tolerance.
        assert!(tess <= 1.0, "seam jump {tess} px with tessellation");
    }
}

#[test]
fn triangle_counts_at_equal_error() {
    // For each criterion, the coarsest setting that reaches the target on the living room
    // (centred head), and the triangles it emits over the six views. The target is p99 <= 0.5
    // px as asked, and also max <= 1 px: on this scene p99 over its ~18 000 edges is ~0 even
    // for the plain warp, since the error lives in a few dozen long edges (floor, walls).
    let cave = cave_at(1280, 720);
    let scene = living_room();
    let head = Vec3::new(0.0, 1.7, 0.0);
    let target = 0.5;
    let candidates: Vec<(&str, Vec<Criterion>)> = vec![
        ("uniform", (0..=6).map(Criterion::Uniform).collect()),
        (
            "edge",
            [
                4096.0, 2048.0, 1024.0, 512.0, 256.0, 128.0, 64.0, 32.0, 16.0,
            ]
            .map(Criterion::Edge)
            .to_vec(),
        ),
        (
            "sphere",
            [
                4096.0, 2048.0, 1024.0, 512.0, 256.0, 128.0, 64.0, 32.0, 16.0,
            ]
            .map(Criterion::Sphere)
            .to_vec(),
        ),
        (
            "error",
            [16.0, 8.0, 4.0, 2.0, 1.0, 0.5, 0.25]
                .map(Criterion::Error)
                .to_vec(),
        ),
    ];
    let mut results = Vec::new();
    for (name, list) in candidates {
        // The coarsest setting that reaches the target, and its triangle count.
        let found = list.into_iter().find_map(|c| {
            let (e, n) = frame_error(&cave, head, &scene, &settings(Some(c)));
            (e.p99 <= target && e.max <= 2.0 * target).then_some(n)
        });
        if let Some(n) = found {
            results.push((name, n));
        }
    }
    let count = |n: &str| results.iter().find(|(k, _)| *k == n).map(|(_, c)| *c);
    let error = count("error").expect("the error criterion reaches its own target");
    let uniform = count("uniform").expect("uniform reaches the target");
    // Every criterion must reach the target, and the adaptive ones must beat uniform
    // refinement by a wide margin. How edge/sphere/error rank against each other is not
    // asserted (`omnicave bench` measures the methods' triangles and errors): at this target
    // each sits at its coarsest setting, and much of what they draw is refinement all of them
    // share (edges crossing the projective viewpoint's plane where their visible part is in
    // view); they measure within 11 % of each other.
    for other in ["edge", "sphere"] {
        assert!(
            count(other).is_some(),
            "{other} does not reach the target within max depth {}",
            TessSettings::default().max_depth
        );
    }
    assert!(error * 10 < uniform, "error: {error}, uniform: {uniform}");
}

#[test]
fn an_exhausted_budget_degrades_gracefully() {
    let cave = cave_at(320, 180);
    let scene = living_room();
    let (images, stats, _) = render_tess(
        &cave,
        Head::at(Vec3::new(0.0, 1.7, 0.0)),
        RenderMode::OmniOnAxis,
        &scene,
        settings(Some(Criterion::Uniform(6))),
        Some(20_000),
    );
    assert!(
        stats.iter().any(|s| s.overflowed),
        "uniform:6 should exceed 20 000 triangles"
    );
    assert!(stats.iter().all(|s| s.emitted <= 20_000));
    // Still a picture: most pixels are scene, not background.
    let front = &images[cave.wall_index("front").unwrap()].left;
    let background = front
        .pixels()
        .filter(|p| p[0] < 10 && p[1] < 10 && p[2] < 12)
        .count();
    assert!(
        background < front.pixels().len() / 4,
        "{background} background pixels"
    );
}

/// The subdivision is conforming: in a watertight scene (the box room), every edge of every
/// output triangle is shared by exactly two output triangles (their ends compared bit for bit),
/// for every criterion down to the maximum depth: no T-junction anywhere, so no crack can
/// open whatever the rasteriser does. (Culling is off: a culled face leaves an open border.)
#[test]
fn every_output_edge_is_shared_by_exactly_two_triangles() {
    let cave = cave_at(480, 270);
    let scene = box_room();
    for head in [Vec3::new(0.0, 1.7, 0.0), Vec3::new(1.2, 1.0, -1.3)] {
        for criterion in [
            Criterion::Uniform(4),
            Criterion::Edge(12.0),
            Criterion::Sphere(20.0),
            Criterion::Error(0.5),
        ] {
            let tess = TessSettings {
                frustum_cull: false,
                backface_cull: false,
                ..settings(Some(criterion))
            };
            for mode in [RenderMode::OmniOnAxis, RenderMode::OmniOffAxis] {
                for (view, out) in cpu_views(&cave, head, mode, &scene, &tess) {
                    let mut edges: std::collections::HashMap<([u32; 3], [u32; 3]), u32> =
                        std::collections::HashMap::new();
                    // Every triangle of the picture: the tessellator's, the clusters drawn
                    // whole, and those proven invisible (culling is off, so these are all the
                    // rest), unsplit: no neighbour may split an edge they share.
                    let mut all: Vec<TessTriangle> = out.drawn().collect();
                    let seen: std::collections::HashSet<u32> =
                        all.iter().map(|t| t.source).collect();
                    all.extend(
                        (0..scene.triangle_count() as u32)
                            .filter(|t| !seen.contains(t))
                            .map(|source| TessTriangle {
                                source,
                                corners: [Bary::V0, Bary::V1, Bary::V2],
                            }),
                    );
                    for t in &all {
                        let p = [0, 1, 2].map(|k| {
                            Vec3::from(
                                scene.vertices[scene.indices[3 * t.source as usize + k] as usize]
                                    .position,
                            )
                        });
                        let ends = t
                            .corners
                            .map(|c| point_position(p, c).to_array().map(f32::to_bits));
                        for k in 0..3 {
                            let (a, b) = (ends[k], ends[(k + 1) % 3]);
                            *edges
                                .entry(if a < b { (a, b) } else { (b, a) })
                                .or_default() += 1;
                        }
                    }
                    let open = edges.values().filter(|&&n| n != 2).count();
                    assert_eq!(
                        open,
                        0,
                        "{criterion} {mode:?} head {head} wall {} {:?}: {open} of {} edges \
                         not shared by exactly two of {} triangles",
                        view.wall,
                        view.eye,
                        edges.len(),
                        all.len()
                    );
                }
            }
        }
    }
}

/// One refinement serves both eyes of a wall (`shared_eyes`, on by default): every eye draws
/// exactly the CPU twin's shared refinement, which splits wherever either eye's criterion
/// asks (so it refines at least as far as each eye alone); the frame records half the
/// dispatches; and the picture is the per-eye refinement's but for a few edge pixels (both
/// are within the criterion of the exact warp: a pixel whose centre an edge crosses may flip).
#[test]
fn both_eyes_of_a_wall_share_one_refinement() {
    let mut cave = cave_at(480, 270);
    cave.walls.truncate(2); // left and front walls
    // Off-centre and 0.35 m from the front wall, where the two eyes' warps differ most.
    let head = Vec3::new(0.5, 1.4, -1.15);
    let room = box_room();
    let city = city();
    for (mode, criterion, scene) in [
        (RenderMode::OmniOffAxis, Criterion::Error(0.5), &city),
        (RenderMode::OmniOffAxis, Criterion::Sphere(30.0), &room),
        (RenderMode::OmniOnAxis, Criterion::Edge(20.0), &city),
        // Plain stereo through the tessellator: the eyes are two points, the back-face test
        // uses the ball through both.
        (RenderMode::Stereo, Criterion::Error(0.5), &room),
    ] {
        let label = format!("{mode:?} {criterion}");
        let shared = settings(Some(criterion));
        let alone = TessSettings {
            shared_eyes: false,
            ..shared
        };
        // (images, dispatches, the last view's entries, per-view statistics) per setting.
        let [
            (images, shared_dispatches, entries, stats),
            (alone_images, alone_dispatches, _, _),
        ] = [shared, alone].map(|tess| {
            with_renderer(&cave, NO_MSAA, None, |renderer| {
                renderer.set_scene(scene).unwrap();
                let frame = test_frame(&cave, Head::at(head), mode, OmniSettings::default(), tess);
                let dispatches = renderer.render(&frame).unwrap().dispatches;
                (
                    renderer.read_images().unwrap(),
                    dispatches,
                    renderer.read_tess_entries().unwrap(),
                    renderer.read_tess_stats().unwrap(),
                )
            })
        });
        let dispatches = [shared_dispatches, alone_dispatches];
        assert!(dispatches[0] > 0, "{label}: nothing refined");
        assert_eq!(2 * dispatches[0], dispatches[1], "{label}: dispatches");
        // The last view (the front wall's right eye) draws its wall's shared refinement:
        // exactly the twin's, for either eye.
        let twin = cpu_views(&cave, head, mode, scene, &shared);
        let (_, last) = twin.last().unwrap();
        let mut expected = last.triangles.clone();
        expected.sort();
        assert!(
            sorted_triangles(&entries) == expected,
            "{label}: GPU and twin differ"
        );
        let (_, leader) = &twin[twin.len() - 2];
        let mut leader_triangles = leader.triangles.clone();
        leader_triangles.sort();
        assert!(
            leader_triangles == expected,
            "{label}: the eyes' refinements differ"
        );
        // Each wall's two eyes report the same refinement.
        for pair in stats.chunks_exact(2) {
            assert_eq!(pair[0].emitted, pair[1].emitted, "{label}: {stats:?}");
        }
        // At least as fine as each eye alone, never more than both together.
        let each = cpu_views(&cave, head, mode, scene, &alone);
        for (wall, pair) in each.chunks_exact(2).enumerate() {
            let [l, r] = [&pair[0].1, &pair[1].1].map(|o| o.stats.emitted);
            let both = twin[2 * wall].1.stats.emitted;
            assert!(
                both >= l.max(r) && both <= l + r,
                "{label}: {l}, {r} alone, {both} shared"
            );
        }
        // The pictures: at most 0.5 % of pixels differ by more than 24/255 in a channel (edge
        // pixels whose coverage flips between two meshes that both lie within the criterion).
        let mut differing = 0usize;
        let mut total = 0usize;
        for (a, b) in images.iter().zip(&alone_images) {
            for (x, y) in [(&a.left, &b.left), (&a.right, &b.right)] {
                total += x.pixels().len();
                differing += x
                    .pixels()
                    .zip(y.pixels())
                    .filter(|(p, q)| (0..3).any(|c| p[c].abs_diff(q[c]) > 24))
                    .count();
            }
        }
        assert!(
            differing * 200 <= total,
            "{label}: {differing} of {total} pixels differ"
        );
    }
}

/// A scene of more source triangles than one row of workgroups dispatches (65 535 × 64 =
/// 4 194 240): the tessellator covers them on a two-dimensional grid, so every triangle is
/// culled or refined, the last ones included. The scene shares three vertices between 4.3 M
/// small triangles behind the viewer (no wall sees them: frustum-culled in every view; the
/// vertex buffer stays small), then ends with a red quad ahead, which must be drawn.
#[test]
fn a_scene_past_one_row_of_workgroups_is_tessellated_to_its_last_triangle() {
    let mut cave = cave_at(96, 54);
    cave.walls.truncate(2); // left and front walls
    const HIDDEN: u32 = 4_300_000;
    const { assert!(HIDDEN > 65_535 * 64) };
    let mut scene = Scene::default();
    let vertex = |p: [f32; 3]| omnicave::scene::Vertex {
        position: p,
        normal: [0.0, 0.0, -1.0],
        ..Default::default()
    };
    let grey = scene.add_material(omnicave::scene::Material::unlit("hidden", [0.5; 3]));
    let hidden = [[0.0, 1.7, 5.0], [0.1, 1.7, 5.0], [0.0, 1.8, 5.0]].map(vertex);
    let indices: Vec<u32> = (0..HIDDEN).flat_map(|_| [0, 2, 1]).collect();
    scene.add_mesh(&hidden, &indices, grey);
    let red = scene.add_material(omnicave::scene::Material::unlit("quad", [1.0, 0.0, 0.0]));
    let quad = grid(Vec3::new(-0.5, 1.2, -1.6), Vec3::X, Vec3::Y, 1, 1, 1.0);
    scene.add_mesh(&quad.vertices, &quad.indices, red);
    let tess = TessSettings {
        // Every source triangle through the tessellator's own culling, a thread each.
        skip_fine: false,
        ..settings(Some(Criterion::Error(0.5)))
    };
    let (images, stats, _) = render_tess(
        &cave,
        Head::at(Vec3::new(0.0, 1.7, 0.0)),
        RenderMode::OmniOffAxis,
        &scene,
        tess,
        None,
    );
    for s in &stats {
        assert_eq!(s.input as usize, scene.triangle_count());
        assert_eq!(s.culled_frustum, HIDDEN, "{s:?}");
        assert!(s.emitted >= 2, "{s:?}");
    }
    let front = &images[1];
    for eye in [&front.left, &front.right] {
        let red = eye
            .pixels()
            .filter(|p| p[0] > 200 && p[1] < 40 && p[2] < 40)
            .count();
        // The quad (1 m × 1 m, 1.6 m ahead on the 3.3 m × 2.9 m front wall at 96 × 54) covers
        // roughly 29 × 19 = 550 pixels; at least half of that, whatever the eye.
        assert!(red > 250, "{red} red pixels");
    }
}

/// Models beyond the front wall, one reaching past its left border: the front wall shows most of
/// them, the left wall the part beyond the CAVE's side, the right wall nothing. The clusters that
/// straddle the side walls' eye planes are proven hidden by the planes through the eyes and the
/// walls' borders, so the right wall refines nothing; and the picture is the one drawn when
/// every triangle goes through the tessellator's own culling (`skip_fine` off), so no visible
/// cluster was hidden.
#[test]
fn a_model_beyond_the_front_wall_is_refined_only_where_a_wall_shows_it() {
    let cave = cave_at(160, 90);
    let mut scene = Scene::default();
    let orange = scene.add_material(omnicave::scene::Material::unlit("ball", [1.0, 0.5, 0.0]));
    let sphere = omnicave::scene::build::uv_sphere(1.0, 24, 48);
    // One ball reaching past the front wall's left border; one straight ahead, across the
    // eyes' plane of each side wall (part of it nearer the right wall than the eyes, part
    // further): the case the border planes are for.
    for centre in [Vec3::new(-2.0, 1.4, -2.6), Vec3::new(0.3, 1.4, -3.0)] {
        let ball = sphere.clone().transformed(Mat4::from_translation(centre));
        scene.add_mesh(&ball.vertices, &ball.indices, orange);
    }
    let mut most_on_the_left = 0;
    for (mode, head) in [
        (RenderMode::OmniOffAxis, Vec3::new(0.0, 1.7, 0.0)),
        (RenderMode::OmniOnAxis, Vec3::new(-0.9, 1.5, -1.6)),
        (RenderMode::OmniOffAxis, Vec3::new(1.6, 1.2, 1.0)),
    ] {
        let label = format!("{mode:?}, head {head}");
        let run = |skip_fine| {
            let tess = TessSettings {
                skip_fine,
                ..settings(Some(Criterion::Error(0.25)))
            };
            render_tess(&cave, Head::at(head), mode, &scene, tess, None)
        };
        let (images, stats, _) = run(true);
        let (all_images, all_stats, _) = run(false);
        let shown = |wall: &WallImages| {
            [&wall.left, &wall.right]
                .iter()
                .map(|img| img.pixels().filter(|p| p[0] > 200 && p[2] < 60).count())
                .sum::<usize>()
        };
        let [left, front, right] = [0, 1, 2].map(|w| shown(&all_images[w]));
        assert!(front > 500 && right == 0, "{label}: {left} {front} {right}");
        most_on_the_left = most_on_the_left.max(left);
        // The right wall's two views: no triangle reaches the tessellator (none culled there,
        // none emitted), where with every triangle sent to it most are culled one by one (and
        // some that cross the eyes' plane are emitted, to be clipped: the picture shows none).
        for (s, all) in stats[4..6].iter().zip(&all_stats[4..6]) {
            assert_eq!(
                s.culled_frustum + s.culled_backface + s.emitted,
                0,
                "{label}: {s:?}"
            );
            assert!(all.culled_frustum > 1000, "{label}: {all:?}");
        }
        assert!(
            stats[2].emitted > 0,
            "{label}: the front wall refines nothing"
        );
        let mut differing = 0;
        for (a, b) in images.iter().zip(&all_images) {
            for (x, y) in [(&a.left, &b.left), (&a.right, &b.right)] {
                differing += x.pixels().zip(y.pixels()).filter(|(p, q)| p != q).count();
            }
        }
        assert_eq!(differing, 0, "{label}: pictures differ");
    }
    // Some head sees the ball's far side through the left wall.
    assert!(most_on_the_left > 100, "{most_on_the_left}");
}

/// Renders `scene` with its vertices bound in four windows of 2/7 of them and bound whole,
/// from the centre and 5 cm from the front wall, and checks the frames are one: the same
/// statistics, the same refined triangles, pixel for pixel the same pictures; refined
/// triangles are drawn from every window in one frame or the other.
fn assert_windows_draw_as_whole(cave: &Cave, scene: &Scene, name: &str) {
    use omnicave::render::scene_gpu::GpuVertex;
    use omnicave::render::vertex_windows::{VERTEX_WINDOWS, plan_windows};
    let vertex_bytes = std::mem::size_of::<GpuVertex>() as u64;
    let vertices = scene.vertices.len() as u64;
    let window_bytes = vertices * 2 / 7 * vertex_bytes;
    // The windows as the renderer plans them on this device (a window is rounded down to
    // whole vertices at aligned offsets): all four hold vertices.
    let alignment = u64::from(gpu().device.limits().min_storage_buffer_offset_alignment);
    let plan = plan_windows(
        vertices * vertex_bytes,
        vertex_bytes,
        window_bytes,
        alignment,
    )
    .expect("four windows hold the scene");
    let step = plan[0].size / vertex_bytes;
    assert!(plan[VERTEX_WINDOWS - 1].offset > 0, "{name}: {plan:?}");
    let tess = settings(Some(Criterion::Error(0.5)));
    let mut used = [0usize; VERTEX_WINDOWS];
    for (mode, head) in [
        (RenderMode::OmniOffAxis, Vec3::new(0.0, 1.7, 0.0)),
        // 5 cm from the front wall, turned where the warp bends most.
        (RenderMode::OmniOnAxis, Vec3::new(0.4, 1.6, -1.6)),
    ] {
        let label = format!("{name}, {mode:?}, head {head}");
        let frame = test_frame(cave, Head::at(head), mode, OmniSettings::default(), tess);
        let (whole, windowed) = with_renderer(cave, NO_MSAA, None, |renderer| {
            renderer.set_scene(scene).expect("scene upload");
            let mut run = |window: Option<u64>| {
                renderer.limit_tess_vertex_windows(window);
                renderer.render(&frame).expect("render");
                (
                    renderer.read_images().expect("read back"),
                    renderer.read_tess_stats().expect("stats"),
                    sorted_triangles(&renderer.read_tess_entries().expect("entries")),
                )
            };
            let windowed = run(Some(window_bytes));
            let whole = run(None);
            (whole, windowed)
        });
        assert_eq!(windowed.1, whole.1, "{label}: statistics differ");
        assert_eq!(windowed.2, whole.2, "{label}: refined triangles differ");
        let mut differing = 0;
        for (a, b) in windowed.0.iter().zip(&whole.0) {
            for (x, y) in [(&a.left, &b.left), (&a.right, &b.right)] {
                differing += x.pixels().zip(y.pixels()).filter(|(p, q)| p != q).count();
            }
        }
        assert_eq!(differing, 0, "{label}: pictures differ");
        // The windows the refined triangles' vertices come from (the twin's output is what
        // the GPU draws through the windows).
        for (_, out) in cpu_views(cave, head, mode, scene, &tess) {
            for t in &out.triangles {
                for k in 0..3 {
                    let v = u64::from(scene.indices[3 * t.source as usize + k]);
                    used[((v / step) as usize).min(VERTEX_WINDOWS - 1)] += 1;
                }
            }
        }
    }
    // Every one of the four windows was read for some head.
    assert!(used.iter().all(|&n| n > 0), "{name}: windows used {used:?}");
}

/// A scene whose vertices exceed one storage binding is tessellated through the vertex
/// windows: the renderer is told to bind a scene's vertices in windows of under a third of
/// them (as lavapipe binds an 8-million-triangle scene's 288 MB in three of its 128 MiB), and
/// the frame is the one drawn with the vertices bound whole. The living room, and a model as
/// its exporter wrote it (FlightHelmet, from the shared corpus: several primitives and
/// materials, textures). Vertices past four windows are refused by name, and the renderer
/// goes on.
#[test]
fn a_scene_past_one_storage_binding_is_tessellated_through_its_vertex_windows() {
    use omnicave::render::scene_gpu::GpuVertex;
    let cave = cave_at(160, 90);
    let scene = living_room();
    assert_windows_draw_as_whole(&cave, &scene, "living room");
    if let Some(corpus) = corpus() {
        let mut helmet = load_gltf(&corpus.join("FlightHelmet/FlightHelmet.gltf")).unwrap();
        // Ahead of the viewer, near enough to be refined.
        let fit = helmet.fit_transform(omnicave::scene::SceneFit::Floor, 1.2);
        helmet.transform(Mat4::from_translation(Vec3::new(0.0, 0.8, -1.0)) * fit);
        assert_windows_draw_as_whole(&cave, &helmet, "FlightHelmet");
    }
    // Four windows of under 2/9 of the vertices cannot hold them: refused by name, and the
    // renderer draws the next frame with the vertices bound whole.
    let vertex_bytes = std::mem::size_of::<GpuVertex>() as u64;
    let vertices = scene.vertices.len() as u64;
    with_renderer(&cave, NO_MSAA, None, |renderer| {
        renderer.set_scene(&scene).expect("scene upload");
        let frame = test_frame(
            &cave,
            Head::at(Vec3::new(0.0, 1.7, 0.0)),
            RenderMode::OmniOffAxis,
            OmniSettings::default(),
            settings(Some(Criterion::Error(0.5))),
        );
        renderer.limit_tess_vertex_windows(Some(vertices * 2 / 9 * vertex_bytes));
        let refused = renderer
            .render(&frame)
            .expect_err("vertices past four windows");
        let message = refused.to_string();
        assert!(
            message.contains("vertices") && message.contains("max_storage_buffer_binding_size"),
            "{message}"
        );
        renderer.limit_tess_vertex_windows(None);
        renderer.render(&frame).expect("render after the refusal");
        assert!(!renderer.read_tess_stats().expect("stats").is_empty());
    });
}
