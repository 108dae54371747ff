//! Closed-form checks of the ray-intersection model.

use glam::{DVec3, Vec3};

use super::grid::{Grid, percentile};
use super::points::shells;
use super::*;
use crate::cave::{Head, RenderMode, Wall, thesis_cave};

fn method(mode: RenderMode, assumed: Assumed) -> Method {
    Method { mode, assumed }
}

const IPD: f64 = 0.064;

/// The thesis CAVE with its tracked head at `head`, turned `yaw` degrees.
fn setup(head: Vec3, yaw: f32) -> Setup {
    let head = Head {
        position: head,
        orientation: Head::orientation_from_degrees(yaw, 0.0, 0.0),
    };
    Setup::new(&thesis_cave(), head, IPD, None)
}

/// The horizontal direction a head faces.
fn facing(head: &Head) -> DVec3 {
    let f = head.orientation.as_dquat().normalize() * DVec3::NEG_Z;
    DVec3::new(f.x, 0.0, f.z).normalize()
}

// The model is in double precision: a viewer whose eyes are the method's sees rays that meet
// exactly, up to rounding (about 1e-16 of a radian per operation, a few metres of lever).
const ZERO_ARCMIN: f64 = 1e-6;

fn assert_exact(j: &Judged, what: &str) {
    assert!(
        j.vertical_arcmin.abs() < ZERO_ARCMIN
            && j.direction_arcmin.abs() < ZERO_ARCMIN
            && j.horizontal_arcmin.abs() < ZERO_ARCMIN
            && (j.depth_ratio - 1.0).abs() < 1e-9,
        "{what}: {j:?}"
    );
}

#[test]
fn a_viewer_at_the_assumed_head_looking_as_the_method_assumes_sees_no_error() {
    let s = setup(Vec3::new(0.4, 1.6, 0.3), 35.0);
    let head = s.head;
    let points = shells(head.position.as_dvec3(), &[0.3, 1.0, 2.5, 10.0], 400);
    let cases = [
        (
            method(RenderMode::TrackedStereo, Assumed::Head),
            Gaze::Along(facing(&head)),
        ),
        (
            method(RenderMode::Stereo, Assumed::Head),
            Gaze::Along(DVec3::NEG_Z),
        ),
        (method(RenderMode::OmniOnAxis, Assumed::Head), Gaze::AtPoint),
        (
            method(RenderMode::OmniOffAxis, Assumed::Head),
            Gaze::AtPoint,
        ),
        (
            method(RenderMode::OmniOnAxis, Assumed::Centre),
            Gaze::AtPoint,
        ),
    ];
    for (m, gaze) in cases {
        let g = s.assumed_head(m.assumed).position.as_dvec3();
        let mut judged = 0;
        for &p in &points {
            let Some(shown) = s.shown_at(m, p) else {
                continue;
            };
            let Some(j) = judge(g, IPD, gaze, p, shown) else {
                continue;
            };
            assert_exact(&j, &format!("{} at {p}", m.name()));
            judged += 1;
        }
        // Most of a sphere around the head is on the three walls (floor, ceiling and the open
        // back are not): at least a quarter of the points must have been judged.
        assert!(judged > 100, "{}: only {judged} points judged", m.name());
    }
}

#[test]
fn a_point_on_a_wall_has_no_error_for_any_viewer_and_method() {
    let cave = thesis_cave();
    let s = Setup::new(&cave, Head::at(Vec3::new(-0.3, 1.7, 0.2)), IPD, None);
    let grid = Grid::over(&cave, 0.5, 1.5).unwrap();
    let mut checked = 0;
    for wall in &cave.walls {
        for (u, v) in [(0.1, 0.2), (0.5, 0.5), (0.9, 0.7), (0.3, 0.95)] {
            let p = wall.wall_point_of_pixel(glam::Vec2::new(
                u * wall.resolution[0] as f32,
                v * wall.resolution[1] as f32,
            ));
            let p = p.as_dvec3();
            for mode in RenderMode::ALL {
                for assumed in [Assumed::Head, Assumed::Centre] {
                    let m = method(mode, assumed);
                    let shown = s.shown_at(m, p).expect("a wall point is on its wall");
                    for cell in (0..grid.inside.len()).filter(|c| grid.inside[*c]) {
                        let g = grid.viewer(cell);
                        if let Some(j) = judge(g, IPD, Gaze::AtPoint, p, shown) {
                            assert!(
                                j.vertical_arcmin.abs() < 1e-4
                                    && j.direction_arcmin < 1e-4
                                    && j.horizontal_arcmin.abs() < 1e-4
                                    && (j.depth_ratio - 1.0).abs() < 1e-6,
                                "{} viewer {g} point {p} on {}: {j:?}",
                                m.name(),
                                wall.name
                            );
                            checked += 1;
                        }
                    }
                }
            }
        }
    }
    assert!(checked > 1000, "{checked}");
}

#[test]
fn a_sideways_step_in_front_of_a_flat_wall_shears_the_point_as_the_formula_says() {
    // One wall 2 m ahead of the assumed head, much wider than anything drawn on it.
    let d = 2.0f32;
    let wall = Wall {
        name: "front".into(),
        lower_left: Vec3::new(-20.0, -20.0, -d),
        lower_right: Vec3::new(20.0, -20.0, -d),
        upper_left: Vec3::new(-20.0, 20.0, -d),
        resolution: [1920, 1080],
    };
    let mut cave = thesis_cave();
    cave.walls = vec![wall];
    let head = DVec3::ZERO;
    let s = Setup::new(&cave, Head::at(head.as_vec3()), IPD, None);
    let m = method(RenderMode::Stereo, Assumed::Head);
    // Woods et al.: screen parallax p = e(1 − D/Z) for a point at depth Z; a viewer moved
    // sideways by dx perceives it at X + dx(1 − Z/D), same height, same depth.
    for (x, y, z) in [
        (0.3, 0.2, 1.0),
        (-0.5, -0.1, 3.0),
        (0.0, 0.4, 2.0),
        (1.2, 0.0, 7.5),
    ] {
        let p = DVec3::new(x, y, -z);
        let shown = s.shown_at(m, p).unwrap();
        for dx in [-0.8, -0.1, 0.25, 1.0] {
            let g = DVec3::new(dx, 0.0, 0.0);
            let j = judge(g, IPD, Gaze::Along(DVec3::NEG_Z), p, shown).unwrap();
            let expected = DVec3::new(x + dx * (1.0 - z / f64::from(d)), y, -z);
            let got = j.perceived.unwrap();
            assert!(
                got.distance(expected) < 1e-6,
                "P {p} dx {dx}: P' {got}, formula {expected}"
            );
            assert!(j.vertical_arcmin.abs() < ZERO_ARCMIN, "{j:?}");
        }
    }
}

#[test]
fn omnistereo_is_exact_for_a_viewer_turning_at_the_centre_where_fixed_stereo_is_not() {
    let centre = Vec3::new(0.0, 1.7, 0.0);
    let s = setup(centre, 0.0);
    let g = centre.as_dvec3();
    // The horizontal plane through the eyes, all around (on the three walls).
    let ring: Vec<DVec3> = (0..360)
        .flat_map(|a| {
            let a = f64::from(a).to_radians();
            [0.8, 1.5, 4.0].map(|r| g + r * DVec3::new(a.sin(), 0.0, -a.cos()))
        })
        .collect();
    let worst = |m: Method| {
        let mut worst = 0.0f64;
        let mut judged = 0;
        for &p in &ring {
            let Some(shown) = s.shown_at(m, p) else {
                continue;
            };
            let Some(j) = judge(g, IPD, Gaze::AtPoint, p, shown) else {
                continue;
            };
            worst = worst.max(j.direction_arcmin).max(j.horizontal_arcmin.abs());
            judged += 1;
        }
        assert!(judged > 500, "{}: {judged}", m.name());
        worst
    };
    let omni = worst(method(RenderMode::OmniOnAxis, Assumed::Head));
    let stereo = worst(method(RenderMode::Stereo, Assumed::Head));
    let tracked = worst(method(RenderMode::TrackedStereo, Assumed::Head));
    assert!(omni < ZERO_ARCMIN, "omnistereo {omni} arcmin");
    // Looking 90° to the side, fixed-direction stereo's eyes lie along the line of sight:
    // the rays' horizontal disparity is gone, a whole vergence angle (64 mm at 0.8 m is
    // about 275 arcmin) wrong.
    assert!(stereo > 100.0, "stereo {stereo} arcmin");
    assert!(tracked > 100.0, "tracked stereo {tracked} arcmin");
}

#[test]
fn quantised_wall_points_cost_at_most_one_pixel_of_vertical_disparity() {
    let mut s = setup(Vec3::new(0.0, 1.7, 0.0), 0.0);
    s.quantise = true;
    let m = method(RenderMode::OmniOnAxis, Assumed::Head);
    let g = s.head.position.as_dvec3();
    // The thesis walls' pixels are 2.6 mm wide and 4.0 mm high (2.9 m on 720 rows); 1.65 m
    // away one subtends at most 8.4 arcmin. Half a pixel on each eye gives at most one
    // pixel of vertical disparity.
    let pixel_arcmin = (2.9 / 720.0 / 1.65) * ARCMIN_PER_RADIAN;
    let mut worst = 0.0f64;
    for p in shells(g, &[1.0, 3.0], 400) {
        if let Some(shown) = s.shown_at(m, p)
            && let Some(j) = judge(g, IPD, Gaze::AtPoint, p, shown)
        {
            worst = worst.max(j.vertical_arcmin.abs());
        }
    }
    assert!(
        worst > 0.0 && worst <= pixel_arcmin,
        "{worst} vs {pixel_arcmin}"
    );
}

#[test]
fn the_grid_covers_the_floor_inside_the_walls() {
    let cave = thesis_cave();
    let grid = Grid::over(&cave, 0.1, 1.7).unwrap();
    // 3.3 m less 5 cm on each side: 3.2 m, 33 cells a side, all inside the three walls
    // (the open back is bounded by the walls' box).
    assert_eq!((grid.columns, grid.rows), (33, 33));
    assert_eq!(grid.inside.iter().filter(|i| **i).count(), 33 * 33);
    // The area counts only the cells' parts inside the bounds: 3.2 m × 3.2 m at any step.
    for step in [0.1, 0.2, 0.3, 0.07] {
        let grid = Grid::over(&cave, step, 1.7).unwrap();
        let area = super::grid::MethodMap::floor_area(&grid);
        // 1e-5 m²: the walls are f32 (1.6 m is 1.6000000238).
        assert!((area - 3.2 * 3.2).abs() < 1e-5, "step {step}: {area} m²");
    }
    assert!(Grid::over(&cave, 0.001, 1.7).is_err());
    assert!(Grid::over(&cave, f64::NAN, 1.7).is_err());
}

#[test]
fn percentiles_are_nearest_rank() {
    let mut v: Vec<f64> = (1..=100).map(f64::from).collect();
    assert_eq!(percentile(&mut v, 0.95), 95.0);
    assert_eq!(percentile(&mut v, 0.5), 50.0);
    assert_eq!(percentile(&mut [7.0], 0.95), 7.0);
}

#[test]
fn methods_parse_with_and_without_the_assumed_head() {
    assert_eq!(
        Method::parse("omni-onaxis@centre").unwrap(),
        method(RenderMode::OmniOnAxis, Assumed::Centre)
    );
    assert_eq!(
        Method::parse("stereo").unwrap(),
        method(RenderMode::Stereo, Assumed::Head)
    );
    assert!(
        Method::parse("omni@head")
            .unwrap_err()
            .contains("unknown render mode")
    );
    assert!(Method::parse("stereo@door").unwrap_err().contains("door"));
}
