//! Side-by-side shading comparison, headless (`celray compare`): one
//! [`Renderer`] per view, each with its own shading override, all sharing
//! the scene's camera; a labelled contact sheet and FLIP and PSNR for every
//! pair of views. No window, no event loop. The pieces live in submodules:
//! [`metrics`] (FLIP, PSNR), [`text`] (label font rasterization), [`sheet`]
//! (the contact sheet); what a view is and its labels live in
//! [`crate::view`], re-exported here.

pub mod metrics;
pub mod sheet;
pub mod text;

pub use crate::view::{model_label, settings_label, ViewListError, ViewSpec, MAX_VIEWS};
pub use metrics::{flip_mean, pair_metrics, psnr_rgba8, PairMetrics};
pub use sheet::{contact_sheet, sheet_columns, LABEL_BAR_PX};
pub use text::{draw_text, text_width};

use crate::capture::{CaptureError, Frame};
use crate::gpu::Gpu;
use crate::render::{RenderSettings, Renderer};
use crate::scene::{Scene, SceneError};

#[derive(Debug, thiserror::Error)]
pub enum CompareError {
    #[error(transparent)]
    BadViews(#[from] ViewListError),
    #[error(transparent)]
    Capture(#[from] CaptureError),
    #[error(transparent)]
    Scene(#[from] SceneError),
}

/// Renders every view to convergence: one renderer per view, same camera
/// and settings. `progress(view, done, total)` is called after each sample.
pub fn render_views(
    gpu: &Gpu,
    scene: &Scene,
    settings: &RenderSettings,
    views: &[ViewSpec],
    mut progress: impl FnMut(usize, u32, u32),
) -> Result<Vec<Frame>, CaptureError> {
    views
        .iter()
        .enumerate()
        .map(|(i, view)| {
            let mut renderer = Renderer::new(gpu, view.apply(scene), settings.clone())?;
            renderer.render_to_convergence(gpu, |done, total| progress(i, done, total))?;
            Ok(Frame {
                width: settings.width,
                height: settings.height,
                srgb8: renderer.read_srgb8(gpu)?,
                linear: None,
            })
        })
        .collect()
}

/// Everything `celray compare` reports.
pub struct Comparison {
    pub views: Vec<ViewSpec>,
    pub settings: RenderSettings,
    pub frames: Vec<Frame>,
    pub pairs: Vec<PairMetrics>,
}

impl Comparison {
    /// Renders `views` of `scene` and measures every pair.
    pub fn run(
        gpu: &Gpu,
        scene: &Scene,
        settings: &RenderSettings,
        views: Vec<ViewSpec>,
        progress: impl FnMut(usize, u32, u32),
    ) -> Result<Comparison, CompareError> {
        let frames = render_views(gpu, scene, settings, &views, progress)?;
        let pairs = pair_metrics(&frames);
        Ok(Comparison {
            views,
            settings: settings.clone(),
            frames,
            pairs,
        })
    }

    /// `"toon:4 — 16 spp, jittered, clamp"` for view `i`.
    pub fn view_label(&self, i: usize) -> String {
        format!(
            "{} - {}",
            self.views[i].label(),
            settings_label(&self.settings)
        )
    }

    /// The labelled contact sheet.
    pub fn sheet(&self) -> image::RgbaImage {
        let labelled: Vec<(String, &Frame)> = self
            .frames
            .iter()
            .enumerate()
            .map(|(i, f)| (self.view_label(i), f))
            .collect();
        contact_sheet(&labelled)
    }

    /// One line per pair: `blinn-phong vs toon:4: FLIP mean 0.1234, PSNR 21.05 dB`.
    pub fn text_report(&self) -> String {
        if self.pairs.is_empty() {
            return "one view: no pairs to compare\n".to_string();
        }
        let mut out = String::new();
        for p in &self.pairs {
            let psnr = if p.psnr_db.is_finite() {
                format!("{:.2} dB", p.psnr_db)
            } else {
                "inf (identical)".to_string()
            };
            out.push_str(&format!(
                "{} vs {}: FLIP mean {:.4}, PSNR {psnr}\n",
                self.views[p.a].label(),
                self.views[p.b].label(),
                p.flip_mean
            ));
        }
        out
    }

    /// The report as JSON; an infinite PSNR (identical images) is `null`.
    pub fn json(&self, sheet_path: &str) -> serde_json::Value {
        let views: Vec<serde_json::Value> = self
            .views
            .iter()
            .enumerate()
            .map(|(i, v)| serde_json::json!({ "index": i, "view": v.label() }))
            .collect();
        let pairs: Vec<serde_json::Value> = self
            .pairs
            .iter()
            .map(|p| {
                serde_json::json!({
                    "a": self.views[p.a].label(),
                    "b": self.views[p.b].label(),
                    "a_index": p.a,
                    "b_index": p.b,
                    "flip_mean": p.flip_mean,
                    "psnr_db": if p.psnr_db.is_finite() { Some(p.psnr_db) } else { None },
                })
            })
            .collect();
        serde_json::json!({
            "sheet": sheet_path,
            "width": self.settings.width,
            "height": self.settings.height,
            "settings": settings_label(&self.settings),
            "views": views,
            "pairs": pairs,
        })
    }
}
