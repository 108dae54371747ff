//! Unreal nDisplay's `.ndisplay` JSON: `nDisplay.scene.screens` (each a plane centred at its
//! `location`, turned by its `rotation`, `size` width × height), placed through the
//! `scene.xforms` it is parented to. Unreal's frame is left-handed: x forward, y right, z up,
//! in centimetres. A viewport whose projection policy names a screen gives its pixel size.

use std::collections::HashMap;

use glam::{DMat3, DVec3};
use serde_json::Value;

use super::{ImportedWall, clean_name};
use crate::cave::placement::LengthUnit;

/// Budget: the longest chain of parents followed (a cycle is an error, not a hang).
const MAX_PARENTS: usize = 32;

fn number(v: &Value, key: &str, at: &str) -> Result<f64, String> {
    match v.get(key) {
        None => Ok(0.0),
        Some(n) => n
            .as_f64()
            .filter(|x| x.is_finite())
            .ok_or(format!("{at}.{key} is not a number")),
    }
}

/// A component's placement in Unreal's frame: its location and the images of its x, y, z axes
/// (Unreal's FRotationMatrix of pitch, yaw, roll).
fn placement(c: &Value, at: &str) -> Result<(DVec3, DMat3), String> {
    let l = c.get("location").unwrap_or(&Value::Null);
    let r = c.get("rotation").unwrap_or(&Value::Null);
    let location = DVec3::new(
        number(l, "x", at)?,
        number(l, "y", at)?,
        number(l, "z", at)?,
    );
    let (sp, cp) = number(r, "pitch", at)?.to_radians().sin_cos();
    let (sy, cy) = number(r, "yaw", at)?.to_radians().sin_cos();
    let (sr, cr) = number(r, "roll", at)?.to_radians().sin_cos();
    let x = DVec3::new(cp * cy, cp * sy, sp);
    let y = DVec3::new(sr * sp * cy - cr * sy, sr * sp * sy + cr * cy, -sr * cp);
    let z = DVec3::new(-(cr * sp * cy + sr * sy), cy * sr - cr * sp * sy, cr * cp);
    Ok((location, DMat3::from_cols(x, y, z)))
}

/// Unreal (x forward, y right, z up) to CAVE (x right, y up, −z forward), both unscaled.
fn to_cave(v: DVec3) -> DVec3 {
    DVec3::new(v.y, v.z, -v.x)
}

/// The screens of an nDisplay config.
pub fn walls(text: &str, unit: LengthUnit) -> Result<Vec<ImportedWall>, String> {
    let root: Value = serde_json::from_str(text).map_err(|e| e.to_string())?;
    let nd = root.get("nDisplay").unwrap_or(&root);
    let scene = nd.get("scene").ok_or("no nDisplay.scene")?;
    let empty = serde_json::Map::new();
    let object = |key: &str| scene.get(key).and_then(Value::as_object).unwrap_or(&empty);
    let screens = object("screens");
    // Components that can be parents: xforms, and any other scene component by id.
    let mut parents: HashMap<&str, &Value> = HashMap::new();
    for key in ["xforms", "cameras", "screens"] {
        for (id, c) in object(key) {
            parents.insert(id, c);
        }
    }
    let (resolutions, order) = viewport_sizes(nd);
    let m = unit.metres();
    let mut out = Vec::new();
    for (id, screen) in screens {
        let at = format!("scene.screens.{id}");
        let size = screen.get("size").ok_or(format!("{at} has no size"))?;
        let (w, h) = (number(size, "width", &at)?, number(size, "height", &at)?);
        if w <= 0.0 || h <= 0.0 {
            return Err(format!("{at}.size must be positive"));
        }
        let (mut centre, mut axes) = placement(screen, &at)?;
        let mut parent = screen.get("parentId").and_then(Value::as_str).unwrap_or("");
        let mut depth = 0;
        while !parent.is_empty() {
            depth += 1;
            if depth > MAX_PARENTS {
                return Err(format!(
                    "{at}: parents deeper than {MAX_PARENTS} (a cycle?)"
                ));
            }
            let p = parents
                .get(parent)
                .ok_or(format!("{at}: parent '{parent}' is not in the scene"))?;
            let (loc, rot) = placement(p, &format!("scene.{parent}"))?;
            centre = loc + rot * centre;
            axes = rot * axes;
            parent = p.get("parentId").and_then(Value::as_str).unwrap_or("");
        }
        // A screen faces back along its x; its width runs along y, its height along z.
        let right = to_cave(axes.y_axis);
        let up = to_cave(axes.z_axis);
        let c = to_cave(centre) * m;
        let ll = c - 0.5 * w * m * right - 0.5 * h * m * up;
        out.push(ImportedWall {
            name: clean_name(id, &format!("screen{}", out.len())),
            lower_left: ll,
            lower_right: ll + w * m * right,
            upper_left: ll + h * m * up,
            resolution: resolutions.get(id.as_str()).copied(),
        });
    }
    // In the order of their viewports on the nodes' windows (left to right), as the walls'
    // windows are; screens without a viewport after, by name.
    out.sort_by_key(|w| {
        order
            .get(w.name.as_str())
            .copied()
            .unwrap_or((u64::MAX, u64::MAX))
    });
    Ok(out)
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
