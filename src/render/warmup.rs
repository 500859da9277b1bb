//! Compiling a change's pipelines before a view shows it. lavapipe compiles
//! a pipeline the first time it runs, on its one queue thread: a first
//! reflective material or a light's first shadows stopped the whole window
//! for 5-11 s (docs/performance-history.md). The warmer renders one tiny sample of
//! the changed view on a second device of the same adapter, in a thread of
//! its own, and resolves it as the window does, which fills the driver's
//! shader cache; the view keeps its old image (the camera still moves it;
//! a new view shows nothing) until then, and its own first frame
//! afterwards finds the compiled code in the cache. Where the driver keeps
//! no cache the change still costs its compile when it is applied, as
//! before.

use std::sync::mpsc::{self, Receiver, Sender};
use std::thread::JoinHandle;

use crate::gpu::shader::ShaderOverrides;
use crate::gpu::{Gpu, GpuError};
use crate::render::{PipelineKeys, RenderSettings, Renderer};
use crate::scene::Scene;

/// The warm-up renders at this size: the code compiled does not depend on
/// it, and a small image keeps the second device's work to the compile.
const WARM_SIZE: u32 = 16;

/// A change to compile ahead: the changed scene and settings, and, where the
/// view's renderer could tell them, the pipelines it will draw with
/// ([`Renderer::keys_for_edit`]), which the warm-up then uses rather than
/// what a new renderer would choose.
struct Job {
    id: u64,
    scene: Scene,
    settings: RenderSettings,
    keys: Option<PipelineKeys>,
    shaders: Option<std::sync::Arc<ShaderOverrides>>,
    /// The format of the texture the view is resolved into, and the
    /// format it is resolved through ([`Renderer::resolve_into_as`]).
    resolve: Option<(wgpu::TextureFormat, wgpu::TextureFormat)>,
    /// Report the job finished after its still frame
    /// ([`Warmer::request_first_image`]).
    report_still: bool,
    /// The view's own size, whose accumulate tiles the warm-up draws with
    /// where no keys say which ([`Renderer::use_tiles_of_size`]).
    view_size: (u32, u32),
}

/// One view's change being compiled ahead: its job, and the pipelines that
/// job compiles (`None` where only a new renderer could tell).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Warming {
    id: u64,
    /// The pipelines it compiles, where they were known.
    pub keys: Option<PipelineKeys>,
}

/// The warm-up thread and what it has finished.
pub struct Warmer {
    jobs: Option<Sender<Job>>,
    done: Receiver<(u64, Result<PipelineKeys, String>)>,
    /// The last job finished and how it went: jobs run in order.
    finished: Option<(u64, Result<PipelineKeys, String>)>,
    next_id: u64,
    thread: Option<JoinHandle<()>>,
    /// Also compile the resolve into this texture format, through this
    /// view format ([`Warmer::resolving_into`]).
    resolve: Option<(wgpu::TextureFormat, wgpu::TextureFormat)>,
}

impl Warmer {
    /// Starts the thread; its device is opened on the first job, on the
    /// adapter `gpu` uses.
    pub fn new(gpu: &Gpu) -> Warmer {
        let (jobs, inbox) = mpsc::channel::<Job>();
        let (report, done) = mpsc::channel();
        let instance = gpu.instance.clone();
        let adapter = gpu.adapter.clone();
        let thread = std::thread::Builder::new()
            .name("celray pipeline warm-up".into())
            .spawn(move || {
                let mut device: Option<Gpu> = None;
                for job in inbox {
                    let start = std::time::Instant::now();
                    if device.is_none() {
                        device = Gpu::from_adapter(instance.clone(), adapter.clone())
                            .inspect_err(|e| log::warn!("pipeline warm-up: no second device: {e}"))
                            .ok();
                        log::debug!("pipeline warm-up: device opened in {:?}", start.elapsed());
                    }
                    let Some(gpu) = &device else {
                        let failed = Err("no second device".to_string());
                        if report.send((job.id, failed)).is_err() {
                            break;
                        }
                        continue;
                    };
                    gpu.set_shader_overrides(job.shaders.as_deref().cloned());
                    let mut reported = false;
                    let result = warm_still(gpu, &job).and_then(|(renderer, keys)| {
                        log::debug!(
                            "pipeline warm-up {}: still frame at {:?}",
                            job.id,
                            start.elapsed()
                        );
                        if job.report_still {
                            // A new view shows its first image now; its
                            // moving frames compile meanwhile.
                            reported = report.send((job.id, Ok(keys))).is_ok();
                        }
                        warm_moving(gpu, &job, renderer, keys)
                    });
                    log::debug!("pipeline warm-up {}: done at {:?}", job.id, start.elapsed());
                    let result = result.map_err(|e| e.to_string());
                    if let Err(e) = &result {
                        log::warn!("pipeline warm-up: {e}");
                    }
                    if !reported && report.send((job.id, result)).is_err() {
                        break;
                    }
                }
            })
            .ok();
        Warmer {
            jobs: thread.as_ref().map(|_| jobs),
            done,
            finished: None,
            next_id: 0,
            thread,
            resolve: None,
        }
    }

    /// Warm-ups also resolve their sample into a texture of `format`
    /// through a view of `view_format`, as the window's views are, so that
    /// the resolve pipeline is compiled ahead too.
    pub fn resolving_into(
        mut self,
        format: wgpu::TextureFormat,
        view_format: wgpu::TextureFormat,
    ) -> Warmer {
        self.resolve = Some((format, view_format));
        self
    }

    /// Queues the compilation of what `scene` with `settings` draws with
    /// (`keys` where known). `None` where there is no warm-up thread: the
    /// change should then be applied at once.
    pub fn request(
        &mut self,
        gpu: &Gpu,
        scene: Scene,
        settings: RenderSettings,
        keys: Option<PipelineKeys>,
    ) -> Option<Warming> {
        self.queue(gpu, scene, settings, keys, false)
    }

    /// [`Warmer::request`] for a view that has nothing to show yet: it
    /// finishes once a still frame has been drawn (and resolved), so the
    /// view's first image comes as early as it can, and then goes on to
    /// compile what moving frames add (the reproject pass), before the
    /// next job.
    pub fn request_first_image(
        &mut self,
        gpu: &Gpu,
        scene: Scene,
        settings: RenderSettings,
    ) -> Option<Warming> {
        self.queue(gpu, scene, settings, None, true)
    }

    fn queue(
        &mut self,
        gpu: &Gpu,
        scene: Scene,
        settings: RenderSettings,
        keys: Option<PipelineKeys>,
        report_still: bool,
    ) -> Option<Warming> {
        let id = self.next_id;
        let view_size = (settings.width, settings.height);
        let job = Job {
            id,
            view_size,
            scene,
            settings: RenderSettings {
                width: WARM_SIZE,
                height: WARM_SIZE,
                ..settings
            },
            keys,
            shaders: gpu.shader_overrides(),
            resolve: self.resolve,
            report_still,
        };
        self.jobs.as_ref()?.send(job).ok()?;
        self.next_id += 1;
        Some(Warming { id, keys })
    }

    /// Whether `w` has finished (or can no longer finish: the thread is
    /// gone). A warm-up that failed has finished too: the change is then
    /// applied and reports its own error.
    pub fn finished(&mut self, w: &Warming) -> bool {
        self.outcome(w).is_some()
    }

    /// How `w` went, once it has finished: the pipelines it drew with
    /// (`None` for a job that a later one has already overtaken in the
    /// report), or `Err` with the reason where the warm-up failed or its
    /// thread is gone.
    pub fn outcome(&mut self, w: &Warming) -> Option<Result<Option<PipelineKeys>, String>> {
        loop {
            match self.done.try_recv() {
                Ok(done) => self.finished = Some(done),
                Err(mpsc::TryRecvError::Empty) => break,
                Err(mpsc::TryRecvError::Disconnected) => {
                    return Some(Err("the warm-up thread is gone".into()));
                }
            }
        }
        match &self.finished {
            Some((id, result)) if *id == w.id => Some(result.clone().map(Some)),
            Some((id, _)) if *id > w.id => Some(Ok(None)),
            _ => None,
        }
    }
}

impl Drop for Warmer {
    /// Closes the queue and waits for the job in progress.
    fn drop(&mut self) {
        self.jobs = None;
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

/// One sample of the job's scene at the warm-up size, with its pipelines,
/// resolved as the window does; returns the renderer and the pipelines it
/// drew with.
fn warm_still(gpu: &Gpu, job: &Job) -> Result<(Renderer, PipelineKeys), GpuError> {
    let mut renderer = Renderer::new(gpu, job.scene.clone(), job.settings.clone())?;
    match &job.keys {
        Some(keys) => renderer.use_pipelines(gpu, keys)?,
        None => renderer.use_tiles_of_size(job.view_size.0, job.view_size.1),
    }
    renderer.render_sample(gpu)?;
    if let Some((format, view_format)) = job.resolve {
        resolve_once(gpu, &mut renderer, format, view_format)?;
    }
    gpu.wait_idle()?;
    let keys = renderer.pipeline_keys();
    Ok((renderer, keys))
}

/// With temporal reprojection on, a second sample from a moved camera (a
/// moving frame, which runs the reproject pass); returns the pipelines
/// `renderer` drew with, `drew` and the reproject pass where it ran.
fn warm_moving(
    gpu: &Gpu,
    job: &Job,
    mut renderer: Renderer,
    mut drew: PipelineKeys,
) -> Result<PipelineKeys, GpuError> {
    if drew.reproject {
        let mut camera = job.scene.camera.clone();
        camera.eye += (camera.target - camera.eye) * 0.01;
        renderer.set_camera(camera);
        renderer.render_sample(gpu)?;
        drew.reproject = renderer.last_frame_moved();
        gpu.wait_idle()?;
    }
    Ok(drew)
}

/// Resolves `renderer`'s image once into a new texture of `format`, through
/// a view of `view_format` (which compiles that resolve pipeline).
fn resolve_once(
    gpu: &Gpu,
    renderer: &mut Renderer,
    format: wgpu::TextureFormat,
    view_format: wgpu::TextureFormat,
) -> Result<(), GpuError> {
    let target = gpu.device.create_texture(&wgpu::TextureDescriptor {
        label: Some("warm-up resolve"),
        size: wgpu::Extent3d {
            width: WARM_SIZE,
            height: WARM_SIZE,
            depth_or_array_layers: 1,
        },
        mip_level_count: 1,
        sample_count: 1,
        dimension: wgpu::TextureDimension::D2,
        format,
        usage: wgpu::TextureUsages::RENDER_ATTACHMENT,
        view_formats: &[view_format],
    });
    let mut encoder = gpu
        .device
        .create_command_encoder(&wgpu::CommandEncoderDescriptor {
            label: Some("warm-up resolve"),
        });
    renderer.resolve_into_as(gpu, &mut encoder, &target, view_format)?;
    gpu.queue.submit([encoder.finish()]);
    Ok(())
}
