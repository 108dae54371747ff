//! Where the tessellator and the tessellated draws bind the scene's vertices: one buffer, as
//! storage, in up to [`VERTEX_WINDOWS`] windows, so a scene whose vertices exceed the GPU's
//! largest storage binding is still tessellated (the shaders pick the window, see
//! `vertex_window` in shaders/common.wgsl).

/// Windows the shaders declare. Keep in sync with `VERTEX_WINDOWS` in shaders/common.wgsl.
/// Four bind up to four times the largest storage binding (on lavapipe, 512 MiB: 7.46 million
/// vertices); each window costs a storage binding in the tessellator's compute stage, which
/// binds 15 of the 16 the renderer asks for.
pub const VERTEX_WINDOWS: usize = 4;

/// Bytes of one window binding: offset into the vertex buffer and size.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Window {
    pub offset: u64,
    pub size: u64,
}

/// The vertices take more than the windows can bind.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct WindowsTooSmall {
    /// The most the windows bind, bytes.
    pub limit: u64,
}

/// The windows of a vertex buffer of `buffer_bytes` holding vertices of `vertex_bytes`, each
/// binding at most `binding_limit` bytes at offsets that are multiples of `alignment`
/// (`min_storage_buffer_offset_alignment`).
///
/// A buffer within the limit is bound whole as window 0 (the others repeat it and are never
/// read). A larger one is cut into windows of W whole vertices each, W the largest multiple
/// of the vertices that fill an aligned offset; the last window takes the rest. The shaders
/// read W as window 0's length, so every window but the last is exactly W vertices long.
pub fn plan_windows(
    buffer_bytes: u64,
    vertex_bytes: u64,
    binding_limit: u64,
    alignment: u64,
) -> Result<[Window; VERTEX_WINDOWS], WindowsTooSmall> {
    let whole = Window {
        offset: 0,
        size: buffer_bytes,
    };
    if buffer_bytes <= binding_limit {
        return Ok([whole; VERTEX_WINDOWS]);
    }
    // Vertices per aligned step: the smallest count whose bytes are a multiple of the
    // alignment (32 vertices of 72 bytes at 256).
    let alignment = alignment.max(1);
    let vertex_bytes = vertex_bytes.max(1);
    let step = alignment / gcd(vertex_bytes, alignment);
    let window_vertices = binding_limit / vertex_bytes / step * step;
    let window_bytes = window_vertices * vertex_bytes;
    let limit = window_bytes * VERTEX_WINDOWS as u64;
    if window_bytes == 0 || buffer_bytes > limit {
        return Err(WindowsTooSmall { limit });
    }
    let mut windows = [whole; VERTEX_WINDOWS];
    for (k, window) in windows.iter_mut().enumerate() {
        let offset = k as u64 * window_bytes;
        if offset < buffer_bytes {
            *window = Window {
                offset,
                size: window_bytes.min(buffer_bytes - offset),
            };
        } else {
            // Past the vertices: never read; bound to window 0's bytes to be valid.
            *window = Window {
                offset: 0,
                size: window_bytes,
            };
        }
    }
    Ok(windows)
}

/// A bind group entry for `window` of `buffer`.
pub fn window_entry(
    buffer: &wgpu::Buffer,
    binding: u32,
    window: Window,
) -> wgpu::BindGroupEntry<'_> {
    wgpu::BindGroupEntry {
        binding,
        resource: wgpu::BindingResource::Buffer(wgpu::BufferBinding {
            buffer,
            offset: window.offset,
            size: wgpu::BufferSize::new(window.size),
        }),
    }
}

fn gcd(a: u64, b: u64) -> u64 {
    if b == 0 { a } else { gcd(b, a % b) }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The window and local vertex the shaders read vertex `v` from (mirrors
    /// `vertex_window` in shaders/common.wgsl): W is window 0's length in vertices.
    fn shader_window(
        v: u64,
        windows: &[Window; VERTEX_WINDOWS],
        vertex_bytes: u64,
    ) -> (usize, u64) {
        let w = windows[0].size / vertex_bytes;
        if v < w {
            return (0, v);
        }
        let k = (v / w).min(VERTEX_WINDOWS as u64 - 1);
        (k as usize, v - k * w)
    }

    #[test]
    fn every_vertex_is_read_from_a_window_that_holds_it_at_its_own_bytes() {
        for (vertices, limit, alignment) in [
            (1_000u64, 1u64 << 20, 256u64),
            (4_000_000, 128 << 20, 256),
            (7_000, 72 * 2_000 + 17, 256),
            (7_000, 72 * 2_000, 64),
            (7_999, 72 * 2_016, 256),
            (5, 72 * 4, 32),
        ] {
            let bytes = vertices * 72;
            let windows = plan_windows(bytes, 72, limit, alignment).unwrap();
            for w in &windows {
                assert!(w.size <= limit, "{w:?} over {limit}");
                assert_eq!(w.offset % alignment, 0, "{w:?}");
                assert!(w.offset + w.size <= bytes, "{w:?} past the buffer");
            }
            for v in (0..vertices).step_by(7).chain([vertices - 1]) {
                let (k, local) = shader_window(v, &windows, 72);
                let at = windows[k].offset + local * 72;
                assert_eq!(at, v * 72, "vertex {v} read from window {k}");
                assert!(
                    local * 72 + 72 <= windows[k].size,
                    "vertex {v} past window {k}"
                );
            }
        }
    }

    #[test]
    fn vertices_past_four_windows_are_refused_with_the_limit() {
        let limit = 72 * 1_024;
        let fits = plan_windows(4 * limit, 72, limit, 256);
        assert!(fits.is_ok());
        let err = plan_windows(4 * limit + 72, 72, limit, 256).unwrap_err();
        assert_eq!(err.limit, 4 * limit);
        // A limit smaller than one aligned step of vertices binds nothing.
        assert!(plan_windows(72 * 100, 72, 72 * 31, 256).is_err());
    }
}
