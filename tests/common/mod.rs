//! Helpers shared by the integration tests: one GPU, marker scenes, pixel analysis.
#![allow(dead_code, clippy::unwrap_used, clippy::expect_used)]

pub mod fuzz;
pub mod gltf_files;
pub mod vrpn_peer;
pub mod xvfb;

use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::sync::OnceLock;

use glam::{Mat4, Vec2, Vec3};
use image::RgbaImage;

use omnicave::cave::omni::OmniSettings;
use omnicave::cave::{Cave, Head, RenderMode};
use omnicave::pano::{PanoRoute, PanoSettings, PanoStereo, Projection};
use omnicave::render::{FrameParams, Gpu, RenderSettings, Renderer, WallImages};
use omnicave::scene::Lighting;
use omnicave::scene::build::{MeshData, uv_sphere};
use omnicave::scene::{Material, Scene};
use omnicave::tess::TessSettings;

/// One device for the whole test binary (lavapipe in CI). Fails loudly if there is none:
/// a missing driver must turn CI red, not skip the rendering tests.
pub fn gpu() -> &'static Gpu {
    static GPU: OnceLock<Gpu> = OnceLock::new();
    GPU.get_or_init(|| {
        Gpu::headless().expect("a GPU adapter (lavapipe: apt-get install mesa-vulkan-drivers)")
    })
}

/// Distinct, exactly reproducible unlit colours (components 0 or 1 survive sRGB encoding
/// exactly as 0 or 255).
pub const MARKER_COLOURS: [[u8; 3]; 7] = [
    [255, 0, 0],
    [0, 255, 0],
    [0, 0, 255],
    [255, 255, 0],
    [255, 0, 255],
    [0, 255, 255],
    [255, 255, 255],
];

pub const BACKGROUND_SRGB: [f32; 3] = [0.0, 0.0, 0.0];

/// Settings for tests that match exact colours: no MSAA (edges would blend), no wireframe.
pub const NO_MSAA: RenderSettings = RenderSettings {
    msaa: 1,
    wireframe: false,
};

/// A small unlit sphere of the given radius at each point, coloured `MARKER_COLOURS[i % 7]`.
fn markers(points: &[Vec3], radius: impl Fn(Vec3) -> f32) -> Scene {
    markers_tessellated(points, radius, 12, 16)
}

/// [`markers`] with spheres of `rings` × `segments` faces. A 12 × 16 sphere seen obliquely has
/// a silhouette whose centroid sits up to 0.3 px off its centre's image; 48 × 64 brings that
/// under 0.02 px, for tests that resolve a fraction of a pixel.
pub fn markers_tessellated(
    points: &[Vec3],
    radius: impl Fn(Vec3) -> f32,
    rings: u32,
    segments: u32,
) -> Scene {
    let mut scene = Scene::default();
    for (i, p) in points.iter().enumerate() {
        let c = MARKER_COLOURS[i % MARKER_COLOURS.len()];
        let m = scene.add_material(Material::unlit(
            &format!("marker {i}"),
            c.map(|v| f32::from(v) / 255.0),
        ));
        let mesh = uv_sphere(radius(*p), rings, segments).transformed(Mat4::from_translation(*p));
        scene.add_mesh(&mesh.vertices, &mesh.indices, m);
    }
    scene
}

/// Markers whose radius grows with the distance from `viewer`.
pub fn marker_scene(points: &[Vec3], viewer: Vec3, radius_per_metre: f32) -> Scene {
    markers(points, |p| radius_per_metre * (p - viewer).length())
}

/// Like [`marker_scene`], but each marker's radius is chosen so that its image on the wall it
/// is seen through from `viewer` has about `radius_px` pixels of radius, however close the
/// viewer stands to that wall (a fixed size would shrink to nothing 0.3 m from a wall).
pub fn marker_scene_px(points: &[Vec3], viewer: Vec3, cave: &Cave, radius_px: f32) -> Scene {
    markers(points, |p| {
        let distance = (p - viewer).length();
        // Metres per pixel at the wall, and how much nearer the wall is than the marker.
        let seen_on = cave.walls.iter().find_map(|w| {
            let px = w.pixel_of_ray(viewer, p)?;
            inside(px, w.resolution, 0.0).then(|| {
                let m_per_px = w.size_m().x / w.resolution[0] as f32;
                let wall_distance = (w.wall_point_of_pixel(px) - viewer).length();
                radius_px * m_per_px * distance / wall_distance
            })
        });
        seen_on.unwrap_or(0.01 * distance)
    })
}

/// Centroid and pixel count of every marker colour present, in one pass over the image.
pub fn centroids(img: &RgbaImage) -> HashMap<[u8; 3], (Vec2, usize)> {
    let mut acc: HashMap<[u8; 3], (Vec2, usize)> = HashMap::new();
    for (x, y, p) in img.enumerate_pixels() {
        let rgb = [p[0], p[1], p[2]];
        if MARKER_COLOURS.contains(&rgb) {
            let e = acc.entry(rgb).or_insert((Vec2::ZERO, 0));
            e.0 += Vec2::new(x as f32 + 0.5, y as f32 + 0.5);
            e.1 += 1;
        }
    }
    acc.into_iter()
        .map(|(k, (sum, n))| (k, (sum / n as f32, n)))
        .collect()
}

/// Adds a mesh with an unlit colour to a scene.
pub fn add_unlit(scene: &mut Scene, mesh: &MeshData, rgb: [u8; 3]) {
    let m = scene.add_material(Material::unlit("unlit", rgb.map(|v| f32::from(v) / 255.0)));
    scene.add_mesh(&mesh.vertices, &mesh.indices, m);
}

/// Renders one frame and reads every wall's eye images back.
pub fn render(
    cave: &Cave,
    head: Head,
    mode: RenderMode,
    scene: &Scene,
    settings: RenderSettings,
) -> Vec<WallImages> {
    render_omni(cave, head, mode, scene, settings, OmniSettings::default())
}

/// The frame every test renders: IPD 0.064 m, scene placed at the CAVE, default lights.
pub fn test_frame<'a>(
    cave: &'a Cave,
    head: Head,
    mode: RenderMode,
    omni: OmniSettings,
    tess: TessSettings,
) -> FrameParams<'a> {
    FrameParams {
        cave,
        head,
        mode,
        eye_separation: 0.064,
        world_from_cave: Mat4::IDENTITY,
        lighting: Lighting::default(),
        shading: omnicave::scene::Shading::Pbr,
        shadows: omnicave::scene::shadows::ShadowSettings::default(),
        background: BACKGROUND_SRGB,
        omni,
        tess,
        sky: omnicave::sky::SkySettings::default(),
        wand_ray: None,
        animation: omnicave::scene::rig::Playback::REST,
    }
}

/// Renders with tessellation; returns the images, the per-view tessellation statistics and the
/// last view's output triangles.
pub fn render_tess(
    cave: &Cave,
    head: Head,
    mode: RenderMode,
    scene: &Scene,
    tess: TessSettings,
    capacity: Option<u32>,
) -> (
    Vec<WallImages>,
    Vec<omnicave::tess::TessStats>,
    Vec<omnicave::render::tessellator::GpuTessEntry>,
) {
    with_renderer(cave, NO_MSAA, capacity, |renderer| {
        renderer.set_scene(scene).expect("scene upload");
        renderer
            .render(&test_frame(cave, head, mode, OmniSettings::default(), tess))
            .expect("render");
        (
            renderer.read_images().expect("read back"),
            renderer.read_tess_stats().expect("stats"),
            renderer.read_tess_entries().expect("entries"),
        )
    })
}

/// A renderer for this CAVE, settings and tessellation budget: one made before, if any is
/// free (the newest few are kept for the whole test binary, in a static: a thread-local one
/// would drop them while the thread's other locals go away, which aborts). `f` leaves it as
/// it found it but for the scene: no sky, the same budget. Building a renderer's pipelines costs lavapipe
/// far more than a test frame, and the application too renders frame after frame with one
/// renderer while the head, the mode and the scene change.
pub fn with_renderer<T>(
    cave: &Cave,
    settings: RenderSettings,
    capacity: Option<u32>,
    f: impl FnOnce(&mut Renderer) -> T,
) -> T {
    type Key = (Cave, RenderSettings, Option<u32>);
    /// Renderers kept (each holds its CAVE's targets).
    const KEPT: usize = 4;
    static RENDERERS: std::sync::Mutex<Vec<(Key, Renderer)>> = std::sync::Mutex::new(Vec::new());
    let kept = || RENDERERS.lock().unwrap_or_else(|e| e.into_inner());
    let key = (cave.clone(), settings, capacity);
    let found = {
        let mut kept = kept();
        kept.iter()
            .position(|(k, _)| *k == key)
            .map(|i| kept.remove(i).1)
    };
    let mut renderer = found.unwrap_or_else(|| {
        let mut renderer = Renderer::new(gpu(), cave, settings).expect("renderer");
        if let Some(c) = capacity {
            renderer.set_tess_capacity(c);
        }
        renderer
    });
    let out = f(&mut renderer);
    let evicted = {
        let mut kept = kept();
        kept.push((key, renderer));
        (kept.len() > KEPT).then(|| kept.remove(0))
    };
    drop(evicted);
    out
}

/// As [`render`], with explicit omnistereo settings.
pub fn render_omni(
    cave: &Cave,
    head: Head,
    mode: RenderMode,
    scene: &Scene,
    settings: RenderSettings,
    omni: OmniSettings,
) -> Vec<WallImages> {
    with_renderer(cave, settings, None, |renderer| {
        renderer.set_scene(scene).expect("scene upload");
        renderer
            .render(&test_frame(cave, head, mode, omni, TessSettings::default()))
            .expect("render");
        renderer.read_images().expect("read back")
    })
}

/// The thesis CAVE at a test resolution.
pub fn cave_at(width: u32, height: u32) -> Cave {
    let mut cave = omnicave::cave::thesis_cave();
    for wall in &mut cave.walls {
        wall.resolution = [width, height];
    }
    cave
}

/// Centroid (pixel coordinates, centres at +0.5) and count of pixels of exactly `rgb`.
pub fn centroid_of(img: &RgbaImage, rgb: [u8; 3]) -> Option<(Vec2, usize)> {
    let mut sum = Vec2::ZERO;
    let mut n = 0usize;
    for (x, y, p) in img.enumerate_pixels() {
        if p[0] == rgb[0] && p[1] == rgb[1] && p[2] == rgb[2] {
            sum += Vec2::new(x as f32 + 0.5, y as f32 + 0.5);
            n += 1;
        }
    }
    (n > 0).then(|| (sum / n as f32, n))
}

/// Checks that the marker of `colour` is drawn within 1 px of `expected` and returns the error
/// in pixels; `None` (nothing checked) when `expected` is within 8 px of the border, where a
/// cut-off disc's centroid is biased. Panics, naming `what`, if the marker is missing or off.
pub fn assert_marker_at(
    found: &HashMap<[u8; 3], (Vec2, usize)>,
    colour: [u8; 3],
    expected: Vec2,
    size: [u32; 2],
    what: &str,
) -> Option<f32> {
    if !inside(expected, size, 8.0) {
        return None;
    }
    let (got, _) = *found
        .get(&colour)
        .unwrap_or_else(|| panic!("{what}: expected at {expected} but not drawn"));
    let err = (got - expected).length();
    // 1 px: the acceptance tolerance. Markers are ~3 px in radius on the wall; a sphere's image
    // centroid is offset from its centre's image by (r/d)² × its distance from the principal
    // point, < 0.3 px for the markers and walls used here.
    assert!(
        err <= 1.0,
        "{what}: drawn at {got}, expected {expected} ({err:.2} px)"
    );
    Some(err)
}

/// Whether `p` lies at least `margin` pixels inside an image of `size`.
pub fn inside(p: Vec2, size: [u32; 2], margin: f32) -> bool {
    p.x >= margin
        && p.y >= margin
        && p.x <= size[0] as f32 - margin
        && p.y <= size[1] as f32 - margin
}

/// Least-squares line y = a + b·x through points.
pub fn fit_line(points: &[(f32, f32)]) -> (f32, f32) {
    let n = points.len() as f64;
    let (sx, sy, sxx, sxy) = points.iter().fold((0.0, 0.0, 0.0, 0.0), |acc, &(x, y)| {
        let (x, y) = (f64::from(x), f64::from(y));
        (acc.0 + x, acc.1 + y, acc.2 + x * x, acc.3 + x * y)
    });
    let b = (n * sxy - sx * sy) / (n * sxx - sx * sx);
    let a = (sy - b * sx) / n;
    (a as f32, b as f32)
}

/// Receive drops the kernel counted for the UDP socket on `port` (Linux /proc/net/udp).
pub fn udp_kernel_drops(port: u16) -> Option<u64> {
    let table = std::fs::read_to_string("/proc/net/udp").ok()?;
    let port_hex = format!(":{port:04X}");
    table.lines().skip(1).find_map(|line| {
        let fields: Vec<&str> = line.split_whitespace().collect();
        let local = fields.get(1)?;
        local
            .ends_with(&port_hex)
            .then(|| fields.last()?.parse().ok())?
    })
}

/// The path of `rel` in the repository.
pub fn repo(rel: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join(rel)
}

/// A folder under the build's scratch directory (`target/tmp/<name>`), created if missing,
/// for the files a test writes.
pub fn tmp_dir(name: &str) -> PathBuf {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join(name);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// Runs the `omnicave` binary from the repository root with `args` (log level warn, no
/// colour); its exit code (-1 when a signal ended it), standard output and standard error.
/// Panics if the binary panicked (exit code 101): bad input must never panic.
pub fn run_omnicave(args: &[&str]) -> (i32, String, String) {
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_omnicave"))
        .args(args)
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .env("RUST_LOG", "warn")
        .env("NO_COLOR", "1")
        .output()
        .unwrap();
    let code = out.status.code().unwrap_or(-1);
    let stderr = String::from_utf8_lossy(&out.stderr).into_owned();
    assert_ne!(code, 101, "omnicave {args:?} panicked:\n{stderr}");
    (
        code,
        String::from_utf8_lossy(&out.stdout).into_owned(),
        stderr,
    )
}

/// A mono panorama of `projection` by `route` over `fov_deg` (degrees), turned 20° right,
/// 720×360 pixels, 512-pixel cube faces.
pub fn pano_settings(projection: Projection, route: PanoRoute, fov_deg: [f32; 2]) -> PanoSettings {
    PanoSettings {
        projection,
        h_fov: fov_deg[0].to_radians(),
        v_fov: fov_deg[1].to_radians(),
        route,
        stereo: PanoStereo::Mono,
        yaw: 20f32.to_radians(),
        size: [720, 360],
        cube_size: 512,
    }
}

/// `../shared/corpus` (third-party glTF models), or `None` with a line saying the tests that
/// need it skip; under CI (which has it) a missing corpus fails instead.
#[allow(dead_code, clippy::print_stdout)]
pub fn corpus() -> Option<PathBuf> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/corpus");
    if dir.is_dir() {
        return Some(dir);
    }
    let msg = format!("SKIPPED: {} not found (the shared corpus)", dir.display());
    assert!(
        std::env::var_os("CI").is_none(),
        "{msg}, and CI must not skip"
    );
    println!("{msg}");
    None
}
