//! Headless capture: scene -> renderer -> N samples -> PNG (sRGB) or EXR
//! (linear HDR). No window, no event loop.

use std::path::Path;
use std::sync::atomic::{AtomicBool, Ordering};

use crate::gpu::{Gpu, GpuError};
use crate::render::{RenderSettings, Renderer};
use crate::scene::{CameraPath, Scene};

#[derive(Debug, thiserror::Error)]
pub enum CaptureError {
    #[error(transparent)]
    Gpu(#[from] GpuError),
    #[error("cannot write {path}: {reason}")]
    Write { path: String, reason: String },
    #[error("output {0}: unknown image type; use a .png (sRGB) or .exr (linear HDR) file name")]
    UnknownFormat(String),
}

/// The image file types celray writes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum OutputFormat {
    /// 8-bit sRGB-encoded, tone mapped.
    Png,
    /// 32-bit float linear radiance, before tone mapping.
    Exr,
}

impl OutputFormat {
    /// The format a file name asks for, by extension.
    pub fn from_path(path: &Path) -> Result<OutputFormat, CaptureError> {
        match path
            .extension()
            .and_then(|e| e.to_str())
            .map(str::to_ascii_lowercase)
            .as_deref()
        {
            Some("png") => Ok(OutputFormat::Png),
            Some("exr") => Ok(OutputFormat::Exr),
            _ => Err(CaptureError::UnknownFormat(path.display().to_string())),
        }
    }
}

/// A rendered image: sRGB bytes and, when asked for, linear floats.
pub struct Frame {
    pub width: u32,
    pub height: u32,
    /// RGBA8, sRGB-encoded, top row first.
    pub srgb8: Vec<u8>,
    /// RGBA f32 linear radiance (alpha 1), when read back.
    pub linear: Option<Vec<f32>>,
}

impl Frame {
    /// A `width` x `height` image of one opaque sRGB colour (for tests).
    #[cfg(test)]
    pub(crate) fn flat(width: u32, height: u32, rgb: [u8; 3]) -> Frame {
        Frame {
            width,
            height,
            srgb8: (0..width * height)
                .flat_map(|_| [rgb[0], rgb[1], rgb[2], 255])
                .collect(),
            linear: None,
        }
    }

    /// The sRGB image as an `image` buffer.
    pub fn to_rgba8(&self) -> image::RgbaImage {
        image::RgbaImage::from_raw(self.width, self.height, self.srgb8.clone())
            .expect("readback size matches the image size")
    }

    /// The sRGB colour of pixel (x, y).
    pub fn pixel(&self, x: u32, y: u32) -> [u8; 4] {
        let i = ((y * self.width + x) * 4) as usize;
        [
            self.srgb8[i],
            self.srgb8[i + 1],
            self.srgb8[i + 2],
            self.srgb8[i + 3],
        ]
    }
}

/// Renders `scene` with `settings` to convergence on `gpu`.
pub fn render_frame(
    gpu: &Gpu,
    scene: Scene,
    settings: RenderSettings,
    want_linear: bool,
    progress: impl FnMut(u32, u32),
) -> Result<Frame, CaptureError> {
    let mut renderer = Renderer::new(gpu, scene, settings)?;
    renderer.render_to_convergence(gpu, progress)?;
    read_frame(gpu, &renderer, want_linear)
}

/// Renders like [`render_frame`], but waits for each sample before calling
/// `progress(done, total)` (so that progress and timings are true), and
/// stops between two samples once `stop` is set. Returns the image of the
/// samples done with their count per pixel, or `None` when stopped before
/// the first one.
pub fn render_frame_until_stopped(
    gpu: &Gpu,
    scene: Scene,
    settings: RenderSettings,
    want_linear: bool,
    mut progress: impl FnMut(u32, u32),
    stop: &AtomicBool,
) -> Result<Option<(Frame, u32)>, CaptureError> {
    let mut renderer = Renderer::new(gpu, scene, settings)?;
    while !renderer.converged() && !stop.load(Ordering::SeqCst) {
        renderer.render_sample(gpu)?;
        gpu.wait_idle()?;
        progress(renderer.samples(), renderer.settings().spp);
    }
    if renderer.samples() == 0 {
        return Ok(None);
    }
    Ok(Some((
        read_frame(gpu, &renderer, want_linear)?,
        renderer.samples(),
    )))
}

/// The resolved image of what `renderer` has accumulated. Pixels whose
/// traversal hit one of its limits are drawn magenta; a warning says how
/// many, so that the colour is never the only sign.
fn read_frame(gpu: &Gpu, renderer: &Renderer, want_linear: bool) -> Result<Frame, CaptureError> {
    let overflow = renderer.overflow_pixels(gpu)?;
    if overflow > 0 {
        log::warn!(
            "{overflow} pixel samples hit a traversal limit and are drawn magenta (the step \
             budget of a query, the traversal stack, or a CSG tree's intervals or mesh \
             crossings per ray: docs/csg.md)"
        );
    }
    Ok(Frame {
        width: renderer.settings().width,
        height: renderer.settings().height,
        srgb8: renderer.read_srgb8(gpu)?,
        linear: if want_linear {
            Some(renderer.read_linear(gpu)?)
        } else {
            None
        },
    })
}

/// Renders frames 0..=`last` of a camera path, one sample per frame as the
/// live app does, and returns frame `last` as the app would show it: with
/// `settings.temporal` off every moving frame is a fresh single sample; with
/// reprojection each moving frame blends into the reprojected history. A
/// frame whose camera equals the previous one's accumulates exactly (until
/// `settings.spp` samples, where the app stops too).
pub fn render_path_frame(
    gpu: &Gpu,
    scene: Scene,
    settings: RenderSettings,
    path: &CameraPath,
    last: u32,
    want_linear: bool,
    mut progress: impl FnMut(u32, u32),
) -> Result<Frame, CaptureError> {
    let mut renderer = Renderer::new(gpu, scene, settings.clone())?;
    let base = renderer.scene().camera.clone();
    for f in 0..=last {
        let camera = path.camera_at(&base, f);
        if f == 0 || camera != renderer.scene().camera {
            renderer.set_camera(camera);
        }
        // The app stops sampling a still view once it has converged.
        if !renderer.converged() {
            renderer.render_sample(gpu)?;
        }
        progress(f + 1, last + 1);
    }
    gpu.wait_idle()?;
    Ok(Frame {
        width: settings.width,
        height: settings.height,
        srgb8: renderer.read_srgb8(gpu)?,
        linear: if want_linear {
            Some(renderer.read_linear(gpu)?)
        } else {
            None
        },
    })
}

/// Writes `frame` to `path` as PNG or EXR (by extension).
pub fn save(frame: &Frame, path: &Path) -> Result<(), CaptureError> {
    let write_err = |e: image::ImageError| CaptureError::Write {
        path: path.display().to_string(),
        reason: e.to_string(),
    };
    match OutputFormat::from_path(path)? {
        OutputFormat::Png => frame
            .to_rgba8()
            .save_with_format(path, image::ImageFormat::Png)
            .map_err(write_err),
        OutputFormat::Exr => {
            let linear = frame.linear.clone().ok_or_else(|| CaptureError::Write {
                path: path.display().to_string(),
                reason: "no linear image was read back".into(),
            })?;
            image::Rgba32FImage::from_raw(frame.width, frame.height, linear)
                .ok_or_else(|| CaptureError::Write {
                    path: path.display().to_string(),
                    reason: "size mismatch".into(),
                })?
                .save_with_format(path, image::ImageFormat::OpenExr)
                .map_err(write_err)
        }
    }
}
