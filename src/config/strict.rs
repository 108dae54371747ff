//! Fixed-size arrays taken exactly: serde fills `[f32; 3]` from the first three elements and
//! ignores the rest, so `resolution = [64, 56, "x", true]` would pass. The text's arrays are
//! compared with the model's, element count by element count.

use toml::Value;

/// An array of the text whose length the model does not take.
#[derive(Debug, Clone, PartialEq)]
pub struct WrongLength {
    /// `wall[0].resolution`.
    pub path: String,
    pub got: usize,
    pub expected: usize,
}

/// Compares every array of `text` with the same array of `model` (the settings as parsed,
/// serialised back): a length that differs is an array with elements the model dropped.
pub fn check_lengths(text: &str, model: &Value) -> Result<(), WrongLength> {
    let Ok(raw) = text.parse::<toml::Table>() else {
        return Ok(()); // It parsed as the model a moment ago; nothing to compare otherwise.
    };
    compare(&Value::Table(raw), model, String::new())
}

fn compare(raw: &Value, model: &Value, path: String) -> Result<(), WrongLength> {
    match (raw, model) {
        (Value::Table(raw), Value::Table(model)) => {
            for (key, value) in raw {
                if let Some(twin) = model.get(key) {
                    let path = if path.is_empty() {
                        key.clone()
                    } else {
                        format!("{path}.{key}")
                    };
                    compare(value, twin, path)?;
                }
            }
        }
        (Value::Array(raw), Value::Array(model)) => {
            if raw.len() != model.len() {
                return Err(WrongLength {
                    path,
                    got: raw.len(),
                    expected: model.len(),
                });
            }
            for (i, (a, b)) in raw.iter().zip(model).enumerate() {
                compare(a, b, format!("{path}[{i}]"))?;
            }
        }
        _ => {}
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn extra_elements_are_found_with_their_path() {
        let model: Value = toml::from_str("[[wall]]\nresolution = [64, 56]\n").unwrap();
        let text = "[[wall]]\nresolution = [64, 56, \"x\", true, 1.5]\n";
        assert_eq!(
            check_lengths(text, &model),
            Err(WrongLength {
                path: "wall[0].resolution".into(),
                got: 5,
                expected: 2
            })
        );
        assert_eq!(
            check_lengths("[[wall]]\nresolution = [64, 56]\n", &model),
            Ok(())
        );
    }
}
