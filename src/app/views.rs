//! The view slots: up to four views, each an image in a texture and, while
//! the layout shows it, a [`Renderer`] drawing into it. Kept in step with
//! the panel's model ([`ViewSlots::sync`]), sampled a few samples a frame
//! until converged, resolved when their sample count changed, saved on
//! request.

use std::path::{Path, PathBuf};

use super::model::Model;
use super::screenshot;
use super::surface::read_rgba8;
use super::timing::FrameTimer;
use crate::gpu::{Gpu, GpuError};
use crate::render::warmup::{Warmer, Warming};
use crate::render::{RenderSettings, Renderer};
use crate::scene::{Camera, Scene};
use crate::view::ViewSpec;

/// The number of view slots (the most views a layout shows).
pub const WINDOW_VIEW_SLOTS: usize = 4;

/// What a view's renderer was last brought up to date with: a panel edit
/// changes one of these, and [`ViewSlots::sync`] applies what changed.
#[derive(Clone, PartialEq)]
struct ViewInputs {
    spec: ViewSpec,
    scene_rev: u64,
    camera: Camera,
    settings: RenderSettings,
}

impl ViewInputs {
    /// The scene this view draws: the model's, through the view's spec, at
    /// the view's camera.
    fn scene(&self, model: &Model) -> Scene {
        let mut scene = self.spec.apply(&model.scene);
        scene.camera = self.camera.clone();
        scene
    }
}

/// One view slot: the texture the view is resolved into and, while the
/// layout shows the slot, a renderer drawing into it. The texture is copied
/// into the window (fast on a CPU driver), or, where the surface cannot be
/// copied into, drawn by egui under `tex_id` (which never changes).
struct ViewSlot {
    tex_id: Option<egui::TextureId>,
    texture: wgpu::Texture,
    renderer: Option<Renderer>,
    inputs: Option<ViewInputs>,
    /// Samples in the texture (resolved), to skip resolving unchanged images.
    shown: Option<u32>,
    /// A change waiting for its pipelines to compile ahead
    /// ([`crate::render::warmup`]); meanwhile the renderer draws the old state.
    warming: Option<Warming>,
    /// A renderer rebuilt with reloaded shaders, waiting for its pipelines
    /// to compile ahead ([`ViewSlots::reload_renderers`]); meanwhile the
    /// old renderer draws with the old shaders.
    reloaded: Option<(Renderer, Warming)>,
    /// A view's first renderer, built while its pipelines compile ahead
    /// (the building overlaps the compile), and the inputs it was built
    /// for; it draws once the warm-up has finished.
    pending: Option<(Renderer, ViewInputs)>,
}

/// The view slots and what they share.
pub(super) struct ViewSlots {
    slots: Vec<ViewSlot>,
    format: wgpu::TextureFormat,
    /// Pixel size of each shown view, from the last layout.
    pub sizes: Vec<(u32, u32)>,
    /// Whether new renderers time their passes (the window has a timer).
    timed: bool,
    /// Compiles a change's new pipelines before a view applies it.
    warmer: Warmer,
}

fn view_texture(gpu: &Gpu, size: (u32, u32), format: wgpu::TextureFormat) -> wgpu::Texture {
    gpu.device.create_texture(&wgpu::TextureDescriptor {
        label: Some("view image"),
        size: wgpu::Extent3d {
            width: size.0,
            height: size.1,
            depth_or_array_layers: 1,
        },
        mip_level_count: 1,
        sample_count: 1,
        dimension: wgpu::TextureDimension::D2,
        format,
        usage: wgpu::TextureUsages::RENDER_ATTACHMENT
            | wgpu::TextureUsages::TEXTURE_BINDING
            | wgpu::TextureUsages::COPY_SRC,
        // The resolve writes through the sRGB view (resolve_format); the
        // window copies and egui samples the encoded bytes as they are.
        view_formats: &[resolve_format(format)],
    })
}

/// A view's renderer, timing its passes where the window has a timer.
fn new_renderer(
    gpu: &Gpu,
    scene: Scene,
    settings: RenderSettings,
    timed: bool,
) -> Result<Renderer, GpuError> {
    let mut renderer = Renderer::new(gpu, scene, settings)?;
    if timed {
        renderer.enable_pass_timing(gpu);
    }
    Ok(renderer)
}

/// The format the views are resolved through: the sRGB twin of the image's
/// format, so the target encodes as it stores (cheaper on the CPU driver
/// than the resolve shader's own encoding, and the same bytes a capture
/// gets); the image's own format where it has no twin.
fn resolve_format(format: wgpu::TextureFormat) -> wgpu::TextureFormat {
    format.add_srgb_suffix()
}

impl ViewSlots {
    /// Empty slots with images of `format`; with `egui`, each image is
    /// registered there to be drawn as an egui image.
    pub fn new(
        gpu: &Gpu,
        format: wgpu::TextureFormat,
        mut egui: Option<&mut egui_wgpu::Renderer>,
        timed: bool,
    ) -> ViewSlots {
        let slots = (0..WINDOW_VIEW_SLOTS)
            .map(|_| {
                let texture = view_texture(gpu, (1, 1), format);
                let tex_id = egui.as_mut().map(|r| {
                    r.register_native_texture(
                        &gpu.device,
                        &texture.create_view(&Default::default()),
                        wgpu::FilterMode::Nearest,
                    )
                });
                ViewSlot {
                    tex_id,
                    texture,
                    renderer: None,
                    inputs: None,
                    shown: None,
                    warming: None,
                    reloaded: None,
                    pending: None,
                }
            })
            .collect();
        ViewSlots {
            slots,
            format,
            sizes: Vec::new(),
            timed,
            warmer: Warmer::new(gpu).resolving_into(format, resolve_format(format)),
        }
    }

    /// The egui texture of each slot (where egui draws the views).
    pub fn texture_ids(&self) -> Vec<Option<egui::TextureId>> {
        self.slots.iter().map(|s| s.tex_id).collect()
    }

    /// Each slot's image, and whether it shows a view.
    pub fn images(&self) -> Vec<(&wgpu::Texture, bool)> {
        self.slots
            .iter()
            .map(|s| (&s.texture, s.renderer.is_some()))
            .collect()
    }

    /// The renderer of view `i`, while it is shown.
    pub fn renderer(&self, i: usize) -> Option<&Renderer> {
        self.slots.get(i).and_then(|s| s.renderer.as_ref())
    }

    fn renderers(&self) -> impl Iterator<Item = &Renderer> {
        self.slots.iter().filter_map(|s| s.renderer.as_ref())
    }

    /// Samples accumulated in each of the first `count` views.
    pub fn samples(&self, count: usize) -> Vec<u32> {
        self.slots[..count.min(self.slots.len())]
            .iter()
            .map(|s| s.renderer.as_ref().map_or(0, Renderer::samples))
            .collect()
    }

    /// Whether any shown view is still converging.
    pub fn converging(&self) -> bool {
        self.renderers().any(|r| !r.converged())
    }

    /// The acceleration structure the first shown view's rays walk, and why
    /// the driver's is not used, if it is not.
    pub fn accel_info(&self) -> Option<(&'static str, Option<String>)> {
        self.renderers()
            .next()
            .map(|r| (r.accel_in_use(), r.accel_notice().map(str::to_string)))
    }

    /// Makes each shown view's renderer match the model (and each image the
    /// size of its view); drops the renderers of views not shown.
    pub fn sync(
        &mut self,
        gpu: &Gpu,
        model: &Model,
        egui: &mut egui_wgpu::Renderer,
    ) -> Result<(), GpuError> {
        let count = model.layout.view_count();
        for i in 0..self.slots.len() {
            if i >= count {
                let slot = &mut self.slots[i];
                slot.renderer = None;
                slot.inputs = None;
                slot.shown = None;
                slot.warming = None;
                slot.reloaded = None;
                slot.pending = None;
                continue;
            }
            let size = self.sizes.get(i).copied().unwrap_or((1, 1));
            self.resize_image(gpu, i, size, egui);
            let want = ViewInputs {
                spec: model.views[i].clone(),
                scene_rev: model.scene_rev,
                camera: model.scene.camera.clone(),
                settings: RenderSettings {
                    width: size.0,
                    height: size.1,
                    ..model.settings.clone()
                },
            };
            self.update_renderer(gpu, i, want, model)?;
            self.swap_reloaded(gpu, i)?;
        }
        Ok(())
    }

    /// Puts slot `i`'s reloaded renderer in place once its warm-up has
    /// finished, brought up to what the old one drew meanwhile (settings,
    /// scene and camera changed since the reload).
    fn swap_reloaded(&mut self, gpu: &Gpu, i: usize) -> Result<(), GpuError> {
        let slot = &mut self.slots[i];
        let Some((_, w)) = &slot.reloaded else {
            return Ok(());
        };
        if !self.warmer.finished(w) {
            return Ok(());
        }
        let Some((mut new, _)) = slot.reloaded.take() else {
            return Ok(());
        };
        if let Some(old) = &slot.renderer {
            if new.settings() != old.settings() {
                new.set_settings(gpu, old.settings().clone())?;
            }
            if new.scene() != old.scene() {
                let mut same_but_camera = old.scene().clone();
                same_but_camera.camera = new.scene().camera.clone();
                if &same_but_camera == new.scene() {
                    new.set_camera(old.scene().camera.clone());
                } else {
                    new.update_scene(gpu, old.scene().clone())?;
                }
            }
        }
        slot.renderer = Some(new);
        slot.shown = None;
        Ok(())
    }

    /// A new image for slot `i` when its view's size changed.
    fn resize_image(
        &mut self,
        gpu: &Gpu,
        i: usize,
        size: (u32, u32),
        egui: &mut egui_wgpu::Renderer,
    ) {
        let slot = &mut self.slots[i];
        if (slot.texture.width(), slot.texture.height()) == size {
            return;
        }
        let texture = view_texture(gpu, size, self.format);
        if let Some(id) = slot.tex_id {
            egui.update_egui_texture_from_wgpu_texture(
                &gpu.device,
                &texture.create_view(&Default::default()),
                wgpu::FilterMode::Nearest,
                id,
            );
        }
        slot.texture = texture;
        slot.shown = None;
    }

    /// Brings slot `i`'s renderer up to `want`: in place where only
    /// settings, scene contents or camera changed, else a new renderer.
    fn update_renderer(
        &mut self,
        gpu: &Gpu,
        i: usize,
        want: ViewInputs,
        model: &Model,
    ) -> Result<(), GpuError> {
        let timed = self.timed;
        if self.slots[i].inputs.as_ref() == Some(&want) {
            // Also where a change waiting for its warm-up was undone.
            self.slots[i].warming = None;
            return Ok(());
        }
        if !self.compiled_ahead(gpu, i, &want, model) {
            return Ok(());
        }
        let slot = &mut self.slots[i];
        if !matches!(&slot.inputs, Some(had) if had.spec == want.spec) {
            // A new renderer is built below, with the current shaders.
            slot.reloaded = None;
        }
        match (&mut slot.renderer, &slot.inputs) {
            (Some(renderer), Some(had)) if had.spec == want.spec => {
                if had.settings != want.settings {
                    renderer.set_settings(gpu, want.settings.clone())?;
                }
                if had.scene_rev != want.scene_rev {
                    renderer.update_scene(gpu, want.scene(model))?;
                } else if had.camera != want.camera {
                    renderer.set_camera(want.camera.clone());
                }
            }
            _ => {
                slot.renderer = None;
                let renderer = match slot.pending.take() {
                    Some((mut built, had))
                        if had.spec == want.spec
                            && had.scene_rev == want.scene_rev
                            && had.settings == want.settings =>
                    {
                        built.set_camera(want.camera.clone());
                        built
                    }
                    _ => new_renderer(gpu, want.scene(model), want.settings.clone(), timed)?,
                };
                slot.renderer = Some(renderer);
            }
        }
        slot.inputs = Some(want);
        slot.shown = None;
        Ok(())
    }

    /// Whether slot `i` may apply `want` now: its renderer has the
    /// pipelines `want` draws with, or they have been compiled ahead
    /// ([`crate::render::warmup`]). Otherwise it asks the warmer to compile
    /// them, and meanwhile the old renderer follows the camera. A view
    /// shown for the first time (the app's first views too) waits for its
    /// compilation the same way, showing nothing meanwhile, so that no
    /// frame of the window stalls on a compile.
    fn compiled_ahead(&mut self, gpu: &Gpu, i: usize, want: &ViewInputs, model: &Model) -> bool {
        let slot = &mut self.slots[i];
        // The pipelines the change will draw with, where the renderer can
        // tell without applying it, and whether it has them.
        let (keys, has) = match (&slot.renderer, &slot.inputs) {
            (Some(renderer), Some(had)) => {
                let keys = match (
                    had.spec == want.spec,
                    had.settings != want.settings,
                    had.scene_rev != want.scene_rev,
                ) {
                    (false, _, _) | (true, true, true) => None,
                    (true, true, false) => renderer.keys_for_settings(&want.settings),
                    (true, false, true) => renderer.keys_for_edit(&want.scene(model)),
                    (true, false, false) => Some(renderer.pipeline_keys()),
                };
                (keys, keys.is_some_and(|k| renderer.has_pipelines(&k)))
            }
            _ => (None, false),
        };
        let warming = slot
            .warming
            .map(|w| (w.keys, w.keys == keys && self.warmer.finished(&w)));
        match step(has, keys, warming) {
            Step::Apply => {
                slot.warming = None;
                return true;
            }
            Step::Wait => {
                // A view with nothing to show yet builds its renderer
                // now, while the warm-up compiles on the other thread (the
                // frame that asked for the warm-up has been shown).
                if slot.renderer.is_none() && slot.pending.is_none() {
                    match new_renderer(gpu, want.scene(model), want.settings.clone(), self.timed) {
                        Ok(renderer) => slot.pending = Some((renderer, want.clone())),
                        // Building it again when the warm-up is done reports the error.
                        Err(e) => log::debug!("view {i}: {e}"),
                    }
                }
            }
            Step::Warm => {
                let (scene, settings) = (want.scene(model), want.settings.clone());
                let request = if slot.renderer.is_none() {
                    self.warmer.request_first_image(gpu, scene, settings)
                } else {
                    self.warmer.request(gpu, scene, settings, keys)
                };
                match request {
                    Some(w) => slot.warming = Some(w),
                    None => return true,
                }
            }
        }
        if let (Some(renderer), Some(had)) = (&mut slot.renderer, &mut slot.inputs) {
            if had.camera != want.camera {
                renderer.set_camera(want.camera.clone());
                had.camera = want.camera.clone();
                slot.shown = None;
            }
        }
        false
    }

    /// For each of the first `count` views, whether it has nothing to show
    /// yet: its first pipelines are being compiled ahead.
    pub fn compiling_first(&self, count: usize) -> Vec<bool> {
        (self.slots.iter().take(count))
            .map(|s| s.renderer.is_none() && s.warming.is_some())
            .collect()
    }

    /// How many views wait for a change's (or reloaded shaders')
    /// pipelines to compile.
    pub fn warming(&self) -> usize {
        self.slots
            .iter()
            .filter(|s| s.warming.is_some() || s.reloaded.is_some())
            .count()
    }

    /// Renders up to `per_view` samples into every shown view that has not
    /// converged, their passes timed where `timed`. Returns whether any
    /// sample was rendered, and the first error (after which that view
    /// renders no more this frame).
    pub fn sample(&mut self, gpu: &Gpu, per_view: u32, timed: bool) -> (bool, Option<GpuError>) {
        let mut sampled = false;
        let mut error = None;
        for renderer in self.slots.iter_mut().filter_map(|s| s.renderer.as_mut()) {
            renderer.time_samples(timed);
            for _ in 0..per_view {
                if renderer.converged() {
                    break;
                }
                if let Err(e) = renderer.render_sample(gpu) {
                    error = Some(e);
                    break;
                }
                sampled = true;
            }
        }
        (sampled, error)
    }

    /// Gives each view's newly read-back pass times to `timer`.
    pub fn collect_pass_times(&mut self, timer: &mut FrameTimer) {
        for (slot, s) in self.slots.iter_mut().enumerate() {
            let Some(renderer) = s.renderer.as_mut() else {
                continue;
            };
            if let Some(times) = renderer.collect_pass_times() {
                timer.add_view_times(slot, times);
            }
        }
    }

    /// Records the resolve of every view whose sample count changed since
    /// its image was last resolved.
    pub fn resolve_changed(
        &mut self,
        gpu: &Gpu,
        encoder: &mut wgpu::CommandEncoder,
    ) -> Result<(), GpuError> {
        let mut failed = None;
        for slot in &mut self.slots {
            let Some(renderer) = &mut slot.renderer else {
                continue;
            };
            if slot.shown != Some(renderer.samples()) {
                // One view's failure is reported; the others still draw.
                match renderer.resolve_into_as(
                    gpu,
                    encoder,
                    &slot.texture,
                    resolve_format(self.format),
                ) {
                    Ok(()) => slot.shown = Some(renderer.samples()),
                    Err(e) => failed = Some(e),
                }
            }
        }
        failed.map_or(Ok(()), Err)
    }

    /// Rebuilds every shown view's renderer with the device's current
    /// shaders (after a hot reload). The new renderers' pipelines are
    /// compiled ahead ([`crate::render::warmup`]) while the old renderers
    /// keep drawing; [`ViewSlots::sync`] puts each in place when its
    /// warm-up has finished (at once where there is no warm-up thread). On
    /// an error, nothing changes.
    pub fn reload_renderers(&mut self, gpu: &Gpu) -> Result<(), GpuError> {
        let timed = self.timed;
        let rebuilt = self
            .slots
            .iter()
            .map(|slot| {
                let Some(old) = &slot.renderer else {
                    return Ok(None);
                };
                new_renderer(gpu, old.scene().clone(), old.settings().clone(), timed).map(Some)
            })
            .collect::<Result<Vec<_>, GpuError>>()?;
        for (slot, new) in self.slots.iter_mut().zip(rebuilt) {
            let Some(renderer) = new else { continue };
            let keys = renderer.pipeline_keys();
            let job = self.warmer.request(
                gpu,
                renderer.scene().clone(),
                renderer.settings().clone(),
                Some(keys),
            );
            match job {
                Some(w) => slot.reloaded = Some((renderer, w)),
                None => {
                    slot.renderer = Some(renderer);
                    slot.reloaded = None;
                    slot.shown = None;
                }
            }
        }
        Ok(())
    }

    /// Saves each shown view's image (full size, even under a wipe) as a
    /// new PNG in `dir`, named with `stamp` and the view's label; returns
    /// the paths written, or the first failure.
    pub fn save(
        &mut self,
        gpu: &Gpu,
        dir: &Path,
        stamp: &str,
        labels: &[String],
    ) -> Result<Vec<PathBuf>, String> {
        let mut saved = Vec::new();
        for (i, slot) in self.slots.iter_mut().enumerate() {
            let Some(renderer) = &mut slot.renderer else {
                continue;
            };
            let fail = |e: String| format!("cannot save view {}: {e}", i + 1);
            let mut encoder = gpu.device.create_command_encoder(&Default::default());
            renderer
                .resolve_into_as(
                    gpu,
                    &mut encoder,
                    &slot.texture,
                    resolve_format(self.format),
                )
                .map_err(|e| fail(e.to_string()))?;
            gpu.queue.submit([encoder.finish()]);
            let label = labels.get(i).map_or("", String::as_str);
            let stem = format!("celray-{stamp}-view{}-{}", i + 1, screenshot::slug(label));
            let (w, h) = (slot.texture.width(), slot.texture.height());
            let rgba =
                read_rgba8(gpu, &slot.texture, self.format).map_err(|e| fail(e.to_string()))?;
            let path = screenshot::save_new_png(dir, &stem, w, h, &rgba)
                .map_err(|e| fail(e.to_string()))?;
            saved.push(path);
        }
        Ok(saved)
    }
}

/// What a view does with a change this frame ([`ViewSlots::compiled_ahead`]).
#[derive(Debug, PartialEq)]
enum Step {
    /// Apply it: the pipelines are there, or compiled ahead.
    Apply,
    /// Keep the old state: its warm-up is still compiling.
    Wait,
    /// Start a warm-up for it, and keep the old state.
    Warm,
}

/// The step for a change whose pipelines are `keys` (where known), given
/// whether the renderer `has` them and the slot's warm-up, if any: the
/// keys it compiles and whether it has finished.
fn step<K: PartialEq>(has: bool, keys: Option<K>, warming: Option<(Option<K>, bool)>) -> Step {
    if has {
        return Step::Apply;
    }
    match warming {
        Some((k, finished)) if k == keys => {
            if finished {
                Step::Apply
            } else {
                Step::Wait
            }
        }
        _ => Step::Warm,
    }
}

#[cfg(test)]
mod tests {
    use super::{step, Step, ViewSlots};
    use crate::app::layout::Layout;
    use crate::app::model::Model;
    use crate::gpu::shader::ShaderOverrides;
    use crate::gpu::{AdapterChoice, Gpu};
    use crate::render::RenderSettings;
    use crate::scene::Scene;

    /// A shader hot reload rebuilds the view's renderer with the new
    /// shaders but keeps drawing with the old one until the new one's
    /// pipelines are compiled ahead; `sync` then puts it in place, brought
    /// up to a camera moved meanwhile. The reloaded resolve paints
    /// magenta, so the pixel tells which renderer draws.
    #[test]
    fn reloaded_shaders_show_once_compiled_ahead() {
        let gpu = Gpu::new_headless(&AdapterChoice::for_tests()).unwrap();
        let format = wgpu::TextureFormat::Rgba8Unorm;
        let mut egui =
            egui_wgpu::Renderer::new(&gpu.device, format, egui_wgpu::RendererOptions::default());
        let mut slots = ViewSlots::new(&gpu, format, Some(&mut egui), false);
        let mut model = Model::new(
            Scene::builtin_default(),
            None,
            &[],
            Layout::Single,
            RenderSettings::default(),
        );
        slots.sizes = vec![(16, 12)];
        slots.sync(&gpu, &model, &mut egui).unwrap();
        // The first view, too, waits for its pipelines' warm-up.
        assert_eq!(slots.compiling_first(1), [true]);
        assert!(slots.slots[0].renderer.is_none());
        wait_for_warm_ups(&gpu, &mut slots, &model, &mut egui);
        assert_eq!(slots.compiling_first(1), [false]);
        let corner = |slots: &mut ViewSlots| {
            let r = slots.slots[0].renderer.as_mut().expect("a renderer");
            r.render_sample(&gpu).unwrap();
            r.read_srgb8(&gpu).unwrap()[..3].to_vec()
        };
        let before = corner(&mut slots);
        assert_ne!(before, [255, 0, 255]);

        let dir = std::env::temp_dir().join(format!("celray-view-reload-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let resolve = crate::gpu::shader::SHADER_FILES
            .iter()
            .find(|(name, _)| *name == "resolve.wgsl")
            .unwrap()
            .1;
        let magenta = resolve.replace(
            "return vec4<f32>(c, 1.0);",
            "return vec4<f32>(1.0, 0.0, 1.0, 1.0);",
        );
        assert_ne!(magenta, resolve, "resolve.wgsl changed shape");
        std::fs::write(dir.join("resolve.wgsl"), magenta).unwrap();
        gpu.set_shader_overrides(Some(ShaderOverrides::read_dir(&dir).unwrap()));
        std::fs::remove_dir_all(&dir).unwrap();
        slots.reload_renderers(&gpu).unwrap();
        assert_eq!(slots.warming(), 1, "the reload waits for its warm-up");
        assert_eq!(corner(&mut slots), before, "the old shaders draw meanwhile");

        model.scene.camera.eye.x += 0.5;
        wait_for_warm_ups(&gpu, &mut slots, &model, &mut egui);
        assert_eq!(
            corner(&mut slots),
            [255, 0, 255],
            "the reloaded shaders draw"
        );
        let drawn = slots.slots[0].renderer.as_ref().unwrap().scene();
        assert_eq!(
            drawn.camera, model.scene.camera,
            "at the camera moved meanwhile"
        );
    }

    /// Syncs `slots` with `model` until no view waits for a warm-up.
    fn wait_for_warm_ups(
        gpu: &Gpu,
        slots: &mut ViewSlots,
        model: &Model,
        egui: &mut egui_wgpu::Renderer,
    ) {
        let start = std::time::Instant::now();
        while slots.warming() > 0 {
            assert!(start.elapsed().as_secs() < 300, "warm-up never finished");
            std::thread::sleep(std::time::Duration::from_millis(20));
            slots.sync(gpu, model, egui).unwrap();
        }
    }

    /// A change applies at once where the renderer has its pipelines, and
    /// otherwise only once a warm-up of the same pipelines has finished; a
    /// change to other pipelines starts a warm-up of its own, and one whose
    /// pipelines only a new renderer could tell (`None`) waits for the
    /// warm-up of such a change.
    #[test]
    fn a_change_waits_for_the_warm_up_of_its_own_pipelines() {
        assert_eq!(step(true, Some(1), None), Step::Apply);
        assert_eq!(step(true, Some(1), Some((Some(2), false))), Step::Apply);
        assert_eq!(step(false, Some(1), None), Step::Warm);
        assert_eq!(step(false, Some(1), Some((Some(1), false))), Step::Wait);
        assert_eq!(step(false, Some(1), Some((Some(1), true))), Step::Apply);
        assert_eq!(step(false, Some(1), Some((Some(2), true))), Step::Warm);
        assert_eq!(step(false, Some(1), Some((None, true))), Step::Warm);
        assert_eq!(step::<u8>(false, None, None), Step::Warm);
        assert_eq!(step::<u8>(false, None, Some((None, false))), Step::Wait);
        assert_eq!(step::<u8>(false, None, Some((None, true))), Step::Apply);
    }
}
