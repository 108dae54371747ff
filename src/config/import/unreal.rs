//! Unreal's scene graph as both nDisplay formats give it (the JSON `.ndisplay` and the legacy
//! `.cfg`): components with a parent, a location, a rotation (pitch, yaw, roll in degrees) and
//! a scale, in Unreal's left-handed frame (x forward, y right, z up). A screen is a plane in
//! its component's y–z plane, facing back along x.

use std::collections::{HashMap, HashSet};

use glam::{DMat3, DVec3};

use super::ImportedWall;

/// One scene component: an xform (scene node), a camera, a screen.
#[derive(Debug, Clone)]
pub struct Component {
    pub parent: Option<String>,
    pub location: DVec3,
    /// Pitch, yaw, roll, degrees.
    pub rotation: [f64; 3],
    pub scale: DVec3,
    /// Why it moves with the viewer (a camera, a tracked node), if it does.
    pub follows: Option<String>,
    /// Where it is defined (a line, a JSON path), for messages.
    pub at: String,
}

/// Unreal's FRotationMatrix of pitch, yaw, roll (degrees): the images of x, y, z.
pub fn rotation_matrix([pitch, yaw, roll]: [f64; 3]) -> DMat3 {
    let (sp, cp) = pitch.to_radians().sin_cos();
    let (sy, cy) = yaw.to_radians().sin_cos();
    let (sr, cr) = roll.to_radians().sin_cos();
    let x = DVec3::new(cp * cy, cp * sy, sp);
    let y = DVec3::new(sr * sp * cy - cr * sy, sr * sp * sy + cr * cy, -sr * cp);
    let z = DVec3::new(-(cr * sp * cy + sr * sy), cy * sr - cr * sp * sy, cr * cp);
    DMat3::from_cols(x, y, z)
}

/// Unreal (x forward, y right, z up; left-handed) to CAVE (x right, y up, +z back;
/// right-handed), unscaled.
pub fn to_cave(v: DVec3) -> DVec3 {
    DVec3::new(v.y, v.z, -v.x)
}

/// How Unreal's axes became CAVE's, for the output's comments.
pub fn conversion(unit: &str, scale: f64) -> String {
    format!(
        "Unreal's frame (x forward, y right, z up; left-handed) in {unit}: CAVE x = Unreal y, \
         CAVE y = Unreal z, CAVE z = -Unreal x (right-handed), lengths × {scale}"
    )
}

/// The components by id.
#[derive(Debug, Default)]
pub struct Graph {
    pub components: HashMap<String, Component>,
}

impl Graph {
    /// Marks the components that carry the viewer: a camera's parent (not a root) under which
    /// no more screens hang than cameras (`shutter_glasses` carrying three cameras and one
    /// `screen_main` in RWTH's aixCAVE, whose walls hang from `cave_origin`; a static camera
    /// beside the walls it looks at marks nothing). Files since UE 5 say nothing of trackers,
    /// so this is how a head-attached screen is told apart. Linear in the graph.
    pub fn mark_viewer_nodes(&mut self, cameras: &[&str], screens: &[&str]) {
        // The candidates: each camera's parent that has a parent itself, with its cameras.
        let mut index: HashMap<String, usize> = HashMap::new();
        let mut candidates: Vec<(String, String, usize)> = Vec::new();
        for camera in cameras {
            let Some(parent) = self
                .components
                .get(*camera)
                .and_then(|c| c.parent.clone())
                .filter(|p| !p.is_empty())
            else {
                continue;
            };
            let is_root = self
                .components
                .get(&parent)
                .is_none_or(|c| c.parent.as_deref().is_none_or(str::is_empty));
            if is_root {
                continue;
            }
            match index.get(&parent) {
                Some(&i) => candidates[i].2 += 1,
                None => {
                    index.insert(parent.clone(), candidates.len());
                    candidates.push((parent, (*camera).to_owned(), 1));
                }
            }
        }
        if candidates.is_empty() {
            return;
        }
        // Screens under each candidate: each screen adds one to its nearest candidate and that
        // one's candidate ancestors (each component's nearest candidate found once).
        let mut nearest: HashMap<&str, Option<usize>> = HashMap::new();
        let above: Vec<Option<usize>> = candidates
            .iter()
            .map(|(c, _, _)| {
                let parent = self.components[c.as_str()].parent.as_deref().unwrap_or("");
                self.nearest_candidate(parent, &index, &mut nearest)
            })
            .collect();
        let mut under = vec![0usize; candidates.len()];
        for screen in screens {
            let mut at = self.nearest_candidate(screen, &index, &mut nearest);
            let mut steps = 0;
            while let Some(i) = at {
                under[i] += 1;
                at = above[i];
                steps += 1;
                if steps > candidates.len() {
                    break; // a cycle: Placer::place names it
                }
            }
        }
        for ((carrier, camera, cameras), under) in candidates.iter().zip(under) {
            if under == 0 || under > *cameras {
                continue;
            }
            if let Some(c) = self.components.get_mut(carrier.as_str())
                && c.follows.is_none()
            {
                c.follows = Some(format!(
                    "it is under '{carrier}', which carries the camera '{camera}' and no more \
                     screens than cameras: it moves with the viewer"
                ));
            }
        }
    }

    /// The nearest candidate (by index) among `id` and its ancestors, each component's found
    /// once (`memo`); a cycle or a missing parent ends the walk ([`Placer::place`] names them).
    fn nearest_candidate<'a>(
        &'a self,
        id: &'a str,
        index: &HashMap<String, usize>,
        memo: &mut HashMap<&'a str, Option<usize>>,
    ) -> Option<usize> {
        let mut path: Vec<&'a str> = Vec::new();
        let mut seen: HashSet<&'a str> = HashSet::new();
        let mut at = id;
        let mut found = None;
        loop {
            if let Some(&m) = memo.get(at) {
                found = m;
                break;
            }
            let Some((key, c)) = self.components.get_key_value(at) else {
                break;
            };
            if !seen.insert(key.as_str()) {
                break;
            }
            path.push(key.as_str());
            if let Some(&i) = index.get(key) {
                found = Some(i);
                break;
            }
            match c.parent.as_deref() {
                Some(p) if !p.is_empty() => at = p,
                _ => break,
            }
        }
        for node in path {
            memo.insert(node, found);
        }
        found
    }
}

/// A placement as Unreal's FTransform holds one: a rotation, a scale per axis and a
/// translation, composed as Unreal composes them (rotations multiply, scales multiply axis by
/// axis, never a shear).
#[derive(Debug, Clone, Copy)]
pub struct Xform {
    pub rotation: DMat3,
    pub scale: DVec3,
    pub translation: DVec3,
}

impl Xform {
    pub const IDENTITY: Self = Self {
        rotation: DMat3::IDENTITY,
        scale: DVec3::ONE,
        translation: DVec3::ZERO,
    };

    /// A point of this component's frame in its parent's (or the root's) frame.
    pub fn point(&self, p: DVec3) -> DVec3 {
        self.translation + self.rotation * (self.scale * p)
    }

    /// `child`'s placement, given in this frame, in this frame's parent.
    pub fn then(&self, child: &Self) -> Self {
        Self {
            rotation: self.rotation * child.rotation,
            scale: self.scale * child.scale,
            translation: self.point(child.translation),
        }
    }
}

/// A component's placement in the scene root, and why it follows the viewer (itself or a
/// parent), if it does.
type Placement = (Xform, Option<String>);

/// Places components, each once (a chain shared by many screens is walked once: linear in the
/// file).
#[derive(Debug)]
pub struct Placer<'a> {
    graph: &'a Graph,
    placed: HashMap<&'a str, Placement>,
}

impl<'a> Placer<'a> {
    pub fn new(graph: &'a Graph) -> Self {
        Self {
            graph,
            placed: HashMap::new(),
        }
    }

    /// Component `id` placed in the scene root. A missing parent or a cycle is an error naming
    /// them; any depth of acyclic parents is followed.
    pub fn place(&mut self, id: &'a str) -> Result<Placement, String> {
        // Up to the root or to a component already placed.
        let mut path: Vec<&'a str> = Vec::new();
        let mut on_path: HashSet<&'a str> = HashSet::new();
        let mut at = id;
        let mut base: Placement = (Xform::IDENTITY, None);
        loop {
            if let Some(p) = self.placed.get(at) {
                base = p.clone();
                break;
            }
            if !on_path.insert(at) {
                let from = path.iter().position(|p| *p == at).unwrap_or(0);
                let mut cycle: Vec<&str> = path[from..].to_vec();
                cycle.push(at);
                return Err(format!("parents form a cycle: {}", cycle.join(" → ")));
            }
            let (key, c) =
                self.graph
                    .components
                    .get_key_value(at)
                    .ok_or_else(|| match path.last() {
                        None => format!("'{at}' is not in the scene"),
                        Some(child) => format!(
                            "'{child}' ({}) has the parent '{at}', which is not in the scene",
                            self.graph.components[*child].at
                        ),
                    })?;
            path.push(key.as_str());
            match c.parent.as_deref() {
                Some(p) if !p.is_empty() => at = p,
                _ => break,
            }
        }
        // Down again, placing each.
        for id in path.into_iter().rev() {
            let c = &self.graph.components[id];
            let local = Xform {
                rotation: rotation_matrix(c.rotation),
                scale: c.scale,
                translation: c.location,
            };
            let follows = base.1.clone().or_else(|| c.follows.clone());
            base = (base.0.then(&local), follows);
            self.placed.insert(id, base.clone());
        }
        Ok(base)
    }

    /// The corners of screen `id` (a `width` × `height` plane, file units, scaled by its own
    /// and its parents' scale), `metres` per file unit; `Ok(Err(why))` for a screen that moves
    /// with the viewer.
    pub fn screen(
        &mut self,
        id: &'a str,
        [w, h]: [f64; 2],
        metres: f64,
    ) -> Result<Result<[DVec3; 3], String>, String> {
        let (to_root, follows) = self.place(id)?;
        if let Some(why) = follows {
            return Ok(Err(why));
        }
        // Lower left, lower right, upper left in the screen's own y–z plane.
        let corners = [
            DVec3::new(0.0, -0.5 * w, -0.5 * h),
            DVec3::new(0.0, 0.5 * w, -0.5 * h),
            DVec3::new(0.0, -0.5 * w, 0.5 * h),
        ]
        .map(|p| to_cave(to_root.point(p)) * metres);
        Ok(Ok(corners))
    }
}

/// Budget: screens in one file, the viewer's own included (four times the walls imported).
pub const MAX_SCREENS: usize = 4 * super::MAX_IMPORTED_WALLS;

/// Makes the wall of a placed screen.
pub fn wall(name: String, corners: [DVec3; 3], resolution: Option<[u32; 2]>) -> ImportedWall {
    ImportedWall {
        name,
        lower_left: corners[0],
        lower_right: corners[1],
        upper_left: corners[2],
        resolution,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn node(parent: Option<&str>, location: DVec3, yaw: f64, scale: DVec3) -> Component {
        Component {
            parent: parent.map(String::from),
            location,
            rotation: [0.0, yaw, 0.0],
            scale,
            follows: None,
            at: "here".into(),
        }
    }

    #[test]
    fn a_front_screen_two_parents_deep_with_yaw_and_scale() {
        let mut g = Graph::default();
        // A root turned 90° (yaw: x forward → y), scaled ×2, then the screen 1 unit ahead.
        g.components.insert(
            "root".into(),
            node(None, DVec3::new(0.0, 0.0, 100.0), 90.0, DVec3::splat(2.0)),
        );
        g.components.insert(
            "s".into(),
            node(Some("root"), DVec3::new(1.0, 0.0, 0.0), 0.0, DVec3::ONE),
        );
        let [ll, lr, ul] = Placer::new(&g)
            .screen("s", [2.0, 1.0], 0.01)
            .unwrap()
            .unwrap();
        // The screen's centre (1, 0, 0) scaled to (2, 0, 0), turned to (0, 2, 0), moved to
        // (0, 2, 100): CAVE (2, 100, 0) cm. Its sides are doubled by the root's scale.
        let centre = 0.5 * (lr + ul);
        assert!(
            (centre - DVec3::new(0.02, 1.0, 0.0)).length() < 1e-12,
            "{centre}"
        );
        assert!(((lr - ll).length() - 0.04).abs() < 1e-12);
        assert!(((ul - ll).length() - 0.02).abs() < 1e-12);
    }

    #[test]
    fn scales_compose_as_unreal_composes_them_without_shear() {
        // A parent stretched along its y, a child screen turned 90° under it: Unreal multiplies
        // the scales axis by axis, so the screen's width (its own y) is doubled.
        let mut g = Graph::default();
        g.components.insert(
            "p".into(),
            node(None, DVec3::ZERO, 0.0, DVec3::new(1.0, 2.0, 1.0)),
        );
        g.components
            .insert("s".into(), node(Some("p"), DVec3::ZERO, 90.0, DVec3::ONE));
        let [ll, lr, ul] = Placer::new(&g)
            .screen("s", [100.0, 100.0], 1.0)
            .unwrap()
            .unwrap();
        assert!(((lr - ll).length() - 200.0).abs() < 1e-9);
        assert!(((ul - ll).length() - 100.0).abs() < 1e-9);
        assert!(
            (lr - ll).dot(ul - ll).abs() < 1e-9,
            "a rectangle, not a shear"
        );
    }

    #[test]
    fn a_screen_beside_the_cameras_on_the_glasses_follows_the_viewer() {
        let mut g = Graph::default();
        g.components
            .insert("origin".into(), node(None, DVec3::ZERO, 0.0, DVec3::ONE));
        for (id, parent) in [
            ("glasses", "origin"),
            ("cam_l", "glasses"),
            ("cam_r", "glasses"),
            ("main", "glasses"),
            ("wall", "origin"),
            ("hinge", "origin"),
            ("static_cam", "hinge"),
            ("strip_a", "hinge"),
            ("strip_b", "hinge"),
        ] {
            g.components
                .insert(id.into(), node(Some(parent), DVec3::ZERO, 0.0, DVec3::ONE));
        }
        g.mark_viewer_nodes(
            &["cam_l", "cam_r", "static_cam"],
            &["main", "wall", "strip_a", "strip_b"],
        );
        let mut placer = Placer::new(&g);
        assert!(placer.place("main").unwrap().1.is_some(), "on the glasses");
        assert!(placer.place("wall").unwrap().1.is_none());
        // Two strips beside one static camera: walls.
        assert!(placer.place("strip_a").unwrap().1.is_none());
    }

    #[test]
    fn cycles_and_missing_parents_are_named() {
        let mut g = Graph::default();
        for (id, p) in [("a", "b"), ("b", "c"), ("c", "a")] {
            g.components
                .insert(id.into(), node(Some(p), DVec3::ZERO, 0.0, DVec3::ONE));
        }
        let e = Placer::new(&g).place("a").unwrap_err();
        assert!(e.contains("cycle: a → b → c → a"), "{e}");
        g.components
            .insert("d".into(), node(Some("x"), DVec3::ZERO, 0.0, DVec3::ONE));
        let e = Placer::new(&g).place("d").unwrap_err();
        assert!(e.contains("'d' (here) has the parent 'x'"), "{e}");
        // Deep but acyclic: followed.
        for i in 0..500 {
            g.components.insert(
                format!("n{i}"),
                node(
                    (i > 0).then(|| format!("n{}", i - 1)).as_deref(),
                    DVec3::X,
                    0.0,
                    DVec3::ONE,
                ),
            );
        }
        let mut placer = Placer::new(&g);
        let (to_root, _) = placer.place("n499").unwrap();
        assert_eq!(to_root.translation, DVec3::new(500.0, 0.0, 0.0));
        // A camera up the chain: every screen below it follows the viewer.
        g.components.get_mut("n10").unwrap().follows = Some("a camera".into());
        let mut placer = Placer::new(&g);
        assert_eq!(placer.place("n499").unwrap().1.as_deref(), Some("a camera"));
        assert_eq!(placer.place("n9").unwrap().1, None);
    }
}
