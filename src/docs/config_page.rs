//! The config reference and the budgets page, from the settings model's JSON Schema.

use std::fmt::Write as _;

use serde_json::{Map, Value};

use super::{DocsError, cell, generated_header};

/// The schema as JSON, from the settings model (what `omnicave config schema` prints).
fn schema() -> Result<Value, DocsError> {
    serde_json::from_str(&crate::config::schema::json_schema_text())
        .map_err(|e| DocsError::Schema(e.to_string()))
}

/// A definition of the schema's `$defs` by its `$ref`.
fn resolve<'a>(defs: &'a Map<String, Value>, reference: &str) -> Option<&'a Value> {
    defs.get(reference.strip_prefix("#/$defs/")?)
}

/// The table a property opens, if it is one: `[name]` for an object, `[[name]]` for an
/// array of objects.
fn table_of<'a>(defs: &'a Map<String, Value>, property: &'a Value) -> Option<(&'a Value, bool)> {
    let target = match property.get("$ref").and_then(Value::as_str) {
        Some(r) => resolve(defs, r)?,
        None => property,
    };
    if target.get("properties").is_some() {
        return Some((target, false));
    }
    let items = property.get("items")?;
    let item = match items.get("$ref").and_then(Value::as_str) {
        Some(r) => resolve(defs, r)?,
        None => items,
    };
    item.get("properties").is_some().then_some((item, true))
}

/// A value's type in words ("number", "3 numbers", "`mono`, `stereo`", …).
fn type_text(defs: &Map<String, Value>, v: &Value) -> String {
    if let Some(r) = v.get("$ref").and_then(Value::as_str) {
        return resolve(defs, r).map_or_else(|| r.to_string(), |d| type_text(defs, d));
    }
    if let Some(names) = v.get("enum").and_then(Value::as_array) {
        let names: Vec<String> = names.iter().map(|n| format!("`{}`", plain(n))).collect();
        return format!("one of {}", names.join(", "));
    }
    if let Some(options) = v.get("anyOf").and_then(Value::as_array) {
        let texts: Vec<String> = options
            .iter()
            .filter(|o| o.get("type").and_then(Value::as_str) != Some("null"))
            .map(|o| type_text(defs, o))
            .collect();
        return texts.join(", or ");
    }
    let kinds: Vec<&str> = match v.get("type") {
        Some(Value::String(s)) => vec![s.as_str()],
        Some(Value::Array(a)) => a.iter().filter_map(Value::as_str).collect(),
        _ => Vec::new(),
    };
    let kind = kinds.into_iter().find(|k| *k != "null").unwrap_or("any");
    match kind {
        "array" => array_text(defs, v),
        "object" => match v.get("additionalProperties") {
            Some(inner @ Value::Object(_)) => {
                format!("table of name → {}", type_text(defs, inner))
            }
            _ => "table".into(),
        },
        "number" => "number".into(),
        other => other.to_string(),
    }
}

/// An array's type: "3 numbers", "list of strings".
fn array_text(defs: &Map<String, Value>, v: &Value) -> String {
    let item = v
        .get("items")
        .map_or_else(|| "value".into(), |i| type_text(defs, i));
    let plural = if item.starts_with("one of") || item.contains(' ') {
        format!("({item})")
    } else {
        format!("{item}s")
    };
    match (
        v.get("minItems").and_then(Value::as_u64),
        v.get("maxItems").and_then(Value::as_u64),
    ) {
        (Some(a), Some(b)) if a == b => format!("{a} {plural}"),
        (Some(a), Some(b)) => format!("{a}–{b} {plural}"),
        _ => format!("list of {plural}"),
    }
}

/// A property's allowed range, from `minimum`/`maximum` (on it or on its items).
fn range_text(v: &Value) -> String {
    let bound = |v: &Value| {
        (
            v.get("minimum").and_then(Value::as_f64),
            v.get("maximum").and_then(Value::as_f64),
        )
    };
    let (mut lo, mut hi) = bound(v);
    let mut prefix = "";
    if lo.is_none()
        && hi.is_none()
        && let Some(items) = v.get("items")
    {
        (lo, hi) = bound(items);
        prefix = "each ";
    }
    let n = |x: f64| {
        Value::from(x)
            .to_string()
            .trim_end_matches(".0")
            .to_string()
    };
    match (lo, hi) {
        (Some(a), Some(b)) => format!("{prefix}{} – {}", n(a), n(b)),
        (Some(a), None) if a != 0.0 => format!("{prefix}≥ {}", n(a)),
        (None, Some(b)) => format!("{prefix}≤ {}", n(b)),
        _ => String::new(),
    }
}

/// A JSON value as it is written in TOML (strings quoted, arrays, inline tables).
fn toml_text(v: &Value) -> String {
    match v {
        Value::String(s) => format!("{s:?}"),
        Value::Array(a) => {
            let items: Vec<String> = a.iter().map(toml_text).collect();
            format!("[{}]", items.join(", "))
        }
        Value::Object(m) => {
            let items: Vec<String> = m
                .iter()
                .map(|(k, v)| format!("{} = {}", toml_key(k), toml_text(v)))
                .collect();
            format!("{{ {} }}", items.join(", "))
        }
        Value::Null => "unset".into(),
        other => other.to_string(),
    }
}

/// A key as TOML writes it: bare when it can be, quoted otherwise.
fn toml_key(k: &str) -> String {
    if !k.is_empty()
        && k.chars()
            .all(|c| c.is_ascii_alphanumeric() || c == '_' || c == '-')
    {
        k.to_string()
    } else {
        format!("{k:?}")
    }
}

/// A JSON string's text, or the value's JSON.
fn plain(v: &Value) -> String {
    v.as_str().map_or_else(|| v.to_string(), str::to_string)
}

/// Writes the table `name` (and, after it, every table nested in it).
fn write_table(
    out: &mut String,
    defs: &Map<String, Value>,
    name: &str,
    def: &Value,
    array: bool,
    default: Option<&Value>,
) {
    let heading = if array {
        format!("[[{name}]]")
    } else {
        format!("[{name}]")
    };
    let _ = writeln!(out, "## `{heading}`\n");
    if let Some(doc) = def.get("description").and_then(Value::as_str) {
        let _ = writeln!(out, "{}\n", cell(doc));
    }
    let Some(properties) = def.get("properties").and_then(Value::as_object) else {
        return;
    };
    let required: Vec<&str> = def
        .get("required")
        .and_then(Value::as_array)
        .map(|r| r.iter().filter_map(Value::as_str).collect())
        .unwrap_or_default();
    let mut nested = Vec::new();
    let mut rows = String::new();
    for (key, property) in properties {
        let own_default = property
            .get("default")
            .or_else(|| default.and_then(|d| d.get(key)));
        if let Some((inner, inner_array)) = table_of(defs, property) {
            nested.push((key, inner, inner_array, own_default));
            continue;
        }
        let default_text = match own_default {
            Some(d) => format!("`{}`", toml_text(d)),
            None if required.contains(&key.as_str()) => "required".into(),
            None => "unset".into(),
        };
        let doc = property.get("description").and_then(Value::as_str);
        let _ = writeln!(
            rows,
            "| `{key}` | {} | {default_text} | {} | {} |",
            cell(&type_text(defs, property)),
            range_text(property),
            cell(doc.unwrap_or("")),
        );
    }
    if !rows.is_empty() {
        out.push_str("| key | type | default | range | meaning |\n|---|---|---|---|---|\n");
        out.push_str(&rows);
        out.push('\n');
    }
    for (key, inner, inner_array, inner_default) in nested {
        write_table(
            out,
            defs,
            &format!("{name}.{key}"),
            inner,
            inner_array,
            inner_default,
        );
    }
}

/// A top-level table of the config: its name, its definition, whether it is an array of
/// tables (`[[name]]`) and its default.
struct Section {
    name: String,
    def: Value,
    array: bool,
    default: Option<Value>,
}

/// The top-level tables of the schema, with their definitions.
fn sections(schema: &Value) -> Result<Vec<Section>, DocsError> {
    let missing = |what: &str| DocsError::Schema(format!("no {what}"));
    let defs = schema
        .get("$defs")
        .and_then(Value::as_object)
        .ok_or_else(|| missing("$defs"))?;
    let properties = schema
        .get("properties")
        .and_then(Value::as_object)
        .ok_or_else(|| missing("properties"))?;
    properties
        .iter()
        .map(|(name, property)| {
            let (def, array) = table_of(defs, property)
                .ok_or_else(|| DocsError::Schema(format!("[{name}] is not a table")))?;
            Ok(Section {
                name: name.clone(),
                def: def.clone(),
                array,
                default: property.get("default").cloned(),
            })
        })
        .collect()
}

/// `reference/config.md`: every table and key of the config file.
pub fn config_page() -> Result<String, DocsError> {
    let schema = schema()?;
    let defs = schema
        .get("$defs")
        .and_then(Value::as_object)
        .cloned()
        .unwrap_or_default();
    let mut out = generated_header("the settings model (`src/config/file.rs`)");
    out.push_str(
        "# Config keys\n\n\
         Every key of the config file (TOML), by table: its type, its default (what an absent \
         key means), the range validation accepts and what it does. Every key is optional \
         unless it says *required*; *unset* means the key has no value unless given. The same \
         model gives the JSON Schema (`omnicave config schema`, committed as \
         `config/omnicave.schema.json`) that editors validate configs with, the panel's \
         controls and the saved config. Lengths are metres and angles degrees unless a key \
         says otherwise.\n\n",
    );
    for section in sections(&schema)? {
        write_table(
            &mut out,
            &defs,
            &section.name,
            &section.def,
            section.array,
            section.default.as_ref(),
        );
    }
    Ok(out)
}

/// A fixed limit of the program: what it bounds and its value.
struct FixedLimit {
    what: &'static str,
    value: String,
    source: &'static str,
}

/// The limits no setting changes, from the constants that enforce them.
fn fixed_limits() -> Vec<FixedLimit> {
    use crate::{cluster, config, guests, read_capped, scene, sky, tess, tracking};
    let mib = |b: u64| format!("{} MiB", b >> 20);
    vec![
        FixedLimit {
            what: "`omnicave guests`: scene points judged",
            value: guests::grid::MAX_POINTS.to_string(),
            source: "guests::grid::MAX_POINTS",
        },
        FixedLimit {
            what: "`omnicave guests`: grid cells (the step is at least 5 mm)",
            value: guests::grid::MAX_CELLS.to_string(),
            source: "guests::grid::MAX_CELLS",
        },
        FixedLimit {
            what: "`omnicave guests`: judgements in one run (viewer positions, grid and reach, × points × distinct methods × eye heights)",
            value: guests::grid::MAX_JUDGEMENTS.to_string(),
            source: "guests::grid::MAX_JUDGEMENTS",
        },
        FixedLimit {
            what: "`omnicave guests`: worker threads (`--threads` above it is clamped)",
            value: guests::grid::MAX_THREADS.to_string(),
            source: "guests::grid::MAX_THREADS",
        },
        FixedLimit {
            what: "`omnicave guests`: eye heights mapped in one run",
            value: guests::report::MAX_EYE_HEIGHTS.to_string(),
            source: "guests::report::MAX_EYE_HEIGHTS",
        },
        FixedLimit {
            what: "Config file size",
            value: mib(read_capped::MAX_CONFIG_BYTES),
            source: "read_capped::MAX_CONFIG_BYTES",
        },
        FixedLimit {
            what: "Pixels per side of a wall's image",
            value: config::MAX_WALL_PIXELS.to_string(),
            source: "config::MAX_WALL_PIXELS",
        },
        FixedLimit {
            what: "Windows (projectors) per wall",
            value: config::wall_output::MAX_EYE_OUTPUTS.to_string(),
            source: "config::wall_output::MAX_EYE_OUTPUTS",
        },
        FixedLimit {
            what: "Walls one `config import` reads",
            value: config::import::MAX_IMPORTED_WALLS.to_string(),
            source: "config::import::MAX_IMPORTED_WALLS",
        },
        FixedLimit {
            what: "Tessellation depth (segments per edge: 2^depth)",
            value: tess::MAX_DEPTH_LIMIT.to_string(),
            source: "tess::MAX_DEPTH_LIMIT",
        },
        FixedLimit {
            what: "glTF: bytes of one decoded (compressed) buffer view",
            value: mib(scene::MAX_DECODED_VIEW_BYTES as u64),
            source: "scene::MAX_DECODED_VIEW_BYTES",
        },
        FixedLimit {
            what: "glTF: elements of a sparse accessor without a buffer view",
            value: scene::MAX_SPARSE_BASE_ELEMENTS.to_string(),
            source: "scene::MAX_SPARSE_BASE_ELEMENTS",
        },
        FixedLimit {
            what: "glTF: points of one Draco-compressed primitive",
            value: scene::MAX_DRACO_POINTS.to_string(),
            source: "scene::MAX_DRACO_POINTS",
        },
        FixedLimit {
            what: "Sky: cube face side from an equirectangular image, pixels",
            value: sky::cubemap::MAX_EQUIRECT_FACE_SIZE.to_string(),
            source: "sky::cubemap::MAX_EQUIRECT_FACE_SIZE",
        },
        FixedLimit {
            what: "Sky: cube face side from six face images, pixels",
            value: sky::cubemap::MAX_FACE_SIZE.to_string(),
            source: "sky::cubemap::MAX_FACE_SIZE",
        },
        FixedLimit {
            what: "OSC: bundle nesting",
            value: tracking::osc::MAX_BUNDLE_DEPTH.to_string(),
            source: "tracking::osc::MAX_BUNDLE_DEPTH",
        },
        FixedLimit {
            what: "OSC: array nesting in a message",
            value: tracking::osc::MAX_ARRAY_DEPTH.to_string(),
            source: "tracking::osc::MAX_ARRAY_DEPTH",
        },
        FixedLimit {
            what: "Tracking: largest coordinate accepted, any unit",
            value: format!("{:e}", tracking::osc::MAX_ABS_NUMBER),
            source: "tracking::osc::MAX_ABS_NUMBER",
        },
        FixedLimit {
            what: "Tracking: farthest position from the CAVE's origin, m",
            value: tracking::plausibility::MAX_TRACKED_DISTANCE_M.to_string(),
            source: "tracking::plausibility::MAX_TRACKED_DISTANCE_M",
        },
        FixedLimit {
            what: "Tracking: buttons / analog axes of the input device",
            value: format!(
                "{} / {}",
                tracking::receiver::MAX_BUTTONS,
                tracking::receiver::MAX_ANALOGS
            ),
            source: "tracking::receiver::MAX_BUTTONS, MAX_ANALOGS",
        },
        FixedLimit {
            what: "VRPN: one message, bytes",
            value: mib(tracking::vrpn_wire::MAX_MESSAGE as u64),
            source: "tracking::vrpn_wire::MAX_MESSAGE",
        },
        FixedLimit {
            what: "VRPN: sender and type names, ids per connection",
            value: format!(
                "{} bytes, {}",
                tracking::vrpn_wire::MAX_NAME,
                tracking::vrpn_wire::MAX_IDS
            ),
            source: "tracking::vrpn_wire::MAX_NAME, MAX_IDS",
        },
        FixedLimit {
            what: "DTrack: bodies per frame; flystick buttons / controllers",
            value: format!(
                "{}; {} / {}",
                tracking::dtrack::MAX_TARGETS,
                tracking::dtrack::MAX_FLYSTICK_BUTTONS,
                tracking::dtrack::MAX_FLYSTICK_CONTROLLERS
            ),
            source: "tracking::dtrack::MAX_TARGETS, MAX_FLYSTICK_*",
        },
        FixedLimit {
            what: "Cluster: one message; one text field, bytes",
            value: format!(
                "{}; {}",
                mib(cluster::messages::MAX_MESSAGE_BYTES as u64),
                cluster::messages::MAX_TEXT_BYTES
            ),
            source: "cluster::messages::MAX_MESSAGE_BYTES, MAX_TEXT_BYTES",
        },
    ]
}

/// `reference/budgets.md`: what every input may cost, settable and fixed.
pub fn budgets_page() -> Result<String, DocsError> {
    let schema = schema()?;
    let defs = schema
        .get("$defs")
        .and_then(Value::as_object)
        .cloned()
        .unwrap_or_default();
    let mut out =
        generated_header("the settings model's `[budgets]` and the limits' constants in `src/`");
    out.push_str(
        "# Budgets\n\n\
         Every input has a budget. Past it, the input is refused with an error naming the \
         file, the field and the budget (a texture over its side is downscaled, with a \
         warning); nothing is half-loaded. The settable budgets are the config's `[budgets]` \
         table; the others are fixed.\n\n",
    );
    let budgets = sections(&schema)?
        .into_iter()
        .find(|section| section.name == "budgets")
        .ok_or_else(|| DocsError::Schema("no [budgets] table".into()))?;
    write_table(
        &mut out,
        &defs,
        "budgets",
        &budgets.def,
        false,
        budgets.default.as_ref(),
    );
    out.push_str("## Fixed limits\n\n| what | limit | constant |\n|---|---|---|\n");
    for limit in fixed_limits() {
        let _ = writeln!(
            out,
            "| {} | {} | `{}` |",
            limit.what, limit.value, limit.source
        );
    }
    Ok(out)
}
