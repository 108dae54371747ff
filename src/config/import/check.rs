//! `config import --check`: each imported wall's size, centre and normal, and whether walls
//! that share an edge meet there (the gap or overlap in millimetres), before anything is
//! written, to compare with the lab's drawing.

use glam::DVec3;

use super::ImportedWall;

/// Edges closer than this meet, metres (the importer's promised precision, 0.1 mm).
pub const MEET_M: f64 = 1e-4;
/// Walls in one plane to within this are tiles of one wall, metres (measured screens are a few
/// millimetres off).
const COPLANAR_M: f64 = 0.005;
/// Parallel edges farther apart than this are not neighbours, metres.
const NEIGHBOUR_M: f64 = 0.1;
/// Edges at more than this angle are not parallel (cos 2°).
const PARALLEL_COS: f64 = 0.999_390_827;

/// One wall as the check prints it.
#[derive(Debug, Clone, PartialEq)]
pub struct WallCheck {
    pub name: String,
    /// Width, height, metres.
    pub size: [f64; 2],
    pub centre: DVec3,
    /// Towards the side the image is seen from.
    pub normal: DVec3,
}

/// How two walls' nearest parallel edges meet.
#[derive(Debug, Clone, PartialEq)]
pub struct EdgeJoin {
    pub a: String,
    pub a_edge: &'static str,
    pub b: String,
    pub b_edge: &'static str,
    /// The largest distance between the edges along their common length, metres.
    pub distance: f64,
    /// One wall reaches into the other (through its plane, or over it when coplanar).
    pub overlap: bool,
}

impl EdgeJoin {
    pub fn describe(&self) -> String {
        let what = if self.distance <= MEET_M {
            "meet".to_owned()
        } else if self.overlap {
            format!("overlap {:.1} mm", self.distance * 1000.0)
        } else {
            format!("gap {:.1} mm", self.distance * 1000.0)
        };
        format!(
            "{} {} edge – {} {} edge: {what}",
            self.a, self.a_edge, self.b, self.b_edge
        )
    }
}

/// A wall's four edges by name, each from one corner to the next.
fn edges(w: &ImportedWall) -> [(&'static str, DVec3, DVec3); 4] {
    let upper_right = w.lower_right + (w.upper_left - w.lower_left);
    [
        ("lower", w.lower_left, w.lower_right),
        ("right", w.lower_right, upper_right),
        ("upper", upper_right, w.upper_left),
        ("left", w.upper_left, w.lower_left),
    ]
}

/// Distance from `p` to the wall's rectangle (0 inside it).
fn distance_to_rectangle(w: &ImportedWall, p: DVec3) -> f64 {
    let (x, y) = (w.lower_right - w.lower_left, w.upper_left - w.lower_left);
    let d = p - w.lower_left;
    let s = (d.dot(x) / x.length_squared()).clamp(0.0, 1.0);
    let t = (d.dot(y) / y.length_squared()).clamp(0.0, 1.0);
    (w.lower_left + s * x + t * y - p).length()
}

/// How edge `b` lies along edge `a`: the largest distance between them over their common
/// length, and the middle of that length on each, when they are parallel and share at least a
/// tenth of the shorter.
fn along(a: (DVec3, DVec3), b: (DVec3, DVec3)) -> Option<(f64, DVec3, DVec3)> {
    let da = a.1 - a.0;
    let len_a = da.length();
    let u = da.try_normalize()?;
    let db = b.1 - b.0;
    let len_b = db.length();
    if u.dot(db.try_normalize()?).abs() < PARALLEL_COS {
        return None;
    }
    let (t0, t1) = ((b.0 - a.0).dot(u), (b.1 - a.0).dot(u));
    let (lo, hi) = (t0.min(t1).max(0.0), t0.max(t1).min(len_a));
    if hi - lo < 0.1 * len_a.min(len_b) {
        return None;
    }
    // Points of b over the common length, and their distance to a's line.
    let on_b = |t: f64| b.0 + db * ((t - t0) / (t1 - t0));
    let off = |p: DVec3| {
        let q = p - a.0;
        (q - q.dot(u) * u).length()
    };
    let (p, q) = (on_b(lo), on_b(hi));
    // The middle of the common span, on each edge.
    Some((
        off(p).max(off(q)),
        a.0 + u * (0.5 * (lo + hi)),
        0.5 * (p + q),
    ))
}

/// How two walls in one plane lie side by side: in A's axes, the overlap of their extents
/// across the side they share (negative: a gap), when they share at least a tenth of it along.
fn coplanar(a: &ImportedWall, b: &ImportedWall) -> Option<EdgeJoin> {
    let (x, y) = (a.lower_right - a.lower_left, a.upper_left - a.lower_left);
    let (ex, ey) = (x.try_normalize()?, y.try_normalize()?);
    let normal = ex.cross(ey);
    let b_normal = (b.lower_right - b.lower_left)
        .cross(b.upper_left - b.lower_left)
        .try_normalize()?;
    let b_upper_right = b.lower_right + (b.upper_left - b.lower_left);
    let off_plane = [b.lower_left, b.lower_right, b.upper_left, b_upper_right]
        .iter()
        .map(|p| (*p - a.lower_left).dot(normal).abs())
        .fold(0.0, f64::max);
    if normal.dot(b_normal).abs() < PARALLEL_COS || off_plane > COPLANAR_M {
        return None;
    }
    let corners = [b.lower_left, b.lower_right, b.upper_left, b_upper_right]
        .map(|p| (p - a.lower_left).dot(ex));
    let (bx0, bx1) = (
        corners.iter().copied().fold(f64::INFINITY, f64::min),
        corners.iter().copied().fold(f64::NEG_INFINITY, f64::max),
    );
    let corners = [b.lower_left, b.lower_right, b.upper_left, b_upper_right]
        .map(|p| (p - a.lower_left).dot(ey));
    let (by0, by1) = (
        corners.iter().copied().fold(f64::INFINITY, f64::min),
        corners.iter().copied().fold(f64::NEG_INFINITY, f64::max),
    );
    let (wa, ha) = (x.length(), y.length());
    let over_x = wa.min(bx1) - bx0.max(0.0);
    let over_y = ha.min(by1) - by0.max(0.0);
    // Side by side along x (sharing a vertical side) or along y (a horizontal one).
    let along_x = over_y >= 0.1 * ha.min(by1 - by0) && over_x > -NEIGHBOUR_M;
    let along_y = over_x >= 0.1 * wa.min(bx1 - bx0) && over_y > -NEIGHBOUR_M;
    let (across, a_edge, towards_b) = match (along_x, along_y) {
        // Overlapping in both: the narrower overlap is the shared side.
        (true, true) if over_x <= over_y => side_x(over_x, bx0 + bx1 > wa, ex),
        (true, true) => side_y(over_y, by0 + by1 > ha, ey),
        (true, false) => side_x(over_x, bx0 + bx1 > wa, ex),
        (false, true) => side_y(over_y, by0 + by1 > ha, ey),
        (false, false) => return None,
    };
    // B's side that faces A, in B's own axes (B may be turned in the plane).
    let (bx, by) = (
        (b.lower_right - b.lower_left).normalize_or_zero(),
        (b.upper_left - b.lower_left).normalize_or_zero(),
    );
    let towards_a = -towards_b;
    let b_edge = if towards_a.dot(bx).abs() >= towards_a.dot(by).abs() {
        if towards_a.dot(bx) > 0.0 {
            "right"
        } else {
            "left"
        }
    } else if towards_a.dot(by) > 0.0 {
        "upper"
    } else {
        "lower"
    };
    Some(EdgeJoin {
        a: a.name.clone(),
        a_edge,
        b: b.name.clone(),
        b_edge,
        distance: across.abs(),
        overlap: across > 0.0,
    })
}

/// The shared side of two walls side by side along A's width (`b_right`: B to A's right):
/// the overlap, A's edge and the direction from A towards B.
fn side_x(across: f64, b_right: bool, ex: DVec3) -> (f64, &'static str, DVec3) {
    if b_right {
        (across, "right", ex)
    } else {
        (across, "left", -ex)
    }
}

/// The shared side of two walls one above the other (`b_above`: B above A).
fn side_y(across: f64, b_above: bool, ey: DVec3) -> (f64, &'static str, DVec3) {
    if b_above {
        (across, "upper", ey)
    } else {
        (across, "lower", -ey)
    }
}

/// Each wall's size, centre and normal, and the join of every pair of walls that share an
/// edge: walls in one plane by how far they overlap or stand apart across their shared side
/// (projection tiles blended over each other overlap), walls at an angle by their nearest
/// parallel edges.
pub fn check_walls(walls: &[ImportedWall]) -> (Vec<WallCheck>, Vec<EdgeJoin>) {
    let checks = walls
        .iter()
        .map(|w| {
            let (x, y) = (w.lower_right - w.lower_left, w.upper_left - w.lower_left);
            WallCheck {
                name: w.name.clone(),
                size: [x.length(), y.length()],
                centre: w.lower_left + 0.5 * (x + y),
                normal: x.cross(y).normalize_or_zero(),
            }
        })
        .collect();
    let mut joins = Vec::new();
    for (i, a) in walls.iter().enumerate() {
        for b in &walls[i + 1..] {
            if let Some(join) = coplanar(a, b) {
                joins.push(join);
                continue;
            }
            let mut best: Option<EdgeJoin> = None;
            for (a_edge, a0, a1) in edges(a) {
                for (b_edge, b0, b1) in edges(b) {
                    let Some((distance, a_mid, b_mid)) = along((a0, a1), (b0, b1)) else {
                        continue;
                    };
                    if distance > NEIGHBOUR_M
                        || best.as_ref().is_some_and(|j| j.distance <= distance)
                    {
                        continue;
                    }
                    let overlap = distance_to_rectangle(b, a_mid) <= MEET_M
                        || distance_to_rectangle(a, b_mid) <= MEET_M;
                    best = Some(EdgeJoin {
                        a: a.name.clone(),
                        a_edge,
                        b: b.name.clone(),
                        b_edge,
                        distance,
                        overlap,
                    });
                }
            }
            joins.extend(best);
        }
    }
    (checks, joins)
}

/// The check as `config import --check` prints it.
pub fn check_report(walls: &[ImportedWall]) -> String {
    let (checks, joins) = check_walls(walls);
    let v = |p: DVec3| format!("({:.4}, {:.4}, {:.4})", p.x, p.y, p.z);
    let mut out = String::from("walls (CAVE space, metres):\n");
    for c in &checks {
        out.push_str(&format!(
            "  {}: {:.4} × {:.4} m, centre {}, normal {}\n",
            c.name,
            c.size[0],
            c.size[1],
            v(c.centre),
            v(c.normal)
        ));
    }
    out.push_str("edges shared by two walls:\n");
    if joins.is_empty() {
        out.push_str("  none (no two walls have parallel edges within 100 mm)\n");
    }
    for j in &joins {
        out.push_str(&format!("  {}\n", j.describe()));
    }
    let apart = joins.iter().filter(|j| j.distance > MEET_M).count();
    out.push_str(&format!(
        "{} walls, {} shared edges, {} meeting within 0.1 mm, {} apart\n",
        checks.len(),
        joins.len(),
        joins.len() - apart,
        apart
    ));
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn wall(name: &str, ll: DVec3, lr: DVec3, ul: DVec3) -> ImportedWall {
        ImportedWall {
            name: name.into(),
            lower_left: ll,
            lower_right: lr,
            upper_left: ul,
            resolution: None,
        }
    }

    /// The first join reads as `ends`.
    fn assert_join(joins: &[EdgeJoin], ends: &str) {
        let said = joins[0].describe();
        assert!(said.ends_with(ends), "{said}");
    }

    #[test]
    fn corners_meet_gap_and_overlap() {
        let left = wall(
            "left",
            DVec3::new(-1.0, 0.0, 1.0),
            DVec3::new(-1.0, 0.0, -1.0),
            DVec3::new(-1.0, 2.0, 1.0),
        );
        let front = |x0: f64| {
            wall(
                "front",
                DVec3::new(x0, 0.0, -1.0),
                DVec3::new(1.0, 0.0, -1.0),
                DVec3::new(x0, 2.0, -1.0),
            )
        };
        let (checks, joins) = check_walls(&[left.clone(), front(-1.0)]);
        assert_eq!(checks[0].normal, DVec3::X);
        assert_eq!(checks[1].normal, DVec3::Z);
        assert_eq!(checks[1].size, [2.0, 2.0]);
        assert_eq!(joins.len(), 1);
        assert_eq!((joins[0].a_edge, joins[0].b_edge), ("right", "left"));
        assert_join(&joins, "meet");
        // The front wall 12 mm short of the corner: a gap; 12 mm past it: an overlap.
        let (_, joins) = check_walls(&[left.clone(), front(-0.988)]);
        assert_join(&joins, "gap 12.0 mm");
        let (_, joins) = check_walls(&[left.clone(), front(-1.012)]);
        assert_join(&joins, "overlap 12.0 mm");
        // Far apart: no join.
        // Two tiles of one wall, 0.3 m blended over each other, then 5 mm apart.
        let tile = |x0: f64| {
            wall(
                "tile",
                DVec3::new(x0, 0.0, -1.0),
                DVec3::new(x0 + 1.0, 0.0, -1.0),
                DVec3::new(x0, 1.0, -1.0),
            )
        };
        let (_, joins) = check_walls(&[tile(0.0), tile(0.7)]);
        assert_eq!(joins.len(), 1);
        assert_join(&joins, "right edge – tile left edge: overlap 300.0 mm");
        let (_, joins) = check_walls(&[tile(1.005), tile(0.0)]);
        assert_join(&joins, "left edge – tile right edge: gap 5.0 mm");
        // Blended tiles 0.2 mm apart in depth are still tiles of one wall.
        let mut deeper = tile(0.7);
        for c in [
            &mut deeper.lower_left,
            &mut deeper.lower_right,
            &mut deeper.upper_left,
        ] {
            c.z -= 0.0002;
        }
        let (_, joins) = check_walls(&[tile(0.0), deeper]);
        assert_join(&joins, "right edge – tile left edge: overlap 300.0 mm");
        // The right tile turned 180° in its plane: its touching side is its own right.
        let turned = wall(
            "turned",
            DVec3::new(1.7, 1.0, -1.0),
            DVec3::new(0.7, 1.0, -1.0),
            DVec3::new(1.7, 0.0, -1.0),
        );
        let (_, joins) = check_walls(&[tile(0.0), turned]);
        assert_join(&joins, "right edge – turned right edge: overlap 300.0 mm");
        // A short front wall poking 12 mm through the left wall's plane, low down: an overlap.
        let short = wall(
            "short",
            DVec3::new(-1.012, 0.0, -1.0),
            DVec3::new(1.0, 0.0, -1.0),
            DVec3::new(-1.012, 0.8, -1.0),
        );
        let (_, joins) = check_walls(&[left.clone(), short]);
        assert_join(&joins, "overlap 12.0 mm");
        let far = wall(
            "far",
            DVec3::new(5.0, 0.0, 0.0),
            DVec3::new(6.0, 0.0, 0.0),
            DVec3::new(5.0, 1.0, 0.0),
        );
        assert!(check_walls(&[left, far]).1.is_empty());
    }
}
