//! The rule layer (the role of OpenSubdiv's `Sdc`): which scheme refines the levels, and the
//! weights and rules it applies, computed from facts about a neighbourhood (a valence, the
//! sharpness of some edges, the rule of a vertex) and nothing about how a mesh is stored.
//! Topology gathers the neighbourhoods ([`crate::topology`], [`crate::curves`]); the step
//! ([`crate::step`]) and the limits ([`crate::limit`]) apply these rules through them.
//!
//! Four rule sets, one [`Scheme`]:
//! - repeated averaging of any degree n (Zorin-Schröder): replicate, then n centroid averages
//!   alternating dual -> primal and primal -> dual, with the 1-D scheme of the same degree on
//!   curves (DESIGN.md §1-2);
//! - classic bilinear: the averaging scheme of degree 1 (midpoints), without a limit;
//! - classic Doo-Sabin: the averaging step of degree 2, then the original Doo-Sabin weights
//!   ([`doo_sabin_weight`]) on the faces around vertices off the curve network;
//! - classic Catmull-Clark exactly as OpenSubdiv's `catmark` ([`catmark`]).
//!
//! One sharpness convention, OpenSubdiv's: 0 is smooth, [`INFINITELY_SHARP`] (10) is sharp at
//! every level; the cage stores larger values (and infinity) as 10 ([`crate::Cage`]), and
//! boundary edges are infinitely sharp.

pub(crate) mod catmark;

use crate::error::{Error, Result};
use crate::mesh::INFINITELY_SHARP;
use crate::options::{Creasing, Options, Rules};

/// The rule set a refinement runs, chosen by the options' degree and rules.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Scheme {
    /// Repeated averaging of degree `degree` (1 bilinear, 2 Doo-Sabin variant, 3 Catmull-Clark
    /// variant, 4 biquartic, ...).
    Averaging { degree: u32 },
    /// Classic bilinear subdivision: the averaging scheme of degree 1.
    Bilinear,
    /// Classic Doo-Sabin: the averaging step of degree 2 with the original weights away from the
    /// curve network.
    DooSabin,
    /// Classic Catmull-Clark as OpenSubdiv's `catmark`.
    CatmullClark { creasing: Creasing },
}

/// How limit positions (and normals) are found for a scheme.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum LimitMethod {
    /// Bilinear: the surface interpolates the refined points; normals of each face's patch.
    Interpolating,
    /// Averaging of degree >= 2: eigenvector masks at interior vertices, the 1-D B-spline on
    /// curves ([`crate::limit`]).
    Eigen,
    /// OpenSubdiv's Catmull-Clark limit masks, positions only ([`catmark`]).
    CatmullClark,
}

impl Scheme {
    /// The scheme of checked options (degree 1..=3 for the classic rules).
    pub(crate) fn new(options: &Options) -> Scheme {
        match (options.rules, options.degree) {
            (Rules::Averaging, degree) => Scheme::Averaging { degree },
            (Rules::Classic, 1) => Scheme::Bilinear,
            (Rules::Classic, 2) => Scheme::DooSabin,
            (Rules::Classic, _) => Scheme::CatmullClark {
                creasing: options.creasing,
            },
        }
    }

    /// The degree: the number of averages of a step (Catmull-Clark: 3).
    pub(crate) fn degree(self) -> u32 {
        match self {
            Scheme::Averaging { degree } => degree,
            Scheme::Bilinear => 1,
            Scheme::DooSabin => 2,
            Scheme::CatmullClark { .. } => 3,
        }
    }

    /// True when a step leaves primal data (one value per vertex): odd degrees; false when it
    /// leaves dual data (one value per face).
    pub(crate) fn is_primal(self) -> bool {
        self.degree() % 2 == 1
    }

    /// True for the rules that refine through per-level sharpness and vertex rules
    /// ([`crate::curves::LevelSharpness`]) instead of the curve network's 1-D scheme.
    pub(crate) fn uses_sharpness(self) -> bool {
        matches!(self, Scheme::CatmullClark { .. })
    }

    /// How this scheme's limit is computed, or why it has none (`normals`: normals too).
    pub(crate) fn limit(self, normals: bool) -> Result<LimitMethod> {
        match self {
            Scheme::Averaging { degree: 1 } => Ok(LimitMethod::Interpolating),
            Scheme::Averaging { .. } => Ok(LimitMethod::Eigen),
            Scheme::CatmullClark { .. } if normals => Err(Error::InvalidInput(
                "limit normals with classic rules are not implemented; use the averaging rules"
                    .into(),
            )),
            Scheme::CatmullClark { .. } => Ok(LimitMethod::CatmullClark),
            Scheme::Bilinear | Scheme::DooSabin => Err(Error::InvalidInput(
                "limit positions with classic rules exist for degree 3 (Catmull-Clark) only".into(),
            )),
        }
    }
}

/// True if `s` is sharp (positive).
#[inline]
pub(crate) fn is_sharp(s: f32) -> bool {
    s > 0.0
}

/// True if `s` is infinitely sharp.
#[inline]
pub(crate) fn is_infinitely_sharp(s: f32) -> bool {
    s >= INFINITELY_SHARP
}

/// True if `s` is semi-sharp (sharp for a finite number of levels).
#[inline]
pub(crate) fn is_semi_sharp(s: f32) -> bool {
    is_sharp(s) && !is_infinitely_sharp(s)
}

/// Sharpness one level down (OpenSubdiv's `Crease::decrementSharpness`): minus one, infinitely
/// sharp stays so, and nothing below zero.
#[inline]
pub fn decrement(s: f32) -> f32 {
    if s <= 0.0 {
        0.0
    } else if is_infinitely_sharp(s) {
        INFINITELY_SHARP
    } else if s > 1.0 {
        s - 1.0
    } else {
        0.0
    }
}

/// The averaging rules' semi-sharp blend: how much a curve vertex's 1-D value replaces its 2-D
/// centroid in a step whose curve edges have sharpness `s` (1 sharp; the fractional part of
/// the last sharp level blends).
#[inline]
pub(crate) fn curve_weight(s: f32) -> f64 {
    s.min(1.0) as f64
}

/// The blend weight of a corner of sharpness `s` in the step from level `level`, `None` once
/// the corner has become smooth.
#[inline]
pub(crate) fn corner_weight(s: f32, level: u32) -> Option<f64> {
    if is_infinitely_sharp(s) {
        return Some(1.0);
    }
    let level = level as f32;
    (s > level).then(|| (s - level).min(1.0) as f64)
}

/// How a vertex takes part in the curve network of a step: on exactly two curve edges and not
/// tagged, it is a curve vertex (the 1-D scheme runs through it); on one, three or more, or
/// tagged, a corner (it keeps its cage point).
#[inline]
pub(crate) fn is_curve_vertex(curve_edges: usize, tagged: bool) -> bool {
    curve_edges == 2 && !tagged
}

/// Doo-Sabin weight `a_i` of a face of `k` corners (`i = 0` is the corner's own point):
/// `a_0 = 1/4 + 5/(4k)`, `a_i = (3 + 2 cos(2 i pi / k)) / (4k)`.
pub fn doo_sabin_weight(i: usize, k: usize) -> f64 {
    let kf = k as f64;
    if i == 0 {
        0.25 + 5.0 / (4.0 * kf)
    } else {
        (3.0 + 2.0 * (2.0 * std::f64::consts::PI * i as f64 / kf).cos()) / (4.0 * kf)
    }
}

/// The centred cardinal B-spline of degree `n` (support `[-(n+1)/2, (n+1)/2]`, integral 1) at
/// `t`, by the Cox–de Boor recursion (stable for every degree): the limit curve of the 1-D
/// scheme of degree n, whose values at the integers are its limit mask on curves.
pub fn cardinal_bspline(n: u32, t: f64) -> f64 {
    // x in the support [0, n+1] of the uncentred spline; values[i] holds N_d(x - i).
    let x = t + (n as f64 + 1.0) / 2.0;
    let n = n as usize;
    let mut values: Vec<f64> = (0..=n)
        .map(|i| {
            let y = x - i as f64;
            if (0.0..1.0).contains(&y) {
                1.0
            } else {
                0.0
            }
        })
        .collect();
    for d in 1..=n {
        for i in 0..=n - d {
            let y = x - i as f64;
            values[i] = (y * values[i] + (d as f64 + 1.0 - y) * values[i + 1]) / d as f64;
        }
    }
    values[0]
}

/// Derivative of [`cardinal_bspline`] with respect to `t` (`n >= 1`).
pub fn cardinal_bspline_derivative(n: u32, t: f64) -> f64 {
    cardinal_bspline(n - 1, t + 0.5) - cardinal_bspline(n - 1, t - 0.5)
}
