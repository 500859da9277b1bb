//! Closest hits of arbitrary rays on the GPU, by the trace pass's own
//! traversal: what the tests compare with the CPU reference, and what the
//! ray-throughput benchmark times. Group 0 is the scene's shared group,
//! group 1 [`PASS_LAYOUT`] (the rays and their hits).

use std::collections::HashMap;
use std::sync::Mutex;

use wgpu::util::DeviceExt;

use crate::accel::PrivateSizes;
use crate::gpu::layout::{buffer_entries, read_only_storage_entry, read_write_storage_entry};
use crate::gpu::shader::Traversal;
use crate::gpu::twins::{GpuHit, GpuRay, RAY_BATCH_WORKGROUP};
use crate::gpu::uniform_tables::UniformTables;
use crate::gpu::{readback, shader, Gpu, GpuError};
use crate::render::driver_accel::{self, DriverAccel};
use crate::render::scene_buffers::{scene_layout, SceneBuffers, PASS_GROUP, SCENE_GROUP};

/// Group 1 of the ray batch, binding by binding as `shaders/ray_batch.wgsl`
/// declares it.
pub const PASS_LAYOUT: [wgpu::BindGroupLayoutEntry; 2] = [
    read_only_storage_entry(0, wgpu::ShaderStages::COMPUTE), // rays
    read_write_storage_entry(1),                             // hits
];

/// The traversal of the software variant on `gpu`.
fn software(gpu: &Gpu) -> Traversal {
    if gpu.packet_walk() {
        Traversal::Packet
    } else {
        Traversal::Software
    }
}

pub struct RayBatch {
    traversal: Traversal,
    /// By the private arrays' lengths (`SceneAccel::sizes`; the full
    /// lengths first, made at once so that a broken shader fails here).
    modules: Mutex<shader::SizedModules>,
    scene_layout: wgpu::BindGroupLayout,
    layout: wgpu::BindGroupLayout,
    pipeline_layout: wgpu::PipelineLayout,
    /// The layout of group 2 of the driver variant, when built so.
    driver: Option<wgpu::BindGroupLayout>,
    any_hit: bool,
    /// By whether the scene has CSG shapes (override `CSG_ENABLED`, as in
    /// the trace pass), which tables it reads from uniform copies and the
    /// private arrays' lengths; built the first time a scene needs one.
    pipelines: Mutex<HashMap<(bool, UniformTables, PrivateSizes), wgpu::ComputePipeline>>,
}

impl RayBatch {
    /// The software variant: rays walk celray's own BVH, as packets of 8
    /// where the device can ([`Gpu::packet_walk`]), else each on its own.
    pub fn new(gpu: &Gpu) -> Result<RayBatch, GpuError> {
        Self::with_traversal(gpu, software(gpu))
    }

    /// The variant that walks `traversal`'s structures ([`Traversal::Driver`]
    /// needs ray queries; trace with [`RayBatch::trace_driver_timed`]).
    pub fn with_traversal(gpu: &Gpu, traversal: Traversal) -> Result<RayBatch, GpuError> {
        if traversal == Traversal::Packet && !gpu.packet_walk() {
            return Err(GpuError::Unsupported(format!(
                "the packet walk needs a CPU adapter with subgroups of 8 ({})",
                gpu.summary
            )));
        }
        Self::build(gpu, traversal, false)
    }

    /// The software variant whose rays stop at the first hit they find, as
    /// the trace pass's shadow rays do: a hit's `instance` says the ray is
    /// blocked, its `t` is where (not necessarily the nearest hit).
    pub fn any_hit(gpu: &Gpu) -> Result<RayBatch, GpuError> {
        Self::build(gpu, software(gpu), true)
    }

    fn build(gpu: &Gpu, traversal: Traversal, any_hit: bool) -> Result<RayBatch, GpuError> {
        let mut modules = shader::SizedModules::new("ray_batch.wgsl");
        modules.get(gpu, traversal, PrivateSizes::FULL)?;
        gpu.scoped(|| {
            let scene_layout = scene_layout(gpu);
            let layout = gpu
                .device
                .create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
                    label: Some("ray batch layout"),
                    entries: &PASS_LAYOUT,
                });
            let pipeline_layout =
                gpu.device
                    .create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
                        label: Some("ray batch pipeline layout"),
                        bind_group_layouts: &[Some(&scene_layout), Some(&layout)],
                        immediate_size: 0,
                    });
            let driver =
                (traversal == Traversal::Driver).then(|| driver_accel::bind_group_layout(gpu));
            RayBatch {
                traversal,
                modules: Mutex::new(modules),
                scene_layout,
                layout,
                pipeline_layout,
                driver,
                any_hit,
                pipelines: Mutex::new(HashMap::new()),
            }
        })
    }

    /// The pipeline for `scene`, built the first time.
    fn pipeline_for(
        &self,
        gpu: &Gpu,
        scene: &SceneBuffers,
    ) -> Result<wgpu::ComputePipeline, GpuError> {
        let csg = !scene.accel.csg_ops.is_empty();
        // The driver variant too: its CSG evaluator keeps the same arrays.
        let sizes = scene.accel.sizes;
        let key = (csg, scene.tables, sizes);
        let mut pipelines = self.pipelines.lock().unwrap_or_else(|e| e.into_inner());
        if let Some(p) = pipelines.get(&key) {
            return Ok(p.clone());
        }
        let mut modules = self.modules.lock().unwrap_or_else(|e| e.into_inner());
        let module = modules.get(gpu, self.traversal, sizes)?;
        let constants = [
            ("CSG_ENABLED", f64::from(u8::from(csg))),
            ("ANY_HIT", f64::from(u8::from(self.any_hit))),
            scene.tables.constant(),
            gpu.edge_tolerance_constant(),
        ];
        let pipeline = match &self.driver {
            Some(driver_layout) => driver_accel::pipeline(
                gpu,
                "ray batch pipeline (driver ray queries)",
                module,
                &[&self.scene_layout, &self.layout],
                driver_layout,
                &constants,
            ),
            None => gpu
                .device
                .create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
                    label: Some("ray batch pipeline"),
                    layout: Some(&self.pipeline_layout),
                    module,
                    entry_point: Some("main"),
                    compilation_options: wgpu::PipelineCompilationOptions {
                        constants: &constants,
                        ..Default::default()
                    },
                    cache: None,
                }),
        };
        pipelines.insert(key, pipeline.clone());
        Ok(pipeline)
    }

    /// Traces `rays` against `scene`; returns one hit per ray (timed:
    /// [`RayBatch::trace_timed`]).
    pub fn trace(
        &self,
        gpu: &Gpu,
        scene: &SceneBuffers,
        rays: &[GpuRay],
    ) -> Result<Vec<GpuHit>, GpuError> {
        Ok(self.trace_any(gpu, scene, None, rays, false)?.0)
    }

    /// As [`RayBatch::trace`], also returning the seconds from submit to
    /// completion of the dispatch alone. The batch is dispatched twice and
    /// the second dispatch is timed: the first submission also carries the
    /// rays' upload and the zero fill wgpu gives a new storage buffer (on
    /// lavapipe, with the first touch of its pages, 15-20 ms for 921,600
    /// rays: docs/performance-history.md), which are not the traversal's cost.
    pub fn trace_timed(
        &self,
        gpu: &Gpu,
        scene: &SceneBuffers,
        rays: &[GpuRay],
    ) -> Result<(Vec<GpuHit>, f64), GpuError> {
        self.trace_any(gpu, scene, None, rays, true)
    }

    /// [`RayBatch::trace`] through the driver's structures `accel` (built
    /// for `scene`); this batch must be the driver variant.
    pub fn trace_driver(
        &self,
        gpu: &Gpu,
        scene: &SceneBuffers,
        accel: &DriverAccel,
        rays: &[GpuRay],
    ) -> Result<Vec<GpuHit>, GpuError> {
        Ok(self.trace_any(gpu, scene, Some(accel), rays, false)?.0)
    }

    /// [`RayBatch::trace_timed`] through the driver's structures `accel`
    /// (built for `scene`); this batch must be the driver variant.
    pub fn trace_driver_timed(
        &self,
        gpu: &Gpu,
        scene: &SceneBuffers,
        accel: &DriverAccel,
        rays: &[GpuRay],
    ) -> Result<(Vec<GpuHit>, f64), GpuError> {
        self.trace_any(gpu, scene, Some(accel), rays, true)
    }

    fn trace_any(
        &self,
        gpu: &Gpu,
        scene: &SceneBuffers,
        accel: Option<&DriverAccel>,
        rays: &[GpuRay],
        timed: bool,
    ) -> Result<(Vec<GpuHit>, f64), GpuError> {
        let driver_group = match (&self.driver, accel) {
            (None, None) => None,
            (Some(layout), Some(a)) => Some(a.bind_group(gpu, layout)),
            _ => {
                return Err(GpuError::Unsupported(
                    "ray batch: the driver variant traces with driver structures, \
                     the software variant without"
                        .into(),
                ))
            }
        };
        if rays.is_empty() {
            return Ok((Vec::new(), 0.0));
        }
        let ray_buffer = gpu
            .device
            .create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some("ray batch rays"),
                contents: bytemuck::cast_slice(rays),
                usage: wgpu::BufferUsages::STORAGE,
            });
        let hit_bytes = (rays.len() * std::mem::size_of::<GpuHit>()) as u64;
        let hit_buffer = gpu.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("ray batch hits"),
            size: hit_bytes,
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
            mapped_at_creation: false,
        });
        let entries = buffer_entries(&[&ray_buffer, &hit_buffer]);
        let group = gpu.device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("ray batch bind group"),
            layout: &self.layout,
            entries: &entries,
        });
        let pipeline = self.pipeline_for(gpu, scene)?;
        let dispatch = || {
            let mut encoder = gpu.device.create_command_encoder(&Default::default());
            {
                let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
                    label: Some("ray batch pass"),
                    timestamp_writes: None,
                });
                pass.set_pipeline(&pipeline);
                pass.set_bind_group(SCENE_GROUP, &scene.bind_group, &[]);
                pass.set_bind_group(PASS_GROUP, &group, &[]);
                if let Some(driver) = &driver_group {
                    pass.set_bind_group(driver_accel::DRIVER_GROUP, driver, &[]);
                }
                // At most 65,535 workgroups: up to 4 million rays per batch.
                let groups = (rays.len() as u32).div_ceil(RAY_BATCH_WORKGROUP);
                pass.dispatch_workgroups(groups, 1, 1);
            }
            gpu.queue.submit([encoder.finish()]);
        };
        if timed {
            // The upload and the hit buffer's zero fill ride on this one.
            dispatch();
        }
        gpu.wait_idle()?;
        let start = std::time::Instant::now();
        dispatch();
        gpu.wait_idle()?;
        let seconds = start.elapsed().as_secs_f64();
        let bytes = readback::copy_and_read(gpu, &hit_buffer, hit_bytes, "ray batch readback")?;
        gpu.take_errors()?;
        Ok((bytemuck::cast_slice(&bytes).to_vec(), seconds))
    }
}
