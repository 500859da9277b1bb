//! Screenshots: PNG files with a timestamped name that never replaces an
//! existing file.

use std::io::Write;
use std::path::{Path, PathBuf};

/// The local time as `20250131-142502`, for file names.
pub fn timestamp() -> String {
    jiff::Zoned::now().strftime("%Y%m%d-%H%M%S").to_string()
}

/// Writes `rgba` (RGBA8, top row first) as a PNG named `STEM.png` in `dir`,
/// or `STEM-2.png`, `STEM-3.png`, ... if that exists: files are created
/// with `create_new`, so an existing file is never replaced, even by a
/// second celray saving at the same second. Returns the path written.
pub fn save_new_png(
    dir: &Path,
    stem: &str,
    width: u32,
    height: u32,
    rgba: &[u8],
) -> std::io::Result<PathBuf> {
    let bytes = encode_png(width, height, rgba)?;
    for n in 1..10_000u32 {
        let name = if n == 1 {
            format!("{stem}.png")
        } else {
            format!("{stem}-{n}.png")
        };
        let path = dir.join(name);
        match std::fs::OpenOptions::new()
            .write(true)
            .create_new(true)
            .open(&path)
        {
            Ok(mut file) => {
                file.write_all(&bytes)?;
                return Ok(path);
            }
            Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => continue,
            Err(e) => return Err(e),
        }
    }
    Err(std::io::Error::other(format!(
        "{}: too many screenshots named {stem}",
        dir.display()
    )))
}

/// Writes `rgba` as a PNG at `path`, replacing it (for `--screenshot PATH`).
pub fn save_png(path: &Path, width: u32, height: u32, rgba: &[u8]) -> std::io::Result<()> {
    std::fs::write(path, encode_png(width, height, rgba)?)
}

fn encode_png(width: u32, height: u32, rgba: &[u8]) -> std::io::Result<Vec<u8>> {
    use image::ImageEncoder;
    let mut out = Vec::new();
    image::codecs::png::PngEncoder::new(&mut out)
        .write_image(rgba, width, height, image::ExtendedColorType::Rgba8)
        .map_err(std::io::Error::other)?;
    Ok(out)
}

/// A file-name-safe version of a view label (`toon:4` -> `toon4`).
pub fn slug(label: &str) -> String {
    let s: String = label
        .chars()
        .map(|c| if c.is_ascii_alphanumeric() { c } else { '-' })
        .collect();
    s.split('-')
        .filter(|p| !p.is_empty())
        .collect::<Vec<_>>()
        .join("-")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn never_overwrites_an_existing_file() {
        let dir = std::env::temp_dir().join(format!("celray-shots-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        let red = [255u8, 0, 0, 255];
        let blue = [0u8, 0, 255, 255];
        let a = save_new_png(&dir, "shot", 1, 1, &red).unwrap();
        let b = save_new_png(&dir, "shot", 1, 1, &blue).unwrap();
        let c = save_new_png(&dir, "shot", 1, 1, &blue).unwrap();
        assert_eq!(a, dir.join("shot.png"));
        assert_eq!(b, dir.join("shot-2.png"));
        assert_eq!(c, dir.join("shot-3.png"));
        // The first file still holds the first image.
        let first = image::open(&a).unwrap().to_rgba8();
        assert_eq!(first.get_pixel(0, 0).0, red);
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn timestamps_and_slugs_are_file_name_safe() {
        let t = timestamp();
        assert_eq!(t.len(), 15, "{t}");
        assert!(t.chars().all(|c| c.is_ascii_digit() || c == '-'));
        assert_eq!(slug("toon:4"), "toon-4");
        assert_eq!(slug("toon (4 bands: 0.15, 0.50)"), "toon-4-bands-0-15-0-50");
    }
}
