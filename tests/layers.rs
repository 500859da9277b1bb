//! The layer rules of docs/architecture.md, checked on the source text: a
//! layer that names a crate or module it must not import fails here, with
//! the file and line. Comments are skipped, so a doc comment may still say
//! what a layer does not do.

use std::fs;
use std::path::{Path, PathBuf};

/// One rule: every `.rs` file under `root` (a folder or one file) must not
/// name any word of `forbidden` (a crate path like `wgpu` or a module path
/// like `crate::render`).
struct Rule {
    root: &'static str,
    forbidden: &'static [&'static [&'static str]],
}

/// What no CPU-only layer may name: the GPU, the passes, the window.
const CPU_ONLY: &[&str] = &[
    "wgpu",
    "winit",
    "egui",
    "crate::gpu",
    "crate::render",
    "crate::app",
    "crate::capture",
];

/// The headless layers above capture: what one view shows and the
/// comparison sheets. Sampling and the fixtures sit below them.
const ABOVE_CAPTURE: &[&str] = &["crate::view", "crate::compare"];

/// What no layer below the app may name.
const UI: &[&str] = &["winit", "egui", "egui_wgpu", "egui_winit", "crate::app"];

const RULES: &[Rule] = &[
    Rule {
        root: "src/scene",
        forbidden: &[CPU_ONLY, &["crate::accel", "crate::sampling"]],
    },
    Rule {
        root: "src/sampling.rs",
        forbidden: &[
            CPU_ONLY,
            &["crate::accel", "crate::scene", "crate::fixtures", "clap"],
            ABOVE_CAPTURE,
        ],
    },
    Rule {
        root: "src/accel",
        forbidden: &[CPU_ONLY],
    },
    Rule {
        root: "src/gpu",
        forbidden: &[UI, &["crate::render", "crate::capture"]],
    },
    Rule {
        root: "src/render",
        forbidden: &[UI],
    },
    Rule {
        root: "src/capture.rs",
        forbidden: &[UI],
    },
    Rule {
        root: "src/view.rs",
        forbidden: &[UI],
    },
    Rule {
        root: "src/compare",
        forbidden: &[UI],
    },
    Rule {
        root: "src/fixtures.rs",
        forbidden: &[
            CPU_ONLY,
            &["crate::accel", "crate::sampling"],
            ABOVE_CAPTURE,
        ],
    },
];

fn rust_files(root: &Path) -> Vec<PathBuf> {
    if root.is_file() {
        return vec![root.to_path_buf()];
    }
    let mut files = Vec::new();
    let mut stack = vec![root.to_path_buf()];
    while let Some(dir) = stack.pop() {
        for entry in fs::read_dir(&dir).expect("read source folder") {
            let path = entry.expect("folder entry").path();
            if path.is_dir() {
                stack.push(path);
            } else if path.extension().is_some_and(|e| e == "rs") {
                files.push(path);
            }
        }
    }
    files.sort();
    files
}

/// True when `line` names `word` as a path segment start: `wgpu::`,
/// `use wgpu`, `crate::render::x`, `crate::render;`, `crate::{gpu, render}`
/// (not `wgpu_types` or `crate::renderer`).
fn names(line: &str, word: &str) -> bool {
    if let (Some(module), Some(open)) = (word.strip_prefix("crate::"), line.find("crate::{")) {
        let group = &line[open + "crate::{".len()..];
        let group = group.split('}').next().unwrap_or(group);
        if group
            .split(|c: char| c == ',' || c.is_whitespace())
            .any(|part| part == module || part.starts_with(&format!("{module}::")))
        {
            return true;
        }
    }
    line.match_indices(word).any(|(at, _)| {
        let before = line[..at].chars().next_back();
        let after = line[at + word.len()..].chars().next();
        let starts = before.is_none_or(|c| !(c.is_alphanumeric() || c == '_' || c == ':'));
        let ends = after.is_none_or(|c| !(c.is_alphanumeric() || c == '_'));
        starts && ends
    })
}

#[test]
fn layers_import_only_what_the_architecture_allows() {
    let manifest = Path::new(env!("CARGO_MANIFEST_DIR"));
    let mut broken = Vec::new();
    let mut checked = 0;
    for rule in RULES {
        let files = rust_files(&manifest.join(rule.root));
        assert!(!files.is_empty(), "no Rust files under {}", rule.root);
        for file in files {
            checked += 1;
            let text = fs::read_to_string(&file).expect("read source file");
            for (number, line) in text.lines().enumerate() {
                let code = line.split("//").next().unwrap_or("");
                for word in rule.forbidden.iter().copied().flatten() {
                    if names(code, word) {
                        broken.push(format!(
                            "{}:{}: the {} layer names `{}`: {}",
                            file.strip_prefix(manifest).unwrap_or(&file).display(),
                            number + 1,
                            rule.root,
                            word,
                            line.trim()
                        ));
                    }
                }
            }
        }
    }
    assert!(checked > 20, "only {checked} files checked: wrong roots?");
    assert!(
        broken.is_empty(),
        "layer rules broken (docs/architecture.md):\n{}",
        broken.join("\n")
    );
}

#[test]
fn the_checker_sees_an_import_and_ignores_look_alikes() {
    assert!(names("use wgpu::util::DeviceExt;", "wgpu"));
    assert!(names("    let x: wgpu::Buffer;", "wgpu"));
    assert!(names("use crate::render;", "crate::render"));
    assert!(names(
        "use crate::{gpu, render::Renderer};",
        "crate::render"
    ));
    assert!(!names("use crate::{gpu, renderer};", "crate::render"));
    assert!(!names("use wgpu_types::X;", "wgpu"));
    assert!(!names("use crate::renderer::X;", "crate::render"));
    assert!(!names("let my_wgpu = 1;", "wgpu"));
}
