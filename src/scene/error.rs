//! The error type of the scene module.

use std::path::PathBuf;

/// Everything that can go wrong while loading, validating or editing a scene.
///
/// Every message names the file, instance, material, key, ... it is about,
/// so that it can be shown to the user as is.
#[derive(Debug, thiserror::Error)]
pub enum SceneError {
    /// The scene file could not be read. The reason is part of the
    /// message (not a `source`), so a printed error chain says it once.
    #[error("cannot read scene file {}: {reason}", path.display())]
    Io { path: PathBuf, reason: String },

    /// The file is not valid RON, or does not have the shape of a scene
    /// file (unknown field, wrong type, missing field, ...).
    #[error("{file}:{line}:{col}: {message}")]
    Syntax {
        file: String,
        line: usize,
        col: usize,
        message: String,
    },

    /// The `version` field holds a version this build cannot read.
    #[error(
        "{file}: unsupported scene format version {found}; this build reads version {supported}"
    )]
    UnsupportedVersion {
        file: String,
        found: u32,
        supported: u32,
    },

    /// An instance names a material or shape that the file does not define.
    #[error(
        "{file}: instance {instance}: unknown {kind} \"{name}\"; available {kind}s: {available}"
    )]
    UnknownName {
        file: String,
        instance: usize,
        /// `"material"` or `"shape"`.
        kind: &'static str,
        name: String,
        /// The names that are defined, comma separated.
        available: String,
    },

    /// A mesh file referenced by the scene does not exist.
    #[error("mesh file {} not found (shape \"{shape}\" in scene file {scene}; mesh paths are relative to the scene file's directory)", path.display())]
    MeshNotFound {
        path: PathBuf,
        shape: String,
        scene: String,
    },

    /// A mesh file exists but could not be read or understood.
    #[error("cannot load mesh {}: {reason}", path.display())]
    MeshParse { path: PathBuf, reason: String },

    /// A base-colour image is missing, cannot be decoded, or is over a limit.
    #[error("texture {} of material \"{material}\": {reason}", path.display())]
    Texture {
        path: PathBuf,
        material: String,
        reason: String,
    },

    /// A value is out of range or inconsistent; `context` says where
    /// (for example `scene.ron: material "red"` or `instance 3`).
    #[error("{context}: {message}")]
    Invalid { context: String, message: String },

    /// `apply_override` was given a key it does not know.
    #[error("unknown scene setting \"{key}\"; valid keys: {valid}")]
    UnknownKey { key: String, valid: String },

    /// `apply_override` was given a value it cannot parse for its key.
    #[error("bad value \"{value}\" for scene setting \"{key}\": expected {expected} ({reason})")]
    BadValue {
        key: String,
        value: String,
        expected: String,
        reason: String,
    },

    /// `parse_shading_model` was given text it does not understand.
    #[error(
        "unknown shading model \"{text}\"; accepted forms: \"blinn-phong\", \"toon\" (4 bands), \"toon:N\" with N in 1..={max}"
    )]
    BadShadingModel { text: String, max: u32 },
}

impl SceneError {
    /// Shorthand for [`SceneError::Invalid`].
    pub(crate) fn invalid(context: impl Into<String>, message: impl Into<String>) -> Self {
        SceneError::Invalid {
            context: context.into(),
            message: message.into(),
        }
    }

    /// Prefixes the context of an [`SceneError::Invalid`] with the file
    /// name, so that validation errors found while loading name the file.
    pub(crate) fn in_file(self, file: &str) -> Self {
        match self {
            SceneError::Invalid { context, message } => SceneError::Invalid {
                context: format!("{file}: {context}"),
                message,
            },
            other => other,
        }
    }
}
