//! The celray command line: headless rendering, adapter listing, benchmarks.

mod bench;

use std::path::{Path, PathBuf};

use anyhow::{bail, Context, Result};
use clap::{Args, Parser, Subcommand};

use celray::capture::{self, OutputFormat};
use celray::gpu::{AdapterChoice, Gpu};
use celray::render::{RenderMode, RenderSettings, ToneMap};
use celray::sampling::PixelPattern;
use celray::scene::{parse_shading_model, Scene};

#[derive(Parser)]
#[command(
    name = "celray",
    version,
    about = "Toon shading, CSG, instancing and accumulation-buffer effects on any Vulkan device"
)]
struct Cli {
    /// Adapter: auto (prefer a real GPU), software (lavapipe) or part of an
    /// adapter's name. Default: $CELRAY_ADAPTER, else auto.
    #[arg(long, global = true)]
    adapter: Option<String>,
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Render a scene headless to a PNG (sRGB) or EXR (linear HDR) file.
    Render(RenderArgs),
    /// List every adapter wgpu can see, with backend, type and driver.
    Adapters,
    /// Time the raster path on the default scene and on FlightHelmet.
    Bench(bench::BenchArgs),
}

#[derive(Args)]
struct RenderArgs {
    /// Scene file (.ron). Without it, the built-in default scene.
    scene: Option<PathBuf>,
    /// Output image: .png or .exr.
    #[arg(short, long)]
    output: PathBuf,
    /// Image width in pixels (default: the scene camera's).
    #[arg(long)]
    width: Option<u32>,
    /// Image height in pixels (default: the scene camera's).
    #[arg(long)]
    height: Option<u32>,
    /// Samples per pixel to accumulate.
    #[arg(long, default_value_t = 16)]
    spp: u32,
    /// Seed of the sample pattern: same seed, same image.
    #[arg(long, default_value_t = 0)]
    seed: u32,
    /// Sub-pixel pattern: regular, random, jittered or halton.
    #[arg(long, default_value = "jittered")]
    pattern: String,
    /// Override every material: blinn-phong, toon (4 bands) or toon:N.
    #[arg(long)]
    shading: Option<String>,
    /// How primary visibility is found: raster, hybrid or raytrace.
    #[arg(long, default_value = "hybrid")]
    mode: String,
    /// Mirror reflection bounces after the primary hit (hybrid, raytrace).
    #[arg(long, default_value_t = 3)]
    max_bounces: u32,
    /// Tone mapping: clamp or reinhard.
    #[arg(long, default_value = "clamp")]
    tone_map: String,
    /// Change one scene value, e.g. --set camera.fov_y_deg=30 (repeatable).
    #[arg(long = "set", value_name = "KEY=VALUE")]
    sets: Vec<String>,
    /// No progress bar.
    #[arg(short, long)]
    quiet: bool,
}

fn main() {
    env_logger::Builder::from_env(env_logger::Env::default().default_filter_or("warn")).init();
    let cli = Cli::parse();
    if let Err(e) = run(cli) {
        eprintln!("error: {e:#}");
        std::process::exit(1);
    }
}

fn adapter_choice(flag: &Option<String>) -> AdapterChoice {
    flag.as_deref()
        .map(AdapterChoice::parse)
        .unwrap_or_else(AdapterChoice::from_env)
}

fn run(cli: Cli) -> Result<()> {
    match cli.command {
        Command::Adapters => {
            let adapters = celray::gpu::list_adapters();
            if adapters.is_empty() {
                bail!("no adapters found; install lavapipe with `sudo apt-get install -y mesa-vulkan-drivers libvulkan1`");
            }
            for a in adapters {
                println!("{}\t{}\t{}\t{}", a.name, a.backend, a.device_type, a.driver);
            }
            Ok(())
        }
        Command::Render(args) => render(args, &adapter_choice(&cli.adapter)),
        Command::Bench(args) => {
            let gpu = Gpu::new_headless(&adapter_choice(&cli.adapter))?;
            bench::run(&gpu, &args)
        }
    }
}

fn load_scene(path: Option<&Path>) -> Result<Scene> {
    Ok(match path {
        Some(p) => Scene::load(p)?,
        None => Scene::builtin_default(),
    })
}

fn render(args: RenderArgs, adapter: &AdapterChoice) -> Result<()> {
    let format = OutputFormat::from_path(&args.output)?;
    if let Some(scene_path) = &args.scene {
        if same_file(scene_path, &args.output) {
            bail!(
                "output {} is the scene file; refusing to overwrite an input",
                args.output.display()
            );
        }
    }
    let mut scene = load_scene(args.scene.as_deref())?;
    for set in &args.sets {
        let (key, value) = set
            .split_once('=')
            .with_context(|| format!("--set {set:?}: expected KEY=VALUE"))?;
        scene.apply_override(key.trim(), value.trim())?;
    }
    if let Some(model) = &args.shading {
        scene.override_shading(&parse_shading_model(model)?);
    }
    let mut settings = RenderSettings::for_camera(&scene.camera);
    settings.width = args.width.unwrap_or(settings.width);
    settings.height = args.height.unwrap_or(settings.height);
    if settings.width == 0 || settings.height == 0 {
        bail!(
            "image size {}x{} is empty: width and height must be at least 1",
            settings.width,
            settings.height
        );
    }
    if args.spp == 0 {
        bail!("--spp 0: at least one sample per pixel is needed");
    }
    settings.spp = args.spp;
    settings.seed = args.seed;
    settings.pattern = PixelPattern::parse(&args.pattern).with_context(|| {
        format!(
            "--pattern {:?}: expected regular, random, jittered or halton",
            args.pattern
        )
    })?;
    settings.mode = RenderMode::parse(&args.mode).with_context(|| {
        format!(
            "--mode {:?}: expected raster, hybrid or raytrace",
            args.mode
        )
    })?;
    settings.max_bounces = args.max_bounces;
    settings.tone_map = ToneMap::parse(&args.tone_map)
        .with_context(|| format!("--tone-map {:?}: expected clamp or reinhard", args.tone_map))?;

    let gpu = Gpu::new_headless(adapter)?;
    let bar = if args.quiet || settings.spp < 2 {
        indicatif::ProgressBar::hidden()
    } else {
        let bar = indicatif::ProgressBar::new(u64::from(settings.spp));
        bar.set_style(
            indicatif::ProgressStyle::with_template(
                "{msg} [{bar:30}] {pos}/{len} samples {elapsed}",
            )
            .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
        );
        bar.set_message("rendering");
        bar
    };
    let frame = capture::render_frame(
        &gpu,
        scene,
        settings,
        format == OutputFormat::Exr,
        |done, _| bar.set_position(u64::from(done)),
    )?;
    bar.finish_and_clear();
    capture::save(&frame, &args.output)?;
    if !args.quiet {
        eprintln!(
            "wrote {} ({}x{}, {})",
            args.output.display(),
            frame.width,
            frame.height,
            gpu.summary.name
        );
    }
    Ok(())
}

fn same_file(a: &Path, b: &Path) -> bool {
    match (a.canonicalize(), b.canonicalize()) {
        (Ok(a), Ok(b)) => a == b,
        _ => false,
    }
}
