//! The `omnicave` command line: the CAVE application (`run`, the default), headless `render`
//! and `bench`.

use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::Context;
use clap::{Parser, Subcommand};
use glam::Vec3;
use tracing_indicatif::span_ext::IndicatifSpanExt;
use tracing_subscriber::layer::SubscriberExt;
use tracing_subscriber::util::SubscriberInitExt;

use omnicave::cave::RenderMode;
use omnicave::cave::omni::{PoleMerge, WarpVariant};
use omnicave::config::AppMode;
use omnicave::headless::{self, Overrides};
use omnicave::output::formats::StereoFormat;
use omnicave::scene::{SceneFit, Shading};
use omnicave::sky::SkyMode;
use omnicave::tess::{Criterion, MAX_DEPTH_LIMIT, parse_criterion};
use omnicave::tracking::sim::{Pattern, SimForm, SimOptions};
use omnicave::tracking::{Calibration, OscMapping, QuaternionOrder};

#[derive(Debug, Parser)]
#[command(
    name = "omnicave",
    version,
    about = "Omnidirectional stereo rendering for CAVEs"
)]
struct Cli {
    /// Without a command: the bundled scene in the desktop preview (`run --preview`).
    #[command(subcommand)]
    command: Option<Command>,
    /// Also write the log to FILE (appended, without colours), for a CAVE's unattended runs.
    #[arg(long, global = true, value_name = "FILE")]
    log_file: Option<PathBuf>,
}

#[derive(Debug, Subcommand)]
enum Command {
    /// Open the application: a borderless window per wall (CAVE mode) or the unfolded preview,
    /// with the control panel.
    Run(RunArgs),
    /// Render one frame headless: every wall for both eyes, written as PNG files.
    Render(RenderArgs),
    /// Measure the frame time of every method in one run; write results.csv and report.md.
    Bench(BenchArgs),
    /// Where guests may stand: each method's disparity distortion for viewers away from the
    /// assumed head, over the floor (heat maps, grid.csv, the sweet area per method).
    Guests(GuestsArgs),
    /// Send a moving head over OSC (circle, figure eight or a recorded path), as a tracker
    /// would: to test head tracking without one.
    TrackSim(TrackSimArgs),
    /// List the monitors `[[wall]] monitor` can name (its index or its name), with their
    /// sizes, positions and refresh rates.
    Monitors,
    /// Print a shell completion script (e.g. `omnicave completions bash > omnicave.bash`).
    Completions {
        /// The shell to complete in.
        #[arg(value_enum)]
        shell: clap_complete::Shell,
    },
    /// Config file tools.
    #[command(subcommand)]
    Config(ConfigCommand),
    /// Regenerate the book's reference pages (docs/src) from the code, or with --check say
    /// which committed page is stale. For developers; run in the repository.
    #[command(hide = true)]
    Docs(DocsArgs),
}

#[derive(Debug, clap::Args)]
struct DocsArgs {
    /// Compare instead of writing: fail, naming each page that differs from the code.
    #[arg(long)]
    check: bool,
    /// The repository's root.
    #[arg(long, default_value = ".")]
    repo: PathBuf,
}

#[derive(Debug, Subcommand)]
enum ConfigCommand {
    /// Print the config file's JSON Schema (what `config/omnicave.schema.json` holds), for
    /// editors that validate and complete TOML.
    Schema,
    /// Convert the walls of an Equalizer, CalVR, nDisplay (JSON or legacy .cfg), Vrui or MinVR
    /// file into omnicave's `[[wall]]` tables (CAVE space: metres, +y up).
    Import(ImportArgs),
}

#[derive(Debug, clap::Args)]
struct ImportArgs {
    /// The file to read.
    file: PathBuf,
    /// Its format; default: from its content, else its extension (.eqc, .ndisplay/.json,
    /// .minvr/.vrsetup).
    #[arg(long)]
    format: Option<omnicave::config::import::ImportFormat>,
    /// The file's length unit; default: the file's own (Vrui's inchScale or meterScale), else
    /// the format's (Equalizer m, CalVR mm, nDisplay JSON cm, nDisplay .cfg m, Vrui inch,
    /// MinVR foot).
    #[arg(long)]
    units: Option<omnicave::cave::placement::LengthUnit>,
    /// Vrui: the root section (installation) to read, where the file has several.
    #[arg(long)]
    section: Option<String>,
    /// Print each wall's size, centre and normal and how the walls meet at their edges (gaps
    /// and overlaps in mm); write nothing.
    #[arg(long, conflicts_with_all = ["base", "output"])]
    check: bool,
    /// Pixels of a wall whose window or viewport the file does not give, WxH.
    #[arg(long, value_parser = parse_size, default_value = "1920x1080")]
    resolution: [u32; 2],
    /// Write a whole config: this one, with its walls replaced (comments kept).
    #[arg(long, value_name = "CONFIG")]
    base: Option<PathBuf>,
    /// Where to write; default: standard output.
    #[arg(long, short)]
    output: Option<PathBuf>,
}

#[derive(Debug, clap::Args)]
// `--ipd -1` is a value out of range, not an unknown flag `-1`.
#[command(allow_negative_numbers = true)]
struct TrackSimArgs {
    /// Where the application listens: HOST:PORT.
    #[arg(long, default_value = "127.0.0.1:7000")]
    target: String,
    /// A config whose [tracking] addresses, quaternion order, rigid body and calibration to
    /// use (the path is given in CAVE space and sent in the tracker's frame).
    #[arg(long)]
    config: Option<PathBuf>,
    /// The path to move along (or --replay FILE).
    #[arg(long, value_enum, default_value_t = PatternName::Circle)]
    pattern: PatternName,
    /// Replay a recorded path instead: CSV lines t,x,y,z[,qw,qx,qy,qz] (s, CAVE m), looping.
    #[arg(long, value_name = "CSV")]
    replay: Option<PathBuf>,
    /// Centre of the circle or figure eight, CAVE metres X,Y,Z; default: the config's head.
    #[arg(long, value_parser = parse_vec3, allow_hyphen_values = true)]
    centre: Option<Vec3>,
    /// Radius (half-width of the figure eight), metres.
    #[arg(long, default_value_t = 0.5, value_parser = parse_radius)]
    radius: f32,
    /// Seconds per lap.
    #[arg(long, default_value_t = 8.0, value_parser = parse_period)]
    period: f32,
    /// Packets per second.
    #[arg(long, default_value_t = 60.0, value_parser = parse_rate)]
    rate: f64,
    /// Stop after SECONDS (default: until Ctrl+C).
    #[arg(long, value_name = "SECONDS", value_parser = parse_seconds)]
    duration: Option<f64>,
    /// Message form: position, pose (x y z + quaternion), bundle (position + orientation
    /// messages), euler (position + yaw pitch roll), natnet (/rigidbody <id> position/quat).
    #[arg(long, value_enum, default_value_t = SimForm::Bundle)]
    form: SimForm,
    /// Quaternion order to send (default: the config's).
    #[arg(long, value_enum)]
    quaternion_order: Option<QuaternionOrder>,
    /// After every pose packet, send N hostile datagrams (random bytes, cut packets, huge and
    /// non-finite coordinates): a robustness soak (scripts/soak.sh).
    #[arg(long, value_name = "N", default_value_t = 0, value_parser = clap::value_parser!(u32).range(0..=100))]
    junk: u32,
}

/// `track-sim --pattern`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
enum PatternName {
    Circle,
    FigureEight,
    Still,
}

fn parse_radius(s: &str) -> Result<f32, String> {
    let v = parse_finite(s, "metres")?;
    if (0.0..=100.0).contains(&v) {
        Ok(v)
    } else {
        Err(format!("radius {v} m is outside 0..100 m"))
    }
}

fn parse_period(s: &str) -> Result<f32, String> {
    let v = parse_finite(s, "seconds")?;
    if (0.01..=1e6).contains(&v) {
        Ok(v)
    } else {
        Err(format!("period {v} s is outside 0.01..1e6 s"))
    }
}

fn parse_rate(s: &str) -> Result<f64, String> {
    let v = f64::from(parse_finite(s, "packets per second")?);
    if (0.1..=10_000.0).contains(&v) {
        Ok(v)
    } else {
        Err(format!("rate {v} Hz is outside 0.1..10000 Hz"))
    }
}

fn parse_listen(s: &str) -> Result<std::net::SocketAddr, String> {
    s.trim().parse().map_err(|_| {
        format!("'{s}' is not an address:port to listen on (e.g. 0.0.0.0:7000, 127.0.0.1:0)")
    })
}

#[derive(Debug, clap::Args)]
// `--ipd -1` is a value out of range, not an unknown flag `-1`.
#[command(allow_negative_numbers = true)]
struct RunArgs {
    /// Configuration (TOML); its [app] section says CAVE or preview, monitors and formats.
    #[arg(long, default_value = "config/cave.toml")]
    config: PathBuf,
    /// glTF scene instead of the config's, or "none" for the sky alone.
    #[arg(long)]
    scene: Option<PathBuf>,
    /// Force the desktop preview (walls unfolded in one window).
    #[arg(long, conflicts_with = "cave")]
    preview: bool,
    /// Force CAVE mode (a window per wall).
    #[arg(long)]
    cave: bool,
    /// Log frame statistics (fps, CPU and GPU frame time) every SECONDS.
    #[arg(long, value_name = "SECONDS", value_parser = parse_seconds)]
    stats_every: Option<f64>,
    /// Quit by itself after SECONDS (demos, soak tests).
    #[arg(long, value_name = "SECONDS", value_parser = parse_seconds)]
    quit_after: Option<f64>,
    /// Listen for OSC head tracking on ADDRESS:PORT (switches tracking on; port 0 picks a free
    /// port, which is logged).
    #[arg(long, value_name = "ADDRESS:PORT", value_parser = parse_listen)]
    osc_listen: Option<std::net::SocketAddr>,
    /// Cluster mode: run as one rank of an `mpirun` job (rank 0 the master with the panel and
    /// the input; each wall on the rank its `[[wall]] node` names). Needs a build with
    /// `--features cluster`.
    #[arg(long)]
    cluster: bool,
    /// Write this process's walls' eye images, the frame's state and its settings to
    /// DIR/frame-NNNNNN/ every --record-every frames (to check a cluster against single-process
    /// mode; each recorded frame is read back from the GPU, which slows it).
    #[arg(long, value_name = "DIR")]
    record: Option<PathBuf>,
    /// With --record: record every Nth frame (frame numbers from the master in a cluster).
    #[arg(long, value_name = "N", default_value_t = 1, value_parser = clap::value_parser!(u64).range(1..))]
    record_every: u64,
}

/// `bench --cluster`: this rank's part of the cluster bench (rank 0 writes the report).
fn cluster_bench(args: BenchArgs) -> anyhow::Result<()> {
    #[cfg(feature = "cluster")]
    {
        let transport = omnicave::cluster::mpi_transport::MpiTransport::init()?;
        let files = omnicave::bench::cluster::run_cluster(
            &omnicave::bench::cluster::ClusterBenchOptions {
                config: args.config,
                scene: args.scene.first().cloned(),
                frames: args
                    .frames
                    .map_or(if args.quick { 20 } else { 200 }, |f| f as usize),
                size: args.size,
                out: args.out,
            },
            Box::new(transport),
        )
        .context("cluster bench failed")?;
        for f in files {
            tracing::info!("wrote {}", f.display());
        }
        Ok(())
    }
    #[cfg(not(feature = "cluster"))]
    {
        let _ = args;
        Err(omnicave::cluster::ClusterError::NotBuilt.into())
    }
}

fn parse_seconds(s: &str) -> Result<f64, String> {
    let v: f64 = s
        .trim()
        .parse()
        .map_err(|_| format!("'{s}' is not a number of seconds"))?;
    if v.is_finite() && v > 0.0 && v <= 1e6 {
        Ok(v)
    } else {
        Err(format!("{v} seconds is outside 0..1e6"))
    }
}

#[derive(Debug, clap::Args)]
// `--ipd -1` is a value out of range, not an unknown flag `-1`.
#[command(allow_negative_numbers = true)]
struct BenchArgs {
    /// CAVE configuration (TOML): walls, resolution, MSAA, head.
    #[arg(long, default_value = "config/cave.toml")]
    config: PathBuf,
    /// A scene to measure (repeatable); default: the config's scene, the bundled city and the
    /// bundled atrium.
    #[arg(long)]
    scene: Vec<PathBuf>,
    /// Sky for the sky methods; default: the config's, else the bundled one.
    #[arg(long)]
    skybox: Option<PathBuf>,
    /// Fewer frames and head positions.
    #[arg(long)]
    quick: bool,
    /// Timed frames per method and case.
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..=1000))]
    frames: Option<u32>,
    /// Pixel size of every wall image, WxH (overrides the config; --quick: 192x108).
    #[arg(long, value_parser = parse_size)]
    size: Option<[u32; 2]>,
    /// Output folder.
    #[arg(long, default_value = "out/bench")]
    out: PathBuf,
    /// Measure only this method (repeatable): a name as the report writes it, or any mode
    /// with any criterion, e.g. 'omni-offaxis + tess error:3'. Plain stereo, the reference,
    /// always runs; the panorama methods do not.
    #[arg(long = "method", conflicts_with_all = ["stability", "panorama_only"])]
    methods: Vec<String>,
    /// Run the stability sweep instead (head positions over the whole CAVE, every warp
    /// configuration, holes and popping of every render method): writes stability.md,
    /// stability.csv and stability-rendered.csv. With --quick, every ninth head position is
    /// rendered; --size sets the rendered wall size (default 320x180).
    #[arg(long)]
    stability: bool,
    /// Only the panorama methods (geometric and image routes against the CPU ray caster):
    /// panorama.csv, report.md and the 360° images.
    #[arg(long, conflicts_with = "stability")]
    panorama_only: bool,
    /// Cluster mode, under `mpirun`: every rank renders its walls (`[[wall]] node`) in
    /// lockstep, then the messages alone; rank 0 writes cluster.md and cluster.csv (what the
    /// cluster costs per frame). Needs a build with `--features cluster`.
    #[arg(long, conflicts_with_all = ["stability", "panorama_only", "methods"])]
    cluster: bool,
}

#[derive(Debug, clap::Args)]
// `--ipd -1` is a value out of range, not an unknown flag `-1`.
#[command(allow_negative_numbers = true)]
struct RenderArgs {
    /// CAVE configuration (TOML).
    #[arg(long, default_value = "config/cave.toml")]
    config: PathBuf,
    /// glTF scene (.gltf or .glb), or "none" for the sky alone; default: the config's [scene]
    /// path.
    #[arg(long)]
    scene: Option<PathBuf>,
    /// Render mode; default: the config's.
    #[arg(long, value_enum)]
    mode: Option<RenderMode>,
    /// Surface shading; default: the config's.
    #[arg(long, value_enum)]
    shading: Option<Shading>,
    /// Where the model goes: as-authored, or floor (centred on the CAVE's floor).
    #[arg(long, value_enum)]
    fit: Option<SceneFit>,
    /// Scale the model so that its largest side is this many metres (0: the file's units).
    #[arg(long)]
    size_m: Option<f32>,
    /// Then move the model by X,Y,Z metres (e.g. 0,0.9,-1: on a table ahead).
    #[arg(long, value_parser = parse_vec3, allow_hyphen_values = true)]
    scene_offset: Option<glam::Vec3>,
    /// Draw every material double-sided (content wound the wrong way).
    #[arg(long)]
    double_sided: bool,
    /// Start at a camera of the scene file (its name or index): the head stands there.
    #[arg(long)]
    camera: Option<String>,
    /// Head position in CAVE space, metres: X,Y,Z.
    #[arg(long, value_parser = parse_vec3, allow_hyphen_values = true)]
    head: Option<Vec3>,
    /// Head yaw in degrees (positive turns left; 0 faces the front wall), for tracked-stereo.
    #[arg(long, value_parser = parse_yaw, allow_hyphen_values = true)]
    head_yaw: Option<f32>,
    /// Eye separation in metres.
    #[arg(long, value_parser = parse_ipd)]
    ipd: Option<f32>,
    /// Pixel size of every wall image, WxH (overrides the config).
    #[arg(long, value_parser = parse_size)]
    size: Option<[u32; 2]>,
    /// MSAA samples: 1 or 4.
    #[arg(long, value_parser = parse_msaa)]
    msaa: Option<u32>,
    /// Draw the wireframe overlay.
    #[arg(long)]
    wireframe: bool,
    /// Omnistereo warp: similar-triangles (stable) or intersection-point (to show its failures).
    #[arg(long, value_enum)]
    warp: Option<WarpVariant>,
    /// Omnistereo pole merge: START,END elevation in degrees (e.g. 60,75), or "off".
    #[arg(long, value_parser = parse_pole_merge)]
    pole_merge: Option<PoleMergeArg>,
    /// Adaptive tessellation before the warp: none, uniform:N, edge:PX, sphere:PX or error:PX.
    #[arg(long, value_parser = parse_tess)]
    tess: Option<TessArg>,
    /// Deepest subdivision, 0–16 (default: the config's, normally 12 = up to 4096 segments
    /// per edge; hardware tessellators stop at 6 = 64).
    #[arg(long, value_parser = parse_depth)]
    tess_max_depth: Option<u32>,
    /// Sky: an equirectangular image (PNG/JPEG/HDR) or a folder of six faces, or "none".
    #[arg(long, value_parser = parse_skybox)]
    skybox: Option<SkyboxArg>,
    /// Sky mode (auto follows the render mode).
    #[arg(long, value_enum)]
    skybox_mode: Option<SkyMode>,
    /// Also write each wall in a stereo output format (repeatable).
    #[arg(long = "format", value_enum)]
    formats: Vec<StereoFormat>,
    /// What to render: every wall with both eyes, or the panorama (the wide field of view, as
    /// the config's [panorama] section and the flags below say).
    #[arg(long, value_enum, default_value_t = ViewArg::Walls)]
    view: ViewArg,
    /// Panorama projection.
    #[arg(long, value_enum)]
    projection: Option<omnicave::pano::Projection>,
    /// Panorama route: geometric (equirectangular and Hammer) or image.
    #[arg(long, value_enum)]
    pano_route: Option<omnicave::pano::PanoRoute>,
    /// Panorama stereo (geometric route).
    #[arg(long, value_enum)]
    pano_stereo: Option<omnicave::pano::PanoStereoKind>,
    /// Panorama field of view in degrees: H,V (e.g. 360,180).
    #[arg(long, value_parser = parse_fov)]
    fov: Option<[f32; 2]>,
    /// Panorama turn from the navigation direction, degrees, positive to the right.
    #[arg(long, value_parser = parse_yaw, allow_hyphen_values = true)]
    pano_yaw: Option<f32>,
    /// Panorama image size, WxH.
    #[arg(long, value_parser = parse_size)]
    pano_size: Option<[u32; 2]>,
    /// Render the scene's animation at this time, seconds (wrapped into the animation as the
    /// config's [animation] repeat says): the same time gives the same images.
    #[arg(long, value_parser = parse_time)]
    time: Option<f32>,
    /// The animation to pose the scene by, by name (default: the config's, else the file's
    /// first).
    #[arg(long)]
    animation: Option<String>,
    /// Show what a guest standing at X,Y,Z (metres, the eyes' midpoint) sees of the walls
    /// rendered for the head, beside what tracked stereo for them would show (seen-*.png,
    /// correct-*.png, compare.png, viewer.md) instead of the wall images.
    #[arg(long, value_parser = parse_vec3, allow_hyphen_values = true, conflicts_with = "view")]
    viewer: Option<Vec3>,
    /// The guest's facing in degrees (positive turns left; 0 faces the front wall); default:
    /// the head's yaw.
    #[arg(long, value_parser = parse_yaw, allow_hyphen_values = true, requires = "viewer")]
    viewer_yaw: Option<f32>,
    /// The guest's eye images' field of view in degrees, H,V (each up to 170).
    #[arg(long, value_parser = parse_fov, requires = "viewer")]
    viewer_fov: Option<[f32; 2]>,
    /// The guest's eye images' size, WxH.
    #[arg(long, value_parser = parse_size, requires = "viewer")]
    viewer_size: Option<[u32; 2]>,
    /// Output folder.
    #[arg(long)]
    out: PathBuf,
}

#[derive(Debug, clap::Args)]
struct GuestsArgs {
    /// CAVE configuration (TOML).
    #[arg(long, default_value = "config/cave.toml")]
    config: PathBuf,
    /// glTF scene whose visible surface is judged; default: the config's [scene] path.
    #[arg(long, conflicts_with = "shells")]
    scene: Option<PathBuf>,
    /// Judge shells of points at these distances (metres) around the assumed head instead of
    /// a scene, e.g. 0.5,1,2,4.
    #[arg(long, value_delimiter = ',', num_args = 1.., allow_negative_numbers = true)]
    shells: Option<Vec<f64>>,
    /// Scene points judged: rays cast from the assumed head (or points on the shells).
    #[arg(long, default_value_t = 10_000)]
    points: usize,
    /// Methods: render mode, optionally @head (the tracked head, default) or @centre, e.g.
    /// tracked-stereo,stereo,omni-onaxis@centre. Default: tracked-stereo, stereo, omni-onaxis,
    /// omni-offaxis for the head and omni-onaxis@centre.
    #[arg(long, value_delimiter = ',', value_parser = omnicave::guests::Method::parse)]
    methods: Vec<omnicave::guests::Method>,
    /// Grid cell size on the floor, metres.
    #[arg(long, default_value_t = 0.1)]
    step: f64,
    /// Viewer eye heights in metres (a map each), e.g. 1.2,1.7; default: the head's.
    #[arg(long, value_delimiter = ',')]
    eye_heights: Vec<f64>,
    /// Tracked head position in CAVE space, metres: X,Y,Z.
    #[arg(long, value_parser = parse_vec3, allow_hyphen_values = true)]
    head: Option<Vec3>,
    /// Tracked head yaw in degrees (positive turns left), for tracked-stereo.
    #[arg(long, value_parser = parse_yaw, allow_hyphen_values = true)]
    head_yaw: Option<f32>,
    /// Eye separation in metres (default: the config's).
    #[arg(long)]
    ipd: Option<f64>,
    /// Sweet area limit: 95th percentile of vertical disparity, arcmin.
    #[arg(long, default_value_t = 20.0)]
    vertical_arcmin: f64,
    /// Sweet area limit: 95th percentile of the direction error, degrees.
    #[arg(long, default_value_t = 1.0)]
    direction_degrees: f64,
    /// Draw wall points at their pixel's centre (the walls' resolution quantises disparity).
    #[arg(long)]
    quantise: bool,
    /// Also sweep the sweet area against CAVE size, head distance to the front wall and
    /// resolution (sweep.csv and charts).
    #[arg(long)]
    sweep: bool,
    /// Worker threads (0: every core; at most 64).
    #[arg(long, default_value_t = 0)]
    threads: usize,
    /// Output folder.
    #[arg(long)]
    out: PathBuf,
}

/// `render --view`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
enum ViewArg {
    Walls,
    Panorama,
}

fn parse_fov(s: &str) -> Result<[f32; 2], String> {
    let parts: Vec<&str> = s.split(',').map(str::trim).collect();
    let [h, v] = parts.as_slice() else {
        return Err(format!("expected H,V in degrees (e.g. 360,180), got '{s}'"));
    };
    let parse = |t: &str, what: &str, max: f32| -> Result<f32, String> {
        let x: f32 = t
            .parse()
            .map_err(|_| format!("{what} field of view '{t}' is not a number"))?;
        if x.is_finite() && (1.0..=max).contains(&x) {
            Ok(x)
        } else {
            Err(format!(
                "{what} field of view {x}° must be 1 to {max} degrees"
            ))
        }
    };
    Ok([parse(h, "horizontal", 360.0)?, parse(v, "vertical", 360.0)?])
}

/// `--skybox` value (a newtype: clap reads `Option<Option<T>>` as an optional-value flag).
#[derive(Debug, Clone)]
struct SkyboxArg(Option<PathBuf>);

fn parse_skybox(s: &str) -> Result<SkyboxArg, String> {
    match s.trim() {
        "" => Err("expected a sky file or folder, or 'none'".into()),
        "none" => Ok(SkyboxArg(None)),
        path => Ok(SkyboxArg(Some(PathBuf::from(path)))),
    }
}

/// `--pole-merge` value: angles, or `None` for "off" (a newtype, because clap reads
/// `Option<Option<T>>` as a flag with an optional value).
#[derive(Debug, Clone, Copy)]
struct PoleMergeArg(Option<PoleMerge>);

fn parse_pole_merge(s: &str) -> Result<PoleMergeArg, String> {
    if s.trim() == "off" {
        return Ok(PoleMergeArg(None));
    }
    let (a, b) = s
        .split_once(',')
        .ok_or_else(|| format!("expected START,END in degrees or 'off', got '{s}'"))?;
    let start = parse_finite(a, "degrees")?;
    let end = parse_finite(b, "degrees")?;
    if !(0.0..=90.0).contains(&start) || !(start..=90.0).contains(&end) {
        return Err(format!(
            "pole merge needs 0 <= START <= END <= 90 degrees, got {start},{end}"
        ));
    }
    Ok(PoleMergeArg(Some(PoleMerge {
        start_degrees: start,
        end_degrees: end,
    })))
}

/// `--tess` value (a newtype: clap reads `Option<Option<T>>` as an optional-value flag).
#[derive(Debug, Clone, Copy)]
struct TessArg(Option<Criterion>);

fn parse_tess(s: &str) -> Result<TessArg, String> {
    parse_criterion(s).map(TessArg)
}

fn parse_depth(s: &str) -> Result<u32, String> {
    let d: u32 = s
        .trim()
        .parse()
        .map_err(|_| format!("'{s}' is not a whole number of levels"))?;
    if d > MAX_DEPTH_LIMIT {
        return Err(format!("depth {d} exceeds the limit of {MAX_DEPTH_LIMIT}"));
    }
    Ok(d)
}

fn parse_finite(s: &str, what: &str) -> Result<f32, String> {
    let v: f32 = s
        .trim()
        .parse()
        .map_err(|_| format!("'{s}' is not a number ({what})"))?;
    if v.is_finite() {
        Ok(v)
    } else {
        Err(format!("'{s}' is not a finite number ({what})"))
    }
}

fn parse_vec3(s: &str) -> Result<Vec3, String> {
    let parts: Vec<&str> = s.split(',').collect();
    if parts.len() != 3 {
        return Err(format!("expected X,Y,Z in metres, got '{s}'"));
    }
    let mut v = [0.0; 3];
    for (slot, part) in v.iter_mut().zip(&parts) {
        *slot = parse_finite(part, "head coordinate")?;
    }
    Ok(Vec3::from(v))
}

fn parse_yaw(s: &str) -> Result<f32, String> {
    let v = parse_finite(s, "degrees")?;
    if v.abs() > 360.0 {
        return Err(format!("yaw {v} is outside -360..360 degrees"));
    }
    Ok(v)
}

fn parse_time(s: &str) -> Result<f32, String> {
    let v = parse_finite(s, "seconds")?;
    if !(0.0..=1e6).contains(&v) {
        return Err(format!("time {v} s is outside 0..1000000 s"));
    }
    Ok(v)
}

fn parse_ipd(s: &str) -> Result<f32, String> {
    let v = parse_finite(s, "metres")?;
    if !(0.0..=0.5).contains(&v) {
        return Err(format!("eye separation {v} m is outside 0..0.5 m"));
    }
    Ok(v)
}

fn parse_size(s: &str) -> Result<[u32; 2], String> {
    let (w, h) = s
        .split_once(['x', 'X'])
        .ok_or_else(|| format!("expected WxH (e.g. 1280x720), got '{s}'"))?;
    let dim = |d: &str| -> Result<u32, String> {
        let v: u32 = d
            .trim()
            .parse()
            .map_err(|_| format!("'{d}' is not a whole number of pixels"))?;
        if (1..=8192).contains(&v) {
            Ok(v)
        } else {
            Err(format!("{v} pixels is outside 1..=8192"))
        }
    };
    Ok([dim(w)?, dim(h)?])
}

fn parse_msaa(s: &str) -> Result<u32, String> {
    match s.trim() {
        "1" => Ok(1),
        "4" => Ok(4),
        _ => Err(format!("MSAA must be 1 or 4, got '{s}'")),
    }
}

fn main() -> ExitCode {
    // First: a SIGTERM while the scene loads must not kill the process by signal.
    let signal_handler =
        omnicave::signals::install(omnicave::signals::command_polls(std::env::args()));
    let cli = match Cli::try_parse() {
        Ok(cli) => cli,
        Err(e) => {
            // clap's own error, with a huge value cut (it would echo it whole); help and
            // version text go out as they are.
            let text = e.render().to_string();
            if e.use_stderr() {
                eprint!("{}", omnicave::messages::cut_long_lines(&text));
            } else {
                let _ = write_stdout(text.as_bytes());
            }
            return ExitCode::from(u8::try_from(e.exit_code()).unwrap_or(2));
        }
    };
    let log_file = match &cli.log_file {
        None => None,
        Some(path) => match std::fs::OpenOptions::new()
            .create(true)
            .append(true)
            .open(path)
        {
            Ok(file) => Some(std::sync::Mutex::new(file)),
            Err(e) => {
                eprintln!("error: cannot open the log file {}: {e}", path.display());
                return ExitCode::FAILURE;
            }
        },
    };
    // Log lines go through the progress bars' layer, so they print above a bar, not inside it.
    let bars = tracing_indicatif::IndicatifLayer::new();
    tracing_subscriber::registry()
        .with(
            tracing_subscriber::EnvFilter::try_from_default_env()
                .unwrap_or_else(|_| "info,wgpu_core=warn,wgpu_hal=warn,naga=warn".into()),
        )
        .with(tracing_subscriber::fmt::layer().with_writer(bars.get_stderr_writer()))
        .with(log_file.map(|file| {
            tracing_subscriber::fmt::layer()
                .with_ansi(false)
                .with_writer(file)
        }))
        .with(bars.with_span_field_formatter(tracing_subscriber::fmt::format::DefaultFields::new()))
        .init();
    if let Err(e) = signal_handler {
        tracing::warn!("no signal handler ({e}): SIGTERM ends the process at once");
    }
    match run(cli) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            // One write: several processes may share this stderr (mpirun tags each write).
            let text = format!(
                "error: {}\n",
                omnicave::messages::cut_long_lines(&error_text(&e))
            );
            let _ = std::io::Write::write_all(&mut std::io::stderr().lock(), text.as_bytes());
            ExitCode::FAILURE
        }
    }
}

/// A progress bar with an elapsed time and an ETA for a long job (drawn only on a terminal).
#[derive(Debug)]
struct Progress {
    span: tracing::Span,
}

impl Progress {
    fn new(job: &'static str) -> Self {
        let span = tracing::info_span!("progress", job);
        span.pb_set_style(
            &indicatif::ProgressStyle::with_template(
                "{span_child_prefix}[{bar:30}] {pos}/{len} {elapsed_precise} (ETA {eta}) {wide_msg}",
            )
            .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar())
            .progress_chars("#>-"),
        );
        span.pb_start();
        Self { span }
    }

    fn show(&mut self, done: usize, total: usize, what: &str) {
        self.span.pb_set_length(total as u64);
        self.span.pb_set_position(done as u64);
        self.span.pb_set_message(what);
    }
}

/// Writes a command's output to standard output; a reader that closed the pipe early (`| head`)
/// is not an error.
/// `config import`: the walls, as tables or in a whole config, checked by loading the result.
fn import_walls(args: &ImportArgs) -> anyhow::Result<()> {
    use omnicave::config::import;
    let import =
        import::import_walls(&args.file, args.format, args.units, args.section.as_deref())?;
    tracing::info!(
        "{}: converted from {}",
        args.file.display(),
        import.conversion
    );
    for note in &import.notes {
        tracing::warn!("{}: {note}", args.file.display());
    }
    if args.check {
        return write_stdout(import::check_report(&import.walls).as_bytes());
    }
    let walls = &import.walls;
    let text = match &args.base {
        None => import::walls_toml(&import, args.resolution, &args.file),
        Some(base) => {
            let base_text = omnicave::read_capped::read_capped_text(
                base,
                omnicave::read_capped::MAX_CONFIG_BYTES,
                "config files",
            )
            .with_context(|| format!("cannot read {}", base.display()))?;
            let text = import::replace_walls(&base_text, &import, args.resolution, &args.file)
                .map_err(|e| anyhow::anyhow!("{}: {e}", base.display()))?;
            // The result must load: its walls are checked as any config's are.
            omnicave::config::Config::from_toml(&text, base)
                .with_context(|| format!("the walls of {}", args.file.display()))?;
            text
        }
    };
    for w in walls {
        tracing::info!(
            "wall {}: {:.3} × {:.3} m",
            w.name,
            (w.lower_right - w.lower_left).length(),
            (w.upper_left - w.lower_left).length()
        );
    }
    match &args.output {
        Some(path) => {
            std::fs::write(path, text).with_context(|| format!("cannot write {}", path.display()))
        }
        None => write_stdout(text.as_bytes()),
    }
}

fn write_stdout(bytes: &[u8]) -> anyhow::Result<()> {
    use std::io::Write;
    let mut out = std::io::stdout().lock();
    match out.write_all(bytes).and_then(|()| out.flush()) {
        Err(e) if e.kind() != std::io::ErrorKind::BrokenPipe => {
            Err(e).context("cannot write to standard output")
        }
        _ => Ok(()),
    }
}

/// The error and its causes on one line, each said once (an I/O error that a message already
/// quotes is not repeated).
fn error_text(e: &anyhow::Error) -> String {
    let mut text = String::new();
    for cause in e.chain() {
        let part = cause.to_string();
        if text.contains(&part) {
            continue;
        }
        if !text.is_empty() {
            text.push_str(": ");
        }
        text.push_str(&part);
    }
    text
}

/// The desktop config: beside the working directory's `config/`, else the source tree's.
fn default_desktop_config() -> PathBuf {
    let local = PathBuf::from("config/desktop.toml");
    if local.exists() {
        return local;
    }
    let bundled = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("config/desktop.toml");
    if bundled.exists() { bundled } else { local }
}

fn run(cli: Cli) -> anyhow::Result<()> {
    let command = cli.command.unwrap_or_else(|| {
        Command::Run(RunArgs {
            config: default_desktop_config(),
            scene: None,
            preview: true,
            cave: false,
            stats_every: None,
            quit_after: None,
            osc_listen: None,
            cluster: false,
            record: None,
            record_every: 1,
        })
    });
    match command {
        Command::Run(args) => run_app(args),
        Command::Bench(args) if args.cluster => cluster_bench(args),
        Command::Bench(args) if args.stability => bench_stability(args),
        Command::Bench(args) => bench(args),
        Command::TrackSim(args) => track_sim(args),
        Command::Monitors => monitors(),
        Command::Completions { shell } => {
            // Into memory first: clap_complete panics on a failed write (a closed pipe).
            let mut script = Vec::new();
            let mut command = <Cli as clap::CommandFactory>::command();
            clap_complete::generate(shell, &mut command, "omnicave", &mut script);
            write_stdout(&script)
        }
        Command::Config(ConfigCommand::Schema) => {
            write_stdout(omnicave::config::schema::json_schema_text().as_bytes())
        }
        Command::Config(ConfigCommand::Import(args)) => import_walls(&args),
        Command::Render(args) => render(args),
        Command::Guests(args) => guests(args),
        Command::Docs(args) => docs(&args),
    }
}

/// `run`: the application.
fn run_app(args: RunArgs) -> anyhow::Result<()> {
    let mode = if args.preview {
        Some(AppMode::Preview)
    } else if args.cave {
        Some(AppMode::Cave)
    } else {
        None
    };
    omnicave::app::run(omnicave::app::RunOptions {
        config: args.config,
        scene: args.scene,
        mode,
        stats_every: args.stats_every,
        quit_after: args.quit_after,
        osc_listen: args.osc_listen,
        cluster: args.cluster,
        record: args.record,
        record_every: args.record_every,
    })
    .context("omnicave stopped")?;
    Ok(())
}

/// `bench --stability`: the stability sweep.
fn bench_stability(args: BenchArgs) -> anyhow::Result<()> {
    let mut bar = Progress::new("stability sweep");
    let files = omnicave::bench::run_stability(
        &omnicave::bench::StabilityOptions {
            config: args.config,
            out: args.out,
            quick: args.quick,
            size: args.size,
        },
        &mut |done, total, what| bar.show(done, total, what),
    )
    .context("stability sweep failed")?;
    for f in files {
        tracing::info!("wrote {}", f.display());
    }
    Ok(())
}

/// `bench`: every method's cost and accuracy.
fn bench(args: BenchArgs) -> anyhow::Result<()> {
    let mut bar = Progress::new("bench");
    let report = omnicave::bench::run(
        &omnicave::bench::BenchOptions {
            config: args.config,
            scenes: args.scene,
            sky: args.skybox,
            out: args.out,
            quick: args.quick,
            frames: args.frames.map(|f| f as usize),
            size: args.size,
            panorama_only: args.panorama_only,
            methods: args.methods,
        },
        &mut |done, total, what| bar.show(done, total, what),
    )
    .context("bench failed")?;
    tracing::info!("adapter: {}", report.adapter);
    for f in &report.files {
        tracing::info!("wrote {}", f.display());
    }
    Ok(())
}

/// `monitors`: the monitors a wall can name.
fn monitors() -> anyhow::Result<()> {
    let monitors = omnicave::app::monitors::list_monitors()?;
    let mut text = String::new();
    for m in &monitors {
        text.push_str(&format!("{m}\n"));
    }
    if monitors.is_empty() {
        text.push_str("no monitors\n");
    }
    write_stdout(text.as_bytes())
}

/// `docs`: the book's generated reference pages, written or checked.
fn docs(args: &DocsArgs) -> anyhow::Result<()> {
    use omnicave::docs;
    let cli = <Cli as clap::CommandFactory>::command();
    let pages = docs::all_pages(&cli, &args.repo)?;
    let book_src = args.repo.join("docs/src");
    if !args.check {
        docs::write_pages(&pages, &book_src)?;
        for page in &pages {
            tracing::info!("wrote docs/src/{}", page.path);
        }
        return Ok(());
    }
    let stale = docs::stale_pages(&pages, &book_src);
    if stale.is_empty() {
        return Ok(());
    }
    anyhow::bail!(
        "{} differ from the code: run `{}` and commit the result",
        stale.join(", "),
        docs::REGENERATE
    )
}

/// `render`: one frame of every wall, headless.
fn render(args: RenderArgs) -> anyhow::Result<()> {
    let overrides = Overrides {
        scene: args.scene,
        mode: args.mode,
        shading: args.shading,
        fit: args.fit,
        size_m: args.size_m,
        offset_m: args.scene_offset,
        double_sided: args.double_sided,
        camera: args.camera,
        head: args.head,
        head_yaw_degrees: args.head_yaw,
        eye_separation: args.ipd,
        size: args.size,
        msaa: args.msaa,
        wireframe: args.wireframe,
        warp: args.warp,
        pole_merge: args.pole_merge.map(|p| p.0),
        tess: args.tess.map(|t| t.0),
        tess_max_depth: args.tess_max_depth,
        sky: args.skybox.map(|s| s.0),
        sky_mode: args.skybox_mode,
        panorama: args.view == ViewArg::Panorama,
        pano_projection: args.projection,
        pano_route: args.pano_route,
        pano_stereo: args.pano_stereo,
        pano_fov_degrees: args.fov,
        pano_yaw_degrees: args.pano_yaw,
        pano_size: args.pano_size,
        animation_time_s: args.time,
        animation: args.animation,
    };
    let written = match args.viewer {
        Some(position) => {
            let viewer = headless::ViewerRequest {
                position,
                yaw_degrees: args.viewer_yaw,
                fov_degrees: args
                    .viewer_fov
                    .unwrap_or(headless::ViewerRequest::DEFAULT_FOV_DEGREES),
                size: args
                    .viewer_size
                    .unwrap_or(headless::ViewerRequest::DEFAULT_SIZE),
            };
            headless::render_viewer_to_dir(&args.config, &overrides, &viewer, &args.out)
        }
        None => headless::render_to_dir(&args.config, &overrides, &args.out, &args.formats),
    }
    .context("render failed")?;
    for f in &written.files {
        tracing::info!("wrote {}", f.display());
    }
    Ok(())
}

fn guests(args: GuestsArgs) -> anyhow::Result<()> {
    use omnicave::guests::grid::Thresholds;
    use omnicave::guests::report::{GuestsRequest, PointSource};

    let limits = Thresholds {
        vertical_arcmin: args.vertical_arcmin,
        direction_degrees: args.direction_degrees,
    };
    let request = GuestsRequest {
        config: args.config,
        source: match args.shells {
            Some(radii) => PointSource::Shells(radii),
            None => PointSource::Scene(args.scene),
        },
        points: args.points,
        methods: if args.methods.is_empty() {
            omnicave::guests::Method::defaults()
        } else {
            args.methods
        },
        step: args.step,
        eye_heights: args.eye_heights,
        head: args.head,
        head_yaw_degrees: args.head_yaw,
        ipd: args.ipd,
        limits,
        quantise: args.quantise,
        sweep: args.sweep,
        threads: args.threads,
        out: args.out,
    };
    let outcome = omnicave::guests::report::run(&request).context("guests failed")?;
    for a in &outcome.areas {
        tracing::info!(
            "{} (eye height {:.2} m): sweet area {:.2} m² of {:.2} m²",
            a.method.name(),
            a.eye_height,
            a.sweet_area_m2,
            a.floor_area_m2
        );
    }
    tracing::info!(
        "{} points × {} viewer positions: the maps took {:.2} s; wrote {} files to {}",
        outcome.points,
        outcome.cells,
        outcome.map_seconds,
        outcome.files.len(),
        request.out.display()
    );
    Ok(())
}

fn track_sim(args: TrackSimArgs) -> anyhow::Result<()> {
    use std::net::ToSocketAddrs;

    let config = args
        .config
        .as_ref()
        .map(|p| omnicave::config::Config::load(p))
        .transpose()?;
    let (mut mapping, calibration, head) = match &config {
        Some(c) => (
            c.tracking.receiver.mapping.clone(),
            c.tracking.settings.calibration,
            c.settings.head().position,
        ),
        None => (
            OscMapping::default(),
            Calibration::default(),
            Vec3::new(0.0, 1.7, 0.0),
        ),
    };
    if let Some(order) = args.quaternion_order {
        mapping.quaternion_order = order;
    }
    let target = args
        .target
        .to_socket_addrs()
        .ok()
        .and_then(|mut a| a.next())
        .ok_or_else(|| omnicave::tracking::TrackingError::Target {
            target: args.target.clone(),
            message: "expected HOST:PORT, e.g. 127.0.0.1:7000".into(),
        })?;
    let centre = args.centre.unwrap_or(head);
    let pattern = match &args.replay {
        Some(path) => {
            // A recorded path of a few hours at 1 kHz is ~200 MB.
            let text = omnicave::read_capped::read_capped_text(path, 256 << 20, "recorded paths")
                .map_err(|source| omnicave::tracking::TrackingError::Read {
                path: path.clone(),
                source,
            })?;
            Pattern::Replay(omnicave::tracking::sim::parse_csv(&text, path)?)
        }
        None => match args.pattern {
            PatternName::Circle => Pattern::Circle {
                centre,
                radius: args.radius,
                period: args.period,
            },
            PatternName::FigureEight => Pattern::FigureEight {
                centre,
                radius: args.radius,
                period: args.period,
            },
            PatternName::Still => Pattern::Still { centre },
        },
    };
    if omnicave::signals::stop_requested() {
        return Ok(());
    }
    omnicave::tracking::sim::run(
        &SimOptions {
            target,
            pattern,
            rate_hz: args.rate,
            duration: args.duration,
            form: args.form,
            mapping,
            calibration,
            junk_per_packet: args.junk,
        },
        omnicave::signals::flag(),
    )?;
    Ok(())
}
