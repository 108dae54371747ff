//! The pose pass (shaders/pose.wgsl): skins and morph targets posed in compute, written over
//! the deformed vertices of the scene's vertex buffer before shadows, tessellation and the
//! warp read it, so every later pass, eye and wall sees geometry already posed. The buffers
//! are uploaded once per scene; a frame writes only the matrices and weights (sizes fixed at
//! load) and dispatches once. Static vertices are not touched.

use bytemuck::{Pod, Zeroable};

use super::bindings::{storage_entry, uniform_entry};
use super::scene_gpu::SceneGpu;
use super::shaders;
use crate::scene::Scene;
use crate::scene::rig::{Playback, Pose, PoseAt, Rig};

/// Keep in sync with `PoseUniforms` in shaders/pose.wgsl (tests/gpu_layout.rs checks).
#[repr(C)]
#[derive(Debug, Clone, Copy, Pod, Zeroable)]
pub struct PoseUniforms {
    pub vertex_count: u32,
    pub groups_x: u32,
    pub pad0: u32,
    pub pad1: u32,
}

/// Keep in sync with `PoseDeformer` in shaders/pose.wgsl (tests/gpu_layout.rs checks).
#[repr(C)]
#[derive(Debug, Clone, Copy, Pod, Zeroable)]
pub struct PoseDeformer {
    pub first_vertex: u32,
    pub rest_offset: u32,
    pub first_matrix: u32,
    pub influences_per_vertex: u32,
    pub influence_offset: u32,
    pub target_count: u32,
    pub delta_offset: u32,
    pub first_weight: u32,
}

/// Keep in sync with `PoseRestVertex` in shaders/pose.wgsl (tests/gpu_layout.rs checks).
#[repr(C)]
#[derive(Debug, Clone, Copy, Pod, Zeroable)]
pub struct PoseRestVertex {
    pub position: [f32; 3],
    /// Which deformer it belongs to.
    pub deformer: u32,
    pub normal: [f32; 4],
    pub tangent: [f32; 4],
}

/// Storage buffers the pass binds in its one stage.
pub const POSE_STORAGE_BUFFERS: u32 = 7;
/// Threads per workgroup (`POSE_WORKGROUP` in the shader).
const WORKGROUP: u32 = 64;
/// Workgroups along one dimension (WebGPU's minimum limit).
const MAX_GROUPS_X: u32 = 65_535;

/// The pass's pipeline, built once per renderer.
#[derive(Debug)]
pub struct PosePipeline {
    layout: wgpu::BindGroupLayout,
    pipeline: wgpu::ComputePipeline,
}

impl PosePipeline {
    /// Compute pipelines built by [`PosePipeline::new`] (once per renderer).
    pub const PIPELINES: u64 = 1;

    pub fn new(device: &wgpu::Device) -> Self {
        let c = wgpu::ShaderStages::COMPUTE;
        let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("PosePipeline::layout"),
            entries: &[
                uniform_entry(0, false),
                storage_entry(1, true, c),
                storage_entry(2, true, c),
                storage_entry(3, true, c),
                storage_entry(4, true, c),
                storage_entry(5, true, c),
                storage_entry(6, true, c),
                storage_entry(7, false, c),
            ],
        });
        let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("PosePipeline::pipeline_layout"),
            bind_group_layouts: &[Some(&layout)],
            immediate_size: 0,
        });
        let module = shaders::module(device, "PosePipeline::shader", shaders::POSE);
        let pipeline = device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
            label: Some("PosePipeline::cs_pose"),
            layout: Some(&pipeline_layout),
            module: &module,
            entry_point: Some("cs_pose"),
            compilation_options: Default::default(),
            cache: None,
        });
        Self { layout, pipeline }
    }
}

/// A scene's pose inputs on the GPU, with the per-frame staging they are written from.
#[derive(Debug)]
pub struct PoseBuffers {
    bind_group: wgpu::BindGroup,
    matrices: wgpu::Buffer,
    weights: wgpu::Buffer,
    /// Per deformer: its first matrix and first weight.
    offsets: Vec<(u32, u32)>,
    groups: [u32; 2],
    /// The frame's matrices and weights, reused (their sizes never change).
    matrix_staging: Vec<[f32; 16]>,
    weight_staging: Vec<f32>,
}

fn entry(binding: u32, buffer: &wgpu::Buffer) -> wgpu::BindGroupEntry<'_> {
    wgpu::BindGroupEntry {
        binding,
        resource: buffer.as_entire_binding(),
    }
}

/// A storage buffer holding `bytes` (at least 64 bytes: bindings may not be empty).
fn storage_with(
    device: &wgpu::Device,
    queue: &wgpu::Queue,
    label: &str,
    bytes: &[u8],
) -> wgpu::Buffer {
    let padded = [0u8; 64];
    let contents = if bytes.is_empty() { &padded[..] } else { bytes };
    super::scene_gpu::buffer_with(device, queue, label, contents, wgpu::BufferUsages::STORAGE)
}

impl PoseBuffers {
    /// Uploads `rig`'s deformers (their vertices lie in `vertex_buffer`, the scene's).
    pub fn new(
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        pipeline: &PosePipeline,
        rig: &Rig,
        vertex_buffer: &wgpu::Buffer,
    ) -> Self {
        let mut deformers = Vec::with_capacity(rig.deformers.len());
        let mut rest = Vec::new();
        let mut influences: Vec<[u32; 2]> = Vec::new();
        let mut deltas: Vec<f32> = Vec::new();
        let mut offsets = Vec::with_capacity(rig.deformers.len());
        let (mut matrices, mut weights) = (0u32, 0u32);
        for (d, deformer) in rig.deformers.iter().enumerate() {
            let targets = deformer.targets.len() as u32;
            deformers.push(PoseDeformer {
                first_vertex: deformer.first_vertex,
                rest_offset: rest.len() as u32,
                first_matrix: matrices,
                influences_per_vertex: deformer.influences_per_vertex,
                influence_offset: influences.len() as u32,
                target_count: targets,
                delta_offset: deltas.len() as u32,
                first_weight: weights,
            });
            offsets.push((matrices, weights));
            matrices += deformer.matrix_count(rig) as u32;
            weights += targets;
            rest.extend(deformer.rest.iter().map(|v| PoseRestVertex {
                position: v.position,
                deformer: d as u32,
                normal: [v.normal[0], v.normal[1], v.normal[2], 0.0],
                tangent: v.tangent,
            }));
            influences.extend(
                deformer
                    .influences
                    .iter()
                    .map(|&(joint, weight)| [joint, weight.to_bits()]),
            );
            for i in 0..deformer.rest.len() {
                for t in &deformer.targets {
                    deltas.extend_from_slice(&t.positions[i]);
                    deltas.extend_from_slice(&t.normals[i]);
                    deltas.extend_from_slice(&t.tangents[i]);
                }
            }
        }
        let vertex_count = rest.len() as u32;
        let groups = vertex_count.div_ceil(WORKGROUP).max(1);
        let groups = [groups.min(MAX_GROUPS_X), groups.div_ceil(MAX_GROUPS_X)];
        let uniforms = super::scene_gpu::buffer_with(
            device,
            queue,
            "PoseBuffers::uniforms",
            bytemuck::bytes_of(&PoseUniforms {
                vertex_count,
                groups_x: groups[0],
                pad0: 0,
                pad1: 0,
            }),
            wgpu::BufferUsages::UNIFORM,
        );
        let deformer_buffer = storage_with(
            device,
            queue,
            "PoseBuffers::deformers",
            bytemuck::cast_slice(&deformers),
        );
        let rest_buffer = storage_with(
            device,
            queue,
            "PoseBuffers::rest",
            bytemuck::cast_slice(&rest),
        );
        let influence_buffer = storage_with(
            device,
            queue,
            "PoseBuffers::influences",
            bytemuck::cast_slice(&influences),
        );
        let delta_buffer = storage_with(
            device,
            queue,
            "PoseBuffers::deltas",
            bytemuck::cast_slice(&deltas),
        );
        let matrix_staging = vec![[0.0f32; 16]; matrices as usize];
        let weight_staging = vec![0.0f32; weights as usize];
        let matrix_buffer = storage_with(
            device,
            queue,
            "PoseBuffers::matrices",
            bytemuck::cast_slice(&matrix_staging),
        );
        let weight_buffer = storage_with(
            device,
            queue,
            "PoseBuffers::weights",
            bytemuck::cast_slice(&weight_staging),
        );
        let bind_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("PoseBuffers::bind_group"),
            layout: &pipeline.layout,
            entries: &[
                entry(0, &uniforms),
                entry(1, &deformer_buffer),
                entry(2, &rest_buffer),
                entry(3, &influence_buffer),
                entry(4, &delta_buffer),
                entry(5, &matrix_buffer),
                entry(6, &weight_buffer),
                entry(7, vertex_buffer),
            ],
        });
        Self {
            bind_group,
            matrices: matrix_buffer,
            weights: weight_buffer,
            offsets,
            groups,
            matrix_staging,
            weight_staging,
        }
    }

    /// Writes `pose`'s matrices and morph weights (evaluated by `rig`) for the next dispatch.
    pub fn write(&mut self, queue: &wgpu::Queue, rig: &Rig, pose: &Pose) {
        for (d, &(first_matrix, first_weight)) in self.offsets.iter().enumerate() {
            if let Some(matrices) = pose.matrices.get(d) {
                for (k, m) in matrices.iter().enumerate() {
                    if let Some(slot) = self.matrix_staging.get_mut(first_matrix as usize + k) {
                        *slot = m.to_cols_array();
                    }
                }
            }
            let targets = rig.deformers.get(d).map_or(0, |x| x.targets.len());
            let weights = rig.morph_weights(d, pose);
            for k in 0..targets {
                if let Some(slot) = self.weight_staging.get_mut(first_weight as usize + k) {
                    *slot = weights.get(k).copied().unwrap_or(0.0);
                }
            }
        }
        if !self.matrix_staging.is_empty() {
            queue.write_buffer(
                &self.matrices,
                0,
                bytemuck::cast_slice(&self.matrix_staging),
            );
        }
        if !self.weight_staging.is_empty() {
            queue.write_buffer(&self.weights, 0, bytemuck::cast_slice(&self.weight_staging));
        }
    }

    /// Records the dispatch (`timestamps`: the pass's begin and end query, when timed).
    pub fn encode(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        pipeline: &PosePipeline,
        timestamps: Option<wgpu::ComputePassTimestampWrites<'_>>,
    ) {
        let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some("PoseBuffers::pass"),
            timestamp_writes: timestamps,
        });
        pass.set_pipeline(&pipeline.pipeline);
        pass.set_bind_group(0, &self.bind_group, &[]);
        pass.dispatch_workgroups(self.groups[0], self.groups[1], 1);
    }
}

/// The largest of the pass's buffers `rig` needs, bytes.
fn largest_binding(rig: &Rig) -> u64 {
    let (mut rest, mut influences, mut deltas, mut matrices) = (0u64, 0u64, 0u64, 0u64);
    for d in &rig.deformers {
        let n = d.rest.len() as u64;
        rest += n * std::mem::size_of::<PoseRestVertex>() as u64;
        influences += d.influences.len() as u64 * 8;
        deltas += n * d.targets.len() as u64 * 36;
        matrices += d.matrix_count(rig) as u64 * 64;
    }
    rest.max(influences).max(deltas).max(matrices)
}

/// A scene's animation on the renderer: its rig, the pose's values, the GPU inputs and the
/// clusters the pose moves.
#[derive(Debug)]
pub struct ScenePose {
    rig: Rig,
    pose: Pose,
    buffers: PoseBuffers,
    clusters: crate::tess::posed_clusters::PosedClusters,
    /// The pose the vertex buffer holds (`None`: to be posed at the next frame).
    last: Option<PoseAt>,
    /// The last animation name the scene does not have (warned about once).
    refused: Option<String>,
}

impl ScenePose {
    /// The pose state of `scene` uploaded as `gpu` (`None`: nothing moves, or the scene is
    /// split over several buffers, which is drawn in its rest pose, with a warning).
    pub fn new(
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        pipeline: &PosePipeline,
        scene: &Scene,
        gpu: &SceneGpu,
    ) -> Option<Self> {
        if scene.rig.is_empty() {
            return None;
        }
        let limit = device.limits().max_storage_buffer_binding_size;
        let largest = gpu
            .whole()
            .map_or(0, |w| w.vertex_buffer.size())
            .max(largest_binding(&scene.rig));
        if largest > limit {
            tracing::warn!(
                "posing the scene binds a {largest}-byte buffer (its vertices, morph targets, \
                 skin weights or joint matrices), more than this device binds ({limit}): \
                 drawn in its rest pose"
            );
            return None;
        }
        let Ok(whole) = gpu.whole() else {
            tracing::warn!(
                "the scene is split over {} buffers: its animation, skins and morph targets \
                 are drawn in their rest pose",
                gpu.chunk_count()
            );
            return None;
        };
        Some(Self {
            buffers: PoseBuffers::new(device, queue, pipeline, &scene.rig, &whole.vertex_buffer),
            clusters: crate::tess::posed_clusters::PosedClusters::new(scene, &gpu.clusters),
            rig: scene.rig.clone(),
            pose: Pose::default(),
            last: None,
            refused: None,
        })
    }

    /// Poses the scene as `playback` asks, unless the vertex buffer holds that pose already:
    /// writes the matrices and weights, records the dispatch into `encoder` and moves the
    /// clusters' and the scene's bounds. Returns whether the pose changed (the shadow maps
    /// must be drawn again).
    pub fn update(
        &mut self,
        queue: &wgpu::Queue,
        encoder: &mut wgpu::CommandEncoder,
        pipeline: &PosePipeline,
        playback: &Playback<'_>,
        gpu: &mut SceneGpu,
    ) -> bool {
        // A name refused once is not looked up again (its message is built once).
        let refused = playback.enabled && self.refused.as_deref() == Some(playback.clip);
        let at = if refused {
            PoseAt::REST
        } else {
            match self.rig.pose_at(playback) {
                Ok(at) => at,
                Err(why) => {
                    tracing::warn!("{why}: drawn in the rest pose");
                    self.refused = Some(playback.clip.to_owned());
                    PoseAt::REST
                }
            }
        };
        if self.last == Some(at) {
            return false;
        }
        self.rig.pose(at, &mut self.pose);
        self.buffers.write(queue, &self.rig, &self.pose);
        self.buffers.encode(encoder, pipeline, None);
        gpu.bounds = self
            .clusters
            .update(&self.rig, &self.pose, &mut gpu.clusters)
            .or(gpu.bounds);
        self.last = Some(at);
        true
    }

    /// The frame that posed last was never submitted: pose again at the next.
    pub fn forget(&mut self) {
        self.last = None;
    }

    /// The pose the vertex buffer holds.
    pub fn current(&self) -> Option<PoseAt> {
        self.last
    }
}
