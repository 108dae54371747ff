//! The panel's live floor map of where guests may stand: computed on a worker thread for the
//! newest head, mode and eye separation, so a frame never waits for it.

use std::sync::Arc;
use std::sync::mpsc::{Receiver, Sender, TryRecvError, channel};
use std::thread::JoinHandle;

use glam::{DVec3, Mat4};

use crate::cave::omni::PoleMerge;
use crate::cave::{Cave, Head, RenderMode};
use crate::guests::grid::{Grid, MethodMap, Thresholds, compute};
use crate::guests::{Assumed, Gaze, Method, Setup, points};
use crate::scene::Scene;

/// What a map is computed for.
#[derive(Debug, Clone, PartialEq)]
pub struct GuestMapRequest {
    pub cave: Cave,
    pub head: Head,
    pub mode: RenderMode,
    pub ipd: f64,
    pub pole_merge: Option<PoleMerge>,
    pub cave_from_world: Mat4,
}

impl GuestMapRequest {
    /// Whether `self` needs a new map where `older` has one: anything but the head changed,
    /// or the head moved more than [`HEAD_STEP_M`] or turned (tracked stereo).
    pub fn differs_from(&self, older: &GuestMapRequest) -> bool {
        self.cave != older.cave
            || self.mode != older.mode
            || self.ipd != older.ipd
            || self.pole_merge != older.pole_merge
            || self.cave_from_world != older.cave_from_world
            || self.head.position.distance(older.head.position) > HEAD_STEP_M
            || (self.mode == RenderMode::TrackedStereo
                && self.head.orientation.angle_between(older.head.orientation) > 0.02)
    }
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

/// The worker thread and its two channels.
pub struct GuestMapWorker {
    requests: Option<Sender<GuestMapRequest>>,
    results: Receiver<GuestMap>,
    thread: Option<JoinHandle<()>>,
    last_sent: Option<GuestMapRequest>,
}

impl std::fmt::Debug for GuestMapWorker {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("GuestMapWorker")
            .field("last_sent", &self.last_sent)
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
                let mut caster: Option<(Mat4, crate::pano::raycast::RayCaster)> = None;
                while let Ok(mut request) = inbox.recv() {
                    // Only the newest request matters.
                    while let Ok(newer) = inbox.try_recv() {
                        request = newer;
                    }
                    let map = compute_map(&scene, &mut caster, request);
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
            requests: thread.as_ref().map(|_| requests),
            results,
            thread,
            last_sent: None,
        }
    }

    /// Asks for a map for `request` unless the last one asked for is still close enough.
    /// Never blocks.
    pub fn request(&mut self, request: GuestMapRequest) {
        if self
            .last_sent
            .as_ref()
            .is_some_and(|last| !request.differs_from(last))
        {
            return;
        }
        if let Some(sender) = &self.requests
            && sender.send(request.clone()).is_ok()
        {
            self.last_sent = Some(request);
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

impl Drop for GuestMapWorker {
    fn drop(&mut self) {
        // Closing the request channel ends the worker's loop after its current map.
        self.requests = None;
        if let Some(thread) = self.thread.take() {
            let _ = thread.join();
        }
    }
}

/// One map: the scene's points visible from the head (the ray caster kept while the scene's
/// placement stays), judged over the floor for the request's mode.
fn compute_map(
    scene: &Scene,
    caster: &mut Option<(Mat4, crate::pano::raycast::RayCaster)>,
    request: GuestMapRequest,
) -> GuestMap {
    let started = std::time::Instant::now();
    if caster
        .as_ref()
        .is_none_or(|(m, _)| *m != request.cave_from_world)
    {
        *caster = Some((
            request.cave_from_world,
            crate::pano::raycast::RayCaster::new(scene, request.cave_from_world),
        ));
    }
    let head = request.head.position.as_dvec3();
    let points = caster.as_ref().map_or_else(Vec::new, |(_, c)| {
        points::visible_from(c, head, LIVE_POINTS, f64::from(request.cave.far))
    });
    let setup = Setup::new(&request.cave, request.head, request.ipd, request.pole_merge);
    let method = Method {
        mode: request.mode,
        assumed: Assumed::Head,
    };
    let limits = Thresholds::default();
    let grid = Grid::over(&request.cave, LIVE_STEP_M, head.y).unwrap_or(Grid {
        first: [0.0; 2],
        step: LIVE_STEP_M,
        columns: 0,
        rows: 0,
        eye_height: head.y,
        inside: Vec::new(),
    });
    // One thread: the render thread keeps the other core.
    let map = compute(&setup, &[method], &points, &grid, Gaze::AtPoint, &limits, 1)
        .pop()
        .unwrap_or(MethodMap {
            method,
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

    fn request(head: glam::Vec3, mode: RenderMode) -> GuestMapRequest {
        GuestMapRequest {
            cave: thesis_cave(),
            head: Head::at(head),
            mode,
            ipd: 0.064,
            pole_merge: None,
            cave_from_world: Mat4::IDENTITY,
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
        worker.request(request(head, RenderMode::OmniOnAxis));
        // 5 mm: below the step, not asked again.
        worker.request(request(
            head + glam::Vec3::X * 0.005,
            RenderMode::OmniOnAxis,
        ));
        let started = std::time::Instant::now();
        let map = loop {
            if let Some(map) = worker.newest() {
                break map;
            }
            assert!(started.elapsed().as_secs() < 60, "no map within a minute");
            std::thread::sleep(std::time::Duration::from_millis(10));
        };
        assert_eq!(map.request.head.position, head);
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
        assert!(worker.newest().is_none(), "the 5 mm move was mapped again");
    }
}
