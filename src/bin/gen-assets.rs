//! Generates the bundled scenes (`assets/living-room.glb`, `assets/city.glb`,
//! `assets/atrium.glb`, the animated sample `assets/animated.glb`) and sky (`assets/sky.png`)
//! deterministically.
//!
//! `gen-assets [--out DIR]` writes them; `gen-assets --check [--out DIR]` fails if the files
//! there differ from what this generator makes (so committed assets always match the code).
//! `gen-assets --dense TRIANGLES [--out DIR]` writes only `dense.glb`, a generated hall of
//! that many triangles for measuring how rendering scales (not bundled: 8 M triangles are
//! about 210 MiB).

use std::path::PathBuf;

use anyhow::{Context, bail};
use glam::{Mat4, Vec3};
use image::{Rgba, RgbaImage};

use omnicave::scene::build::{MeshData, arch, cuboid, frustum_shell, grid, lathe, uv_sphere};
use omnicave::scene::glb_writer::{GlbWriter, MaterialDesc, MaterialMaps, MeshOptions, NodeDesc};
use omnicave::sky::bundled;
use omnicave::sky::cubemap::{equirect_direction, equirect_taps, linear_to_srgb, srgb_to_linear};

/// Generates the bundled scenes (living room, city, atrium, the animated sample) and sky,
/// deterministically.
#[derive(Debug, clap::Parser)]
#[command(name = "gen-assets", version)]
struct Args {
    /// Folder to write living-room.glb, city.glb, atrium.glb, animated.glb and sky.png into.
    #[arg(long, default_value = "assets")]
    out: PathBuf,
    /// Write nothing: fail if the files in --out differ from what the generator makes.
    #[arg(long, conflicts_with = "dense")]
    check: bool,
    /// Write only dense.glb: a hall of about this many triangles (dense grids and a dense
    /// sphere, see `scene::build::dense_hall`), up to 50 million.
    #[arg(long, value_parser = clap::value_parser!(u64).range(1..=50_000_000))]
    dense: Option<u64>,
}

fn main() -> anyhow::Result<()> {
    let Args { out, check, dense } = <Args as clap::Parser>::parse();
    if let Some(triangles) = dense {
        let path = out.join("dense.glb");
        let bytes = dense_hall(triangles);
        std::fs::create_dir_all(&out).with_context(|| format!("creating {}", out.display()))?;
        std::fs::write(&path, &bytes).with_context(|| format!("writing {}", path.display()))?;
        eprintln!("wrote {} ({} MiB)", path.display(), bytes.len() >> 20);
        return Ok(());
    }
    type Generator = fn() -> anyhow::Result<Vec<u8>>;
    let generators: [(&str, Generator); 5] = [
        ("living-room.glb", living_room),
        ("city.glb", city),
        ("atrium.glb", atrium),
        ("animated.glb", || {
            Ok(omnicave::scene::animated_sample::animated_sample_glb())
        }),
        ("sky.png", || png(&sky())),
    ];
    // A bar with an ETA on a terminal (the city and the sky take seconds each).
    let bar = indicatif::ProgressBar::new(generators.len() as u64).with_style(
        indicatif::ProgressStyle::with_template(
            "[{bar:30}] {pos}/{len} {elapsed_precise} (ETA {eta}) {wide_msg}",
        )
        .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar())
        .progress_chars("#>-"),
    );
    let mut stale = Vec::new();
    for (name, generate) in generators {
        bar.set_message(name);
        let bytes = generate()?;
        bar.inc(1);
        let path = out.join(name);
        if check {
            let on_disk = std::fs::read(&path).unwrap_or_default();
            if on_disk != bytes {
                stale.push(path);
            }
        } else {
            std::fs::create_dir_all(&out).with_context(|| format!("creating {}", out.display()))?;
            std::fs::write(&path, &bytes).with_context(|| format!("writing {}", path.display()))?;
            bar.suspend(|| eprintln!("wrote {} ({} KiB)", path.display(), bytes.len() / 1024));
        }
    }
    bar.finish_and_clear();
    if !stale.is_empty() {
        bail!(
            "assets differ from the generator's output: {:?}; run `cargo run --bin gen-assets`",
            stale
        );
    }
    Ok(())
}

/// `scene::build::dense_hall` as a GLB: the shell in grey plaster, the sphere in white.
fn dense_hall(triangles: u64) -> Vec<u8> {
    let (shell, sphere) = omnicave::scene::build::dense_hall(triangles);
    let mut w = GlbWriter::new();
    let plaster = w.add_material(&MaterialDesc::plain("plaster", [0.7, 0.68, 0.64], 0.9));
    let white = w.add_material(&MaterialDesc::plain("white", [0.92, 0.92, 0.9], 0.4));
    let shell_mesh = w.add_mesh("hall", &[(&shell, plaster)]);
    let sphere_mesh = w.add_mesh("sphere", &[(&sphere, white)]);
    let roots = [
        w.add_node(NodeDesc::new("hall").with_mesh(shell_mesh)),
        w.add_node(NodeDesc::new("sphere").with_mesh(sphere_mesh)),
    ];
    w.to_glb(&roots)
}

/// A small deterministic PRNG (xorshift64*), so the assets are byte-identical on every run.
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> f32 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        let v = self.0.wrapping_mul(0x2545_F491_4F6C_DD1D);
        (v >> 40) as f32 / (1u64 << 24) as f32
    }

    fn range(&mut self, lo: f32, hi: f32) -> f32 {
        lo + (hi - lo) * self.next()
    }
}

fn png(img: &RgbaImage) -> anyhow::Result<Vec<u8>> {
    let mut bytes = Vec::new();
    img.write_to(
        &mut std::io::Cursor::new(&mut bytes),
        image::ImageFormat::Png,
    )
    .context("encoding PNG")?;
    Ok(bytes)
}

fn shade(c: [u8; 3], f: f32) -> Rgba<u8> {
    let s = |v: u8| (f32::from(v) * f).clamp(0.0, 255.0) as u8;
    Rgba([s(c[0]), s(c[1]), s(c[2]), 255])
}

/// Parquet: planks 1/4 texture wide with staggered joints and grain; one tile = 1 m.
fn parquet_texture() -> RgbaImage {
    let mut rng = Rng(7);
    let size = 256;
    let plank_w = size / 8;
    let offsets: Vec<u32> = (0..8).map(|_| (rng.next() * size as f32) as u32).collect();
    let tones: Vec<f32> = (0..32).map(|_| rng.range(0.8, 1.1)).collect();
    RgbaImage::from_fn(size, size, |x, y| {
        let column = x / plank_w;
        let along = (y + offsets[column as usize]) % size;
        let plank = column * 4 + along / (size / 4);
        let joint = x.is_multiple_of(plank_w) || along.is_multiple_of(size / 4);
        if joint {
            return Rgba([60, 38, 22, 255]);
        }
        let grain = 0.92 + 0.08 * ((x as f32 * 0.9 + (along as f32 * 0.05).sin() * 3.0).sin());
        shade([168, 112, 64], tones[plank as usize % 32] * grain)
    })
}

/// The parquet's normal map (tangent space, +y up the image): the joints are grooves 2 px
/// wide whose sides face out of them, and the planks' grain ripples slightly.
fn parquet_normal_map() -> RgbaImage {
    let parquet = parquet_texture();
    let size = parquet.width();
    // Height: 0 in a joint, 1 on a plank (the joint colour marks them), plus a faint grain.
    let height = |x: u32, y: u32| {
        let p = parquet.get_pixel(x % size, y % size);
        let joint = p.0[..3] == [60, 38, 22];
        let grain = 0.02 * ((x as f32 * 0.9).sin());
        if joint { 0.0 } else { 1.0 + grain }
    };
    RgbaImage::from_fn(size, size, |x, y| {
        // Central differences, wrapping (the texture tiles); image rows grow downwards, so
        // the tangent-space y (up the image) is minus the row slope.
        let dx = height(x + 1, y) - height(x + size - 1, y);
        let dy = height(x, y + size - 1) - height(x, y + 1);
        let n = Vec3::new(-dx * 0.35, -dy * 0.35, 1.0).normalize();
        let c = (n * 0.5 + 0.5) * 255.0;
        Rgba([c.x.round() as u8, c.y.round() as u8, c.z.round() as u8, 255])
    })
}

/// Wallpaper: soft vertical stripes with a small diamond pattern.
fn wallpaper_texture() -> RgbaImage {
    RgbaImage::from_fn(128, 128, |x, y| {
        let stripe = if (x / 16) % 2 == 0 { 1.0 } else { 0.94 };
        let dx = (x % 32) as i32 - 16;
        let dy = (y % 32) as i32 - 16;
        let diamond = if dx.abs() + dy.abs() < 3 { 0.85 } else { 1.0 };
        shade([222, 214, 190], stripe * diamond)
    })
}

/// A "painting": sky gradient, sun, hills, in a dark frame band.
fn painting_texture() -> RgbaImage {
    let (w, h) = (192, 128);
    RgbaImage::from_fn(w, h, |x, y| {
        let (fx, fy) = (x as f32 / w as f32, y as f32 / h as f32);
        let hill = 0.62 + 0.08 * (fx * 9.0).sin() + 0.05 * (fx * 23.0).cos();
        let sun = ((fx - 0.72).powi(2) + (fy - 0.3).powi(2)).sqrt() < 0.08;
        if sun {
            Rgba([250, 220, 90, 255])
        } else if fy > hill {
            shade([60, 130, 60], 0.8 + 0.4 * (1.0 - fy))
        } else {
            shade([90, 150, 220], 0.7 + 0.5 * fy)
        }
    })
}

/// Book spines / fabric: coarse weave for the sofa.
fn fabric_texture() -> RgbaImage {
    RgbaImage::from_fn(64, 64, |x, y| {
        let weave = if (x + y) % 4 < 2 { 1.0 } else { 0.9 };
        shade([70, 90, 140], weave)
    })
}

/// The living room's materials (indices into the writer's materials).
struct RoomMaterials {
    floor: usize,
    wall: usize,
    ceiling: usize,
    wood: usize,
    sofa: usize,
    metal: usize,
    shade: usize,
    bulb: usize,
    vase: usize,
    painting: usize,
    frame: usize,
    books: Vec<usize>,
}

/// The living room's meshes (indices into the writer's meshes).
struct RoomMeshes {
    sofa: usize,
    table: usize,
    vase: usize,
    chair: usize,
    lamp: usize,
    ceiling_lamp: usize,
    picture: usize,
    shelf: usize,
}

/// The room's extent: x from `ROOM_X0` to `ROOM_X1`, z from `ROOM_Z0` to `ROOM_Z1`, and its
/// height.
const ROOM_X0: f32 = -3.0;
const ROOM_X1: f32 = 3.0;
const ROOM_Z0: f32 = -3.5;
const ROOM_Z1: f32 = 2.5;
const ROOM_TOP: f32 = 2.7;

/// `m` moved by `p`.
fn at(m: MeshData, p: Vec3) -> MeshData {
    m.transformed(Mat4::from_translation(p))
}

/// The living room: a single-quad room around the CAVE with furniture, as GLB bytes.
fn living_room() -> anyhow::Result<Vec<u8>> {
    let mut w = GlbWriter::new();
    let mats = living_room_materials(&mut w)?;
    let [room, floor_node] = add_room_shell(&mut w, &mats);
    let sofa_mesh = w.add_mesh("sofa", &[(&sofa(), mats.sofa)]);
    let table_mesh = w.add_mesh("coffee table", &[(&coffee_table(), mats.wood)]);
    let vase_mesh = w.add_mesh("vase", &[(&vase(), mats.vase)]);
    let chair_mesh = w.add_mesh("chair", &[(&chair(), mats.wood)]);
    let lamp_mesh = add_floor_lamp(&mut w, &mats);
    let ceiling_lamp_mesh = add_ceiling_lamp(&mut w, &mats);
    let picture_mesh = add_picture(&mut w, &mats);
    let shelf_mesh = add_bookshelf(&mut w, &mats);
    let meshes = RoomMeshes {
        sofa: sofa_mesh,
        table: table_mesh,
        vase: vase_mesh,
        chair: chair_mesh,
        lamp: lamp_mesh,
        ceiling_lamp: ceiling_lamp_mesh,
        picture: picture_mesh,
        shelf: shelf_mesh,
    };
    let furniture = add_furniture_nodes(&mut w, &meshes);
    Ok(w.to_glb(&[room, floor_node, furniture]))
}

/// The living room's textures and materials, added in a fixed order.
fn living_room_materials(w: &mut GlbWriter) -> anyhow::Result<RoomMaterials> {
    let parquet = w.add_png_texture("parquet", &png(&parquet_texture())?);
    let wallpaper = w.add_png_texture("wallpaper", &png(&wallpaper_texture())?);
    let painting = w.add_png_texture("painting", &png(&painting_texture())?);
    let fabric = w.add_png_texture("fabric", &png(&fabric_texture())?);

    let textured = |name: &str, texture: usize, roughness: f32| MaterialDesc {
        texture: Some(texture),
        ..MaterialDesc::plain(name, [1.0; 3], roughness)
    };
    let parquet_normals = w.add_png_texture("parquet normals", &png(&parquet_normal_map())?);
    let floor = w.add_material(&MaterialDesc {
        maps: MaterialMaps {
            normal: Some(parquet_normals),
            ..MaterialMaps::default()
        },
        ..textured("parquet", parquet, 0.35)
    });
    let wall = w.add_material(&textured("wallpaper", wallpaper, 0.9));
    let ceiling = w.add_material(&MaterialDesc::plain("ceiling", [0.92, 0.92, 0.9], 0.95));
    let wood = w.add_material(&MaterialDesc::plain("dark wood", [0.30, 0.17, 0.08], 0.45));
    let sofa = w.add_material(&textured("sofa fabric", fabric, 0.85));
    let metal = w.add_material(&MaterialDesc {
        metallic: 1.0,
        ..MaterialDesc::plain("brass", [0.8, 0.62, 0.3], 0.3)
    });
    let shade = w.add_material(&MaterialDesc {
        double_sided: true,
        ..MaterialDesc::plain("lamp shade", [0.95, 0.85, 0.65], 0.8)
    });
    let bulb = w.add_material(&MaterialDesc {
        emissive: [1.0, 0.9, 0.7],
        ..MaterialDesc::plain("bulb", [1.0, 0.95, 0.85], 0.5)
    });
    let vase = w.add_material(&MaterialDesc::plain("glazed vase", [0.1, 0.35, 0.55], 0.12));
    let painting = w.add_material(&textured("painting", painting, 0.6));
    let frame = w.add_material(&MaterialDesc::plain("gilt frame", [0.55, 0.42, 0.15], 0.4));
    let books: Vec<usize> = [
        [0.6, 0.1, 0.1],
        [0.1, 0.3, 0.5],
        [0.2, 0.45, 0.2],
        [0.75, 0.6, 0.2],
        [0.35, 0.2, 0.45],
    ]
    .iter()
    .enumerate()
    .map(|(i, c)| w.add_material(&MaterialDesc::plain(&format!("book {i}"), *c, 0.7)))
    .collect();
    Ok(RoomMaterials {
        floor,
        wall,
        ceiling,
        wood,
        sofa,
        metal,
        shade,
        bulb,
        vase,
        painting,
        frame,
        books,
    })
}

/// The room around the CAVE: walls and ceiling, and the normal-mapped floor; returns their
/// nodes.
fn add_room_shell(w: &mut GlbWriter, mats: &RoomMaterials) -> [usize; 2] {
    // The room: 6 m × 6 m × 2.7 m around the CAVE, each surface a single large quad (two
    // triangles) as in the thesis: exactly what a per-vertex warp interpolates badly.
    let (x0, x1, z0, z1, top) = (ROOM_X0, ROOM_X1, ROOM_Z0, ROOM_Z1, ROOM_TOP);
    let floor = grid(
        Vec3::new(x0, 0.0, z1),
        Vec3::X * (x1 - x0),
        Vec3::NEG_Z * (z1 - z0),
        1,
        1,
        1.0,
    );
    let ceiling = grid(
        Vec3::new(x0, top, z0),
        Vec3::X * (x1 - x0),
        Vec3::Z * (z1 - z0),
        1,
        1,
        1.0,
    );
    let mut walls = MeshData::default();
    let h = Vec3::Y * top;
    walls.append(&grid(
        Vec3::new(x0, 0.0, z0),
        Vec3::X * (x1 - x0),
        h,
        1,
        1,
        1.2,
    )); // front
    walls.append(&grid(
        Vec3::new(x1, 0.0, z1),
        Vec3::NEG_X * (x1 - x0),
        h,
        1,
        1,
        1.2,
    )); // back
    walls.append(&grid(
        Vec3::new(x0, 0.0, z1),
        Vec3::NEG_Z * (z1 - z0),
        h,
        1,
        1,
        1.2,
    )); // left
    walls.append(&grid(
        Vec3::new(x1, 0.0, z0),
        Vec3::Z * (z1 - z0),
        h,
        1,
        1,
        1.2,
    )); // right
    let room_mesh = w.add_mesh("room", &[(&walls, mats.wall), (&ceiling, mats.ceiling)]);
    // The floor with tangents for its normal map: u along +x, v (image rows) towards +z,
    // which is −(n × t) for n = +y, t = +x.
    let mut floor = floor;
    for v in &mut floor.vertices {
        v.tangent = [1.0, 0.0, 0.0, -1.0];
    }
    let floor_mesh = w.add_mesh_with(
        "floor",
        &[(&floor, mats.floor)],
        &MeshOptions {
            tangents: true,
            ..MeshOptions::default()
        },
    );
    let room = w.add_node(NodeDesc::new("room").with_mesh(room_mesh));
    let floor_node = w.add_node(NodeDesc::new("floor").with_mesh(floor_mesh));
    [room, floor_node]
}

/// Sofa against the left room wall, facing +x.
fn sofa() -> MeshData {
    let mut sofa = MeshData::default();
    sofa.append(&at(
        cuboid(Vec3::new(0.9, 0.42, 2.2), 2.0),
        Vec3::new(0.0, 0.21, 0.0),
    ));
    sofa.append(&at(
        cuboid(Vec3::new(0.22, 0.5, 2.2), 2.0),
        Vec3::new(-0.34, 0.67, 0.0),
    ));
    for z in [-1.0, 1.0] {
        sofa.append(&at(
            cuboid(Vec3::new(0.9, 0.62, 0.2), 2.0),
            Vec3::new(0.0, 0.31, z),
        ));
    }
    sofa
}

/// Coffee table: top and four legs.
fn coffee_table() -> MeshData {
    let mut table = at(
        cuboid(Vec3::new(1.1, 0.05, 0.6), 1.0),
        Vec3::new(0.0, 0.42, 0.0),
    );
    for (x, z) in [(-0.5, -0.25), (0.5, -0.25), (-0.5, 0.25), (0.5, 0.25)] {
        table.append(&at(
            cuboid(Vec3::new(0.05, 0.4, 0.05), 1.0),
            Vec3::new(x, 0.2, z),
        ));
    }
    table
}

/// Dense vase on the table (specular highlights show the lighting eye).
fn vase() -> MeshData {
    uv_sphere(0.12, 32, 48).transformed(Mat4::from_scale(Vec3::new(1.0, 1.4, 1.0)))
}

/// A chair (one mesh, used twice through nodes).
fn chair() -> MeshData {
    let mut chair = at(
        cuboid(Vec3::new(0.45, 0.05, 0.45), 1.0),
        Vec3::new(0.0, 0.45, 0.0),
    );
    chair.append(&at(
        cuboid(Vec3::new(0.45, 0.5, 0.04), 1.0),
        Vec3::new(0.0, 0.72, 0.21),
    ));
    for (x, z) in [(-0.2, -0.2), (0.2, -0.2), (-0.2, 0.2), (0.2, 0.2)] {
        chair.append(&at(
            cuboid(Vec3::new(0.035, 0.45, 0.035), 1.0),
            Vec3::new(x, 0.225, z),
        ));
    }
    chair
}

/// Floor lamp: brass pole, dense shade, emissive bulb; returns its mesh.
fn add_floor_lamp(w: &mut GlbWriter, mats: &RoomMaterials) -> usize {
    let pole = frustum_shell(0.015, 0.015, 1.45, 16, true);
    let base = frustum_shell(0.16, 0.14, 0.03, 32, true);
    let mut lamp_metal = pole;
    lamp_metal.append(&base);
    let shade_mesh_data = at(
        frustum_shell(0.24, 0.14, 0.32, 64, false),
        Vec3::new(0.0, 1.3, 0.0),
    );
    let bulb = at(uv_sphere(0.05, 12, 16), Vec3::new(0.0, 1.42, 0.0));
    w.add_mesh(
        "floor lamp",
        &[
            (&lamp_metal, mats.metal),
            (&shade_mesh_data, mats.shade),
            (&bulb, mats.bulb),
        ],
    )
}

/// Ceiling lamp where the config's point light is; returns its mesh.
fn add_ceiling_lamp(w: &mut GlbWriter, mats: &RoomMaterials) -> usize {
    let ceiling_lamp = at(uv_sphere(0.12, 16, 24), Vec3::new(0.0, 2.5, -0.6));
    let ceiling_cord = at(
        frustum_shell(0.008, 0.008, 0.08, 8, false),
        Vec3::new(0.0, 2.62, -0.6),
    );
    w.add_mesh(
        "ceiling lamp",
        &[(&ceiling_lamp, mats.bulb), (&ceiling_cord, mats.metal)],
    )
}

/// Picture hung 1 cm in front of the left room wall (thesis Fig. 7.3: with a plain warp it
/// vanishes behind the wall in one eye): canvas and frame; returns its mesh.
fn add_picture(w: &mut GlbWriter, mats: &RoomMaterials) -> usize {
    let x0 = ROOM_X0;
    let canvas = grid(
        Vec3::new(x0 + 0.012, 1.1, 0.6),
        Vec3::NEG_Z * 1.2,
        Vec3::Y * 0.8,
        1,
        1,
        1.0,
    );
    let canvas = MeshData {
        vertices: canvas
            .vertices
            .iter()
            .map(|v| omnicave::scene::Vertex {
                uv: [(0.6 - v.position[2]) / 1.2, (1.9 - v.position[1]) / 0.8],
                ..*v
            })
            .collect(),
        indices: canvas.indices,
    };
    let mut frame = MeshData::default();
    for (y, z, sy, sz) in [
        (1.08, 0.0, 0.04, 1.28),
        (1.92, 0.0, 0.04, 1.28),
        (1.5, 0.62, 0.88, 0.04),
        (1.5, -0.62, 0.88, 0.04),
    ] {
        frame.append(&at(
            cuboid(Vec3::new(0.03, sy, sz), 1.0),
            Vec3::new(x0 + 0.015, y, z),
        ));
    }
    w.add_mesh("picture", &[(&canvas, mats.painting), (&frame, mats.frame)])
}

/// Bookshelf on the right room wall, many small books (medium density); returns its mesh.
fn add_bookshelf(w: &mut GlbWriter, mats: &RoomMaterials) -> usize {
    let m_books = &mats.books;
    let mut rng = Rng(42);
    let mut shelf = MeshData::default();
    for side in [-0.9, 0.9] {
        shelf.append(&at(
            cuboid(Vec3::new(0.3, 1.9, 0.03), 1.0),
            Vec3::new(0.0, 0.95, side),
        ));
    }
    let mut books: Vec<MeshData> = vec![MeshData::default(); m_books.len()];
    for level in 0..5 {
        let y = 0.05 + level as f32 * 0.45;
        shelf.append(&at(
            cuboid(Vec3::new(0.3, 0.03, 1.8), 1.0),
            Vec3::new(0.0, y, 0.0),
        ));
        let mut z = -0.86;
        while z < 0.82 {
            let thick = rng.range(0.025, 0.06);
            let tall = rng.range(0.2, 0.34);
            let pick = (rng.next() * m_books.len() as f32) as usize % m_books.len();
            books[pick].append(&at(
                cuboid(Vec3::new(0.22, tall, thick), 4.0),
                Vec3::new(0.02, y + 0.015 + tall / 2.0, z + thick / 2.0),
            ));
            z += thick + 0.004;
        }
    }
    let mut shelf_prims: Vec<(&MeshData, usize)> = vec![(&shelf, mats.wood)];
    for (mesh, mat) in books.iter().zip(m_books) {
        shelf_prims.push((mesh, *mat));
    }
    w.add_mesh("bookshelf", &shelf_prims)
}

/// Furniture hierarchy: a group node with children (exercises node transforms); returns the
/// group.
fn add_furniture_nodes(w: &mut GlbWriter, meshes: &RoomMeshes) -> usize {
    let n_sofa = w.add_node(
        NodeDesc::new("sofa")
            .with_mesh(meshes.sofa)
            .at(Vec3::new(-2.45, 0.0, 0.0)),
    );
    let n_vase = w.add_node(
        NodeDesc::new("vase")
            .with_mesh(meshes.vase)
            .at(Vec3::new(0.25, 0.61, 0.0)),
    );
    let n_table = w.add_node(
        NodeDesc::new("coffee table")
            .with_mesh(meshes.table)
            .at(Vec3::new(-1.75, 0.0, 0.3))
            .rotated_y_degrees(90.0)
            .with_children(vec![n_vase]),
    );
    let n_chair_a = w.add_node(
        NodeDesc::new("chair A")
            .with_mesh(meshes.chair)
            .at(Vec3::new(1.0, 0.0, -2.2))
            .rotated_y_degrees(200.0),
    );
    let n_chair_b = w.add_node(
        NodeDesc::new("chair B")
            .with_mesh(meshes.chair)
            .at(Vec3::new(2.2, 0.0, -1.0))
            .rotated_y_degrees(120.0),
    );
    let n_lamp = w.add_node(
        NodeDesc::new("floor lamp")
            .with_mesh(meshes.lamp)
            .at(Vec3::new(-2.3, 0.0, -2.8)),
    );
    let n_shelf = w.add_node(
        NodeDesc::new("bookshelf")
            .with_mesh(meshes.shelf)
            .at(Vec3::new(2.82, 0.0, 0.6))
            .rotated_y_degrees(180.0),
    );
    let n_picture = w.add_node(NodeDesc::new("picture").with_mesh(meshes.picture));
    let n_ceiling_lamp = w.add_node(NodeDesc::new("ceiling lamp").with_mesh(meshes.ceiling_lamp));
    w.add_node(NodeDesc::new("furniture").with_children(vec![
        n_sofa,
        n_table,
        n_chair_a,
        n_chair_b,
        n_lamp,
        n_shelf,
        n_picture,
        n_ceiling_lamp,
    ]))
}

/// City ground: one 40 m cell = a 30 m block of pavement and half a 10 m street on each side.
fn street_texture() -> RgbaImage {
    let size = 256;
    let m = |px: u32| px as f32 * 40.0 / size as f32; // pixels → metres
    RgbaImage::from_fn(size, size, |x, y| {
        let (mx, my) = (m(x), m(y));
        let in_street_x = !(5.0..35.0).contains(&mx);
        let in_street_y = !(5.0..35.0).contains(&my);
        if !(in_street_x || in_street_y) {
            // Pavement with 2 m slabs.
            let joint = (mx % 2.0) < 0.16 || (my % 2.0) < 0.16;
            return if joint {
                Rgba([150, 150, 145, 255])
            } else {
                Rgba([190, 188, 180, 255])
            };
        }
        // Centre line dashes (street centre lies on the cell border).
        let near_centre_x = in_street_x && !(0.25..=39.75).contains(&mx);
        let near_centre_y = in_street_y && !(0.25..=39.75).contains(&my);
        let crossing = in_street_x && in_street_y;
        if !crossing && ((near_centre_x && (my % 4.0) < 2.0) || (near_centre_y && (mx % 4.0) < 2.0))
        {
            return Rgba([240, 240, 235, 255]);
        }
        let grain = ((x * 7 + y * 13) % 5) as f32 * 0.02;
        shade([62, 64, 68], 0.95 + grain)
    })
}

/// Whether a facade texel is glass.
fn facade_window(x: u32, y: u32) -> bool {
    (12..52).contains(&x) && (14..46).contains(&y)
}

/// The facade's metallic-roughness map (green: roughness, blue: metallic): smooth glass,
/// rough render.
fn facade_metallic_roughness() -> RgbaImage {
    RgbaImage::from_fn(64, 64, |x, y| {
        let roughness = if facade_window(x, y) { 20 } else { 255 };
        Rgba([0, roughness, 0, 255])
    })
}

/// Facade: one tile = 4 m × 4 m with a window.
fn facade_texture() -> RgbaImage {
    RgbaImage::from_fn(64, 64, |x, y| {
        let window = facade_window(x, y);
        if window {
            let sky = 0.8 + 0.4 * (y as f32 / 64.0);
            shade([70, 95, 120], sky)
        } else {
            Rgba([205, 200, 188, 255])
        }
    })
}

fn city() -> anyhow::Result<Vec<u8>> {
    let mut w = GlbWriter::new();
    let streets = w.add_png_texture("streets", &png(&street_texture())?);
    let facade = w.add_png_texture("facade", &png(&facade_texture())?);
    let facade_mr = w.add_png_texture(
        "facade metallic-roughness",
        &png(&facade_metallic_roughness())?,
    );
    let m_ground = w.add_material(&MaterialDesc {
        texture: Some(streets),
        ..MaterialDesc::plain("streets", [1.0; 3], 0.9)
    });
    let building_tints = [
        [1.0, 1.0, 1.0],
        [0.95, 0.85, 0.75],
        [0.8, 0.85, 0.95],
        [0.9, 0.9, 0.8],
    ];
    let m_buildings: Vec<usize> = building_tints
        .iter()
        .enumerate()
        .map(|(i, c)| {
            w.add_material(&MaterialDesc {
                texture: Some(facade),
                maps: MaterialMaps {
                    metallic_roughness: Some(facade_mr),
                    ..MaterialMaps::default()
                },
                ..MaterialDesc::plain(&format!("facade {i}"), *c, 1.0)
            })
        })
        .collect();
    let m_trunk = w.add_material(&MaterialDesc::plain("trunk", [0.35, 0.25, 0.15], 0.9));
    let m_leaves = w.add_material(&MaterialDesc::plain("leaves", [0.2, 0.45, 0.18], 0.9));

    // Ground: one huge quad, 16 × 16 cells of 40 m; the CAVE stands on a crossing at the origin.
    let cells = 16;
    let extent = cells as f32 * 40.0;
    let origin = Vec3::new(-extent / 2.0, 0.0, extent / 2.0);
    let ground = grid(
        origin,
        Vec3::X * extent,
        Vec3::NEG_Z * extent,
        1,
        1,
        1.0 / 40.0,
    );
    let ground_mesh = w.add_mesh("ground", &[(&ground, m_ground)]);
    let mut roots = vec![w.add_node(NodeDesc::new("ground").with_mesh(ground_mesh))];

    // Buildings on every block; cell (i, j) spans [i·40, i·40+40] shifted so a crossing is at 0.
    let mut rng = Rng(2015);
    let mut per_material: Vec<MeshData> = vec![MeshData::default(); m_buildings.len()];
    let half = cells / 2;
    for i in -half..half {
        for j in -half..half {
            let (cx, cz) = (i as f32 * 40.0 + 20.0, j as f32 * 40.0 + 20.0);
            // Quadrant-split blocks: up to four buildings per block.
            for (qx, qz) in [(-7.5, -7.5), (7.5, -7.5), (-7.5, 7.5), (7.5, 7.5)] {
                if rng.next() < 0.2 {
                    continue;
                }
                let (sx, sz) = (rng.range(9.0, 12.0), rng.range(9.0, 12.0));
                let dist = (cx * cx + cz * cz).sqrt();
                let tall = rng.range(8.0, 25.0)
                    + if dist > 120.0 {
                        rng.range(0.0, 45.0)
                    } else {
                        0.0
                    };
                let b = cuboid(Vec3::new(sx, tall, sz), 0.25).transformed(Mat4::from_translation(
                    Vec3::new(cx + qx, tall / 2.0, cz + qz),
                ));
                let k = (rng.next() * per_material.len() as f32) as usize % per_material.len();
                per_material[k].append(&b);
            }
        }
    }
    let prims: Vec<(&MeshData, usize)> = per_material
        .iter()
        .zip(m_buildings.iter().copied())
        .collect();
    let buildings_mesh = w.add_mesh("buildings", &prims);
    roots.push(w.add_node(NodeDesc::new("buildings").with_mesh(buildings_mesh)));

    // Trees along the two streets through the origin: one mesh, many nodes.
    let trunk = frustum_shell(0.15, 0.12, 2.0, 8, false);
    let crown = frustum_shell(1.4, 0.0, 3.5, 10, true)
        .transformed(Mat4::from_translation(Vec3::new(0.0, 1.8, 0.0)));
    let tree_mesh = w.add_mesh("tree", &[(&trunk, m_trunk), (&crown, m_leaves)]);
    let mut trees = Vec::new();
    for k in -6..=6 {
        if k == 0 {
            continue;
        }
        let d = k as f32 * 18.0;
        for p in [
            Vec3::new(d, 0.0, 4.0),
            Vec3::new(d, 0.0, -4.0),
            Vec3::new(4.0, 0.0, d),
            Vec3::new(-4.0, 0.0, d),
        ] {
            trees.push(w.add_node(NodeDesc::new("tree").with_mesh(tree_mesh).at(p)));
        }
    }
    roots.push(w.add_node(NodeDesc::new("trees").with_children(trees)));
    Ok(w.to_glb(&roots))
}

/// Flagstones: a grid of slightly varied stone slabs with dark joints (128 px per 2 m slab).
fn flagstone_texture() -> RgbaImage {
    let mut rng = Rng(1907);
    let tones: Vec<f32> = (0..16).map(|_| rng.range(0.85, 1.0)).collect();
    RgbaImage::from_fn(256, 256, |x, y| {
        let (i, j) = (x / 128, y / 128);
        let (u, v) = (x % 128, y % 128);
        if u < 2 || v < 2 {
            return shade([70, 66, 60], 1.0);
        }
        let tone = tones[((i + 2 * j) % 16) as usize];
        let grain = 0.94 + 0.06 * (((x * 7 + y * 13) % 17) as f32 / 17.0);
        shade([190, 180, 160], tone * grain)
    })
}

/// The atrium's half width (x), half length (z) and height, m.
const ATRIUM_HALF_X: f32 = 10.0;
const ATRIUM_HALF_Z: f32 = 18.0;
const ATRIUM_HEIGHT: f32 = 14.0;
/// Height of one storey of the arcades, m.
const ATRIUM_STOREY: f32 = 7.0;
/// Distance between column centres along an arcade, m.
const ATRIUM_BAY: f32 = 4.0;
/// Distance of each arcade from the atrium's long axis, m.
const ATRIUM_X_ROW: f32 = 6.0;

/// The atrium's materials (indices into the writer's materials).
struct AtriumMaterials {
    floor: usize,
    wall: usize,
    marble: usize,
    stone: usize,
}

/// The atrium's repeated meshes (indices into the writer's meshes).
struct AtriumMeshes {
    column: usize,
    arch: usize,
    baluster: usize,
}

/// An atrium for the bench's scaling with scene size: 20 m × 36 m, 14 m high, two storeys of
/// fluted columns carrying arcades, a balustraded gallery, and large floor, wall and ceiling
/// polygons; over 200 000 triangles, most of them small and far from the CAVE (which stands
/// at the centre of the floor, facing −z), the floor and walls few and large.
fn atrium() -> anyhow::Result<Vec<u8>> {
    let mut w = GlbWriter::new();
    let mats = atrium_materials(&mut w)?;
    let mut roots = add_atrium_shell(&mut w, &mats).to_vec();
    let column_mesh = w.add_mesh("column", &[(&fluted_column(), mats.marble)]);
    let arch_mesh = w.add_mesh("arch", &[(&arcade_bay(), mats.stone)]);
    let baluster_mesh = w.add_mesh("baluster", &[(&lathe(&baluster_profile(), 12), mats.stone)]);
    let meshes = AtriumMeshes {
        column: column_mesh,
        arch: arch_mesh,
        baluster: baluster_mesh,
    };
    let [columns, arches, balusters] = add_arcade_nodes(&mut w, &meshes);
    let slab_mesh = w.add_mesh("gallery floors", &[(&gallery_floors(), mats.stone)]);
    roots.push(w.add_node(NodeDesc::new("gallery floors").with_mesh(slab_mesh)));
    roots.push(w.add_node(NodeDesc::new("columns").with_children(columns)));
    roots.push(w.add_node(NodeDesc::new("arcades").with_children(arches)));
    roots.push(w.add_node(NodeDesc::new("balustrades").with_children(balusters)));
    Ok(w.to_glb(&roots))
}

/// The atrium's texture and materials, added in a fixed order.
fn atrium_materials(w: &mut GlbWriter) -> anyhow::Result<AtriumMaterials> {
    let flags = w.add_png_texture("flagstones", &png(&flagstone_texture())?);
    let floor = w.add_material(&MaterialDesc {
        texture: Some(flags),
        ..MaterialDesc::plain("floor", [1.0; 3], 0.7)
    });
    let wall = w.add_material(&MaterialDesc::plain("plaster", [0.86, 0.82, 0.74], 0.9));
    let marble = w.add_material(&MaterialDesc::plain("marble", [0.93, 0.92, 0.9], 0.35));
    let stone = w.add_material(&MaterialDesc::plain("stone", [0.78, 0.72, 0.62], 0.8));
    Ok(AtriumMaterials {
        floor,
        wall,
        marble,
        stone,
    })
}

/// The shell: one quad per face, seen from inside; returns the floor's and the walls' nodes.
fn add_atrium_shell(w: &mut GlbWriter, mats: &AtriumMaterials) -> [usize; 2] {
    let (half_x, half_z, height) = (ATRIUM_HALF_X, ATRIUM_HALF_Z, ATRIUM_HEIGHT);
    let shell = [
        grid(
            Vec3::new(-half_x, 0.0, half_z),
            Vec3::X * 2.0 * half_x,
            Vec3::NEG_Z * 2.0 * half_z,
            1,
            1,
            0.5,
        ),
        grid(
            Vec3::new(-half_x, height, -half_z),
            Vec3::X * 2.0 * half_x,
            Vec3::Z * 2.0 * half_z,
            1,
            1,
            0.5,
        ),
    ];
    let walls = [
        grid(
            Vec3::new(-half_x, 0.0, -half_z),
            Vec3::X * 2.0 * half_x,
            Vec3::Y * height,
            1,
            1,
            0.5,
        ),
        grid(
            Vec3::new(half_x, 0.0, half_z),
            Vec3::NEG_X * 2.0 * half_x,
            Vec3::Y * height,
            1,
            1,
            0.5,
        ),
        grid(
            Vec3::new(-half_x, 0.0, half_z),
            Vec3::NEG_Z * 2.0 * half_z,
            Vec3::Y * height,
            1,
            1,
            0.5,
        ),
        grid(
            Vec3::new(half_x, 0.0, -half_z),
            Vec3::Z * 2.0 * half_z,
            Vec3::Y * height,
            1,
            1,
            0.5,
        ),
    ];
    let mut wall_mesh = MeshData::default();
    for g in &walls {
        wall_mesh.append(g);
    }
    wall_mesh.append(&shell[1]);
    let floor_mesh = w.add_mesh("floor", &[(&shell[0], mats.floor)]);
    let walls_mesh = w.add_mesh("walls and ceiling", &[(&wall_mesh, mats.wall)]);
    [
        w.add_node(NodeDesc::new("floor").with_mesh(floor_mesh)),
        w.add_node(NodeDesc::new("walls").with_mesh(walls_mesh)),
    ]
}

/// A fluted column, 6 m: base, shaft with 16 flutes (64 segments, 16 rings), capital.
fn fluted_column() -> MeshData {
    let mut column = MeshData::default();
    let base: Vec<(f32, f32)> = (0..=6)
        .map(|k| {
            let t = k as f32 / 6.0;
            (
                0.62 - 0.14 * t + 0.05 * (t * std::f32::consts::PI).sin(),
                0.4 * t,
            )
        })
        .collect();
    column.append(&lathe(&base, 64));
    let flutes = 16.0;
    let mut shaft = lathe(
        &(0..=16)
            .map(|k| (0.46 - 0.06 * k as f32 / 16.0, 0.4 + 5.0 * k as f32 / 16.0))
            .collect::<Vec<_>>(),
        64,
    );
    for v in &mut shaft.vertices {
        // Flutes: the radius dips 2.5 cm between the arrises.
        let a = v.position[0].atan2(v.position[2]);
        let dip = 0.025 * (0.5 - 0.5 * (a * flutes).cos());
        let r = (v.position[0] * v.position[0] + v.position[2] * v.position[2]).sqrt();
        let k = (r - dip) / r.max(1e-6);
        v.position[0] *= k;
        v.position[2] *= k;
    }
    column.append(&shaft);
    let capital: Vec<(f32, f32)> = (0..=8)
        .map(|k| {
            let t = k as f32 / 8.0;
            (0.4 + 0.32 * t * t, 5.4 + 0.6 * t)
        })
        .collect();
    column.append(&lathe(&capital, 64));
    column.append(
        &cuboid(Vec3::new(1.5, 0.2, 1.5), 1.0)
            .transformed(Mat4::from_translation(Vec3::new(0.0, 6.1, 0.0))),
    );
    column
}

/// An arch spanning 4 m between column centres, springing from the capitals, with the
/// wall above it up to the next floor.
fn arcade_bay() -> MeshData {
    let (bay, storey) = (ATRIUM_BAY, ATRIUM_STOREY);
    let mut arcade =
        arch(1.45, 2.0, 0.8, 48).transformed(Mat4::from_translation(Vec3::new(0.0, 6.2, 0.0)));
    arcade.append(&cuboid(Vec3::new(bay, storey - 8.2, 0.8), 1.0).transformed(
        Mat4::from_translation(Vec3::new(0.0, 8.2 + 0.5 * (storey - 8.2), 0.0)),
    ));
    arcade
}

/// A baluster's profile, 0.9 m: a turned profile of 12 rings (drawn 12 around).
fn baluster_profile() -> Vec<(f32, f32)> {
    (0..=12)
        .map(|k| {
            let t = k as f32 / 12.0;
            let bulge = (t * std::f32::consts::PI).sin();
            (0.05 + 0.05 * bulge * bulge, 0.9 * t)
        })
        .collect()
}

/// The two storeys of arcades on both sides: a node per column and arch, and on the upper
/// storey the gallery's balusters; returns the columns', arches' and balusters' nodes.
fn add_arcade_nodes(w: &mut GlbWriter, meshes: &AtriumMeshes) -> [Vec<usize>; 3] {
    let (storey, bay, x_row) = (ATRIUM_STOREY, ATRIUM_BAY, ATRIUM_X_ROW);
    let mut columns = Vec::new();
    let mut arches = Vec::new();
    let mut balusters = Vec::new();
    let rows = 9;
    for level in 0..2 {
        let y = level as f32 * storey;
        for side in [-1.0f32, 1.0] {
            let x = side * x_row;
            for k in 0..rows {
                let z = (k as f32 - (rows - 1) as f32 / 2.0) * bay;
                columns.push(
                    w.add_node(
                        NodeDesc::new("column")
                            .with_mesh(meshes.column)
                            .at(Vec3::new(x, y, z)),
                    ),
                );
                if k + 1 < rows {
                    arches.push(
                        w.add_node(
                            NodeDesc::new("arch")
                                .with_mesh(meshes.arch)
                                .rotated_y_degrees(90.0)
                                .at(Vec3::new(x, y, z + 0.5 * bay)),
                        ),
                    );
                }
            }
            if level == 1 {
                // The gallery's balustrade along the arcade, 25 cm apart.
                let n = ((rows - 1) as f32 * bay / 0.25) as i32;
                for b in 0..n {
                    let z = -0.5 * (rows - 1) as f32 * bay + (b as f32 + 0.5) * 0.25;
                    balusters.push(
                        w.add_node(
                            NodeDesc::new("baluster")
                                .with_mesh(meshes.baluster)
                                .at(Vec3::new(x - side * 0.6, y, z)),
                        ),
                    );
                }
            }
        }
    }
    [columns, arches, balusters]
}

/// The gallery floors: slabs from the arcades to the side walls.
fn gallery_floors() -> MeshData {
    let (half_x, half_z, storey) = (ATRIUM_HALF_X, ATRIUM_HALF_Z, ATRIUM_STOREY);
    let slab_w = half_x - ATRIUM_X_ROW + 0.8;
    let mut slabs = MeshData::default();
    for side in [-1.0f32, 1.0] {
        slabs.append(
            &cuboid(Vec3::new(slab_w, 0.3, 2.0 * half_z), 0.5).transformed(Mat4::from_translation(
                Vec3::new(side * (half_x - 0.5 * slab_w), storey - 0.15, 0.0),
            )),
        );
    }
    slabs
}

/// Smooth 3D value noise in 0..1 (a hashed lattice, trilinear with smoothstep), so the clouds
/// wrap seamlessly around the sphere.
fn value_noise(p: Vec3) -> f32 {
    let hash = |x: i32, y: i32, z: i32| {
        let mut h = (x as u32).wrapping_mul(0x8da6_b343)
            ^ (y as u32).wrapping_mul(0xd816_3841)
            ^ (z as u32).wrapping_mul(0xcb1a_b31f);
        h ^= h >> 13;
        h = h.wrapping_mul(0x5bd1_e995);
        h ^= h >> 15;
        (h & 0xffff) as f32 / 65535.0
    };
    let i = p.floor();
    let f = p - i;
    let s = f * f * (Vec3::splat(3.0) - 2.0 * f);
    let (x, y, z) = (i.x as i32, i.y as i32, i.z as i32);
    let lerp = |a: f32, b: f32, t: f32| a + (b - a) * t;
    let x00 = lerp(hash(x, y, z), hash(x + 1, y, z), s.x);
    let x10 = lerp(hash(x, y + 1, z), hash(x + 1, y + 1, z), s.x);
    let x01 = lerp(hash(x, y, z + 1), hash(x + 1, y, z + 1), s.x);
    let x11 = lerp(hash(x, y + 1, z + 1), hash(x + 1, y + 1, z + 1), s.x);
    lerp(lerp(x00, x10, s.y), lerp(x01, x11, s.y), s.z)
}

fn fbm(p: Vec3, octaves: u32) -> f32 {
    let (mut sum, mut amp, mut freq, mut norm) = (0.0, 0.5, 1.0, 0.0);
    for _ in 0..octaves {
        sum += amp * value_noise(p * freq);
        norm += amp;
        amp *= 0.5;
        freq *= 2.03;
    }
    sum / norm
}

/// The bundled sky, equirectangular 2048×1024: gradient, clouds, distant mountains, ground,
/// and the calibration beacons and ring of `omnicave::sky::bundled`.
fn sky() -> RgbaImage {
    let (w, h) = (2048u32, 1024u32);
    // Clouds at a quarter of the resolution (they are soft), upsampled bilinearly.
    let (cw, ch) = (w / 4, h / 4);
    let clouds: Vec<f32> = (0..cw * ch)
        .map(|i| {
            let (x, y) = (i % cw, i / cw);
            let d = equirect_direction((x as f32 + 0.5) / cw as f32, (y as f32 + 0.5) / ch as f32);
            let n = fbm(d * 3.0 + Vec3::new(11.0, 3.0, 7.0), 5);
            let cover = ((n - 0.5) / 0.2).clamp(0.0, 1.0);
            // Clouds thin out towards the horizon and stay clear of the ring and beacons'
            // band below 31° (beacons on a uniform background keep their drawn centroids
            // unbiased).
            let elevation = d.y.asin().to_degrees();
            cover * ((elevation - 31.0) / 10.0).clamp(0.0, 1.0)
        })
        .collect();
    let cloud_at = |u: f32, v: f32| -> f32 {
        equirect_taps(cw, ch, u, v)
            .iter()
            .map(|&(x, y, weight)| weight * clouds[(y * cw + x) as usize])
            .sum()
    };
    let lin = |c: [u8; 3]| {
        Vec3::new(
            srgb_to_linear(c[0]),
            srgb_to_linear(c[1]),
            srgb_to_linear(c[2]),
        )
    };
    let zenith = lin([38, 88, 170]);
    let horizon = lin([185, 205, 228]);
    let mountain = lin([86, 100, 122]);
    let ground_near = lin([58, 70, 46]);
    let ground_far = lin([104, 116, 96]);
    let cloud = lin([246, 246, 248]);
    let cloud_shadow = lin([170, 176, 190]);
    let (ring_lo, ring_hi) = bundled::RING_ELEVATION_DEGREES;
    // The calibration features: a beacon's or the ring's colour where `d` is on one.
    let feature = |d: Vec3| -> Option<[u8; 3]> {
        let elevation = d.y.clamp(-1.0, 1.0).asin().to_degrees();
        for b in &bundled::BEACONS {
            if d.dot(b.direction()) >= b.radius_degrees.to_radians().cos() {
                return Some(b.rgb);
            }
        }
        if elevation < ring_lo || elevation > bundled::RING_TICK_TOP_DEGREES {
            return None;
        }
        let azimuth = d.x.atan2(-d.z).to_degrees();
        let tick_offset =
            (azimuth / bundled::RING_TICK_DEGREES).round() * bundled::RING_TICK_DEGREES - azimuth;
        let on_tick = tick_offset.abs() * elevation.to_radians().cos()
            <= bundled::RING_TICK_HALF_WIDTH_DEGREES;
        (elevation <= ring_hi || on_tick).then_some(bundled::RING_RGB)
    };
    // Whether a pixel may touch a feature (then it is supersampled for an anti-aliased edge, so
    // the features' drawn centroids and edges are accurate to a small fraction of a texel).
    let near_feature = |d: Vec3| {
        let elevation = d.y.clamp(-1.0, 1.0).asin().to_degrees();
        (elevation > ring_lo - 0.5 && elevation < bundled::RING_TICK_TOP_DEGREES + 0.5)
            || bundled::BEACONS
                .iter()
                .any(|b| d.dot(b.direction()) >= (b.radius_degrees + 0.5).to_radians().cos())
    };
    let background = |u: f32, v: f32, d: Vec3| -> Vec3 {
        let elevation = d.y.clamp(-1.0, 1.0).asin().to_degrees();
        // Distant mountains: a ridge line from noise around the horizon.
        let ridge = 0.6
            + 14.0
                * (fbm(
                    Vec3::new(d.x * 4.0, 0.0, d.z * 4.0) + Vec3::new(5.0, 0.5, 2.0),
                    4,
                ) - 0.35)
                    .max(0.0);
        if elevation < 0.0 {
            let t = (-elevation / 40.0).clamp(0.0, 1.0).sqrt();
            ground_far.lerp(ground_near, t)
        } else if elevation < ridge {
            // Haze: lighter towards the ridge top.
            mountain.lerp(horizon, 0.35 * elevation / ridge)
        } else {
            let t = (elevation / 90.0).clamp(0.0, 1.0).powf(0.6);
            let sky = horizon.lerp(zenith, t);
            let c = cloud_at(u, v);
            // Darker cloud bases: shade by the density just below.
            let below = cloud_at(u, (v + 0.004).min(1.0));
            sky.lerp(
                cloud.lerp(cloud_shadow, (below - c).clamp(0.0, 1.0) * 2.0),
                c,
            )
        }
    };
    const SUB: u32 = 4;
    RgbaImage::from_fn(w, h, |x, y| {
        let (u, v) = ((x as f32 + 0.5) / w as f32, (y as f32 + 0.5) / h as f32);
        let d = equirect_direction(u, v);
        let base = background(u, v, d);
        let colour = if near_feature(d) {
            let mut sum = Vec3::ZERO;
            for sy in 0..SUB {
                for sx in 0..SUB {
                    let su = (x as f32 + (sx as f32 + 0.5) / SUB as f32) / w as f32;
                    let sv = (y as f32 + (sy as f32 + 0.5) / SUB as f32) / h as f32;
                    sum += feature(equirect_direction(su, sv)).map_or(base, lin);
                }
            }
            sum / (SUB * SUB) as f32
        } else {
            base
        };
        Rgba([
            linear_to_srgb(colour.x),
            linear_to_srgb(colour.y),
            linear_to_srgb(colour.z),
            255,
        ])
    })
}
