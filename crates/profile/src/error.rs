use std::path::PathBuf;

/// Everything that can go wrong choosing or reading a profile.
#[derive(Debug, thiserror::Error)]
pub enum ProfileError {
    #[error("profile {file}:{line}:{column}: key `{key}`: {message}")]
    Parse {
        file: String,
        line: usize,
        column: usize,
        /// Dotted path of the offending key (`render_pass.max_color_attachments`), or `<root>`.
        key: String,
        message: String,
    },
    #[error("profile {file}: key `{key}`: {reason}")]
    Invalid {
        file: String,
        key: String,
        reason: String,
    },
    #[error("profile {name:?} is defined twice: in {first} and in {second}")]
    DuplicateName {
        name: String,
        first: String,
        second: String,
    },
    #[error("reading profile directory {path}: {source}")]
    Io {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    #[error("no profile named {name:?} (available: {available})")]
    UnknownProfile { name: String, available: String },
    #[error("no profile matches device {device:?} and no fallback covers its type {device_type}")]
    NoMatch { device: String, device_type: String },
    #[error("no memory type can serve use `{use_}` (allowed type bits {type_bits:#b})")]
    NoMemoryType { use_: &'static str, type_bits: u32 },
}
