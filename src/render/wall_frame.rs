//! One frame of the walls, as its stages in order: the views, lights and shadows, culling,
//! refinement, then per view the scene, the sky and the resolve, and last the read-backs.

use super::frame_timer::{self, ViewStage};
use super::scene_gpu::SceneGpu;
use super::sky_pass::SkyFrame;
use super::tessellator::{self, TessUniforms};
use super::uniforms::{self, FrameLights, FrameUniforms, ViewUniforms};
use super::{
    FrameParams, FrameStats, RenderError, Renderer, readback, srgb_to_linear_color, targets,
};
use crate::cave::omni::OmniSettings;
use crate::cave::{ViewSetup, eye_positions, view_setups};
use crate::sky::SkyMode;
use crate::tess::EyeShare;
use crate::tess::clusters::{ClusterTest, Verdict};

/// What the culling stage decided for the whole frame.
#[derive(Debug, Clone, Copy)]
struct FramePlan {
    /// The tessellator refines this frame (a criterion is set, a scene and a tessellator).
    tessellate: bool,
    /// Clusters are classified per view: the provably fine drawn directly, the rest refined
    /// (or, untessellated, the invisible dropped).
    direct: bool,
}

/// How every view's scene pass draws this frame.
#[derive(Debug, Clone, Copy)]
struct PassStyle {
    /// The clear colour in linear light (sRGB attachments).
    clear: wgpu::Color,
    /// The clear colour as bytes the shaders encode (already sRGB).
    encoded_clear: wgpu::Color,
    /// Whether the views draw shader-encoded samples (see `render::resolve`).
    encoded: bool,
    wireframe: bool,
    /// Split rounds of the tessellator per view.
    rounds: u32,
}

impl Renderer {
    /// [`Renderer::render`]'s frame.
    pub(super) fn render_walls(
        &mut self,
        frame: &FrameParams<'_>,
    ) -> Result<FrameStats, RenderError> {
        self.sync_walls(frame.cave);
        let views = self.frame_views(frame);
        let mut encoder = self.begin_frame(views.len());
        self.pose_scene(&mut encoder, frame);
        let frame_uniforms = self.prepare_frame(
            &mut encoder,
            frame,
            frame.mode.is_omni().then_some(frame.omni),
        );
        if let Some(timer) = &self.timer {
            encoder.write_timestamp(&timer.queries, frame_timer::SHADOWS_END);
        }
        self.walls.write_uniforms(
            &self.queue,
            &frame_uniforms,
            views.iter().map(ViewUniforms::from),
        );
        let plan = self.cull(frame, &views);
        self.prepare_refinement(frame, &views, plan)?;
        self.prepare_sky(frame, &views);
        self.prepare_wand(frame);
        let style = self.pass_style(frame);
        self.drew_encoded = style.encoded;
        self.walls
            .set_tessellated_views(if plan.tessellate { views.len() } else { 0 });
        let mut drew = false;
        for (index, view) in views.iter().enumerate() {
            drew = self.encode_view(&mut encoder, frame, plan, style, index, view, drew);
        }
        let stats = self.frame_stats(&views, plan, style.rounds);
        self.queue_readbacks(&mut encoder, views.len(), plan.tessellate);
        self.queue.submit([encoder.finish()]);
        self.readback.finish();
        self.last_views = views;
        Ok(stats)
    }

    /// The frame's views: every wall's eyes for the mode, less the walls filtered out.
    fn frame_views(&self, frame: &FrameParams<'_>) -> Vec<ViewSetup> {
        let mut views = view_setups(frame.cave, &frame.head, frame.mode, frame.eye_separation);
        if let Some(walls) = &self.wall_filter {
            views.retain(|v| walls.get(v.wall).copied().unwrap_or(false));
        }
        views
    }

    /// The frame's command encoder, with the timer's first timestamp.
    fn begin_frame(&mut self, views: usize) -> wgpu::CommandEncoder {
        let mut encoder = self
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                label: Some("Renderer::frame"),
            });
        if let Some(timer) = &mut self.timer {
            timer.ensure_views(&self.device, &self.queue, views);
            encoder.write_timestamp(&timer.queries, 0);
        }
        encoder
    }

    /// The frame's uniforms (the config's and the scene's lights, the shading model, the
    /// shadow maps' layers), with the scene's blended draws sorted back to front from the
    /// head; records the shadow maps into `encoder` when they changed.
    pub(super) fn prepare_frame(
        &mut self,
        encoder: &mut wgpu::CommandEncoder,
        frame: &FrameParams<'_>,
        omni: Option<OmniSettings>,
    ) -> FrameUniforms {
        let head = frame.world_from_cave.transform_point3(frame.head.position);
        if let Some(scene) = &mut self.scene {
            scene.sort_blended(head);
        }
        let scene_lights = self.scene.as_ref().map_or(&[][..], |s| s.lights.as_slice());
        let lights = FrameLights {
            config: &frame.lighting,
            scene: scene_lights,
            shading: frame.shading,
        };
        let centre = frame.world_from_cave.transform_point3(glam::Vec3::ZERO);
        let bounds = self.scene.as_ref().and_then(|s| s.bounds);
        let plan =
            crate::scene::shadows::plan_shadows(&lights.all(), bounds, centre, &frame.shadows);
        self.scene_pass.shadows.prepare(
            &self.device,
            &self.queue,
            &plan,
            frame.shadows.map_size,
            frame.shadows.range_test(),
        );
        if let Some(scene) = &self.scene {
            self.scene_pass.shadows.encode(encoder, scene);
        }
        let shadows = uniforms::FrameShadows {
            settings: &frame.shadows,
            plan: &plan,
        };
        let sky = self
            .sky_irradiance
            .as_ref()
            .filter(|_| frame.sky.mode != SkyMode::Off)
            .map(|irradiance| uniforms::SkyLight {
                irradiance,
                strength: frame.sky.light * frame.sky.exposure,
            });
        FrameUniforms::new(frame.world_from_cave, lights, Some(shadows), sky, omni)
    }

    /// Culling: each view's clusters, the provably invisible dropped, the rest drawn whole
    /// or, when tessellating, refined if they may need it (see `tess::clusters`). A split
    /// scene has no clusters (and is not tessellated): drawn whole, every draw in every view.
    /// Both eyes of a wall share one refinement (`tess.shared_eyes`): a cluster either eye
    /// refines is refined for both.
    fn cull(&mut self, frame: &FrameParams<'_>, views: &[ViewSetup]) -> FramePlan {
        let tessellate =
            frame.tess.criterion.is_some() && self.scene.is_some() && self.tessellator.is_some();
        let direct = self.scene.as_ref().is_some_and(|s| !s.clusters.is_empty())
            && (!tessellate || frame.tess.skip_fine);
        crate::tess::eye_shares(
            views,
            tessellate && frame.tess.shared_eyes,
            &mut self.eye_shares,
        );
        if let (true, Some(scene)) = (direct, &self.scene) {
            let omni = frame.mode.is_omni().then_some(frame.omni);
            let unproven = if tessellate {
                Verdict::Needy
            } else {
                Verdict::Fine
            };
            self.cluster_tests.clear();
            self.cluster_tests.extend(views.iter().map(|v| {
                let wall = &frame.cave.walls[v.wall];
                let tv = crate::tess::tess_view(v, wall, frame.world_from_cave, omni);
                ClusterTest::for_settings(&tv, &frame.tess, tessellate)
            }));
            self.cluster_splits
                .resize_with(views.len(), Default::default);
            let tests = &self.cluster_tests;
            for (i, split) in self.cluster_splits.iter_mut().enumerate().take(views.len()) {
                let own = tests.get(i).copied().flatten();
                let other = match self.eye_shares.get(i) {
                    Some(EyeShare::Leads { partner }) => Some(*partner),
                    Some(EyeShare::Follows { leader }) => Some(*leader),
                    _ => None,
                };
                match other {
                    Some(o) => {
                        let other = tests.get(o).copied().flatten();
                        split.classify(&scene.clusters, &[own.as_ref(), other.as_ref()], unproven);
                    }
                    None => split.classify(&scene.clusters, &[own.as_ref()], unproven),
                }
            }
        }
        FramePlan { tessellate, direct }
    }

    /// Whether view `index` draws the refinement of the view before it.
    fn follows(&self, index: usize) -> bool {
        matches!(self.eye_shares.get(index), Some(EyeShare::Follows { .. }))
    }

    /// Refinement's inputs: the tessellator's buffers, each view's clusters to refine and
    /// its uniforms.
    fn prepare_refinement(
        &mut self,
        frame: &FrameParams<'_>,
        views: &[ViewSetup],
        plan: FramePlan,
    ) -> Result<(), RenderError> {
        let (true, Some(scene), Some(tessellator)) =
            (plan.tessellate, &self.scene, &self.tessellator)
        else {
            return Ok(());
        };
        let limits = self.tess_limits();
        let buffers = self
            .walls
            .tessellation(&self.device, tessellator, scene, limits)?;
        // A view that draws its partner's refinement uploads no clusters of its own (the
        // same list as its leader's).
        let shares = &self.eye_shares;
        let follows = |i: usize| matches!(shares.get(i), Some(EyeShare::Follows { .. }));
        buffers.write_needy(
            &self.queue,
            self.cluster_splits[..if plan.direct { views.len() } else { 0 }]
                .iter()
                .enumerate()
                .map(|(i, s)| {
                    if follows(i) {
                        &[][..]
                    } else {
                        s.needy.as_slice()
                    }
                }),
            &mut self.needy_ranges,
        );
        let ranges = &self.needy_ranges;
        let omni = frame.mode.is_omni();
        buffers.write_uniforms(
            &self.queue,
            views.iter().enumerate().map(|(i, v)| {
                let (offset, count, triangles) = ranges.get(i).copied().unwrap_or((0, 0, 0));
                let wall = &frame.cave.walls[v.wall];
                let own = TessUniforms {
                    cluster_mode: u32::from(plan.direct),
                    needy_offset: offset,
                    needy_count: count,
                    root_bound: triangles,
                    ..TessUniforms::new(v, wall, &frame.tess, omni)
                };
                match shares.get(i) {
                    Some(EyeShare::Leads { partner }) => match views.get(*partner) {
                        Some(other) => own.with_partner(v, other, wall, omni),
                        None => own,
                    },
                    _ => own,
                }
            }),
        );
        Ok(())
    }

    /// The sky's per-view uniforms for the frame's mode.
    fn prepare_sky(&mut self, frame: &FrameParams<'_>, views: &[ViewSetup]) {
        let sky_frame = SkyFrame {
            world_from_cave: frame.world_from_cave,
            head: frame.head.position,
            eye_separation: frame.eye_separation,
            // The omnistereo modes' fixed-direction eyes are their stereo eyes.
            offaxis_eyes: eye_positions(
                frame.mode,
                &frame.head,
                frame.eye_separation,
                frame.cave.stereo_view_direction,
            ),
            pole_merge: frame.omni.pole_merge,
            exposure: frame.sky.exposure,
        };
        self.sky_pass.prepare(
            &self.device,
            &self.queue,
            frame.cave,
            views,
            &frame.sky,
            frame.sky.mode.resolve(frame.mode),
            &sky_frame,
        );
    }

    /// The wand ray's positions, rewritten in place (nothing allocated).
    fn prepare_wand(&mut self, frame: &FrameParams<'_>) {
        let Some(ray) = &frame.wand_ray else {
            return;
        };
        crate::scene::wand_mesh::positions(ray, frame.world_from_cave, &mut self.wand_positions);
        for (v, p) in self.wand_vertices.iter_mut().zip(&self.wand_positions) {
            v.position = p.to_array();
        }
        self.wand.write_vertices(&self.queue, &self.wand_vertices);
    }

    /// How the views' scene passes draw: with MSAA, the shaders encode each fragment's
    /// colour once and `resolve_pass` averages the samples in linear light, instead of the
    /// rasteriser encoding every sample (see `resolve`); blending needs linear colour in the
    /// target.
    fn pass_style(&self, frame: &FrameParams<'_>) -> PassStyle {
        let clear = srgb_to_linear_color(frame.background);
        let encoded = self.encoded_samples
            && self.settings.msaa > 1
            && !self.scene.as_ref().is_some_and(SceneGpu::has_blended_draws)
            && !(frame.wand_ray.is_some() && self.wand.has_blended_draws());
        PassStyle {
            clear,
            encoded_clear: wgpu::Color {
                r: f64::from(frame.background[0]),
                g: f64::from(frame.background[1]),
                b: f64::from(frame.background[2]),
                a: clear.a,
            },
            encoded,
            wireframe: self.settings.wireframe && self.wireframe_supported,
            rounds: tessellator::rounds(&frame.tess),
        }
    }

    /// One view: its refinement (or its wall's other eye's, `leader_drew` saying whether that
    /// has output), then its scene pass (scene, wand, sky) and its resolve; whether the
    /// tessellator drew anything for it.
    #[allow(clippy::too_many_arguments)]
    fn encode_view(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        frame: &FrameParams<'_>,
        plan: FramePlan,
        style: PassStyle,
        index: usize,
        view: &ViewSetup,
        leader_drew: bool,
    ) -> bool {
        let timer = self.timer.as_ref();
        let drew = self.encode_refinement(encoder, plan, style.rounds, index, leader_drew);
        let target = &self.targets[view.wall].eyes[view.eye.map_or(0, |e| e as usize)];
        let samples = target
            .encoded_samples
            .as_ref()
            .and_then(|(view, group)| Some((view, group.as_ref()?)))
            .filter(|_| style.encoded);
        let encoded = samples.is_some();
        let mut pass = match samples {
            Some((view, _)) => targets::begin_scene_pass(
                encoder,
                "Renderer::scene_pass",
                view,
                None,
                &target.depth_view,
                style.encoded_clear,
            ),
            None => targets::begin_scene_pass(
                encoder,
                "Renderer::scene_pass",
                &target.color_view,
                target.msaa_view.as_ref(),
                &target.depth_view,
                style.clear,
            ),
        };
        self.draw_scene(
            &mut pass,
            frame,
            plan,
            drew,
            index,
            style.wireframe,
            encoded,
        );
        let in_pass = timer.is_some_and(|t| t.mark_in_pass(&mut pass, index, ViewStage::Scene));
        self.sky_pass.draw(&mut pass, index, view.wall, encoded);
        if in_pass && let Some(t) = timer {
            t.mark_in_pass(&mut pass, index, ViewStage::Sky);
        }
        drop(pass);
        if let Some(t) = timer
            && !in_pass
        {
            t.mark(encoder, index, ViewStage::Scene);
            t.mark(encoder, index, ViewStage::Sky);
        }
        // The resolve stage: the pass's end, and the encoded samples' resolve pass.
        if let Some((_, group)) = samples {
            self.resolve_pass
                .encode(encoder, group, &target.encoded_view);
        }
        if let Some(t) = timer {
            t.mark(encoder, index, ViewStage::Resolve);
        }
        drew
    }

    /// Records view `index`'s refinement, alone or for both eyes of its wall, or nothing but
    /// its statistics where it draws its wall's other eye's (`leader_drew`); whether the
    /// tessellator drew anything for it.
    fn encode_refinement(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        plan: FramePlan,
        rounds: u32,
        index: usize,
        leader_drew: bool,
    ) -> bool {
        let timer = self.timer.as_ref();
        match (self.walls.tessellated(), &self.tessellator) {
            (Some(buffers), Some(_)) if self.follows(index) => {
                buffers.encode_follower(
                    encoder,
                    index,
                    leader_drew,
                    timer.map(|t| t.tess_marks(index)),
                );
                leader_drew
            }
            (Some(buffers), Some(tessellator)) => {
                let needy = plan
                    .direct
                    .then(|| self.needy_ranges.get(index).map_or(0, |r| r.1));
                let partner = match self.eye_shares.get(index) {
                    Some(EyeShare::Leads { partner }) => Some(*partner),
                    _ => None,
                };
                buffers.encode(
                    tessellator,
                    encoder,
                    index,
                    partner,
                    rounds,
                    needy,
                    timer.map(|t| t.tess_marks(index)),
                )
            }
            _ => {
                if let Some(t) = timer {
                    for stage in [
                        ViewStage::TessCull,
                        ViewStage::TessSplit,
                        ViewStage::TessSort,
                    ] {
                        t.mark(encoder, index, stage);
                    }
                }
                false
            }
        }
    }

    /// Draws the scene and the wand into view `index`'s pass: refined output where the
    /// tessellator `drew`, the fine clusters directly, or every draw.
    #[allow(clippy::too_many_arguments)]
    fn draw_scene(
        &self,
        pass: &mut wgpu::RenderPass<'_>,
        frame: &FrameParams<'_>,
        plan: FramePlan,
        drew: bool,
        index: usize,
        wireframe: bool,
        encoded: bool,
    ) {
        let split = self.cluster_splits.get(index).filter(|_| plan.direct);
        let fine = split.map_or(&[][..], |s| s.fine.as_slice());
        let views = self.walls.bind_group();
        match (&self.scene, self.walls.tessellated()) {
            (Some(scene), Some(buffers)) => self.scene_pass.draw_split(
                pass,
                scene,
                views,
                drew.then_some(buffers),
                split.map(|s| s.needy_draws.as_slice()),
                fine,
                index,
                wireframe,
                encoded,
            ),
            (Some(scene), None) if plan.direct => self.scene_pass.draw_split(
                pass, scene, views, None, None, fine, index, wireframe, encoded,
            ),
            (Some(scene), None) => {
                self.scene_pass
                    .draw(pass, scene, views, index, wireframe, encoded);
            }
            (None, _) => {}
        }
        if frame.wand_ray.is_some() {
            // Never tessellated: its segments are short enough for the per-vertex warp.
            self.scene_pass
                .draw(pass, &self.wand, views, index, false, encoded);
        }
    }

    /// The frame's counts: views, triangles submitted, dispatches, and what was drawn
    /// directly and refined.
    fn frame_stats(&mut self, views: &[ViewSetup], plan: FramePlan, rounds: u32) -> FrameStats {
        let n = views.len();
        // A view drawing its wall's other eye's refinement dispatches nothing.
        let refining = (0..n).filter(|&i| !self.follows(i)).count();
        let tessellated_views = match (plan.tessellate, plan.direct) {
            (false, _) => 0,
            (true, true) => self.needy_ranges.iter().filter(|r| r.1 > 0).count(),
            (true, false) => refining,
        };
        self.last_dispatches = tessellated_views * tessellator::dispatches_per_view(rounds);
        let triangles = self.scene.as_ref().map_or(0, |s| s.triangle_count);
        let splits = &self.cluster_splits[..if plan.direct { n } else { 0 }];
        let refined_input: usize = match (plan.tessellate, plan.direct) {
            (false, _) => 0,
            (true, true) => splits
                .iter()
                .enumerate()
                .filter(|(i, _)| !self.follows(*i))
                .flat_map(|(_, s)| &s.needy)
                .map(|r| r[1] as usize)
                .sum(),
            (true, false) => triangles * refining,
        };
        let fine_triangles: usize = if plan.tessellate && plan.direct {
            splits.iter().map(|s| s.fine_triangles() as usize).sum()
        } else {
            0
        };
        FrameStats {
            views: n,
            triangles_submitted: triangles * n,
            dispatches: self.last_dispatches,
            fine_triangles,
            refined_input,
        }
    }

    /// Resolves the frame's timestamps and copies them and the tessellation counts into the
    /// read-back ring (read later without waiting).
    fn queue_readbacks(
        &mut self,
        encoder: &mut wgpu::CommandEncoder,
        views: usize,
        tessellate: bool,
    ) {
        let stamps = frame_timer::timestamp_count(views);
        if let Some(timer) = &self.timer {
            encoder.resolve_query_set(&timer.queries, 0..stamps, &timer.resolve, 0);
            self.timed_stamps = stamps;
            self.timed_views = views;
        }
        self.frame_number += 1;
        let layout = readback::SlotLayout {
            timestamps: if self.timer.is_some() { stamps } else { 0 },
            tess_views: if tessellate { views } else { 0 },
        };
        let needed = layout.stats_offset() + tessellator::STATS_BYTES * layout.tess_views as u64;
        if needed > self.readback.slot_size() {
            // More walls than the ring was made for (not per frame).
            self.readback = readback::ReadbackRing::new(&self.device, needed);
        }
        let wanted = layout.timestamps > 0 || layout.tess_views > 0;
        let Some(slot) = wanted
            .then(|| self.readback.begin(self.frame_number, layout))
            .flatten()
        else {
            return;
        };
        if let Some(timer) = &self.timer {
            encoder.copy_buffer_to_buffer(&timer.resolve, 0, slot, 0, layout.stats_offset());
        }
        if let Some(stats) = self
            .walls
            .tessellated()
            .and_then(|t| t.stats_buffer(layout.tess_views))
        {
            encoder.copy_buffer_to_buffer(
                stats,
                0,
                slot,
                layout.stats_offset(),
                needed - layout.stats_offset(),
            );
        }
    }
}
