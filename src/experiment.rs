//! `celray experiment sampling`: how fast each sub-pixel pattern converges.
//! Renders an edge scene and a one-dimensional zone plate with every pattern
//! at 1 to 256 samples, measures the RMS error against a 1024-sample
//! jittered reference, and plots error against samples on log-log axes with
//! the fitted slopes in the legend.

use std::path::PathBuf;

use anyhow::Context;
use plotters::prelude::*;

use celray::capture::render_frame;
use celray::gpu::Gpu;
use celray::render::{RenderMode, RenderSettings};
use celray::sampling::PixelPattern;
use celray::scene::Scene;

#[derive(Debug, clap::Args)]
pub struct ExperimentArgs {
    /// Which experiment: sampling.
    pub name: String,
    /// Output plot (.png).
    #[arg(short, long)]
    pub output: PathBuf,
    /// Image size of the test scenes (square).
    #[arg(long, default_value_t = 128)]
    pub size: u32,
}

const SPP: [u32; 9] = [1, 2, 4, 8, 16, 32, 64, 128, 256];

/// A black card whose slanted edge crosses a white image
/// ([`celray::fixtures::slanted_card`], the scene the edge tests use).
fn edge_scene(size: u32) -> anyhow::Result<Scene> {
    Ok(celray::fixtures::slanted_card(size, 3.0, 17.0)?)
}

/// A one-dimensional zone plate: black bars whose n-th edge sits at
/// c * sqrt(n), so the frequency grows linearly across the image, from
/// well below to above the pixel rate.
pub fn zone_plate_scene(size: u32) -> anyhow::Result<Scene> {
    let half_width = 4.0 * 15f64.to_radians().tan();
    let pixel = 2.0 * half_width / f64::from(size);
    // Edge spacing c^2 / (2 x) reaches half a pixel at the right border.
    let c = (pixel * 2.0 * half_width).sqrt();
    let mut instances = String::new();
    let mut n = 0u32;
    loop {
        let (x0, x1) = (c * f64::from(n).sqrt(), c * f64::from(n + 1).sqrt());
        if x0 > 2.0 * half_width {
            break;
        }
        let centre = x0 + (x1 - x0) * 0.5 - half_width;
        instances += &format!(
            "(shape: \"bar\", material: \"black\", transform: (translate: ({centre:.6}, 0.0, 0.0), rotate_deg: (90.0, 0.0, 0.0), scale: ({:.6}, 1.0, 1.0))),\n",
            (x1 - x0) * 0.5
        );
        n += 2;
    }
    let ron = format!(
        r#"(version: 1,
            camera: (eye: (0.0, 0.0, 4.0), target: (0.0, 0.0, 0.0), up: (0.0, 1.0, 0.0), fov_y_deg: 30.0, width: {size}, height: {size}),
            ambient: (0.0, 0.0, 0.0), background: (1.0, 1.0, 1.0), lights: [],
            materials: {{ "black": (base_color: (0.0, 0.0, 0.0), specular_color: (0.0, 0.0, 0.0), model: BlinnPhong) }},
            shapes: {{ "bar": Plane(Quad(half_size: (1.0, 3.0))) }},
            instances: [{instances}],
        )"#
    );
    Ok(Scene::from_ron_str(
        &ron,
        "zone plate",
        std::path::Path::new("."),
    )?)
}

fn render_linear(
    gpu: &Gpu,
    scene: &Scene,
    pattern: PixelPattern,
    spp: u32,
) -> anyhow::Result<Vec<f32>> {
    let settings = RenderSettings {
        width: scene.camera.width,
        height: scene.camera.height,
        spp,
        pattern,
        mode: RenderMode::Raster,
        ..RenderSettings::default()
    };
    let frame = render_frame(gpu, scene.clone(), settings, true, |_, _| {})?;
    frame.linear.context("no linear image")
}

fn rms(a: &[f32], b: &[f32]) -> f64 {
    let sum: f64 = a
        .chunks(4)
        .zip(b.chunks(4))
        .map(|(p, q)| (f64::from(p[0]) - f64::from(q[0])).powi(2))
        .sum();
    (sum / (a.len() / 4) as f64).sqrt()
}

/// Least-squares slope of ln(error) on ln(spp).
pub fn log_slope(points: &[(u32, f64)]) -> f64 {
    let xs: Vec<f64> = points.iter().map(|(s, _)| f64::from(*s).ln()).collect();
    let ys: Vec<f64> = points.iter().map(|(_, e)| e.max(1e-9).ln()).collect();
    let n = xs.len() as f64;
    let (mx, my) = (xs.iter().sum::<f64>() / n, ys.iter().sum::<f64>() / n);
    let num: f64 = xs.iter().zip(&ys).map(|(x, y)| (x - mx) * (y - my)).sum();
    let den: f64 = xs.iter().map(|x| (x - mx).powi(2)).sum();
    num / den
}

type Curves = Vec<(PixelPattern, Vec<(u32, f64)>)>;

fn measure(gpu: &Gpu, scene: &Scene) -> anyhow::Result<Curves> {
    let reference = render_linear(gpu, scene, PixelPattern::Jittered, 1024)?;
    PixelPattern::ALL
        .iter()
        .map(|&pattern| {
            let points = SPP
                .iter()
                .map(|&spp| {
                    Ok((
                        spp,
                        rms(&render_linear(gpu, scene, pattern, spp)?, &reference),
                    ))
                })
                .collect::<anyhow::Result<Vec<_>>>()?;
            Ok((pattern, points))
        })
        .collect()
}

pub fn run(gpu: &Gpu, args: &ExperimentArgs) -> anyhow::Result<()> {
    if args.name != "sampling" {
        anyhow::bail!(
            "experiment {:?}: the only experiment is `sampling`",
            args.name
        );
    }
    if args.output.extension().and_then(|e| e.to_str()) != Some("png") {
        anyhow::bail!("output {}: the plot is a .png file", args.output.display());
    }
    plotters::style::register_font(
        "sans-serif",
        FontStyle::Normal,
        epaint_default_fonts::HACK_REGULAR,
    )
    .map_err(|_| anyhow::anyhow!("the built-in font did not load"))?;
    let panels = [
        ("edge", measure(gpu, &edge_scene(args.size)?)?),
        (
            "1D zone plate",
            measure(gpu, &zone_plate_scene(args.size)?)?,
        ),
    ];
    for (name, curves) in &panels {
        for (pattern, points) in curves {
            out!(
                "{name:<14} {:<9} slope {:+.2}  errors {:?}",
                pattern.name(),
                log_slope(points),
                points
                    .iter()
                    .map(|(_, e)| format!("{e:.4}"))
                    .collect::<Vec<_>>()
            );
        }
    }
    let root = BitMapBackend::new(&args.output, (1200, 520)).into_drawing_area();
    root.fill(&WHITE)?;
    let colours = [RED, BLUE, GREEN, MAGENTA];
    for ((name, curves), area) in panels.iter().zip(root.split_evenly((1, 2))) {
        let max = curves
            .iter()
            .flat_map(|(_, p)| p.iter().map(|(_, e)| *e))
            .fold(1e-6, f64::max)
            * 1.5;
        let min = curves
            .iter()
            .flat_map(|(_, p)| p.iter().map(|(_, e)| *e))
            .fold(f64::MAX, f64::min)
            .max(1e-6)
            / 1.5;
        let mut chart = ChartBuilder::on(&area)
            .caption(
                format!("{name}: RMS error vs samples per pixel"),
                ("sans-serif", 20),
            )
            .margin(12)
            .x_label_area_size(36)
            .y_label_area_size(56)
            .build_cartesian_2d((1f64..256f64).log_scale(), (min..max).log_scale())?;
        chart
            .configure_mesh()
            .x_desc("samples per pixel")
            .y_desc("RMS error")
            .draw()?;
        for ((pattern, points), colour) in curves.iter().zip(colours) {
            let series: Vec<(f64, f64)> = points.iter().map(|(s, e)| (f64::from(*s), *e)).collect();
            chart
                .draw_series(LineSeries::new(series.clone(), colour.stroke_width(2)))?
                .label(format!(
                    "{} (slope {:+.2})",
                    pattern.name(),
                    log_slope(points)
                ))
                .legend(move |(x, y)| {
                    PathElement::new(vec![(x, y), (x + 18, y)], colour.stroke_width(2))
                });
            chart.draw_series(series.iter().map(|p| Circle::new(*p, 3, colour.filled())))?;
        }
        chart
            .configure_series_labels()
            .background_style(WHITE.mix(0.85))
            .border_style(BLACK)
            .draw()?;
    }
    root.present()?;
    out!("wrote {}", args.output.display());
    Ok(())
}
