//! GPU timestamps around each stage of a walls frame (shadows; per view: tessellation culling,
//! split rounds, sort, scene draw, sky, resolve), resolved for the read-back ring or a blocking
//! read, and the per-stage breakdown computed from them.
//!
//! The layout is fixed by the number of views, so a read-back needs no record of what was
//! written: timestamp 0 starts the frame, 1 ends the pose pass (skins and morph targets),
//! 2 the shadow maps (and the frame's uploads), then each view writes [`STAGES_PER_VIEW`] in [`ViewStage`] order. A stage a view skips (no
//! tessellation, no sky) is written right after the one before it and takes no time.

/// What a stage of one view is.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ViewStage {
    /// cs_init: back-face and frustum culling, and the first `SPLIT_LEVELS` (12) levels of
    /// splitting, which it does itself.
    TessCull,
    /// The split rounds beyond those levels (prepare + split, `max_depth` / `SPLIT_LEVELS`
    /// times, rounded up, less one): none at the default maximum depth of 12.
    TessSplit,
    /// Sorting the output by draw and writing the indirect draws.
    TessSort,
    /// The scene's draws (and the wand's).
    Scene,
    /// The sky's draw.
    Sky,
    /// The end of the render pass: MSAA resolve and stores.
    Resolve,
}

pub const STAGES_PER_VIEW: usize = 6;

impl ViewStage {
    pub const ALL: [ViewStage; STAGES_PER_VIEW] = [
        ViewStage::TessCull,
        ViewStage::TessSplit,
        ViewStage::TessSort,
        ViewStage::Scene,
        ViewStage::Sky,
        ViewStage::Resolve,
    ];

    /// Whether the stage belongs to the tessellator (culling, splitting, sorting).
    pub fn is_tessellation(self) -> bool {
        matches!(
            self,
            ViewStage::TessCull | ViewStage::TessSplit | ViewStage::TessSort
        )
    }

    /// Short name (report columns, the panel).
    pub fn name(self) -> &'static str {
        match self {
            ViewStage::TessCull => "tess cull",
            ViewStage::TessSplit => "tess split",
            ViewStage::TessSort => "tess sort",
            ViewStage::Scene => "scene",
            ViewStage::Sky => "sky",
            ViewStage::Resolve => "resolve",
        }
    }
}

/// Timestamps a walls frame of `views` views writes.
pub fn timestamp_count(views: usize) -> u32 {
    (FIRST_VIEW_STAMP + STAGES_PER_VIEW * views) as u32
}

/// Timestamps before the first view's.
const FIRST_VIEW_STAMP: usize = 3;

/// Index of the timestamp that ends `stage` of view `view`.
pub fn stage_end(view: usize, stage: ViewStage) -> u32 {
    (FIRST_VIEW_STAMP + STAGES_PER_VIEW * view + stage as usize) as u32
}

/// Index of the timestamp that ends the pose pass.
pub const POSE_END: u32 = 1;
/// Index of the timestamp that ends the shadow maps.
pub const SHADOWS_END: u32 = 2;

/// Where one frame's GPU time went, ms.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct FrameBreakdown {
    /// From the first timestamp to the last.
    pub total_ms: f64,
    /// The pose pass: skins and morph targets (0 for a static scene or an unchanged pose).
    pub pose_ms: f64,
    /// Shadow maps (and uploads before the first view).
    pub shadows_ms: f64,
    /// Each view's stages, in [`ViewStage::ALL`] order.
    pub views: Vec<[f64; STAGES_PER_VIEW]>,
    /// False when the adapter cannot write timestamps inside passes: a tessellation's time is
    /// then all under `tess cull`, and scene, sky and resolve all under `scene`.
    pub inside_passes: bool,
}

impl FrameBreakdown {
    /// A stage summed over the views.
    pub fn stage_ms(&self, stage: ViewStage) -> f64 {
        self.views.iter().map(|v| v[stage as usize]).sum()
    }

    /// Fills `self` from resolved timestamps (8 bytes each) of a frame of `views` views.
    /// False (and `self` left empty) when they are missing or out of order (a counter that
    /// wrapped, a driver that reordered them).
    pub fn read(
        &mut self,
        bytes: &[u8],
        views: usize,
        period_ns: f32,
        inside_passes: bool,
    ) -> bool {
        self.views.clear();
        self.total_ms = 0.0;
        self.shadows_ms = 0.0;
        self.pose_ms = 0.0;
        self.inside_passes = inside_passes;
        let count = timestamp_count(views) as usize;
        let tick = |i: usize| {
            bytes
                .get(i * 8..i * 8 + 8)
                .and_then(|b| b.try_into().ok())
                .map(u64::from_le_bytes)
        };
        let ms = |a: u64, b: u64| (b - a) as f64 * f64::from(period_ns) * 1e-6;
        let mut previous = match tick(0) {
            Some(t) => t,
            None => return false,
        };
        let first = previous;
        for i in 1..count {
            let Some(t) = tick(i) else {
                self.views.clear();
                return false;
            };
            if t < previous {
                self.views.clear();
                return false;
            }
            let d = ms(previous, t);
            if i == POSE_END as usize {
                self.pose_ms = d;
            } else if i == SHADOWS_END as usize {
                self.shadows_ms = d;
            } else {
                let k = i - FIRST_VIEW_STAMP;
                let (view, stage) = (k / STAGES_PER_VIEW, k % STAGES_PER_VIEW);
                if stage == 0 {
                    self.views.push([0.0; STAGES_PER_VIEW]);
                }
                if let Some(v) = self.views.get_mut(view) {
                    v[stage] = d;
                }
            }
            previous = t;
        }
        self.total_ms = ms(first, previous);
        true
    }
}

/// The query set and its resolve buffer, sized for the walls' views (grown, never per frame).
#[derive(Debug)]
pub struct FrameTimer {
    pub queries: wgpu::QuerySet,
    pub resolve: wgpu::Buffer,
    pub period_ns: f32,
    /// Timestamps the query set holds.
    capacity: u32,
    /// Whether timestamps may be written inside passes.
    pub inside_passes: bool,
}

impl FrameTimer {
    /// A timer for frames of up to `views` views (at least the panorama's two timestamps).
    pub fn new(device: &wgpu::Device, queue: &wgpu::Queue, views: usize, inside: bool) -> Self {
        let capacity = timestamp_count(views).max(2);
        Self {
            queries: device.create_query_set(&wgpu::QuerySetDescriptor {
                label: Some("FrameTimer::queries"),
                ty: wgpu::QueryType::Timestamp,
                count: capacity,
            }),
            resolve: device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("FrameTimer::resolve"),
                size: u64::from(capacity) * 8,
                usage: wgpu::BufferUsages::QUERY_RESOLVE | wgpu::BufferUsages::COPY_SRC,
                mapped_at_creation: false,
            }),
            period_ns: queue.get_timestamp_period(),
            capacity,
            inside_passes: inside,
        }
    }

    /// Grows the query set when a frame has more views than it holds (a CAVE reconfigured).
    pub fn ensure_views(&mut self, device: &wgpu::Device, queue: &wgpu::Queue, views: usize) {
        if timestamp_count(views) > self.capacity {
            *self = Self::new(device, queue, views, self.inside_passes);
        }
    }

    /// Stage marks for one view's tessellation.
    pub fn tess_marks(&self, view: usize) -> TessMarks<'_> {
        TessMarks {
            queries: &self.queries,
            cull: stage_end(view, ViewStage::TessCull),
            split: stage_end(view, ViewStage::TessSplit),
            sort: stage_end(view, ViewStage::TessSort),
            inside_passes: self.inside_passes,
        }
    }

    /// Writes the timestamp ending `stage` of `view` at encoder level (between passes).
    pub fn mark(&self, encoder: &mut wgpu::CommandEncoder, view: usize, stage: ViewStage) {
        encoder.write_timestamp(&self.queries, stage_end(view, stage));
    }

    /// Writes the timestamp ending `stage` of `view` inside a render pass, if the adapter
    /// allows; returns whether it did (if not, write it with [`Self::mark`] after the pass).
    pub fn mark_in_pass(
        &self,
        pass: &mut wgpu::RenderPass<'_>,
        view: usize,
        stage: ViewStage,
    ) -> bool {
        if self.inside_passes {
            pass.write_timestamp(&self.queries, stage_end(view, stage));
        }
        self.inside_passes
    }
}

/// Where a view's tessellation writes the ends of its culling, split rounds and sort.
#[derive(Debug, Clone, Copy)]
pub struct TessMarks<'a> {
    pub queries: &'a wgpu::QuerySet,
    pub cull: u32,
    pub split: u32,
    pub sort: u32,
    /// Inside the compute pass; otherwise all three after it.
    pub inside_passes: bool,
}

#[cfg(test)]
mod tests {
    use super::*;

    fn bytes(ticks: &[u64]) -> Vec<u8> {
        ticks.iter().flat_map(|t| t.to_le_bytes()).collect()
    }

    #[test]
    fn breakdown_attributes_each_interval_to_its_stage() {
        // One view: start 0, pose end 0.5 ms, shadows end 1 ms, then cull 2, split 4, sort 5,
        // scene 9, sky 10, resolve 12 (1 ns per tick).
        let ticks: Vec<u64> = [0.0, 0.5, 1.0, 2.0, 4.0, 5.0, 9.0, 10.0, 12.0]
            .iter()
            .map(|ms| (ms * 1e6) as u64)
            .collect();
        let mut b = FrameBreakdown::default();
        assert!(b.read(&bytes(&ticks), 1, 1.0, true));
        assert_eq!(b.total_ms, 12.0);
        assert_eq!(b.pose_ms, 0.5);
        assert_eq!(b.shadows_ms, 0.5);
        assert_eq!(b.views, vec![[1.0, 2.0, 1.0, 4.0, 1.0, 2.0]]);
        assert_eq!(b.stage_ms(ViewStage::Scene), 4.0);
        // Out of order or too short: refused, nothing half-filled.
        let mut bad = ticks.clone();
        bad[5] = 0;
        assert!(!b.read(&bytes(&bad), 1, 1.0, true));
        assert!(b.views.is_empty());
        assert!(!b.read(&bytes(&ticks[..6]), 1, 1.0, true));
        assert_eq!(timestamp_count(6), 39);
        assert_eq!(stage_end(1, ViewStage::TessCull), 9);
    }
}
