//! # bidegree
//!
//! Quad subdivision surfaces of any degree by repeated averaging (Zorin & Schröder, "A unified
//! framework for primal/dual quadrilateral subdivision schemes"). Degree 1 is bilinear, 2 a
//! Doo-Sabin variant, 3 a Catmull-Clark variant, 4 biquartic, and so on; odd degrees are primal
//! (data on vertices), even degrees dual (data on faces), all in one code path. The paper proves
//! C1 continuity at irregular points for degrees up to 9; higher degrees are allowed but unproven.
//!
//! Layers (each module imports only those below it; see `docs/ARCHITECTURE.md`):
//! - ground floor: `error`, [`memory`] (fallible allocation, the machine's memory), `scalar`
//!   (the [`Scalar`] trait), `parallel` (fixed-chunk gathers), `mesh` (the input [`Cage`] and
//!   its checks), `topology` (refined [`Level`]s), `options`;
//! - rules: `scheme` (the rule sets: averaging of any degree, classic Catmull-Clark,
//!   Doo-Sabin and bilinear, OpenSubdiv's `Sdc` role) and `curves` (boundaries, creases and
//!   corners on the levels: [`CurveNetwork`]s and classic sharpness);
//! - refinement: `refinement` (levels, curve networks, sharpness of one cage and scheme) and
//!   `step` (the step primitive, on full and partial levels);
//! - evaluation: `evaluate`, `output` (drawing and dual mesh), [`analysis`] (the paper's §4),
//!   `limit` (limit positions and normals), `adaptive` (the quadtree forest of §3);
//! - the facade: [`Plan`] (a refinement with its caches), [`subdivide`],
//!   [`subdivide_adaptive`], and [`io`] (OBJ).
//!
//! ```
//! use bidegree::{Cage, Options, Plan};
//! // A unit square pyramid without its base (an open mesh with a boundary).
//! let points = [0.0f64, 0.0, 1.0, -1.0, -1.0, 0.0, 1.0, -1.0, 0.0, 1.0, 1.0, 0.0, -1.0, 1.0, 0.0];
//! let cage = Cage::from_indices(5, &[3, 3, 3, 3], &[0, 1, 2, 0, 2, 3, 0, 3, 4, 0, 4, 1]).unwrap();
//! let plan = Plan::new(&cage, &Options { degree: 4, levels: 2, ..Options::default() }).unwrap();
//! let refined = plan.evaluate(&points, 3).unwrap();
//! assert_eq!(refined.len(), 3 * plan.num_output_vertices());
//! ```

mod adaptive;
pub mod analysis;
mod curves;
mod error;
mod evaluate;
mod face_varying;
pub mod io;
mod limit;
pub mod memory;
mod mesh;
mod options;
mod output;
mod parallel;
mod plan;
mod refinement;
mod scalar;
mod scheme;
mod step;
#[cfg(test)]
mod tests;
mod topology;

// The integration tests' cages (`tests/common`) name the crate; its unit tests share them.
#[cfg(test)]
extern crate self as bidegree;

pub use adaptive::{
    margin_rings, subdivide_adaptive, subdivide_adaptive_with_data, subdivide_adaptive_with_margin,
    triangle_template, AdaptiveData, AdaptiveMesh, AdaptiveOptions,
};
pub use curves::CurveNetwork;
pub use error::{AdaptiveStage, Error, Result};
pub use face_varying::{FaceVaryingMode, SharedValues};
pub use mesh::{validate_geometry, Cage, Corner, Crease, INFINITELY_SHARP};
pub use options::{
    estimate, Boundary, Creasing, Estimate, NormalDomain, Options, OutputKind, Rules,
    DEFAULT_MEMORY_BUDGET, MAX_DEGREE, MAX_LEVELS,
};
pub use plan::Plan;
pub use scalar::Scalar;
pub use topology::Level;

/// Subdivides `points` (interleaved, `channels` per cage vertex) in one go: validates the
/// geometry (finite values, no zero-area face), builds the plan and evaluates it.
pub fn subdivide<T: Scalar>(
    cage: &Cage,
    points: &[T],
    channels: usize,
    options: &Options,
) -> Result<(Plan, Vec<T>)> {
    validate_geometry(cage, points, channels)?;
    let plan = Plan::new(cage, options)?;
    let refined = plan.evaluate(points, channels)?;
    Ok((plan, refined))
}
