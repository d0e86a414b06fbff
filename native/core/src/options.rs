//! The options of a request (degree, levels, output, boundary, rules, creasing, memory budget),
//! their limits and the one check of them, and the size estimate made before any work.

use crate::error::{Error, Result};
use crate::mesh::Cage;

/// Highest supported degree (number of averaging steps per level).
pub const MAX_DEGREE: u32 = 31;
/// Highest number of levels accepted before the memory estimate is even made.
pub const MAX_LEVELS: u32 = 16;
/// Default memory budget of a request: 4 GiB, or less on a machine with less memory
/// ([`crate::memory::default_memory_budget`] is the budget `Options::default()` takes).
pub const DEFAULT_MEMORY_BUDGET: u64 = 4 << 30;

/// What is drawn at the last level.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum OutputKind {
    /// The drawing mesh: `M_L` with primal points (dual data gets one more dual -> primal
    /// average, the paper's drawing step). Every face is a quad when L >= 1.
    #[default]
    Primal,
    /// The true dual mesh: one point per face of `M_L`, one face per vertex of `M_L` (per fan
    /// of faces around it at a non-manifold vertex; closed along boundaries and non-manifold
    /// edges by the curve's 1-D points).
    Dual,
}

/// How boundaries are treated.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Boundary {
    /// Boundary edges are sharp curves (Blender's and OpenSubdiv's default).
    #[default]
    EdgeOnly,
    /// As `EdgeOnly`, and boundary vertices with a single face are corners.
    EdgeAndCorner,
    /// No boundary interpolation (OpenSubdiv's `VTX_BOUNDARY_NONE`): as `EdgeOnly`, with every
    /// face at a vertex on a boundary edge not creased infinitely a hole.
    None,
}

/// Which rules refine the levels.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Rules {
    /// Repeated averaging (Zorin-Schröder), any degree.
    #[default]
    Averaging,
    /// Classic rule sets (degrees 1 to 3): degree 3 Catmull-Clark exactly as OpenSubdiv's
    /// `catmark`, degree 2 the original Doo-Sabin weights, degree 1 bilinear (the rule layer,
    /// `scheme`, has them all).
    Classic,
}

/// Where [`crate::Plan::limit_surface_with`] puts the limit normals (Blender's attribute
/// domains; USD's `faceVarying` and `vertex` interpolation).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum NormalDomain {
    /// One normal per output face corner, split where the surface has more than one: one per
    /// side at curve vertices, per face at degree 1.
    #[default]
    Corner,
    /// One normal per output vertex, as the positions (OpenSubdiv's form): where a vertex's
    /// corners have different normals, the unit vector along their sum (smooth shading across
    /// the split).
    Vertex,
}

/// How semi-sharp edge sharpness decreases from level to level.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Creasing {
    /// Minus one per level (OpenSubdiv's `CREASE_UNIFORM`, Blender's choice).
    #[default]
    Uniform,
    /// Chaikin: each half takes 3/4 of its own sharpness and 1/4 of the mean of the other
    /// semi-sharp edges at its vertex, minus one (OpenSubdiv's `CREASE_CHAIKIN`).
    Chaikin,
}

/// Options of a subdivision request.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Options {
    /// Number of averaging steps per level (1 bilinear, 2 Doo-Sabin variant, 3 Catmull-Clark
    /// variant, 4 biquartic, ...), 1..=31. C1 at irregular points is proven up to 9.
    pub degree: u32,
    /// Number of refinement levels.
    pub levels: u32,
    /// Drawing mesh or true dual mesh.
    pub output: OutputKind,
    /// Boundary interpolation.
    pub boundary: Boundary,
    /// Largest memory, in bytes, a request may need (estimated before any work; a request over
    /// the machine's memory is refused whatever the budget, see [`crate::memory`]).
    pub memory_budget: u64,
    /// Averaging or classic rules.
    pub rules: Rules,
    /// How semi-sharp creases decrease with classic degree-3 rules (uniform or Chaikin).
    pub creasing: Creasing,
}

impl Default for Options {
    fn default() -> Self {
        Options {
            degree: 4,
            levels: 2,
            output: OutputKind::Primal,
            boundary: Boundary::EdgeOnly,
            memory_budget: crate::memory::default_memory_budget(),
            rules: Rules::Averaging,
            creasing: Creasing::Uniform,
        }
    }
}

/// Size of a request, estimated from the cage before any work.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Estimate {
    /// Output vertices.
    pub vertices: u64,
    /// Output faces.
    pub faces: u64,
    /// Peak memory of plan and evaluation, in bytes (for f64 points with 3 channels).
    pub bytes: u64,
}

/// Checks that `degree` is in `1..=MAX_DEGREE`.
pub(crate) fn check_degree(degree: u32) -> Result<()> {
    if !(1..=MAX_DEGREE).contains(&degree) {
        return Err(Error::DegreeOutOfRange {
            degree: degree as i64,
            max: MAX_DEGREE,
        });
    }
    Ok(())
}

/// Checks that `levels` is in `min..=MAX_LEVELS`.
pub(crate) fn check_levels(levels: u32, min: u32) -> Result<()> {
    if !(min..=MAX_LEVELS).contains(&levels) {
        return Err(Error::LevelOutOfRange {
            levels: levels as i64,
            min,
            max: MAX_LEVELS,
        });
    }
    Ok(())
}

/// The one check of a request's options.
fn check_options(options: &Options) -> Result<()> {
    check_degree(options.degree)?;
    if options.rules == Rules::Classic && options.degree > 3 {
        return Err(Error::InvalidInput(format!(
            "classic rules exist for degrees 1 to 3, not {}",
            options.degree
        )));
    }
    check_levels(options.levels, 0)
}

/// Estimates the output size and peak memory of a request without doing it.
pub fn estimate(cage: &Cage, options: &Options) -> Result<Estimate> {
    check_options(options)?;
    // Exact counts per level (edges estimated from corners for the cage: each interior edge has
    // two corners), in f64 so that absurd requests cannot overflow.
    let mut v = cage.num_vertices() as f64;
    let mut f = cage.num_faces() as f64;
    let mut c = cage.face_vertices().len() as f64;
    let mut e = c / 2.0 + 1.0;
    let mut bytes = 0.0;
    let level_bytes = |v: f64, e: f64, c: f64| 4.0 * (v + 4.0 * c) + 16.0 * e;
    // The averaging rules' regular windows (`step::regular`): per coarse face of a step from a
    // level of quads (every level after the cage, and a cage of quads), its net of at most 3 x
    // 3 (degrees 2-3), 4 x 4 (4-5) or 6 x 6 (6-9) ids, a mask and a share; degree 1 has none.
    // Degrees 3 and 5 add their fused points (`step::fused`): a net of 4 x 4 ids and the
    // points' bits per face, and at most its four fine vertices as the rest. Degrees 2 and 4
    // drawn as the primal mesh add, for the last step, its windows again (ending in the
    // drawing points) and the fused drawing points: per coarse vertex (about one per face) a
    // net of 4 x 4 faces, its four corners and its points' bits; and the tables the whole
    // windows keep to make them (`Drawing::Later`: per face four twins and four vertices, a
    // flag per face and per vertex). Classic Catmull-Clark keeps the fused points of degree
    // 3 alone (`step::catmark::SmoothPoints`).
    let fused = 4.0 * 16.0 + 2.0 + 4.0 * 4.0;
    let drawn = matches!(options.degree, 2 | 4)
        && options.rules == Rules::Averaging
        && options.output != OutputKind::Dual;
    let net = match options.degree {
        2 if options.rules == Rules::Averaging => 4.0 * 9.0 + 2.0,
        3 if options.rules == Rules::Averaging => 4.0 * 9.0 + 2.0 + fused,
        4 if options.rules == Rules::Averaging => 4.0 * 16.0 + 2.0,
        5 if options.rules == Rules::Averaging => 4.0 * 16.0 + 2.0 + fused,
        6..=9 if options.rules == Rules::Averaging => 4.0 * 36.0 + 2.0,
        3 if options.rules == Rules::Classic => fused,
        _ => 0.0,
    };
    bytes += level_bytes(v, e, c);
    for step in 0..options.levels {
        if step > 0 || cage.all_quads() {
            bytes += net * f;
            if drawn && step + 1 == options.levels {
                bytes += (net + fused + 4.0 * 4.0 + 34.0) * f;
            }
        }
        (v, e, f, c) = (v + e + f, 2.0 * e + c, c, 4.0 * c);
        bytes += level_bytes(v, e, c);
    }
    // Evaluation keeps about five arrays of the larger of vertices and faces (f64 x 3): the
    // four buffers of a windowed step, kept by the plan between evaluations, and the output.
    bytes += 5.0 * 24.0 * v.max(f);
    Ok(Estimate {
        vertices: v as u64,
        faces: f as u64,
        bytes: bytes.min(u64::MAX as f64) as u64,
    })
}
