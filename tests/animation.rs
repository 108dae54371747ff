//! Animated scenes: glTF animations, skins and morph targets posed on the GPU before
//! tessellation and the warp. The GPU pose equals its CPU twin on the bundled animated sample
//! and on third-party models (`../shared/corpus`: BoxAnimated, SimpleSkin, Fox); markers
//! carried by posed meshes land where the CPU pose, projected independently, says, in every
//! mode and through the tessellator; `render --time` is reproducible; the clusters' bounds
//! follow the pose; malformed data is refused naming what is wrong. The corpus tests skip,
//! saying so, where the corpus is absent (a newcomer's clone); CI has it and must not skip.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::print_stdout)]

mod common;

use std::path::Path;

use common::*;
use glam::{Mat4, Quat, Vec3};
use omnicave::cave::omni::{PoleMerge, omni_eye};
use omnicave::cave::{Eye, Head, RenderMode, eye_positions};
use omnicave::scene::animated_sample::{SHOULDER_AT, animated_sample_glb};
use omnicave::scene::animation::{Interpolation, Sampler, Values};
use omnicave::scene::build::uv_sphere;
use omnicave::scene::rig::{
    Channel, Clip, Deformer, MorphTarget, Playback, Pose, PoseAt, RestVertex, Rig, RigNode, Skin,
    Target, Trs,
};
use omnicave::scene::{Material, Scene, SceneBudget, SceneFit, Vertex, load_gltf, load_gltf_bytes};
use omnicave::tess::{Criterion, TessSettings};

/// A corpus model as a user places it: on the floor, `size` metres across, 2 m ahead.
fn placed(path: &Path, size: f32) -> Scene {
    let mut scene = load_gltf(path).unwrap_or_else(|e| panic!("{e}"));
    let fit = scene.fit_transform(SceneFit::Floor, size);
    scene.transform(Mat4::from_translation(Vec3::new(0.0, 0.5, -2.0)) * fit);
    scene
}

fn sample() -> Scene {
    load_gltf_bytes(
        &animated_sample_glb(),
        Path::new("animated.glb"),
        &SceneBudget::default(),
    )
    .unwrap()
}

fn playing<'a>(clip: &'a str, seconds: f64) -> Playback<'a> {
    Playback {
        enabled: true,
        clip,
        seconds,
        repeat: true,
    }
}

#[test]
fn simple_skin_poses_as_worked_by_hand() {
    let Some(corpus) = corpus() else { return };
    let scene = load_gltf(&corpus.join("SimpleSkin/SimpleSkin.gltf")).unwrap();
    let rig = &scene.rig;
    assert_eq!(
        (rig.clips.len(), rig.skins.len(), rig.deformers.len()),
        (1, 1, 1)
    );
    let mut pose = Pose::default();
    let mut vertices = scene.vertices.clone();
    // Both joints' inverse bind matrices translate by (−0.5, −1, 0) and both joints stand at
    // (0, 1, 0): at rest the skin moves the mesh by −0.5 along x.
    let at = |vertices: &[Vertex], i: usize| Vec3::from(vertices[i].position);
    assert!((at(&vertices, 9) - Vec3::new(0.5, 2.0, 0.0)).length() < 1e-6);
    // t = 1 s: the second joint has turned 90° about z (keyframe (0, 0, 0.707, 0.707)).
    // Vertex 9 (1, 2, 0), all on joint 2: T(0,1,0)·Rz(90°)·(0.5, 1, 0) = (−1, 1.5, 0).
    // Vertex 4 (0, 1, 0), half on each: ((−0.5, 1, 0) + T(0,1,0)·Rz(90°)·(−0.5, 0, 0))/2
    // = ((−0.5, 1, 0) + (0, 0.5, 0))/2 = (−0.25, 0.75, 0).
    rig.deform_all(
        &mut pose,
        PoseAt {
            clip: Some(0),
            time: 1.0,
        },
        &mut vertices,
    );
    assert!((at(&vertices, 9) - Vec3::new(-1.0, 1.5, 0.0)).length() < 1e-5);
    assert!((at(&vertices, 4) - Vec3::new(-0.25, 0.75, 0.0)).length() < 1e-5);
    // t = 0.5 s: keyframe (0, 0, 0.383, 0.924), 45.03° once normalised:
    // vertex 9 at T(0,1,0)·Rz(45°)·(0.5, 1, 0) = (0.5c − s, 1 + 0.5s + c).
    rig.deform_all(
        &mut pose,
        PoseAt {
            clip: Some(0),
            time: 0.5,
        },
        &mut vertices,
    );
    let angle = 2.0 * 0.383f32.atan2(0.924);
    let (s, c) = angle.sin_cos();
    let expected = Vec3::new(0.5 * c - s, 1.0 + 0.5 * s + c, 0.0);
    assert!(
        (at(&vertices, 9) - expected).length() < 1e-5,
        "{}",
        at(&vertices, 9)
    );
}

/// Poses `scene` at each of `times` of `clip` on the GPU, reads the vertex buffer back and
/// compares it with the CPU twin; returns the largest position difference, metres.
fn gpu_against_cpu(scene: &Scene, clip: &str, times: &[f64]) -> f32 {
    let cave = cave_at(64, 48);
    with_renderer(&cave, NO_MSAA, None, |renderer| {
        renderer.set_scene(scene).expect("scene");
        let mut worst = 0.0f32;
        let mut pose = Pose::default();
        let mut cpu = scene.vertices.clone();
        for &t in times {
            let playback = playing(clip, t);
            let mut frame = test_frame(
                &cave,
                Head::at(Vec3::new(0.0, 1.7, 0.0)),
                RenderMode::Mono,
                Default::default(),
                TessSettings::default(),
            );
            frame.animation = playback;
            renderer.render(&frame).expect("render");
            let gpu = renderer.read_scene_vertices().unwrap().expect("one buffer");
            let at = scene.rig.pose_at(&playback).unwrap();
            assert_eq!(renderer.scene_pose(), Some(at));
            scene.rig.deform_all(&mut pose, at, &mut cpu);
            for (i, (g, c)) in gpu.iter().zip(&cpu).enumerate() {
                let d = (Vec3::from(g.position) - Vec3::from(c.position)).length();
                worst = worst.max(d);
                let n = (Vec3::from(g.normal) - Vec3::from(c.normal)).length();
                assert!(
                    n < 1e-4,
                    "vertex {i} at {t} s: normal {:?} vs {:?}",
                    g.normal,
                    c.normal
                );
                let t = (glam::Vec4::from(g.tangent) - glam::Vec4::from(c.tangent)).length();
                assert!(
                    t < 1e-4,
                    "vertex {i} at {t} s: tangent {:?} vs {:?}",
                    g.tangent,
                    c.tangent
                );
                assert_eq!(g.uv, c.uv, "vertex {i}: the pose left its other attributes");
            }
        }
        worst
    })
}

/// The bound, 1e-5 m. The GPU and the CPU run the same f32 operations in the same
/// order; only fused multiply-adds may round differently, a few ulps of a coordinate of a
/// few metres (1e-6 m).
const POSE_TOLERANCE_M: f32 = 1e-5;

#[test]
fn the_gpu_pose_equals_the_cpu_twin_on_the_bundled_sample() {
    let scene = sample();
    let times = [0.0, 0.4, 1.5, 2.25, 3.7, 5.1];
    let worst = gpu_against_cpu(&scene, "Show", &times);
    assert!(worst < POSE_TOLERANCE_M, "{worst} m");
    // Placed (scaled, moved, mirrored) as a config may place it: the placement poses too.
    let mut mirrored = sample();
    mirrored.transform(Mat4::from_scale(Vec3::new(-0.5, 0.5, 0.5)));
    let worst = gpu_against_cpu(&mirrored, "Show", &times);
    assert!(worst < POSE_TOLERANCE_M, "{worst} m");
}

#[test]
fn the_gpu_pose_equals_the_cpu_twin_on_corpus_models() {
    let Some(corpus) = corpus() else { return };
    let times = [0.0, 0.37, 1.1, 2.9];
    for (file, clips) in [
        ("SimpleSkin/SimpleSkin.gltf", vec![""]),
        ("BoxAnimated/BoxAnimated.gltf", vec![""]),
        ("Fox/Fox.glb", vec!["Survey", "Walk", "Run"]),
    ] {
        let scene = placed(&corpus.join(file), 1.2);
        assert!(!scene.rig.is_empty(), "{file}: nothing posed");
        for clip in clips {
            let worst = gpu_against_cpu(&scene, clip, &times);
            println!("{file} {clip}: GPU against CPU pose, worst {worst:.2e} m");
            assert!(worst < POSE_TOLERANCE_M, "{file} {clip}: {worst} m");
        }
    }
}

/// Joint matrices `pose` gives deformer `d`, blended for one vertex's influences.
fn blended(rig: &Rig, pose: &Pose, d: usize, vertex: usize) -> Mat4 {
    let deformer = &rig.deformers[d];
    let per = deformer.influences_per_vertex as usize;
    if per == 0 {
        return pose.matrices[d][0];
    }
    deformer.influences[vertex * per..(vertex + 1) * per]
        .iter()
        .fold(Mat4::ZERO, |m, &(j, w)| {
            m + pose.matrices[d][j as usize] * w
        })
}

const MARKER_RADIUS: f32 = 0.035;

/// Four markers, each a sphere carried by something that moves: a node animated through its
/// parent (red), a joint of a skin down a hierarchy (green), two joints half each (blue) and
/// a morph target (yellow). Their centres in mesh space, and the rig.
fn marker_rig() -> (Scene, [Vec3; 4]) {
    let node = |name: &str, parent: Option<usize>, t: Vec3| RigNode {
        name: name.into(),
        parent,
        rest_matrix: Mat4::from_translation(t),
        rest: Trs {
            translation: t,
            ..Trs::default()
        },
        weights: vec![],
    };
    let mut nodes = vec![
        node("base", None, Vec3::new(-0.6, 1.5, -2.6)),
        node("carried", Some(0), Vec3::new(0.0, 0.3, 0.0)),
        node("shoulder", None, Vec3::new(0.5, 1.2, -2.4)),
        node("hand", Some(2), Vec3::new(0.0, 0.5, 0.0)),
        node("left", None, Vec3::new(-0.2, 1.0, -2.2)),
        node("right", None, Vec3::new(0.2, 1.0, -2.2)),
        node("morphing", None, Vec3::new(0.0, 2.0, -2.5)),
    ];
    nodes[6].weights = vec![0.0];
    let track = |node: usize, target: Target, times: Vec<f32>, output: Vec<f32>, values| Channel {
        node,
        target,
        sampler: Sampler::new(times, output, Interpolation::Linear, values).unwrap(),
    };
    let turn = |axis: Vec3, degrees: &[f32]| -> Vec<f32> {
        degrees
            .iter()
            .flat_map(|d| Quat::from_axis_angle(axis, d.to_radians()).to_array())
            .collect()
    };
    let channels = vec![
        track(
            0,
            Target::Rotation,
            vec![0.0, 2.0],
            turn(Vec3::Z, &[0.0, 80.0]),
            Values::Rotation,
        ),
        track(
            0,
            Target::Translation,
            vec![0.0, 2.0],
            vec![-0.6, 1.5, -2.6, -0.3, 1.7, -2.9],
            Values::Vector3,
        ),
        track(
            2,
            Target::Rotation,
            vec![0.0, 2.0],
            turn(Vec3::X, &[0.0, -60.0]),
            Values::Rotation,
        ),
        track(
            3,
            Target::Rotation,
            vec![0.0, 2.0],
            turn(Vec3::Z, &[0.0, 45.0]),
            Values::Rotation,
        ),
        track(
            4,
            Target::Translation,
            vec![0.0, 2.0],
            vec![-0.2, 1.0, -2.2, -0.5, 0.7, -2.2],
            Values::Vector3,
        ),
        track(
            5,
            Target::Translation,
            vec![0.0, 2.0],
            vec![0.2, 1.0, -2.2, 0.3, 1.6, -2.0],
            Values::Vector3,
        ),
        track(
            6,
            Target::Weights,
            vec![0.0, 2.0],
            vec![0.0, 1.0],
            Values::Weights(1),
        ),
    ];
    let mut scene = Scene::default();
    let mut rig = Rig {
        nodes,
        clips: vec![Clip {
            name: "move".into(),
            start: 0.0,
            end: 2.0,
            channels,
        }],
        skins: vec![
            Skin {
                name: "arm".into(),
                joints: vec![2, 3],
                inverse_bind: vec![
                    Mat4::from_translation(Vec3::new(0.5, 1.2, -2.4)).inverse(),
                    Mat4::from_translation(Vec3::new(0.5, 1.7, -2.4)).inverse(),
                ],
            },
            Skin {
                name: "pair".into(),
                joints: vec![4, 5],
                inverse_bind: vec![
                    Mat4::from_translation(Vec3::new(-0.2, 1.0, -2.2)).inverse(),
                    Mat4::from_translation(Vec3::new(0.2, 1.0, -2.2)).inverse(),
                ],
            },
        ],
        deformers: vec![],
        placement: Mat4::IDENTITY,
    };
    // Mesh-space centres: the carried node's origin; the hand joint's bind position 0.2 m
    // above it; midway between the pair; the morphing node's origin.
    let centres = [
        Vec3::ZERO,
        Vec3::new(0.5, 1.9, -2.4),
        Vec3::new(0.0, 1.0, -2.2),
        Vec3::ZERO,
    ];
    let sphere = uv_sphere(MARKER_RADIUS, 24, 32);
    for (k, centre) in centres.iter().enumerate() {
        let rgb = MARKER_COLOURS[k].map(|v| f32::from(v) / 255.0);
        let material = scene.add_material(Material::unlit(&format!("marker {k}"), rgb));
        let rest: Vec<RestVertex> = sphere
            .vertices
            .iter()
            .map(|v| RestVertex {
                position: (Vec3::from(v.position) + *centre).to_array(),
                normal: v.normal,
                tangent: [0.0; 4],
            })
            .collect();
        let n = rest.len();
        let (node, skin, per, influences, targets) = match k {
            0 => (1, None, 0, vec![], vec![]),
            1 => (
                3,
                Some(0),
                4,
                [(1, 1.0), (0, 0.0), (0, 0.0), (0, 0.0)].repeat(n),
                vec![],
            ),
            2 => (
                6,
                Some(1),
                4,
                [(0, 0.5), (1, 0.5), (0, 0.0), (0, 0.0)].repeat(n),
                vec![],
            ),
            _ => (
                6,
                None,
                0,
                vec![],
                vec![MorphTarget {
                    positions: vec![[0.4, -0.3, 0.2]; n],
                    normals: vec![[0.0; 3]; n],
                    tangents: vec![[0.0; 3]; n],
                }],
            ),
        };
        rig.deformers.push(Deformer {
            label: format!("marker {k}"),
            first_vertex: scene.vertices.len() as u32,
            node,
            skin,
            rest,
            influences_per_vertex: per,
            influences,
            targets,
        });
        let vertices: Vec<Vertex> = sphere.vertices.clone();
        scene.add_mesh(&vertices, &sphere.indices, material);
    }
    let mut pose = Pose::default();
    rig.deform_all(&mut pose, PoseAt::REST, &mut scene.vertices);
    scene.rig = rig;
    (scene, centres)
}

/// Where the CPU pose puts each marker's centre at `at`.
fn posed_centres(scene: &Scene, centres: &[Vec3; 4], at: PoseAt) -> Vec<Vec3> {
    let rig = &scene.rig;
    let mut pose = Pose::default();
    rig.pose(at, &mut pose);
    (0..4)
        .map(|k| {
            let morphed = centres[k]
                + rig.deformers[k]
                    .targets
                    .iter()
                    .zip(rig.morph_weights(k, &pose))
                    .map(|(t, w)| Vec3::from(t.positions[0]) * *w)
                    .sum::<Vec3>();
            blended(rig, &pose, k, 0).transform_point3(morphed)
        })
        .collect()
}

#[test]
fn markers_carried_by_posed_meshes_land_where_the_cpu_pose_says() {
    // 320 px per metre: a marker of 3.5 cm radius 2.4 m away is about 7 px across.
    let size = [960, 540];
    let cave = cave_at(size[0], size[1]);
    let (scene, centres) = marker_rig();
    let pole = Some(PoleMerge::default());
    let tessellated = TessSettings {
        criterion: Some(Criterion::Error(0.5)),
        ..TessSettings::default()
    };
    let heads = [
        ("centred", Vec3::new(0.0, 1.7, 0.0)),
        ("off-centre", Vec3::new(0.6, 1.4, 0.5)),
        ("5 cm from the left wall", Vec3::new(-1.45, 1.6, 0.0)),
    ];
    let (mut checked, mut moved) = (0, 0.0f32);
    with_renderer(&cave, NO_MSAA, None, |renderer| {
        renderer.set_scene(&scene).expect("scene");
        for t in [0.0, 0.7, 1.9] {
            let at = PoseAt {
                clip: Some(0),
                time: t as f32,
            };
            let expected_at = posed_centres(&scene, &centres, at);
            moved = moved
                .max((expected_at[0] - posed_centres(&scene, &centres, PoseAt::REST)[0]).length());
            for (head_name, head) in heads {
                for mode in [
                    RenderMode::Mono,
                    RenderMode::Stereo,
                    RenderMode::OmniOnAxis,
                    RenderMode::OmniOffAxis,
                ] {
                    let mut frame =
                        test_frame(&cave, Head::at(head), mode, Default::default(), tessellated);
                    frame.animation = playing("move", t);
                    renderer.render(&frame).expect("render");
                    let images = renderer.read_images().expect("read back");
                    let eyes =
                        eye_positions(mode, &Head::at(head), 0.064, cave.stereo_view_direction);
                    for (wall, wall_images) in cave.walls.iter().zip(&images) {
                        for eye in Eye::BOTH {
                            let found = centroids(wall_images.eye(eye));
                            for (k, p) in expected_at.iter().enumerate() {
                                let from = if mode.is_omni() {
                                    omni_eye(head, *p, 0.064, eye, pole)
                                } else {
                                    eyes[eye as usize]
                                };
                                let Some(expected) = wall.pixel_of_ray(from, *p) else {
                                    continue;
                                };
                                let what = format!(
                                    "t {t} s, {head_name}, {mode}, {} {}: marker {k} at {p}",
                                    wall.name,
                                    eye.name()
                                );
                                if assert_marker_at(
                                    &found,
                                    MARKER_COLOURS[k],
                                    expected,
                                    size,
                                    &what,
                                )
                                .is_some()
                                {
                                    checked += 1;
                                }
                            }
                        }
                    }
                }
            }
        }
    });
    assert!(moved > 0.2, "the carried marker moved only {moved} m");
    assert!(checked >= 150, "only {checked} marker positions checked");
}

#[test]
fn the_clusters_bounds_hold_every_posed_vertex() {
    use omnicave::tess::clusters::build_clusters;
    use omnicave::tess::posed_clusters::PosedClusters;
    for (name, scene) in [("sample", sample()), ("markers", marker_rig().0)] {
        let draws = scene
            .draws
            .iter()
            .enumerate()
            .map(|(d, draw)| (d as u32, draw.first_index, draw.index_count));
        let mut clusters = build_clusters(&scene, draws);
        let mut posed = PosedClusters::new(&scene, &clusters);
        assert!(!posed.is_empty());
        let mut pose = Pose::default();
        let mut vertices = scene.vertices.clone();
        for step in 0..=40 {
            let at = PoseAt {
                clip: Some(0),
                time: scene.rig.clips[0].end * step as f32 / 40.0,
            };
            scene.rig.deform_all(&mut pose, at, &mut vertices);
            let bounds = posed.update(&scene.rig, &pose, &mut clusters).unwrap();
            for c in &clusters {
                for t in c.first_triangle..c.first_triangle + c.triangle_count {
                    let corners: Vec<Vec3> = (0..3)
                        .map(|k| {
                            Vec3::from(
                                vertices[scene.indices[3 * t as usize + k] as usize].position,
                            )
                        })
                        .collect();
                    for (k, p) in corners.iter().enumerate() {
                        // 1e-5 m: the box's f32 arithmetic against the vertices'.
                        let inside = (*p - c.centre).abs().cmple(c.half_size + 1e-5).all();
                        assert!(
                            inside,
                            "{name} at {at:?}: triangle {t} corner {p} outside its cluster"
                        );
                        assert!(p.cmpge(bounds.0 - 1e-5).all() && p.cmple(bounds.1 + 1e-5).all());
                        let next = corners[(k + 1) % 3];
                        assert!((next - *p).length() <= c.max_edge + 1e-5);
                    }
                }
            }
        }
    }
}

/// The animated sample's GLB with its JSON changed by `edit` (and bytes appended to its
/// binary chunk by `edit` through the returned buffer).
fn edited(edit: impl FnOnce(&mut serde_json::Value, &mut Vec<u8>)) -> Vec<u8> {
    let glb = animated_sample_glb();
    let json_len = u32::from_le_bytes(glb[12..16].try_into().unwrap()) as usize;
    let mut doc: serde_json::Value = serde_json::from_slice(&glb[20..20 + json_len]).unwrap();
    let mut bin = glb[20 + json_len + 8..].to_vec();
    edit(&mut doc, &mut bin);
    bin.resize(bin.len().next_multiple_of(4), 0);
    doc["buffers"][0]["byteLength"] = bin.len().into();
    omnicave::scene::glb_writer::glb_bytes(&doc, &bin)
}

/// Appends float data as a new accessor of `ty`; returns its index.
fn add_floats(doc: &mut serde_json::Value, bin: &mut Vec<u8>, data: &[f32], ty: &str) -> usize {
    while !bin.len().is_multiple_of(4) {
        bin.push(0);
    }
    let offset = bin.len();
    bin.extend(data.iter().flat_map(|v| v.to_le_bytes()));
    let views = doc["bufferViews"].as_array_mut().unwrap();
    views
        .push(serde_json::json!({"buffer": 0, "byteOffset": offset, "byteLength": data.len() * 4}));
    let view = views.len() - 1;
    let components = match ty {
        "SCALAR" => 1,
        "VEC3" => 3,
        _ => 4,
    };
    let accessors = doc["accessors"].as_array_mut().unwrap();
    accessors.push(serde_json::json!({
        "bufferView": view, "componentType": 5126, "count": data.len() / components, "type": ty
    }));
    accessors.len() - 1
}

fn load_error(bytes: &[u8], budget: &SceneBudget) -> String {
    match load_gltf_bytes(bytes, Path::new("edited.glb"), budget) {
        Ok(_) => panic!("loaded"),
        Err(e) => e.to_string(),
    }
}

#[test]
fn malformed_animation_data_is_refused_naming_what_is_wrong() {
    let budget = SceneBudget::default();
    // The block's rotation sampler is sampler 3, its translation 4 (see animated_sample).
    let cases: Vec<(&str, Vec<u8>, &[&str])> = vec![
        (
            "times that do not increase",
            edited(|doc, bin| {
                let a = add_floats(doc, bin, &[0.0, 1.0, 1.0, 3.0, 4.0], "SCALAR");
                doc["animations"][0]["samplers"][3]["input"] = a.into();
            }),
            &["animation 0 (Show) channel 3", "must increase"],
        ),
        (
            "a NaN key",
            edited(|doc, bin| {
                let a = add_floats(doc, bin, &[0.0, 1.0, f32::NAN, 3.0, 4.0], "SCALAR");
                doc["animations"][0]["samplers"][3]["input"] = a.into();
            }),
            &["channel 3", "not finite"],
        ),
        (
            "too few outputs",
            edited(|doc, bin| {
                let a = add_floats(doc, bin, &[1.0, 2.0, 3.0, 4.0, 5.0, 6.0], "VEC3");
                doc["animations"][0]["samplers"][4]["output"] = a.into();
            }),
            &["channel 4", "6 output values for 3 keyframes"],
        ),
        (
            "a NaN output",
            edited(|doc, bin| {
                let a = add_floats(
                    doc,
                    bin,
                    &[1.0, f32::NAN, 3.0, 1.0, 2.0, 3.0, 1.0, 2.0, 3.0],
                    "VEC3",
                );
                doc["animations"][0]["samplers"][4]["output"] = a.into();
            }),
            &["channel 4", "not finite"],
        ),
        (
            "a zero rotation",
            edited(|doc, bin| {
                let mut q = [0.0, 0.0, 0.0, 1.0].repeat(5);
                q[8..12].copy_from_slice(&[0.0; 4]);
                let a = add_floats(doc, bin, &q, "VEC4");
                doc["animations"][0]["samplers"][3]["output"] = a.into();
            }),
            &["channel 3", "zero quaternion"],
        ),
        (
            "joints past the skin's",
            edited(|doc, _| {
                doc["skins"][0]["joints"] = serde_json::json!([2]);
            }),
            &[
                "mesh 1 (arm) primitive 0",
                "joint 1",
                "skin 0 (arm skin) has 1 joints",
            ],
        ),
        (
            "a channel on a node the file lacks",
            edited(|doc, _| {
                doc["animations"][0]["channels"][2]["target"]["node"] = 99.into();
            }),
            &["animation 0 channel 2 targets node 99, but the file has 5"],
        ),
        (
            "a channel on an unknown path",
            edited(|doc, _| {
                doc["animations"][0]["channels"][2]["target"]["path"] = "pointer".into();
            }),
            &[
                "animation 0 channel 2",
                "translation, rotation, scale or weights",
            ],
        ),
        (
            "weights of a mesh without morph targets",
            edited(|doc, _| {
                doc["animations"][0]["channels"][0]["target"]["node"] = 4.into();
            }),
            &["channel 0", "node 4", "no morph targets"],
        ),
    ];
    for (what, bytes, needles) in cases {
        let e = load_error(&bytes, &budget);
        for needle in needles {
            assert!(e.contains(needle), "{what}: {e:?} lacks {needle:?}");
        }
        assert!(
            e.contains("edited.glb"),
            "{what}: {e} does not name the file"
        );
    }
    // Budgets, each naming itself and the object over it.
    for (budget, needles) in [
        (
            SceneBudget {
                max_joints: 1,
                ..budget
            },
            ["budgets.max_joints = 1", "arm skin"],
        ),
        (
            SceneBudget {
                max_morph_targets: 1,
                ..budget
            },
            ["budgets.max_morph_targets = 1", "mesh 0 (surface)"],
        ),
        (
            SceneBudget {
                max_animation_channels: 3,
                ..budget
            },
            ["budgets.max_animation_channels = 3", "channel 3"],
        ),
        (
            SceneBudget {
                max_keyframes: 8,
                ..budget
            },
            ["budgets.max_keyframes = 8", "channel 2"],
        ),
        (
            SceneBudget {
                max_pose_bytes: 1 << 10,
                ..budget
            },
            ["budgets.max_pose_memory_mb = 0", "mesh 0 (surface)"],
        ),
    ] {
        let e = load_error(&animated_sample_glb(), &budget);
        for needle in needles {
            assert!(e.contains(needle), "{e:?} lacks {needle:?}");
        }
    }
    // Weights that do not sum to one are scaled to (the documented repair), not refused.
    let halves = edited(|doc, bin| {
        let weights_accessor = doc["meshes"][1]["primitives"][0]["attributes"]["WEIGHTS_0"]
            .as_u64()
            .unwrap() as usize;
        let count = doc["accessors"][weights_accessor]["count"]
            .as_u64()
            .unwrap() as usize;
        let a = add_floats(doc, bin, &[0.25, 0.25, 0.0, 0.0].repeat(count), "VEC4");
        doc["meshes"][1]["primitives"][0]["attributes"]["WEIGHTS_0"] = a.into();
        doc["meshes"][1]["primitives"][0]["attributes"]["JOINTS_0"] =
            doc["meshes"][1]["primitives"][0]["attributes"]["JOINTS_0"].clone();
    });
    let scene = load_gltf_bytes(&halves, Path::new("halves.glb"), &budget).unwrap();
    let arm = scene
        .rig
        .deformers
        .iter()
        .find(|d| d.skin.is_some())
        .unwrap();
    for v in arm
        .influences
        .chunks_exact(arm.influences_per_vertex as usize)
    {
        let sum: f32 = v.iter().map(|i| i.1).sum();
        assert!((sum - 1.0).abs() < 1e-6, "{v:?}");
    }
}

/// Runs `omnicave render` of `scene` at `time` (into a fresh folder) and returns the front
/// wall's left eye.
fn render_at(scene: &Path, time: &str, clip: Option<&str>, tag: &str, place: bool) -> Vec<u8> {
    let out = tmp_dir(&format!("animation-{tag}"));
    let mut args = vec![
        "render",
        "--config",
        "config/desktop.toml",
        "--scene",
        scene.to_str().unwrap(),
        "--size",
        "160x120",
        "--skybox",
        "none",
        "--time",
        time,
        "--out",
        out.to_str().unwrap(),
    ];
    if let Some(clip) = clip {
        args.extend(["--animation", clip]);
    }
    if place {
        // As a user places a model authored around its own origin: on the floor, 1.2 m
        // across, 2.2 m ahead.
        args.extend([
            "--fit",
            "floor",
            "--size-m",
            "1.2",
            "--scene-offset=0,0.3,-2.2",
        ]);
    }
    let (code, _, err) = run_omnicave(&args);
    assert_eq!(code, 0, "render {args:?}: {err}");
    let front = image::open(out.join("front-left.png")).unwrap().to_rgba8();
    front.into_raw()
}

fn differing(a: &[u8], b: &[u8]) -> usize {
    a.chunks_exact(4)
        .zip(b.chunks_exact(4))
        .filter(|(x, y)| x != y)
        .count()
}

#[test]
fn render_time_is_reproducible_and_moves_the_scene() {
    let sample_path = repo("assets/animated.glb");
    let mut models = vec![(sample_path, None, "sample")];
    let corpus = corpus();
    if let Some(corpus) = &corpus {
        models.push((corpus.join("BoxAnimated/BoxAnimated.gltf"), None, "box"));
        models.push((corpus.join("SimpleSkin/SimpleSkin.gltf"), None, "skin"));
        models.push((corpus.join("Fox/Fox.glb"), Some("Walk"), "fox"));
    }
    for (path, clip, tag) in &models {
        let place = *tag != "sample";
        let a = render_at(path, "0.9", *clip, &format!("{tag}-a"), place);
        let b = render_at(path, "0.9", *clip, &format!("{tag}-b"), place);
        let c = render_at(path, "2.6", *clip, &format!("{tag}-c"), place);
        assert_eq!(
            differing(&a, &b),
            0,
            "{tag}: the same time gave other images"
        );
        let changed = differing(&a, &c);
        println!("{tag}: {changed} pixels change between 0.9 s and 2.6 s");
        assert!(
            changed > 20,
            "{tag}: only {changed} pixels changed between instants"
        );
    }
    // A name the file lacks is refused, naming what it has.
    let (code, _, err) = run_omnicave(&[
        "render",
        "--config",
        "config/desktop.toml",
        "--scene",
        "assets/animated.glb",
        "--animation",
        "Dance",
        "--out",
        tmp_dir("animation-bad").to_str().unwrap(),
    ]);
    assert_ne!(code, 0);
    assert!(
        err.contains("no animation named \"Dance\"") && err.contains("Show"),
        "{err}"
    );
}

#[test]
fn a_static_scene_has_no_pose_and_an_animated_one_poses_once_per_instant() {
    let cave = cave_at(64, 48);
    with_renderer(&cave, NO_MSAA, None, |renderer| {
        let head = Head::at(Vec3::new(0.0, 1.7, 0.0));
        let mut frame = test_frame(
            &cave,
            head,
            RenderMode::Mono,
            Default::default(),
            TessSettings::default(),
        );
        let still = marker_scene(&[Vec3::new(0.0, 1.5, -2.0)], Vec3::ZERO, 0.02);
        renderer.set_scene(&still).unwrap();
        frame.animation = playing("", 1.0);
        renderer.render(&frame).unwrap();
        assert_eq!(renderer.scene_pose(), None, "a static scene is not posed");
        let scene = sample();
        renderer.set_scene(&scene).unwrap();
        renderer.render(&frame).unwrap();
        let first = renderer.read_scene_vertices().unwrap().unwrap();
        // The arm's top at 1 s is off the vertical (the elbow bends).
        let arm = scene
            .rig
            .deformers
            .iter()
            .find(|d| d.skin.is_some())
            .unwrap();
        let top = first[arm.first_vertex as usize..]
            .iter()
            .take(arm.rest.len())
            .map(|v| Vec3::from(v.position))
            .max_by(|a, b| a.y.total_cmp(&b.y))
            .unwrap();
        assert!(
            (top.x - SHOULDER_AT.x).abs() > 0.05,
            "the arm did not bend: {top}"
        );
        // Off: the rest pose again.
        frame.animation.enabled = false;
        renderer.render(&frame).unwrap();
        assert_eq!(renderer.scene_pose(), Some(PoseAt::REST));
        let rest = renderer.read_scene_vertices().unwrap().unwrap();
        for (r, v) in rest.iter().zip(&scene.vertices) {
            assert!((Vec3::from(r.position) - Vec3::from(v.position)).length() < 1e-6);
        }
    });
}

/// Past the device's largest buffer (a scene split over several, forced here by a small
/// limit), an animated scene still renders, in its rest pose, as the split static scene
/// would: nothing is posed into buffers the pass cannot bind whole.
#[test]
fn a_split_animated_scene_renders_in_its_rest_pose() {
    let cave = cave_at(64, 48);
    let scene = sample();
    let mut frame = test_frame(
        &cave,
        Head::at(Vec3::new(0.0, 1.7, 0.0)),
        RenderMode::Stereo,
        Default::default(),
        TessSettings::default(),
    );
    frame.animation = playing("Show", 1.5);
    let mut renderer = omnicave::render::Renderer::new(gpu(), &cave, NO_MSAA).unwrap();
    renderer.limit_scene_buffers(Some(32 << 10));
    renderer.set_scene(&scene).expect("split upload");
    assert!(
        renderer.scene_chunks() >= 2,
        "{} chunks",
        renderer.scene_chunks()
    );
    renderer.render(&frame).expect("render");
    assert_eq!(renderer.scene_pose(), None, "a split scene is not posed");
    let split = renderer.read_images().unwrap();
    // The same scene whole, with the animation off: the rest pose, pixel for pixel.
    frame.animation.enabled = false;
    let whole = with_renderer(&cave, NO_MSAA, None, |renderer| {
        renderer.set_scene(&scene).unwrap();
        renderer.render(&frame).unwrap();
        renderer.read_images().unwrap()
    });
    for (a, b) in split.iter().zip(&whole) {
        assert_eq!(a.left.as_raw(), b.left.as_raw(), "wall {}", a.wall);
    }
}
