//! Animated content as CPU data: the node hierarchy, clips, skins, morph targets and the
//! primitives they move; the pose at a time and the posed vertices (the CPU twin of
//! shaders/pose.wgsl, which the GPU pose pass runs before tessellation and the warp).
//!
//! A primitive is *deformed* when a skin, morph targets or an animated node (itself or an
//! ancestor) moves it; every other primitive is baked into scene space at load and costs
//! nothing per frame. A deformed primitive keeps its vertices in mesh space ([`RestVertex`])
//! with its influences and morph deltas; each frame the pose gives it matrices:
//!
//! - skinned: one per joint, Jᵢ = placement · global(jointᵢ) · inverseBindᵢ (the mesh node's
//!   own transform is ignored, as glTF says);
//! - rigid (an animated node, or morph targets alone): one, placement · global(node).
//!
//! A vertex is morphed first (rest + Σₖ wₖ·Δₖ for position, normal and tangent), then moved by
//! M = Σᵢ wᵢ·Jᵢ (skinned) or the one matrix: position M·p, normal along the inverse transpose
//! (the cofactor matrix, signed by the determinant), tangent M·t, all in f32 in the order the
//! shader uses.

use glam::{Mat3, Mat4, Quat, Vec3};

use super::Vertex;
use super::animation::{Sampler, Values};

/// A node's local transform as translation, rotation and scale (what channels target).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Trs {
    pub translation: Vec3,
    pub rotation: Quat,
    pub scale: Vec3,
}

impl Default for Trs {
    fn default() -> Self {
        Self {
            translation: Vec3::ZERO,
            rotation: Quat::IDENTITY,
            scale: Vec3::ONE,
        }
    }
}

impl Trs {
    pub fn matrix(&self) -> Mat4 {
        Mat4::from_scale_rotation_translation(self.scale, self.rotation, self.translation)
    }
}

/// One node of the file's hierarchy.
#[derive(Debug, Clone, PartialEq)]
pub struct RigNode {
    pub name: String,
    /// Its parent (every parent comes before its children in [`Rig::nodes`]).
    pub parent: Option<usize>,
    /// The file's transform, as it gave it (a matrix or TRS).
    pub rest_matrix: Mat4,
    /// The same as TRS (a matrix decomposed), for channels to override a part of.
    pub rest: Trs,
    /// The node's morph target weights when no channel sets them (the node's `weights`, else
    /// its mesh's, else zeros).
    pub weights: Vec<f32>,
}

/// What a channel animates.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Target {
    Translation,
    Rotation,
    Scale,
    Weights,
}

/// One animated property of one node.
#[derive(Debug, Clone, PartialEq)]
pub struct Channel {
    pub node: usize,
    pub target: Target,
    pub sampler: Sampler,
}

/// A glTF animation: its channels played together.
#[derive(Debug, Clone, PartialEq)]
pub struct Clip {
    pub name: String,
    /// The first and last keyframe time of any channel, seconds.
    pub start: f32,
    pub end: f32,
    pub channels: Vec<Channel>,
}

impl Clip {
    pub fn duration(&self) -> f32 {
        self.end - self.start
    }
}

/// A skin: joints and their inverse bind matrices.
#[derive(Debug, Clone, PartialEq)]
pub struct Skin {
    pub name: String,
    pub joints: Vec<usize>,
    pub inverse_bind: Vec<Mat4>,
}

/// A deformed vertex before the pose: mesh space.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct RestVertex {
    pub position: [f32; 3],
    pub normal: [f32; 3],
    /// xyz and handedness, as [`Vertex::tangent`] (zero: none).
    pub tangent: [f32; 4],
}

/// One morph target's deltas, one per vertex of its primitive.
#[derive(Debug, Clone, PartialEq)]
pub struct MorphTarget {
    pub positions: Vec<[f32; 3]>,
    /// Zeros where the file has none.
    pub normals: Vec<[f32; 3]>,
    pub tangents: Vec<[f32; 3]>,
}

/// A primitive the pose moves: where its vertices lie in [`super::Scene::vertices`] and how
/// they move.
#[derive(Debug, Clone, PartialEq)]
pub struct Deformer {
    /// Names the mesh and primitive in messages.
    pub label: String,
    pub first_vertex: u32,
    /// The node whose mesh it is.
    pub node: usize,
    pub skin: Option<usize>,
    pub rest: Vec<RestVertex>,
    /// Influences a vertex has (4 per `JOINTS_n`/`WEIGHTS_n` set; 0 when not skinned).
    pub influences_per_vertex: u32,
    /// `rest.len() × influences_per_vertex` (joint of the skin, weight); weights sum to one.
    pub influences: Vec<(u32, f32)>,
    pub targets: Vec<MorphTarget>,
}

impl Deformer {
    /// Matrices the pose gives it: one per joint, or one.
    pub fn matrix_count(&self, rig: &Rig) -> usize {
        self.skin
            .and_then(|s| rig.skins.get(s))
            .map_or(1, |s| s.joints.len())
    }
}

/// Everything of a scene that moves.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Rig {
    /// Parents before children.
    pub nodes: Vec<RigNode>,
    pub clips: Vec<Clip>,
    pub skins: Vec<Skin>,
    pub deformers: Vec<Deformer>,
    /// Scene space from the file's space: how the scene was placed after loading.
    pub placement: Mat4,
}

/// Which clip at which time (clip-local seconds: the clock has wrapped or clamped it).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PoseAt {
    /// `None`: no clip, every node at its rest transform (as the scene was baked).
    pub clip: Option<usize>,
    pub time: f32,
}

impl PoseAt {
    pub const REST: Self = Self {
        clip: None,
        time: 0.0,
    };
}

/// What the clock asks of a frame: the animation by name, the clock's time and how it wraps.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Playback<'a> {
    /// Off: the rest pose.
    pub enabled: bool,
    /// The animation's name ("": the first).
    pub clip: &'a str,
    /// The clock, seconds from the animation's start.
    pub seconds: f64,
    /// Wrap at the end (else hold the ends).
    pub repeat: bool,
}

impl Playback<'static> {
    /// Every node at its rest transform.
    pub const REST: Self = Self {
        enabled: false,
        clip: "",
        seconds: 0.0,
        repeat: true,
    };
}

/// A pose's values, reused frame to frame.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Pose {
    locals: Vec<Trs>,
    /// Each node's placed global transform (placement · parent chain · local).
    pub globals: Vec<Mat4>,
    /// Each node's morph weights (its rest weights unless a channel set them).
    pub node_weights: Vec<Vec<f32>>,
    /// Per deformer, its matrices (see [`Deformer::matrix_count`]).
    pub matrices: Vec<Vec<Mat4>>,
    scratch: Vec<f32>,
    /// Per node: a channel of the clip sets its translation, rotation or scale.
    moved: Vec<bool>,
}

impl Rig {
    /// Whether anything moves.
    pub fn is_empty(&self) -> bool {
        self.deformers.is_empty()
    }

    /// The clip named `name` ("": the first), or why there is none.
    pub fn clip_named(&self, name: &str) -> Result<Option<usize>, String> {
        if name.is_empty() {
            return Ok((!self.clips.is_empty()).then_some(0));
        }
        if self.clips.is_empty() {
            return Err(format!(
                "the scene has no animations, so none named \"{name}\""
            ));
        }
        self.clips
            .iter()
            .position(|c| c.name == name)
            .map(Some)
            .ok_or_else(|| {
                let names: Vec<&str> = self.clips.iter().map(|c| c.name.as_str()).collect();
                format!(
                    "the scene has no animation named \"{name}\" (it has: {})",
                    names.join(", ")
                )
            })
    }

    /// The pose `playback` asks for, or why there is none (an animation name the file lacks).
    pub fn pose_at(&self, playback: &Playback<'_>) -> Result<PoseAt, String> {
        if !playback.enabled {
            return Ok(PoseAt::REST);
        }
        Ok(match self.clip_named(playback.clip)? {
            None => PoseAt::REST,
            Some(clip) => PoseAt {
                clip: Some(clip),
                time: self.clip_time(clip, playback.seconds, playback.repeat),
            },
        })
    }

    /// Clip `clip`'s time at clock time `seconds`: wrapped into the clip (`repeat`) or held
    /// at its ends.
    pub fn clip_time(&self, clip: usize, seconds: f64, repeat: bool) -> f32 {
        let Some(c) = self.clips.get(clip) else {
            return 0.0;
        };
        let (start, length) = (f64::from(c.start), f64::from(c.duration()));
        let seconds = if seconds.is_finite() { seconds } else { 0.0 };
        let local = if length <= 0.0 {
            0.0
        } else if repeat {
            seconds.rem_euclid(length)
        } else {
            seconds.clamp(0.0, length)
        };
        (start + local) as f32
    }

    /// Evaluates the pose at `at` into `pose`: node transforms (channels over the rest TRS),
    /// globals down the hierarchy, morph weights and every deformer's matrices.
    pub fn pose(&self, at: PoseAt, pose: &mut Pose) {
        let n = self.nodes.len();
        pose.locals.clear();
        pose.locals.extend(self.nodes.iter().map(|node| node.rest));
        pose.node_weights.resize_with(n, Vec::new);
        for (weights, node) in pose.node_weights.iter_mut().zip(&self.nodes) {
            weights.clear();
            weights.extend_from_slice(&node.weights);
        }
        let mut animated = false;
        if let Some(clip) = at.clip.and_then(|c| self.clips.get(c)) {
            animated = true;
            for channel in &clip.channels {
                let components = channel.sampler.values().components();
                pose.scratch.resize(components.max(4), 0.0);
                channel.sampler.sample(at.time, &mut pose.scratch);
                let v = &pose.scratch;
                let Some(local) = pose.locals.get_mut(channel.node) else {
                    continue;
                };
                match channel.target {
                    Target::Translation => local.translation = Vec3::new(v[0], v[1], v[2]),
                    Target::Scale => local.scale = Vec3::new(v[0], v[1], v[2]),
                    Target::Rotation => {
                        // Samplers give unit rotations; a degenerate one keeps the rest's.
                        if let Some(q) = glam::Vec4::new(v[0], v[1], v[2], v[3]).try_normalize() {
                            local.rotation = Quat::from_vec4(q);
                        }
                    }
                    Target::Weights => {
                        if let (Some(weights), Values::Weights(k)) = (
                            pose.node_weights.get_mut(channel.node),
                            channel.sampler.values(),
                        ) {
                            weights.clear();
                            weights.extend_from_slice(&v[..k]);
                        }
                    }
                }
            }
        }
        // A node a channel moves uses TRS; the others keep the file's matrix exactly.
        pose.moved.clear();
        pose.moved.resize(if animated { n } else { 0 }, false);
        if let Some(clip) = at.clip.and_then(|c| self.clips.get(c)) {
            for channel in &clip.channels {
                if channel.target != Target::Weights
                    && let Some(m) = pose.moved.get_mut(channel.node)
                {
                    *m = true;
                }
            }
        }
        pose.globals.resize(n, Mat4::IDENTITY);
        for i in 0..n {
            let node = &self.nodes[i];
            let local = if pose.moved.get(i).copied().unwrap_or(false) {
                pose.locals[i].matrix()
            } else {
                node.rest_matrix
            };
            let parent = match node.parent {
                Some(p) if p < i => pose.globals[p],
                _ => self.placement,
            };
            pose.globals[i] = parent * local;
        }
        pose.matrices.resize_with(self.deformers.len(), Vec::new);
        for (d, matrices) in self.deformers.iter().zip(&mut pose.matrices) {
            matrices.clear();
            match d.skin.and_then(|s| self.skins.get(s)) {
                Some(skin) => {
                    // The joints' globals carry the placement already.
                    matrices.extend(skin.joints.iter().zip(&skin.inverse_bind).map(|(&j, ibm)| {
                        pose.globals.get(j).copied().unwrap_or(self.placement) * *ibm
                    }));
                }
                None => matrices.push(pose.globals.get(d.node).copied().unwrap_or(self.placement)),
            }
        }
    }

    /// Deformer `d`'s morph weights in `pose` (one per target).
    pub fn morph_weights<'p>(&self, d: usize, pose: &'p Pose) -> &'p [f32] {
        let Some(deformer) = self.deformers.get(d) else {
            return &[];
        };
        pose.node_weights
            .get(deformer.node)
            .map_or(&[][..], |w| &w[..w.len().min(deformer.targets.len())])
    }

    /// Writes deformer `d`'s posed vertices over `out` (its range of the scene's vertices),
    /// keeping their other attributes: the CPU twin of shaders/pose.wgsl.
    pub fn deform(&self, d: usize, pose: &Pose, out: &mut [Vertex]) {
        let (Some(deformer), Some(matrices)) = (self.deformers.get(d), pose.matrices.get(d)) else {
            return;
        };
        let weights = self.morph_weights(d, pose);
        let per = deformer.influences_per_vertex as usize;
        for (i, (rest, out)) in deformer.rest.iter().zip(out.iter_mut()).enumerate() {
            let mut p = Vec3::from(rest.position);
            let mut n = Vec3::from(rest.normal);
            let mut t = Vec3::from_slice(&rest.tangent[..3]);
            for (target, &w) in deformer.targets.iter().zip(weights) {
                p += w * Vec3::from(target.positions[i]);
                n += w * Vec3::from(target.normals[i]);
                t += w * Vec3::from(target.tangents[i]);
            }
            let m = if per == 0 {
                matrices.first().copied().unwrap_or(Mat4::IDENTITY)
            } else {
                let mut m = Mat4::ZERO;
                for &(joint, weight) in &deformer.influences[i * per..(i + 1) * per] {
                    if let Some(j) = matrices.get(joint as usize) {
                        m += *j * weight;
                    }
                }
                m
            };
            let moved = move_vertex(m, p, n, t, rest.tangent[3]);
            out.position = moved.position;
            out.normal = moved.normal;
            out.tangent = moved.tangent;
        }
    }

    /// Poses every deformer's vertices in `vertices` (the whole scene's) at `at`.
    pub fn deform_all(&self, pose: &mut Pose, at: PoseAt, vertices: &mut [Vertex]) {
        self.pose(at, pose);
        for (d, deformer) in self.deformers.iter().enumerate() {
            let first = deformer.first_vertex as usize;
            if let Some(out) = vertices.get_mut(first..first + deformer.rest.len()) {
                self.deform(d, pose, out);
            }
        }
    }
}

/// One morphed vertex moved by `m`.
fn move_vertex(m: Mat4, p: Vec3, n: Vec3, t: Vec3, handedness: f32) -> RestVertex {
    let linear = Mat3::from_mat4(m);
    let det = linear.determinant();
    let sign = if det < 0.0 { -1.0 } else { 1.0 };
    // The inverse transpose up to a positive factor: the cofactor matrix times sign(det).
    let cofactor = Mat3::from_cols(
        linear.y_axis.cross(linear.z_axis),
        linear.z_axis.cross(linear.x_axis),
        linear.x_axis.cross(linear.y_axis),
    );
    let normal = (cofactor * n * sign).try_normalize().unwrap_or(Vec3::Y);
    let tangent = match (linear * t).try_normalize() {
        Some(t) if handedness != 0.0 => {
            let w = if handedness < 0.0 { -1.0 } else { 1.0 };
            [t.x, t.y, t.z, w * sign]
        }
        _ => [0.0; 4],
    };
    RestVertex {
        position: m.transform_point3(p).to_array(),
        normal: normal.to_array(),
        tangent,
    }
}

/// Joint matrices a skin may have, by default (`budgets.max_joints`).
pub const DEFAULT_MAX_JOINTS: u32 = 1024;
/// Morph targets one primitive may have, by default (`budgets.max_morph_targets`).
pub const DEFAULT_MAX_MORPH_TARGETS: u32 = 128;
/// Animation channels of a file, all clips together (`budgets.max_animation_channels`).
pub const DEFAULT_MAX_CHANNELS: u32 = 65_536;
/// Keyframes of a file, all channels together (`budgets.max_keyframes`).
pub const DEFAULT_MAX_KEYFRAMES: u32 = 4 << 20;

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::animation::Interpolation;

    fn two_joint_rig() -> Rig {
        // Joint 0 at the origin, joint 1 one unit up, child of 0; a vertex at (1, 1, 0)
        // bound half to each.
        let nodes = vec![
            RigNode {
                name: "root".into(),
                parent: None,
                rest_matrix: Mat4::IDENTITY,
                rest: Trs::default(),
                weights: vec![],
            },
            RigNode {
                name: "arm".into(),
                parent: Some(0),
                rest_matrix: Mat4::from_translation(Vec3::Y),
                rest: Trs {
                    translation: Vec3::Y,
                    ..Trs::default()
                },
                weights: vec![],
            },
            RigNode {
                name: "mesh".into(),
                parent: None,
                rest_matrix: Mat4::IDENTITY,
                rest: Trs::default(),
                weights: vec![0.0],
            },
        ];
        let quarter = Quat::from_rotation_z(std::f32::consts::FRAC_PI_2);
        let output = [Quat::IDENTITY, quarter]
            .iter()
            .flat_map(|q| q.to_array())
            .collect();
        let sampler = Sampler::new(
            vec![0.0, 1.0],
            output,
            Interpolation::Linear,
            Values::Rotation,
        )
        .unwrap();
        let weights = Sampler::new(
            vec![0.0, 1.0],
            vec![0.0, 1.0],
            Interpolation::Linear,
            Values::Weights(1),
        )
        .unwrap();
        Rig {
            nodes,
            clips: vec![Clip {
                name: "bend".into(),
                start: 0.0,
                end: 1.0,
                channels: vec![
                    Channel {
                        node: 1,
                        target: Target::Rotation,
                        sampler,
                    },
                    Channel {
                        node: 2,
                        target: Target::Weights,
                        sampler: weights,
                    },
                ],
            }],
            skins: vec![Skin {
                name: "skin".into(),
                joints: vec![0, 1],
                inverse_bind: vec![Mat4::IDENTITY, Mat4::from_translation(-Vec3::Y)],
            }],
            deformers: vec![Deformer {
                label: "test".into(),
                first_vertex: 0,
                node: 2,
                skin: Some(0),
                rest: vec![RestVertex {
                    position: [1.0, 1.0, 0.0],
                    normal: [1.0, 0.0, 0.0],
                    tangent: [0.0, 1.0, 0.0, 1.0],
                }],
                influences_per_vertex: 4,
                influences: vec![(0, 0.5), (1, 0.5), (0, 0.0), (0, 0.0)],
                targets: vec![MorphTarget {
                    positions: vec![[0.0, 0.0, 2.0]],
                    normals: vec![[0.0; 3]],
                    tangents: vec![[0.0; 3]],
                }],
            }],
            placement: Mat4::IDENTITY,
        }
    }

    #[test]
    fn the_rest_pose_leaves_a_vertex_where_its_bind_pose_put_it() {
        let rig = two_joint_rig();
        let mut pose = Pose::default();
        let mut v = [Vertex::default()];
        rig.deform_all(&mut pose, PoseAt::REST, &mut v);
        assert!((Vec3::from(v[0].position) - Vec3::new(1.0, 1.0, 0.0)).length() < 1e-6);
        assert!((Vec3::from(v[0].normal) - Vec3::X).length() < 1e-6);
    }

    #[test]
    fn a_half_bound_vertex_moves_half_way_and_the_morph_applies_first() {
        // At t = 1 joint 1 turns 90° about z at (0, 1, 0): the vertex bound to it alone would
        // go to (0, 2, 0); half-bound, the blended matrix puts it midway, (0.5, 1.5, 0), and
        // the full morph weight adds (0, 0, 2) before the skin: half of it turned about z
        // (which z is unchanged by) and half not, so z = 2.
        let rig = two_joint_rig();
        let mut pose = Pose::default();
        let mut v = [Vertex::default()];
        rig.deform_all(
            &mut pose,
            PoseAt {
                clip: Some(0),
                time: 1.0,
            },
            &mut v,
        );
        let p = Vec3::from(v[0].position);
        assert!((p - Vec3::new(0.5, 1.5, 2.0)).length() < 1e-6, "{p}");
        // The normal: the blend of identity and a quarter turn, (I + R)/2, has inverse
        // transpose ∝ itself here (a rotation-scale), so x̂ goes to (1, 1, 0)/√2.
        let n = Vec3::from(v[0].normal);
        assert!(
            (n - Vec3::new(1.0, 1.0, 0.0).normalize()).length() < 1e-6,
            "{n}"
        );
        assert_eq!(v[0].tangent[3], 1.0);
    }

    #[test]
    fn clip_time_wraps_or_holds() {
        let rig = two_joint_rig();
        assert!((rig.clip_time(0, 2.25, true) - 0.25).abs() < 1e-6);
        assert!((rig.clip_time(0, -0.25, true) - 0.75).abs() < 1e-6);
        assert_eq!(rig.clip_time(0, 5.0, false), 1.0);
        assert_eq!(rig.clip_time(0, -1.0, false), 0.0);
        assert_eq!(rig.clip_time(0, f64::NAN, true), 0.0);
        assert_eq!(rig.clip_named("").unwrap(), Some(0));
        assert!(rig.clip_named("walk").unwrap_err().contains("bend"));
    }

    #[test]
    fn a_mirroring_placement_keeps_normals_outward_and_flips_handedness() {
        let mut rig = two_joint_rig();
        rig.placement = Mat4::from_scale(Vec3::new(-1.0, 1.0, 1.0));
        let mut pose = Pose::default();
        let mut v = [Vertex::default()];
        rig.deform_all(&mut pose, PoseAt::REST, &mut v);
        assert!((Vec3::from(v[0].position) - Vec3::new(-1.0, 1.0, 0.0)).length() < 1e-6);
        assert!((Vec3::from(v[0].normal) - Vec3::NEG_X).length() < 1e-6);
        assert_eq!(v[0].tangent[3], -1.0);
    }
}
