//! The settings' ranges, read from the model's schema: the one place a range is written
//! (`#[schemars(range(..))]` beside its field in `file.rs`) serves validation, the panel's
//! sliders and editors alike, so a new setting with a range needs no other code.

use std::collections::BTreeMap;
use std::ops::RangeInclusive;
use std::sync::OnceLock;

use serde_json::{Map, Value};

use super::ConfigFile;

/// A setting's allowed range (inclusive; an open side is infinite).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Bounds {
    pub min: f64,
    pub max: f64,
}

impl Bounds {
    /// As a slider range.
    pub fn f32_range(self) -> RangeInclusive<f32> {
        self.min as f32..=self.max as f32
    }

    /// Whether a value (compared at the `f32` precision settings are stored in) lies inside.
    fn holds(self, value: f64) -> bool {
        let v = value as f32;
        v.is_finite() && v >= self.min as f32 && v <= self.max as f32
    }

    fn describe(self) -> String {
        format!(
            "must be between {} and {}",
            self.min as f32, self.max as f32
        )
    }
}

/// The range of the setting at `path` (`cave.eye_separation`, `wall[0].resolution[1]`), if
/// the model gives it one.
pub fn bounds(path: &str) -> Option<Bounds> {
    // The panel asks every frame: no allocation for a path without indices.
    if !path.contains('[') {
        return table().get(path).copied();
    }
    table().get(&generic_path(path)).copied()
}

/// A value outside its range: the field's path, the value as written and the reason.
#[derive(Debug, Clone, PartialEq)]
pub(super) struct OutOfBounds {
    pub path: String,
    pub value: String,
    pub reason: String,
}

/// The first setting of `file` outside its range (non-finite numbers included).
pub(super) fn check(file: &ConfigFile) -> Result<(), OutOfBounds> {
    let value = serde_json::to_value(file).map_err(|e| OutOfBounds {
        path: "(the whole file)".into(),
        value: String::new(),
        reason: format!("cannot be checked: {e}"),
    })?;
    walk(&value, String::new(), table())
}

fn walk(value: &Value, path: String, table: &BTreeMap<String, Bounds>) -> Result<(), OutOfBounds> {
    match value {
        Value::Object(map) => {
            for (key, item) in map {
                let path = if path.is_empty() {
                    key.clone()
                } else {
                    format!("{path}.{key}")
                };
                walk(item, path, table)?;
            }
        }
        Value::Array(items) => {
            for (i, item) in items.iter().enumerate() {
                walk(item, format!("{path}[{i}]"), table).map_err(|e| {
                    // A vector setting (a size, a rotation) is reported whole.
                    if items.iter().all(|v| v.is_number() || v.is_null()) {
                        OutOfBounds {
                            value: format!(
                                "[{}]",
                                items.iter().map(number_text).collect::<Vec<_>>().join(", ")
                            ),
                            reason: format!("every component {}", e.reason),
                            path: path.clone(),
                        }
                    } else {
                        e
                    }
                })?;
            }
        }
        Value::Number(n) => {
            if let (Some(bounds), Some(x)) = (table.get(&generic_path(&path)), n.as_f64())
                && !bounds.holds(x)
            {
                return Err(OutOfBounds {
                    path,
                    value: number_text(value),
                    reason: bounds.describe(),
                });
            }
        }
        // Serialising turns NaN and infinities into null.
        Value::Null => {
            if let Some(bounds) = table.get(&generic_path(&path)) {
                return Err(OutOfBounds {
                    path,
                    value: "NaN or infinite".into(),
                    reason: format!("{} (a finite number)", bounds.describe()),
                });
            }
        }
        _ => {}
    }
    Ok(())
}

/// A number as the config has it (an `f32` setting in its shortest form); null is NaN or
/// infinite.
fn number_text(value: &Value) -> String {
    match value {
        Value::Number(n) if n.is_f64() => format!("{:?}", n.as_f64().unwrap_or(f64::NAN) as f32),
        Value::Number(n) => n.to_string(),
        _ => "NaN".into(),
    }
}

/// `wall[2].resolution[0]` → `wall[].resolution[]`.
fn generic_path(path: &str) -> String {
    let mut out = String::with_capacity(path.len());
    let mut in_index = false;
    for c in path.chars() {
        match c {
            '[' => {
                in_index = true;
                out.push_str("[]");
            }
            ']' => in_index = false,
            _ if in_index => {}
            _ => out.push(c),
        }
    }
    out
}

/// Every bounded setting's generic path and range, from the model's schema (built once).
fn table() -> &'static BTreeMap<String, Bounds> {
    static TABLE: OnceLock<BTreeMap<String, Bounds>> = OnceLock::new();
    TABLE.get_or_init(|| {
        let schema = schemars::schema_for!(ConfigFile).to_value();
        let empty = Map::new();
        let defs = schema
            .get("$defs")
            .and_then(Value::as_object)
            .unwrap_or(&empty);
        let mut table = BTreeMap::new();
        collect(&schema, defs, String::new(), &mut table, 0);
        table
    })
}

/// Walks a schema (through `$ref`s, properties, items and alternatives), noting each
/// `minimum`/`maximum` under its path.
fn collect(
    schema: &Value,
    defs: &Map<String, Value>,
    path: String,
    table: &mut BTreeMap<String, Bounds>,
    depth: usize,
) {
    // The model has no recursive types; the limit only guards against a schema that did.
    if depth > 16 {
        return;
    }
    if let Some(name) = schema
        .get("$ref")
        .and_then(Value::as_str)
        .and_then(|r| r.strip_prefix("#/$defs/"))
        && let Some(def) = defs.get(name)
    {
        collect(def, defs, path.clone(), table, depth + 1);
    }
    let number = |key: &str| schema.get(key).and_then(Value::as_f64);
    if number("minimum").is_some() || number("maximum").is_some() {
        table.insert(
            path.clone(),
            Bounds {
                min: number("minimum").unwrap_or(f64::NEG_INFINITY),
                max: number("maximum").unwrap_or(f64::INFINITY),
            },
        );
    }
    if let Some(properties) = schema.get("properties").and_then(Value::as_object) {
        for (key, item) in properties {
            let item_path = if path.is_empty() {
                key.clone()
            } else {
                format!("{path}.{key}")
            };
            collect(item, defs, item_path, table, depth + 1);
        }
    }
    if let Some(items) = schema.get("items") {
        collect(items, defs, format!("{path}[]"), table, depth + 1);
    }
    for key in ["anyOf", "oneOf", "allOf"] {
        for alternative in schema
            .get(key)
            .and_then(Value::as_array)
            .into_iter()
            .flatten()
        {
            collect(alternative, defs, path.clone(), table, depth + 1);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ranges_come_from_the_model() {
        let b = bounds("cave.eye_separation").expect("bounded");
        assert_eq!((b.min, b.max), (0.0, 0.5));
        let b = bounds("wall[3].resolution[1]").expect("bounded");
        assert_eq!((b.min, b.max), (1.0, 8192.0));
        assert!(bounds("tracking.filter.beta").is_some());
        assert!(bounds("render.wireframe").is_none());
    }

    #[test]
    fn a_vector_setting_is_reported_whole() {
        let mut file = ConfigFile::default();
        file.panorama.size = [1024, 0];
        let e = check(&file).expect_err("zero width");
        assert_eq!(
            (e.path.as_str(), e.value.as_str()),
            ("panorama.size", "[1024, 0]")
        );
        assert!(
            e.reason
                .starts_with("every component must be between 1 and 8192"),
            "{e:?}"
        );
    }

    #[test]
    fn out_of_range_and_non_finite_values_are_found() {
        let mut file = ConfigFile::default();
        assert_eq!(check(&file), Ok(()));
        file.gamepad.dead_zone = 0.95;
        let e = check(&file).expect_err("out of range");
        assert_eq!(e.path, "gamepad.dead_zone");
        assert_eq!(e.value, "0.95");
        assert!(e.reason.contains("between 0 and 0.9"), "{e:?}");
        file.gamepad.dead_zone = f32::NAN;
        assert_eq!(check(&file).expect_err("NaN").path, "gamepad.dead_zone");
        file.gamepad.dead_zone = 0.1;
        // The bound is an f64 the f32 setting cannot hold exactly: the bound itself passes.
        file.cave.near = 1e-4;
        assert_eq!(check(&file), Ok(()));
    }
}
