//! The panel's live floor map of where guests may stand: computed on a worker thread for the
//! newest head, mode and eye separation, so a frame never waits for it.

use std::sync::Arc;
use std::sync::mpsc::{Receiver, Sender, TryRecvError, channel};

use glam::{DVec3, Mat4};

use crate::cave::omni::PoleMerge;
use crate::cave::{Cave, Head, RenderMode};
use crate::guests::grid::{Grid, MethodMap, Thresholds, compute};
use crate::guests::{Assumed, Gaze, Method, Setup, points};
use crate::scene::Scene;

/// What a map is computed for, besides the walls: the head, the mode and the eyes.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GuestMapPose {
    pub head: Head,
    pub mode: RenderMode,
    pub ipd: f64,
    pub pole_merge: Option<PoleMerge>,
    /// Where the CAVE stands in the scene (navigation and `[scene.world_from_cave]`).
    pub world_from_cave: Mat4,
}

/// What a map is computed for.
#[derive(Debug, Clone, PartialEq)]
pub struct GuestMapRequest {
    pub cave: Cave,
    pub pose: GuestMapPose,
}

impl GuestMapPose {
    /// Whether `self` needs a new map where `older` has one: anything but the head changed,
    /// or the head moved more than [`HEAD_STEP_M`] or turned (tracked stereo).
    pub fn differs_from(&self, older: &GuestMapPose) -> bool {
        self.mode != older.mode
            || self.ipd != older.ipd
            || self.pole_merge != older.pole_merge
            || placement_moved(self.world_from_cave, older.world_from_cave)
            || self.head.position.distance(older.head.position) > HEAD_STEP_M
            || (self.mode == RenderMode::TrackedStereo
                && self.head.orientation.angle_between(older.head.orientation) > 0.02)
    }
}

/// Whether navigation moved the CAVE in the scene enough for a new map: more than
/// [`HEAD_STEP_M`] (in CAVE metres, whatever the scene's scale), a turn of more than 0.02 rad,
/// or a change of scale of more than 0.1 %.
fn placement_moved(a: Mat4, b: Mat4) -> bool {
    let (sa, qa, ta) = a.to_scale_rotation_translation();
    let (sb, qb, tb) = b.to_scale_rotation_translation();
    let scale = sa.x.abs().max(1e-6);
    (sa - sb).abs().max_element() > 1e-3 * scale
        || qa.angle_between(qb) > 0.02
        || ta.distance(tb) / scale > HEAD_STEP_M
}

/// How far the head moves before the map is recomputed, metres (a tenth of a grid cell).
pub const HEAD_STEP_M: f32 = 0.01;
/// Scene points the live map judges (fewer than `omnicave guests`' 10 000: it follows the head).
pub const LIVE_POINTS: usize = 3000;
/// The live map's cell size, metres.
pub const LIVE_STEP_M: f64 = 0.1;

/// A finished map.
#[derive(Debug, Clone, PartialEq)]
pub struct GuestMap {
    pub request: GuestMapRequest,
    pub grid: Grid,
    pub map: MethodMap,
    /// The assumed head on the floor plan.
    pub head: DVec3,
    pub limits: Thresholds,
    /// Seconds the worker took.
    pub seconds: f64,
}

/// The worker thread's two channels (the thread ends by itself once its request channel
/// closes; nobody waits for it).
pub struct GuestMapWorker {
    /// `None` once the worker is gone: nothing more is asked or copied.
    requests: Option<Sender<GuestMapRequest>>,
    results: Receiver<GuestMap>,
    last_sent: Option<GuestMapRequest>,
    sent: u64,
}

impl std::fmt::Debug for GuestMapWorker {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("GuestMapWorker")
            .field("last_sent", &self.last_sent)
            .field("sent", &self.sent)
            .finish_non_exhaustive()
    }
}

impl GuestMapWorker {
    /// Starts the worker for `scene` (shared, not copied).
    pub fn start(scene: Arc<Scene>) -> Self {
        let (requests, inbox) = channel::<GuestMapRequest>();
        let (outbox, results) = channel();
        let thread = std::thread::Builder::new()
            .name("guest map".into())
            .spawn(move || {
                // The scene in its own (world) space, built once: navigation moves the eye
                // and the rays instead.
                let caster = crate::pano::raycast::RayCaster::new(&scene, Mat4::IDENTITY);
                while let Ok(mut request) = inbox.recv() {
                    // Only the newest request matters.
                    while let Ok(newer) = inbox.try_recv() {
                        request = newer;
                    }
                    let map = compute_map(&caster, request);
                    if outbox.send(map).is_err() {
                        break;
                    }
                }
            })
            .ok();
        if thread.is_none() {
            tracing::warn!("cannot start the guest map's thread; the panel shows no map");
        }
        Self {
            requests: thread.map(|_| requests),
            results,
            last_sent: None,
            sent: 0,
        }
    }

    /// Requests sent to the worker so far.
    pub fn requests_sent(&self) -> u64 {
        self.sent
    }

    /// Asks for a map for `cave` and `pose` unless the last one asked for is still close
    /// enough. Never blocks, and copies the walls only when it asks (not every frame).
    pub fn request(&mut self, cave: &Cave, pose: GuestMapPose) {
        let Some(sender) = &self.requests else {
            return;
        };
        if self
            .last_sent
            .as_ref()
            .is_some_and(|last| last.cave == *cave && !pose.differs_from(&last.pose))
        {
            return;
        }
        let request = GuestMapRequest {
            cave: cave.clone(),
            pose,
        };
        if sender.send(request.clone()).is_ok() {
            self.last_sent = Some(request);
            self.sent += 1;
        } else {
            tracing::warn!("the guest map's thread has stopped; the panel shows no new map");
            self.requests = None;
        }
    }

    /// The newest finished map, if one arrived since the last call. Never blocks.
    pub fn newest(&mut self) -> Option<GuestMap> {
        let mut newest = None;
        loop {
            match self.results.try_recv() {
                Ok(map) => newest = Some(map),
                Err(TryRecvError::Empty | TryRecvError::Disconnected) => return newest,
            }
        }
    }
}

/// One map: the scene's points visible from the head, cast in the scene's space through the
/// request's placement, judged over the floor for the request's mode.
fn compute_map(caster: &crate::pano::raycast::RayCaster, request: GuestMapRequest) -> GuestMap {
    let started = std::time::Instant::now();
    let pose = request.pose;
    let head = pose.head.position.as_dvec3();
    let world_from_cave = pose.world_from_cave.as_dmat4();
    let cave_from_world = world_from_cave.inverse();
    let far = f64::from(request.cave.far);
    let points: Vec<DVec3> = points::visible_from(
        caster,
        world_from_cave.transform_point3(head),
        LIVE_POINTS,
        far * world_from_cave.transform_vector3(DVec3::X).length(),
        world_from_cave,
    )
    .into_iter()
    .map(|p| cave_from_world.transform_point3(p))
    .collect();
    let setup = Setup::new(&request.cave, pose.head, pose.ipd, pose.pole_merge);
    let method = Method {
        mode: pose.mode,
        assumed: Assumed::Head,
    };
    let limits = Thresholds::default();
    // A CAVE with no floor to stand on (one flat wall) has no map.
    let (grid, maps) = match Grid::over(&request.cave, LIVE_STEP_M, head.y) {
        // One thread: the render thread keeps the other core.
        Ok(grid) => {
            let maps = compute(&setup, &[method], &points, &grid, Gaze::AtPoint, &limits, 1);
            (grid, maps)
        }
        Err(_) => (Grid::empty(LIVE_STEP_M, head.y), Vec::new()),
    };
    let map = maps.into_iter().next().unwrap_or(MethodMap {
        method,
        computed_as: method,
        cells: Vec::new(),
        shown_points: 0,
        reach_m: Vec::new(),
        reach_area_m2: 0.0,
        fusion_reach_area_m2: 0.0,
    });
    GuestMap {
        request,
        grid,
        map,
        head,
        limits,
        seconds: started.elapsed().as_secs_f64(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cave::thesis_cave;

    fn pose(head: glam::Vec3, mode: RenderMode) -> GuestMapPose {
        GuestMapPose {
            head: Head::at(head),
            mode,
            ipd: 0.064,
            pole_merge: None,
            world_from_cave: Mat4::IDENTITY,
        }
    }

    #[test]
    fn the_worker_maps_the_newest_request_and_skips_small_head_moves() {
        // A box room 6 m wide around the CAVE: every direction from the head meets it.
        let mut scene = Scene::default();
        let room = crate::scene::build::cuboid(glam::Vec3::new(6.0, 4.0, 6.0), 1.0)
            .transformed(Mat4::from_translation(glam::Vec3::new(0.0, 2.0, 0.0)));
        let mut material = crate::scene::Material::unlit("room", [0.5; 3]);
        // Seen from inside.
        material.double_sided = true;
        let m = scene.add_material(material);
        scene.add_mesh(&room.vertices, &room.indices, m);
        let mut worker = GuestMapWorker::start(Arc::new(scene));
        let head = glam::Vec3::new(0.0, 1.7, 0.0);
        let cave = thesis_cave();
        worker.request(&cave, pose(head, RenderMode::OmniOnAxis));
        // 5 mm: below the step, not asked again; another mode is.
        worker.request(
            &cave,
            pose(head + glam::Vec3::X * 0.005, RenderMode::OmniOnAxis),
        );
        assert_eq!(worker.requests_sent(), 1, "a 5 mm move was asked again");
        let started = std::time::Instant::now();
        let map = loop {
            if let Some(map) = worker.newest() {
                break map;
            }
            assert!(started.elapsed().as_secs() < 60, "no map within a minute");
            std::thread::sleep(std::time::Duration::from_millis(10));
        };
        assert_eq!(map.request.pose.head.position, head);
        assert_eq!(map.map.method.mode, RenderMode::OmniOnAxis);
        assert!(map.map.shown_points > 1000, "{}", map.map.shown_points);
        // The cell at the head sees omnistereo exactly.
        let cell = map
            .map
            .cells
            .iter()
            .enumerate()
            .find(|(c, _)| map.grid.viewer(*c).distance(map.head) < 1e-9)
            .and_then(|(_, f)| *f)
            .expect("a cell at the head");
        assert!(
            cell.vertical_p95 < 1e-3 && cell.direction_p95 < 1e-3,
            "{cell:?}"
        );
        worker.request(&cave, pose(head, RenderMode::Stereo));
        assert_eq!(worker.requests_sent(), 2, "another mode was not asked");
        // A scene in centimetres (scale 100): a turn of 0.1 rad in place is a new map, 5 mm of
        // navigation is not, 2 cm is.
        let scaled = |yaw: f32, x: f32| GuestMapPose {
            world_from_cave: Mat4::from_scale_rotation_translation(
                glam::Vec3::splat(100.0),
                glam::Quat::from_rotation_y(yaw),
                glam::Vec3::new(100.0 * x, 0.0, 0.0),
            ),
            ..pose(head, RenderMode::Stereo)
        };
        worker.request(&cave, scaled(0.0, 0.0));
        assert_eq!(worker.requests_sent(), 3);
        worker.request(&cave, scaled(0.1, 0.0));
        assert_eq!(worker.requests_sent(), 4, "a turn in place was not asked");
        worker.request(&cave, scaled(0.1, 0.005));
        assert_eq!(worker.requests_sent(), 4, "5 mm of navigation was asked");
        worker.request(&cave, scaled(0.1, 0.02));
        assert_eq!(
            worker.requests_sent(),
            5,
            "2 cm of navigation was not asked"
        );
    }
}
