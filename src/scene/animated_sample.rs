//! A generated animated scene written as binary glTF, the way an exporter writes one: a
//! morphing data surface (two morph targets with normal deltas, LINEAR weights), a skinned
//! arm (two joints, blended weights, a CUBICSPLINE elbow) and a spinning block (LINEAR
//! rotation through a full turn, STEP translation), in one animation "Show" of 4 s. The asset
//! generator writes it to assets/animated.glb; tests load it as content a lab would bring.

use glam::{Mat4, Quat, Vec3};
use serde_json::{Value, json};

/// Length of the "Show" animation, seconds.
pub const SHOW_SECONDS: f32 = 4.0;
/// Where the surface's centre, the arm's shoulder and the block stand (metres, as authored:
/// ahead of a head at the CAVE's centre).
pub const SURFACE_AT: Vec3 = Vec3::new(0.0, 1.0, -2.4);
pub const SHOULDER_AT: Vec3 = Vec3::new(-1.1, 0.4, -2.2);
pub const BLOCK_AT: Vec3 = Vec3::new(1.1, 1.2, -2.2);
/// The elbow's height above the shoulder, metres.
const ELBOW_ABOVE: f32 = 0.45;
const ARM_LENGTH: f32 = 0.9;
const ARM_HALF_WIDTH: f32 = 0.06;
const GRID: usize = 40;
const SURFACE_SIZE: f32 = 1.2;

/// The binary chunk and the buffer views and accessors that describe it.
#[derive(Default)]
struct Binary {
    bytes: Vec<u8>,
    views: Vec<Value>,
    accessors: Vec<Value>,
}

impl Binary {
    fn view(&mut self, data: &[u8], target: Option<u32>) -> usize {
        while !self.bytes.len().is_multiple_of(4) {
            self.bytes.push(0);
        }
        let mut view = json!({
            "buffer": 0,
            "byteOffset": self.bytes.len(),
            "byteLength": data.len(),
        });
        if let Some(t) = target {
            view["target"] = json!(t);
        }
        self.bytes.extend_from_slice(data);
        self.views.push(view);
        self.views.len() - 1
    }

    /// Float elements of `components` each; `bounds`: with min and max (positions need them).
    fn floats(&mut self, data: &[f32], components: usize, bounds: bool, vertex: bool) -> usize {
        let ty = match components {
            1 => "SCALAR",
            3 => "VEC3",
            4 => "VEC4",
            _ => "MAT4",
        };
        let bytes: Vec<u8> = data.iter().flat_map(|v| v.to_le_bytes()).collect();
        let view = self.view(&bytes, vertex.then_some(34962));
        let mut accessor = json!({
            "bufferView": view,
            "componentType": 5126,
            "count": data.len() / components,
            "type": ty,
        });
        if bounds {
            let mut min = vec![f32::INFINITY; components];
            let mut max = vec![f32::NEG_INFINITY; components];
            for element in data.chunks_exact(components) {
                for (c, v) in element.iter().enumerate() {
                    min[c] = min[c].min(*v);
                    max[c] = max[c].max(*v);
                }
            }
            accessor["min"] = json!(min);
            accessor["max"] = json!(max);
        }
        self.accessors.push(accessor);
        self.accessors.len() - 1
    }

    fn indices(&mut self, data: &[u16]) -> usize {
        let bytes: Vec<u8> = data.iter().flat_map(|v| v.to_le_bytes()).collect();
        let view = self.view(&bytes, Some(34963));
        self.accessors.push(json!({
            "bufferView": view,
            "componentType": 5123,
            "count": data.len(),
            "type": "SCALAR",
        }));
        self.accessors.len() - 1
    }

    fn joints(&mut self, data: &[[u8; 4]]) -> usize {
        let bytes: Vec<u8> = data.iter().flatten().copied().collect();
        let view = self.view(&bytes, Some(34962));
        self.accessors.push(json!({
            "bufferView": view,
            "componentType": 5121,
            "count": data.len(),
            "type": "VEC4",
        }));
        self.accessors.len() - 1
    }
}

/// The surface's height for each morph target at (x, z), and its gradient.
fn target_height(target: usize, x: f32, z: f32) -> (f32, f32, f32) {
    if target == 0 {
        // A bump in the middle.
        let h = 0.25 * (-(x * x + z * z) / 0.06).exp();
        (h, h * (-2.0 * x / 0.06), h * (-2.0 * z / 0.06))
    } else {
        // Ripples.
        let (k, a) = (7.0, 0.06);
        (
            a * (k * x).sin() * (k * z).cos(),
            a * k * (k * x).cos() * (k * z).cos(),
            -a * k * (k * x).sin() * (k * z).sin(),
        )
    }
}

fn surface(bin: &mut Binary) -> Value {
    let n = GRID;
    let mut positions = Vec::with_capacity(n * n * 3);
    let mut normals = Vec::with_capacity(n * n * 3);
    let mut targets = [Vec::new(), Vec::new()];
    let mut target_normals = [Vec::new(), Vec::new()];
    for j in 0..n {
        for i in 0..n {
            let x = (i as f32 / (n - 1) as f32 - 0.5) * SURFACE_SIZE;
            let z = (j as f32 / (n - 1) as f32 - 0.5) * SURFACE_SIZE;
            positions.extend_from_slice(&[x, 0.0, z]);
            normals.extend_from_slice(&[0.0, 1.0, 0.0]);
            for t in 0..2 {
                let (h, dx, dz) = target_height(t, x, z);
                targets[t].extend_from_slice(&[0.0, h, 0.0]);
                let normal = Vec3::new(-dx, 1.0, -dz).normalize() - Vec3::Y;
                target_normals[t].extend_from_slice(&normal.to_array());
            }
        }
    }
    let mut indices = Vec::new();
    for j in 0..n - 1 {
        for i in 0..n - 1 {
            let a = (j * n + i) as u16;
            let (b, c, d) = (a + 1, a + n as u16, a + n as u16 + 1);
            indices.extend_from_slice(&[a, c, b, b, c, d]);
        }
    }
    let position = bin.floats(&positions, 3, true, true);
    let normal = bin.floats(&normals, 3, false, true);
    let index = bin.indices(&indices);
    let target_accessors: Vec<Value> = (0..2)
        .map(|t| {
            json!({
                "POSITION": bin.floats(&targets[t], 3, true, true),
                "NORMAL": bin.floats(&target_normals[t], 3, false, true),
            })
        })
        .collect();
    json!({
        "name": "surface",
        "primitives": [{
            "attributes": {"POSITION": position, "NORMAL": normal},
            "indices": index,
            "material": 0,
            "targets": target_accessors,
        }],
        "weights": [0.0, 0.0],
        "extras": {"targetNames": ["bump", "ripple"]},
    })
}

/// A square bar from the shoulder up, in bind-pose scene space, bound to the shoulder
/// (joint 0) below the elbow and the elbow (joint 1) above, blended around it.
fn arm(bin: &mut Binary) -> Value {
    let rings = 12;
    let (mut positions, mut normals, mut joints, mut weights) =
        (Vec::new(), Vec::new(), Vec::new(), Vec::new());
    let mut indices: Vec<u16> = Vec::new();
    let w = ARM_HALF_WIDTH;
    let sides = [
        (Vec3::X, Vec3::Z),
        (Vec3::Z, Vec3::NEG_X),
        (Vec3::NEG_X, Vec3::NEG_Z),
        (Vec3::NEG_Z, Vec3::X),
    ];
    let mut push = |p: Vec3, n: Vec3, positions: &mut Vec<f32>, normals: &mut Vec<f32>| {
        let t = ((p.y - SHOULDER_AT.y) / ARM_LENGTH).clamp(0.0, 1.0);
        let s = ((t - 0.4) / 0.2).clamp(0.0, 1.0);
        let elbow = s * s * (3.0 - 2.0 * s);
        positions.extend_from_slice(&p.to_array());
        normals.extend_from_slice(&n.to_array());
        // Only joints with weight are named (a zero weight names joint 0, as exporters do).
        if elbow <= 0.0 || elbow >= 1.0 {
            joints.push([u8::from(elbow >= 1.0), 0, 0, 0]);
            weights.extend_from_slice(&[1.0, 0.0, 0.0, 0.0]);
        } else {
            joints.push([0u8, 1, 0, 0]);
            weights.extend_from_slice(&[1.0 - elbow, elbow, 0.0, 0.0]);
        }
    };
    for (normal, along) in sides {
        let first = (positions.len() / 3) as u16;
        for r in 0..=rings {
            let y = SHOULDER_AT.y + ARM_LENGTH * r as f32 / rings as f32;
            for side in [-1.0, 1.0] {
                let p = Vec3::new(SHOULDER_AT.x, y, SHOULDER_AT.z) + normal * w + along * w * side;
                push(p, normal, &mut positions, &mut normals);
            }
        }
        for r in 0..rings as u16 {
            let a = first + 2 * r;
            indices.extend_from_slice(&[a, a + 1, a + 2, a + 1, a + 3, a + 2]);
        }
    }
    // The top cap.
    let first = (positions.len() / 3) as u16;
    let top = SHOULDER_AT.y + ARM_LENGTH;
    for (dx, dz) in [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)] {
        let p = Vec3::new(SHOULDER_AT.x + dx * w, top, SHOULDER_AT.z + dz * w);
        push(p, Vec3::Y, &mut positions, &mut normals);
    }
    indices.extend_from_slice(&[first, first + 2, first + 1, first, first + 3, first + 2]);
    let position = bin.floats(&positions, 3, true, true);
    let normal = bin.floats(&normals, 3, false, true);
    let joint = bin.joints(&joints);
    let weight = bin.floats(&weights, 4, false, true);
    let index = bin.indices(&indices);
    json!({
        "name": "arm",
        "primitives": [{
            "attributes": {
                "POSITION": position, "NORMAL": normal, "JOINTS_0": joint, "WEIGHTS_0": weight
            },
            "indices": index,
            "material": 1,
        }],
    })
}

/// A cube of side 0.25 m about its node's origin, flat-shaded.
fn block(bin: &mut Binary) -> Value {
    let h = 0.125;
    let (mut positions, mut normals, mut indices) = (Vec::new(), Vec::new(), Vec::<u16>::new());
    for axis in 0..3 {
        for sign in [-1.0f32, 1.0] {
            let mut n = [0.0f32; 3];
            n[axis] = sign;
            let n = Vec3::from(n);
            let (u, v) = (
                n.any_orthonormal_vector(),
                n.cross(n.any_orthonormal_vector()),
            );
            let first = (positions.len() / 3) as u16;
            for (a, b) in [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)] {
                let p = (n + u * a + v * b) * h;
                positions.extend_from_slice(&p.to_array());
                normals.extend_from_slice(&n.to_array());
            }
            // Counter-clockwise seen from outside: u × v = n.
            indices.extend_from_slice(&[first, first + 1, first + 2, first, first + 2, first + 3]);
        }
    }
    let position = bin.floats(&positions, 3, true, true);
    let normal = bin.floats(&normals, 3, false, true);
    let index = bin.indices(&indices);
    json!({
        "name": "block",
        "primitives": [{
            "attributes": {"POSITION": position, "NORMAL": normal},
            "indices": index,
            "material": 2,
        }],
    })
}

fn quat_about(axis: Vec3, degrees: f32) -> [f32; 4] {
    Quat::from_axis_angle(axis, degrees.to_radians()).to_array()
}

/// The animation "Show": every channel, each with its own interpolation.
fn show(bin: &mut Binary) -> Value {
    let mut samplers = Vec::new();
    let mut channels = Vec::new();
    let mut add = |bin: &mut Binary,
                   node: usize,
                   path: &str,
                   times: &[f32],
                   output: &[f32],
                   components: usize,
                   interpolation: &str| {
        let input = bin.floats(times, 1, true, false);
        let output = bin.floats(output, components, false, false);
        samplers.push(json!({"input": input, "output": output, "interpolation": interpolation}));
        channels
            .push(json!({"sampler": samplers.len() - 1, "target": {"node": node, "path": path}}));
    };
    // The surface: bump up, ripple, both, none.
    add(
        bin,
        0,
        "weights",
        &[0.0, 1.0, 2.0, 3.0, 4.0],
        &[0.0, 0.0, 1.0, 0.0, 0.0, 1.0, 1.0, 1.0, 0.0, 0.0],
        1,
        "LINEAR",
    );
    // The shoulder leans forward and back.
    let shoulder: Vec<f32> = [0.0, 20.0, 0.0]
        .iter()
        .flat_map(|&d| quat_about(Vec3::X, -d))
        .collect();
    add(bin, 2, "rotation", &[0.0, 2.0, 4.0], &shoulder, 4, "LINEAR");
    // The elbow bends one way, then the other, easing (zero tangents).
    let elbow: Vec<f32> = [0.0, 70.0, -40.0, 0.0]
        .iter()
        .flat_map(|&d| {
            let mut key = vec![0.0; 4];
            key.extend_from_slice(&quat_about(Vec3::Z, d));
            key.extend_from_slice(&[0.0; 4]);
            key
        })
        .collect();
    add(
        bin,
        3,
        "rotation",
        &[0.0, 1.5, 3.0, 4.0],
        &elbow,
        4,
        "CUBICSPLINE",
    );
    // The block turns a full turn (through a quaternion sign flip) and jumps up half-way.
    let turn: Vec<f32> = [0.0, 90.0, 180.0, 270.0, 360.0]
        .iter()
        .flat_map(|&d| quat_about(Vec3::Y, d))
        .collect();
    add(
        bin,
        4,
        "rotation",
        &[0.0, 1.0, 2.0, 3.0, 4.0],
        &turn,
        4,
        "LINEAR",
    );
    let up = BLOCK_AT + Vec3::Y * 0.2;
    let jump = [BLOCK_AT.to_array(), up.to_array(), BLOCK_AT.to_array()].concat();
    add(bin, 4, "translation", &[0.0, 2.0, 4.0], &jump, 3, "STEP");
    json!({"name": "Show", "samplers": samplers, "channels": channels})
}

/// The sample as a `.glb` file's bytes.
pub fn animated_sample_glb() -> Vec<u8> {
    let mut bin = Binary::default();
    let meshes = vec![surface(&mut bin), arm(&mut bin), block(&mut bin)];
    let elbow_global = Mat4::from_translation(SHOULDER_AT + Vec3::Y * ELBOW_ABOVE);
    let inverse_bind: Vec<f32> = [Mat4::from_translation(SHOULDER_AT), elbow_global]
        .iter()
        .flat_map(|m| m.inverse().to_cols_array())
        .collect();
    let inverse_bind = bin.floats(&inverse_bind, 16, false, false);
    let animation = show(&mut bin);
    let nodes = json!([
        {"name": "surface", "mesh": 0, "translation": SURFACE_AT.to_array()},
        {"name": "arm", "mesh": 1, "skin": 0},
        {"name": "shoulder", "translation": SHOULDER_AT.to_array(), "children": [3]},
        {"name": "elbow", "translation": [0.0, ELBOW_ABOVE, 0.0]},
        {"name": "block", "mesh": 2, "translation": BLOCK_AT.to_array()},
    ]);
    let material = |name: &str, rgb: [f32; 3]| {
        json!({
            "name": name,
            "pbrMetallicRoughness": {
                "baseColorFactor": [rgb[0], rgb[1], rgb[2], 1.0],
                "metallicFactor": 0.0,
                "roughnessFactor": 0.55,
            },
            "doubleSided": true,
        })
    };
    bin.bytes.resize(bin.bytes.len().next_multiple_of(4), 0);
    let document = json!({
        "asset": {"version": "2.0", "generator": "omnicave gen-assets (animated sample)"},
        "scene": 0,
        "scenes": [{"name": "animated", "nodes": [0, 1, 2, 4]}],
        "nodes": nodes,
        "meshes": meshes,
        "skins": [{"name": "arm skin", "joints": [2, 3], "inverseBindMatrices": inverse_bind}],
        "animations": [animation],
        "materials": [
            material("surface", [0.15, 0.45, 0.9]),
            material("arm", [0.9, 0.45, 0.15]),
            material("block", [0.3, 0.8, 0.3]),
        ],
        "buffers": [{"byteLength": bin.bytes.len()}],
        "bufferViews": bin.views,
        "accessors": bin.accessors,
    });
    super::glb_writer::glb_bytes(&document, &bin.bytes)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::load_gltf_bytes;
    use crate::scene::rig::{Pose, PoseAt};

    #[test]
    fn the_sample_loads_with_its_skin_morph_targets_and_animation() {
        let scene = load_gltf_bytes(
            &animated_sample_glb(),
            std::path::Path::new("animated.glb"),
            &Default::default(),
        )
        .unwrap();
        let rig = &scene.rig;
        assert_eq!(rig.clips.len(), 1);
        assert_eq!(rig.clips[0].name, "Show");
        assert!((rig.clips[0].duration() - SHOW_SECONDS).abs() < 1e-6);
        assert_eq!(rig.skins.len(), 1);
        assert_eq!(rig.deformers.len(), 3, "surface, arm and block all move");
        assert_eq!(rig.deformers[0].targets.len(), 2);
        // At rest the arm's top is straight above the shoulder.
        let mut pose = Pose::default();
        let mut vertices = scene.vertices.clone();
        rig.deform_all(&mut pose, PoseAt::REST, &mut vertices);
        let top = vertices
            .iter()
            .map(|v| Vec3::from(v.position))
            .filter(|p| (p.x - SHOULDER_AT.x).abs() < 0.1 && (p.z - SHOULDER_AT.z).abs() < 0.1)
            .map(|p| p.y)
            .fold(f32::MIN, f32::max);
        assert!((top - (SHOULDER_AT.y + ARM_LENGTH)).abs() < 1e-5, "{top}");
        // A second in, the surface's bump is full.
        rig.deform_all(
            &mut pose,
            PoseAt {
                clip: Some(0),
                time: 1.0,
            },
            &mut vertices,
        );
        let first = rig.deformers[0].first_vertex as usize;
        let middle = first + (GRID / 2) * GRID + GRID / 2;
        assert!(vertices[middle].position[1] > SURFACE_AT.y + 0.2);
    }
}
