//! Reads a glTF file's animations, skins and morph targets into a [`Rig`]: checked against
//! the budgets, malformed data refused naming the animation, channel, skin or mesh, and the
//! documented repairs (weights renormalised) applied with a warning.

use glam::{Mat4, Quat, Vec3};

use super::animation::{Interpolation, Sampler, Values};
use super::budget::SceneBudget;
use super::gltf_data::BinaryData;
use super::rig::{
    Channel, Clip, Deformer, MorphTarget, Pose, PoseAt, RestVertex, Rig, RigNode, Skin, Target, Trs,
};

/// What the rig builder needs of the loader: reading accessors and naming errors.
pub(super) struct RigContext<'a> {
    pub data: &'a BinaryData,
    pub budget: &'a SceneBudget,
    /// The file, for warnings.
    pub path: &'a std::path::Path,
}

impl RigContext<'_> {
    fn warn(&self, what: &str) {
        tracing::warn!("{}: {what}", self.path.display());
    }
}

/// The rig as it is built, with what the loader asks while visiting nodes.
#[derive(Debug, Default)]
pub(super) struct RigBuilder {
    pub rig: Rig,
    /// glTF node index → rig node index.
    node_index: Vec<usize>,
    /// glTF skin index → rig skin index.
    skin_index: Vec<usize>,
    /// Per glTF node: a channel moves it or an ancestor.
    moved: Vec<bool>,
    /// The rest pose (nodes at their file transforms), for the bind-time matrices.
    rest: Pose,
    /// Bytes the deformers added so far hold (see `budgets.max_pose_memory_mb`).
    pose_bytes: u64,
}

/// Bytes a posed vertex holds for posing: its mesh-space position, normal and tangent, on
/// the CPU and the GPU.
const REST_BYTES: u64 = 2 * 48;
/// Bytes of one morph target's deltas per vertex (position, normal, tangent), CPU and GPU.
const DELTA_BYTES: u64 = 2 * 36;
/// Bytes of one JOINTS_n/WEIGHTS_n set per vertex (four joints and weights), CPU and GPU.
const SET_BYTES: u64 = 2 * 32;

/// What the builder refuses: the message, naming the object (the loader adds the file).
pub(super) type RigResult<T> = Result<T, String>;

impl RigBuilder {
    /// Nodes, skins and clips of `document` (everything but the deformed primitives, which
    /// the loader adds as it meets them).
    pub fn new(document: &gltf::Document, cx: &RigContext<'_>) -> RigResult<Self> {
        let mut builder = Self::default();
        builder.read_nodes(document);
        builder.read_skins(document, cx)?;
        builder.read_clips(document, cx)?;
        builder.rig.pose(PoseAt::REST, &mut builder.rest);
        Ok(builder)
    }

    /// Rig nodes ordered parents first (a preorder walk from the roots; nodes in a cycle,
    /// which the loader refuses if drawn, come last without a parent).
    fn read_nodes(&mut self, document: &gltf::Document) {
        let count = document.nodes().count();
        let mut parent = vec![None; count];
        for node in document.nodes() {
            for child in node.children() {
                if parent[child.index()].is_none() && child.index() != node.index() {
                    parent[child.index()] = Some(node.index());
                }
            }
        }
        let mut order = Vec::with_capacity(count);
        let mut seen = vec![false; count];
        let mut stack: Vec<usize> = (0..count).rev().filter(|&i| parent[i].is_none()).collect();
        let nodes: Vec<gltf::Node<'_>> = document.nodes().collect();
        while let Some(i) = stack.pop() {
            if std::mem::replace(&mut seen[i], true) {
                continue;
            }
            order.push(i);
            for child in nodes[i].children().collect::<Vec<_>>().into_iter().rev() {
                if parent[child.index()] == Some(i) && !seen[child.index()] {
                    stack.push(child.index());
                }
            }
        }
        order.extend((0..count).filter(|&i| !seen[i]));
        self.node_index = vec![0; count];
        for (r, &i) in order.iter().enumerate() {
            self.node_index[i] = r;
        }
        self.rig.nodes = order
            .iter()
            .map(|&i| {
                let node = &nodes[i];
                let rest_matrix = Mat4::from_cols_array_2d(&node.transform().matrix());
                let (t, r, s) = node.transform().decomposed();
                let weights = node
                    .weights()
                    .or_else(|| node.mesh().and_then(|m| m.weights()))
                    .map(<[f32]>::to_vec)
                    .unwrap_or_else(|| vec![0.0; node.mesh().map_or(0, |m| target_count(&m))]);
                RigNode {
                    name: node
                        .name()
                        .map_or_else(|| format!("node {i}"), str::to_owned),
                    // A parent only counts if it comes first (it always does, but for cycles).
                    parent: parent[i]
                        .map(|p| self.node_index[p])
                        .filter(|&p| p < self.node_index[i]),
                    rest_matrix,
                    rest: Trs {
                        translation: Vec3::from(t),
                        rotation: Quat::from_array(r).normalize(),
                        scale: Vec3::from(s),
                    },
                    weights,
                }
            })
            .collect();
    }

    fn read_skins(&mut self, document: &gltf::Document, cx: &RigContext<'_>) -> RigResult<()> {
        for skin in document.skins() {
            let name = skin.name().map_or_else(
                || format!("skin {}", skin.index()),
                |n| format!("skin {} ({n})", skin.index()),
            );
            let joints: Vec<usize> = skin.joints().map(|j| self.node_index[j.index()]).collect();
            if joints.is_empty() {
                return Err(format!("{name} has no joints"));
            }
            if joints.len() as u64 > u64::from(cx.budget.max_joints) {
                return Err(format!(
                    "{name} has {} joints, over budgets.max_joints = {}",
                    joints.len(),
                    cx.budget.max_joints
                ));
            }
            let inverse_bind = match skin.inverse_bind_matrices() {
                Some(accessor) => {
                    let m = cx
                        .data
                        .read_f32::<16>(&accessor)
                        .map_err(|why| format!("{name}: inverseBindMatrices: {why}"))?;
                    if m.len() < joints.len() {
                        return Err(format!(
                            "{name}: {} inverse bind matrices for {} joints",
                            m.len(),
                            joints.len()
                        ));
                    }
                    if m.iter().flatten().any(|v| !v.is_finite()) {
                        return Err(format!(
                            "{name}: an inverse bind matrix contains NaN or infinity"
                        ));
                    }
                    m.iter()
                        .take(joints.len())
                        .map(Mat4::from_cols_array)
                        .collect()
                }
                None => vec![Mat4::IDENTITY; joints.len()],
            };
            self.skin_index.push(self.rig.skins.len());
            self.rig.skins.push(Skin {
                name,
                joints,
                inverse_bind,
            });
        }
        Ok(())
    }

    fn read_clips(&mut self, document: &gltf::Document, cx: &RigContext<'_>) -> RigResult<()> {
        let mut channels_seen = 0u64;
        let mut keyframes_seen = 0u64;
        self.moved = vec![false; document.nodes().count()];
        for animation in document.animations() {
            let name = animation
                .name()
                .map_or_else(|| format!("animation {}", animation.index()), str::to_owned);
            let mut channels = Vec::new();
            for (c, channel) in animation.channels().enumerate() {
                let label = format!("animation {} ({name}) channel {c}", animation.index());
                channels_seen += 1;
                if channels_seen > u64::from(cx.budget.max_animation_channels) {
                    return Err(format!(
                        "{label}: the file has more than budgets.max_animation_channels = {} \
                         channels",
                        cx.budget.max_animation_channels
                    ));
                }
                let node = channel.target().node();
                let sampler = channel.sampler();
                keyframes_seen += sampler.input().count() as u64;
                if keyframes_seen > u64::from(cx.budget.max_keyframes) {
                    return Err(format!(
                        "{label}: the file has more than budgets.max_keyframes = {} keyframes",
                        cx.budget.max_keyframes
                    ));
                }
                let (target, values) = match channel.target().property() {
                    gltf::animation::Property::Translation => {
                        (Target::Translation, Values::Vector3)
                    }
                    gltf::animation::Property::Rotation => (Target::Rotation, Values::Rotation),
                    gltf::animation::Property::Scale => (Target::Scale, Values::Vector3),
                    gltf::animation::Property::MorphTargetWeights => {
                        let targets = node.mesh().map_or(0, |m| target_count(&m));
                        if targets == 0 {
                            return Err(format!(
                                "{label} animates the morph weights of node {}, whose mesh has \
                                 no morph targets",
                                node.index()
                            ));
                        }
                        (Target::Weights, Values::Weights(targets))
                    }
                };
                let fail = |why: String| format!("{label} (node {}): {why}", node.index());
                let times = cx
                    .data
                    .read_f32::<1>(&sampler.input())
                    .map_err(|why| fail(format!("input: {why}")))?
                    .into_iter()
                    .map(|[t]| t)
                    .collect();
                let output = sampler.output();
                let flat: Vec<f32> = match values {
                    Values::Vector3 => cx.data.read_f32::<3>(&output).map(flatten),
                    Values::Rotation => cx.data.read_f32::<4>(&output).map(flatten),
                    Values::Weights(_) => cx.data.read_f32::<1>(&output).map(flatten),
                }
                .map_err(|why| fail(format!("output: {why}")))?;
                let interpolation = match sampler.interpolation() {
                    gltf::animation::Interpolation::Step => Interpolation::Step,
                    gltf::animation::Interpolation::Linear => Interpolation::Linear,
                    gltf::animation::Interpolation::CubicSpline => Interpolation::CubicSpline,
                };
                // A rotation keyframe (not a CUBICSPLINE tangent) must have a length.
                let (per_key, value_at) = match interpolation {
                    Interpolation::CubicSpline => (3, 1),
                    _ => (1, 0),
                };
                if values == Values::Rotation
                    && flat
                        .chunks_exact(4)
                        .enumerate()
                        .filter(|(k, _)| k % per_key == value_at)
                        .any(|(_, q)| {
                            let l = q.iter().map(|v| v * v).sum::<f32>();
                            l.is_finite() && l < 1e-12
                        })
                {
                    return Err(fail("a rotation keyframe is the zero quaternion".into()));
                }
                let sampler = Sampler::new(times, flat, interpolation, values)
                    .map_err(|e| fail(e.to_string()))?;
                if target != Target::Weights {
                    self.moved[node.index()] = true;
                }
                channels.push(Channel {
                    node: self.node_index[node.index()],
                    target,
                    sampler,
                });
            }
            let (start, end) = channels
                .iter()
                .map(|c| c.sampler.time_range())
                .fold((f32::INFINITY, f32::NEG_INFINITY), |(a, b), (s, e)| {
                    (a.min(s), b.max(e))
                });
            if channels.is_empty() {
                continue;
            }
            self.rig.clips.push(Clip {
                name,
                start: start.min(0.0),
                end,
                channels,
            });
        }
        // A node moves if it or an ancestor does: down the (parents-first) order.
        let mut moved_rig = vec![false; self.rig.nodes.len()];
        for (doc, &r) in self.node_index.iter().enumerate() {
            moved_rig[r] = self.moved[doc];
        }
        for r in 0..moved_rig.len() {
            if let Some(p) = self.rig.nodes[r].parent
                && moved_rig[p]
            {
                moved_rig[r] = true;
            }
        }
        for (doc, &r) in self.node_index.iter().enumerate() {
            self.moved[doc] = moved_rig[r];
        }
        Ok(())
    }

    /// Whether a primitive of `node` is posed per frame (a skin, morph targets, or a channel
    /// moving the node or an ancestor).
    pub fn deforms(&self, node: &gltf::Node<'_>, primitive: &gltf::Primitive<'_>) -> bool {
        node.skin().is_some()
            || primitive.morph_targets().next().is_some()
            || self.moved.get(node.index()).copied().unwrap_or(false)
    }

    /// Whether the pose of the deformer about to be added mirrors (its rest matrices'
    /// determinant is negative): its triangles' winding is flipped as a mirrored static
    /// mesh's is.
    pub fn mirrors(&self, node: &gltf::Node<'_>) -> bool {
        let m = match node.skin() {
            Some(skin) => {
                let s = &self.rig.skins[self.skin_index[skin.index()]];
                self.rest.globals[s.joints[0]] * s.inverse_bind[0]
            }
            None => self.rest.globals[self.node_index[node.index()]],
        };
        glam::Mat3::from_mat4(m).determinant() < 0.0
    }

    /// Adds the deformer of `primitive` of `node` whose vertices (mesh space, in `rest`) start
    /// at `first_vertex` of the scene; warns about repaired weights.
    pub fn add(
        &mut self,
        cx: &RigContext<'_>,
        node: &gltf::Node<'_>,
        primitive: &gltf::Primitive<'_>,
        rest: Vec<RestVertex>,
        first_vertex: u32,
        label: &str,
    ) -> RigResult<()> {
        let n = rest.len();
        // What posing it holds (mesh-space vertices, deltas, influences), counted before
        // anything is read: targets and weight sets cost nothing in file size.
        let targets = primitive.morph_targets().count() as u64;
        let sets = if node.skin().is_some() {
            (0..)
                .take_while(|&set| {
                    primitive.get(&gltf::Semantic::Joints(set)).is_some()
                        && primitive.get(&gltf::Semantic::Weights(set)).is_some()
                })
                .count() as u64
        } else {
            0
        };
        self.pose_bytes = self.pose_bytes.saturating_add(
            (n as u64).saturating_mul(REST_BYTES + targets * DELTA_BYTES + sets * SET_BYTES),
        );
        if self.pose_bytes > cx.budget.max_pose_bytes {
            return Err(format!(
                "{label}: what the animated primitives hold (vertices, morph deltas, skin \
                 weights) reaches {} MiB here, over budgets.max_pose_memory_mb = {}",
                self.pose_bytes >> 20,
                cx.budget.max_pose_bytes >> 20
            ));
        }
        let targets = self.morph_targets(cx, primitive, n, label)?;
        let (skin, influences_per_vertex, influences) = match node.skin() {
            Some(skin) => {
                let s = self.skin_index[skin.index()];
                let joints = self.rig.skins[s].joints.len();
                let (per, influences) =
                    read_influences(cx, primitive, n, joints, &self.rig.skins[s].name, label)?;
                (Some(s), per, influences)
            }
            None => (None, 0, Vec::new()),
        };
        self.rig.deformers.push(Deformer {
            label: label.to_owned(),
            first_vertex,
            node: self.node_index[node.index()],
            skin,
            rest,
            influences_per_vertex,
            influences,
            targets,
        });
        Ok(())
    }

    fn morph_targets(
        &self,
        cx: &RigContext<'_>,
        primitive: &gltf::Primitive<'_>,
        n: usize,
        label: &str,
    ) -> RigResult<Vec<MorphTarget>> {
        let count = primitive.morph_targets().count();
        if count as u64 > u64::from(cx.budget.max_morph_targets) {
            return Err(format!(
                "{label} has {count} morph targets, over budgets.max_morph_targets = {}",
                cx.budget.max_morph_targets
            ));
        }
        let read = |accessor: Option<gltf::Accessor<'_>>, what: &str, k: usize| {
            let Some(accessor) = accessor else {
                return Ok(vec![[0.0; 3]; n]);
            };
            let values = cx
                .data
                .read_f32::<3>(&accessor)
                .map_err(|why| format!("{label}: morph target {k} {what}: {why}"))?;
            if values.len() != n {
                return Err(format!(
                    "{label}: morph target {k} {what} has {} elements but POSITION has {n}",
                    values.len()
                ));
            }
            if values.iter().flatten().any(|v| !v.is_finite()) {
                return Err(format!(
                    "{label}: morph target {k} {what} contains NaN or infinity"
                ));
            }
            Ok(values)
        };
        primitive
            .morph_targets()
            .enumerate()
            .map(|(k, t)| {
                Ok(MorphTarget {
                    positions: read(t.positions(), "POSITION", k)?,
                    normals: read(t.normals(), "NORMAL", k)?,
                    tangents: read(t.tangents(), "TANGENT", k)?,
                })
            })
            .collect()
    }

    /// The finished rig, with the scene's deformed vertices posed at rest.
    pub fn finish(self, vertices: &mut [super::Vertex]) -> Rig {
        let mut pose = Pose::default();
        self.rig.deform_all(&mut pose, PoseAt::REST, vertices);
        self.rig
    }
}

/// Morph targets of a mesh (its first primitive's; glTF requires every primitive to have
/// the same number).
fn target_count(mesh: &gltf::Mesh<'_>) -> usize {
    mesh.primitives()
        .map(|p| p.morph_targets().count())
        .max()
        .unwrap_or(0)
}

fn flatten<const N: usize>(v: Vec<[f32; N]>) -> Vec<f32> {
    v.into_iter().flatten().collect()
}

/// Every `JOINTS_n`/`WEIGHTS_n` set of a skinned primitive as (joint, weight) pairs, 4 per
/// set per vertex. Joints past the skin's are refused; weights that are negative are taken
/// as zero and each vertex's are scaled to sum to one (a vertex with none follows its first
/// joint), with one warning per primitive saying how many vertices were repaired.
fn read_influences(
    cx: &RigContext<'_>,
    primitive: &gltf::Primitive<'_>,
    n: usize,
    joint_count: usize,
    skin: &str,
    label: &str,
) -> RigResult<(u32, Vec<(u32, f32)>)> {
    let mut sets = Vec::new();
    for set in 0.. {
        let (Some(joints), Some(weights)) = (
            primitive.get(&gltf::Semantic::Joints(set)),
            primitive.get(&gltf::Semantic::Weights(set)),
        ) else {
            break;
        };
        let read = |accessor: &gltf::Accessor<'_>, what: String| {
            let values = cx
                .data
                .read_f32::<4>(accessor)
                .map_err(|why| format!("{label}: {what}: {why}"))?;
            if values.len() != n {
                return Err(format!(
                    "{label}: {what} has {} elements but POSITION has {n}",
                    values.len()
                ));
            }
            if values.iter().flatten().any(|v| !v.is_finite()) {
                return Err(format!("{label}: {what} contains NaN or infinity"));
            }
            Ok(values)
        };
        if matches!(
            joints.data_type(),
            gltf::accessor::DataType::F32
                | gltf::accessor::DataType::I8
                | gltf::accessor::DataType::I16
        ) || joints.normalized()
        {
            return Err(format!(
                "{label}: JOINTS_{set} must hold unsigned bytes or shorts, not {:?}",
                joints.data_type()
            ));
        }
        sets.push((
            read(&joints, format!("JOINTS_{set}"))?,
            read(&weights, format!("WEIGHTS_{set}"))?,
        ));
    }
    if sets.is_empty() {
        return Err(format!(
            "{label} is skinned by {skin} but has no JOINTS_0 and WEIGHTS_0"
        ));
    }
    let per = 4 * sets.len();
    let mut influences = Vec::with_capacity(n * per);
    let mut repaired = 0usize;
    for v in 0..n {
        let start = influences.len();
        for (joints, weights) in &sets {
            for k in 0..4 {
                let joint = joints[v][k];
                let weight = weights[v][k].max(0.0);
                if weight > 0.0 && joint as usize >= joint_count {
                    return Err(format!(
                        "{label}: vertex {v} is bound to joint {joint}, but {skin} has \
                         {joint_count} joints"
                    ));
                }
                // A zero-weight slot may name any joint: it is pointed at joint 0.
                let joint = if weight > 0.0 { joint as u32 } else { 0 };
                influences.push((joint, weight));
            }
        }
        let slots = &mut influences[start..];
        // In f64: finite f32 weights near the type's largest sum to more than it holds.
        let sum: f64 = slots.iter().map(|s| f64::from(s.1)).sum();
        if sum <= 0.0 {
            repaired += 1;
            let first = sets[0].0[v][0];
            slots[0] = (
                if (first as usize) < joint_count {
                    first as u32
                } else {
                    0
                },
                1.0,
            );
        } else {
            if (sum - 1.0).abs() > 2e-3 {
                repaired += 1;
            }
            for s in slots.iter_mut() {
                s.1 = (f64::from(s.1) / sum) as f32;
            }
        }
    }
    if repaired > 0 {
        cx.warn(&format!(
            "{label}: {repaired} of {n} vertices have skin weights that do not sum to one \
             (or are negative): scaled to sum to one (a vertex with none follows its first \
             joint)"
        ));
    }
    Ok((per as u32, influences))
}
