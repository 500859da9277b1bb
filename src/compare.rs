//! Side-by-side shading comparison, headless: one [`Renderer`] per view,
//! each with its own shading override, all sharing the scene's camera; a
//! labelled contact sheet; FLIP (NVIDIA's perceptual difference, via the
//! `nv-flip` crate) and PSNR for every pair of views. The live app's
//! multi-view layout uses the same [`ViewSpec`]s. No window, no event loop.

use ab_glyph::{Font, FontRef, PxScale, ScaleFont};

use crate::capture::{CaptureError, Frame};
use crate::gpu::Gpu;
use crate::render::{RenderSettings, Renderer, ToneMap};
use crate::scene::{parse_shading_model, Scene, SceneError, ShadingModel};

/// The most views one comparison renders.
pub const MAX_VIEWS: usize = 16;

#[derive(Debug, thiserror::Error)]
pub enum CompareError {
    #[error("--views {text:?}: {reason}")]
    BadViews { text: String, reason: String },
    #[error(transparent)]
    Capture(#[from] CaptureError),
    #[error(transparent)]
    Scene(#[from] SceneError),
}

/// One view of a comparison: the scene's own materials, or every material
/// switched to one shading model.
#[derive(Debug, Clone, PartialEq)]
pub struct ViewSpec {
    /// `None`: materials as the scene file says.
    pub shading: Option<ShadingModel>,
}

impl ViewSpec {
    /// The scene's materials as authored.
    pub const SCENE: ViewSpec = ViewSpec { shading: None };

    /// Every material switched to `model`.
    pub fn with_model(model: ShadingModel) -> ViewSpec {
        ViewSpec {
            shading: Some(model),
        }
    }

    /// `scene` (materials as authored), `blinn-phong`, `toon` or `toon:N`.
    pub fn parse(text: &str) -> Result<ViewSpec, SceneError> {
        let t = text.trim().to_ascii_lowercase();
        if t == "scene" {
            return Ok(ViewSpec::SCENE);
        }
        parse_shading_model(&t).map(ViewSpec::with_model)
    }

    /// A comma-separated list such as `"blinn-phong,toon:4,toon:7"`.
    pub fn parse_list(text: &str) -> Result<Vec<ViewSpec>, CompareError> {
        let bad = |reason: String| CompareError::BadViews {
            text: text.to_string(),
            reason,
        };
        if text.trim().is_empty() {
            return Err(bad(
                "no views; give a comma-separated list such as \"blinn-phong,toon:4\"".into(),
            ));
        }
        let views = text
            .split(',')
            .enumerate()
            .map(|(i, part)| {
                ViewSpec::parse(part).map_err(|e| {
                    bad(format!(
                        "view {} ({:?}): {e}; \"scene\" keeps the scene's own materials",
                        i + 1,
                        part.trim()
                    ))
                })
            })
            .collect::<Result<Vec<_>, _>>()?;
        if views.len() > MAX_VIEWS {
            return Err(bad(format!("{} views; at most {MAX_VIEWS}", views.len())));
        }
        Ok(views)
    }

    /// The text that parses back to this view (`scene`, `blinn-phong`,
    /// `toon:4`), or a description for toon models with uneven thresholds.
    pub fn label(&self) -> String {
        match &self.shading {
            None => "scene".to_string(),
            Some(model) => model_label(model),
        }
    }

    /// `scene` with this view's shading applied.
    pub fn apply(&self, scene: &Scene) -> Scene {
        let mut scene = scene.clone();
        if let Some(model) = &self.shading {
            scene.override_shading(model);
        }
        scene
    }
}

/// `blinn-phong`, `toon:N` for evenly spaced bands, else
/// `toon (N bands: t1, t2, ...)`.
pub fn model_label(model: &ShadingModel) -> String {
    match model {
        ShadingModel::BlinnPhong => "blinn-phong".to_string(),
        ShadingModel::Toon(toon) => {
            let even = crate::scene::Toon::even(toon.bands());
            if toon.thresholds == even.thresholds {
                format!("toon:{}", toon.bands())
            } else {
                let t: Vec<String> = toon.thresholds.iter().map(|t| format!("{t:.2}")).collect();
                format!("toon ({} bands: {})", toon.bands(), t.join(", "))
            }
        }
    }
}

/// A short description of the settings that change a view's look:
/// `16 spp, jittered, clamp`.
pub fn settings_label(settings: &RenderSettings) -> String {
    let pattern = settings.pattern.name();
    let tone = match settings.tone_map {
        ToneMap::Clamp => "clamp",
        ToneMap::Reinhard => "reinhard",
    };
    let mut s = format!("{} spp, {pattern}, {tone}", settings.spp);
    if (settings.exposure - 1.0).abs() > 1e-6 {
        s.push_str(&format!(", exposure {:.2}", settings.exposure));
    }
    s
}

/// Differences between views `a` and `b` (indices into the view list).
#[derive(Debug, Clone, PartialEq)]
pub struct PairMetrics {
    pub a: usize,
    pub b: usize,
    /// Mean of FLIP's per-pixel error map, in [0, 1]; 0 for equal images.
    pub flip_mean: f32,
    /// Peak signal-to-noise ratio over the 8-bit RGB channels, in dB;
    /// infinite for equal images.
    pub psnr_db: f64,
}

/// PSNR in dB of two RGBA8 images of the same size, over R, G and B.
pub fn psnr_rgba8(a: &[u8], b: &[u8]) -> f64 {
    assert_eq!(a.len(), b.len(), "images differ in size");
    let mut sum = 0.0f64;
    let mut n = 0u64;
    for (pa, pb) in a.chunks_exact(4).zip(b.chunks_exact(4)) {
        for c in 0..3 {
            let d = f64::from(pa[c]) - f64::from(pb[c]);
            sum += d * d;
            n += 1;
        }
    }
    if sum == 0.0 || n == 0 {
        return f64::INFINITY;
    }
    let mse = sum / n as f64;
    10.0 * (255.0f64 * 255.0 / mse).log10()
}

fn rgb8(frame: &Frame) -> Vec<u8> {
    frame
        .srgb8
        .chunks_exact(4)
        .flat_map(|p| [p[0], p[1], p[2]])
        .collect()
}

/// The mean FLIP error of `test` against `reference` (sRGB images of the
/// same size), at FLIP's default 67 pixels per degree.
pub fn flip_mean(reference: &Frame, test: &Frame) -> f32 {
    let r = nv_flip::FlipImageRgb8::with_data(reference.width, reference.height, &rgb8(reference));
    let t = nv_flip::FlipImageRgb8::with_data(test.width, test.height, &rgb8(test));
    let error = nv_flip::flip(r, t, nv_flip::DEFAULT_PIXELS_PER_DEGREE);
    nv_flip::FlipPool::from_image(&error).mean()
}

/// FLIP mean and PSNR for every pair `a < b` of `frames` (all one size).
pub fn pair_metrics(frames: &[Frame]) -> Vec<PairMetrics> {
    let mut out = Vec::new();
    for a in 0..frames.len() {
        for b in a + 1..frames.len() {
            out.push(PairMetrics {
                a,
                b,
                flip_mean: flip_mean(&frames[a], &frames[b]),
                psnr_db: psnr_rgba8(&frames[a].srgb8, &frames[b].srgb8),
            });
        }
    }
    out
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

/// Height in pixels of the label bar above each view on a contact sheet.
pub const LABEL_BAR_PX: u32 = 30;
const GAP_PX: u32 = 4;

/// The built-in label font (Hack, shipped with egui's default fonts).
fn label_font() -> FontRef<'static> {
    FontRef::try_from_slice(epaint_default_fonts::HACK_REGULAR)
        .expect("the font compiled into epaint_default_fonts parses")
}

/// Draws `text` with its top-left corner at (`x`, `y`), `size_px` tall,
/// blending `color` over `image` by glyph coverage.
pub fn draw_text(
    image: &mut image::RgbaImage,
    x: f32,
    y: f32,
    size_px: f32,
    color: [u8; 3],
    text: &str,
) {
    let font = label_font();
    let scale = PxScale::from(size_px);
    let scaled = font.as_scaled(scale);
    let baseline = y + scaled.ascent();
    let mut caret = x;
    let mut previous = None;
    for ch in text.chars() {
        let id = scaled.glyph_id(ch);
        if let Some(prev) = previous {
            caret += scaled.kern(prev, id);
        }
        previous = Some(id);
        let glyph = id.with_scale_and_position(scale, ab_glyph::point(caret, baseline));
        caret += scaled.h_advance(id);
        let Some(outlined) = font.outline_glyph(glyph) else {
            continue;
        };
        let bounds = outlined.px_bounds();
        outlined.draw(|gx, gy, coverage| {
            let px = bounds.min.x as i64 + i64::from(gx);
            let py = bounds.min.y as i64 + i64::from(gy);
            if px < 0 || py < 0 || px >= i64::from(image.width()) || py >= i64::from(image.height())
            {
                return;
            }
            let p = image.get_pixel_mut(px as u32, py as u32);
            let a = coverage.clamp(0.0, 1.0);
            for c in 0..3 {
                p[c] = (f32::from(p[c]) * (1.0 - a) + f32::from(color[c]) * a).round() as u8;
            }
        });
    }
}

/// Width in pixels of `text` drawn `size_px` tall.
pub fn text_width(size_px: f32, text: &str) -> f32 {
    let font = label_font();
    let scaled = font.as_scaled(PxScale::from(size_px));
    text.chars()
        .map(|c| scaled.h_advance(scaled.glyph_id(c)))
        .sum()
}

/// Columns of a contact sheet of `n` views: one row up to 4, then a grid.
pub fn sheet_columns(n: usize) -> usize {
    if n <= 4 {
        n.max(1)
    } else {
        (n as f64).sqrt().ceil() as usize
    }
}

/// A contact sheet: each frame under a dark bar holding its label.
pub fn contact_sheet(frames: &[(String, &Frame)]) -> image::RgbaImage {
    let n = frames.len().max(1);
    let cols = sheet_columns(n) as u32;
    let rows = n.div_ceil(cols as usize) as u32;
    let (w, h) = frames
        .first()
        .map(|(_, f)| (f.width, f.height))
        .unwrap_or((1, 1));
    let cell_h = h + LABEL_BAR_PX;
    let sheet_w = cols * w + (cols + 1) * GAP_PX;
    let sheet_h = rows * cell_h + (rows + 1) * GAP_PX;
    let mut sheet = image::RgbaImage::from_pixel(sheet_w, sheet_h, image::Rgba([24, 24, 28, 255]));
    for (i, (label, frame)) in frames.iter().enumerate() {
        let (col, row) = (i as u32 % cols, i as u32 / cols);
        let x0 = GAP_PX + col * (w + GAP_PX);
        let y0 = GAP_PX + row * (cell_h + GAP_PX);
        draw_text(
            &mut sheet,
            x0 as f32 + 6.0,
            y0 as f32 + 6.0,
            18.0,
            [235, 235, 235],
            label,
        );
        let img = frame.to_rgba8();
        image::imageops::replace(
            &mut sheet,
            &img,
            i64::from(x0),
            i64::from(y0 + LABEL_BAR_PX),
        );
    }
    sheet
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_view_lists() {
        let v = ViewSpec::parse_list("blinn-phong, toon:4 ,TOON:7,scene").unwrap();
        let labels: Vec<String> = v.iter().map(ViewSpec::label).collect();
        assert_eq!(labels, ["blinn-phong", "toon:4", "toon:7", "scene"]);
        assert_eq!(ViewSpec::parse("toon").unwrap().label(), "toon:4");
        let err = ViewSpec::parse_list("toon:4,phong")
            .unwrap_err()
            .to_string();
        assert!(err.contains("view 2") && err.contains("phong"), "{err}");
        assert!(ViewSpec::parse_list("").is_err());
        assert!(ViewSpec::parse_list("toon:99").is_err());
        let many = vec!["toon"; MAX_VIEWS + 1].join(",");
        assert!(ViewSpec::parse_list(&many).is_err());
    }

    #[test]
    fn labels_of_uneven_toon_models_list_thresholds() {
        let model = ShadingModel::Toon(crate::scene::Toon {
            thresholds: vec![0.15, 0.5, 0.85],
            specular_threshold: 0.5,
            rim: None,
        });
        assert_eq!(model_label(&model), "toon (4 bands: 0.15, 0.50, 0.85)");
    }

    #[test]
    fn psnr_follows_its_definition() {
        let a = vec![10u8, 20, 30, 255, 40, 50, 60, 255];
        assert!(psnr_rgba8(&a, &a).is_infinite());
        // One channel off by 3 of six: MSE = 9 / 6 = 1.5; alpha is ignored.
        let mut b = a.clone();
        b[1] = 23;
        b[3] = 0;
        let expected = 10.0 * (255.0f64 * 255.0 / 1.5).log10();
        assert!((psnr_rgba8(&a, &b) - expected).abs() < 1e-9);
    }

    fn flat(w: u32, h: u32, rgb: [u8; 3]) -> Frame {
        Frame {
            width: w,
            height: h,
            srgb8: (0..w * h)
                .flat_map(|_| [rgb[0], rgb[1], rgb[2], 255])
                .collect(),
            linear: None,
        }
    }

    #[test]
    fn flip_is_zero_for_equal_images_and_grows_with_difference() {
        let grey = flat(32, 32, [128, 128, 128]);
        let near = flat(32, 32, [136, 128, 128]);
        let far = flat(32, 32, [255, 0, 0]);
        assert_eq!(flip_mean(&grey, &grey), 0.0);
        let small = flip_mean(&grey, &near);
        let large = flip_mean(&grey, &far);
        assert!(small > 0.0 && small < large, "{small} vs {large}");
        let pairs = pair_metrics(&[grey, near, far]);
        assert_eq!(
            pairs.iter().map(|p| (p.a, p.b)).collect::<Vec<_>>(),
            [(0, 1), (0, 2), (1, 2)]
        );
    }

    #[test]
    fn contact_sheet_places_views_and_labels() {
        let red = flat(40, 20, [200, 0, 0]);
        let blue = flat(40, 20, [0, 0, 200]);
        let sheet = contact_sheet(&[("A".into(), &red), ("B".into(), &blue)]);
        assert_eq!(sheet.width(), 2 * 40 + 3 * GAP_PX);
        assert_eq!(sheet.height(), 20 + LABEL_BAR_PX + 2 * GAP_PX);
        let y = GAP_PX + LABEL_BAR_PX + 10;
        assert_eq!(sheet.get_pixel(GAP_PX + 20, y).0, [200, 0, 0, 255]);
        assert_eq!(sheet.get_pixel(2 * GAP_PX + 40 + 20, y).0, [0, 0, 200, 255]);
        // The label bar holds light text pixels.
        let bright = (GAP_PX..GAP_PX + LABEL_BAR_PX)
            .flat_map(|y| (GAP_PX..GAP_PX + 40).map(move |x| (x, y)))
            .filter(|&(x, y)| sheet.get_pixel(x, y).0[0] > 150)
            .count();
        assert!(bright > 5, "{bright} label pixels");
    }
}
