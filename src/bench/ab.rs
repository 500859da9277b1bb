//! `bench scene --compare-shaders DIR`: one scene timed with two sets of
//! shaders in one process, frame by frame in turn. On a shared machine the
//! load moves by 20-40% within minutes, more than most kernel changes
//! gain, and two runs of `bench` minutes apart see different loads. Two
//! renderers alternating frames see the same load, so the ratio of each
//! pair of frames (B over A) stays near the change's own effect; its median
//! over the pairs is the figure. `bench rays --compare-shaders DIR` does
//! the same for the ray-batch kernel, one dispatch of each in turn.

use std::path::Path;

use celray::gpu::shader::ShaderOverrides;
use celray::gpu::Gpu;
use celray::render::ray_batch::RayBatch;
use celray::render::AccelChoice;
use celray::scene::Scene;

use super::report::{md, Report};
use super::{ray_renderer, BenchArgs, TimedRenderer, WARM_UP_FRAMES};

/// The median and quartiles of B / A over pairs of frames, and in how many
/// pairs B was the faster.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PairedRatio {
    pub median: f64,
    pub q1: f64,
    pub q3: f64,
    pub b_faster: usize,
    pub pairs: usize,
}

impl PairedRatio {
    /// From (A ms, B ms) pairs; None without a pair of positive times.
    pub fn of(pairs: &[(f64, f64)]) -> Option<PairedRatio> {
        let mut ratios: Vec<f64> = pairs
            .iter()
            .filter(|(a, b)| *a > 0.0 && *b > 0.0)
            .map(|(a, b)| b / a)
            .collect();
        if ratios.is_empty() {
            return None;
        }
        ratios.sort_by(f64::total_cmp);
        // Linear interpolation between order statistics (quantile q of n
        // values sits at position q (n - 1)).
        let quantile = |q: f64| {
            let pos = q * (ratios.len() - 1) as f64;
            let (lo, hi) = (pos.floor() as usize, pos.ceil() as usize);
            ratios[lo] + (ratios[hi] - ratios[lo]) * (pos - lo as f64)
        };
        Some(PairedRatio {
            median: quantile(0.5),
            q1: quantile(0.25),
            q3: quantile(0.75),
            b_faster: ratios.iter().filter(|r| **r < 1.0).count(),
            pairs: ratios.len(),
        })
    }
}

/// Times `scene` with the shaders in use (A: the built-in ones, or
/// `--shaders`) and with `dir`'s (B), `args.frames` pairs of frames, and
/// reports per pass and for the whole frame: the fastest frame of each and
/// the paired ratio B / A.
pub fn compare_shaders(
    gpu: &Gpu,
    args: &BenchArgs,
    (path, scene): (&Path, Scene),
    dir: &Path,
    r: &Report,
) -> anyhow::Result<()> {
    let b_shaders = ShaderOverrides::read_given_dir(dir, "--compare-shaders")?;
    // Passes read their shader files when they are created.
    let mut a = TimedRenderer::new(gpu, scene.clone(), args.mode, args)?;
    let a_shaders = gpu.shader_overrides();
    gpu.set_shader_overrides(Some(b_shaders));
    let b = TimedRenderer::new(gpu, scene, args.mode, args);
    gpu.set_shader_overrides(a_shaders.map(|s| (*s).clone()));
    let mut b = b?;
    for _ in 0..WARM_UP_FRAMES {
        a.frame(gpu)?;
        b.frame(gpu)?;
    }
    // Names in the order first seen; per name, the (A, B) pairs.
    let mut series: Vec<(&'static str, Vec<(f64, f64)>)> = vec![("frame", Vec::new())];
    for i in 0..args.frames {
        // Each goes first in every other pair, so neither always runs
        // just after the other's work.
        let ((a_ms, a_passes), (b_ms, b_passes)) = if i % 2 == 0 {
            let a = a.frame(gpu)?;
            (a, b.frame(gpu)?)
        } else {
            let b = b.frame(gpu)?;
            (a.frame(gpu)?, b)
        };
        series[0].1.push((a_ms, b_ms));
        for (name, a_pass) in &a_passes {
            let Some((_, b_pass)) = b_passes.iter().find(|(n, _)| n == name) else {
                continue;
            };
            match series.iter_mut().find(|(n, _)| n == name) {
                Some((_, pairs)) => pairs.push((*a_pass, *b_pass)),
                None => series.push((name, vec![(*a_pass, *b_pass)])),
            }
        }
    }
    md!(
        r,
        "\n## {} ({}x{}, {} mode): A = {}, B = {}\n",
        path.display(),
        args.width,
        args.height,
        args.mode.name(),
        shaders_name(args),
        dir.display()
    );
    paired_table(r, "scene_ab", args.frames, &series);
    Ok(())
}

/// `bench rays --compare-shaders DIR`: each ray case's batch (`cases`:
/// name and scene) traced by the ray-batch kernel built from the shaders
/// in use (A) and from `dir`'s (B), `args.frames` pairs of dispatches in
/// turn, the same rays and scene buffers for both.
pub fn compare_ray_shaders(
    gpu: &Gpu,
    args: &BenchArgs,
    cases: Vec<(&'static str, Scene)>,
    dir: &Path,
    r: &Report,
) -> anyhow::Result<()> {
    let b_shaders = ShaderOverrides::read_given_dir(dir, "--compare-shaders")?;
    let a = RayBatch::new(gpu)?;
    let a_shaders = gpu.shader_overrides();
    gpu.set_shader_overrides(Some(b_shaders));
    let b = RayBatch::new(gpu);
    gpu.set_shader_overrides(a_shaders.map(|s| (*s).clone()));
    let b = b?;
    md!(
        r,
        "\n## Ray batches ({}x{} primary rays): A = {}, B = {}\n",
        args.width,
        args.height,
        shaders_name(args),
        dir.display()
    );
    let mut series = Vec::new();
    for (case, scene) in cases {
        let (renderer, _, rays) = ray_renderer(gpu, scene, args, AccelChoice::Software)?;
        let buffers = renderer.scene_buffers();
        // trace_timed runs each batch once untimed before the timed
        // dispatch: no separate warm-up.
        let time = |batch: &RayBatch| -> anyhow::Result<f64> {
            Ok(batch.trace_timed(gpu, buffers, &rays)?.1 * 1e3)
        };
        let mut pairs = Vec::new();
        for i in 0..args.frames {
            let pair = if i % 2 == 0 {
                let a_ms = time(&a)?;
                (a_ms, time(&b)?)
            } else {
                let b_ms = time(&b)?;
                (time(&a)?, b_ms)
            };
            pairs.push(pair);
        }
        series.push((case, pairs));
    }
    paired_table(r, "rays_ab", args.frames, &series);
    Ok(())
}

fn shaders_name(args: &BenchArgs) -> String {
    args.shaders
        .as_ref()
        .map_or("built-in shaders".to_string(), |d| d.display().to_string())
}

/// Per series, the fastest time of A and of B and the paired ratio B / A:
/// a Markdown table, and with `--json` one line (case `case`).
fn paired_table(r: &Report, case: &str, pairs: u32, series: &[(&'static str, Vec<(f64, f64)>)]) {
    md!(
        r,
        "| ms | A fastest | B fastest | B / A median | quartiles | B faster |"
    );
    md!(r, "|---|---|---|---|---|---|");
    let least = |pairs: &[(f64, f64)], pick: fn(&(f64, f64)) -> f64| {
        pairs.iter().map(pick).fold(f64::INFINITY, f64::min)
    };
    let mut ratios = serde_json::Map::new();
    let mut a_min = serde_json::Map::new();
    let mut b_min = serde_json::Map::new();
    for (name, pairs) in series {
        let Some(p) = PairedRatio::of(pairs) else {
            continue;
        };
        let (a_least, b_least) = (least(pairs, |x| x.0), least(pairs, |x| x.1));
        md!(
            r,
            "| {name} | {a_least:.2} | {b_least:.2} | {:.3} | {:.3}-{:.3} | {} of {} |",
            p.median,
            p.q1,
            p.q3,
            p.b_faster,
            p.pairs
        );
        let round = |x: f64| (x * 1e3).round() / 1e3;
        ratios.insert(name.to_string(), round(p.median).into());
        a_min.insert(name.to_string(), round(a_least).into());
        b_min.insert(name.to_string(), round(b_least).into());
    }
    if r.json {
        out!(
            "{}",
            serde_json::json!({
                "case": case,
                "pairs": pairs,
                "ratio": ratios,
                "a_min": a_min,
                "b_min": b_min,
                "driver": r.driver,
            })
        );
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Ratios 0.5, 1, 2 and 4 (in scrambled pairs): median between the
    /// middle two (1.5), quartiles at positions 0.75 and 2.25 of the
    /// sorted four, and one pair where B is faster.
    #[test]
    fn paired_ratio_quantiles() {
        let p = PairedRatio::of(&[(2.0, 4.0), (4.0, 2.0), (1.0, 4.0), (3.0, 3.0)]).unwrap();
        assert_eq!(p.pairs, 4);
        assert_eq!(p.b_faster, 1);
        assert!((p.median - 1.5).abs() < 1e-12, "{p:?}");
        assert!((p.q1 - (0.5 + 0.75 * 0.5)).abs() < 1e-12, "{p:?}");
        assert!((p.q3 - (2.0 + 0.25 * 2.0)).abs() < 1e-12, "{p:?}");
    }

    /// A pair with a zero or missing time says nothing about the ratio.
    #[test]
    fn paired_ratio_ignores_untimed_pairs() {
        assert_eq!(PairedRatio::of(&[(0.0, 3.0), (2.0, 0.0)]), None);
        let p = PairedRatio::of(&[(0.0, 3.0), (2.0, 3.0)]).unwrap();
        assert_eq!((p.pairs, p.median), (1, 1.5));
    }
}
