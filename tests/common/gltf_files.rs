//! Hand-made glTF files for the loader tests: a one-triangle file with an external buffer that a
//! test may break, and a GLB with its JSON chunk replaced.

use std::path::{Path, PathBuf};

use serde_json::json;

/// A one-triangle glTF `<name>.gltf` in `dir` (counter-clockwise seen from +z, no normals) with
/// its buffer in `<name>.bin`; `edit` may change the JSON or the binary first.
pub fn write_triangle_gltf(
    dir: &Path,
    name: &str,
    edit: impl FnOnce(&mut serde_json::Value, &mut Vec<u8>),
) -> PathBuf {
    let mut bin = Vec::new();
    for v in [[0.0f32, 0.0, -2.0], [1.0, 0.0, -2.0], [0.0, 1.0, -2.0]] {
        for c in v {
            bin.extend_from_slice(&c.to_le_bytes());
        }
    }
    for i in [0u16, 1, 2, 0] {
        bin.extend_from_slice(&i.to_le_bytes()); // last one is padding
    }
    let bin_name = format!("{name}.bin");
    let mut doc = json!({
        "asset": {"version": "2.0"},
        "scene": 0,
        "scenes": [{"nodes": [0]}],
        "nodes": [{"mesh": 0}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0}, "indices": 1}]}],
        "buffers": [{"uri": bin_name, "byteLength": 44}],
        "bufferViews": [
            {"buffer": 0, "byteOffset": 0, "byteLength": 36},
            {"buffer": 0, "byteOffset": 36, "byteLength": 6}
        ],
        "accessors": [
            {"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3",
             "min": [0.0, 0.0, -2.0], "max": [1.0, 1.0, -2.0]},
            {"bufferView": 1, "componentType": 5123, "count": 3, "type": "SCALAR"}
        ]
    });
    edit(&mut doc, &mut bin);
    let path = dir.join(format!("{name}.gltf"));
    std::fs::write(&path, doc.to_string()).unwrap();
    std::fs::write(dir.join(&bin_name), &bin).unwrap();
    path
}

/// `glb` with its JSON chunk replaced by `doc` (the BIN chunk kept).
pub fn with_json(glb: &[u8], doc: &serde_json::Value) -> Vec<u8> {
    let json_len = u32::from_le_bytes(glb[12..16].try_into().unwrap()) as usize;
    let bin = &glb[20 + json_len..];
    let mut text = doc.to_string().into_bytes();
    while !text.len().is_multiple_of(4) {
        text.push(b' ');
    }
    let mut out = Vec::new();
    out.extend_from_slice(b"glTF");
    out.extend_from_slice(&2u32.to_le_bytes());
    out.extend_from_slice(&((12 + 8 + text.len() + bin.len()) as u32).to_le_bytes());
    out.extend_from_slice(&(text.len() as u32).to_le_bytes());
    out.extend_from_slice(b"JSON");
    out.extend_from_slice(&text);
    out.extend_from_slice(bin);
    out
}
