//! The crate's one error type.
//!
//! Every variant names the file (or the procedural spec) it came from and, for glTF, the element
//! as a JSON pointer (`/accessors/3`, `/meshes/0/primitives/1/indices`), the same notation the
//! Khronos glTF-Validator uses in its reports, so a user can compare the two directly.

use thiserror::Error;

/// Everything that can go wrong while loading or generating a scene or a camera path.
#[derive(Debug, Error)]
pub enum SceneError {
    /// The file could not be read at all.
    #[error("{file}: cannot read: {source}")]
    Io {
        file: String,
        #[source]
        source: std::io::Error,
    },

    /// The bytes are neither a GLB container nor a JSON glTF document.
    #[error("{file}: not a glTF file: {reason}")]
    NotGltf { file: String, reason: String },

    /// The GLB container (header or chunks) is malformed; `offset` is the byte where it breaks.
    #[error("{file}: GLB container, byte {offset}: {reason}")]
    Glb {
        file: String,
        offset: usize,
        reason: String,
    },

    /// The JSON text does not parse.
    #[error("{file}: invalid JSON at line {line}, column {column}: {reason}")]
    Json {
        file: String,
        line: usize,
        column: usize,
        reason: String,
    },

    /// An element is structurally wrong: a missing required property, a value of the wrong type
    /// or out of its allowed range, a misaligned offset, an unsupported version.
    #[error("{file}: {pointer}: {reason}")]
    Invalid {
        file: String,
        pointer: String,
        reason: String,
    },

    /// An index into another top-level array points past its end.
    #[error("{file}: {pointer}: refers to {target}/{index}, but there are only {len}")]
    UnresolvedReference {
        file: String,
        pointer: String,
        target: &'static str,
        index: u64,
        len: usize,
    },

    /// A buffer's bytes are missing, undecodable or shorter than declared.
    #[error("{file}: {pointer}: buffer: {reason}")]
    Buffer {
        file: String,
        pointer: String,
        reason: String,
    },

    /// A texture's image is missing, of an undecoded format, corrupt or too large.
    #[error("{file}: {pointer}: image: {reason}")]
    Image {
        file: String,
        pointer: String,
        reason: String,
    },

    /// An accessor or buffer view reaches past the end of what contains it.
    #[error("{file}: {pointer}: out of bounds: {reason}")]
    OutOfBounds {
        file: String,
        pointer: String,
        reason: String,
    },

    /// A vertex index is not smaller than the number of vertices of its primitive.
    #[error(
        "{file}: {pointer}: index {index} at position {position} is out of range \
         (the primitive has {vertex_count} vertices)"
    )]
    IndexOutOfRange {
        file: String,
        pointer: String,
        index: u64,
        position: usize,
        vertex_count: usize,
    },

    /// A NaN or an infinity in a transform, a vertex attribute or a derived bound.
    #[error("{file}: {pointer}: non-finite value: {what}")]
    NonFinite {
        file: String,
        pointer: String,
        what: String,
    },

    /// The node hierarchy is not a forest: a loop, or a node with two parents.
    #[error("{file}: {pointer}: node hierarchy: {reason}")]
    Hierarchy {
        file: String,
        pointer: String,
        reason: String,
    },

    /// The file requires an extension this loader does not implement.
    #[error("{file}: {pointer}: required extension `{name}` is not supported")]
    UnsupportedExtension {
        file: String,
        pointer: String,
        name: String,
    },

    /// The input asks for more than [`crate::Limits`] allows (vertices, indices, instances);
    /// guards memory against hostile or corrupted counts.
    #[error("{file}: {pointer}: {what} would reach {requested}, above the limit of {limit}")]
    LimitExceeded {
        file: String,
        pointer: String,
        what: &'static str,
        requested: u64,
        limit: u64,
    },

    /// The file is valid but the selected scene draws no triangle.
    #[error("{file}: the scene has no triangles to draw ({reason})")]
    EmptyScene { file: String, reason: String },

    /// `load` got a spec that is neither an existing glTF file nor a procedural name.
    #[error("scene spec `{spec}`: {reason}")]
    BadSpec { spec: String, reason: String },

    /// A camera path (JSON file or built in code) is malformed.
    #[error("{file}: camera path{}: {field}: {reason}", frame.map(|f| format!(", frame {f}")).unwrap_or_default())]
    CameraPath {
        file: String,
        frame: Option<usize>,
        field: String,
        reason: String,
    },

    /// Cluster data that does not fit its scene, or a cluster file that does not parse.
    #[error("clusters of {what}: {reason}")]
    Clusters { what: String, reason: String },

    /// A handle to an instance or mesh that no longer exists (or never did).
    #[error("{scene}: stale {what} handle {index} (generation {generation}): {reason}")]
    StaleHandle {
        scene: String,
        what: &'static str,
        index: u32,
        generation: u32,
        reason: String,
    },

    /// A mesh removed while instances still draw it.
    #[error("{scene}: mesh {mesh} is drawn by {instances} instances: remove them first")]
    MeshInUse {
        scene: String,
        mesh: u32,
        instances: u32,
    },
}

impl SceneError {
    /// The JSON pointer of the glTF element the error is about, when there is one.
    ///
    /// Container and JSON syntax errors point at the whole document (`""`), like the validator.
    pub fn pointer(&self) -> Option<&str> {
        match self {
            SceneError::Invalid { pointer, .. }
            | SceneError::UnresolvedReference { pointer, .. }
            | SceneError::Buffer { pointer, .. }
            | SceneError::Image { pointer, .. }
            | SceneError::OutOfBounds { pointer, .. }
            | SceneError::IndexOutOfRange { pointer, .. }
            | SceneError::NonFinite { pointer, .. }
            | SceneError::Hierarchy { pointer, .. }
            | SceneError::UnsupportedExtension { pointer, .. }
            | SceneError::LimitExceeded { pointer, .. } => Some(pointer),
            SceneError::NotGltf { .. } | SceneError::Glb { .. } | SceneError::Json { .. } => {
                Some("")
            }
            SceneError::Io { .. }
            | SceneError::EmptyScene { .. }
            | SceneError::BadSpec { .. }
            | SceneError::CameraPath { .. }
            | SceneError::Clusters { .. }
            | SceneError::StaleHandle { .. }
            | SceneError::MeshInUse { .. } => None,
        }
    }

    /// A short stable name of the variant, for tables and logs.
    pub fn kind(&self) -> &'static str {
        match self {
            SceneError::Io { .. } => "io",
            SceneError::NotGltf { .. } => "not-gltf",
            SceneError::Glb { .. } => "glb",
            SceneError::Json { .. } => "json",
            SceneError::Invalid { .. } => "invalid",
            SceneError::UnresolvedReference { .. } => "unresolved-reference",
            SceneError::Buffer { .. } => "buffer",
            SceneError::Image { .. } => "image",
            SceneError::OutOfBounds { .. } => "out-of-bounds",
            SceneError::IndexOutOfRange { .. } => "index-out-of-range",
            SceneError::NonFinite { .. } => "non-finite",
            SceneError::Hierarchy { .. } => "hierarchy",
            SceneError::UnsupportedExtension { .. } => "unsupported-extension",
            SceneError::LimitExceeded { .. } => "limit-exceeded",
            SceneError::EmptyScene { .. } => "empty-scene",
            SceneError::BadSpec { .. } => "bad-spec",
            SceneError::CameraPath { .. } => "camera-path",
            SceneError::Clusters { .. } => "clusters",
            SceneError::StaleHandle { .. } => "stale-handle",
            SceneError::MeshInUse { .. } => "mesh-in-use",
        }
    }
}
