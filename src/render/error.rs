//! Everything that can go wrong in the render layer (and in setting up its tessellator).

/// Everything that can go wrong in the render layer.
#[derive(Debug, thiserror::Error)]
pub enum RenderError {
    #[error(
        "no usable GPU adapter: {0} (is a Vulkan driver such as mesa-vulkan-drivers installed?)"
    )]
    NoAdapter(String),
    #[error("cannot create the GPU device: {0}")]
    Device(String),
    #[error("the GPU stopped working: {0}")]
    GpuFault(String),
    #[error("reading images back from the GPU failed: {0}")]
    Readback(String),
    #[error("MSAA ×{0} is not supported here (use 1 or 4)")]
    Msaa(u32),
    #[error(transparent)]
    Tessellation(#[from] TessError),
    #[error(
        "the panorama's geometric route needs the tessellator, which this adapter cannot run \
         (use the image route)"
    )]
    PanoramaNeedsTessellator,
    #[error("a panorama of {0}×{1} pixels is empty or exceeds this device's texture limit")]
    PanoramaSize(u32, u32),
    #[error("sky faces of {size}×{size} exceed this device's texture limit of {max}")]
    SkyTooLarge { size: u32, max: u32 },
    #[error(
        "the scene's {what} take {bytes} bytes, more than the largest buffer, {limit} bytes \
         (this GPU's max_buffer_size, or the limit set): split the primitive in the file"
    )]
    SceneTooLarge {
        what: &'static str,
        bytes: u64,
        limit: u64,
    },
    #[error(
        "texture {name} is {width}×{height}; this GPU's textures are at most {max} pixels a \
         side (max_texture_dimension_2d): lower budgets.max_texture_side to {max}"
    )]
    TextureTooLarge {
        name: String,
        width: u32,
        height: u32,
        max: u32,
    },
    #[error(
        "{what} would be {width}×{height} pixels; this GPU's images are at most {max} a side \
         (max_texture_dimension_2d)"
    )]
    TextureLimit {
        what: String,
        width: u32,
        height: u32,
        max: u32,
    },
    #[error("the GPU could not hold the scene (out of memory?) {0}")]
    OutOfMemory(String),
}

/// Everything that can go wrong setting up the tessellator.
#[derive(Debug, thiserror::Error)]
pub enum TessError {
    #[error(
        "the scene is split over {0} buffers (it is larger than this GPU's largest buffer); \
         the tessellator binds it whole: use a mode without tessellation or a smaller scene"
    )]
    SplitScene(usize),
    #[error(
        "the scene's {what} take {bytes} bytes; the tessellator binds at most {limit} bytes \
         of them on this GPU (set by its max_storage_buffer_binding_size): use a mode \
         without tessellation or a smaller scene"
    )]
    BindingTooLarge {
        what: &'static str,
        bytes: u64,
        limit: u64,
    },
}
