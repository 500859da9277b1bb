//! Shader hot reload: shader files read from a folder on disk replace the
//! embedded ones for renderers made afterwards; a broken file is an error
//! that names it, and the embedded shaders still work after it.

use std::path::{Path, PathBuf};

use celray::gpu::shader::{ShaderOverrides, SHADER_FILES};
use celray::gpu::{AdapterChoice, Gpu};
use celray::render::{RenderSettings, Renderer};
use celray::scene::Scene;

fn copy_shaders(name: &str) -> PathBuf {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR"))
        .join("shader-reload")
        .join(name);
    let _ = std::fs::remove_dir_all(&dir);
    for (file, text) in SHADER_FILES {
        let path = dir.join(file);
        std::fs::create_dir_all(path.parent().unwrap()).unwrap();
        std::fs::write(path, text).unwrap();
    }
    dir
}

fn small() -> RenderSettings {
    RenderSettings {
        width: 32,
        height: 18,
        spp: 1,
        ..RenderSettings::default()
    }
}

fn render(gpu: &Gpu) -> Result<Vec<u8>, celray::gpu::GpuError> {
    let mut r = Renderer::new(gpu, Scene::builtin_default(), small())?;
    r.render_to_convergence(gpu, |_, _| {})?;
    r.read_srgb8(gpu)
}

#[test]
fn shaders_on_disk_replace_the_embedded_ones() {
    let gpu = Gpu::new_headless(&AdapterChoice::for_tests()).unwrap();
    let embedded = render(&gpu).unwrap();

    // An unchanged copy renders the same image.
    let dir = copy_shaders("same");
    gpu.set_shader_overrides(Some(ShaderOverrides::read_dir(&dir).unwrap()));
    assert_eq!(render(&gpu).unwrap(), embedded);

    // An edited resolve shader is used: every pixel magenta.
    let resolve = dir.join("resolve.wgsl");
    let text = std::fs::read_to_string(&resolve).unwrap();
    let edited = text.replace(
        "return vec4<f32>(c, 1.0);",
        "return vec4<f32>(1.0, 0.0, 1.0, 1.0);",
    );
    assert_ne!(edited, text, "resolve.wgsl changed shape; update this test");
    std::fs::write(&resolve, edited).unwrap();
    gpu.set_shader_overrides(Some(ShaderOverrides::read_dir(&dir).unwrap()));
    let magenta = render(&gpu).unwrap();
    assert!(magenta.chunks(4).all(|p| p == [255, 0, 255, 255]));

    // Back to the embedded shaders.
    gpu.set_shader_overrides(None);
    assert_eq!(render(&gpu).unwrap(), embedded);
}

#[test]
fn a_broken_shader_is_an_error_naming_the_file() {
    let gpu = Gpu::new_headless(&AdapterChoice::for_tests()).unwrap();
    let dir = copy_shaders("broken");
    let raster = dir.join("raster.wgsl");
    let mut text = std::fs::read_to_string(&raster).unwrap();
    text.push_str("\nfn broken( -> {\n");
    std::fs::write(&raster, text).unwrap();
    gpu.set_shader_overrides(Some(ShaderOverrides::read_dir(&dir).unwrap()));
    let err = match Renderer::new(&gpu, Scene::builtin_default(), small()) {
        Ok(_) => panic!("a broken raster.wgsl built a renderer"),
        Err(e) => e.to_string(),
    };
    // The error points into raster.wgsl itself, at the broken line.
    let broken_line = std::fs::read_to_string(&raster).unwrap().lines().count();
    assert!(
        err.contains(&format!("(raster.wgsl:{broken_line}:")),
        "{err}"
    );
    // The device is still usable, and the embedded shaders still work.
    let _ = gpu.take_errors();
    gpu.set_shader_overrides(None);
    assert!(render(&gpu).is_ok());
}
