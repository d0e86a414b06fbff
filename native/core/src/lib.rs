//! # bidegree
//!
//! Quad subdivision surfaces of any degree by repeated averaging (Zorin & Schröder, "A unified
//! framework for primal/dual quadrilateral subdivision schemes"). Degree 1 is bilinear, 2 a
//! Doo-Sabin variant, 3 a Catmull-Clark variant, 4 biquartic, and so on; odd degrees are primal
//! (data on vertices), even degrees dual (data on faces), all in one code path. The paper proves
//! C1 continuity at irregular points for degrees up to 9; higher degrees are allowed but unproven.
//!
//! Layout:
//! - [`mesh`]: the input cage (topology, creases, corners) and its validation;
//! - [`topology`]: refined topology per level (`M_j -> M_{j+1}`), flat structure-of-arrays tables;
//! - [`plan`]: everything that depends only on topology and options (levels, curve networks);
//! - [`evaluate`]: running points and attributes through a plan (parallel gathers);
//! - [`output`]: output meshes (drawing mesh, true dual mesh, edges, face origins);
//! - [`limit`]: limit positions and normals at the output vertices, every degree;
//! - [`adaptive`]: adaptive subdivision on a quadtree forest with crack-free triangles (§3);
//! - [`classic`]: OpenSubdiv's Catmull-Clark and the original Doo-Sabin rules;
//! - [`analysis`]: subdivision matrices, their spectra and the C1 report (the paper's §4);
//! - [`io`]: OBJ reading and writing.
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

pub mod adaptive;
pub mod analysis;
pub mod classic;
pub mod error;
pub mod evaluate;
pub mod io;
pub mod limit;
pub mod mesh;
pub mod output;
pub mod plan;
pub mod topology;

pub use adaptive::{subdivide_adaptive, AdaptiveMesh, AdaptiveOptions};
pub use classic::Creasing;
pub use error::{Error, Result};
pub use evaluate::Scalar;
pub use mesh::{Cage, Corner, Crease};
pub use plan::{estimate, Boundary, Estimate, Options, OutputKind, Plan, Rules};

/// Highest supported degree (number of averaging steps per level).
pub const MAX_DEGREE: u32 = 31;
/// Highest number of levels accepted before the memory estimate is even made.
pub const MAX_LEVELS: u32 = 16;
/// Default memory budget of a request: 4 GiB.
pub const DEFAULT_MEMORY_BUDGET: u64 = 4 << 30;
/// Sharpness at or above which a crease or corner is infinitely sharp (as in OpenSubdiv).
pub const INFINITELY_SHARP: f32 = 10.0;

/// Subdivides `points` (interleaved, `channels` per cage vertex) in one go: validates the
/// geometry (finite values, no zero-area face), builds the plan and evaluates it.
pub fn subdivide<T: Scalar>(
    cage: &Cage,
    points: &[T],
    channels: usize,
    options: &Options,
) -> Result<(Plan, Vec<T>)> {
    mesh::validate_geometry(cage, points, channels)?;
    let plan = Plan::new(cage, options)?;
    let refined = plan.evaluate(points, channels)?;
    Ok((plan, refined))
}
