//! What `omnicave bench` is asked to run.

use std::path::PathBuf;

/// What to run.
#[derive(Debug, Clone)]
pub struct BenchOptions {
    pub config: PathBuf,
    /// Scenes; empty: the config's scene, the bundled city and the bundled atrium.
    pub scenes: Vec<PathBuf>,
    /// Sky for the sky methods; `None`: the config's, else the bundled one.
    pub sky: Option<PathBuf>,
    pub out: PathBuf,
    /// Fewer frames and head positions (about 5 minutes for the three default scenes on
    /// lavapipe, 2 cores).
    pub quick: bool,
    /// Timed frames (rounds) per method and case (default 12, quick 5).
    pub frames: Option<usize>,
    /// Replaces every wall's pixel size (quick default: 192×108).
    pub size: Option<[u32; 2]>,
    /// Only these methods (exact names; plain stereo, the reference, always runs), and no
    /// panorama methods; empty: every method.
    pub methods: Vec<String>,
    /// Only the panorama methods (`panorama.csv` and a report of them alone).
    pub panorama_only: bool,
}

/// Wall size of a quick run: 15 % of the thesis CAVE's in each direction, so that CI's
/// software renderer (which spends seconds per full-size city frame) finishes in under two
/// minutes.
pub const QUICK_SIZE: [u32; 2] = [192, 108];
