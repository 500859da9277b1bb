//! Sample patterns and the [`SampleSchedule`]: sample k of a frame gets a
//! sub-pixel offset, a lens point and a shutter time that depend only on
//! (k, sample count, seed), so the same settings always give the same image.
//! The pattern's names (`PixelPattern::name`) live here too. Pure math, no
//! GPU, no clap.

use glam::Vec2;

/// How sub-pixel positions are spread over a pixel.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum PixelPattern {
    /// Cell centres of an n x n grid (n = ceil(sqrt(spp))).
    Regular,
    /// Independent uniform points.
    Random,
    /// One uniform point in each cell of the n x n grid (stratified).
    #[default]
    Jittered,
    /// The Halton (2, 3) sequence, shifted by a seed-dependent rotation.
    Halton,
}

impl PixelPattern {
    /// Every pattern, in the order menus and `--help` list them.
    pub const ALL: [PixelPattern; 4] = [
        PixelPattern::Regular,
        PixelPattern::Random,
        PixelPattern::Jittered,
        PixelPattern::Halton,
    ];

    /// The word the CLI, the panel and reports use.
    pub fn name(self) -> &'static str {
        match self {
            PixelPattern::Regular => "regular",
            PixelPattern::Random => "random",
            PixelPattern::Jittered => "jittered",
            PixelPattern::Halton => "halton",
        }
    }

    /// The pattern called `text`, if any.
    pub fn parse(text: &str) -> Option<PixelPattern> {
        Self::ALL.into_iter().find(|p| p.name() == text)
    }
}

/// A 32-bit integer hash (Jarkko Lempiäinen's "lowbias32" by Chris Wellons).
pub fn hash_u32(mut x: u32) -> u32 {
    x ^= x >> 16;
    x = x.wrapping_mul(0x7feb_352d);
    x ^= x >> 15;
    x = x.wrapping_mul(0x846c_a68b);
    x ^= x >> 16;
    x
}

/// A uniform number in [0, 1) from three integers.
pub fn uniform(a: u32, b: u32, c: u32) -> f32 {
    let h = hash_u32(a ^ hash_u32(b.wrapping_add(0x9e37_79b9) ^ hash_u32(c)));
    (h >> 8) as f32 / (1u32 << 24) as f32
}

/// The radical inverse of `i` in `base` (van der Corput).
pub fn radical_inverse(mut i: u32, base: u32) -> f32 {
    let inv = 1.0 / base as f64;
    let mut scale = inv;
    let mut r = 0.0f64;
    while i > 0 {
        r += (i % base) as f64 * scale;
        i /= base;
        scale *= inv;
    }
    r as f32
}

/// Sub-pixel offset in [0, 1)^2 of sample `k` of `spp` for `seed`.
pub fn pixel_offset(pattern: PixelPattern, k: u32, spp: u32, seed: u32) -> Vec2 {
    // Grids above 4096 x 4096 cells are pointless (and would overflow n * n).
    let n = (spp.clamp(1, 1 << 24) as f32).sqrt().ceil() as u32;
    let cell = Vec2::new((k % n) as f32, ((k / n) % n) as f32);
    match pattern {
        PixelPattern::Regular => (cell + Vec2::splat(0.5)) / n as f32,
        PixelPattern::Random => Vec2::new(uniform(k, seed, 1), uniform(k, seed, 2)),
        PixelPattern::Jittered => {
            // The cells are visited in a seed-shuffled order so that a
            // partial count (spp not a square) still spreads over the pixel.
            let cells = n * n;
            let j = shuffled_index(k % cells, cells, seed);
            let cell = Vec2::new((j % n) as f32, (j / n) as f32);
            (cell + Vec2::new(uniform(k, seed, 3), uniform(k, seed, 4))) / n as f32
        }
        PixelPattern::Halton => {
            let shift = Vec2::new(uniform(seed, 0, 5), uniform(seed, 0, 6));
            let p = Vec2::new(radical_inverse(k + 1, 2), radical_inverse(k + 1, 3)) + shift;
            p - p.floor()
        }
    }
}

/// What sample k of a frame uses: its sub-pixel offset, lens point,
/// shutter time and the seed its per-pixel random numbers are drawn with.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Sample {
    /// Sub-pixel position in [0, 1)^2 (0.5, 0.5 is the pixel centre).
    pub pixel_offset: Vec2,
    /// Point on the unit aperture (scaled by the aperture radius later).
    pub lens: Vec2,
    /// Fraction of the shutter interval in [0, 1).
    pub time: f32,
    /// Seed of the shaders' random numbers for this sample (hashed with
    /// the pixel and the sample index): the schedule's seed.
    pub seed: u32,
}

/// The aperture's shape in unit coordinates (radius 1).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Aperture {
    Disk,
    Square,
    /// A regular polygon with this many blades, turned by `rotation` radians.
    Polygon {
        blades: u32,
        rotation: f32,
    },
}

/// Which sample k of a frame is: sample k -> {pixel jitter, lens point,
/// shutter time, seed}, for one pattern, aperture, sample count and seed
/// (built from the render settings and the camera by
/// `RenderSettings::sample_schedule`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SampleSchedule {
    pub pattern: PixelPattern,
    pub aperture: Aperture,
    /// Samples per pixel the frame converges to.
    pub spp: u32,
    pub seed: u32,
}

impl SampleSchedule {
    /// Sample `k`: every dimension is drawn from the same pattern, each
    /// with its own seed, so pixel offset, lens point and time are
    /// stratified (for jittered, Halton) and uncorrelated with each other.
    pub fn sample(&self, k: u32) -> Sample {
        sample(self.pattern, self.aperture, k, self.spp, self.seed)
    }
}

fn sample(pattern: PixelPattern, aperture: Aperture, k: u32, spp: u32, seed: u32) -> Sample {
    let lens_square = pixel_offset(pattern, k, spp, seed ^ 0x5bd1_e995);
    let time = match pattern {
        PixelPattern::Regular => {
            (k % spp.max(1)) as f32 / spp.max(1) as f32 + 0.5 / spp.max(1) as f32
        }
        PixelPattern::Random => uniform(k, seed, 7),
        // Stratified in time: one random time in each 1/spp of the shutter,
        // visited in a shuffled order.
        PixelPattern::Jittered | PixelPattern::Halton => {
            let n = spp.clamp(1, 1 << 24);
            (shuffled_index(k % n, n, seed ^ 0x27d4_eb2d) as f32 + uniform(k, seed, 8)) / n as f32
        }
    };
    Sample {
        pixel_offset: pixel_offset(pattern, k, spp, seed),
        lens: map_to_aperture(lens_square, aperture),
        time,
        seed,
    }
}

/// Maps a uniform point of [0, 1)^2 to a uniform point of the aperture.
pub fn map_to_aperture(u: Vec2, aperture: Aperture) -> Vec2 {
    match aperture {
        Aperture::Disk => concentric_disk(u),
        Aperture::Square => u * 2.0 - Vec2::ONE,
        Aperture::Polygon { blades, rotation } => {
            // Pick a triangle (centre, corner i, corner i + 1) by u.x, then a
            // uniform point in it (the square folded along its diagonal).
            let n = blades.max(3);
            let scaled = u.x * n as f32;
            let i = (scaled as u32).min(n - 1);
            let (mut a, mut b) = (scaled - i as f32, u.y);
            if a + b > 1.0 {
                (a, b) = (1.0 - a, 1.0 - b);
            }
            let corner = |j: u32| {
                let phi = rotation + std::f32::consts::TAU * j as f32 / n as f32;
                Vec2::new(phi.cos(), phi.sin())
            };
            corner(i) * a + corner(i + 1) * b
        }
    }
}

/// Shirley and Chiu's concentric map of the square to the unit disk: uniform
/// and with low distortion, so stratification survives.
pub fn concentric_disk(u: Vec2) -> Vec2 {
    let p = u * 2.0 - Vec2::ONE;
    if p == Vec2::ZERO {
        return Vec2::ZERO;
    }
    let (r, theta) = if p.x.abs() > p.y.abs() {
        (p.x, std::f32::consts::FRAC_PI_4 * (p.y / p.x))
    } else {
        (
            p.y,
            std::f32::consts::FRAC_PI_2 - std::f32::consts::FRAC_PI_4 * (p.x / p.y),
        )
    };
    Vec2::new(theta.cos(), theta.sin()) * r
}

/// A bijection of 0..n chosen by `seed` (cycle walking over a hashed
/// power-of-two domain), used to order the strata of the jittered pattern.
fn shuffled_index(i: u32, n: u32, seed: u32) -> u32 {
    let bits = 32 - (n.max(2) - 1).leading_zeros();
    let mask = (1u32 << bits) - 1;
    let mut x = i;
    loop {
        // An invertible mix on `bits` bits: xor-shift and odd multiply.
        for round in 0..3u32 {
            x ^= hash_u32(seed ^ round) & mask;
            x = x.wrapping_mul(hash_u32(seed.wrapping_add(round)) | 1) & mask;
            x ^= x >> (bits / 2).max(1);
        }
        if x < n {
            return x;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn regular_is_cell_centres() {
        assert_eq!(
            pixel_offset(PixelPattern::Regular, 0, 1, 7),
            Vec2::splat(0.5)
        );
        assert_eq!(
            pixel_offset(PixelPattern::Regular, 3, 4, 7),
            Vec2::splat(0.75)
        );
    }

    #[test]
    fn jittered_puts_one_point_in_each_cell() {
        for seed in 0..20 {
            let n = 5;
            let mut seen = vec![false; n * n];
            for k in 0..(n * n) as u32 {
                let p = pixel_offset(PixelPattern::Jittered, k, (n * n) as u32, seed);
                assert!(p.x >= 0.0 && p.x < 1.0 && p.y >= 0.0 && p.y < 1.0);
                let c = (p.y * n as f32) as usize * n + (p.x * n as f32) as usize;
                assert!(!seen[c], "cell {c} twice for seed {seed}");
                seen[c] = true;
            }
        }
    }

    #[test]
    fn shuffle_is_a_permutation() {
        for n in [1u32, 2, 3, 7, 16, 100] {
            let mut v: Vec<u32> = (0..n).map(|i| shuffled_index(i, n, 42)).collect();
            v.sort();
            assert_eq!(v, (0..n).collect::<Vec<_>>());
        }
    }

    #[test]
    fn random_mean_is_a_half() {
        // Mean of 4096 U(0,1) draws: standard error 1/sqrt(12*4096) = 0.0045;
        // 0.02 is more than four standard errors.
        let m: f32 = (0..4096)
            .map(|k| pixel_offset(PixelPattern::Random, k, 4096, 3).x)
            .sum::<f32>()
            / 4096.0;
        assert!((m - 0.5).abs() < 0.02, "mean {m}");
    }

    #[test]
    fn apertures_are_uniform_and_inside() {
        // Mean of |p|^2 over a uniform unit disk is 1/2; over a regular
        // hexagon of circumradius 1 it is 5/12 (polar moment / area).
        // 4096 jittered samples: standard errors below 0.005; 0.02 is safe.
        let mean_r2 = |aperture| {
            let schedule = SampleSchedule {
                pattern: PixelPattern::Jittered,
                aperture,
                spp: 4096,
                seed: 9,
            };
            (0..4096)
                .map(|k| schedule.sample(k).lens.length_squared())
                .sum::<f32>()
                / 4096.0
        };
        assert!((mean_r2(Aperture::Disk) - 0.5).abs() < 0.02);
        assert!(
            (mean_r2(Aperture::Polygon {
                blades: 6,
                rotation: 0.3
            }) - 5.0 / 12.0)
                .abs()
                < 0.02
        );
        assert!((mean_r2(Aperture::Square) - 2.0 / 3.0).abs() < 0.02);
        let random = SampleSchedule {
            pattern: PixelPattern::Random,
            aperture: Aperture::Disk,
            spp: 512,
            seed: 1,
        };
        for k in 0..512 {
            let p = random.sample(k).lens;
            assert!(p.length() <= 1.0 + 1e-6);
        }
    }

    #[test]
    fn times_are_stratified_over_the_shutter() {
        let schedule = SampleSchedule {
            pattern: PixelPattern::Jittered,
            aperture: Aperture::Disk,
            spp: 64,
            seed: 5,
        };
        let mut t: Vec<f32> = (0..64).map(|k| schedule.sample(k).time).collect();
        t.sort_by(f32::total_cmp);
        for (i, v) in t.iter().enumerate() {
            assert!(
                *v >= i as f32 / 64.0 && *v < (i + 1) as f32 / 64.0,
                "sample {i}: {v}"
            );
        }
    }

    #[test]
    fn radical_inverse_base_two() {
        assert_eq!(radical_inverse(1, 2), 0.5);
        assert_eq!(radical_inverse(3, 2), 0.75);
        assert!((radical_inverse(1, 3) - 1.0 / 3.0).abs() < 1e-7);
    }
}
