//! Which process drives which wall, and what each process loaded (compared at start-up).

use super::{ClusterError, Digest, Identity};
use crate::config::{Config, ConfigFile};
use crate::scene::Scene;

/// The settings text the master sends (a whole config file).
pub fn settings_text(settings: &ConfigFile) -> Result<String, String> {
    toml::to_string(settings).map_err(|e| format!("cannot encode the settings: {e}"))
}

/// What this process loaded: its settings as validated, the scene's geometry, materials
/// and textures as loaded, and the sky file's bytes.
pub fn identity(host: String, config: &Config, scene: &Scene) -> Identity {
    let settings = settings_text(&config.settings).unwrap_or_default();
    let mut s = Digest::builder();
    for v in &scene.vertices {
        for part in [
            &v.position[..],
            &v.normal,
            &v.uv,
            &v.uv1,
            &v.color,
            &v.tangent,
        ] {
            s.add(bytemuck::cast_slice(part));
        }
    }
    s.add(bytemuck::cast_slice(&scene.indices));
    for d in &scene.draws {
        s.add(format!("{d:?}").as_bytes());
    }
    for m in &scene.materials {
        s.add(format!("{m:?}").as_bytes());
    }
    for t in &scene.textures {
        s.add(&t.rgba8);
    }
    let sky = config
        .sky_path
        .as_ref()
        .and_then(|p| std::fs::read(p).ok())
        .map_or_else(Digest::default, |bytes| Digest::of(&bytes));
    Identity {
        host,
        config: Digest::of(settings.as_bytes()),
        scene: s.finish(),
        sky,
    }
}

/// The walls each rank drives (names; index = rank), or the first wall on a rank the
/// cluster does not have.
pub fn walls_by_node(config: &Config, size: usize) -> Result<Vec<Vec<String>>, ClusterError> {
    let mut walls = vec![Vec::new(); size];
    for (i, wall) in config.cave.walls.iter().enumerate() {
        let node = node_of(config, i);
        match walls.get_mut(node) {
            Some(list) => list.push(wall.name.clone()),
            None => {
                return Err(ClusterError::MissingNode {
                    wall: wall.name.clone(),
                    node,
                    size,
                });
            }
        }
    }
    Ok(walls)
}

/// The rank that drives wall `i` (0 when the config does not say).
pub fn node_of(config: &Config, i: usize) -> usize {
    config
        .settings
        .walls
        .get(i)
        .and_then(|w| w.node)
        .map_or(0, |n| n as usize)
}
