//! Every input has a budget, stated and enforced: a scene of 8.4 million vertices renders
//! within the device's limits and a node-graph bomb is refused before it expands; outputs past
//! the device's texture limit, textures past their memory and size budgets, device files,
//! FIFOs and oversized files, too many walls or too much render-target memory, over-long
//! arrays, and counts a file declares below what it holds are refused with a message naming
//! the file, field or budget; images larger than one staging buffer read back whole; and a
//! scene larger than the device's largest buffer is split and drawn the same.
#![allow(clippy::unwrap_used, clippy::expect_used)]

mod common;

use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::{Duration, Instant};

use common::gltf_files::with_json;
use common::{repo, run_omnicave as omnicave};
use glam::Vec3;
use omnicave::config::Config;
use omnicave::scene::build::grid;
use omnicave::scene::glb_writer::{GlbWriter, MaterialDesc, NodeDesc};
use omnicave::scene::{SceneBudget, load_gltf, load_gltf_within};
use serde_json::json;

fn out_dir() -> PathBuf {
    common::tmp_dir("budgets")
}

// ------------------------------------------------------------------ scene size

/// A 28×28-cell ground grid (841 vertices) drawn by `instances` nodes side by side.
fn instanced_grid(name: &str, instances: usize) -> (PathBuf, usize) {
    let mut w = GlbWriter::new();
    let material = w.add_material(&MaterialDesc::plain("ground", [0.2, 0.6, 0.3], 0.8));
    let cell = grid(Vec3::new(-0.5, 0.0, 0.5), Vec3::X, Vec3::NEG_Z, 28, 28, 1.0);
    let vertices = cell.vertices.len();
    let mesh = w.add_mesh("cell", &[(&cell, material)]);
    let side = (instances as f32).sqrt().ceil() as usize;
    let nodes: Vec<usize> = (0..instances)
        .map(|i| {
            let (x, z) = ((i % side) as f32, (i / side) as f32);
            w.add_node(
                NodeDesc::new(&format!("cell {i}"))
                    .with_mesh(mesh)
                    .at(Vec3::new(x - side as f32 / 2.0, 0.0, -z - 0.5)),
            )
        })
        .collect();
    let root = w.add_node(NodeDesc::new("ground").with_children(nodes));
    let path = out_dir().join(format!("{name}.glb"));
    std::fs::write(&path, w.to_glb(&[root])).unwrap();
    (path, vertices * instances)
}

/// Green pixels in the row 4 px above the bottom of `out/front-left.png` (the ground), and the
/// image's width.
fn green_near_the_bottom(out: &std::path::Path) -> (usize, usize) {
    let front = image::open(out.join("front-left.png")).unwrap().to_rgb8();
    let (w, h) = front.dimensions();
    let green = (0..w)
        .filter(|&x| {
            let p = front.get_pixel(x, h - 4).0;
            p[1] > p[0] + 20 && p[1] > p[2] + 20
        })
        .count();
    (green, w as usize)
}

/// A valid scene past 8 388 608 vertices, whose vertex buffer is past wgpu's default 256 MiB
/// buffer limit, renders: the device's own limit is asked for (lavapipe: 2 GiB) and every size
/// is checked against it. This scene, 10 000 instances of a grid, has 8.41 M vertices (606 MB
/// of vertex data). The tessellator binds the vertices in up to four windows of the device's
/// largest storage binding: where four hold less (lavapipe: 4 × 128 MiB), that mode is
/// refused naming the limit; where they hold it (a discrete GPU), it renders the ground too.
#[test]
fn a_scene_of_8_4_million_instanced_vertices_renders() {
    let (path, vertices) = instanced_grid("ground-10000", 10_000);
    assert!(vertices > 8_388_608, "{vertices}");
    let out = out_dir().join("large-scene");
    let _ = std::fs::remove_dir_all(&out);
    let scene = path.to_str().unwrap();
    let config = repo("config/desktop.toml");
    let (code, _, stderr) = omnicave(&[
        "render",
        "--config",
        config.to_str().unwrap(),
        "--scene",
        scene,
        "--mode",
        "stereo",
        "--size",
        "96x64",
        "--skybox",
        "none",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert_eq!(code, 0, "{stderr}");
    // The ground fills the lower half of the front wall's view: green, not background.
    let (green, w) = green_near_the_bottom(&out);
    assert!(green > w / 2, "ground not drawn: {green} of {w}");

    // Tessellated omnistereo binds the whole vertex buffer, in up to four windows.
    let (code, _, stderr) = omnicave(&[
        "render",
        "--config",
        config.to_str().unwrap(),
        "--scene",
        scene,
        "--mode",
        "omni-offaxis",
        "--tess",
        "error:1",
        "--size",
        "96x64",
        "--skybox",
        "none",
        "--out",
        out.to_str().unwrap(),
    ]);
    match code {
        // Past the device's storage binding: refused, naming the limit with its figures.
        1 => assert!(
            stderr.contains("max_storage_buffer_binding_size") && stderr.contains("vertices take"),
            "{stderr}"
        ),
        // A device that binds it: all 15.7 M triangles through the tessellator's grid.
        0 => {
            let (green, w) = green_near_the_bottom(&out);
            assert!(green > w / 2, "tessellated ground: {green} of {w}");
        }
        _ => panic!("exit {code}: {stderr}"),
    }
}

/// A 2 KB node graph whose nodes each list the next one twice as a child would expand to
/// 2^40 instances: the expansion is counted before anything is built and stops at the
/// instance budget, naming the node.
#[test]
fn a_node_graph_bomb_is_refused_before_it_expands() {
    let mut w = GlbWriter::new();
    let material = w.add_material(&MaterialDesc::plain("m", [1.0; 3], 1.0));
    let cell = grid(Vec3::ZERO, Vec3::X, Vec3::NEG_Z, 1, 1, 1.0);
    let mesh = w.add_mesh("quad", &[(&cell, material)]);
    let mut child = w.add_node(NodeDesc::new("leaf").with_mesh(mesh));
    for level in 0..40 {
        child =
            w.add_node(NodeDesc::new(&format!("level {level}")).with_children(vec![child, child]));
    }
    let path = out_dir().join("node-bomb.glb");
    std::fs::write(&path, w.to_glb(&[child])).unwrap();
    assert!(std::fs::metadata(&path).unwrap().len() < 4096);
    let started = Instant::now();
    let err = load_gltf(&path).unwrap_err().to_string();
    // Counting stops at the 1 048 577th instance: well under a second even unoptimised.
    assert!(
        started.elapsed() < Duration::from_secs(20),
        "{:?}",
        started.elapsed()
    );
    assert!(
        err.contains("node-bomb.glb") && err.contains("budgets.max_instances = 1048576"),
        "{err}"
    );
    // The vertex budget speaks for a graph of fewer, larger instances.
    let small = SceneBudget {
        max_vertices: 1000,
        ..SceneBudget::default()
    };
    let err = load_gltf_within(&path, &small).unwrap_err().to_string();
    assert!(
        err.contains("budgets.max_vertices = 1000") && err.contains("mesh 0 (quad)"),
        "{err}"
    );
}

// ------------------------------------------------------------------ output size

/// Frame packing an 8192-high wall makes a 16 725-high image, past the device's 16 384 limit:
/// it is refused naming the limit (the eye images are written).
#[test]
fn outputs_past_the_device_limit_are_refused_naming_it() {
    let out = out_dir().join("frame-packing");
    let config = repo("config/desktop.toml");
    let (code, _, stderr) = omnicave(&[
        "render",
        "--config",
        config.to_str().unwrap(),
        "--scene",
        "none",
        "--skybox",
        "none",
        "--size",
        "16x8192",
        "--format",
        "frame-packing",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert_eq!(code, 1, "{stderr}");
    assert!(
        stderr.contains("frame-packing output would be 16×16725")
            && stderr.contains("max_texture_dimension_2d"),
        "{stderr}"
    );
}

// ------------------------------------------------------------------ memory and files

fn solid_png(side: u32, rgb: [u8; 3]) -> Vec<u8> {
    let img = image::RgbaImage::from_pixel(side, side, image::Rgba([rgb[0], rgb[1], rgb[2], 255]));
    let mut out = Vec::new();
    img.write_to(&mut std::io::Cursor::new(&mut out), image::ImageFormat::Png)
        .unwrap();
    out
}

/// Six textured quads, each with its own `side`² PNG.
fn textured_file(name: &str, side: u32) -> PathBuf {
    let mut w = GlbWriter::new();
    let mut nodes = Vec::new();
    for i in 0..6u8 {
        let texture = w.add_png_texture(&format!("t{i}"), &solid_png(side, [40 * i, 200, 90]));
        let material = w.add_material(&MaterialDesc {
            texture: Some(texture),
            ..MaterialDesc::plain(&format!("m{i}"), [1.0; 3], 1.0)
        });
        let quad = grid(
            Vec3::new(f32::from(i) - 3.0, 1.0, -2.0),
            Vec3::X * 0.9,
            Vec3::Y * 0.9,
            1,
            1,
            1.0,
        );
        let mesh = w.add_mesh(&format!("q{i}"), &[(&quad, material)]);
        nodes.push(w.add_node(NodeDesc::new(&format!("n{i}")).with_mesh(mesh)));
    }
    let path = out_dir().join(format!("{name}.glb"));
    std::fs::write(&path, w.to_glb(&nodes)).unwrap();
    path
}

/// Textures count against `budgets.max_texture_memory_mb` from their headers, before their
/// pixels are decoded (six 8192² PNGs fit in a 1.6 MB file and would take 5.8 GB), and images
/// past `budgets.max_texture_side` are downscaled. Shown here at 2048² with the budgets scaled
/// down alike (the default 1.5 GiB refuses the fifth 8192² image the same way).
#[test]
fn texture_memory_and_size_budgets_hold() {
    let path = textured_file("six-textures", 2048);
    // 2048² with mips is 21.3 MiB: a 64 MiB budget holds three.
    let tight = SceneBudget {
        max_texture_bytes: 64 << 20,
        ..SceneBudget::default()
    };
    let err = load_gltf_within(&path, &tight).unwrap_err().to_string();
    assert!(
        err.contains("image 3 (2048×2048")
            && err.contains("over budgets.max_texture_memory_mb = 64"),
        "{err}"
    );
    // Downscaled to 256² they all fit, with their colours.
    let small = SceneBudget {
        max_texture_bytes: 64 << 20,
        max_texture_side: 256,
        ..SceneBudget::default()
    };
    let scene = load_gltf_within(&path, &small).unwrap();
    assert_eq!(scene.textures.len(), 6);
    for (i, t) in scene.textures.iter().enumerate() {
        assert_eq!((t.width, t.height), (256, 256));
        assert_eq!(&t.rgba8[..4], &[40 * i as u8, 200, 90, 255]);
    }
    // An image whose header claims 60 000² (14 GB decoded) is refused from its header.
    let mut w = GlbWriter::new();
    let mut header = solid_png(1, [0, 0, 0]);
    header[16..20].copy_from_slice(&60_000u32.to_be_bytes());
    header[20..24].copy_from_slice(&60_000u32.to_be_bytes());
    let texture = w.add_png_texture("liar", &header);
    let material = w.add_material(&MaterialDesc {
        texture: Some(texture),
        ..MaterialDesc::plain("m", [1.0; 3], 1.0)
    });
    let quad = grid(Vec3::ZERO, Vec3::X, Vec3::Y, 1, 1, 1.0);
    let mesh = w.add_mesh("q", &[(&quad, material)]);
    let node = w.add_node(NodeDesc::new("n").with_mesh(mesh));
    let liar = out_dir().join("huge-header.glb");
    std::fs::write(&liar, w.to_glb(&[node])).unwrap();
    let started = Instant::now();
    let err = load_gltf(&liar).unwrap_err().to_string();
    assert!(started.elapsed() < Duration::from_secs(10));
    // (The PNG decoder may refuse the forged header's checksum first: either way, no pixels.)
    assert!(
        err.contains("image 0")
            && (err.contains("budgets.max_texture_memory_mb") || err.contains("CRC")),
        "{err}"
    );
}

/// Only regular files are read as scenes and skies (a device such as `/dev/zero`, a FIFO or a
/// socket is refused before it is opened: opening a FIFO without a writer would block), and
/// each under `budgets.max_file_mb`.
#[test]
fn device_files_fifos_and_huge_files_are_not_read() {
    let config = repo("config/desktop.toml");
    let out = out_dir().join("dev-zero");
    let small = out_dir().join("small-files.toml");
    let text = std::fs::read_to_string(&config)
        .unwrap()
        .replace("\"../assets/", &format!("\"{}/", repo("assets").display()))
        + "\n[budgets]\nmax_file_mb = 4\n";
    std::fs::write(&small, text).unwrap();
    let fifo = out_dir().join("scene.fifo");
    let _ = std::fs::remove_file(&fifo);
    assert!(
        Command::new("mkfifo")
            .arg(&fifo)
            .status()
            .unwrap()
            .success()
    );
    // 5 MiB, sparse: over the 4 MiB cap without writing it.
    let huge = out_dir().join("huge.glb");
    std::fs::File::create(&huge)
        .unwrap()
        .set_len(5 << 20)
        .unwrap();
    let started = Instant::now();
    for (scene, expected) in [
        ("/dev/zero", "is not a regular file"),
        (fifo.to_str().unwrap(), "is not a regular file"),
        (
            huge.to_str().unwrap(),
            "5.0 MiB is over the limit of 4.0 MiB (budgets.max_file_mb)",
        ),
    ] {
        let (code, _, stderr) = omnicave(&[
            "render",
            "--config",
            small.to_str().unwrap(),
            "--scene",
            scene,
            "--out",
            out.to_str().unwrap(),
        ]);
        assert_eq!(code, 1, "{stderr}");
        assert!(
            stderr.contains(scene) && stderr.contains(expected),
            "{stderr}"
        );
    }
    // A broken sky is reported and the render goes on without it.
    for sky in ["/dev/zero", huge.to_str().unwrap()] {
        let (code, _, stderr) = omnicave(&[
            "render",
            "--config",
            small.to_str().unwrap(),
            "--skybox",
            sky,
            "--size",
            "32x24",
            "--out",
            out.to_str().unwrap(),
        ]);
        assert_eq!(code, 0, "{stderr}");
        assert!(
            stderr.contains(sky) && stderr.contains("rendering without a sky"),
            "{stderr}"
        );
    }
    assert!(started.elapsed() < Duration::from_secs(180));
}

/// A config with `walls` copies of a 1 m wall, named w0, w1, …
fn many_walls(walls: usize, extra: &str) -> String {
    let mut text = String::from(extra);
    for i in 0..walls {
        let x = i as f32 * 1.1;
        text.push_str(&format!(
            "[[wall]]\nname = \"w{i}\"\nlower_left = [{x}, 0.0, -2.0]\nlower_right = [{}, 0.0, \
             -2.0]\nupper_left = [{x}, 1.0, -2.0]\nresolution = [64, 64]\n",
            x + 1.0
        ));
    }
    text
}

/// Walls are budgeted (`budgets.max_walls`, 64) and checked in one pass, so that a config of
/// 262 144 walls is refused at once; the render targets of the largest legal walls (three
/// 8192² at MSAA 4, 13.5 GiB) count against `budgets.max_target_memory_mb`.
#[test]
fn wall_count_and_target_memory_are_budgeted() {
    let path = Path::new("walls.toml");
    let err = Config::from_toml(&many_walls(65, ""), path)
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("(65 walls)") && err.contains("budgets.max_walls = 64"),
        "{err}"
    );
    // A larger budget takes them all; a thousand walls validate in one pass.
    let config = Config::from_toml(&many_walls(1000, "[budgets]\nmax_walls = 1000\n"), path)
        .expect("1000 walls within their budget");
    assert_eq!(config.cave.walls.len(), 1000);
    let err = Config::from_toml(
        &many_walls(2, "[budgets]\nmax_walls = 1000\n").replace("name = \"w1\"", "name = \"w0\""),
        path,
    )
    .unwrap_err()
    .to_string();
    assert!(
        err.contains("wall[1].name") && err.contains("another wall"),
        "{err}"
    );

    // The largest legal config: three 8192² walls at MSAA 4.
    let big = many_walls(3, "[render]\nmsaa = 4\n").replace("[64, 64]", "[8192, 8192]");
    let err = Config::from_toml(&big, path).unwrap_err().to_string();
    assert!(
        err.contains("13.5 GiB of render targets")
            && err.contains("budgets.max_target_memory_mb = 4096"),
        "{err}"
    );
    // The config file itself is read under a cap (4 MiB): 262 144 walls are refused unread.
    let huge = out_dir().join("262144-walls.toml");
    std::fs::write(&huge, many_walls(262_144, "")).unwrap();
    let err = Config::load(&huge).unwrap_err().to_string();
    assert!(
        err.contains("262144-walls.toml") && err.contains("config files"),
        "{err}"
    );
}

// ------------------------------------------------------------------ strict input

/// Fixed-size arrays take exactly their number of elements, and wall corners are bounded (a
/// wall with 1e30 corners would overflow its squared lengths, and the NaN would pass the
/// perpendicularity test).
#[test]
fn fixed_size_arrays_and_wall_geometry_are_strict() {
    let cave = std::fs::read_to_string(repo("config/cave.toml")).unwrap();
    let path = Path::new("strict.toml");
    let err = |text: &str| Config::from_toml(text, path).unwrap_err().to_string();

    let text = cave.replacen(
        "resolution = [1280, 720]",
        "resolution = [64, 56, \"x\", true, 1.5]",
        1,
    );
    assert_ne!(text, cave);
    let e = err(&text);
    assert!(
        e.contains("wall[0].resolution") && e.contains("takes exactly 2 elements"),
        "{e}"
    );
    let e = err(&cave.replacen(
        "position = [0.0, 1.7, 0.0]",
        "position = [0.0, 1.7, 0.0, 9.0]",
        1,
    ));
    assert!(
        e.contains("head.position") && e.contains("(4 elements)"),
        "{e}"
    );

    let mut huge = cave.clone();
    for corner in ["lower_left", "lower_right", "upper_left"] {
        let start = huge.find(&format!("{corner} = [")).unwrap();
        let end = start + huge[start..].find(']').unwrap() + 1;
        huge.replace_range(start..end, &format!("{corner} = [1e30, 1e30, 1e30]"));
    }
    let e = err(&huge);
    assert!(
        e.contains("wall[0].lower_left") && e.contains("between -100000 and 100000"),
        "{e}"
    );
    // Within the range, a skew is still found (worked in f64).
    let skew = cave.replacen(
        "upper_left = [-1.65, 2.9, -1.65]",
        "upper_left = [-1.6, 2.9, -1.65]",
        1,
    );
    assert_ne!(skew, cave);
    assert!(err(&skew).contains("not perpendicular"));
}

/// The budget counts what the accessors declare; a Draco bitstream that decodes to more is
/// refused, a file with more materials than the renderer takes is refused, and the files a
/// `.gltf` names are held to the file budget together.
#[test]
fn declared_counts_materials_and_named_files_are_held_to_the_budget() {
    use omnicave::scene::glb_writer::{AttributeEncoding, MeshOptions};
    let mut w = GlbWriter::new();
    let material = w.add_material(&MaterialDesc::plain("m", [1.0; 3], 1.0));
    let sheet = grid(Vec3::ZERO, Vec3::X, Vec3::Y, 10, 10, 1.0);
    let options = MeshOptions {
        encoding: AttributeEncoding::Draco,
        ..MeshOptions::default()
    };
    let mesh = w.add_mesh_with("sheet", &[(&sheet, material)], &options);
    let node = w.add_node(NodeDesc::new("n").with_mesh(mesh));
    let mut doc = w.json(&[node]);
    let position = doc["meshes"][0]["primitives"][0]["attributes"]["POSITION"]
        .as_u64()
        .unwrap() as usize;
    doc["accessors"][position]["count"] = json!(3);
    let path = out_dir().join("draco-understated.glb");
    std::fs::write(&path, with_json(&w.to_glb(&[node]), &doc)).unwrap();
    let err = load_gltf(&path).unwrap_err().to_string();
    assert!(
        err.contains("decodes to 121 vertices") && err.contains("declare (3 and"),
        "{err}"
    );

    let mut doc = w.json(&[node]);
    doc["materials"] = json!(vec![json!({}); 65_537]);
    let path = out_dir().join("many-materials.glb");
    std::fs::write(&path, with_json(&w.to_glb(&[node]), &doc)).unwrap();
    let err = load_gltf(&path).unwrap_err().to_string();
    assert!(
        err.contains("65537 materials") && err.contains("at most 65536"),
        "{err}"
    );

    // Three buffers naming one 2 MiB file, under a 5 MiB budget: the third passes it.
    let dir = out_dir().join("shared-buffer");
    std::fs::create_dir_all(&dir).unwrap();
    std::fs::write(dir.join("big.bin"), vec![0u8; 2 << 20]).unwrap();
    let gltf = json!({
        "asset": {"version": "2.0"},
        "scene": 0,
        "scenes": [{"nodes": [0]}],
        "nodes": [{"mesh": 0}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0}}]}],
        "buffers": [
            {"uri": "big.bin", "byteLength": 2 << 20},
            {"uri": "big.bin", "byteLength": 2 << 20},
            {"uri": "big.bin", "byteLength": 2 << 20}
        ],
        "bufferViews": [{"buffer": 0, "byteLength": 36}],
        "accessors": [{"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3",
                       "min": [0, 0, 0], "max": [0, 0, 0]}]
    });
    let path = dir.join("shared.gltf");
    std::fs::write(&path, gltf.to_string()).unwrap();
    let budget = SceneBudget {
        max_file_bytes: 5 << 20,
        ..SceneBudget::default()
    };
    let err = load_gltf_within(&path, &budget).unwrap_err().to_string();
    assert!(
        err.contains("buffer 2") && err.contains("for the scene's files together"),
        "{err}"
    );
}

/// The side-by-side and panorama outputs at 8192 px are larger than one staging buffer may be
/// (256 MiB): read-back goes in bands of at most 64 MiB, and a 4100² image (67 MB) comes back
/// in two bands, every pixel where it belongs.
#[test]
fn images_larger_than_one_staging_buffer_read_back_whole() {
    let gpu = common::gpu();
    let side = 4100u32;
    let texture = gpu.device.create_texture(&wgpu::TextureDescriptor {
        label: Some("budgets::large"),
        size: wgpu::Extent3d {
            width: side,
            height: side,
            depth_or_array_layers: 1,
        },
        mip_level_count: 1,
        sample_count: 1,
        dimension: wgpu::TextureDimension::D2,
        format: wgpu::TextureFormat::Rgba8Unorm,
        usage: wgpu::TextureUsages::COPY_DST | wgpu::TextureUsages::COPY_SRC,
        view_formats: &[],
    });
    let pixel = |x: u32, y: u32| [x as u8, y as u8, ((x >> 8) ^ (y >> 8)) as u8, 255];
    let mut data = Vec::with_capacity((side * side * 4) as usize);
    for y in 0..side {
        for x in 0..side {
            data.extend_from_slice(&pixel(x, y));
        }
    }
    gpu.queue.write_texture(
        texture.as_image_copy(),
        &data,
        wgpu::TexelCopyBufferLayout {
            offset: 0,
            bytes_per_row: Some(side * 4),
            rows_per_image: Some(side),
        },
        texture.size(),
    );
    let small = gpu.device.create_texture(&wgpu::TextureDescriptor {
        label: Some("budgets::small"),
        size: wgpu::Extent3d {
            width: 3,
            height: 2,
            depth_or_array_layers: 1,
        },
        ..texture_descriptor_like(&texture)
    });
    gpu.queue.write_texture(
        small.as_image_copy(),
        &[9u8; 24],
        wgpu::TexelCopyBufferLayout {
            offset: 0,
            bytes_per_row: Some(12),
            rows_per_image: Some(2),
        },
        small.size(),
    );
    let images = omnicave::render::targets::read_textures(
        &gpu.device,
        &gpu.queue,
        &[&small, &texture, &small],
    )
    .unwrap();
    assert_eq!(images.len(), 3);
    assert!(images[0].pixels().all(|p| p.0 == [9; 4]));
    assert!(images[2].pixels().all(|p| p.0 == [9; 4]));
    let big = &images[1];
    assert_eq!(big.dimensions(), (side, side));
    assert_eq!(big.as_raw(), &data, "pixels out of place");
}

fn texture_descriptor_like(t: &wgpu::Texture) -> wgpu::TextureDescriptor<'static> {
    wgpu::TextureDescriptor {
        label: None,
        size: t.size(),
        mip_level_count: 1,
        sample_count: 1,
        dimension: t.dimension(),
        format: t.format(),
        usage: t.usage(),
        view_formats: &[],
    }
}

/// A scene larger than the device's largest buffer is split over several buffers by draws
/// (cut at triangles where one draw is larger) and drawn the same. Shown on the living room
/// with the limit lowered to 256 KiB (lavapipe's own limit, 2 GiB, is past any budgeted
/// scene): the stereo walls are pixel-identical to the unsplit upload, with the shadows drawn
/// from the split buffers too; the tessellated modes, which bind the scene whole, refuse it
/// naming the split.
#[test]
fn a_scene_past_one_buffer_is_split_and_drawn_the_same() {
    use omnicave::cave::omni::OmniSettings;
    use omnicave::cave::{Head, RenderMode};
    use omnicave::render::Renderer;
    use omnicave::tess::{Criterion, TessSettings};
    let cave = common::cave_at(96, 64);
    let scene = load_gltf(&repo("assets/living-room.glb")).unwrap();
    let head = Head::at(Vec3::new(0.2, 1.6, -0.3));
    let frame = common::test_frame(
        &cave,
        head,
        RenderMode::Stereo,
        OmniSettings::default(),
        TessSettings::default(),
    );
    let render = |limit: Option<u64>| {
        let mut renderer = Renderer::new(common::gpu(), &cave, common::NO_MSAA).unwrap();
        renderer.limit_scene_buffers(limit);
        renderer.set_scene(&scene).expect("scene upload");
        renderer.render(&frame).expect("render");
        (renderer.scene_chunks(), renderer.read_images().unwrap())
    };
    let (one, whole) = render(None);
    let (chunks, split) = render(Some(256 << 10));
    assert_eq!(one, 1);
    assert!(chunks >= 3, "{chunks} chunks");
    for (a, b) in whole.iter().zip(&split) {
        assert_eq!(a.left.as_raw(), b.left.as_raw(), "wall {}", a.wall);
        assert_eq!(a.right.as_raw(), b.right.as_raw(), "wall {}", a.wall);
    }
    let mut renderer = Renderer::new(common::gpu(), &cave, common::NO_MSAA).unwrap();
    renderer.limit_scene_buffers(Some(256 << 10));
    renderer.set_scene(&scene).expect("scene upload");
    let tessellated = common::test_frame(
        &cave,
        head,
        RenderMode::OmniOffAxis,
        OmniSettings::default(),
        TessSettings {
            criterion: Some(Criterion::Error(1.0)),
            ..TessSettings::default()
        },
    );
    let err = renderer.render(&tessellated).unwrap_err().to_string();
    assert!(
        err.contains(&format!("split over {chunks} buffers")),
        "{err}"
    );
    // One material (the living room merged into a single draw) is cut at triangles.
    let mut merged = scene.clone();
    for d in &mut merged.draws {
        d.material = 0;
    }
    let mut renderer = Renderer::new(common::gpu(), &cave, common::NO_MSAA).unwrap();
    renderer.limit_scene_buffers(Some(256 << 10));
    renderer.set_scene(&merged).expect("one material, split");
    assert!(renderer.scene_chunks() >= 3);
    renderer.render(&frame).expect("render");
    // A limit below one triangle: refused naming it.
    renderer.limit_scene_buffers(Some(100));
    let err = renderer.set_scene(&scene).unwrap_err().to_string();
    assert!(
        err.contains("vertices of one triangle") && err.contains("100 bytes"),
        "{err}"
    );
}

/// End to end: a side-by-side image of an 8192² wall is 16 384 × 8192, 512 MiB, past one
/// staging buffer: it is read back in bands, and each half holds its eye's view of the red
/// quad in the middle of the wall.
#[test]
fn a_side_by_side_image_of_an_8192_wall_reads_back() {
    use omnicave::cave::omni::OmniSettings;
    use omnicave::cave::{Head, RenderMode};
    use omnicave::output::formats::StereoFormat;
    use omnicave::render::Renderer;
    use omnicave::render::present::PresentParams;
    use omnicave::tess::TessSettings;
    let mut cave = common::cave_at(8192, 8192);
    cave.walls.retain(|w| w.name == "front"); // one wall: its targets alone are 1 GiB
    let mut scene = omnicave::scene::Scene::default();
    // A quad over the middle of the wall, seen by both eyes.
    let quad = grid(Vec3::new(-0.5, 1.2, -1.5), Vec3::X, Vec3::Y, 1, 1, 1.0);
    common::add_unlit(&mut scene, &quad, [200, 40, 40]);
    let mut renderer = Renderer::new(common::gpu(), &cave, common::NO_MSAA).unwrap();
    renderer.set_scene(&scene).expect("scene upload");
    let frame = common::test_frame(
        &cave,
        Head::at(Vec3::new(0.0, 1.7, 0.0)),
        RenderMode::Stereo,
        OmniSettings::default(),
        TessSettings::default(),
    );
    renderer.render(&frame).expect("render");
    let image = renderer
        .compose(
            0,
            PresentParams {
                format: StereoFormat::SideBySide { half: false },
                frame: 0,
                swap_eyes: false,
            },
        )
        .expect("compose and read back");
    assert_eq!(image.dimensions(), (16384, 8192));
    // The quad's colour at the middle of each half.
    for x in [4096, 4096 + 8192] {
        let p = image.get_pixel(x, 4096).0;
        // Red, as the quad (its exact level depends on the colour encoding, not tested here).
        assert!(p[0] > p[1] + 80 && p[0] > p[2] + 80, "half at {x}: {p:?}");
    }
}
