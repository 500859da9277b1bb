//! `celray bench accel`: the driver's acceleration structures (wgpu ray
//! queries) beside celray's own BVH on the ray-throughput scenes: closest-hit
//! Mrays/s of the ray-batch kernel, the trace pass in raytrace mode, build
//! time and memory, and the per-sample top-level rebuild that motion blur
//! costs on the driver path.

use std::time::Instant;

use celray::gpu::shader::Traversal;
use celray::gpu::Gpu;
use celray::render::driver_accel::DriverAccel;
use celray::render::ray_batch::RayBatch;
use celray::render::{AccelChoice, RenderMode, RenderSettings, Renderer};
use celray::scene::Scene;

use super::report::{md, Report};
use super::{ball_grid, best_of, grid, ray_renderer, spot_scene, BenchArgs};

/// GPU milliseconds of the trace pass, raytrace mode, best of 3 samples.
fn trace_ms(gpu: &Gpu, scene: &Scene, args: &BenchArgs, accel: AccelChoice) -> anyhow::Result<f64> {
    let settings = RenderSettings {
        width: args.width,
        height: args.height,
        spp: 1 << 20,
        mode: RenderMode::Raytrace,
        accel,
        ..RenderSettings::default()
    };
    let mut r = Renderer::new(gpu, scene.clone(), settings)?;
    r.enable_pass_timing(gpu);
    best_of(|| {
        r.render_sample(gpu)?;
        let times = r.pass_times(gpu)?;
        Ok(times
            .iter()
            .find(|(n, _)| *n == "trace")
            .map_or(f64::NAN, |(_, ms)| *ms))
    })
}

fn row(
    gpu: &Gpu,
    name: &str,
    case: &str,
    scene: Scene,
    args: &BenchArgs,
    r: &Report,
) -> anyhow::Result<()> {
    let (renderer, software_build_ms, rays) =
        ray_renderer(gpu, scene.clone(), args, AccelChoice::Software)?;
    let buffers = renderer.scene_buffers();
    let software = RayBatch::new(gpu)?;
    let sw_s = best_of(|| Ok(software.trace_timed(gpu, buffers, &rays)?.1))?;
    let accel = &buffers.accel;
    let sw_bytes = accel.nodes.len() * 32
        + accel.triangles.len() * 96
        + accel.tlas_items.len() * 4
        + scene.instances.len() * 208;
    let sw_trace = trace_ms(gpu, &scene, args, AccelChoice::Software)?;
    let mib = |b: f64| b / (1024.0 * 1024.0);
    r.case(
        &format!("{case}_software"),
        sw_s * 1e3,
        Some(rays.len() as f64 / sw_s / 1e6),
        &[("ray_batch", sw_s * 1e3), ("trace", sw_trace)],
    );
    md!(r,
        "| {name} | software | {:.1} | {:.0} | - (the BVH bounds the whole motion) | BVH build + upload {:.0} | {:.1} (nodes, triangles, instances) | - |",
        rays.len() as f64 / sw_s / 1e6,
        sw_trace,
        software_build_ms,
        mib(sw_bytes as f64),
    );

    let mut driver = match DriverAccel::build(gpu, &scene, buffers) {
        Ok(d) => d,
        Err(reason) => {
            md!(
                r,
                "| {name} | driver | - | - | - | not run: {reason} | - | - |"
            );
            r.skipped(&format!("{case}_driver"), &reason.to_string());
            return Ok(());
        }
    };
    let batch = RayBatch::with_traversal(gpu, Traversal::Driver)?;
    let drv_s = best_of(|| Ok(batch.trace_driver_timed(gpu, buffers, &driver, &rays)?.1))?;
    let drv_trace = trace_ms(gpu, &scene, args, AccelChoice::Driver)?;
    // Motion blur on the driver path: the top level rebuilt per sample.
    let rebuild_ms = best_of(|| {
        let start = Instant::now();
        let mut encoder = gpu.device.create_command_encoder(&Default::default());
        driver.encode_motion(&mut encoder, &scene, 0.5);
        gpu.queue.submit([encoder.finish()]);
        gpu.wait_idle()?;
        Ok(start.elapsed().as_secs_f64() * 1e3)
    })?;
    let s = driver.stats;
    r.case(
        &format!("{case}_driver"),
        drv_s * 1e3,
        Some(rays.len() as f64 / drv_s / 1e6),
        &[
            ("ray_batch", drv_s * 1e3),
            ("trace", drv_trace),
            ("tlas_rebuild", rebuild_ms),
            ("build", s.build_ms),
        ],
    );
    md!(r,
        "| {name} | driver | {:.1} | {:.0} | {:.1} | {} BLAS + TLAS of {}: {:.0} | {:.1} inputs (+ driver-owned structures, size not reported by wgpu) | {:.2}x |",
        rays.len() as f64 / drv_s / 1e6,
        drv_trace,
        rebuild_ms,
        s.blas_count,
        s.instance_count,
        s.build_ms,
        mib(s.input_bytes as f64),
        sw_s / drv_s,
    );
    Ok(())
}

pub fn accel_suite(
    gpu: &Gpu,
    args: &BenchArgs,
    helmet: Option<&Scene>,
    r: &Report,
) -> anyhow::Result<()> {
    md!(
        r,
        "\n## Driver ray queries vs software BVH ({}x{}, one primary ray per pixel)\n",
        args.width,
        args.height
    );
    if !gpu.has_ray_queries() {
        md!(
            r,
            "adapter {} has no ray queries: the driver path is skipped",
            gpu.summary.name
        );
    }
    md!(r, "| scene | path | closest-hit Mrays/s | trace pass ms (raytrace) | TLAS rebuild ms (motion, per sample) | build ms | memory MiB | driver speed-up (closest hit) |");
    md!(r, "|---|---|---|---|---|---|---|---|");
    if let Some(helmet) = helmet {
        row(
            gpu,
            "FlightHelmet, anchor camera",
            "accel_helmet",
            helmet.clone(),
            args,
            r,
        )?;
    }
    row(
        gpu,
        "spot x 10,000",
        "accel_spot_10000",
        grid(&spot_scene(args)?, 10_000, 1.1),
        args,
        r,
    )?;
    row(
        gpu,
        "100 analytic spheres",
        "accel_spheres_100",
        ball_grid(args, 100)?,
        args,
        r,
    )
}
