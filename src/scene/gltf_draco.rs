//! `KHR_draco_mesh_compression`: a primitive's Draco bitstream decoded (the pure-Rust
//! `draco-core`) into the attributes and indices the loader builds vertices from.

use draco_core::{DecoderBuffer, Mesh, MeshDecoder};

/// A primitive's decoded geometry, per point (the Draco points become the vertices).
#[derive(Debug, Default)]
pub struct DracoPrimitive {
    pub positions: Vec<[f32; 3]>,
    pub normals: Option<Vec<[f32; 3]>>,
    pub tangents: Option<Vec<[f32; 4]>>,
    pub uv0: Option<Vec<[f32; 2]>>,
    pub uv1: Option<Vec<[f32; 2]>>,
    pub colors: Option<Vec<[f32; 4]>>,
    /// Triangle list.
    pub indices: Vec<u32>,
}

/// Most points a Draco primitive may decode to (its bitstream, unlike an accessor, is not
/// bounded by the file's size).
pub const MAX_DRACO_POINTS: usize = 1 << 24;

/// Decodes `bytes` (the extension's buffer view) with the glTF attribute → Draco unique id map
/// of the extension. `normalized(name)` tells whether the file's accessor for an attribute is
/// normalized (integer colours and coordinates are then mapped to 0..1 as the accessor says).
pub fn decode(
    bytes: &[u8],
    attributes: &serde_json::Map<String, serde_json::Value>,
    normalized: impl Fn(&str) -> Option<(bool, u32)>,
) -> Result<DracoPrimitive, String> {
    let mut mesh = Mesh::new();
    MeshDecoder::new()
        .decode(&mut DecoderBuffer::new(bytes), &mut mesh)
        .map_err(|e| format!("the Draco bitstream does not decode: {e}"))?;
    let n = mesh.num_points();
    if n > MAX_DRACO_POINTS {
        return Err(format!(
            "the Draco mesh has {n} points, more than the {MAX_DRACO_POINTS} allowed"
        ));
    }
    let read = |name: &str, components: usize| -> Result<Option<Vec<f32>>, String> {
        let Some(id) = attributes.get(name) else {
            return Ok(None);
        };
        let id = id
            .as_u64()
            .and_then(|i| u32::try_from(i).ok())
            .ok_or_else(|| format!("its {name} id {id} is not an attribute id"))?;
        let attribute = mesh
            .attribute_by_unique_id(id)
            .ok_or_else(|| format!("its {name} refers to Draco attribute {id}, which it lacks"))?;
        let mut values = attribute.read_f32s(n, components);
        // Integer attributes the accessor declares normalized: to 0..1 (or −1..1).
        if let Some((true, max)) = normalized(name) {
            let scale = 1.0 / max as f32;
            for v in &mut values {
                *v = (*v * scale).max(-1.0);
            }
        }
        if values.iter().any(|v| !v.is_finite()) {
            return Err(format!("its {name} contains NaN or infinity"));
        }
        Ok(Some(values))
    };
    fn chunks<const N: usize>(v: Vec<f32>) -> Vec<[f32; N]> {
        v.chunks_exact(N)
            .map(|c| std::array::from_fn(|i| c[i]))
            .collect()
    }
    let positions = read("POSITION", 3)?
        .map(chunks::<3>)
        .ok_or("its extension has no POSITION")?;
    let colors = match read("COLOR_0", 4)? {
        Some(c) => {
            // A three-component colour reads 0 alpha: opaque.
            let has_alpha = attributes
                .get("COLOR_0")
                .and_then(|id| id.as_u64())
                .and_then(|id| mesh.attribute_by_unique_id(id as u32))
                .is_some_and(|a| a.num_components() >= 4);
            let mut c = chunks::<4>(c);
            if !has_alpha {
                for v in &mut c {
                    v[3] = 1.0;
                }
            }
            Some(c)
        }
        None => None,
    };
    let indices: Vec<u32> = mesh.faces().iter().flat_map(|f| f.map(|p| p.0)).collect();
    if let Some(bad) = indices.iter().find(|&&i| i as usize >= n) {
        return Err(format!("a Draco face refers to point {bad} of {n}"));
    }
    Ok(DracoPrimitive {
        positions,
        normals: read("NORMAL", 3)?.map(chunks::<3>),
        tangents: read("TANGENT", 4)?.map(chunks::<4>),
        uv0: read("TEXCOORD_0", 2)?.map(chunks::<2>),
        uv1: read("TEXCOORD_1", 2)?.map(chunks::<2>),
        colors,
        indices,
    })
}
