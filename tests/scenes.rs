//! The bundled scenes match their generator and load; glTF features (node hierarchy, unlit,
//! emissive, textures) survive the whole path from file to pixels.
#![allow(clippy::unwrap_used, clippy::expect_used)]

mod common;

use std::path::Path;
use std::process::Command;

use common::*;
use glam::{Mat4, Quat, Vec3};
use omnicave::cave::{Head, RenderMode};
use omnicave::render::RenderSettings;
use omnicave::scene::build::{cuboid, grid, uv_sphere};
use omnicave::scene::glb_writer::{GlbWriter, MaterialDesc, NodeDesc};
use omnicave::scene::load_gltf;

fn repo(rel: &str) -> std::path::PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join(rel)
}

#[test]
fn committed_assets_match_the_generator() {
    let out = Command::new(env!("CARGO_BIN_EXE_gen-assets"))
        .args(["--check", "--out"])
        .arg(repo("assets"))
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
}

#[test]
fn bundled_scenes_load_with_textures_and_surround_the_cave() {
    for (name, min_tris, min_textures) in [("living-room.glb", 5_000, 4), ("city.glb", 5_000, 2)] {
        let scene = load_gltf(&repo(&format!("assets/{name}"))).unwrap();
        let (lo, hi) = scene.bounds().unwrap();
        assert!(scene.triangle_count() >= min_tris, "{name}");
        assert!(scene.textures.len() >= min_textures, "{name}");
        // The CAVE (±1.65 m, 0..2.9 m) stands inside the scene's horizontal extent.
        assert!(
            lo.x < -1.65 && hi.x > 1.65 && lo.z < -1.65 && hi.z > 1.65,
            "{name}"
        );
        for v in &scene.vertices {
            let n = Vec3::from(v.normal);
            assert!((n.length() - 1.0).abs() < 1e-3, "{name}: normal {n}");
        }
    }
}

#[test]
fn gltf_node_hierarchy_unlit_and_emissive_render_where_and_how_expected() {
    // A marker placed through two nested nodes (translate, then rotate+scale), an unlit colour
    // and an emissive-only surface, written as a real .glb and loaded back.
    let mut w = GlbWriter::new();
    let unlit = w.add_material(&MaterialDesc {
        unlit: true,
        ..MaterialDesc::plain("unlit green", [0.0, 1.0, 0.0], 1.0)
    });
    let emissive = w.add_material(&MaterialDesc {
        emissive: [1.0, 0.0, 0.0],
        ..MaterialDesc::plain("glowing", [0.0, 0.0, 0.0], 1.0)
    });
    let sphere = uv_sphere(0.03, 12, 16);
    let panel = cuboid(Vec3::new(0.6, 0.4, 0.02), 1.0);
    let m_sphere = w.add_mesh("marker", &[(&sphere, unlit)]);
    let m_panel = w.add_mesh("panel", &[(&panel, emissive)]);
    let child = w.add_node(
        NodeDesc::new("child")
            .with_mesh(m_sphere)
            .at(Vec3::new(0.5, 0.0, 0.0))
            .rotated_y_degrees(90.0)
            .scaled(Vec3::splat(1.5)),
    );
    let parent = w.add_node(
        NodeDesc::new("parent")
            .at(Vec3::new(0.2, 1.5, -3.0))
            .rotated_y_degrees(90.0)
            .with_children(vec![child]),
    );
    let panel_node = w.add_node(
        NodeDesc::new("panel")
            .with_mesh(m_panel)
            .at(Vec3::new(-0.8, 1.2, -3.0)),
    );
    let path = Path::new(env!("CARGO_TARGET_TMPDIR")).join("hierarchy.glb");
    std::fs::write(&path, w.to_glb(&[parent, panel_node])).unwrap();
    let scene = load_gltf(&path).unwrap();

    // Where the marker's centre should be: parent · child · origin.
    let parent_m = Mat4::from_rotation_translation(
        Quat::from_rotation_y(90f32.to_radians()),
        Vec3::new(0.2, 1.5, -3.0),
    );
    let child_m = Mat4::from_scale_rotation_translation(
        Vec3::splat(1.5),
        Quat::from_rotation_y(90f32.to_radians()),
        Vec3::new(0.5, 0.0, 0.0),
    );
    let centre = (parent_m * child_m).transform_point3(Vec3::ZERO);
    assert!(
        (centre - Vec3::new(0.2, 1.5, -3.5)).length() < 1e-5,
        "{centre}"
    );

    let size = [960, 540];
    let cave = cave_at(size[0], size[1]);
    let head = Head::at(Vec3::new(0.0, 1.7, 0.0));
    let images = render(&cave, head, RenderMode::Mono, &scene, NO_MSAA);
    let front = cave.wall_index("front").unwrap();
    let img = &images[front].left;
    let expected = cave.walls[front]
        .pixel_of_ray(head.position, centre)
        .unwrap();
    let (got, _) = centroid_of(img, [0, 255, 0]).expect("unlit marker drawn in exactly its colour");
    assert!((got - expected).length() <= 1.0);

    // The emissive panel (black base colour) shows its emission: saturated red. Green and blue
    // are not zero: even a black dielectric keeps a weak specular reflection (strength 0.04,
    // broad at roughness 1), about 0.03 linear ≈ 50 in sRGB.
    let p = cave.walls[front]
        .pixel_of_ray(head.position, Vec3::new(-0.8, 1.2, -2.99))
        .unwrap();
    let px = img.get_pixel(p.x as u32, p.y as u32);
    assert!(px[0] >= 250 && px[1] <= 90 && px[2] <= 90, "{px:?}");
}

#[test]
fn textured_floor_is_sampled_and_lit() {
    // A floor quad with a two-colour checker texture: both texel colours must appear, and the
    // lit result must differ from the unlit texel values (lighting applied).
    let checker = image::RgbaImage::from_fn(8, 8, |x, y| {
        if (x / 4 + y / 4) % 2 == 0 {
            image::Rgba([255, 255, 255, 255])
        } else {
            image::Rgba([40, 40, 40, 255])
        }
    });
    let mut png = Vec::new();
    checker
        .write_to(&mut std::io::Cursor::new(&mut png), image::ImageFormat::Png)
        .unwrap();
    let mut w = GlbWriter::new();
    let tex = w.add_png_texture("checker", &png);
    let mat = w.add_material(&MaterialDesc {
        texture: Some(tex),
        ..MaterialDesc::plain("floor", [1.0; 3], 0.8)
    });
    let floor = grid(
        Vec3::new(-4.0, 0.0, 4.0),
        Vec3::X * 8.0,
        Vec3::NEG_Z * 8.0,
        1,
        1,
        0.5,
    );
    let mesh = w.add_mesh("floor", &[(&floor, mat)]);
    let node = w.add_node(NodeDesc::new("floor").with_mesh(mesh));
    let path = Path::new(env!("CARGO_TARGET_TMPDIR")).join("checker.glb");
    std::fs::write(&path, w.to_glb(&[node])).unwrap();
    let scene = load_gltf(&path).unwrap();
    assert_eq!(scene.textures.len(), 1);

    let cave = cave_at(320, 180);
    let images = render(
        &cave,
        Head::at(Vec3::new(0.0, 1.7, 0.0)),
        RenderMode::Mono,
        &scene,
        RenderSettings::default(),
    );
    let front = &images[cave.wall_index("front").unwrap()].left;
    // Lower half of the front wall shows the floor.
    let lum: Vec<u32> = (100..180)
        .flat_map(|y| (0..320).map(move |x| (x, y)))
        .map(|(x, y)| {
            front.get_pixel(x, y).0[..3]
                .iter()
                .map(|&c| u32::from(c))
                .sum::<u32>()
                / 3
        })
        .collect();
    let bright = lum.iter().filter(|&&l| l > 150).count();
    let dark = lum.iter().filter(|&&l| l < 80).count();
    assert!(
        bright > lum.len() / 5 && dark > lum.len() / 5,
        "checker not visible"
    );
}

#[test]
fn the_double_sided_setting_draws_content_wound_the_wrong_way() {
    // A single-sided quad in front of the front wall whose front face points away from the
    // viewer (as in a model wound inward): culled as the file says, drawn with
    // `[scene] double_sided = true`.
    let mut w = GlbWriter::new();
    let mat = w.add_material(&MaterialDesc {
        unlit: true,
        ..MaterialDesc::plain("away", [1.0, 0.0, 1.0], 0.5)
    });
    // u × v = X × −Y = −Z: the front face looks towards the front wall, away from the viewer.
    let quad = grid(Vec3::new(-0.5, 2.2, -1.0), Vec3::X, Vec3::NEG_Y, 1, 1, 1.0);
    let mesh = w.add_mesh("away", &[(&quad, mat)]);
    let node = w.add_node(NodeDesc::new("away").with_mesh(mesh));
    let path = Path::new(env!("CARGO_TARGET_TMPDIR")).join("wound-away.glb");
    std::fs::write(&path, w.to_glb(&[node])).unwrap();

    let cave = cave_at(160, 90);
    let magenta_at_centre = |double_sided: bool| {
        let mut settings = omnicave::config::ConfigFile::default();
        settings.scene.double_sided = double_sided;
        let scene = omnicave::setup::load_scene(&settings, &path).unwrap();
        let images = render(
            &cave,
            Head::at(Vec3::new(0.0, 1.7, 0.0)),
            RenderMode::Mono,
            &scene,
            RenderSettings::default(),
        );
        let front = &images[cave.wall_index("front").unwrap()].left;
        // The quad covers the wall's centre seen from the head.
        let p = front.get_pixel(80, 40).0;
        p[0] > 200 && p[1] < 60 && p[2] > 200
    };
    assert!(!magenta_at_centre(false), "a back face was drawn");
    assert!(
        magenta_at_centre(true),
        "double_sided did not draw the back face"
    );
}

#[test]
fn a_camera_of_the_file_gives_the_start_viewpoint() {
    // A camera 3 m along +x and 4 m along −z, turned 90° to the left (looking along −x): with
    // `[scene] camera`, the configured head stands there, looking where it looks.
    let mut w = GlbWriter::new();
    let m = w.add_material(&MaterialDesc::plain("grey", [0.5; 3], 1.0));
    let mesh = w.add_mesh("box", &[(&cuboid(Vec3::ONE, 1.0), m)]);
    let cam = w.add_camera("entrance", 1.0);
    let b = w.add_node(NodeDesc::new("box").with_mesh(mesh));
    let c = w.add_node(
        NodeDesc::new("entrance camera")
            .with_camera(cam)
            .at(Vec3::new(3.0, 1.6, -4.0))
            .rotated_y_degrees(90.0),
    );
    let path = Path::new(env!("CARGO_TARGET_TMPDIR")).join("camera.glb");
    std::fs::write(&path, w.to_glb(&[b, c])).unwrap();
    let scene = load_gltf(&path).unwrap();
    assert_eq!(scene.cameras.len(), 1);
    assert_eq!(scene.cameras[0].name, "entrance");

    let mut settings = omnicave::config::ConfigFile::default();
    settings.head.position = [0.2, 1.7, 0.1];
    for name in ["entrance", "0"] {
        settings.scene.camera = name.into();
        omnicave::setup::place_at_camera(&mut settings, &scene).unwrap();
        let world_from_cave = settings.world_from_cave();
        let head = world_from_cave.transform_point3(Vec3::from(settings.head.position));
        let ahead = world_from_cave.transform_vector3(Vec3::NEG_Z);
        assert!((head - Vec3::new(3.0, 1.6, -4.0)).length() < 1e-5, "{head}");
        assert!((ahead - Vec3::NEG_X).length() < 1e-5, "{ahead}");
    }
    settings.scene.camera = "balcony".into();
    let err = omnicave::setup::place_at_camera(&mut settings, &scene)
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("balcony") && err.contains("0: \"entrance\""),
        "{err}"
    );
}
