//! The JSON Schema of the config file, derived from the settings model, so that editors (e.g.
//! Taplo / Even Better TOML through the `#:schema` line of the bundled configs) validate and
//! complete a lab's config as it is written.

use serde_json::Value;

use super::ConfigFile;

/// The schema as pretty-printed JSON (what `omnicave config schema` prints and
/// `config/omnicave.schema.json` holds).
pub fn json_schema_text() -> String {
    let mut schema = schemars::schema_for!(ConfigFile).to_value();
    if let Value::Object(map) = &mut schema {
        map.insert("title".into(), "omnicave config".into());
    }
    shortest_floats(&mut schema);
    let mut text = serde_json::to_string_pretty(&schema).unwrap_or_else(|e| e.to_string());
    text.push('\n');
    text
}

/// Writes numbers that came from `f32` settings as their shortest `f32` decimal (0.064, not
/// 0.06400000303983688), as the config file has them.
fn shortest_floats(value: &mut Value) {
    match value {
        Value::Number(n) if n.is_f64() => {
            if let Some(x) = n.as_f64()
                && f64::from(x as f32) == x
                && let Ok(short) = (x as f32).to_string().parse::<f64>()
                && let Some(number) = serde_json::Number::from_f64(short)
            {
                *n = number;
            }
        }
        Value::Array(items) => items.iter_mut().for_each(shortest_floats),
        Value::Object(map) => map.values_mut().for_each(shortest_floats),
        _ => {}
    }
}
