//! Image difference metrics between rendered views: FLIP (NVIDIA's
//! perceptual difference, via the `nv-flip` crate) and PSNR.

use crate::capture::Frame;

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

#[cfg(test)]
mod tests {
    use super::*;

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

    #[test]
    fn flip_is_zero_for_equal_images_and_grows_with_difference() {
        let grey = Frame::flat(32, 32, [128, 128, 128]);
        let near = Frame::flat(32, 32, [136, 128, 128]);
        let far = Frame::flat(32, 32, [255, 0, 0]);
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
}
