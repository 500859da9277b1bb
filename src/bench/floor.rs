//! The floor kernel (shaders/bench_floor.wgsl): a primary and a shadow ray
//! per pixel against N spheres by brute force, timed in the same run as the
//! real cases so that every trace figure can be stated as a ratio to it.

use wgpu::util::DeviceExt;

use celray::gpu::layout::{buffer_entries, BENCH_FLOOR_LAYOUT};
use celray::gpu::timer::GpuTimer;
use celray::gpu::{shader, Gpu};

#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct FloorParams {
    size_px: [u32; 2],
    sphere_count: u32,
    tan_half_fov: f32,
}

/// `n` spheres on a square grid filling the view of the kernel's camera
/// (eye at z = 5 looking down -z, 40 degree vertical field of view).
fn spheres(n: u32) -> Vec<[f32; 4]> {
    let side = (n as f32).sqrt().ceil() as u32;
    let extent = 3.2; // the grid spans about the view's height at z = 0
    let step = extent / side as f32;
    (0..n)
        .map(|i| {
            let (x, y) = ((i % side) as f32, (i / side) as f32);
            [
                (x + 0.5) * step - extent * 0.5,
                (y + 0.5) * step - extent * 0.5,
                0.0,
                step * 0.45,
            ]
        })
        .collect()
}

/// GPU milliseconds (median of `frames` dispatches, after one warm-up; wall
/// time per dispatch where the adapter has no timestamp queries) of the floor
/// kernel against `n` spheres at `width` x `height`.
pub fn floor_ms(gpu: &Gpu, width: u32, height: u32, n: u32, frames: u32) -> anyhow::Result<f64> {
    let module = shader::create_module(gpu, "bench_floor.wgsl")?;
    let layout = gpu
        .device
        .create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("floor layout"),
            entries: &BENCH_FLOOR_LAYOUT,
        });
    let pipeline_layout = gpu
        .device
        .create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("floor pipeline layout"),
            bind_group_layouts: &[Some(&layout)],
            immediate_size: 0,
        });
    let pipeline = gpu
        .device
        .create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
            label: Some("floor pipeline"),
            layout: Some(&pipeline_layout),
            module: &module,
            entry_point: Some("main"),
            compilation_options: Default::default(),
            cache: None,
        });
    let params = FloorParams {
        size_px: [width, height],
        sphere_count: n,
        tan_half_fov: 20f32.to_radians().tan(),
    };
    let uniform = gpu
        .device
        .create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("floor params"),
            contents: bytemuck::bytes_of(&params),
            usage: wgpu::BufferUsages::UNIFORM,
        });
    let sphere_buffer = gpu
        .device
        .create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("floor spheres"),
            contents: bytemuck::cast_slice(&spheres(n)),
            usage: wgpu::BufferUsages::STORAGE,
        });
    let out = gpu.device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("floor output"),
        size: u64::from(width) * u64::from(height) * 4,
        usage: wgpu::BufferUsages::STORAGE,
        mapped_at_creation: false,
    });
    let group = gpu.device.create_bind_group(&wgpu::BindGroupDescriptor {
        label: Some("floor bind group"),
        layout: &layout,
        entries: &buffer_entries(&[&uniform, &sphere_buffer, &out]),
    });
    let mut timer = GpuTimer::new(gpu, "floor", ["floor"]);
    let mut times = Vec::new();
    for i in 0..=frames.max(1) {
        let start = std::time::Instant::now();
        let mut encoder = gpu.device.create_command_encoder(&Default::default());
        if let Some((t, _)) = &mut timer {
            t.begin();
        }
        {
            let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
                label: Some("floor pass"),
                timestamp_writes: timer
                    .as_mut()
                    .and_then(|(t, [floor])| t.compute_writes(*floor)),
            });
            pass.set_pipeline(&pipeline);
            pass.set_bind_group(0, &group, &[]);
            pass.dispatch_workgroups(width.div_ceil(8), height.div_ceil(8), 1);
        }
        if let Some((t, _)) = &mut timer {
            t.finish(&mut encoder);
        }
        gpu.queue.submit([encoder.finish()]);
        if let Some((t, _)) = &mut timer {
            t.after_submit();
        }
        gpu.wait_idle()?;
        let wall = start.elapsed().as_secs_f64() * 1e3;
        let ms = match &mut timer {
            Some((t, _)) => t.wait(gpu)?.first().map_or(wall, |(_, ms)| *ms),
            None => wall,
        };
        if i > 0 {
            times.push(ms);
        }
    }
    gpu.take_errors()?;
    times.sort_by(f64::total_cmp);
    Ok(times[times.len() / 2])
}
