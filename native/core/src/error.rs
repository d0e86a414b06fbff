//! Typed errors: every way an input or a request can be refused, each naming the offending item.

use thiserror::Error;

/// Everything that can go wrong in bidegree. Validation happens before any work, so an error
/// never leaves partial results behind.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum Error {
    /// The mesh has no faces (or no vertices).
    #[error("empty mesh: {0}")]
    EmptyMesh(String),
    /// A face has fewer than three vertices (`size` as given, which may be negative).
    #[error("face {face} has size {size}; faces need at least 3 vertices")]
    FaceTooSmall { face: usize, size: i64 },
    /// A face uses the same vertex twice.
    #[error("face {face} uses vertex {vertex} more than once")]
    RepeatedVertex { face: usize, vertex: usize },
    /// A face, crease or corner refers to a vertex that does not exist.
    #[error("{what} refers to vertex {index}, but the mesh has {num_vertices} vertices")]
    IndexOutOfRange {
        what: String,
        index: i64,
        num_vertices: usize,
    },
    /// A coordinate or attribute value is NaN or infinite.
    #[error("vertex {vertex} has a non-finite coordinate")]
    NonFinite { vertex: usize },
    /// A face has (numerically) zero area.
    #[error("face {face} is degenerate (zero area)")]
    DegenerateFace { face: usize },
    /// More than two faces share an edge.
    #[error("edge ({a}, {b}) is shared by {faces} faces; the mesh must be a 2-manifold")]
    NonManifoldEdge { a: usize, b: usize, faces: usize },
    /// Two faces traverse a shared edge in the same direction.
    #[error("faces {face_a} and {face_b} have opposite orientations across edge ({a}, {b})")]
    InconsistentOrientation {
        a: usize,
        b: usize,
        face_a: usize,
        face_b: usize,
    },
    /// A crease names a vertex pair that is not an edge of the mesh.
    #[error("crease {crease} ({a}, {b}) is not an edge of the mesh")]
    CreaseNotAnEdge { crease: usize, a: usize, b: usize },
    /// The degree is outside 1..=MAX_DEGREE.
    #[error("degree {degree} is out of range 1..={max}")]
    DegreeOutOfRange { degree: i64, max: u32 },
    /// The number of levels is outside `min..=MAX_LEVELS` (`min` is 0 for uniform
    /// subdivision, 1 for adaptive, which refines at least one level).
    #[error("levels {levels} is out of range {min}..={max}")]
    LevelOutOfRange { levels: i64, min: u32, max: u32 },
    /// The estimated memory of the request exceeds the budget.
    #[error(
        "the result would need about {required} bytes ({faces} faces), over the memory budget of {budget} bytes"
    )]
    MemoryBudget {
        required: u64,
        budget: u64,
        faces: u64,
    },
    /// More memory than this process can have: a request estimated over the machine's memory
    /// (physical memory, or a cgroup limit when lower) although within its budget, or an
    /// allocation the system refused (under an address-space limit, say). `available` is the
    /// memory the process can have, as far as it is known (`u64::MAX` when not).
    #[error(
        "out of memory: {required} bytes could not be had (this process can have about \
         {available} bytes in all: the machine's memory, its cgroup or address-space limit); \
         lower the levels or the degree, or subdivide parts of the mesh separately"
    )]
    OutOfMemory { required: u64, available: u64 },
    /// Arrays of the wrong length or shape, a bad option value, a sharpness below zero.
    #[error("invalid input: {0}")]
    InvalidInput(String),
    /// A file could not be read or written, or is malformed (with its line number).
    #[error("{0}")]
    Io(String),
    /// A bug: an internal invariant failed (a caught panic). Please report it.
    #[error("internal error: {0}")]
    Internal(String),
    /// The output has a NaN or infinite value although the input was finite: the values
    /// overflow the floating-point type of the computation (float32 beyond about 3.4e38).
    #[error(
        "output vertex {vertex} is not finite: the input's values overflow {scalar} in the \
         computation (scale the cage down or use float64)"
    )]
    NonFiniteOutput { vertex: usize, scalar: &'static str },
    /// The work was stopped by its caller (a signal such as Ctrl-C); nothing was written.
    #[error("interrupted: {0}")]
    Interrupted(String),
    /// Adaptive subdivision refused over its memory ([`Error::MemoryBudget`] or
    /// [`Error::OutOfMemory`], the `error`), saying when: before any work, before making a
    /// level (the coarser levels were made and are dropped), or before the output.
    #[error("adaptive subdivision {stage}: {error}")]
    AdaptiveStopped {
        stage: AdaptiveStage,
        error: Box<Error>,
    },
    /// An error restated in the terms of the file the mesh came from: `message` names the file,
    /// the line (when the error has one) and the file's own indices (1-based OBJ vertices);
    /// `error` is the same error in the mesh's 0-based terms, with its kind and details.
    #[error("{message}")]
    InFile {
        message: String,
        line: Option<usize>,
        error: Box<Error>,
    },
}

impl Error {
    /// The error itself, without the context of [`Error::InFile`] and
    /// [`Error::AdaptiveStopped`].
    pub fn kind(&self) -> &Error {
        match self {
            Error::InFile { error, .. } | Error::AdaptiveStopped { error, .. } => error.kind(),
            other => other,
        }
    }
}

/// When adaptive subdivision refused a request over its memory ([`Error::AdaptiveStopped`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum AdaptiveStage {
    /// Before any work: the result's size was known (tolerance 0 refines uniformly).
    BeforeTheWork,
    /// Before making this level (`1..=max_level`): the coarser levels were made (they are
    /// dropped), and the estimate with this one passed the budget.
    Level(u32),
    /// After every level, before the output mesh was made.
    Output,
}

impl std::fmt::Display for AdaptiveStage {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            AdaptiveStage::BeforeTheWork => f.write_str("refused before any work"),
            AdaptiveStage::Level(1) => f.write_str("refused before making level 1"),
            AdaptiveStage::Level(level) => write!(
                f,
                "stopped before making level {level} (levels 1..={} were made, and are dropped)",
                level - 1
            ),
            AdaptiveStage::Output => {
                f.write_str("stopped before the output (every level was refined)")
            }
        }
    }
}

/// Result type of the crate.
pub type Result<T> = std::result::Result<T, Error>;
