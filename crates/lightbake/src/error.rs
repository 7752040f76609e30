//! User-facing errors. Every message names the file, mesh, triangle, node or parameter at fault.
//!
//! Internal invariants are checked with `assert!`/`debug_assert!` instead; bad *input* never
//! panics.

use std::path::PathBuf;

/// Everything that can go wrong in a bake because of its input, settings or environment.
#[derive(Debug, thiserror::Error)]
pub enum BakeError {
    /// A file could not be read.
    #[error("cannot read {path}: {source}")]
    Read {
        /// The file.
        path: PathBuf,
        /// The OS error.
        source: std::io::Error,
    },
    /// A file or directory could not be written.
    #[error("cannot write {path}: {source}")]
    Write {
        /// The file or directory.
        path: PathBuf,
        /// The OS error.
        source: std::io::Error,
    },
    /// The glTF document itself is malformed (JSON, schema, GLB container).
    #[error("{path}: not a valid glTF file: {message}")]
    BadGltf {
        /// The file.
        path: PathBuf,
        /// What the parser said.
        message: String,
    },
    /// A glTF buffer is missing or shorter than declared.
    #[error("{path}: buffer {index} ({uri}) cannot be loaded: {message}")]
    MissingBuffer {
        /// The glTF file.
        path: PathBuf,
        /// Buffer index.
        index: usize,
        /// Its URI, or `<GLB BIN chunk>`.
        uri: String,
        /// Why.
        message: String,
    },
    /// An accessor has the wrong type, or points outside its buffer.
    #[error("{context}: {message}")]
    BadAccessor {
        /// Where it is used, e.g. `mesh 'Floor' primitive 0 POSITION (accessor 3)`.
        context: String,
        /// What is wrong with it.
        message: String,
    },
    /// Vertex data contains NaN or infinity.
    #[error("mesh '{mesh}': vertex {vertex} has a non-finite {attribute} ({value})")]
    NonFiniteVertex {
        /// Mesh name.
        mesh: String,
        /// Vertex index.
        vertex: usize,
        /// `position`, `normal`, ...
        attribute: &'static str,
        /// The offending value, printed.
        value: String,
    },
    /// A vertex lies so far from the origin that f32 positions there are meaningless.
    #[error(
        "instance '{instance}' (mesh '{mesh}'): vertex {vertex} lies at {position}, beyond {limit:e} m from the origin, where f32 positions are {spacing:e} m apart; move the scene near the origin or check its units and transforms"
    )]
    FarVertex {
        /// Instance name.
        instance: String,
        /// Mesh name.
        mesh: String,
        /// Vertex index in the mesh.
        vertex: usize,
        /// Its world position, printed.
        position: String,
        /// The limit, m ([`crate::scene::MAX_COORDINATE`]).
        limit: f32,
        /// Float spacing at the limit, m.
        spacing: f32,
    },
    /// A triangle refers to a vertex that does not exist.
    #[error(
        "mesh '{mesh}': triangle {triangle} uses vertex index {index}, but the mesh has {vertex_count} vertices"
    )]
    IndexOutOfRange {
        /// Mesh name.
        mesh: String,
        /// Triangle index.
        triangle: usize,
        /// The bad index.
        index: u32,
        /// How many vertices there are.
        vertex_count: usize,
    },
    /// An index count that is not a multiple of three.
    #[error("mesh '{mesh}': {count} indices is not a whole number of triangles")]
    PartialTriangle {
        /// Mesh name.
        mesh: String,
        /// The index count.
        count: usize,
    },
    /// A node transform that is not finite or collapses space (zero scale).
    #[error(
        "node '{node}': transform is {problem}; a lightmapped mesh needs a finite, invertible transform"
    )]
    BadTransform {
        /// Node or instance name.
        node: String,
        /// `not finite` or `singular (zero scale)`.
        problem: &'static str,
    },
    /// A light with non-finite or negative parameters.
    #[error("light '{light}': {message}")]
    BadLight {
        /// Light name.
        light: String,
        /// What is wrong.
        message: String,
    },
    /// A material with non-finite or negative parameters.
    #[error("material '{material}': {message}")]
    BadMaterial {
        /// Material name.
        material: String,
        /// What is wrong.
        message: String,
    },
    /// A reference to something that does not exist (mesh, material, texture).
    #[error("{what}")]
    BadReference {
        /// A sentence naming the referrer and the missing target.
        what: String,
    },
    /// The scene has no triangles to bake onto.
    #[error("{scene}: the scene has no triangles to bake onto")]
    NoTriangles {
        /// The scene (file) name.
        scene: String,
    },
    /// A setting is outside its valid range.
    #[error("setting `{name}` = {value}: {message}")]
    BadSetting {
        /// Field name, as in `BakeSettings` / the CLI flag.
        name: &'static str,
        /// The value given.
        value: String,
        /// The valid range or reason.
        message: String,
    },
    /// The bake would use more memory than allowed.
    #[error(
        "the bake needs an estimated {needed_mib:.0} MiB ({breakdown}), more than the memory budget of {budget_mib:.0} MiB; lower the texel density or raise the budget"
    )]
    OverMemoryBudget {
        /// Estimated need.
        needed_mib: f64,
        /// The budget.
        budget_mib: f64,
        /// The largest items of the estimate.
        breakdown: String,
    },
    /// The bake would trace more rays than allowed.
    #[error(
        "the bake would trace an estimated {estimated:.2e} rays ({breakdown}), more than the ray budget of {budget:e} (--max-rays); lower the sample counts or the texel density, or raise the budget"
    )]
    OverRayBudget {
        /// Estimated rays.
        estimated: f64,
        /// The budget.
        budget: u64,
        /// What drives the estimate.
        breakdown: String,
    },
    /// xatlas could not unwrap a mesh.
    #[error("mesh '{mesh}': lightmap unwrap failed: {message}")]
    Unwrap {
        /// Mesh name.
        mesh: String,
        /// What went wrong.
        message: String,
    },
    /// The output would replace a file the bake read (`-o` onto the scene's own folder, or
    /// an output named like one of its inputs).
    #[error("{output}: the bake would overwrite its input {input}; write it to another folder")]
    OverwritesInput {
        /// The output folder or file.
        output: PathBuf,
        /// The input (the scene's folder, the scene file, a buffer or an image).
        input: PathBuf,
    },
    /// An image could not be encoded.
    #[error("cannot encode {path}: {message}")]
    Encode {
        /// The file being written.
        path: PathBuf,
        /// The encoder's message.
        message: String,
    },
    /// The bake's thread could not be started ([`crate::BakeHandle`]).
    #[error("cannot start the bake thread: {source}")]
    Thread {
        /// The OS error.
        source: std::io::Error,
    },
    /// A stage produced a NaN or an infinity (a bug in lightbake): the bake stops before
    /// anything is written (the finite checks of [`mod@crate::bake`]).
    #[error(
        "internal error: the {stage} stage produced the non-finite value {value} at {place}; nothing was written (a bug in lightbake; please report it with the scene)"
    )]
    NonFinite {
        /// The stage whose output held it.
        stage: String,
        /// Where: texel, page and instance, or probe.
        place: String,
        /// The value, printed.
        value: String,
    },
    /// A bug in lightbake (a panic on the bake's thread, say); please report it.
    #[error("internal error: {message} (a bug in lightbake; please report it)")]
    Internal {
        /// What went wrong.
        message: String,
    },
    /// The bake was cancelled through [`crate::progress::Progress::cancel`].
    #[error("the bake was cancelled")]
    Cancelled,
    /// A split bake's work folder is incomplete or does not fit this process: a shard's part
    /// is missing, was written for another shard count, or the scene changed since
    /// `bake prepare` ([`crate::bake::shard`]).
    #[error("{dir}: {message}")]
    Shard {
        /// The work folder.
        dir: PathBuf,
        /// What is wrong and what to run.
        message: String,
    },
    /// A bake over a subset of the texels was given earlier values that do not fit it: they
    /// were kept by a bake of other patches or other settings ([`crate::bake::TexelRun`]).
    #[error("a bake over a subset of the texels: {message}")]
    Subset {
        /// What does not fit.
        message: String,
    },
}

/// Shorthand for results with [`BakeError`].
pub type Result<T, E = BakeError> = std::result::Result<T, E>;
