//! Unreal nDisplay's `.ndisplay` JSON (UE 4.27 on): `nDisplay.scene.screens` (each a plane
//! centred at its `location`, turned by its `rotation`, `size` width × height times its
//! `scale`), placed through any depth of `parentId`s among the scene's components. Unreal's
//! frame is left-handed: x forward, y right, z up, in centimetres. A screen under a camera or a
//! tracked component moves with the viewer: it is reported and skipped. A viewport whose
//! projection policy names a screen gives its pixel size.

use std::collections::HashMap;

use glam::DVec3;
use serde_json::Value;

use super::unreal::{Component, Graph, MAX_SCREENS, Placer, conversion, wall};
use super::{Reading, clean_name};
use crate::cave::placement::LengthUnit;

/// Budget: scene components in one file (a 4 MiB file holds about 20 000).
const MAX_COMPONENTS: usize = 100_000;

fn number(v: &Value, key: &str, at: &str, default: f64) -> Result<f64, String> {
    match v.get(key) {
        None | Some(Value::Null) => Ok(default),
        Some(n) => n
            .as_f64()
            .filter(|x| x.is_finite())
            .ok_or(format!("{at}.{key} is not a finite number")),
    }
}

fn vector(c: &Value, key: &str, names: [&str; 3], at: &str, default: f64) -> Result<DVec3, String> {
    let v = c.get(key).unwrap_or(&Value::Null);
    let at = format!("{at}.{key}");
    Ok(DVec3::new(
        number(v, names[0], &at, default)?,
        number(v, names[1], &at, default)?,
        number(v, names[2], &at, default)?,
    ))
}

/// A scene component as the graph needs it.
fn component(kind: &str, id: &str, c: &Value) -> Result<Component, String> {
    let at = format!("scene.{kind}.{id}");
    let rotation = vector(c, "rotation", ["pitch", "yaw", "roll"], &at, 0.0)?;
    let tracker = c
        .get("trackerId")
        .and_then(Value::as_str)
        .filter(|t| !t.is_empty());
    let follows = if kind == "cameras" {
        Some(format!(
            "it is under the camera '{id}', which moves with the viewer"
        ))
    } else {
        tracker.map(|t| format!("it is under '{id}', which follows the tracker '{t}'"))
    };
    Ok(Component {
        parent: c.get("parentId").and_then(Value::as_str).map(String::from),
        location: vector(c, "location", ["x", "y", "z"], &at, 0.0)?,
        rotation: rotation.to_array(),
        scale: vector(c, "scale", ["x", "y", "z"], &at, 1.0)?,
        follows,
        at,
    })
}

/// The screens of an nDisplay config.
pub fn walls(text: &str, reading: &mut Reading<'_>) -> Result<Vec<super::ImportedWall>, String> {
    let root: Value = serde_json::from_str(text).map_err(|e| e.to_string())?;
    let nd = root.get("nDisplay").unwrap_or(&root);
    let scene = nd.get("scene").ok_or("no nDisplay.scene")?;
    let unit = reading.unit.unwrap_or(LengthUnit::Centimetre);
    reading.conversion = conversion(unit.name(), unit.metres());
    // Every scene component (xforms, cameras, screens, meshes, …) can be a parent.
    let mut graph = Graph::default();
    let mut screens: Vec<(&str, &Value)> = Vec::new();
    for (kind, group) in scene.as_object().into_iter().flatten() {
        let Some(group) = group.as_object() else {
            continue;
        };
        for (id, c) in group {
            if !c.is_object() {
                continue;
            }
            if graph.components.len() >= MAX_COMPONENTS {
                return Err(format!("more than {MAX_COMPONENTS} scene components"));
            }
            if graph.components.contains_key(id) {
                reading.notes.push(format!(
                    "the id '{id}' names two scene components; scene.{kind}.{id} is used"
                ));
            }
            graph.components.insert(id.clone(), component(kind, id, c)?);
            if kind == "screens" {
                if screens.len() >= MAX_SCREENS {
                    return Err(format!("more than {MAX_SCREENS} screens"));
                }
                screens.push((id, c));
            }
        }
    }
    let cameras: Vec<&str> = scene
        .get("cameras")
        .and_then(Value::as_object)
        .map(|c| c.keys().map(String::as_str).collect())
        .unwrap_or_default();
    let screen_ids: Vec<&str> = screens.iter().map(|(id, _)| *id).collect();
    graph.mark_viewer_nodes(&cameras, &screen_ids);
    let (resolutions, order) = viewport_sizes(nd);
    let mut placer = Placer::new(&graph);
    let mut out = Vec::new();
    for (id, screen) in screens {
        let at = format!("scene.screens.{id}");
        let scaled = screen.get("scale").is_some();
        let size = match screen.get("size") {
            Some(size) => [
                number(size, "width", &at, f64::NAN)?,
                number(size, "height", &at, f64::NAN)?,
            ],
            // The size carried by the scale alone (a unit plane scaled).
            None if scaled => [1.0, 1.0],
            None => return Err(format!("{at} has neither a size nor a scale")),
        };
        if !size.iter().all(|v| *v > 0.0) {
            return Err(format!("{at}.size must be positive"));
        }
        match placer
            .screen(id, size, unit.metres())
            .map_err(|e| format!("{at}: {e}"))?
        {
            Ok(corners) => out.push((
                order.get(id).copied(),
                wall(
                    clean_name(id, &format!("screen{}", out.len())),
                    corners,
                    resolutions.get(id).copied(),
                ),
            )),
            Err(why) => reading
                .notes
                .push(format!("{at} skipped, not a wall: {why}")),
        }
    }
    // In the order of their viewports on the nodes' windows (left to right), as the walls'
    // windows are; screens without a viewport after, by name.
    out.sort_by_key(|(place, _)| place.unwrap_or((u64::MAX, u64::MAX)));
    Ok(out.into_iter().map(|(_, w)| w).collect())
}

/// Screen id → pixels of the viewport that projects onto it.
type Sizes = HashMap<String, [u32; 2]>;
/// Screen id → its viewport's place on the nodes' windows (top, then left).
type Places = HashMap<String, (u64, u64)>;

/// The pixel size and place of each screen's viewport.
fn viewport_sizes(nd: &Value) -> (Sizes, Places) {
    let mut out = HashMap::new();
    let mut order = HashMap::new();
    let Some(nodes) = nd.pointer("/cluster/nodes").and_then(Value::as_object) else {
        return (out, order);
    };
    for node in nodes.values() {
        let Some(viewports) = node.get("viewports").and_then(Value::as_object) else {
            continue;
        };
        for vp in viewports.values() {
            let screen = vp
                .pointer("/projectionPolicy/parameters/screen")
                .and_then(Value::as_str);
            let size = ["w", "h"].map(|k| {
                vp.pointer(&format!("/region/{k}"))
                    .and_then(Value::as_f64)
                    .filter(|v| (1.0..=65535.0).contains(v))
            });
            if let (Some(screen), [Some(w), Some(h)]) = (screen, size) {
                out.insert(screen.to_owned(), [w as u32, h as u32]);
                let at = |k: &str| {
                    let window = node
                        .pointer(&format!("/window/{k}"))
                        .and_then(Value::as_f64)
                        .unwrap_or(0.0);
                    let region = vp
                        .pointer(&format!("/region/{k}"))
                        .and_then(Value::as_f64)
                        .unwrap_or(0.0);
                    (window + region).clamp(0.0, 1e9) as u64
                };
                order.insert(screen.to_owned(), (at("y"), at("x")));
            }
        }
    }
    (out, order)
}
