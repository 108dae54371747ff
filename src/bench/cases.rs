//! The situations measured: head positions, where the CAVE stands in the scene, and files the
//! bench finds beside the config.

use std::path::{Path, PathBuf};

use glam::{Mat4, Vec3};

use crate::config::Config;

/// Head positions: the config's, off-centre, 0.3 m from the front wall and near a corner
/// (0.35 m from two walls); `--quick`: the first and the third. Placed relative to the walls'
/// bounding box (front = −z), and skipped with a warning where that is behind a wall.
pub fn heads(config: &Config, quick: bool) -> Vec<(String, Vec3)> {
    let (min, max) = crate::cave::Cave::bounding_box(&config.cave.walls);
    let h = config.settings.head().position;
    let size = max - min;
    let candidates = [
        ("centred", h),
        (
            "off-centre",
            h + Vec3::new(0.18 * size.x, -0.2, 0.12 * size.z),
        ),
        (
            "0.3 m from the front wall",
            Vec3::new(h.x + 0.3, h.y, min.z + 0.3),
        ),
        (
            "near a corner",
            Vec3::new(min.x + 0.35, h.y - 0.1, min.z + 0.35),
        ),
    ];
    candidates
        .into_iter()
        .enumerate()
        .filter(|(i, _)| !quick || *i == 0 || *i == 2)
        .filter_map(|(_, (name, p))| match config.cave.head_problem(p) {
            None => Some((name.to_owned(), p)),
            Some(problem) => {
                tracing::warn!("bench: head '{name}' skipped: {problem}");
                None
            }
        })
        .collect()
}

/// Where the CAVE stands in the scene: the config's placement (`start`), and the same turned
/// about the config's head by 90° to the left and by 180° (the scene seen in other
/// directions, as a user navigating would). `--quick`: `start` and `turned 180°`.
pub fn viewpoints(config: &Config, quick: bool) -> Vec<(String, Mat4)> {
    let h = config.settings.head().position;
    let turned = |degrees: f32| {
        config.settings.world_from_cave()
            * Mat4::from_translation(h)
            * Mat4::from_rotation_y(degrees.to_radians())
            * Mat4::from_translation(-h)
    };
    let all = [
        ("start", config.settings.world_from_cave()),
        ("turned 90° left", turned(90.0)),
        ("turned 180°", turned(180.0)),
    ];
    all.into_iter()
        .filter(|(name, _)| !quick || *name != "turned 90° left")
        .map(|(name, m)| (name.to_owned(), m))
        .collect()
}

/// One measured situation: scene placement and head.
#[derive(Debug, Clone)]
pub(super) struct Case {
    pub(super) viewpoint: String,
    pub(super) world_from_cave: Mat4,
    pub(super) head_name: String,
    pub(super) head: Vec3,
}

/// Every viewpoint with every head; `--quick`: both heads at `start`, the centred head at
/// the other viewpoint. The sky alone only from `start` (turning turns the sky only).
pub(super) fn cases(config: &Config, quick: bool, with_scene: bool) -> Vec<Case> {
    let heads = heads(config, quick);
    let mut out = Vec::new();
    for (i, (viewpoint, world_from_cave)) in viewpoints(config, quick).into_iter().enumerate() {
        if i > 0 && !with_scene {
            break;
        }
        for (j, (head_name, head)) in heads.iter().enumerate() {
            if quick && i > 0 && j > 0 {
                continue;
            }
            out.push(Case {
                viewpoint: viewpoint.clone(),
                world_from_cave,
                head_name: head_name.clone(),
                head: *head,
            });
        }
    }
    out
}

/// A bundled file: relative to the repository the config lives in (config/…), else the
/// current folder.
pub(super) fn bundled_path(config: &Path, relative: &str) -> PathBuf {
    let beside = config
        .parent()
        .and_then(Path::parent)
        .map(|root| root.join(relative));
    match beside {
        Some(p) if p.exists() => p,
        _ => PathBuf::from(relative),
    }
}
