//! User-facing render settings, and their GPU twins filled in `to_gpu`.
//! Each settings enum gets its names here, once (`named_enum!`): `ALL`,
//! `name()`, `parse()` and clap's `ValueEnum`, which the CLI, the panel and
//! reports all use. (The sample pattern's names live with it in
//! `sampling`, which stays free of clap.)

use crate::gpu::twins::{
    ResolveUniforms, RENDER_MODE_HYBRID, RENDER_MODE_RASTER, RENDER_MODE_RAYTRACE, TONE_MAP_CLAMP,
    TONE_MAP_REINHARD,
};
use crate::sampling::{Aperture, PixelPattern, SampleSchedule};
use crate::scene::ApertureShape;

/// Gives a settings enum its names, in one table: `ALL` (every variant, in
/// the order menus and `--help` list them), `name()` (the word the CLI, the
/// panel and reports use), `parse()` (its inverse) and clap's `ValueEnum`
/// (the CLI's possible values).
macro_rules! named_enum {
    ($ty:ident { $($variant:ident => $name:literal),+ $(,)? }) => {
        impl $ty {
            /// Every variant, in the order menus and `--help` list them.
            pub const ALL: [$ty; [$($name),+].len()] = [$($ty::$variant),+];

            /// The word the CLI, the panel and reports use.
            pub fn name(self) -> &'static str {
                match self {
                    $($ty::$variant => $name),+
                }
            }

            /// The variant called `text`, if any.
            pub fn parse(text: &str) -> Option<$ty> {
                Self::ALL.into_iter().find(|v| v.name() == text)
            }
        }

        impl clap::ValueEnum for $ty {
            fn value_variants<'a>() -> &'a [Self] {
                &Self::ALL
            }

            fn to_possible_value(&self) -> Option<clap::builder::PossibleValue> {
                Some(clap::builder::PossibleValue::new(self.name()))
            }
        }
    };
}

/// How linear radiance becomes a displayable value in [0, 1].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub enum ToneMap {
    /// Clamp to [0, 1]: shading values are shown as computed (what the
    /// tests compare against closed forms).
    #[default]
    Clamp,
    /// c / (1 + c): keeps highlights from clipping.
    Reinhard,
}

named_enum!(ToneMap {
    Clamp => "clamp",
    Reinhard => "reinhard",
});

impl ToneMap {
    /// The resolve shader's `TONE_MAP` constant.
    pub fn to_gpu(self) -> u32 {
        match self {
            ToneMap::Clamp => TONE_MAP_CLAMP,
            ToneMap::Reinhard => TONE_MAP_REINHARD,
        }
    }
}

/// Which passes find what each pixel sees.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum RenderMode {
    /// Rasterize every instance (analytic shapes tessellated; CSG shapes
    /// are not drawn); no ray tracing, so no shadows or reflections.
    Raster,
    /// Meshes rasterized, analytic shapes ray-traced exactly and composited
    /// by depth; shadows and reflections traced against everything.
    #[default]
    Hybrid,
    /// Ray-trace everything: the reference hybrid is tested against.
    Raytrace,
}

named_enum!(RenderMode {
    Raster => "raster",
    Hybrid => "hybrid",
    Raytrace => "raytrace",
});

impl RenderMode {
    pub fn to_gpu(self) -> u32 {
        match self {
            RenderMode::Raster => RENDER_MODE_RASTER,
            RenderMode::Hybrid => RENDER_MODE_HYBRID,
            RenderMode::Raytrace => RENDER_MODE_RAYTRACE,
        }
    }
}

/// Most samples per pixel celray accumulates (`--spp`, the app's sample
/// target): there the noise left in a pixel whose samples spread over the
/// whole display range is under one 8-bit level (1/sqrt(2^16) = 1/256), and
/// the f32 accumulator, whose sum has then reached 2^16 sample values, keeps
/// only about 8 bits of each further sample.
pub const MAX_SPP: u32 = 1 << 16;

/// Most samples in one image, width x height x spp: 2^37, which is
/// 1920x1080 at [`MAX_SPP`] or 3840x2160 at 16,384 spp. It refuses a
/// mistyped count before hours of work rather than anything the GPU cannot
/// do.
pub const MAX_IMAGE_SAMPLES: u64 = 1 << 37;

/// Most mirror/glossy bounces after the primary hit (`--max-bounces`, the
/// app's slider): past a few bounces a reflection adds nothing visible.
pub const MAX_BOUNCES: u32 = 16;
/// Which acceleration structure the ray-traced passes walk.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum AccelChoice {
    /// The driver's where the adapter has ray queries and the driver path
    /// measured faster on that kind of adapter (see
    /// [`AccelChoice::driver_preferred`]), else software.
    #[default]
    Auto,
    /// celray's own two-level BVH, walked in WGSL: any adapter.
    Software,
    /// The driver's acceleration structures through wgpu ray queries;
    /// falls back to software, with a notice, where it cannot run.
    Driver,
}

named_enum!(AccelChoice {
    Auto => "auto",
    Software => "software",
    Driver => "driver",
});

impl AccelChoice {
    /// Whether `auto` takes the driver path on adapters of this type (given
    /// ray queries): only where it measured faster than the software path
    /// (`celray bench accel`, README "Driver ray queries"). On lavapipe
    /// (Mesa 25.0.7, 2 cores) it did not (0.6x the software closest-hit
    /// rate on FlightHelmet and 100 spheres, 1.0x on spot x 10,000; the trace
    /// pass 1.2-1.7x slower), so CPU adapters stay on software; no other
    /// adapter type has been measured yet, so they do too.
    pub fn driver_preferred(_device_type: wgpu::DeviceType) -> bool {
        false
    }
}

/// What happens to the image while the view moves.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Temporal {
    /// Every change restarts the accumulation: a moving view shows one
    /// sample per frame (what `celray render` does).
    #[default]
    Off,
    /// While the camera moves, each sample is blended into the previous
    /// frame's image reprojected along the motion vectors, with the history
    /// rejected on disocclusion and clipped to the neighbourhood; the
    /// moment it stops, exact accumulation restarts.
    Reproject,
    /// For comparison: the reprojected history blended blindly (no
    /// rejection, no clipping), the plain exponential blend that ghosts.
    Blend,
}

named_enum!(Temporal {
    Off => "off",
    Reproject => "reproject",
    Blend => "blend",
});

/// Everything about how a scene is rendered that is not the scene itself.
#[derive(Debug, Clone, PartialEq)]
pub struct RenderSettings {
    /// Image size in pixels (defaults to the scene camera's size).
    pub width: u32,
    pub height: u32,
    /// Samples per pixel the accumulation converges to.
    pub spp: u32,
    /// Seed of every random choice: same seed, same image.
    pub seed: u32,
    /// Sub-pixel positions of the samples.
    pub pattern: PixelPattern,
    pub tone_map: ToneMap,
    /// Linear scale applied before tone mapping.
    pub exposure: f32,
    pub mode: RenderMode,
    /// Mirror reflection bounces after the primary hit (ray modes).
    pub max_bounces: u32,
    /// Which acceleration structure rays walk (same image either way).
    pub accel: AccelChoice,
    /// Temporal accumulation while the camera moves.
    pub temporal: Temporal,
}

impl Default for RenderSettings {
    fn default() -> Self {
        RenderSettings {
            width: 1280,
            height: 720,
            spp: 16,
            seed: 0,
            pattern: PixelPattern::Jittered,
            tone_map: ToneMap::Clamp,
            exposure: 1.0,
            mode: RenderMode::Hybrid,
            max_bounces: 3,
            accel: AccelChoice::Auto,
            temporal: Temporal::Off,
        }
    }
}

impl RenderSettings {
    /// Settings at the scene camera's image size.
    pub fn for_camera(camera: &crate::scene::Camera) -> RenderSettings {
        RenderSettings {
            width: camera.width,
            height: camera.height,
            ..RenderSettings::default()
        }
    }

    /// Which sample k is under these settings, through `camera`'s aperture.
    pub fn sample_schedule(&self, camera: &crate::scene::Camera) -> SampleSchedule {
        let aperture = match camera.aperture {
            ApertureShape::Disk => Aperture::Disk,
            ApertureShape::Square => Aperture::Square,
            ApertureShape::Polygon {
                blades,
                rotation_deg,
            } => Aperture::Polygon {
                blades,
                rotation: rotation_deg.to_radians(),
            },
        };
        SampleSchedule {
            pattern: self.pattern,
            aperture,
            spp: self.spp,
            seed: self.seed,
        }
    }

    /// The resolve pass's uniforms for a target of this width (its tone
    /// map is a pipeline constant, [`ToneMap::to_gpu`]).
    pub fn to_gpu(&self) -> ResolveUniforms {
        ResolveUniforms {
            width: self.width,
            exposure: self.exposure,
            _pad: [0; 2],
        }
    }
}
