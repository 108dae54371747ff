//! One frame of the panorama view, as its stages: the targets, the look-up's uniforms, then
//! either route (the six cube faces and the look-up, or each eye's tessellated projection).

use super::tessellator::{self, TessUniforms};
use super::uniforms::ViewUniforms;
use super::{FrameParams, RenderError, Renderer, panorama, sky_pass, srgb_to_linear_color};
use crate::cave::Eye;
use crate::pano::{PanoRoute, PanoSettings};
use crate::sky::SkyMode;

impl Renderer {
    /// [`Renderer::render_panorama`]'s frame.
    pub(super) fn render_panorama_frame(
        &mut self,
        frame: &FrameParams<'_>,
        pano: &PanoSettings,
    ) -> Result<(), RenderError> {
        let route = self.check_panorama(pano)?;
        self.pano
            .ensure_targets(&self.device, pano.size, self.settings.msaa);
        let mut encoder = self
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                label: Some("Renderer::panorama"),
            });
        if let Some(timer) = &self.timer {
            encoder.write_timestamp(&timer.queries, 0);
        }
        if let (Some(pose), Some(scene)) = (&mut self.scene_pose, &mut self.scene)
            && pose.update(
                &self.queue,
                &mut encoder,
                &self.pose_pipeline,
                &frame.animation,
                scene,
            )
        {
            self.scene_pass.shadows.invalidate();
        }
        let face_size = pano
            .cube_size
            .clamp(4, self.device.limits().max_texture_dimension_2d);
        self.write_panorama_lookup(frame, pano, face_size);
        match route {
            PanoRoute::Image => self.encode_panorama_faces(&mut encoder, frame, face_size),
            PanoRoute::Geometric => self.encode_panorama_eyes(&mut encoder, frame, pano)?,
        }
        if let Some(timer) = &self.timer {
            encoder.write_timestamp(&timer.queries, 1);
            encoder.resolve_query_set(&timer.queries, 0..2, &timer.resolve, 0);
            self.timed_stamps = 2;
        }
        self.queue.submit([encoder.finish()]);
        Ok(())
    }

    /// The route the panorama takes, or why it cannot be drawn here.
    fn check_panorama(&self, pano: &PanoSettings) -> Result<PanoRoute, RenderError> {
        let [w, h] = pano.size;
        let max = self.device.limits().max_texture_dimension_2d;
        if w == 0 || h == 0 || w > max || h > max {
            return Err(RenderError::PanoramaSize(w, h));
        }
        let route = pano.effective_route();
        if route == PanoRoute::Geometric && self.tessellator.is_none() {
            return Err(RenderError::PanoramaNeedsTessellator);
        }
        Ok(route)
    }

    /// The uniforms of the panorama's look-up (the image route's projection, and the sky
    /// behind either route).
    fn write_panorama_lookup(&self, frame: &FrameParams<'_>, pano: &PanoSettings, face_size: u32) {
        let clear = srgb_to_linear_color(frame.background);
        let fitted = pano.fitted();
        self.pano.write_resolve(
            &self.queue,
            &panorama::ResolveUniforms {
                cave_from_view: pano
                    .view_from_cave(frame.head.position)
                    .inverse()
                    .to_cols_array_2d(),
                cube_from_cave: sky_pass::cube_from_cave(frame.world_from_cave).to_cols_array_2d(),
                window: fitted.map_window(),
                params: [
                    fitted.projection.code() as f32,
                    panorama::face_half_extent(face_size),
                    frame.sky.exposure,
                    0.0,
                ],
                background: [clear.r as f32, clear.g as f32, clear.b as f32, 1.0],
            },
        );
    }

    /// The sky's cube behind the panorama (at infinity, the same for every eye), unless the
    /// sky is off.
    fn panorama_sky(&self, frame: &FrameParams<'_>) -> Option<&wgpu::BindGroup> {
        self.sky_pass
            .cube_bind_group()
            .filter(|_| frame.sky.mode != SkyMode::Off)
    }

    /// The image route: the scene into six cube faces from the head, then the look-up.
    fn encode_panorama_faces(
        &mut self,
        encoder: &mut wgpu::CommandEncoder,
        frame: &FrameParams<'_>,
        face_size: u32,
    ) {
        let head = frame.head.position;
        let (near, far) = (frame.cave.near, frame.cave.far);
        self.pano
            .ensure_cube(&self.device, face_size, self.settings.msaa);
        let frame_uniforms = self.prepare_frame(encoder, frame, None);
        let faces = (0..6).map(|f| ViewUniforms {
            clip_from_cave: panorama::face_clip_from_cave(f, head, face_size, near, far)
                .to_cols_array_2d(),
            eye_position: head.extend(1.0).to_array(),
            // A plain perspective view: no omnistereo, no panorama fields.
            ..bytemuck::Zeroable::zeroed()
        });
        self.pano_set
            .write_uniforms(&self.queue, &frame_uniforms, faces);
        self.pano_set.set_tessellated_views(0);
        let (scene_pass, scene, faces) =
            (&self.scene_pass, &self.scene, self.pano_set.bind_group());
        // Alpha 0 where the faces show nothing: the look-up puts the sky there.
        let clear = srgb_to_linear_color(frame.background);
        let face_clear = wgpu::Color { a: 0.0, ..clear };
        self.pano.encode_faces(encoder, face_clear, |pass, face| {
            if let Some(scene) = scene {
                scene_pass.draw(pass, scene, faces, face, false, false);
            }
        });
        self.pano.encode_resolve(encoder, self.panorama_sky(frame));
        self.pano_views = 1;
    }

    /// The geometric route: each eye's view uniforms and tessellation, then each eye's pass.
    fn encode_panorama_eyes(
        &mut self,
        encoder: &mut wgpu::CommandEncoder,
        frame: &FrameParams<'_>,
        pano: &PanoSettings,
    ) -> Result<(), RenderError> {
        let eyes: &[Option<Eye>] = if pano.stereo.is_stereo() {
            &[Some(Eye::Left), Some(Eye::Right)]
        } else {
            &[None]
        };
        self.prepare_panorama_eyes(encoder, frame, pano, eyes)?;
        let rounds = tessellator::rounds(&frame.tess);
        let clear = srgb_to_linear_color(frame.background);
        let sky = self.panorama_sky(frame);
        for index in 0..eyes.len() {
            let (Some(scene), Some(buffers), Some(tessellator)) =
                (&self.scene, self.pano_set.tessellated(), &self.tessellator)
            else {
                // No scene: the sky alone (or the clear colour).
                if let (Some(mut pass), Some(sky)) =
                    (self.pano.begin_eye_pass(encoder, index, clear), sky)
                {
                    self.pano.draw_sky(&mut pass, sky);
                }
                continue;
            };
            buffers.encode(tessellator, encoder, index, None, rounds, None, None);
            if let Some(mut pass) = self.pano.begin_eye_pass(encoder, index, clear) {
                self.scene_pass.draw_panorama(
                    &mut pass,
                    scene,
                    self.pano_set.bind_group(),
                    buffers,
                    index,
                );
                if let Some(sky) = sky {
                    self.pano.draw_sky(&mut pass, sky);
                }
            }
        }
        self.pano_views = eyes.len();
        Ok(())
    }

    /// The geometric route's per-eye uniforms and the tessellator's inputs.
    fn prepare_panorama_eyes(
        &mut self,
        encoder: &mut wgpu::CommandEncoder,
        frame: &FrameParams<'_>,
        pano: &PanoSettings,
        eyes: &[Option<Eye>],
    ) -> Result<(), RenderError> {
        let head = frame.head.position;
        let omni = matches!(pano.stereo, crate::pano::PanoStereo::Omni);
        let frame_uniforms = self.prepare_frame(encoder, frame, omni.then_some(frame.omni));
        let msaa = self.settings.msaa;
        let views = eyes.iter().map(|&eye| {
            panorama::pano_view_uniforms(
                pano,
                head,
                eye,
                frame.eye_separation,
                frame.cave.near,
                frame.cave.far,
                msaa,
            )
        });
        self.pano_set
            .write_uniforms(&self.queue, &frame_uniforms, views);
        let pixels_per_radian = pano.size[0] as f32 / pano.fitted().fov().x;
        let radius = if omni {
            0.5 * frame.eye_separation
        } else {
            0.0
        };
        if let (Some(scene), Some(tessellator)) = (&self.scene, &self.tessellator) {
            let limits = self.tess_limits();
            let buffers = self
                .pano_set
                .tessellation(&self.device, tessellator, scene, limits)?;
            buffers.write_uniforms(
                &self.queue,
                eyes.iter().map(|_| {
                    TessUniforms::panorama(&frame.tess, pano.size, pixels_per_radian, head, radius)
                }),
            );
        }
        self.pano_set
            .set_tessellated_views(if self.scene.is_some() { eyes.len() } else { 0 });
        Ok(())
    }
}
