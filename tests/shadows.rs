//! Shadows fall where the light's geometry says, in every render mode: a cube above a floor,
//! lit by the config's directional light from straight above, then by its point light; the
//! floor under the cube is shaded as the CPU twin shades it with that light blocked, the floor
//! beside the shadow as the twin shades it lit — on the walls, through tessellated
//! omnistereo and in the panorama. Switching shadows off lights the floor under the cube.
#![allow(clippy::unwrap_used, clippy::expect_used)]

mod common;

use common::*;
use glam::{Mat4, Vec2, Vec3};
use omnicave::cave::omni::OmniSettings;
use omnicave::cave::{Head, RenderMode};
use omnicave::pano::raycast::RayCaster;
use omnicave::pano::{PanoRoute, Projection};
use omnicave::render::pbr::{SurfacePoint, shade_pbr};
use omnicave::render::uniforms::{FrameLights, FrameUniforms, MAX_LIGHTS};
use omnicave::render::{FrameParams, Renderer};
use omnicave::scene::build::{cuboid, grid};
use omnicave::scene::shadows::ShadowSettings;
use omnicave::scene::{Lighting, Material, Scene, Shading};
use omnicave::tess::{Criterion, TessSettings};

const HEAD: Vec3 = Vec3::new(0.0, 1.6, 0.0);
const FLOOR_Y: f32 = 0.6;
/// The cube: 0.3 m, its centre 0.6 m above the floor, 1.2 m ahead.
const CUBE: Vec3 = Vec3::new(0.0, 1.2, -1.2);

/// The matte grey every surface of these scenes has (the CPU twin shades it alike).
fn add_grey(scene: &mut Scene) -> usize {
    scene.add_material(Material {
        base_color: [0.8, 0.8, 0.8, 1.0],
        roughness: 1.0,
        ..Material::default()
    })
}

fn scene() -> Scene {
    let mut scene = Scene::default();
    let grey = add_grey(&mut scene);
    let floor = grid(
        Vec3::new(-2.0, FLOOR_Y, 1.0),
        Vec3::X * 4.0,
        Vec3::NEG_Z * 4.0,
        4,
        4,
        1.0,
    );
    scene.add_mesh(&floor.vertices, &floor.indices, grey);
    let cube = cuboid(Vec3::splat(0.3), 1.0).transformed(Mat4::from_translation(CUBE));
    scene.add_mesh(&cube.vertices, &cube.indices, grey);
    scene
}

/// Only the light under test: the sun from straight above, or the point light 1.3 m above
/// the cube.
fn lighting(point: bool) -> Lighting {
    let mut l = Lighting {
        ambient: Vec3::splat(0.1),
        sun_direction: Vec3::NEG_Y,
        sun_color: Vec3::ZERO,
        point_position: CUBE + Vec3::Y * 1.3,
        point_color: Vec3::ZERO,
        point_range: 10.0,
        sun_shadows: true,
        point_shadows: true,
    };
    if point {
        l.point_color = Vec3::splat(1.5);
    } else {
        l.sun_color = Vec3::ONE;
    }
    l
}

/// The floor at `p` as the CPU twin shades it, the light reaching it (`lit`) or not.
fn twin(lighting: &Lighting, p: Vec3, lit: bool) -> [u8; 3] {
    placed_twin(Mat4::IDENTITY, lighting, p, lit)
}

/// [`twin`] with the scene placed at `world_from_cave` (`p` in CAVE space).
fn placed_twin(world_from_cave: Mat4, lighting: &Lighting, p: Vec3, lit: bool) -> [u8; 3] {
    let frame = FrameUniforms::new(
        world_from_cave,
        FrameLights {
            config: lighting,
            scene: &[],
            shading: Shading::Pbr,
        },
        None,
        None,
        None,
    );
    let visibility = [if lit { 1.0 } else { 0.0 }; MAX_LIGHTS];
    let c = shade_pbr(
        &frame,
        &SurfacePoint {
            position: p,
            normal: Vec3::Y,
            base_color: Vec3::splat(0.8),
            metallic: 0.0,
            roughness: 1.0,
            occlusion: 1.0,
        },
        HEAD,
        &visibility,
    );
    c.to_array().map(omnicave::sky::cubemap::linear_to_srgb)
}

/// A named image and where a CAVE-space point lands in it.
type View = (String, image::RgbaImage, Box<dyn Fn(Vec3) -> Vec2>);

/// The front wall's left eye in `mode` (tessellated in omnistereo), and the panorama ahead;
/// with a function from a CAVE-space point to its pixel in each.
fn images(lighting: Lighting, shadows: ShadowSettings) -> Vec<View> {
    let cave = cave_at(320, 280);
    let front = cave.wall_index("front").unwrap();
    let scene = scene();
    let mut renderer = Renderer::new(gpu(), &cave, NO_MSAA).expect("renderer");
    renderer.set_scene(&scene).expect("scene upload");
    let frame = |mode, tess| {
        let mut f: FrameParams<'_> =
            test_frame(&cave, Head::at(HEAD), mode, OmniSettings::default(), tess);
        f.lighting = lighting;
        f.shadows = shadows;
        f
    };
    let mut out: Vec<View> = Vec::new();
    for (mode, tess) in [
        (RenderMode::Mono, TessSettings::default()),
        (RenderMode::Stereo, TessSettings::default()),
        (RenderMode::TrackedStereo, TessSettings::default()),
        (RenderMode::OmniOnAxis, TessSettings::default()),
        (
            RenderMode::OmniOffAxis,
            TessSettings {
                criterion: Some(Criterion::Error(0.5)),
                ..TessSettings::default()
            },
        ),
    ] {
        renderer.render(&frame(mode, tess)).expect("render");
        let images = renderer.read_images().expect("read back");
        let wall = cave.walls[front].clone();
        out.push((
            mode.name().to_owned(),
            images[front].left.clone(),
            Box::new(move |p| wall.pixel_of_ray(HEAD, p).unwrap()),
        ));
    }
    let mut pano = pano_settings(Projection::Perspective, PanoRoute::Geometric, [90.0, 100.0]);
    pano.size = [280, 320];
    renderer
        .render_panorama(&frame(RenderMode::Mono, TessSettings::default()), &pano)
        .expect("panorama");
    let [image, _] = renderer.read_panorama().expect("read back");
    out.push((
        "panorama".into(),
        image,
        Box::new(move |p| {
            let dir = pano.view_from_cave(HEAD).transform_vector3(p - HEAD);
            let ndc = pano.fitted().project(dir).unwrap();
            let [w, h] = pano.size.map(|v| v as f32);
            Vec2::new((ndc.x + 1.0) * 0.5 * w, (1.0 - ndc.y) * 0.5 * h)
        }),
    ));
    out
}

fn close(a: [u8; 3], b: [u8; 3], tolerance: u8) -> bool {
    a.iter().zip(b).all(|(x, y)| x.abs_diff(y) <= tolerance)
}

#[test]
fn a_shadow_falls_where_the_lights_geometry_says_in_every_render_mode() {
    // Under the cube's centre (straight below it for both lights), and beside the shadow:
    // the sun's shadow is the cube's 0.3 m square; the point light's is the top face
    // projected from 1.3 m above it onto the floor 0.75 m further down, 0.52 m across.
    let under = Vec3::new(0.0, FLOOR_Y, CUBE.z);
    let beside = Vec3::new(0.45, FLOOR_Y, CUBE.z);
    for point in [false, true] {
        // The shadow's edge: 4 cm inside and outside it (the edge's filtering is a texel or
        // two, 5.5 mm here).
        let edge = if point { 0.15 * 1.9 / 1.15 } else { 0.15 };
        let inside = Vec3::new(edge - 0.04, FLOOR_Y, CUBE.z);
        let outside = Vec3::new(edge + 0.04, FLOOR_Y, CUBE.z);
        let light = lighting(point);
        let (want_dark, want_lit) = (twin(&light, under, false), twin(&light, beside, true));
        for (name, image, pixel) in images(light, ShadowSettings::default()) {
            let at = |p: Vec3| {
                let q = pixel(p);
                let px = image.get_pixel(q.x as u32, q.y as u32);
                [px[0], px[1], px[2]]
            };
            let (dark, lit) = (at(under), at(beside));
            // 4 levels: the pixel's point is not exactly the one the twin shades.
            assert!(
                close(dark, want_dark, 4),
                "{name}: {dark:?} vs {want_dark:?}"
            );
            assert!(close(lit, want_lit, 4), "{name}: {lit:?} vs {want_lit:?}");
            let (i, o) = (at(inside), at(outside));
            let (want_i, want_o) = (twin(&light, inside, false), twin(&light, outside, true));
            assert!(
                close(i, want_i, 4),
                "{name}: inside the edge {i:?} vs {want_i:?}"
            );
            assert!(
                close(o, want_o, 4),
                "{name}: outside the edge {o:?} vs {want_o:?}"
            );
        }
    }
    // Switched off, the floor under the cube is lit like the rest.
    let light = lighting(false);
    let off = ShadowSettings {
        enabled: false,
        ..ShadowSettings::default()
    };
    let want = twin(&light, under, true);
    for (name, image, pixel) in images(light, off) {
        let q = pixel(under);
        let px = image.get_pixel(q.x as u32, q.y as u32);
        let got = [px[0], px[1], px[2]];
        assert!(
            close(got, want, 4),
            "shadows off, {name}: {got:?} vs {want:?}"
        );
    }
}

/// Every pixel of `a` within `tolerance` levels of `b`'s.
/// (`a`: the picture under test, `b`: the one it must equal.)
fn assert_within(name: &str, a: &image::RgbaImage, b: &image::RgbaImage, tolerance: u8) {
    assert_eq!(a.dimensions(), b.dimensions(), "{name}");
    for (x, y, p) in a.enumerate_pixels() {
        let q = b.get_pixel(x, y);
        let worst = (0..3).map(|c| p[c].abs_diff(q[c])).max().unwrap_or(0);
        assert!(
            worst <= tolerance,
            "{name}: pixel ({x}, {y}) {p:?} against {q:?}"
        );
    }
}

#[test]
fn the_filters_range_test_leaves_the_picture_as_it_was() {
    // The sun from above, the point light above the cube, and the point light off to the
    // side and ahead, so that the cube's shadow falls across two of its cube map's faces
    // (between −Y and −Z, 45° down): every render mode's picture with the range test equals
    // the one that always filters. 1 level: where the filter's nine weights sum to 9 it
    // answers 1 or 0 up to float rounding, and the shortcut answers 1 or 0 exactly.
    let oblique = Lighting {
        point_position: CUBE + Vec3::new(0.3, 0.7, 0.7),
        ..lighting(true)
    };
    // And maps of 203 texels: 1 / 203 is not exact in floats, and the last tile is partial.
    for (what, light, map_size) in [
        ("sun", lighting(false), 1024),
        ("point light above", lighting(true), 1024),
        ("point light at 45°", oblique, 1024),
        ("point light at 45°, 203-texel maps", oblique, 203),
    ] {
        let settings = ShadowSettings {
            map_size,
            ..ShadowSettings::default()
        };
        let with = images(light, settings);
        let without = images(
            light,
            ShadowSettings {
                pcf_range_test: false,
                ..settings
            },
        );
        let shadowless = images(
            light,
            ShadowSettings {
                enabled: false,
                ..settings
            },
        );
        for (((name, a, _), (_, b, _)), (_, c, _)) in with.iter().zip(&without).zip(&shadowless) {
            let name = format!("{what}, {name}");
            assert_within(&name, a, b, 1);
            // The picture has a shadow for the test to keep: it differs from no shadows.
            let shadowed = a.pixels().zip(c.pixels()).filter(|(p, q)| p != q).count();
            assert!(shadowed > 100, "{name}: no shadow in the picture");
        }
    }
}

/// A mono frame from `HEAD` under `lighting`, the default shadows.
fn mono_frame(cave: &omnicave::cave::Cave, lighting: Lighting) -> FrameParams<'_> {
    let mut frame = test_frame(
        cave,
        Head::at(HEAD),
        RenderMode::Mono,
        OmniSettings::default(),
        TessSettings::default(),
    );
    frame.lighting = lighting;
    frame
}

#[test]
fn the_range_tiles_hold_every_depth_the_filter_can_read() {
    // The point light's six layers and the sun's one, read back after a frame: the GPU's
    // tiles equal the CPU twin's (min and max of the same floats: exact), and they are not
    // trivial (the cube's silhouette makes ranges that are not a single depth).
    use omnicave::render::shadow_pass::tile_ranges;
    for (point, layers) in [(true, 6), (false, 1)] {
        let cave = cave_at(160, 140);
        let mut renderer = Renderer::new(gpu(), &cave, NO_MSAA).expect("renderer");
        renderer.set_scene(&scene()).expect("scene upload");
        let mut frame = mono_frame(&cave, lighting(point));
        // 203 texels: rows padded to 1024 bytes in the copy, and a last tile of 3 texels.
        frame.shadows = ShadowSettings {
            map_size: 203,
            ..ShadowSettings::default()
        };
        renderer.render(&frame).expect("render");
        let maps = renderer.read_shadow_maps(layers).expect("read back");
        assert_eq!(maps.depths.len(), layers);
        assert_eq!(maps.ranges.len(), layers);
        let mut spread = 0;
        for (layer, (depths, ranges)) in maps.depths.iter().zip(&maps.ranges).enumerate() {
            let twin = tile_ranges(depths, maps.map_size);
            assert_eq!(
                ranges.len(),
                51 * 51,
                "layer {layer}: 203 texels in tiles of 4"
            );
            for (i, (gpu, cpu)) in ranges.iter().zip(&twin).enumerate() {
                assert_eq!(gpu, cpu, "layer {layer}, tile {i}");
            }
            spread += ranges.iter().filter(|r| r[0] < r[1]).count();
        }
        assert!(spread > 0, "every tile one depth: the test shows nothing");
    }
}

#[test]
fn the_range_tiles_follow_the_settings_and_the_map_size() {
    // One renderer through the changes a user makes in the panel: maps drawn with the range
    // test off (no tiles computed), then on (the maps are not drawn again, the tiles must be),
    // then another map size (maps and tiles again). Each picture equals a fresh renderer's
    // (within 1 level, as above): stale or missing tiles would shade lit floor as shadowed.
    let cave = cave_at(160, 140);
    let front = cave.wall_index("front").unwrap();
    let picture = |renderer: &mut Renderer, shadows: ShadowSettings| {
        let mut frame = mono_frame(&cave, lighting(true));
        frame.shadows = shadows;
        renderer.render(&frame).expect("render");
        renderer.read_images().expect("read back")[front]
            .left
            .clone()
    };
    let fresh = |shadows: ShadowSettings| {
        let mut renderer = Renderer::new(gpu(), &cave, NO_MSAA).expect("renderer");
        renderer.set_scene(&scene()).expect("scene upload");
        picture(&mut renderer, shadows)
    };
    let mut renderer = Renderer::new(gpu(), &cave, NO_MSAA).expect("renderer");
    renderer.set_scene(&scene()).expect("scene upload");
    let off = ShadowSettings {
        pcf_range_test: false,
        ..ShadowSettings::default()
    };
    let resized = ShadowSettings {
        map_size: 512,
        ..ShadowSettings::default()
    };
    for (name, settings) in [
        ("range test off", off),
        ("then on", ShadowSettings::default()),
        ("then 512-texel maps", resized),
        (
            "then off again",
            ShadowSettings {
                map_size: 512,
                ..off
            },
        ),
        ("then on again", resized),
    ] {
        let got = picture(&mut renderer, settings);
        assert_within(name, &got, &fresh(settings), 1);
    }
}

#[test]
fn a_point_lights_shadows_fall_right_through_five_faces_of_its_cube() {
    // A point light 0.5 m above a floor beyond the front wall, with boxes around it in eight
    // directions (the four side faces' axes and the diagonals between them, where two faces
    // meet and overlap) and one under it (the bottom face): every floor pixel of the front
    // wall away from a shadow's edge is as dark or as lit as the CPU twin says, as the segment
    // to the light meets the scene's triangles or not (the panorama's CPU ray caster). A
    // wrongly chosen face reads as lit, so the shadowed pixels are what check the choice. The
    // scene is turned 30° against the CAVE and moved, so the cube map's faces (the scene's
    // axes) are not the CAVE's: the shader picks the face from the maps' own matrices. (The
    // floor lies below the light: its top face lights nothing here.)
    let world_from_cave =
        Mat4::from_translation(Vec3::new(0.4, 0.0, -0.7)) * Mat4::from_rotation_y(0.52);
    let light_cave = Vec3::new(0.1, 0.5, -3.3);
    let half = Vec3::new(0.1, 0.1, 0.1);
    // Turning by 0.52 rad about y adds 0.52 to the angle of (sin, cos): so these lie along
    // the scene's axes and diagonals.
    let mut boxes: Vec<Vec3> = (0..8)
        .map(|k| {
            let a = k as f32 * std::f32::consts::FRAC_PI_4 - 0.52;
            light_cave + Vec3::new(0.6 * a.sin(), -0.15, 0.6 * a.cos())
        })
        .collect();
    boxes.push(light_cave - Vec3::Y * 0.25);
    let mut scene = Scene::default();
    let grey = add_grey(&mut scene);
    let floor = grid(
        Vec3::new(-4.0, 0.0, 0.0),
        Vec3::X * 8.0,
        Vec3::NEG_Z * 8.0,
        8,
        8,
        1.0,
    )
    .transformed(world_from_cave);
    scene.add_mesh(&floor.vertices, &floor.indices, grey);
    for &c in &boxes {
        let cube = cuboid(half * 2.0, 1.0).transformed(world_from_cave * Mat4::from_translation(c));
        scene.add_mesh(&cube.vertices, &cube.indices, grey);
    }
    let light = Lighting {
        point_position: world_from_cave.transform_point3(light_cave),
        ..lighting(true)
    };
    let cave = cave_at(320, 280);
    let front = cave.wall_index("front").unwrap();
    let mut renderer = Renderer::new(gpu(), &cave, NO_MSAA).expect("renderer");
    renderer.set_scene(&scene).expect("scene upload");
    let mut frame = mono_frame(&cave, light);
    frame.world_from_cave = world_from_cave;
    renderer.render(&frame).expect("render");
    let image = renderer.read_images().expect("read back")[front]
        .left
        .clone();
    let shade = |p: Vec3, lit: bool| placed_twin(world_from_cave, &light, p, lit);
    // The scene's own triangles in CAVE space, for what the light and the eye see.
    let caster = RayCaster::new(&scene, world_from_cave.inverse());
    let shadowed = |p: Vec3| {
        let to_light = light_cave - p;
        let length = to_light.length();
        caster.cast(p, to_light / length, 1e-4, length).is_some()
    };
    let wall = &cave.walls[front];
    let size = wall.size_m();
    // Pixels tested, lit and shadowed, by the cube face their direction from the light lies
    // along (the scene's axes: +X, -X, +Y, -Y, +Z, -Z).
    let mut tested = [[0usize; 2]; 6];
    // Shadowed pixels within the degree where two faces overlap.
    let mut at_seams = 0;
    let (w, h) = image.dimensions();
    for py in (0..h).step_by(2) {
        for px in (0..w).step_by(2) {
            let on_wall = wall.lower_left
                + wall.right_axis() * ((px as f32 + 0.5) / w as f32 * size.x)
                + wall.up_axis() * ((1.0 - (py as f32 + 0.5) / h as f32) * size.y);
            let dir = on_wall - HEAD;
            if dir.y >= -1e-3 {
                continue;
            }
            let p = HEAD + dir * (-HEAD.y / dir.y);
            let from_light = p - light_cave;
            // Within 2 m of the light (further out the light grazes the floor and the
            // slope-scaled bias decides), seen past the boxes, and 3 cm from any shadow's edge
            // (the filter and the normal offset reach a few millimetres there).
            let seen = caster
                .cast(HEAD, dir.normalize(), 0.0, f32::MAX)
                .is_some_and(|hit| (hit.distance - (p - HEAD).length()).abs() < 1e-3);
            if from_light.length() > 2.0 || !seen {
                continue;
            }
            let lit = !shadowed(p);
            let margin = 0.03;
            let near_edge = [Vec3::X, Vec3::NEG_X, Vec3::Z, Vec3::NEG_Z]
                .iter()
                .any(|&o| shadowed(p + o * margin) == lit);
            if near_edge {
                continue;
            }
            let want = shade(p, lit);
            let px_colour = image.get_pixel(px, py);
            let got = [px_colour[0], px_colour[1], px_colour[2]];
            assert!(
                close(got, want, 4),
                "pixel ({px}, {py}), floor point {p} (CAVE): {got:?}, the twin says {} {want:?}",
                if lit { "lit" } else { "shadowed" }
            );
            let d = world_from_cave.transform_vector3(from_light);
            let a = d.abs();
            let axis = if a.x >= a.y && a.x >= a.z {
                0
            } else if a.y >= a.z {
                1
            } else {
                2
            };
            tested[2 * axis + usize::from(d[axis] < 0.0)][usize::from(lit)] += 1;
            let mut sorted = a.to_array();
            sorted.sort_by(f32::total_cmp);
            if !lit && sorted[1] >= sorted[2] * 44.5f32.to_radians().tan() {
                at_seams += 1;
            }
        }
    }
    // Shadows and light through each side face (the front wall sees the floor around the
    // light on every side) and the bottom one, and shadows where faces overlap.
    for face in [0, 1, 3, 4, 5] {
        assert!(
            tested[face][0] > 20 && tested[face][1] > 20,
            "face {face}: {:?}",
            tested[face]
        );
    }
    assert!(
        at_seams > 20,
        "{at_seams} shadowed pixels where faces overlap"
    );
}
