//! glTF as exporters write it, from file to pixels: every feature the loader reads is written
//! into a real file by the test, loaded back and rendered on the walls, through the
//! tessellated omnistereo path and in the panorama, and the pixels are checked where the
//! feature says they must change (and against the CPU twin of the shading where it lights).
//! Every generated file is also checked by the Khronos glTF validator. A minimal file without
//! normals gets them from its winding, and `extras` of any JSON type load.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::print_stdout)]

mod common;

use std::path::{Path, PathBuf};

use common::gltf_files::{with_json, write_triangle_gltf};
use common::*;
use glam::{Vec2, Vec3};
use image::RgbaImage;
use omnicave::cave::omni::OmniSettings;
use omnicave::cave::{Cave, Head, RenderMode};
use omnicave::pano::{PanoRoute, PanoSettings, Projection};
use omnicave::render::Renderer;
use omnicave::render::pbr::{LIT, SurfacePoint, shade_pbr};
use omnicave::render::uniforms::{FrameLights, FrameUniforms, MAX_LIGHTS};
use omnicave::scene::build::{MeshData, grid, uv_sphere};
use omnicave::scene::glb_writer::{
    AttributeEncoding, GlbWriter, LightDesc, MaterialDesc, MaterialMaps, MeshOptions, NodeDesc,
    quantization_step,
};
use omnicave::scene::{Lighting, Scene, Shading, load_gltf};
use omnicave::tess::{Criterion, TessSettings};
use serde_json::json;

const HEAD: Vec3 = Vec3::new(0.0, 1.6, 0.0);

fn cave() -> Cave {
    cave_at(320, 280)
}

/// Where generated files are kept (and validated).
fn out_dir() -> PathBuf {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("target/test-gltf");
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

fn write(name: &str, w: &GlbWriter, roots: &[usize]) -> PathBuf {
    let path = out_dir().join(format!("{name}.glb"));
    std::fs::write(&path, w.to_glb(roots)).unwrap();
    path
}

fn png(img: &RgbaImage) -> Vec<u8> {
    let mut out = Vec::new();
    img.write_to(&mut std::io::Cursor::new(&mut out), image::ImageFormat::Png)
        .unwrap();
    out
}

/// A 0.8 m square facing the head (+z) at `z`, centred at (x, 1.6).
fn square(x: f32, z: f32) -> MeshData {
    grid(
        Vec3::new(x - 0.4, 1.2, z),
        Vec3::X * 0.8,
        Vec3::Y * 0.8,
        1,
        1,
        1.0 / 0.8,
    )
}

/// Lighting with nothing but what a test asks for.
fn dark() -> Lighting {
    Lighting {
        ambient: Vec3::ZERO,
        sun_direction: Vec3::NEG_Y,
        sun_color: Vec3::ZERO,
        point_position: Vec3::ZERO,
        point_color: Vec3::ZERO,
        point_range: 1.0,
        sun_shadows: true,
        point_shadows: true,
    }
}

/// One way of drawing a scene, and where a CAVE-space point lands in its image.
struct Route {
    name: &'static str,
    image: RgbaImage,
    pano: Option<PanoSettings>,
}

impl Route {
    fn pixel(&self, cave: &Cave, p: Vec3) -> Vec2 {
        match &self.pano {
            None => {
                let front = &cave.walls[cave.wall_index("front").unwrap()];
                front.pixel_of_ray(HEAD, p).unwrap()
            }
            Some(pano) => {
                let dir = pano.view_from_cave(HEAD).transform_vector3(p - HEAD);
                let ndc = pano.fitted().project(dir).unwrap();
                let [w, h] = pano.size.map(|v| v as f32);
                Vec2::new((ndc.x + 1.0) * 0.5 * w, (1.0 - ndc.y) * 0.5 * h)
            }
        }
    }

    fn at(&self, cave: &Cave, p: Vec3) -> [u8; 3] {
        let q = self.pixel(cave, p);
        let px = self.image.get_pixel(q.x as u32, q.y as u32);
        [px[0], px[1], px[2]]
    }
}

/// The scene drawn three ways: the front wall (mono, plain draw), the front wall through the
/// tessellated omnistereo path (left eye), and the panorama's geometric route (perspective,
/// ahead).
fn routes(scene: &Scene, lighting: Lighting) -> Vec<Route> {
    routes_shaded(scene, lighting, Shading::Pbr)
}

/// [`routes`] in the shading model `shading`.
fn routes_shaded(scene: &Scene, lighting: Lighting, shading: Shading) -> Vec<Route> {
    let cave = cave();
    let front = cave.wall_index("front").unwrap();
    let mut renderer = Renderer::new(gpu(), &cave, NO_MSAA).expect("renderer");
    renderer.set_scene(scene).expect("scene upload");
    let mut out = Vec::new();
    for (name, mode, tess) in [
        ("walls", RenderMode::Mono, TessSettings::default()),
        (
            "omnistereo, tessellated",
            RenderMode::OmniOffAxis,
            TessSettings {
                criterion: Some(Criterion::Error(0.5)),
                ..TessSettings::default()
            },
        ),
    ] {
        let mut frame = test_frame(&cave, Head::at(HEAD), mode, OmniSettings::default(), tess);
        frame.lighting = lighting;
        frame.shading = shading;
        renderer.render(&frame).expect("render");
        let images = renderer.read_images().expect("read back");
        out.push(Route {
            name,
            image: images[front].left.clone(),
            pano: None,
        });
    }
    let mut pano = pano_settings(Projection::Perspective, PanoRoute::Geometric, [90.0, 80.0]);
    pano.size = [320, 280];
    let mut frame = test_frame(
        &cave,
        Head::at(HEAD),
        RenderMode::Mono,
        OmniSettings::default(),
        TessSettings::default(),
    );
    frame.lighting = lighting;
    frame.shading = shading;
    renderer.render_panorama(&frame, &pano).expect("panorama");
    let [image, _] = renderer.read_panorama().expect("read back");
    out.push(Route {
        name: "panorama",
        image,
        pano: Some(pano),
    });
    out
}

/// A matte dielectric point as the CPU twin shades it for the head, in sRGB bytes.
fn twin(lighting: &Lighting, p: Vec3, normal: Vec3, base_color: Vec3) -> [u8; 3] {
    let frame = FrameUniforms::new(
        glam::Mat4::IDENTITY,
        FrameLights {
            config: lighting,
            scene: &[],
            shading: Shading::Pbr,
        },
        None,
        None,
        None,
    );
    let surface = SurfacePoint {
        position: p,
        normal,
        base_color,
        metallic: 0.0,
        roughness: 1.0,
        occlusion: 1.0,
    };
    srgb(shade_pbr(&frame, &surface, HEAD, &LIT))
}

fn close(a: [u8; 3], b: [u8; 3], tolerance: u8) -> bool {
    a.iter().zip(b).all(|(x, y)| x.abs_diff(y) <= tolerance)
}

fn srgb(linear: Vec3) -> [u8; 3] {
    linear
        .to_array()
        .map(omnicave::sky::cubemap::linear_to_srgb)
}

// ---- the files ----

fn checker_png() -> Vec<u8> {
    png(&RgbaImage::from_fn(16, 16, |x, y| {
        if (x / 4 + y / 4) % 2 == 0 {
            image::Rgba([255, 255, 255, 255])
        } else {
            image::Rgba([0, 255, 0, 255])
        }
    }))
}

/// Two squares of the same lit colour. `cad`: both without texture coordinates and without
/// textures, as CAD tools export (valid glTF; drawn black before). Otherwise the left one's
/// material also has a base colour texture its primitive has no coordinates for (invalid
/// glTF, MESH_PRIMITIVE_TOO_FEW_TEXCOORDS, but written by careless exporters), the right one
/// none.
fn file_without_uvs(cad: bool) -> PathBuf {
    let mut w = GlbWriter::new();
    let texture = if cad {
        None
    } else {
        Some(w.add_png_texture("checker", &checker_png()))
    };
    let left = w.add_material(&MaterialDesc {
        texture,
        ..MaterialDesc::plain("left", [0.8, 0.3, 0.1], 1.0)
    });
    let right = w.add_material(&MaterialDesc::plain("right", [0.8, 0.3, 0.1], 1.0));
    let options = MeshOptions {
        uvs: false,
        ..MeshOptions::default()
    };
    let a = w.add_mesh_with("left", &[(&square(-0.45, -1.0), left)], &options);
    let b = w.add_mesh_with("right", &[(&square(0.45, -1.0), right)], &options);
    let na = w.add_node(NodeDesc::new("a").with_mesh(a));
    let nb = w.add_node(NodeDesc::new("b").with_mesh(b));
    let name = if cad {
        "no-uvs"
    } else {
        "invalid-texture-without-uvs"
    };
    write(name, &w, &[na, nb])
}

/// An unlit white square whose corners are red, green, blue and yellow (COLOR_0).
fn file_vertex_colours(encoding: AttributeEncoding) -> PathBuf {
    let mut w = GlbWriter::new();
    let white = w.add_material(&MaterialDesc {
        unlit: true,
        ..MaterialDesc::plain("white", [1.0; 3], 1.0)
    });
    let mut sq = square(0.0, -1.0);
    // grid's corner order: (0,0) bottom left, (1,0) bottom right, (0,1) top left, (1,1).
    for v in &mut sq.vertices {
        let left = v.position[0] < 0.0;
        let low = v.position[1] < 1.6;
        v.color = match (left, low) {
            (true, true) => [1.0, 0.0, 0.0, 1.0],
            (false, true) => [0.0, 1.0, 0.0, 1.0],
            (true, false) => [0.0, 0.0, 1.0, 1.0],
            (false, false) => [1.0, 1.0, 0.0, 1.0],
        };
    }
    let step = quantization_step(&sq);
    let options = MeshOptions {
        encoding,
        colors: true,
        ..MeshOptions::default()
    };
    let m = w.add_mesh_with("colours", &[(&sq, white)], &options);
    let mut node = NodeDesc::new("colours").with_mesh(m);
    if encoding == AttributeEncoding::Quantized {
        node = node.scaled(Vec3::splat(step));
    }
    let n = w.add_node(node);
    write(&format!("vertex-colours-{encoding:?}"), &w, &[n])
}

/// An unlit square with a red | blue texture moved half its width by KHR_texture_transform.
fn file_texture_transform() -> PathBuf {
    let halves = png(&RgbaImage::from_fn(64, 64, |x, _| {
        if x < 32 {
            image::Rgba([255, 0, 0, 255])
        } else {
            image::Rgba([0, 0, 255, 255])
        }
    }));
    let mut w = GlbWriter::new();
    let tex = w.add_png_texture("halves", &halves);
    let moved = w.add_material(&MaterialDesc {
        texture: Some(tex),
        texture_transform: Some(([0.5, 0.0], 0.0, [1.0, 1.0])),
        unlit: true,
        ..MaterialDesc::plain("moved", [1.0; 3], 1.0)
    });
    let m = w.add_mesh("moved", &[(&square(0.0, -1.0), moved)]);
    let n = w.add_node(NodeDesc::new("moved").with_mesh(m));
    write("texture-transform", &w, &[n])
}

/// A textured, lit sphere written with `encoding`.
fn file_sphere(encoding: AttributeEncoding) -> PathBuf {
    let mut w = GlbWriter::new();
    let tex = w.add_png_texture("checker", &checker_png());
    let mat = w.add_material(&MaterialDesc {
        texture: Some(tex),
        ..MaterialDesc::plain("sphere", [1.0; 3], 0.5)
    });
    let sphere = uv_sphere(0.35, 24, 48);
    let step = quantization_step(&sphere);
    let m = w.add_mesh_with(
        "sphere",
        &[(&sphere, mat)],
        &MeshOptions {
            encoding,
            ..MeshOptions::default()
        },
    );
    let mut node = NodeDesc::new("sphere")
        .with_mesh(m)
        .at(Vec3::new(0.0, 1.6, -1.2));
    if encoding == AttributeEncoding::Quantized {
        node = node.scaled(Vec3::splat(step));
    }
    let n = w.add_node(node);
    write(&format!("sphere-{encoding:?}"), &w, &[n])
}

/// A grey, matte square with a constant normal map tilting its normal towards +x by
/// atan(0.5): the left square with tangents from the file, the right one without (MikkTSpace).
fn file_normal_map() -> PathBuf {
    // Tangent-space normal (0.5, 0, 1) normalised, encoded 0..255.
    let m = Vec3::new(0.5, 0.0, 1.0).normalize();
    let texel = (m * 0.5 + 0.5) * 255.0;
    let map = png(&RgbaImage::from_pixel(
        8,
        8,
        image::Rgba([
            texel.x.round() as u8,
            texel.y.round() as u8,
            texel.z.round() as u8,
            255,
        ]),
    ));
    let mut w = GlbWriter::new();
    let tex = w.add_png_texture("normal", &map);
    let mat = w.add_material(&MaterialDesc {
        maps: MaterialMaps {
            normal: Some(tex),
            ..MaterialMaps::default()
        },
        ..MaterialDesc::plain("bumped", [0.8; 3], 1.0)
    });
    let flat = w.add_material(&MaterialDesc::plain("flat", [0.8; 3], 1.0));
    let mut with_tangents = square(-0.45, -1.0);
    for v in &mut with_tangents.vertices {
        // u grows along +x, v (image rows) downwards: bitangent −y = −(n × t).
        v.tangent = [1.0, 0.0, 0.0, -1.0];
    }
    let a = w.add_mesh_with(
        "file tangents",
        &[(&with_tangents, mat)],
        &MeshOptions {
            tangents: true,
            ..MeshOptions::default()
        },
    );
    let b = w.add_mesh("generated tangents", &[(&square(0.45, -1.0), mat)]);
    let c = w.add_mesh(
        "flat",
        &[(
            &square(0.0, -1.3).transformed(glam::Mat4::from_translation(Vec3::new(0.0, 0.95, 0.0))),
            flat,
        )],
    );
    let roots = [a, b, c].map(|m| w.add_node(NodeDesc::new("square").with_mesh(m)));
    write("normal-map", &w, &roots)
}

/// A black square glowing white where its emissive map is white (left half) only.
fn file_emissive_map() -> PathBuf {
    let halves = png(&RgbaImage::from_fn(64, 64, |x, _| {
        if x < 32 {
            image::Rgba([255, 255, 255, 255])
        } else {
            image::Rgba([0, 0, 0, 255])
        }
    }));
    let mut w = GlbWriter::new();
    let tex = w.add_png_texture("glow", &halves);
    let mat = w.add_material(&MaterialDesc {
        emissive: [1.0; 3],
        maps: MaterialMaps {
            emissive: Some(tex),
            ..MaterialMaps::default()
        },
        ..MaterialDesc::plain("glowing", [0.0; 3], 1.0)
    });
    let m = w.add_mesh("glowing", &[(&square(0.0, -1.0), mat)]);
    let n = w.add_node(NodeDesc::new("glowing").with_mesh(m));
    write("emissive-map", &w, &[n])
}

/// Two half-transparent unlit squares overlapping: red near, blue far, written near first.
fn file_blend() -> PathBuf {
    let mut w = GlbWriter::new();
    let red = w.add_material(&MaterialDesc {
        base_color: [1.0, 0.0, 0.0, 0.5],
        alpha_blend: true,
        unlit: true,
        ..MaterialDesc::plain("red glass", [1.0, 0.0, 0.0], 1.0)
    });
    let blue = w.add_material(&MaterialDesc {
        base_color: [0.0, 0.0, 1.0, 0.5],
        alpha_blend: true,
        unlit: true,
        ..MaterialDesc::plain("blue glass", [0.0, 0.0, 1.0], 1.0)
    });
    let near = w.add_mesh("near", &[(&square(-0.2, -1.0), red)]);
    let far = w.add_mesh("far", &[(&square(0.2, -1.3), blue)]);
    let a = w.add_node(NodeDesc::new("near").with_mesh(near));
    let b = w.add_node(NodeDesc::new("far").with_mesh(far));
    write("blend", &w, &[a, b])
}

/// A matte floor (at 0.8 m, so that the front wall sees it) under spot lights from the file,
/// each pointing straight down from 2 m above the floor at x along z = −1.3: one per
/// `(x, outer cone half-angle)`, the inner cone 5° narrower (or 1° for a narrower one).
fn file_spots_over_floor(name: &str, spots: &[(f32, f32)]) -> PathBuf {
    let mut w = GlbWriter::new();
    let mat = w.add_material(&MaterialDesc::plain("floor", [0.8; 3], 1.0));
    let floor = grid(
        Vec3::new(-2.0, 0.8, 1.0),
        Vec3::X * 4.0,
        Vec3::NEG_Z * 4.0,
        8,
        8,
        0.5,
    );
    let m = w.add_mesh("floor", &[(&floor, mat)]);
    let mut roots = vec![w.add_node(NodeDesc::new("floor").with_mesh(m))];
    for (k, &(x, outer_degrees)) in spots.iter().enumerate() {
        let inner_degrees = if outer_degrees > 5.0 {
            outer_degrees - 5.0
        } else {
            outer_degrees.min(1.0)
        };
        let spot = w.add_light(&LightDesc {
            name: format!("spot {k}"),
            kind: "spot",
            color: [1.0, 1.0, 1.0],
            intensity: 4.0,
            range: None,
            cone: Some((inner_degrees.to_radians(), outer_degrees.to_radians())),
        });
        // The light shines along its node's −z: turned to point down.
        let mut node = NodeDesc::new(&format!("spot {k}"))
            .with_light(spot)
            .at(Vec3::new(x, 2.8, -1.3));
        node.rotation = glam::Quat::from_rotation_x(-std::f32::consts::FRAC_PI_2);
        roots.push(w.add_node(node));
    }
    write(name, &w, &roots)
}

/// The floor under one spot light at (0, 0.8, −1.3), with a 20° cone.
fn file_spot_light() -> PathBuf {
    file_spots_over_floor("spot-light", &[(0.0, 20.0)])
}

/// The floor under a row of `count` narrow spot lights 0.175 m apart (all in the panorama
/// route's view): light k's spot (7 cm across at full strength, 14 cm at its 2° outer cone)
/// lies at [`spot_row_x`]`(k)`.
fn file_spot_row(count: usize) -> PathBuf {
    let spots: Vec<(f32, f32)> = (0..count).map(|k| (spot_row_x(k), 2.0)).collect();
    file_spots_over_floor(&format!("spot-row-{count}"), &spots)
}

fn spot_row_x(k: usize) -> f32 {
    -0.5 + 0.175 * k as f32
}

// ---- the tests ----

#[test]
fn a_primitive_without_texture_coordinates_is_its_colour_not_black() {
    let mut lighting = dark();
    lighting.ambient = Vec3::splat(0.3);
    lighting.sun_color = Vec3::ONE;
    lighting.sun_direction = Vec3::new(0.0, -0.5, -1.0).normalize();
    let cave = cave();
    let (left, right) = (Vec3::new(-0.45, 1.6, -1.0), Vec3::new(0.45, 1.6, -1.0));
    let twin = |p: Vec3| twin(&lighting, p, Vec3::Z, Vec3::new(0.8, 0.3, 0.1));
    for cad in [true, false] {
        let scene = load_gltf(&file_without_uvs(cad)).unwrap();
        // A texture whose coordinates are missing is dropped for that primitive, not
        // sampled at made-up coordinates.
        for draw in &scene.draws {
            assert!(scene.materials[draw.material].base_color_texture.is_none());
        }
        for route in routes(&scene, lighting) {
            let a = route.at(&cave, left);
            let b = route.at(&cave, right);
            let want = twin(left);
            // Lit orange as the CPU twin shades it (4 levels: the pixel's point is not
            // exactly the one the twin shades), and both squares alike (2 levels: they are
            // seen at slightly different angles).
            let what = format!("{} (CAD export: {cad})", route.name);
            assert!(close(a, want, 4), "{what}: {a:?} vs twin {want:?}");
            assert!(close(a, b, 2), "{what}: {a:?} vs {b:?}");
        }
    }
}

#[test]
fn vertex_colours_are_drawn_in_every_route_and_encoding() {
    let cave = cave();
    let corners = [
        (Vec3::new(-0.33, 1.27, -1.0), 0),
        (Vec3::new(0.33, 1.27, -1.0), 1),
        (Vec3::new(-0.33, 1.93, -1.0), 2),
    ];
    for encoding in [AttributeEncoding::Float, AttributeEncoding::Quantized] {
        let scene = load_gltf(&file_vertex_colours(encoding)).unwrap();
        for route in routes(&scene, dark()) {
            for &(p, channel) in &corners {
                let c = route.at(&cave, p);
                // Near each corner its own colour dominates (interpolation leaves at least
                // 80 % of it there).
                let others = (0..3)
                    .filter(|&k| k != channel)
                    .map(|k| c[k])
                    .max()
                    .unwrap();
                assert!(
                    c[channel] > 200 && others < c[channel] / 2 + 40,
                    "{encoding:?} {}: near corner of channel {channel}: {c:?}",
                    route.name
                );
            }
        }
    }
}

#[test]
fn a_texture_transform_moves_the_texture_where_the_extension_says() {
    let scene = load_gltf(&file_texture_transform()).unwrap();
    let cave = cave();
    for route in routes(&scene, dark()) {
        // Offset u by one half: the left half shows the texture's right (blue) half.
        let left = route.at(&cave, Vec3::new(-0.2, 1.6, -1.0));
        let right = route.at(&cave, Vec3::new(0.2, 1.6, -1.0));
        assert!(close(left, [0, 0, 255], 2), "{}: {left:?}", route.name);
        assert!(close(right, [255, 0, 0], 2), "{}: {right:?}", route.name);
    }
}

#[test]
fn quantized_sparse_meshopt_and_draco_attributes_land_where_their_float_twins_do() {
    let float = load_gltf(&file_sphere(AttributeEncoding::Float)).unwrap();
    let float_image = routes(&float, Lighting::default()).remove(0).image;
    for encoding in [
        AttributeEncoding::Quantized,
        AttributeEncoding::Sparse,
        AttributeEncoding::Meshopt,
        AttributeEncoding::Draco,
    ] {
        let scene = load_gltf(&file_sphere(encoding)).unwrap();
        if encoding == AttributeEncoding::Draco {
            // Draco renumbers (and may merge) points: the same shape, 14-bit positions (a
            // 0.7 m sphere: 43 µm steps).
            let (lo, hi) = scene.bounds().unwrap();
            let (flo, fhi) = float.bounds().unwrap();
            assert!((lo - flo).abs().max_element() < 1e-4 && (hi - fhi).abs().max_element() < 1e-4);
            assert_eq!(scene.triangle_count(), float.triangle_count());
        } else {
            assert_eq!(scene.vertices.len(), float.vertices.len());
        }
        let step = quantization_step(&uv_sphere(0.35, 24, 48));
        for (a, b) in scene
            .vertices
            .iter()
            .zip(&float.vertices)
            .filter(|_| encoding != AttributeEncoding::Draco)
        {
            let d = (Vec3::from(a.position) - Vec3::from(b.position)).length();
            // Exact for sparse and meshopt; half a step per axis for 16-bit positions.
            let allowed = if encoding == AttributeEncoding::Quantized {
                step
            } else {
                0.0
            };
            assert!(
                d <= allowed,
                "{encoding:?}: {:?} vs {:?}",
                a.position,
                b.position
            );
        }
        let image = routes(&scene, Lighting::default()).remove(0).image;
        let differing = image
            .pixels()
            .zip(float_image.pixels())
            .filter(|(a, b)| a.0.iter().zip(b.0).any(|(x, y)| x.abs_diff(y) > 8))
            .count();
        match encoding {
            // 8-bit (Draco: 10-bit) normals shade within a few levels; an edge pixel may flip.
            AttributeEncoding::Quantized | AttributeEncoding::Draco => {
                assert!(differing <= 40, "{differing}")
            }
            _ => assert_eq!(differing, 0, "{encoding:?}"),
        }
    }
}

#[test]
fn a_normal_map_bends_the_shading_as_the_cpu_twin_says() {
    let scene = load_gltf(&file_normal_map()).unwrap();
    let mut lighting = dark();
    // Light arriving from the right and the front: the map tilts the normal towards it.
    lighting.sun_direction = Vec3::new(-1.0, 0.0, -0.6).normalize();
    lighting.sun_color = Vec3::ONE;
    let bent = Vec3::new(0.5, 0.0, 1.0).normalize();
    let expected = |p: Vec3, normal: Vec3| twin(&lighting, p, normal, Vec3::splat(0.8));
    let cave = cave();
    let file_tangents = Vec3::new(-0.45, 1.6, -1.0);
    let generated = Vec3::new(0.45, 1.6, -1.0);
    let flat = Vec3::new(0.0, 2.35, -1.3);
    for route in routes(&scene, lighting) {
        let a = route.at(&cave, file_tangents);
        let b = route.at(&cave, generated);
        let f = route.at(&cave, flat);
        let want_bent = expected(file_tangents, bent);
        let want_flat = expected(flat, Vec3::Z);
        // 4 levels: the map's 8-bit texel, and the pixel's point is not exactly the one the
        // twin shades (a matte surface: the shade varies by less than a level across it).
        assert!(
            close(a, want_bent, 4),
            "{}: {a:?} vs {want_bent:?}",
            route.name
        );
        assert!(
            close(b, want_bent, 4),
            "{}: {b:?} vs {want_bent:?}",
            route.name
        );
        assert!(
            close(f, want_flat, 4),
            "{}: {f:?} vs {want_flat:?}",
            route.name
        );
        // And the map matters: the bent normal faces the light more.
        assert!(a[0] > f[0] + 20, "{}: {a:?} vs flat {f:?}", route.name);
    }
}

#[test]
fn an_emissive_map_glows_only_where_it_is_bright() {
    let scene = load_gltf(&file_emissive_map()).unwrap();
    let cave = cave();
    for route in routes(&scene, dark()) {
        let bright = route.at(&cave, Vec3::new(-0.2, 1.6, -1.0));
        let dark_half = route.at(&cave, Vec3::new(0.2, 1.6, -1.0));
        assert!(
            close(bright, [255, 255, 255], 2),
            "{}: {bright:?}",
            route.name
        );
        assert!(
            close(dark_half, [0, 0, 0], 2),
            "{}: {dark_half:?}",
            route.name
        );
    }
}

#[test]
fn blended_quads_compose_back_to_front_in_every_eye() {
    let scene = load_gltf(&file_blend()).unwrap();
    let cave = cave();
    let front = cave.wall_index("front").unwrap();
    // Over the black background: blue at alpha ½, then red at ½ over it (linear light).
    let want = srgb(Vec3::new(0.5, 0.0, 0.25));
    // Front to back instead: red at ½, then blue at ½ over it.
    let wrong = srgb(Vec3::new(0.25, 0.0, 0.5));
    // A point where the near square hides part of the far one, as each eye sees it.
    let overlap = Vec3::new(0.05, 1.6, -1.0);
    let mut renderer = Renderer::new(gpu(), &cave, NO_MSAA).expect("renderer");
    renderer.set_scene(&scene).expect("scene upload");
    for (mode, tess) in [
        (RenderMode::Stereo, TessSettings::default()),
        (
            RenderMode::OmniOnAxis,
            TessSettings {
                criterion: Some(Criterion::Error(0.5)),
                ..TessSettings::default()
            },
        ),
    ] {
        let frame = test_frame(&cave, Head::at(HEAD), mode, OmniSettings::default(), tess);
        renderer.render(&frame).expect("render");
        let images = renderer.read_images().expect("read back");
        for (eye, image) in [
            ("left", &images[front].left),
            ("right", &images[front].right),
        ] {
            let p = cave.walls[front].pixel_of_ray(HEAD, overlap).unwrap();
            let px = image.get_pixel(p.x as u32, p.y as u32);
            let got = [px[0], px[1], px[2]];
            assert!(
                close(got, want, 3),
                "{mode:?} {eye}: {got:?}, want {want:?} (front to back gives {wrong:?})"
            );
        }
    }
    let route = routes(&scene, dark()).pop().unwrap();
    let got = route.at(&cave, overlap);
    assert!(close(got, want, 3), "panorama: {got:?}, want {want:?}");
}

#[test]
fn a_spot_light_from_the_file_lights_its_cone_only() {
    let scene = load_gltf(&file_spot_light()).unwrap();
    assert_eq!(scene.lights.len(), 1);
    let light = &scene.lights[0];
    assert!(
        (light.direction - Vec3::NEG_Y).length() < 1e-5,
        "{:?}",
        light.direction
    );
    let cave = cave();
    for route in routes(&scene, dark()) {
        let under = route.at(&cave, Vec3::new(0.0, 0.8, -1.3));
        // 0.9 m aside: 24° off the axis, outside the 20° cone.
        let aside = route.at(&cave, Vec3::new(0.9, 0.8, -1.3));
        assert!(under[0] > 100, "{}: {under:?}", route.name);
        assert!(aside[0] <= 2, "{}: {aside:?}", route.name);
    }
}

#[test]
fn every_light_up_to_the_limit_lights_its_spot_and_the_one_past_it_none() {
    // One more light than a frame holds: the shader sums the lights by constant index (see
    // shade_pbr in shaders/pbr.wgsl), so each index must be seen to light its own spot.
    let count = MAX_LIGHTS + 1;
    let scene = load_gltf(&file_spot_row(count)).unwrap();
    assert_eq!(scene.lights.len(), count);
    let cave = cave();
    for (shading, route) in [Shading::Pbr, Shading::Simple]
        .into_iter()
        .flat_map(|shading| {
            routes_shaded(&scene, dark(), shading)
                .into_iter()
                .map(move |route| (shading, route))
        })
    {
        let name = format!("{} ({shading:?})", route.name);
        let spots: Vec<[u8; 3]> = (0..count)
            .map(|k| route.at(&cave, Vec3::new(spot_row_x(k), 0.8, -1.3)))
            .collect();
        // Halfway between two spots: 8.75 cm from each axis, outside both 2° cones (7 cm).
        let between: Vec<[u8; 3]> = (0..count - 1)
            .map(|k| route.at(&cave, Vec3::new(spot_row_x(k) + 0.0875, 0.8, -1.3)))
            .collect();
        for (k, got) in spots.iter().enumerate() {
            if k < MAX_LIGHTS {
                // Lit as brightly as the single spot of the test above (> 100 of 255).
                assert!(got[0] > 100, "{}: light {k}'s spot {got:?}", name);
            } else {
                // Left out: black (2 levels for filtering at the image's edge).
                assert!(got[0] <= 2, "{}: light {k} past the limit {got:?}", name);
            }
        }
        for (k, got) in between.iter().enumerate() {
            assert!(got[0] <= 2, "{}: between {k} and {}: {got:?}", name, k + 1);
        }
    }
}

#[test]
fn unknown_required_extensions_and_broken_draco_are_refused_by_name() {
    let dir = out_dir();
    // A Draco primitive whose bitstream is not Draco (its magic overwritten): the error
    // names the extension.
    let mut bytes = std::fs::read(file_sphere(AttributeEncoding::Draco)).unwrap();
    let magic = bytes
        .windows(5)
        .position(|w| w == b"DRACO")
        .expect("a Draco bitstream in the file");
    bytes[magic..magic + 5].copy_from_slice(b"XXXXX");
    let broken = dir.join("broken-draco.glb");
    std::fs::write(&broken, bytes).unwrap();
    let err = load_gltf(&broken).unwrap_err().to_string();
    assert!(
        err.contains("KHR_draco_mesh_compression") || err.contains("Draco"),
        "{err}"
    );
    // A required extension omnicave does not read: refused by its name and the file's.
    let json = r#"{"asset":{"version":"2.0"},"extensionsUsed":["EXT_made_up"],
        "extensionsRequired":["EXT_made_up"],"scenes":[{"nodes":[]}]}"#;
    let path = dir.join("EXT_made_up.gltf");
    std::fs::write(&path, json).unwrap();
    let err = load_gltf(&path).unwrap_err().to_string();
    assert!(
        err.contains("EXT_made_up") && err.contains(&*path.to_string_lossy()),
        "{err}"
    );
}

#[test]
fn every_generated_file_passes_the_khronos_validator() {
    // Not the file with a texture its primitive has no coordinates for: invalid on purpose.
    let files = [
        file_without_uvs(true),
        file_vertex_colours(AttributeEncoding::Float),
        file_vertex_colours(AttributeEncoding::Quantized),
        file_texture_transform(),
        file_sphere(AttributeEncoding::Float),
        file_sphere(AttributeEncoding::Quantized),
        file_sphere(AttributeEncoding::Sparse),
        file_sphere(AttributeEncoding::Meshopt),
        file_sphere(AttributeEncoding::Draco),
        file_normal_map(),
        file_emissive_map(),
        file_blend(),
        file_spot_light(),
        file_spot_row(MAX_LIGHTS + 1),
    ];
    let tool = Path::new(env!("CARGO_MANIFEST_DIR")).join("tools/gltf-validator");
    if !tool.join("node_modules/gltf-validator").is_dir() {
        let msg = "SKIPPED: the Khronos validator is not installed (scripts/test.sh installs it: \
                   cd tools/gltf-validator && npm install)";
        assert!(
            std::env::var_os("CI").is_none(),
            "{msg}, and CI must not skip"
        );
        println!("{msg}");
        return;
    }
    let out = std::process::Command::new("node")
        .arg("validate.mjs")
        .args(&files)
        .current_dir(&tool)
        .output()
        .expect("node runs");
    let report = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{report}{}",
        String::from_utf8_lossy(&out.stderr)
    );
}

#[test]
fn only_the_images_materials_use_are_decoded() {
    // A file carrying a broken image no material uses loads (it is never decoded); the same
    // image used as a base colour texture is refused, naming it.
    let build = |use_it: bool| {
        let mut w = GlbWriter::new();
        let broken = w.add_png_texture("broken", b"\x89PNG\r\n\x1a\n not really a PNG");
        let mat = w.add_material(&MaterialDesc {
            texture: use_it.then_some(broken),
            ..MaterialDesc::plain("plain", [0.5; 3], 1.0)
        });
        let m = w.add_mesh("square", &[(&square(0.0, -1.0), mat)]);
        let n = w.add_node(NodeDesc::new("square").with_mesh(m));
        write(
            if use_it {
                "used-broken-image"
            } else {
                "unused-broken-image"
            },
            &w,
            &[n],
        )
    };
    let scene = load_gltf(&build(false)).unwrap();
    assert!(scene.textures.is_empty());
    let err = load_gltf(&build(true)).unwrap_err().to_string();
    assert!(err.contains("image 0"), "{err}");
}

#[test]
fn a_well_formed_triangle_loads_with_generated_normals() {
    let scene = load_gltf(&write_triangle_gltf(&out_dir(), "good", |_, _| {})).unwrap();
    assert_eq!(scene.triangle_count(), 1);
    // No NORMAL attribute: generated from the winding (counter-clockwise seen from +z).
    for v in &scene.vertices {
        assert!((v.normal[2] - 1.0).abs() < 1e-6, "{:?}", v.normal);
    }
}

/// `extras` may be any JSON value (an array, a string, a number, null, a boolean) on every
/// object that has it.
#[test]
fn gltf_extras_of_any_json_type_load() {
    for extras in [
        json!([1, 2, 3]),
        json!("text"),
        json!(4.5),
        json!(null),
        json!(true),
    ] {
        let mut w = GlbWriter::new();
        let material = w.add_material(&MaterialDesc::plain("m", [1.0; 3], 1.0));
        let quad = grid(Vec3::ZERO, Vec3::X, Vec3::Y, 1, 1, 1.0);
        let mesh = w.add_mesh("q", &[(&quad, material)]);
        let node = w.add_node(NodeDesc::new("n").with_mesh(mesh));
        let mut doc = w.json(&[node]);
        for key in [
            "asset",
            "nodes",
            "meshes",
            "materials",
            "scenes",
            "accessors",
        ] {
            match &mut doc[key] {
                serde_json::Value::Array(items) => {
                    for item in items {
                        item["extras"] = extras.clone();
                    }
                }
                other => other["extras"] = extras.clone(),
            }
        }
        doc["extras"] = extras.clone();
        let out = with_json(&w.to_glb(&[node]), &doc);
        let path = out_dir().join("extras.glb");
        std::fs::write(&path, &out).unwrap();
        let scene = load_gltf(&path).unwrap_or_else(|e| panic!("extras {extras}: {e}"));
        assert_eq!(scene.triangle_count(), 2);
    }
}
