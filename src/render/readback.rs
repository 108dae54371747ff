//! One ring of staging buffers for what a frame reads back from the GPU (its timestamps and
//! the walls' tessellation counts): copied at the end of the frame's work, mapped
//! asynchronously and never waited on. A result arrives a few frames later, tagged with the
//! frame it belongs to; a frame that finds every slot in flight is simply not read back.

use std::sync::Arc;
use std::sync::atomic::{AtomicU8, Ordering};

const FREE: u8 = 0;
const IN_FLIGHT: u8 = 1;
const DONE: u8 = 2;
const FAILED: u8 = 3;

/// Frames in flight at once; more would only mean older numbers.
pub const SLOTS: usize = 3;

/// What a slot holds: `timestamps` timestamps (8 bytes each; 0 when not timed) at 0, then
/// `tess_views` views' tessellation statistics at [`SlotLayout::stats_offset`].
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct SlotLayout {
    pub timestamps: u32,
    pub tess_views: usize,
}

impl SlotLayout {
    /// Where the tessellation statistics start.
    pub fn stats_offset(&self) -> u64 {
        u64::from(self.timestamps) * 8
    }
}

#[derive(Debug)]
struct Slot {
    buffer: wgpu::Buffer,
    /// Set to done or failed by the map callback.
    state: Arc<AtomicU8>,
    frame: u64,
    layout: SlotLayout,
}

/// The ring (see the module documentation).
#[derive(Debug)]
pub struct ReadbackRing {
    slots: Vec<Slot>,
    size: u64,
    /// The slot the frame being encoded copies into, mapped by [`Self::finish`].
    staged: Option<usize>,
}

impl ReadbackRing {
    /// A ring whose slots hold `size` bytes each.
    pub fn new(device: &wgpu::Device, size: u64) -> Self {
        let size = size.max(8).next_multiple_of(wgpu::COPY_BUFFER_ALIGNMENT);
        Self {
            slots: (0..SLOTS)
                .map(|i| Slot {
                    buffer: device.create_buffer(&wgpu::BufferDescriptor {
                        label: Some(&format!("ReadbackRing::slot {i}")),
                        size,
                        usage: wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::MAP_READ,
                        mapped_at_creation: false,
                    }),
                    state: Arc::new(AtomicU8::new(FREE)),
                    frame: 0,
                    layout: SlotLayout::default(),
                })
                .collect(),
            size,
            staged: None,
        }
    }

    /// Bytes each slot holds.
    pub fn slot_size(&self) -> u64 {
        self.size
    }

    /// A free slot for `frame`'s data laid out as `layout`, to copy into while encoding;
    /// `None` when every slot is still in flight.
    pub fn begin(&mut self, frame: u64, layout: SlotLayout) -> Option<&wgpu::Buffer> {
        let index = self
            .slots
            .iter()
            .position(|s| s.state.load(Ordering::Acquire) == FREE)?;
        let slot = &mut self.slots[index];
        slot.frame = frame;
        slot.layout = layout;
        self.staged = Some(index);
        Some(&slot.buffer)
    }

    /// After the frame's work is submitted: maps the slot it copied into.
    pub fn finish(&mut self) {
        let Some(index) = self.staged.take() else {
            return;
        };
        let slot = &self.slots[index];
        slot.state.store(IN_FLIGHT, Ordering::Release);
        let state = slot.state.clone();
        slot.buffer
            .map_async(wgpu::MapMode::Read, .., move |result| {
                let done = if result.is_ok() { DONE } else { FAILED };
                state.store(done, Ordering::Release);
            });
    }

    /// Hands every slot that has arrived to `take(frame, layout, bytes)`, oldest frame first,
    /// and frees it. Never waits (the caller polls the device without blocking first).
    pub fn collect(&mut self, mut take: impl FnMut(u64, SlotLayout, &[u8])) {
        let mut arrived = [(u64::MAX, 0usize); SLOTS];
        let mut count = 0;
        for (i, slot) in self.slots.iter().enumerate() {
            match slot.state.load(Ordering::Acquire) {
                DONE => {
                    arrived[count] = (slot.frame, i);
                    count += 1;
                }
                FAILED => slot.state.store(FREE, Ordering::Release),
                _ => {}
            }
        }
        arrived[..count].sort_unstable();
        for &(_, i) in &arrived[..count] {
            let slot = &self.slots[i];
            if let Ok(bytes) = slot.buffer.get_mapped_range(..) {
                take(slot.frame, slot.layout, &bytes);
            }
            slot.buffer.unmap();
            slot.state.store(FREE, Ordering::Release);
        }
    }
}
