//! The celray command line: the live app (default), headless rendering,
//! shading comparison, adapter listing, benchmarks, the sampling
//! experiment.

/// `println!` for what a command prints on standard output. A reader that
/// stops early (`celray bench --json | head -1`) ends the command quietly
/// with success, where `println!` would panic on the closed pipe; any other
/// write error ends it with a message and exit status 1.
macro_rules! out {
    ($($arg:tt)*) => {
        $crate::print_line(format_args!($($arg)*))
    };
}

mod bench;
mod experiment;

/// What `out!` runs: one line to standard output.
fn print_line(text: std::fmt::Arguments) {
    use std::io::Write;
    let mut stdout = std::io::stdout().lock();
    if let Err(e) = writeln!(stdout, "{text}").and_then(|()| stdout.flush()) {
        if e.kind() == std::io::ErrorKind::BrokenPipe {
            std::process::exit(0);
        }
        eprintln!("error: cannot write to standard output: {e}");
        std::process::exit(1);
    }
}

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

use anyhow::{bail, Context, Result};
use clap::builder::PossibleValue;
use clap::{Args, Parser, Subcommand, ValueEnum};

use celray::capture::{self, OutputFormat};
use celray::gpu::{AdapterChoice, Gpu};
use celray::render::{
    AccelChoice, RenderMode, RenderSettings, Temporal, ToneMap, MAX_BOUNCES, MAX_IMAGE_SAMPLES,
    MAX_SPP,
};
use celray::sampling::PixelPattern;
use celray::scene::{parse_shading_model, CameraPath, Scene, MAX_IMAGE_SIZE};

/// Most frames `celray bench --frames` times per case: the median of a
/// thousand frames is as steady as it gets, and on the CPU driver a
/// thousand frames of one case already take minutes.
const MAX_BENCH_FRAMES: u32 = 1000;

/// Most frames `celray view --exit-after-frames` renders: about half an
/// hour at 60 frames a second.
#[cfg(feature = "app")]
const MAX_EXIT_AFTER_FRAMES: u64 = 100_000;

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
    /// Acceleration structure rays walk: auto, software (celray's own BVH)
    /// or driver (the driver's, through ray queries; falls back to software
    /// with a notice where it cannot run). Used by render, compare, view and
    /// bench.
    #[arg(long, global = true, default_value = "auto")]
    accel: String,
    /// Without a command: `view` on the built-in default scene.
    #[command(subcommand)]
    command: Option<Command>,
}

#[derive(Subcommand)]
enum Command {
    /// Open the live app: a window with camera controls, a settings panel
    /// and side-by-side views (the default command).
    #[cfg(feature = "app")]
    View(ViewArgs),
    /// Render a scene headless to a PNG (sRGB) or EXR (linear HDR) file.
    Render(RenderArgs),
    /// Render a scene with several shading models (headless), write a
    /// labelled contact sheet and print FLIP and PSNR for each pair.
    Compare(CompareArgs),
    /// List every adapter wgpu can see, with backend, type and driver.
    Adapters,
    /// Measure and plot how each sub-pixel pattern converges
    /// (`celray experiment sampling -o plot.png`).
    Experiment(experiment::ExperimentArgs),
    /// Benchmarks: raster frames, ray throughput, effects (see README).
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
    /// Samples per pixel to accumulate (1 to 65536; width x height x spp
    /// at most 2^37). Ctrl+C stops early and writes the samples so far.
    #[arg(long, default_value_t = 16)]
    spp: u32,
    #[command(flatten)]
    image: ImageArgs,
    /// Override every material: blinn-phong, toon (4 bands) or toon:N.
    #[arg(long)]
    shading: Option<String>,
    /// How primary visibility is found.
    #[arg(long, value_enum, default_value_t = RenderMode::Hybrid)]
    mode: RenderMode,
    /// Mirror reflection bounces after the primary hit (hybrid, raytrace;
    /// at most 16).
    #[arg(long, default_value_t = 3)]
    max_bounces: u32,
    /// A scripted camera path (.ron): render frames 0..=K of it, one sample
    /// per frame as the app does, and write frame K (needs --frame).
    #[arg(long, value_name = "PATH", requires = "frame")]
    camera_path: Option<PathBuf>,
    /// With --camera-path: the frame to write.
    #[arg(long, value_name = "K", requires = "camera_path")]
    frame: Option<u32>,
    /// With --camera-path: off (every moving frame one fresh sample),
    /// reproject (blend into the reprojected history, as the app does) or
    /// blend (reprojected without rejection, for comparison).
    #[arg(long, default_value = "off")]
    temporal: String,
    /// No progress bar.
    #[arg(short, long)]
    quiet: bool,
}

/// Options shared by `render`, `compare` and `view` (each has its own
/// `--spp`, whose default and meaning differ).
#[derive(Args)]
struct ImageArgs {
    /// Seed of the sample pattern: same seed, same image.
    #[arg(long, default_value_t = 0)]
    seed: u32,
    /// Sub-pixel pattern.
    #[arg(long, value_enum, default_value_t = PatternArg(PixelPattern::Jittered))]
    pattern: PatternArg,
    /// Tone mapping.
    #[arg(long, value_enum, default_value_t = ToneMap::Clamp)]
    tone_map: ToneMap,
    /// Change one scene value, e.g. --set camera.fov_y_deg=30 (repeatable).
    #[arg(long = "set", value_name = "KEY=VALUE")]
    sets: Vec<String>,
}

impl ImageArgs {
    /// `settings` with this seed, pattern and tone mapping.
    fn apply(&self, settings: RenderSettings) -> RenderSettings {
        RenderSettings {
            seed: self.seed,
            pattern: self.pattern.0,
            tone_map: self.tone_map,
            ..settings
        }
    }
}

/// clap's view of [`PixelPattern`], whose names live in `sampling` (kept
/// free of clap): the possible values are `PixelPattern::ALL` by
/// `PixelPattern::name`.
#[derive(Clone, Copy)]
struct PatternArg(PixelPattern);

/// Every pattern, wrapped for clap, in `PixelPattern::ALL`'s order.
const PATTERN_ARGS: [PatternArg; PixelPattern::ALL.len()] = {
    let mut out = [PatternArg(PixelPattern::ALL[0]); PixelPattern::ALL.len()];
    let mut i = 0;
    while i < out.len() {
        out[i] = PatternArg(PixelPattern::ALL[i]);
        i += 1;
    }
    out
};

impl ValueEnum for PatternArg {
    fn value_variants<'a>() -> &'a [Self] {
        &PATTERN_ARGS
    }

    fn to_possible_value(&self) -> Option<PossibleValue> {
        Some(PossibleValue::new(self.0.name()))
    }
}

/// `"a, b or c"`: the names of every value of a settings enum, for messages
/// about flags parsed after clap (exit status 1 rather than clap's 2).
fn one_of(names: impl IntoIterator<Item = &'static str>) -> String {
    let names: Vec<&str> = names.into_iter().collect();
    match names.split_last() {
        Some((last, rest)) if !rest.is_empty() => format!("{} or {last}", rest.join(", ")),
        Some((last, _)) => last.to_string(),
        None => String::new(),
    }
}

#[derive(Args)]
struct CompareArgs {
    /// Scene file (.ron). Without it, the built-in default scene.
    scene: Option<PathBuf>,
    /// Contact sheet to write (.png).
    #[arg(short, long)]
    output: PathBuf,
    /// Comma-separated views: blinn-phong, toon, toon:N, or scene (the
    /// scene's own materials).
    #[arg(long, default_value = "blinn-phong,toon:4")]
    views: String,
    /// Width of each view in pixels (default: the scene camera's).
    #[arg(long)]
    width: Option<u32>,
    /// Height of each view in pixels (default: the scene camera's).
    #[arg(long)]
    height: Option<u32>,
    /// Samples per pixel to accumulate (1 to 65536).
    #[arg(long, default_value_t = 16)]
    spp: u32,
    #[command(flatten)]
    image: ImageArgs,
    /// Print the report as JSON on stdout.
    #[arg(long)]
    json: bool,
}

#[cfg(feature = "app")]
#[derive(Args)]
struct ViewArgs {
    /// Scene file (.ron), watched for changes. Without it, the built-in
    /// default scene.
    scene: Option<PathBuf>,
    /// Comma-separated views (at most 4): scene, blinn-phong, toon, toon:N.
    #[arg(long, default_value = "scene")]
    views: String,
    /// single, split, wipe or grid (default: from the number of views).
    #[arg(long)]
    layout: Option<String>,
    /// Window width in logical pixels.
    #[arg(long, default_value_t = 1280)]
    width: u32,
    /// Window height in logical pixels.
    #[arg(long, default_value_t = 720)]
    height: u32,
    /// Sample target of the progressive display (1 to 65536).
    #[arg(long, default_value_t = 64)]
    spp: u32,
    #[command(flatten)]
    image: ImageArgs,
    /// Start with uncapped frames (vsync off).
    #[arg(long)]
    no_vsync: bool,
    /// Render this many frames (at most 100000), then exit (for tests and
    /// benchmarks). Counted from the first frame that shows every view
    /// (once their shaders have compiled).
    #[arg(long, value_name = "N")]
    exit_after_frames: Option<u64>,
    /// With --exit-after-frames: save the window's content (panel
    /// included) to this PNG before exiting.
    #[arg(long, value_name = "PATH", requires = "exit_after_frames")]
    screenshot: Option<PathBuf>,
    /// Print frame-time statistics at exit.
    #[arg(long)]
    report_frame_times: bool,
    /// Folder for F12 and panel screenshots.
    #[arg(long, default_value = ".")]
    screenshot_dir: PathBuf,
    /// Do not watch the scene file and shaders for changes.
    #[arg(long)]
    no_watch: bool,
    /// While the camera moves: reproject (blend into the reprojected
    /// history), off (one fresh sample per frame) or blend (no rejection).
    #[arg(long, default_value = "reproject")]
    temporal: String,
    /// A scripted camera path (.ron): frame N shows its camera at frame N
    /// (for tests and benchmarks, with --exit-after-frames).
    #[arg(long, value_name = "PATH")]
    camera_path: Option<PathBuf>,
}

/// An interrupted render: said as is, exit status 130 (as for SIGINT).
#[derive(Debug, thiserror::Error)]
#[error("{0}")]
struct Interrupted(String);

fn main() {
    quiet_device_select_layer();
    env_logger::Builder::from_env(env_logger::Env::default().default_filter_or("warn")).init();
    // Every refusal exits 1, a command line clap cannot parse included
    // (clap's own default is 2); --help and --version exit 0.
    let cli = Cli::try_parse().unwrap_or_else(|e| {
        let _ = e.print();
        std::process::exit(if e.use_stderr() { 1 } else { 0 });
    });
    if let Err(e) = run(cli) {
        if let Some(interrupted) = e.downcast_ref::<Interrupted>() {
            eprintln!("{interrupted}");
            std::process::exit(130);
        }
        eprintln!("error: {e:#}");
        std::process::exit(1);
    }
}

/// Mesa's device-select Vulkan layer asks the Wayland compositor which GPU
/// drives the display. Without a usable `XDG_RUNTIME_DIR` it cannot, and
/// libwayland prints "error: XDG_RUNTIME_DIR is invalid or not set in the
/// environment." (twice) although nothing failed. In exactly that case,
/// and only when the user has set none of the layer's own variables
/// (`NODEVICE_SELECT`, `MESA_VK_DEVICE_SELECT*`, `DRI_PRIME*`) and no X
/// display could answer instead, this turns the layer off with its own
/// switch (`NODEVICE_SELECT=1`) before any wgpu instance exists. celray
/// picks its adapter itself (`--adapter`); no driver message is filtered.
fn quiet_device_select_layer() {
    // The user's own switches for the layer, or an X display it can ask.
    let keep_layer = std::env::vars_os().any(|(name, value)| {
        let name = name.to_string_lossy();
        !value.is_empty()
            && (name == "NODEVICE_SELECT"
                || name == "DISPLAY"
                || name.starts_with("MESA_VK_DEVICE_SELECT")
                || name.starts_with("DRI_PRIME"))
    });
    let absolute = |name: &str| std::env::var_os(name).is_some_and(|v| Path::new(&v).is_absolute());
    // libwayland needs an absolute XDG_RUNTIME_DIR unless it is handed a
    // socket or the socket is named by an absolute path.
    let wayland_reachable = absolute("XDG_RUNTIME_DIR")
        || absolute("WAYLAND_DISPLAY")
        || std::env::var_os("WAYLAND_SOCKET").is_some();
    if !keep_layer && !wayland_reachable {
        // Single-threaded here: main() calls this first.
        std::env::set_var("NODEVICE_SELECT", "1");
    }
}

/// Refuses an image size or sample count past celray's bounds, naming the
/// bound.
fn check_counts(width: u32, height: u32, spp: u32) -> Result<()> {
    if width == 0 || height == 0 {
        bail!("image size {width}x{height} is empty: width and height must be at least 1");
    }
    for (what, size) in [("width", width), ("height", height)] {
        if size > MAX_IMAGE_SIZE {
            bail!("image {what} {size} is over celray's bound of {MAX_IMAGE_SIZE} pixels");
        }
    }
    if spp == 0 {
        bail!("--spp 0: at least one sample per pixel is needed");
    }
    if spp > MAX_SPP {
        bail!(
            "--spp {spp} is over celray's bound of {MAX_SPP} samples per pixel: there the \
             noise left is under one 8-bit level, and the float accumulator keeps only about \
             8 bits of each further sample"
        );
    }
    let total = u64::from(width) * u64::from(height) * u64::from(spp);
    if total > MAX_IMAGE_SAMPLES {
        bail!(
            "{width}x{height} pixels at {spp} spp is {total} samples, over celray's bound of \
             {MAX_IMAGE_SAMPLES} (2^37) samples per image, e.g. 1920x1080 at 65536 spp or \
             3840x2160 at 16384 spp: lower the sample count or the image size"
        );
    }
    Ok(())
}

fn adapter_choice(flag: &Option<String>) -> AdapterChoice {
    flag.as_deref()
        .map(AdapterChoice::parse)
        .unwrap_or_else(AdapterChoice::from_env)
}

fn run(cli: Cli) -> Result<()> {
    let accel = AccelChoice::parse(&cli.accel).with_context(|| {
        format!(
            "--accel {:?}: expected {}",
            cli.accel,
            one_of(AccelChoice::ALL.map(AccelChoice::name))
        )
    })?;
    let Some(command) = cli.command else {
        #[cfg(feature = "app")]
        {
            let Some(Command::View(args)) = Cli::try_parse_from(["celray", "view"])?.command else {
                bail!("internal: no default view arguments");
            };
            return view(args, &adapter_choice(&cli.adapter), accel);
        }
        #[cfg(not(feature = "app"))]
        bail!("this build has no window (built without the `app` feature); try `celray render --help`");
    };
    match command {
        #[cfg(feature = "app")]
        Command::View(args) => view(args, &adapter_choice(&cli.adapter), accel),
        Command::Compare(args) => compare(args, &adapter_choice(&cli.adapter), accel),
        Command::Adapters => {
            let adapters = celray::gpu::list_adapters();
            if adapters.is_empty() {
                bail!("no adapters found; install lavapipe with `sudo apt-get install -y mesa-vulkan-drivers libvulkan1`");
            }
            for a in adapters {
                let rq = if a.ray_queries {
                    "ray queries: yes"
                } else {
                    "ray queries: no"
                };
                let packets = if a.packet_walk {
                    "packet walk: yes"
                } else {
                    "packet walk: no"
                };
                out!(
                    "{}\t{}\t{}\t{}\t{rq}\t{packets}",
                    a.name,
                    a.backend,
                    a.device_type,
                    a.driver
                );
            }
            Ok(())
        }
        Command::Render(args) => render(args, &adapter_choice(&cli.adapter), accel),
        Command::Experiment(args) => {
            // Its largest render is the 1024-sample reference.
            check_counts(args.size, args.size, 1024)?;
            let gpu = Gpu::new_headless(&adapter_choice(&cli.adapter))?;
            experiment::run(&gpu, &args)
        }
        Command::Bench(args) => {
            if !(1..=MAX_BENCH_FRAMES).contains(&args.frames) {
                bail!(
                    "--frames {}: the benchmark times 1 to {MAX_BENCH_FRAMES} frames per case",
                    args.frames
                );
            }
            check_counts(args.width, args.height, 1)?;
            let gpu = Gpu::new_headless(&adapter_choice(&cli.adapter))?;
            bench::run(&gpu, &bench::BenchArgs { accel, ..args })
        }
    }
}

fn load_scene(path: Option<&Path>) -> Result<Scene> {
    Ok(match path {
        Some(p) => Scene::load(p)?,
        None => Scene::builtin_default(),
    })
}

fn render(args: RenderArgs, adapter: &AdapterChoice, accel: AccelChoice) -> Result<()> {
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
    apply_sets(&mut scene, &args.image.sets)?;
    refuse_scene_image_as_output(&scene, &args.output)?;
    if let Some(model) = &args.shading {
        scene.override_shading(&parse_shading_model(model)?);
    }
    let mut settings = args.image.apply(RenderSettings::for_camera(&scene.camera));
    settings.width = args.width.unwrap_or(settings.width);
    settings.height = args.height.unwrap_or(settings.height);
    check_counts(settings.width, settings.height, args.spp)?;
    if args.max_bounces > MAX_BOUNCES {
        bail!(
            "--max-bounces {} is over celray's bound of {MAX_BOUNCES} bounces",
            args.max_bounces
        );
    }
    settings.spp = args.spp;
    settings.mode = args.mode;
    settings.max_bounces = args.max_bounces;
    settings.accel = accel;
    settings.temporal = parse_temporal(&args.temporal)?;
    let path = match &args.camera_path {
        Some(p) => {
            if same_file(p, &args.output) {
                bail!(
                    "output {} is the camera path file; refusing to overwrite an input",
                    args.output.display()
                );
            }
            let path = CameraPath::load(p)?;
            path.check_up(&scene.camera)?;
            Some(path)
        }
        None => None,
    };
    if path.is_none() && settings.temporal != Temporal::Off {
        bail!(
            "--temporal {}: temporal accumulation needs a moving camera; give --camera-path and --frame",
            args.temporal
        );
    }

    // Ctrl+C stops between two samples and writes what is there; a second
    // Ctrl+C ends the process at once.
    let stop = Arc::new(AtomicBool::new(false));
    let handler_stop = Arc::clone(&stop);
    ctrlc::set_handler(move || {
        if handler_stop.swap(true, Ordering::SeqCst) {
            std::process::exit(130);
        }
    })
    .context("cannot install the Ctrl+C handler")?;

    let gpu = Gpu::new_headless(adapter)?;
    if let (Some(path), Some(last)) = (&path, args.frame) {
        let frame = capture::render_path_frame(
            &gpu,
            scene,
            settings,
            path,
            last,
            format == OutputFormat::Exr,
            |_, _| {},
        )?;
        capture::save(&frame, &args.output)?;
        if !args.quiet {
            eprintln!(
                "wrote {} (frame {last} of the camera path, {}x{}, {})",
                args.output.display(),
                frame.width,
                frame.height,
                gpu.summary.name
            );
        }
        return Ok(());
    }
    let bar = if args.quiet || settings.spp < 2 {
        indicatif::ProgressBar::hidden()
    } else {
        let bar = indicatif::ProgressBar::new(u64::from(settings.spp));
        bar.set_style(
            indicatif::ProgressStyle::with_template(
                "{msg} [{bar:30}] {pos}/{len} samples {elapsed}, about {eta} left",
            )
            .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
        );
        bar.set_message("rendering");
        bar
    };
    let mut estimate = EtaNote::new(!args.quiet);
    let spp = settings.spp;
    let rendered = capture::render_frame_until_stopped(
        &gpu,
        scene,
        settings,
        format == OutputFormat::Exr,
        |done, total| {
            bar.set_position(u64::from(done));
            if let Some(line) = estimate.after_sample(done, total) {
                if bar.is_hidden() {
                    eprintln!("{line}");
                } else {
                    bar.println(line);
                }
            }
        },
        &stop,
    )?;
    bar.finish_and_clear();
    let Some((frame, samples)) = rendered else {
        return Err(Interrupted(
            "interrupted before the first sample: nothing written".to_string(),
        )
        .into());
    };
    capture::save(&frame, &args.output)?;
    if samples < spp {
        return Err(Interrupted(format!(
            "interrupted after {samples} of {spp} samples: wrote {} ({}x{}, {samples} spp)",
            args.output.display(),
            frame.width,
            frame.height,
        ))
        .into());
    }
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

/// The one-line time estimate `render` prints once the first samples are
/// timed, for renders that will take a while.
struct EtaNote {
    /// Whether to say anything at all (not with --quiet).
    enabled: bool,
    /// When the first sample finished (it includes one-time start-up work,
    /// so the rate is measured from there).
    first_done: Option<Instant>,
}

impl EtaNote {
    /// Renders shorter than this get no note.
    const WORTH_SAYING: Duration = Duration::from_secs(10);
    /// Samples are timed for at least this long before estimating.
    const MEASURE: Duration = Duration::from_millis(500);

    fn new(enabled: bool) -> EtaNote {
        EtaNote {
            enabled,
            first_done: None,
        }
    }

    /// Called after sample `done` of `total`; returns the note once.
    fn after_sample(&mut self, done: u32, total: u32) -> Option<String> {
        if !self.enabled || done >= total {
            return None;
        }
        let Some(first) = self.first_done else {
            self.first_done = Some(Instant::now());
            return None;
        };
        let measured = first.elapsed();
        if done < 2 || measured < Self::MEASURE {
            return None;
        }
        self.enabled = false;
        let per_sample = measured / (done - 1);
        let left = per_sample
            .checked_mul(total - done)
            .unwrap_or(Duration::MAX);
        (left >= Self::WORTH_SAYING).then(|| {
            format!(
                "{total} samples at {:.1} ms each: about {} left (Ctrl+C stops and writes the image so far)",
                per_sample.as_secs_f64() * 1e3,
                indicatif::HumanDuration(left)
            )
        })
    }
}

fn parse_temporal(text: &str) -> Result<Temporal> {
    Temporal::parse(text).with_context(|| {
        format!(
            "--temporal {text:?}: expected {}",
            one_of(Temporal::ALL.map(Temporal::name))
        )
    })
}

/// Refuses `output` where it is one of the images `scene` reads (a
/// material's, or a mesh's own map): a render never replaces its inputs.
/// The scene file itself is checked before it is loaded.
fn refuse_scene_image_as_output(scene: &Scene, output: &Path) -> Result<()> {
    for image in celray::render::textures::scene_images(scene) {
        if same_file(&image.path, output) {
            bail!(
                "output {} is an image the scene reads ({}); refusing to overwrite an input",
                output.display(),
                image.source
            );
        }
    }
    Ok(())
}

fn same_file(a: &Path, b: &Path) -> bool {
    match (a.canonicalize(), b.canonicalize()) {
        (Ok(a), Ok(b)) => a == b,
        _ => false,
    }
}

/// Applies `--set KEY=VALUE` edits to `scene`.
fn apply_sets(scene: &mut Scene, sets: &[String]) -> Result<()> {
    for set in sets {
        let (key, value) = set
            .split_once('=')
            .with_context(|| format!("--set {set:?}: expected KEY=VALUE"))?;
        scene.apply_override(key.trim(), value.trim())?;
    }
    Ok(())
}

/// Settings from the shared flags, at `width` x `height` and `spp`.
fn image_settings(width: u32, height: u32, spp: u32, image: &ImageArgs) -> Result<RenderSettings> {
    check_counts(width, height, spp)?;
    Ok(image.apply(RenderSettings {
        width,
        height,
        spp,
        ..RenderSettings::default()
    }))
}

fn compare(args: CompareArgs, adapter: &AdapterChoice, accel: AccelChoice) -> Result<()> {
    use celray::compare::Comparison;
    use celray::view::ViewSpec;
    if OutputFormat::from_path(&args.output)? != OutputFormat::Png {
        bail!(
            "--output {}: the contact sheet is a .png file",
            args.output.display()
        );
    }
    if let Some(scene_path) = &args.scene {
        if same_file(scene_path, &args.output) {
            bail!(
                "output {} is the scene file; refusing to overwrite an input",
                args.output.display()
            );
        }
    }
    let views = ViewSpec::parse_list(&args.views)?;
    let mut scene = load_scene(args.scene.as_deref())?;
    apply_sets(&mut scene, &args.image.sets)?;
    refuse_scene_image_as_output(&scene, &args.output)?;
    let settings = image_settings(
        args.width.unwrap_or(scene.camera.width),
        args.height.unwrap_or(scene.camera.height),
        args.spp,
        &args.image,
    )?;
    let settings = RenderSettings { accel, ..settings };
    let gpu = Gpu::new_headless(adapter)?;
    let comparison = Comparison::run(&gpu, &scene, &settings, views, |_, _, _| {})?;
    comparison
        .sheet()
        .save_with_format(&args.output, image::ImageFormat::Png)
        .with_context(|| format!("cannot write {}", args.output.display()))?;
    if args.json {
        let json = comparison.json(&args.output.display().to_string());
        out!("{}", serde_json::to_string_pretty(&json)?);
    } else {
        out!("{}", comparison.text_report().trim_end_matches('\n'));
        eprintln!(
            "wrote {} ({} views of {}x{}, {})",
            args.output.display(),
            comparison.views.len(),
            settings.width,
            settings.height,
            gpu.summary.name
        );
    }
    Ok(())
}

#[cfg(feature = "app")]
fn view(args: ViewArgs, adapter: &AdapterChoice, accel: AccelChoice) -> Result<()> {
    use celray::app::{self, Layout, ViewOptions, WINDOW_VIEW_SLOTS};
    use celray::view::ViewSpec;
    let views = ViewSpec::parse_list(&args.views)?;
    if views.len() > WINDOW_VIEW_SLOTS {
        bail!(
            "--views {:?}: the window shows at most {WINDOW_VIEW_SLOTS} views (use `celray compare` for more)",
            args.views
        );
    }
    let layout = match &args.layout {
        Some(text) => Layout::parse(text)
            .with_context(|| format!("--layout {text:?}: expected single, split, wipe or grid"))?,
        None => Layout::for_count(views.len()),
    };
    if let Some(n) = args.exit_after_frames {
        if !(1..=MAX_EXIT_AFTER_FRAMES).contains(&n) {
            bail!("--exit-after-frames {n}: give 1 to {MAX_EXIT_AFTER_FRAMES} frames");
        }
    }
    if let Some(path) = &args.screenshot {
        if OutputFormat::from_path(path)? != OutputFormat::Png {
            bail!(
                "--screenshot {}: screenshots are .png files",
                path.display()
            );
        }
    }
    if !args.screenshot_dir.is_dir() {
        bail!(
            "--screenshot-dir {}: no such folder",
            args.screenshot_dir.display()
        );
    }
    let mut scene = load_scene(args.scene.as_deref())?;
    apply_sets(&mut scene, &args.image.sets)?;
    let settings = image_settings(
        scene.camera.width,
        scene.camera.height,
        args.spp,
        &args.image,
    )?;
    let mut settings = RenderSettings { accel, ..settings };
    settings.temporal = parse_temporal(&args.temporal)?;
    let camera_path = match &args.camera_path {
        Some(p) => {
            let path = CameraPath::load(p)?;
            path.check_up(&scene.camera)?;
            Some(path)
        }
        None => None,
    };
    let report_times = args.report_frame_times;
    let report = app::run(ViewOptions {
        scene,
        scene_path: args.scene.clone(),
        views,
        layout,
        settings,
        window_size: (args.width, args.height),
        vsync: !args.no_vsync,
        adapter: adapter.clone(),
        exit_after_frames: args.exit_after_frames,
        screenshot: args.screenshot.clone(),
        report_frame_times: report_times,
        screenshot_dir: args.screenshot_dir.clone(),
        watch: !args.no_watch,
        camera_path,
    })?;
    if report_times {
        let warmup = 10.min(report.frame_ms.len() / 4);
        match app::timing::summarize(&report.frame_ms, warmup) {
            Some((mean, median, p95, max)) => out!(
                "{} frames, {}x{} surface, {} view(s), adapter {}\n\
                 frame time (first {warmup} skipped): mean {mean:.2} ms, median {median:.2} ms, \
                 p95 {p95:.2} ms, max {max:.2} ms; {:.1} fps (from the mean)\n\
                 samples accumulated per view: {:?}",
                report.frames,
                report.surface_size.0,
                report.surface_size.1,
                report.views,
                report.adapter,
                1000.0 / mean,
                report.samples
            ),
            None => out!("{} frames: too few to time", report.frames),
        }
        let s = &report.startup;
        let at = |ms: Option<f64>| ms.map_or("never".to_string(), |ms| format!("{ms:.0} ms"));
        out!(
            "startup: first window frame after {}, every view shown after {}; \
             longest wait between window frames until then {:.0} ms",
            at(s.first_frame_ms),
            at(s.views_shown_ms),
            s.longest_wait_ms
        );
        if let Some(t) = app::timing::mean_pass_times(&report.pass_times) {
            out!(
                "GPU per frame (mean of {} timed frames that sampled, all views): raster {:.2} ms, \
                 trace {:.2} ms, outline+accumulate {:.2} ms, resolve {:.2} ms, copy {:.2} ms, \
                 egui {:.2} ms",
                report
                    .pass_times
                    .iter()
                    .filter(|t| t.views_sampled > 0)
                    .count(),
                t.raster_ms,
                t.trace_ms,
                t.accumulate_ms,
                t.resolve_ms,
                t.copy_ms,
                t.egui_ms
            );
        }
        if !report.ui_ms.is_empty() {
            let mean = report.ui_ms.iter().sum::<f64>() / report.ui_ms.len() as f64;
            out!("window CPU per frame (mean): egui {mean:.2} ms");
        }
    }
    if let Some(path) = &args.screenshot {
        if !args.report_frame_times {
            eprintln!("wrote {}", path.display());
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn counts_at_their_bounds_pass_and_one_past_is_refused() {
        assert!(check_counts(1, 1, MAX_SPP).is_ok());
        assert!(check_counts(1, 1, MAX_SPP + 1).is_err());
        assert!(check_counts(MAX_IMAGE_SIZE, 1, 1).is_ok());
        assert!(check_counts(MAX_IMAGE_SIZE + 1, 1, 1).is_err());
        assert!(check_counts(1, MAX_IMAGE_SIZE + 1, 1).is_err());
        // The per-image bound: exactly 2^37 samples pass, more do not; the
        // examples in the message pass.
        assert!(check_counts(8192, 8192, 2048).is_ok()); // 2^13 * 2^13 * 2^11
        assert!(check_counts(8192, 8192, 2049).is_err());
        assert!(check_counts(1920, 1080, MAX_SPP).is_ok());
        let most_4k = (MAX_IMAGE_SAMPLES / (3840 * 2160)) as u32;
        assert!(most_4k >= 16384);
        assert!(check_counts(3840, 2160, most_4k).is_ok());
        assert!(check_counts(3840, 2160, most_4k + 1).is_err());
        assert!(check_counts(0, 1, 1).is_err());
        assert!(check_counts(1, 1, 0).is_err());
        // Extreme values are refused, not overflowed.
        assert!(check_counts(u32::MAX, u32::MAX, u32::MAX).is_err());
    }
}
