//! A glTF file's binary data: buffers, buffer views (`EXT_meshopt_compression` decoded once) and
//! accessors of every layout the specification and `KHR_mesh_quantization` allow (normalized or
//! integer components, byte strides, sparse substitution), read as `f32` or `u32`.

use gltf::accessor::{DataType, Dimensions};

/// Largest decoded size of one compressed buffer view (the decoder's output budget).
pub const MAX_DECODED_VIEW_BYTES: usize = 1 << 28;

/// Most elements of an accessor without a buffer view (zeros, plus sparse values if any): no
/// file data bounds its count.
pub const MAX_SPARSE_BASE_ELEMENTS: usize = 1 << 24;

/// The file's buffers and the decoded contents of its compressed buffer views.
pub struct BinaryData {
    buffers: Vec<Vec<u8>>,
    /// Per buffer view: its decoded bytes where it is meshopt-compressed (or why it cannot be
    /// decoded, reported when something reads it).
    decoded: Vec<Option<Result<Vec<u8>, String>>>,
}

/// Loads every buffer: the GLB's BIN chunk, data URIs and files next to `path`. A
/// `EXT_meshopt_compression` fallback buffer (no URI, no data: only compressed views refer to
/// it) is left empty.
pub fn load_buffers(
    document: &gltf::Document,
    mut blob: Option<Vec<u8>>,
    read_file: &dyn Fn(&str) -> Result<Vec<u8>, String>,
) -> Result<Vec<Vec<u8>>, String> {
    let mut buffers = Vec::new();
    for buffer in document.buffers() {
        let fallback = buffer
            .extension_value("EXT_meshopt_compression")
            .and_then(|e| e.get("fallback"))
            .and_then(|f| f.as_bool())
            .unwrap_or(false);
        let data = match buffer.source() {
            _ if fallback => Vec::new(),
            // A file: read under the size cap (the crate's own read has none).
            gltf::buffer::Source::Uri(uri) if !uri.starts_with("data:") => {
                read_file(uri).map_err(|e| format!("buffer {}: {e}", buffer.index()))?
            }
            _ => {
                gltf::buffer::Data::from_source_and_blob(buffer.source(), None, &mut blob)
                    .map_err(|e| format!("buffer {}: {e}", buffer.index()))?
                    .0
            }
        };
        if !fallback && data.len() < buffer.length() {
            return Err(format!(
                "buffer {} declares {} bytes but holds {}",
                buffer.index(),
                buffer.length(),
                data.len()
            ));
        }
        buffers.push(data);
    }
    Ok(buffers)
}

impl BinaryData {
    /// Decodes every meshopt-compressed buffer view (`EXT_meshopt_compression`).
    pub fn new(document: &gltf::Document, buffers: Vec<Vec<u8>>) -> Self {
        let mut decoded = Vec::new();
        for view in document.views() {
            let compressed = view
                .extension_value("EXT_meshopt_compression")
                .map(|ext| decode_meshopt_view(view.index(), ext, &buffers));
            decoded.push(compressed);
        }
        Self { buffers, decoded }
    }

    /// The bytes of a buffer view, checked to lie inside its buffer.
    pub fn view_bytes(&self, view: &gltf::buffer::View<'_>) -> Result<&[u8], String> {
        if let Some(Some(decoded)) = self.decoded.get(view.index()) {
            return decoded.as_deref().map_err(Clone::clone);
        }
        let buffer = self
            .buffers
            .get(view.buffer().index())
            .map(Vec::as_slice)
            .unwrap_or(&[]);
        view.offset()
            .checked_add(view.length())
            .and_then(|end| buffer.get(view.offset()..end))
            .ok_or_else(|| {
                format!(
                    "buffer view {} (offset {}, {} bytes) lies outside buffer {} ({} bytes)",
                    view.index(),
                    view.offset(),
                    view.length(),
                    view.buffer().index(),
                    buffer.len()
                )
            })
    }

    /// Reads an accessor as `count` elements of `N` floats: normalized integers mapped to
    /// 0..1 or −1..1 as the specification says, other integers converted to their value,
    /// sparse substitutions applied.
    pub fn read_f32<const N: usize>(
        &self,
        accessor: &gltf::Accessor<'_>,
    ) -> Result<Vec<[f32; N]>, String> {
        let components = accessor.dimensions().multiplicity();
        if components != N {
            return Err(format!(
                "has {components} components per element, expected {N}"
            ));
        }
        let ty = accessor.data_type();
        let normalized = accessor.normalized();
        let convert = |bytes: &[u8]| -> f32 { component_f32(ty, normalized, bytes) };
        self.check_extent(accessor)?;
        let mut out = vec![[0.0f32; N]; accessor.count()];
        self.read_elements(accessor, |i, element| {
            let size = ty.size();
            for (c, value) in out[i].iter_mut().enumerate() {
                *value = convert(&element[c * size..(c + 1) * size]);
            }
        })?;
        Ok(out)
    }

    /// Reads a scalar unsigned-integer accessor (indices).
    pub fn read_u32(&self, accessor: &gltf::Accessor<'_>) -> Result<Vec<u32>, String> {
        if accessor.dimensions() != Dimensions::Scalar {
            return Err(format!(
                "has type {:?}, expected SCALAR",
                accessor.dimensions()
            ));
        }
        let ty = accessor.data_type();
        if !matches!(ty, DataType::U8 | DataType::U16 | DataType::U32) {
            return Err(format!(
                "has component type {ty:?}, expected an unsigned integer"
            ));
        }
        self.check_extent(accessor)?;
        let mut out = vec![0u32; accessor.count()];
        self.read_elements(accessor, |i, element| out[i] = read_uint(ty, element))?;
        Ok(out)
    }

    /// Checks, before anything is allocated for it, that an accessor's elements lie in its
    /// buffer view (so that its count is backed by the file's bytes), or, for one made only of
    /// sparse values, that its count is within [`MAX_SPARSE_BASE_ELEMENTS`].
    fn check_extent(&self, accessor: &gltf::Accessor<'_>) -> Result<(), String> {
        let count = accessor.count();
        if count == 0 {
            return Err("has count 0".into());
        }
        match accessor.view() {
            Some(view) => {
                let bytes = self.view_bytes(&view)?;
                let elem = accessor.size();
                let stride = view.stride().unwrap_or(elem);
                if stride < elem {
                    return Err(format!(
                        "buffer view {} has stride {stride}, shorter than the {elem}-byte element",
                        view.index()
                    ));
                }
                let end = stride
                    .checked_mul(count - 1)
                    .and_then(|n| n.checked_add(elem))
                    .and_then(|n| n.checked_add(accessor.offset()));
                if end.is_none_or(|end| end > bytes.len()) {
                    return Err(format!(
                        "{count} elements at offset {} with stride {stride} read past the end of \
                         buffer view {} ({} bytes)",
                        accessor.offset(),
                        view.index(),
                        bytes.len()
                    ));
                }
                Ok(())
            }
            None if count > MAX_SPARSE_BASE_ELEMENTS => Err(format!(
                "has {count} elements but no buffer view: more than the \
                 {MAX_SPARSE_BASE_ELEMENTS} an accessor of zeros (and sparse values) may have"
            )),
            None => Ok(()),
        }
    }

    /// Calls `put(index, element bytes)` for every element: the dense data (zeros without a
    /// buffer view), then the sparse substitutions.
    fn read_elements(
        &self,
        accessor: &gltf::Accessor<'_>,
        mut put: impl FnMut(usize, &[u8]),
    ) -> Result<(), String> {
        self.check_extent(accessor)?;
        let count = accessor.count();
        let elem = accessor.size();
        if let Some(view) = accessor.view() {
            let bytes = self.view_bytes(&view)?;
            let stride = view.stride().unwrap_or(elem);
            for i in 0..count {
                let start = accessor.offset() + i * stride;
                put(i, &bytes[start..start + elem]);
            }
        } else {
            // No buffer view: zeros (then the sparse values), as the specification says.
            let zeros = vec![0u8; elem];
            for i in 0..count {
                put(i, &zeros);
            }
        }
        if let Some(sparse) = accessor.sparse() {
            let n = sparse.count();
            let indices = sparse.indices();
            let index_type = match indices.index_type() {
                gltf::accessor::sparse::IndexType::U8 => DataType::U8,
                gltf::accessor::sparse::IndexType::U16 => DataType::U16,
                gltf::accessor::sparse::IndexType::U32 => DataType::U32,
            };
            let index_bytes = self.view_bytes(&indices.view())?;
            let values = sparse.values();
            let value_bytes = self.view_bytes(&values.view())?;
            let index_size = index_type.size();
            let fits = |bytes: &[u8], offset: usize, size: usize| {
                n.checked_mul(size)
                    .and_then(|len| len.checked_add(offset))
                    .is_some_and(|end| end <= bytes.len())
            };
            if !fits(index_bytes, indices.offset(), index_size)
                || !fits(value_bytes, values.offset(), elem)
            {
                return Err(format!(
                    "its {n} sparse indices or values read past the end of their buffer views"
                ));
            }
            for k in 0..n {
                let at = indices.offset() + k * index_size;
                let target = read_uint(index_type, &index_bytes[at..at + index_size]) as usize;
                if target >= count {
                    return Err(format!(
                        "sparse index {target} is out of range for {count} elements"
                    ));
                }
                let v = values.offset() + k * elem;
                put(target, &value_bytes[v..v + elem]);
            }
        }
        Ok(())
    }
}

/// One little-endian unsigned integer component.
fn read_uint(ty: DataType, b: &[u8]) -> u32 {
    match ty {
        DataType::U8 => u32::from(b[0]),
        DataType::U16 => u32::from(u16::from_le_bytes([b[0], b[1]])),
        _ => u32::from_le_bytes([b[0], b[1], b[2], b[3]]),
    }
}

/// One little-endian component as a float (glTF 2.0 §3.11 for normalized integers).
fn component_f32(ty: DataType, normalized: bool, b: &[u8]) -> f32 {
    match ty {
        DataType::F32 => f32::from_le_bytes([b[0], b[1], b[2], b[3]]),
        DataType::U8 => {
            let v = f32::from(b[0]);
            if normalized { v / 255.0 } else { v }
        }
        DataType::I8 => {
            let v = f32::from(b[0] as i8);
            if normalized { (v / 127.0).max(-1.0) } else { v }
        }
        DataType::U16 => {
            let v = f32::from(u16::from_le_bytes([b[0], b[1]]));
            if normalized { v / 65535.0 } else { v }
        }
        DataType::I16 => {
            let v = f32::from(i16::from_le_bytes([b[0], b[1]]));
            if normalized {
                (v / 32767.0).max(-1.0)
            } else {
                v
            }
        }
        DataType::U32 => u32::from_le_bytes([b[0], b[1], b[2], b[3]]) as f32,
    }
}

/// Decodes one `EXT_meshopt_compression` buffer view into its plain bytes.
fn decode_meshopt_view(
    index: usize,
    ext: &serde_json::Value,
    buffers: &[Vec<u8>],
) -> Result<Vec<u8>, String> {
    let fail = |why: String| format!("buffer view {index} (EXT_meshopt_compression): {why}");
    let field = |name: &str| ext.get(name).and_then(serde_json::Value::as_u64);
    let buffer = field("buffer").ok_or_else(|| fail("has no source buffer".into()))? as usize;
    let offset = field("byteOffset").unwrap_or(0) as usize;
    let length = field("byteLength").ok_or_else(|| fail("has no byteLength".into()))? as usize;
    let stride = field("byteStride").ok_or_else(|| fail("has no byteStride".into()))? as usize;
    let count = field("count").ok_or_else(|| fail("has no count".into()))? as usize;
    let mode = ext.get("mode").and_then(|m| m.as_str()).unwrap_or("");
    let filter = ext.get("filter").and_then(|m| m.as_str()).unwrap_or("NONE");
    let source = buffers
        .get(buffer)
        .and_then(|b| {
            offset
                .checked_add(length)
                .and_then(|end| b.get(offset..end))
        })
        .ok_or_else(|| {
            fail(format!(
                "its {length} bytes at {offset} lie outside buffer {buffer}"
            ))
        })?;
    let size = count
        .checked_mul(stride)
        .filter(|&size| size <= MAX_DECODED_VIEW_BYTES)
        .ok_or_else(|| {
            fail(format!(
                "{count} elements of {stride} bytes exceed the {MAX_DECODED_VIEW_BYTES}-byte budget"
            ))
        })?;
    let decoded = match mode {
        "ATTRIBUTES" => {
            if stride == 0 || !stride.is_multiple_of(4) || stride > 256 {
                return Err(fail(format!(
                    "byteStride {stride} is not a multiple of 4 up to 256"
                )));
            }
            let mut out = meshopt_decode::vertices(source, count, stride)
                .map_err(|e| fail(format!("cannot decode vertex data ({e})")))?;
            meshopt_decode::filter(&mut out, count, stride, filter).map_err(fail)?;
            out
        }
        "TRIANGLES" | "INDICES" => {
            if stride != 2 && stride != 4 {
                return Err(fail(format!("index byteStride {stride} is not 2 or 4")));
            }
            if mode == "TRIANGLES" && !count.is_multiple_of(3) {
                return Err(fail(format!(
                    "TRIANGLES count {count} is not a multiple of 3"
                )));
            }
            meshopt_decode::indices(source, count, stride, mode == "TRIANGLES")
                .map_err(|e| fail(format!("cannot decode index data ({e})")))?
        }
        other => return Err(fail(format!("unknown mode {other:?}"))),
    };
    debug_assert_eq!(decoded.len(), size);
    Ok(decoded)
}

/// The meshoptimizer decoders (the `meshopt` crate) and the extension's filters.
mod meshopt_decode {
    /// Decodes `count` vertices of `stride` bytes (a multiple of 4 up to 256).
    pub fn vertices(source: &[u8], count: usize, stride: usize) -> Result<Vec<u8>, String> {
        // The crate decodes into an element type of the stride's size: one per stride.
        macro_rules! by_stride {
            ($($words:literal)+) => {
                match stride / 4 {
                    $($words => meshopt::encoding::decode_vertex_buffer::<[u32; $words]>(
                        source, count,
                    )
                    .map(|v| bytemuck::cast_slice::<[u32; $words], u8>(&v).to_vec()),)+
                    _ => {
                        return Err(format!(
                            "byteStride {stride} is past the 128 bytes omnicave decodes"
                        ));
                    }
                }
            };
        }
        let decoded = by_stride!(1 2 3 4 5 6 7 8 9 10 11 12 13 14 15 16 17 18 19 20 21 22 23 24
            25 26 27 28 29 30 31 32);
        decoded.map_err(|e| e.to_string())
    }

    /// Decodes `count` triangle indices of `stride` bytes (mode `TRIANGLES`). Mode `INDICES`
    /// (index sequences, which gltfpack writes only for points and lines) is refused.
    pub fn indices(
        source: &[u8],
        count: usize,
        stride: usize,
        triangles: bool,
    ) -> Result<Vec<u8>, String> {
        if !triangles {
            return Err("mode INDICES (an index sequence) is not supported".into());
        }
        let wide: Vec<u32> = meshopt::encoding::decode_index_buffer::<u32>(source, count)
            .map_err(|e| e.to_string())?;
        Ok(if stride == 2 {
            wide.iter()
                .flat_map(|&i| (i as u16).to_le_bytes())
                .collect()
        } else {
            wide.iter().flat_map(|&i| i.to_le_bytes()).collect()
        })
    }

    /// Undoes the extension's filter in place (its Appendix B).
    pub fn filter(
        data: &mut [u8],
        count: usize,
        stride: usize,
        filter: &str,
    ) -> Result<(), String> {
        match filter {
            "NONE" => Ok(()),
            "OCTAHEDRAL" => match stride {
                4 => {
                    octahedral::<1>(data, count);
                    Ok(())
                }
                8 => {
                    octahedral::<2>(data, count);
                    Ok(())
                }
                _ => Err(format!("OCTAHEDRAL needs byteStride 4 or 8, not {stride}")),
            },
            "QUATERNION" if stride == 8 => {
                quaternion(data, count);
                Ok(())
            }
            "QUATERNION" => Err(format!("QUATERNION needs byteStride 8, not {stride}")),
            "EXPONENTIAL" => {
                exponential(data);
                Ok(())
            }
            other => Err(format!("unknown filter {other:?}")),
        }
    }

    fn get<const B: usize>(data: &[u8], at: usize) -> f32 {
        if B == 1 {
            f32::from(data[at] as i8)
        } else {
            f32::from(i16::from_le_bytes([data[at], data[at + 1]]))
        }
    }

    fn put<const B: usize>(data: &mut [u8], at: usize, v: i32) {
        if B == 1 {
            data[at] = (v as i8) as u8;
        } else {
            data[at..at + 2].copy_from_slice(&(v as i16).to_le_bytes());
        }
    }

    /// Rounds half away from zero, as the reference decoder does.
    fn round(v: f32) -> i32 {
        (v + if v >= 0.0 { 0.5 } else { -0.5 }) as i32
    }

    /// Octahedral unit vectors: x and y stored, z encoding 1.0 at the same bit count;
    /// the fourth component is kept.
    fn octahedral<const B: usize>(data: &mut [u8], count: usize) {
        let max = ((1i32 << (8 * B - 1)) - 1) as f32;
        for i in 0..count {
            let at = i * 4 * B;
            let mut x = get::<B>(data, at);
            let mut y = get::<B>(data, at + B);
            let z = get::<B>(data, at + 2 * B) - x.abs() - y.abs();
            let t = z.min(0.0);
            x += if x >= 0.0 { t } else { -t };
            y += if y >= 0.0 { t } else { -t };
            let l = (x * x + y * y + z * z).sqrt();
            let s = if l > 0.0 { max / l } else { 0.0 };
            put::<B>(data, at, round(x * s));
            put::<B>(data, at + B, round(y * s));
            put::<B>(data, at + 2 * B, round(z * s));
        }
    }

    /// Unit quaternions: three components stored, the largest dropped and its index in the
    /// low bits of the fourth, with the components' scale in its high bits.
    fn quaternion(data: &mut [u8], count: usize) {
        let scale = std::f32::consts::FRAC_1_SQRT_2;
        for i in 0..count {
            let at = i * 8;
            let c = |k: usize| i16::from_le_bytes([data[at + 2 * k], data[at + 2 * k + 1]]);
            let last = c(3);
            let sf = i32::from(last) | 3;
            let ss = scale / sf as f32;
            let x = f32::from(c(0)) * ss;
            let y = f32::from(c(1)) * ss;
            let z = f32::from(c(2)) * ss;
            let w = (1.0 - x * x - y * y - z * z).max(0.0).sqrt();
            let qc = (last & 3) as usize;
            let mut out = [0i16; 4];
            out[(qc + 1) & 3] = round(x * 32767.0) as i16;
            out[(qc + 2) & 3] = round(y * 32767.0) as i16;
            out[(qc + 3) & 3] = round(z * 32767.0) as i16;
            out[qc & 3] = round(w * 32767.0) as i16;
            for (k, v) in out.iter().enumerate() {
                data[at + 2 * k..at + 2 * k + 2].copy_from_slice(&v.to_le_bytes());
            }
        }
    }

    /// Floats as a 24-bit signed mantissa and an 8-bit signed exponent per 32-bit component.
    fn exponential(data: &mut [u8]) {
        for word in data.chunks_exact_mut(4) {
            let v = u32::from_le_bytes([word[0], word[1], word[2], word[3]]);
            let m = ((v << 8) as i32) >> 8;
            let e = (v as i32) >> 24;
            let value = m as f32 * (e as f32).exp2();
            word.copy_from_slice(&value.to_le_bytes());
        }
    }

    #[cfg(test)]
    mod tests {
        use super::*;

        #[test]
        fn octahedral_normals_decode_to_unit_vectors() {
            // Encoded as the extension's encoder does: octahedral map of the unit vector,
            // z stores 1.0 (127) at the same bit count.
            for n in [
                [0.0f32, 0.0, 1.0],
                [0.6, 0.0, -0.8],
                [-0.48, 0.6, 0.64],
                [0.0, -1.0, 0.0],
            ] {
                let sum = n[0].abs() + n[1].abs() + n[2].abs();
                let (mut u, mut v) = (n[0] / sum, n[1] / sum);
                if n[2] < 0.0 {
                    let (pu, pv) = (u, v);
                    u = (1.0 - pv.abs()) * if pu >= 0.0 { 1.0 } else { -1.0 };
                    v = (1.0 - pu.abs()) * if pv >= 0.0 { 1.0 } else { -1.0 };
                }
                let mut data = vec![
                    round(u * 127.0) as i8 as u8,
                    round(v * 127.0) as i8 as u8,
                    127,
                    0,
                ];
                octahedral::<1>(&mut data, 1);
                let got = [0, 1, 2].map(|k| f32::from(data[k] as i8) / 127.0);
                for k in 0..3 {
                    // 8-bit octahedral: a few hundredths.
                    assert!((got[k] - n[k]).abs() < 0.03, "{n:?} → {got:?}");
                }
            }
        }

        #[test]
        fn exponential_values_decode_to_mantissa_times_two_to_the_exponent() {
            let encode =
                |m: i32, e: i32| (((e as u32) << 24) | (m as u32 & 0x00ff_ffff)).to_le_bytes();
            let mut data = [encode(3, -1), encode(-5, 2), encode(1000, 0)].concat();
            exponential(&mut data);
            let got: Vec<f32> = data
                .chunks_exact(4)
                .map(|w| f32::from_le_bytes([w[0], w[1], w[2], w[3]]))
                .collect();
            assert_eq!(got, vec![1.5, -20.0, 1000.0]);
        }

        #[test]
        fn quaternions_rebuild_their_dropped_component() {
            // (x, y, z, w) = (0.5, 0.5, 0.5, 0.5) with w dropped (index 3 → stored order
            // starts after it), scale bits all ones.
            let s = 0x7ff0i16 | 3;
            let q = 0.5 / std::f32::consts::FRAC_1_SQRT_2 * f32::from(s | 3);
            let stored = [q as i16, q as i16, q as i16, (s & !3) | 3];
            let mut data: Vec<u8> = stored.iter().flat_map(|v| v.to_le_bytes()).collect();
            quaternion(&mut data, 1);
            let got: Vec<f32> = data
                .chunks_exact(2)
                .map(|w| f32::from(i16::from_le_bytes([w[0], w[1]])) / 32767.0)
                .collect();
            for v in got {
                assert!((v - 0.5).abs() < 1e-3, "{v}");
            }
        }
    }
}
