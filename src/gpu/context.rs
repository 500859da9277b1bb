//! The wgpu instance, adapter choice and device, headless or for a window.

use std::sync::atomic::{AtomicBool, AtomicU32, Ordering};
use std::sync::{Arc, Mutex};

use crate::gpu::shader::ShaderOverrides;
use crate::gpu::uniform_tables::UNIFORM_TABLE_BYTES;
use crate::gpu::GpuError;

/// Which adapter to use: `auto`, `software` or a substring of the adapter name.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub enum AdapterChoice {
    /// Prefer a real GPU (discrete, then integrated), fall back to anything.
    #[default]
    Auto,
    /// The CPU adapter (lavapipe on Linux).
    Software,
    /// The first adapter whose name contains this text (case-insensitive).
    Named(String),
}

impl AdapterChoice {
    /// Parses `auto`, `software` or a name fragment.
    pub fn parse(text: &str) -> AdapterChoice {
        match text.trim() {
            "" | "auto" => AdapterChoice::Auto,
            "software" | "cpu" => AdapterChoice::Software,
            other => AdapterChoice::Named(other.to_string()),
        }
    }

    /// The choice from the `CELRAY_ADAPTER` environment variable, else `auto`.
    pub fn from_env() -> AdapterChoice {
        std::env::var("CELRAY_ADAPTER")
            .map(|v| AdapterChoice::parse(&v))
            .unwrap_or_default()
    }

    /// The adapter the test suite renders on: `CELRAY_ADAPTER` if set (a
    /// run on a GPU, say), else lavapipe (`software`), so that a plain
    /// `cargo test` gives the same images on every machine.
    pub fn for_tests() -> AdapterChoice {
        std::env::var("CELRAY_ADAPTER")
            .map(|v| AdapterChoice::parse(&v))
            .unwrap_or(AdapterChoice::Software)
    }
}

/// What was said of the adapter in use: for logs, stats lines and reports.
#[derive(Debug, Clone)]
pub struct AdapterSummary {
    pub name: String,
    pub backend: String,
    pub device_type: String,
    pub driver: String,
    /// Whether the adapter offers wgpu's ray queries
    /// (`Features::EXPERIMENTAL_RAY_QUERY`): the driver acceleration path.
    pub ray_queries: bool,
    /// Whether ray batches can walk the BVH as packets of 8
    /// (`shaders/lib/trace_packet.wgsl`, written for lavapipe's subgroups:
    /// a CPU adapter with `Features::SUBGROUP` and subgroups of 8 lanes).
    pub packet_walk: bool,
    /// How many threads the driver splits a compute dispatch among: on a
    /// CPU adapter (lavapipe) `LP_NUM_THREADS` where set, else the CPUs
    /// this process may run on, at most 32 (Mesa's `LP_MAX_THREADS`); 1 on
    /// a GPU. The trace and accumulate passes start
    /// [`LOOPING_GROUPS_PER_THREAD`] workgroups per thread on lavapipe
    /// from Mesa 25 ([`Gpu::set_looping_groups`]).
    pub dispatch_threads: u32,
}

/// Whether reading small tables by selection pays on this adapter
/// ([`Gpu::select_tables`]): lavapipe from Mesa 25, which skips a branch
/// none of a SIMD program's 8 lanes takes. Mesa 22.3's runs both sides of
/// every branch, so there every leaf of a selection tree runs: the default
/// scene's trace pass took 2.0x the time of the gathers (twenty-eighth
/// session). Versions in between were not measured; GPUs read indexed
/// tables through their caches.
fn selection_pays(info: &wgpu::AdapterInfo) -> bool {
    lavapipe_from_mesa_25(info)
}

/// Whether this is a CPU adapter whose driver is Mesa 25 or later: where
/// the table selection, the looping workgroups and loops around barriers
/// were measured to pay and to run right.
fn lavapipe_from_mesa_25(info: &wgpu::AdapterInfo) -> bool {
    is_lavapipe_from_mesa_25(info.device_type == wgpu::DeviceType::Cpu, &info.driver_info)
}

/// [`lavapipe_from_mesa_25`] for a CPU adapter or not, by its driver string.
fn is_lavapipe_from_mesa_25(cpu: bool, driver_info: &str) -> bool {
    cpu && mesa_major(driver_info).is_some_and(|major| major >= 25)
}

/// Whether the trace and accumulate kernels loop over tiles in a few
/// workgroups by default ([`Gpu::set_looping_groups`]): on lavapipe from
/// Mesa 25. Mesa 22.3's lavapipe silently stops an invocation's loops
/// after about 65,535 iterations in all, which one invocation looping over
/// every other tile of a 1280 x 720 image passes (the deep scene's rays
/// came back as misses, tests/raytrace.rs, thirty-first session), so there
/// each workgroup keeps one tile; a GPU needs the workgroups to fill it.
fn looping_pays(info: &wgpu::AdapterInfo) -> bool {
    lavapipe_from_mesa_25(info)
}

/// Whether kernels may loop over their tiles around workgroup barriers
/// ([`Gpu::barriers_loop`]). Lavapipe from Mesa 22.3 drew wrong outlines
/// with the accumulate pass's `outlined` looping that way in 16-invocation
/// workgroups (two SIMD programs meeting at each barrier; 5 px outlines in
/// tests/shading.rs, thirty-first session), and right ones with one
/// workgroup per tile; Mesa 25 draws them right either way. Other CPU
/// drivers were not tried, so they keep one workgroup per tile.
fn barriers_loop(info: &wgpu::AdapterInfo) -> bool {
    barriers_loop_on(info.device_type == wgpu::DeviceType::Cpu, &info.driver_info)
}

/// [`barriers_loop`] for a CPU adapter or not, by its driver string.
fn barriers_loop_on(cpu: bool, driver_info: &str) -> bool {
    !cpu || is_lavapipe_from_mesa_25(cpu, driver_info)
}

/// The major version in a Mesa driver string ("Mesa 25.0.7-2~bpo12+1
/// (LLVM 15.0.6)": 25).
fn mesa_major(driver_info: &str) -> Option<u32> {
    let (_, rest) = driver_info.split_once("Mesa ")?;
    rest.split('.').next()?.parse().ok()
}

/// Workgroups of the trace and accumulate kernels per driver thread on
/// lavapipe from Mesa 25, each looping over tiles ([`looping_pays`],
/// [`Gpu::set_looping_groups`]).
pub const LOOPING_GROUPS_PER_THREAD: u32 = 1;

/// [`AdapterSummary::dispatch_threads`] for a CPU adapter.
fn cpu_dispatch_threads() -> u32 {
    let from_env = std::env::var("LP_NUM_THREADS")
        .ok()
        .and_then(|v| v.trim().parse::<u32>().ok());
    let cpus = std::thread::available_parallelism().map_or(1, |n| n.get() as u32);
    from_env.unwrap_or(cpus).clamp(1, 32)
}

impl AdapterSummary {
    fn from_adapter(adapter: &wgpu::Adapter) -> AdapterSummary {
        let info = adapter.get_info();
        AdapterSummary {
            ray_queries: adapter
                .features()
                .contains(wgpu::Features::EXPERIMENTAL_RAY_QUERY),
            packet_walk: info.device_type == wgpu::DeviceType::Cpu
                && adapter.features().contains(wgpu::Features::SUBGROUP)
                && info.subgroup_min_size == 8
                && info.subgroup_max_size == 8,
            dispatch_threads: if info.device_type == wgpu::DeviceType::Cpu {
                cpu_dispatch_threads()
            } else {
                1
            },
            ..AdapterSummary::from_info(&info)
        }
    }

    fn from_info(info: &wgpu::AdapterInfo) -> AdapterSummary {
        AdapterSummary {
            ray_queries: false,
            packet_walk: false,
            dispatch_threads: 1,
            name: info.name.clone(),
            backend: format!("{:?}", info.backend),
            device_type: format!("{:?}", info.device_type),
            driver: format!("{} {}", info.driver, info.driver_info)
                .trim()
                .to_string(),
        }
    }
}

impl std::fmt::Display for AdapterSummary {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "{} ({}, {}, driver: {})",
            self.name, self.backend, self.device_type, self.driver
        )
    }
}

/// A device and queue, with the adapter they came from.
///
/// Validation errors that no error scope captured are collected by an
/// uncaptured-error handler; [`Gpu::take_errors`] turns them into an error.
pub struct Gpu {
    pub instance: wgpu::Instance,
    pub adapter: wgpu::Adapter,
    pub device: wgpu::Device,
    pub queue: wgpu::Queue,
    pub summary: AdapterSummary,
    uncaptured: Arc<Mutex<Vec<String>>>,
    /// Shader files read from disk (hot reload), used instead of the
    /// embedded ones by passes created from now on.
    shader_overrides: Mutex<Option<Arc<ShaderOverrides>>>,
    /// Whether scenes uploaded from now on read their small tables from
    /// uniform copies (gpu::uniform_tables); tests and benchmarks turn it
    /// off to compare with the storage reads.
    uniform_tables: AtomicBool,
    /// Whether scenes uploaded from now on read their smallest tables by
    /// selection (gpu::uniform_tables::SelectedTables; on where
    /// `selection_pays`); tests turn it off to compare with the indexed
    /// reads.
    select_tables: AtomicBool,
    /// Whether renderers prepared from now on search for outlines over the
    /// listed marked tiles (`render::accumulate`); tests turn it off to
    /// check the dispatch over every tile against it.
    outline_tile_list: AtomicBool,
    /// Whether renderers made from now on let the trace pass add the
    /// colour of the tiles no outline reaches to the accumulator itself
    /// (`Renderer::render_sample`); tests turn it off to check it against
    /// the accumulate pass doing it all.
    trace_accumulates: AtomicBool,
    /// Whether renderers made from now on prove on the CPU where tiles are
    /// the smooth inside of one sphere, which the outline marks then skip
    /// (`Renderer::render_sample`); tests turn it off to check the images
    /// against the marks proving it texel by texel.
    smooth_tiles: AtomicBool,
    /// Whether scenes uploaded from now on give shadow rays occluder lists
    /// (`accel::shadow_cull`); tests turn it off to check the lists
    /// against the BVH walk.
    shadow_lists: AtomicBool,
    /// Whether scenes uploaded from now on give primary rays their screen
    /// tile's instances (`accel::screen_tiles`); tests turn it off to
    /// check the tiles against the BVH walk.
    primary_tiles: AtomicBool,
    /// Whether scenes uploaded from now on of at most
    /// `FLAT_TOP_LEVEL_MAX` instances test them in turn instead of
    /// walking the top-level tree; tests turn it off to check against the
    /// walk.
    flat_top_level: AtomicBool,
    /// How many workgroups the trace and accumulate kernels dispatch,
    /// each looping over tiles; 0: one per tile (`set_looping_groups`).
    looping_groups: AtomicU32,
    /// Whether pipelines built from now on give the triangle test's edge
    /// values a tolerance (`set_edge_tolerance`).
    edge_tolerance: AtomicBool,
    /// Whether kernels may loop over tiles around barriers (`barriers_loop`).
    barriers_loop: bool,
    /// Whether passes made from now on use the packet walk
    /// (`set_packet_walk`; never where `summary.packet_walk` says it
    /// cannot run).
    packet_walk: AtomicBool,
}

const INSTALL_HINT: &str = "no GPU adapter found. celray needs a Vulkan driver; \
on Debian/Ubuntu install Mesa's CPU driver lavapipe with \
`sudo apt-get install -y mesa-vulkan-drivers libvulkan1`";

/// Every adapter the instance can see, with a one-line summary each.
pub fn list_adapters() -> Vec<AdapterSummary> {
    let instance = new_instance();
    pollster::block_on(instance.enumerate_adapters(wgpu::Backends::all()))
        .iter()
        .map(AdapterSummary::from_adapter)
        .collect()
}

fn type_rank(t: wgpu::DeviceType) -> u32 {
    match t {
        wgpu::DeviceType::DiscreteGpu => 0,
        wgpu::DeviceType::IntegratedGpu => 1,
        wgpu::DeviceType::VirtualGpu => 2,
        wgpu::DeviceType::Other => 3,
        wgpu::DeviceType::Cpu => 4,
    }
}

fn backend_rank(b: wgpu::Backend) -> u32 {
    // Vulkan first: it is what the tests and the measurements use.
    match b {
        wgpu::Backend::Vulkan => 0,
        wgpu::Backend::Metal | wgpu::Backend::Dx12 => 1,
        _ => 2,
    }
}

/// Picks an adapter from `adapters` by `choice`, or says why none fits
/// (the window code passes the adapters that can present to its surface).
pub fn pick_adapter(
    adapters: Vec<wgpu::Adapter>,
    choice: &AdapterChoice,
) -> Result<wgpu::Adapter, GpuError> {
    if adapters.is_empty() {
        return Err(GpuError::NoAdapter(INSTALL_HINT.to_string()));
    }
    let names: Vec<String> = adapters
        .iter()
        .map(|a| AdapterSummary::from_info(&a.get_info()).to_string())
        .collect();
    let mut candidates: Vec<wgpu::Adapter> = match choice {
        AdapterChoice::Auto => adapters,
        AdapterChoice::Software => adapters
            .into_iter()
            .filter(|a| a.get_info().device_type == wgpu::DeviceType::Cpu)
            .collect(),
        AdapterChoice::Named(part) => {
            let part = part.to_lowercase();
            adapters
                .into_iter()
                .filter(|a| a.get_info().name.to_lowercase().contains(&part))
                .collect()
        }
    };
    candidates.sort_by_key(|a| {
        let info = a.get_info();
        (type_rank(info.device_type), backend_rank(info.backend))
    });
    candidates.into_iter().next().ok_or_else(|| {
        let wanted = match choice {
            AdapterChoice::Software => "no CPU (software) adapter found; install lavapipe with \
                 `sudo apt-get install -y mesa-vulkan-drivers libvulkan1`"
                .to_string(),
            AdapterChoice::Named(n) => format!("no adapter name contains {n:?}"),
            AdapterChoice::Auto => INSTALL_HINT.to_string(),
        };
        GpuError::NoAdapter(format!(
            "{wanted}. Adapters seen:\n  {}",
            names.join("\n  ")
        ))
    })
}

impl Gpu {
    /// A headless device (no window), chosen by `choice`.
    pub fn new_headless(choice: &AdapterChoice) -> Result<Gpu, GpuError> {
        let instance = new_instance();
        let adapters = pollster::block_on(instance.enumerate_adapters(wgpu::Backends::all()));
        let adapter = pick_adapter(adapters, choice)?;
        Self::from_adapter(instance, adapter)
    }

    /// A device on a given adapter (the window code picks one that can present).
    pub fn from_adapter(instance: wgpu::Instance, adapter: wgpu::Adapter) -> Result<Gpu, GpuError> {
        let summary = AdapterSummary::from_adapter(&adapter);
        let edge_tolerance = adapter.get_info().device_type != wgpu::DeviceType::Cpu;
        let select_tables = selection_pays(&adapter.get_info());
        let barriers_loop = barriers_loop(&adapter.get_info());
        // Ray queries serve the driver acceleration path (render/driver_accel.rs);
        // they are requested wherever offered, so either path can be chosen
        // later on one device. They need the experimental-features token and
        // the adapter's own limits (the minimum acceleration-structure limits
        // ask more primitives than lavapipe has).
        let wanted = wgpu::Features::TIMESTAMP_QUERY
            | wgpu::Features::TIMESTAMP_QUERY_INSIDE_ENCODERS
            | wgpu::Features::EXPERIMENTAL_RAY_QUERY
            | wgpu::Features::SUBGROUP;
        let required_features = adapter.features() & wanted;
        let experimental_features =
            if required_features.contains(wgpu::Features::EXPERIMENTAL_RAY_QUERY) {
                // SAFETY: the token only acknowledges that wgpu's ray-query API
                // is experimental; celray uses it through the safe API alone.
                unsafe { wgpu::ExperimentalFeatures::enabled() }
            } else {
                wgpu::ExperimentalFeatures::disabled()
            };
        // The scene's small tables have uniform copies of this size
        // (gpu::uniform_tables): WebGPU's default, which Vulkan drivers meet.
        let uniform_limit = adapter.limits().max_uniform_buffer_binding_size;
        if uniform_limit < u64::from(UNIFORM_TABLE_BYTES) {
            return Err(GpuError::Limit {
                what: format!("{summary}: celray's uniform binding size (bytes)"),
                value: u64::from(UNIFORM_TABLE_BYTES),
                limit: uniform_limit,
            });
        }
        let (device, queue) = pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
            label: Some("celray device"),
            required_features,
            required_limits: adapter.limits(),
            experimental_features,
            memory_hints: wgpu::MemoryHints::Performance,
            trace: wgpu::Trace::Off,
        }))
        .map_err(|e| GpuError::Device(format!("{summary}: {e}")))?;
        let uncaptured = Arc::new(Mutex::new(Vec::new()));
        let sink = uncaptured.clone();
        device.on_uncaptured_error(Arc::new(move |e: wgpu::Error| {
            log::error!("wgpu: {e}");
            if let Ok(mut v) = sink.lock() {
                v.push(e.to_string());
            }
        }));
        log::info!("adapter: {summary}");
        let packet_walk = AtomicBool::new(summary.packet_walk);
        let looping_groups = AtomicU32::new(if looping_pays(&adapter.get_info()) {
            summary.dispatch_threads * LOOPING_GROUPS_PER_THREAD
        } else {
            0
        });
        Ok(Gpu {
            instance,
            adapter,
            device,
            queue,
            summary,
            uncaptured,
            shader_overrides: Mutex::new(None),
            uniform_tables: AtomicBool::new(true),
            select_tables: AtomicBool::new(select_tables),
            outline_tile_list: AtomicBool::new(true),
            trace_accumulates: AtomicBool::new(true),
            smooth_tiles: AtomicBool::new(true),
            shadow_lists: AtomicBool::new(true),
            primary_tiles: AtomicBool::new(true),
            flat_top_level: AtomicBool::new(true),
            looping_groups,
            edge_tolerance: AtomicBool::new(edge_tolerance),
            barriers_loop,
            packet_walk,
        })
    }

    /// Whether scenes uploaded from now on may read small tables from
    /// uniform copies (on by default; off: every table from storage, the
    /// same images, for tests and benchmarks).
    pub fn set_uniform_tables(&self, on: bool) {
        self.uniform_tables.store(on, Ordering::Relaxed);
    }

    pub fn uniform_tables(&self) -> bool {
        self.uniform_tables.load(Ordering::Relaxed)
    }

    /// Whether scenes uploaded from now on read tables of at most
    /// [`MAX_SELECTED`](crate::gpu::uniform_tables::MAX_SELECTED) elements
    /// by selection (a branch per element at a constant index) instead of at
    /// a per-invocation index. On by default where it pays (lavapipe from
    /// Mesa 25: `selection_pays`), where it took about a tenth off the
    /// default scene's trace pass. Tests turn it off to compare.
    pub fn set_select_tables(&self, on: bool) {
        self.select_tables.store(on, Ordering::Relaxed);
    }

    pub fn select_tables(&self) -> bool {
        self.select_tables.load(Ordering::Relaxed)
    }

    /// Whether renderers prepared from now on run the outline search over
    /// the list of marked tiles, one indirect dispatch (on by default;
    /// off: a dispatch over every tile, the unmarked ones stopping at once,
    /// as images with more tiles than a dispatch can count always do; the
    /// same images, for tests and benchmarks).
    pub fn set_outline_tile_list(&self, on: bool) {
        self.outline_tile_list.store(on, Ordering::Relaxed);
    }

    pub fn outline_tile_list(&self) -> bool {
        self.outline_tile_list.load(Ordering::Relaxed)
    }

    /// Whether renderers made from now on let the trace pass accumulate
    /// the pixels of the tiles no outline can reach, where it reads primary
    /// tiles (on by default; off: the accumulate pass adds every pixel, the
    /// same sums, for tests and benchmarks).
    pub fn set_trace_accumulates(&self, on: bool) {
        self.trace_accumulates.store(on, Ordering::Relaxed);
    }

    pub fn trace_accumulates(&self) -> bool {
        self.trace_accumulates.load(Ordering::Relaxed)
    }

    /// Whether renderers made from now on skip the outline marks of the
    /// tiles the CPU proves the smooth inside of one sphere or plane
    /// (`accel::screen_tiles::smooth_sphere_tiles`, `smooth_plane_tiles`;
    /// on by default; off: the marks prove them texel by texel, the same
    /// image, for tests and benchmarks).
    pub fn set_smooth_tiles(&self, on: bool) {
        self.smooth_tiles.store(on, Ordering::Relaxed);
    }

    pub fn smooth_tiles(&self) -> bool {
        self.smooth_tiles.load(Ordering::Relaxed)
    }

    /// Whether scenes uploaded from now on give each instance's shadow rays
    /// the list of occluders that can block them, tested instead of the
    /// BVH walk (on by default; off: every shadow ray that the cull keeps
    /// walks, the same images, for tests and benchmarks).
    pub fn set_shadow_lists(&self, on: bool) {
        self.shadow_lists.store(on, Ordering::Relaxed);
    }

    pub fn shadow_lists(&self) -> bool {
        self.shadow_lists.load(Ordering::Relaxed)
    }

    /// Whether scenes uploaded from now on let primary rays test only the
    /// instances their screen tile can show, instead of walking the BVH
    /// (on by default, for scenes of up to
    /// `accel::screen_tiles::MAX_TILED_INSTANCES` instances; off: every
    /// primary ray walks, the same images, for tests and benchmarks).
    pub fn set_primary_tiles(&self, on: bool) {
        self.primary_tiles.store(on, Ordering::Relaxed);
    }

    pub fn primary_tiles(&self) -> bool {
        self.primary_tiles.load(Ordering::Relaxed)
    }

    /// Whether scenes uploaded from now on of at most
    /// [`crate::render::scene_buffers::FLAT_TOP_LEVEL_MAX`] instances have their rays
    /// test every instance in turn instead of walking the top-level tree
    /// (on by default; off: they walk, the same images, for tests and
    /// benchmarks).
    pub fn set_flat_top_level(&self, on: bool) {
        self.flat_top_level.store(on, Ordering::Relaxed);
    }

    pub fn flat_top_level(&self) -> bool {
        self.flat_top_level.load(Ordering::Relaxed)
    }

    /// How many workgroups the trace pass and the accumulate pass's two
    /// kernels (not the marks) made from now on dispatch, each looping
    /// over every n-th tile (shaders/trace.wgsl, shaders/accumulate.wgsl);
    /// 0: one workgroup per tile (for the accumulate kernels: per tile of
    /// their list, through the indirect dispatches). By default
    /// [`LOOPING_GROUPS_PER_THREAD`] per thread on lavapipe from Mesa 25,
    /// where starting a workgroup costs the driver, and 0 elsewhere: a GPU
    /// needs the workgroups to fill it, and Mesa 22.3 cuts long loops
    /// short (`looping_pays`). Any count gives the same images where the
    /// driver runs it right (for tests and benchmarks).
    pub fn set_looping_groups(&self, groups: u32) {
        self.looping_groups.store(groups, Ordering::Relaxed);
    }

    pub fn looping_groups(&self) -> u32 {
        self.looping_groups.load(Ordering::Relaxed)
    }

    /// Whether a kernel whose workgroups meet at barriers may loop over
    /// tiles on this adapter (the accumulate pass's `outlined`; not on
    /// lavapipe before Mesa 25, where it drew wrong outlines so).
    pub fn barriers_loop(&self) -> bool {
        self.barriers_loop
    }

    /// Whether pipelines built from now on give the triangle test's edge
    /// values a tolerance (the override constant `EDGE_TOLERANCE` of
    /// shaders/lib/intersect.wgsl). By default off on CPU adapters and on
    /// elsewhere: a GPU compiler may fuse multiply-adds and reorder sums, so
    /// the edge values of two triangles at a shared edge need not be exact
    /// negations and a ray could slip between them; there each value gets
    /// `accel::intersect::EDGE_SLACK` of tolerance. Lavapipe's edge values
    /// are exact negations (the watertight test passes there with exact
    /// comparisons, as Woop et al.'s argument needs), and the tolerance cost
    /// a fifth of the default scene's trace pass there. Tests set it to run
    /// the other path on the same device, before creating a pass: passes
    /// keep the pipelines they have built.
    pub fn set_edge_tolerance(&self, on: bool) {
        self.edge_tolerance.store(on, Ordering::Relaxed);
    }

    /// The `EDGE_TOLERANCE` override for pipelines created now.
    pub fn edge_tolerance_constant(&self) -> (&'static str, f64) {
        let on = self.edge_tolerance.load(Ordering::Relaxed);
        ("EDGE_TOLERANCE", f64::from(u8::from(on)))
    }

    /// Whether passes made from now on trace with the packet walk
    /// (`shaders/lib/trace_packet.wgsl`: each 8 invocations of a subgroup
    /// walk the BVH together, sharing its loads). On by default where it can
    /// run: CPU adapters with subgroups of 8 (lavapipe on AVX2), where it
    /// took a quarter off mesh ray batches. A GPU reads memory through
    /// caches and does not need it. Tests turn it off to check the other
    /// walk on the same device; it cannot be turned on where it cannot run.
    pub fn set_packet_walk(&self, on: bool) {
        self.packet_walk
            .store(on && self.summary.packet_walk, Ordering::Relaxed);
    }

    pub fn packet_walk(&self) -> bool {
        self.packet_walk.load(Ordering::Relaxed)
    }

    /// Whether this device has wgpu's ray queries enabled (the driver
    /// acceleration path can run).
    pub fn has_ray_queries(&self) -> bool {
        self.device
            .features()
            .contains(wgpu::Features::EXPERIMENTAL_RAY_QUERY)
    }

    /// Makes passes created from now on use `overrides` (shader files read
    /// from disk) instead of the embedded shaders; `None` goes back to them.
    pub fn set_shader_overrides(&self, overrides: Option<ShaderOverrides>) {
        if let Ok(mut slot) = self.shader_overrides.lock() {
            *slot = overrides.map(Arc::new);
        }
    }

    /// The shader files in use instead of the embedded ones, if any.
    pub fn shader_overrides(&self) -> Option<Arc<ShaderOverrides>> {
        self.shader_overrides.lock().ok().and_then(|s| s.clone())
    }

    /// Errors the uncaptured-error handler has seen since the last call.
    pub fn take_errors(&self) -> Result<(), GpuError> {
        let mut v = self
            .uncaptured
            .lock()
            .map_err(|_| GpuError::Validation("error log poisoned".into()))?;
        if v.is_empty() {
            Ok(())
        } else {
            let all = v.join("\n");
            v.clear();
            Err(GpuError::Validation(all))
        }
    }

    /// Runs `f` inside a validation error scope; a validation error becomes `Err`.
    pub fn scoped<T>(&self, f: impl FnOnce() -> T) -> Result<T, GpuError> {
        let scope = self.device.push_error_scope(wgpu::ErrorFilter::Validation);
        let value = f();
        match pollster::block_on(scope.pop()) {
            Some(e) => Err(GpuError::Validation(e.to_string())),
            None => Ok(value),
        }
    }

    /// Blocks until all submitted work is done.
    pub fn wait_idle(&self) -> Result<(), GpuError> {
        self.device
            .poll(wgpu::PollType::wait_indefinitely())
            .map(|_| ())
            .map_err(|e| GpuError::Device(e.to_string()))
    }
}

/// A headless instance on the primary backends (Vulkan, Metal, DX12), or on
/// those named by `WGPU_BACKEND`.
fn new_instance() -> wgpu::Instance {
    let mut desc = wgpu::InstanceDescriptor::new_without_display_handle_from_env();
    if std::env::var_os("WGPU_BACKEND").is_none() {
        desc.backends = wgpu::Backends::PRIMARY;
    }
    wgpu::Instance::new(desc)
}

#[cfg(test)]
mod tests {
    use super::{barriers_loop_on, is_lavapipe_from_mesa_25, mesa_major};

    /// The major version comes from lavapipe's driver string, and a
    /// string without "Mesa " gives none (selection stays off).
    #[test]
    fn mesa_major_reads_the_driver_string() {
        assert_eq!(mesa_major("Mesa 25.0.7-2~bpo12+1 (LLVM 15.0.6)"), Some(25));
        assert_eq!(mesa_major("Mesa 22.3.6 (LLVM 15.0.6)"), Some(22));
        assert_eq!(mesa_major("570.124.06"), None);
        assert_eq!(mesa_major("Mesa x"), None);
    }

    /// The table selection, the looping workgroups and loops around
    /// barriers are on for lavapipe from Mesa 25 alone among CPU drivers:
    /// Mesa 22.3's silently cuts long loops short and got the barriers
    /// wrong, other CPU drivers were not tried. A GPU is not lavapipe
    /// (it loops around barriers, `barriers_loop`, but needs a workgroup
    /// per tile to fill it).
    #[test]
    fn lavapipe_from_mesa_25_by_kind_and_driver_string() {
        assert!(is_lavapipe_from_mesa_25(
            true,
            "Mesa 25.0.7-2~bpo12+1 (LLVM 15.0.6)"
        ));
        assert!(!is_lavapipe_from_mesa_25(true, "Mesa 22.3.6 (LLVM 15.0.6)"));
        assert!(!is_lavapipe_from_mesa_25(true, "SwiftShader driver"));
        assert!(!is_lavapipe_from_mesa_25(false, "Mesa 25.0.7"));
    }

    /// Kernels loop around barriers on GPUs and on lavapipe from Mesa 25;
    /// Mesa 22.3's lavapipe and CPU drivers that are not Mesa keep one
    /// workgroup per tile.
    #[test]
    fn barriers_loop_from_mesa_25_and_on_gpus() {
        assert!(barriers_loop_on(
            true,
            "Mesa 25.0.7-2~bpo12+1 (LLVM 15.0.6)"
        ));
        assert!(!barriers_loop_on(true, "Mesa 22.3.6 (LLVM 15.0.6)"));
        assert!(!barriers_loop_on(true, "SwiftShader driver"));
        assert!(barriers_loop_on(false, "570.124.06"));
    }
}
