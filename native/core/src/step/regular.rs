//! Regular windows: where a step of the averaging rules is the tensor-product B-spline.
//!
//! On a quad level, replication followed by m centroid averages is, wherever the mesh is a
//! grid, the tensor product of the 1-D Lane-Riesenfeld step: for even m a fine face (child at
//! `x` in {1/4, 3/4} of its parent) is `sum a_k c_k` over the coarse faces, with the binomial
//! mask `a_k = binom(m + 1, k) / 2^m` in each direction (DESIGN.md §1). A child whose whole
//! support is a grid (every cell a quad placed consistently, every vertex inside the support of
//! valence 4 and interior, no curve of the step born there) is therefore computed here by one
//! separable filter of the coarse faces, rows then columns, instead of m passes through the fine
//! level. A step of odd degree n takes the kernel for its first n - 1 averages and finishes with
//! its last dual -> primal average over every vertex; at degrees 3 and 5 most fine vertices come
//! straight from the coarse ones instead ([`super::fused`]), and the kernel makes only the
//! children that the others read.
//!
//! The averages have positive weights, so the support is exactly what the passes would read, and
//! a partial level on which a child is exact holds its whole support too: a child is classified
//! the same way on a partial level as on the full one, and the kernel computes it in its parent's
//! frame on both, so adaptive points stay bitwise the uniform ones.
//!
//! Measured (2026-12-03, 4k ico-quad sphere of the OpenSubdiv bench, levels 2-4, against the
//! passes alone; `docs/research/regular-window-kernel.md`): cached evaluation of degree 4 is
//! 1.9-2.1x faster with one thread (2.0-3.8x with two), degree 9 1.1-1.2x (1.1-2.2x); the first
//! classification (a walk per face over tables of steps) made a new plan dearer, fresh degree 4
//! by up to 28 % (one row 5 % faster) and degree 9 by 21-52 %. In instructions (one thread,
//! level 3) cached degree 4 76.3M -> 48.1M, 9 130.9M -> 111.3M. Building the windows costs 337
//! instructions per coarse face for degree 4 and 743 for degree 9 (the first walk about 2,400
//! for 9); a new plan: degree 4 164.9M (passes alone) -> 219.5M (first walk) -> 162.5M, 6
//! 346.5M (first walk) -> 225.2M, 9 219.5M -> 430.2M -> 256.9M; adaptive 177.9M -> 200.2M ->
//! 188.5M (flat cage, degree 4, level 5) and 565.2M -> 620.2M -> 563.2M (degree 4). For 2 or 3
//! averages the per-face filter cost more than the passes it saves (degree 3 cached 36M -> 67M
//! instructions in a first version), so those kept the passes. With the vectors (below) and the
//! fused first pass, two averages do pay (2026-12-04, callgrind driver): of primal input
//! (degree 3: a net of the face's own four vertices, no shared rows) cached averaging 3 30.2M ->
//! 23.9M (level 2: 7.3M -> 6.1M), a new plan 118.0M -> 128.4M (the classification); of dual
//! input (degree 2 after its first step) cached averaging 2 43.1M -> 25.3M (level 2: 9.9M ->
//! 6.4M), cached `limit-ico-2` 85.5M -> 67.5M. With two averages the fused first pass is the
//! step's last: it writes its children after the kernel, whose padded writes spill into the
//! next child ([`put`]).
//!
//! Rows shared (2026-12-03; instruction counts on the callgrind driver, same sphere, level 3,
//! one thread): at a refined level a face's frame is fixed by the parity of its place in its
//! cage quad's grid, so faces of one frame lie two rows apart, and a face whose net holds an
//! earlier face's rows two rows along copies their filtered values instead of gathering and
//! filtering them again ([`Share`]; the same sums, so no bit changes). Cached degree 4 43.0M ->
//! 43.8M (a net of 3 rows shares one), 5 62.4M -> 57.3M, 6 82.4M -> 64.5M, 7 64.9M -> 59.9M, 8
//! 86.8M -> 69.1M, 9 105.9M -> 80.9M; a new plan (finding the shares): degree 4 158.6M ->
//! 166.9M, 9 252.6M -> 236.4M; adaptive-flat-4-6 441.9M -> 445.1M. Left to do: the columns
//! are filtered per face (a same-frame face two columns along reads another window), and the
//! gather and filters, scalar over a point's channels, are still most of cached degree 9
//! (vectors since: below).
//!
//! Vectors (2026-12-03, instructions, callgrind driver, same case): a point padded to four
//! lanes ([`lanes`], [`put`]), both child columns of a row and both children of a child row
//! filtered at once, the zero taps skipped, the net's data read unchecked (bounds checked once),
//! and the chunk also compiled for AVX2 where the processor has it. Cached degree 3 32.8M ->
//! 32.1M (no kernel), 4 48.9M -> 32.1M, 5 61.6M -> 39.6M, 6 68.9M -> 44.7M, 7 64.4M -> 41.5M, 8
//! 73.8M -> 46.7M, 9 86.4M -> 56.5M; fresh 3 121.4M -> 120.5M, 4 172.0M -> 155.0M, 5 187.8M ->
//! 165.8M, 6 215.6M -> 191.1M, 7 191.2M -> 168.4M, 8 222.1M -> 194.8M, 9 241.9M -> 211.4M;
//! adaptive-flat-4-6 419.9M -> 408.2M. About 4.3M of each cached drop is no kernel's: the first
//! build counted 5.7M a call in a `memset` of the step's zero fill, which every later build
//! lowered to a loop of about 1.4M (the counts of the section above had none). The kernel's
//! chunk is now 12.6M of cached degree 4 and 26.1M of 9; the columns are still filtered per
//! face.
//!
//! The walk (2026-12-04, instructions, callgrind driver, same sphere, one thread): each cell
//! is visited as soon as it is placed, and a first walk ANDs the flags it reads (cells clean,
//! inner vertices that can be inside a grid) instead of setting a bit each, walking again for
//! the bits only where one fails ([`place`]). A new plan of degree 9 153.4M -> 140.3M (level
//! 2: 43.3M -> 40.7M), 4 99.3M -> 97.7M (29.6M -> 29.2M); degree 3, whose walk is one cell,
//! 75.1M -> 76.1M (23.2M -> 23.4M; not profiled: it has no spills to lose);
//! cached degree 4 28.8M as before. With the mask of a face that passes set at once (not
//! tested child by child): degree 9 137.2M (level 2 40.1M), 4 95.3M (28.8M), 3 73.9M
//! (22.9M); with the bounds of the walk's tables checked by folds that vectorize
//! ([`Flags::of`]): 9 135.6M (39.8M), 4 93.7M (28.5M), 3 72.3M (22.6M).
//!
//! A cage of quads (stored with its face offsets, as every cage) has windows for its first step
//! too, as every later level (2026-12-05; before, only levels stored as quads had them, and the
//! step from a quad cage ran every average as a pass). Cached evaluation of the 3,840-quad sphere
//! (instructions, callgrind driver, one thread): level 1 degree 2 1.60M -> 1.26M, 3 1.61M ->
//! 1.24M, 4 3.06M -> 1.81M, 9 6.02M -> 3.47M; level 2 -5 % (degrees 2, 3), -15 % (4), -17 % (9);
//! level 3 -1 % to -5 %. The classification costs more than one evaluation of the step saves: a
//! new plan and its evaluation at level 1 +11 % (degree 4) and +15 % (9), at level 2 +2 % and +3
//! %, at level 3 under +1 %. The kernel's sums are not the passes' (f64 results of quad cages
//! move by at most 1e-12 of a value, 6e-16 of the largest coordinate; normals 2.4e-14), the
//! same on every path that steps from the cage (plans, limits, adaptive partial levels, the
//! face-varying meshes), so adaptive vertices stay bitwise the uniform ones.
//!
//! Rows in explicit AVX2 (2026-12-06, instructions, callgrind driver, same sphere, level 3, one
//! thread): of `f32` nets, each row's two column sums are one 8-lane vector, each item read
//! once by a masked load ([`filter_row_avx2`]; LLVM had paired the items with broadcasts,
//! shuffles and blends, 64 instructions a row of six at degree 9, now 47). Cached degree 9
//! 43.2M -> 39.5M, 4 23.5M -> 22.4M, 3 17.8M -> 17.1M; the same bits. Then both columns'
//! weights as one 8-lane load per tap, and a child row's column sums in explicit vectors too
//! ([`column_sums_avx2`]: with the paired weights alone LLVM rebuilt the column stage with
//! blends, degree 3 17.1M -> 17.9M): degree 9 39.5M -> 35.5M, 4 22.4M -> 21.3M, 5-8 -3 % to
//! -6 %, 3 17.1M as before.
//!
//! Windows can also be made for some of a step's items ([`Windows::for_items`]): the limit's
//! partial levels read a quarter of each step's children, and the kernel and the passes then
//! make only those and what they read (each item's sums are the same, so its bits are).
//!
//! [`Windows`] holds, per step, what the kernel needs (per coarse face, the ids of its net in
//! its frame and the children it writes) and the zone that the passes must still compute: the
//! other children and, pass by pass backwards, what they read. Everything here is topology: a
//! plan builds it once per step ([`crate::refinement::Refinement`]), a partial level per step it
//! runs.

use std::mem::MaybeUninit;

use rayon::prelude::*;

use super::fused::Fused;
use crate::curves::CurveNetwork;
use crate::error::{Error, Result};
use crate::memory;
use crate::parallel::{gather_hinted, CHUNK};
use crate::scalar::{add, zero, Scalar, Value};
use crate::topology::{quad_next, Level, NONE};

/// The kernel's view of one step of an averaging rule on a quad level (module documentation).
#[derive(Debug)]
pub(crate) struct Windows {
    /// The step's degree n.
    degree: u32,
    /// The averages the kernel makes: n, or n - 1 for odd n.
    averages: u32,
    /// Whether the step's input is primal (per coarse vertex; the net is then of vertices).
    primal: bool,
    /// Lowest grid coordinate of a face's net (its own cell is `(0, 0)`).
    lo: i32,
    /// Side of the net (vertices or cells).
    side: usize,
    /// Per coarse face, bit `k` for its child at corner `k` when the kernel writes it.
    masks: Vec<u8>,
    /// Per coarse face, `side * side` coarse vertices (primal input) or faces (dual input) of
    /// its net, row after row in its frame (0 where the walk placed none: no child weighs it);
    /// read only for faces with kernel children.
    nets: Vec<u32>,
    /// Bound of the ids of `nets`: the coarse vertices (primal input) or faces (dual). The
    /// walk writes only vertices of its checked tables ([`Flags::of`]), faces of corners below
    /// `4 nf` and zeros, and `nf > 0`.
    reach: usize,
    /// Per coarse face, the earlier face whose filtered rows it reuses ([`Share`]).
    shares: Vec<u8>,
    /// What the passes still compute.
    zone: Zone,
    /// Whether the kernel and the zone make only some of the step's items ([`Windows::for_items`]).
    partial: bool,
    /// With an odd degree made for some items, the fine vertices its last average makes.
    last_vertices: Option<Vec<u32>>,
    /// Degrees 3 and 5 on primal input: the fine vertices made straight from the coarse ones;
    /// degrees 2 and 4 on dual input, in the windows of a drawn step ([`Windows::drawn`]):
    /// the drawing points made straight from the coarse faces ([`Fused`]). The kernel and the
    /// zone then make only the children the others read, and the step's output is primal.
    fused: Option<Fused>,
    /// Degrees 2 and 4 on dual input, made with [`Drawing::Now`]: the fused drawing points of
    /// the step.
    drawing: Option<Fused>,
    /// Degrees 2 and 4 on dual input, made with [`Drawing::Later`]: the tables the dual grid
    /// of [`Windows::drawn`] reads.
    flags: Option<Flags>,
}

/// The items the passes of a step still compute, in increasing order: the coarse faces whose
/// children the first (fused) pass makes, then for each later average `a = 3..=m` the fine
/// items it makes (vertices after a dual -> primal average, faces after a primal -> dual one);
/// the last list is every child that the kernel does not write.
#[derive(Debug)]
pub(super) struct Zone {
    pub first: Vec<u32>,
    pub passes: Vec<Vec<u32>>,
}

/// Fewest averages the kernel makes (see the module documentation).
const MIN_AVERAGES: u32 = 2;
/// Most averages the kernel makes: its net fits [`MAX_SIDE`].
const MAX_AVERAGES: u32 = 8;
/// Largest net side (8 averages of primal input: vertices `-2..=3`, cells `-2..=2`).
const MAX_SIDE: usize = 6;
/// Faces back (in the order of the level, within a chunk) that a face looks for one whose rows
/// it shares; the kernel keeps the filtered rows of the last `SHARE_BACK + 1` faces. A cage
/// quad's descendants at a level are consecutive (16 of them two steps down, 64 three steps
/// down), so the same-frame faces of its grid are at most 63 apart.
const SHARE_BACK: usize = 63;
/// Bits of the hash of a row's first id that finds a face's candidate ([`shares`]).
const SHARE_KEY_BITS: u32 = 8;
/// Rows between two faces that share rows: children sit at the corner of their parent that
/// their frame's corner 0 is at, so at a refined level a face's frame is fixed by the parity of
/// its place in its cage face's grid, and faces of one frame lie two rows (or columns) apart.
const SHARE_SHIFT: usize = 2;

/// A face's share of an earlier face's filtered rows: 0 for none, else how many faces back
/// that face is (1 to [`SHARE_BACK`]), plus [`Share::BELOW`] when the face lies
/// [`SHARE_SHIFT`] rows below it (its row `j` is the other's `j - SHARE_SHIFT`), without when it
/// lies as far above (its row `j` is the other's `j + SHARE_SHIFT`). Rows of the same coarse
/// ids filtered by the same weights are the same sums in the same order: sharing them changes
/// no bit.
#[derive(Clone, Copy, Debug)]
struct Share(u8);

impl Share {
    const BELOW: u8 = 0x80;

    /// The face `back` faces back and whether this face lies below it, if any.
    fn of(self) -> Option<(usize, bool)> {
        let back = (self.0 & !Share::BELOW) as usize;
        (back != 0).then_some((back, self.0 & Share::BELOW != 0))
    }
}

/// What windows of degree 2 or 4 on dual input do about their step's drawing points
/// ([`Fused::drawing`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Drawing {
    /// The step is not drawn (or has no drawing points).
    Skip,
    /// Made with the windows ([`Windows::drawing`]): the adaptive levels, which draw every
    /// level.
    Now,
    /// Made when a run first wants them ([`Windows::drawn`]): the windows keep the tables the
    /// dual grid reads. A plan's last step, which the limits and the dual mesh read whole.
    Later,
}

/// Whether step `j` of a run from the cage has primal input (per vertex): the cage's points are
/// primal, and the steps leave dual data for even degrees.
pub(crate) fn primal_input(degree: u32, j: usize) -> bool {
    j == 0 || degree % 2 == 1
}

impl Windows {
    /// [`Windows::build`] for step `j` of a run from the cage ([`primal_input`]).
    pub(crate) fn of_step(
        coarse: &Level,
        fine: &Level,
        curves: &CurveNetwork,
        degree: u32,
        j: usize,
        draw: Drawing,
    ) -> Result<Option<Windows>> {
        Windows::build(coarse, fine, curves, degree, primal_input(degree, j), draw)
    }

    /// The windows of a step of the averaging rules of `degree` from `coarse` to `fine` with
    /// the step's `curves`, for `primal` (per coarse vertex) or dual input; `None` when the
    /// kernel has nothing to do (a level with other faces than quads, a degree without a
    /// kernel, or no regular child). Windows of degree 2 or 4 on dual input also hold the
    /// step's fused drawing points, or what makes them later, as `draw` says.
    pub(crate) fn build(
        coarse: &Level,
        fine: &Level,
        curves: &CurveNetwork,
        degree: u32,
        primal: bool,
        draw: Drawing,
    ) -> Result<Option<Windows>> {
        let averages = degree - degree % 2;
        if !(MIN_AVERAGES..=MAX_AVERAGES).contains(&averages)
            || !coarse.all_quads()
            || coarse.num_faces() == 0
        {
            return Ok(None);
        }
        let g = Geometry::of(averages, primal);
        let flags = Flags::of(coarse, curves)?;
        let nf = coarse.num_faces();
        let side = g.side;
        // Every face's mask and net are written, so the tables are not zeroed first: a zeroed
        // allocation is a memset where the allocator reuses memory (2.8 MB of nets a new
        // degree-9 plan at level 2 on the 3,840-quad cage, 7 % of its instructions).
        let mut masks: Vec<u8> = memory::with_capacity(nf)?;
        let mut nets: Vec<u32> = memory::with_capacity(nf * side * side)?;
        let (m, n) = (
            &mut masks.spare_capacity_mut()[..nf],
            &mut nets.spare_capacity_mut()[..nf * side * side],
        );
        match (g.cells_side, primal) {
            (1, true) => classify::<1, true, 4>(&g, &flags, m, n),
            (3, true) => classify::<3, true, 16>(&g, &flags, m, n),
            (3, false) => classify::<3, false, 9>(&g, &flags, m, n),
            (5, true) => classify::<5, true, 36>(&g, &flags, m, n),
            _ => classify::<5, false, 25>(&g, &flags, m, n),
        }
        // SAFETY: `classify` wrote every mask and every net: each face's walk writes each id of
        // its net (checked at compile time, `Walk::writes_whole_net`; the tests compare every
        // net with the reference walk's), and a panic would have unwound past here.
        unsafe {
            masks.set_len(nf);
            nets.set_len(nf * side * side);
        }
        if masks.iter().all(|&m| m == 0) {
            return Ok(None);
        }
        let fused = match (degree, primal) {
            (3 | 5, true) => Fused::new(coarse, degree, &masks, flags.tables())?,
            _ => None,
        };
        let drawing = match (degree, primal, draw) {
            (2 | 4, false, Drawing::Now) => Fused::drawing(coarse, degree, &masks, flags.tables())?,
            _ => None,
        };
        // With fused points, the children that the other fine vertices read alone.
        let read = (fused.as_ref())
            .map(|fused| faces_read(coarse, fine, fused.rest()))
            .transpose()?;
        if let Some(read) = &read {
            for (f, mask) in masks.iter_mut().enumerate() {
                *mask &= read.quad(f);
            }
        }
        let zone = Zone::of(coarse, fine, averages, &masks, read.as_ref())?;
        let shares = shares(&masks, &nets, side)?;
        Ok(Some(Windows {
            degree,
            averages,
            primal,
            lo: g.lo,
            side,
            masks,
            nets,
            reach: if primal { coarse.num_vertices } else { nf },
            shares,
            zone,
            partial: false,
            last_vertices: None,
            fused,
            drawing,
            flags: match (degree, primal, draw) {
                (2 | 4, false, Drawing::Later) => Some(flags),
                _ => None,
            },
        }))
    }

    /// The windows of the same step made for the fine items `needed` alone (sorted: fine faces
    /// for even degrees, fine vertices of an odd degree's last average): the kernel writes only
    /// the needed children, the zone holds only what they read, and an odd degree's last
    /// average runs over `needed`. Each needed item gets the value of the whole step bit for
    /// bit (an item's sums do not depend on which others are made); the others are left as a
    /// partial buffer holds them. `windows` are the step's own (`None`: no kernel child);
    /// they come back unchanged when the step has no windowed form for `primal` input (a level
    /// with other faces than quads, a degree without a kernel, windows made for the other kind
    /// of data).
    pub(crate) fn for_items(
        mut windows: Option<Windows>,
        coarse: &Level,
        fine: &Level,
        degree: u32,
        primal: bool,
        needed: &[u32],
    ) -> Result<Option<Windows>> {
        let averages = degree - degree % 2;
        if !(MIN_AVERAGES..=MAX_AVERAGES).contains(&averages)
            || !coarse.all_quads()
            || coarse.num_faces() == 0
            || windows
                .as_ref()
                .is_some_and(|w| w.primal != primal || w.degree != degree)
        {
            return Ok(windows);
        }
        let odd = degree % 2 == 1;
        let fused = (windows.as_mut().and_then(|w| w.fused.take()))
            .map(|fused| fused.for_items(coarse, needed))
            .transpose()?;
        let faces = match (odd, &fused) {
            (true, Some(fused)) => faces_read(coarse, fine, fused.rest())?,
            (true, None) => faces_read(coarse, fine, needed)?,
            (false, _) => {
                let mut faces = Bits::new(fine.num_faces())?;
                for &f in needed {
                    faces.set(f as usize);
                }
                faces
            }
        };
        let g = Geometry::of(averages, primal);
        let nf = coarse.num_faces();
        let (masks, nets, reach) = match windows {
            Some(w) => {
                let masks =
                    memory::collect((w.masks.iter().enumerate()).map(|(f, &m)| m & faces.quad(f)))?;
                (masks, w.nets, w.reach)
            }
            None => (memory::zeroed(nf)?, Vec::new(), 0),
        };
        let zone = Zone::of(coarse, fine, averages, &masks, Some(&faces))?;
        // No net is read for a face without kernel children (all of them when `nets` is empty).
        let shares = shares(&masks, &nets, g.side)?;
        Ok(Some(Windows {
            degree,
            averages,
            primal,
            lo: g.lo,
            side: g.side,
            masks,
            nets,
            reach,
            shares,
            zone,
            partial: true,
            last_vertices: match (odd, &fused) {
                (true, None) => Some(memory::collect(needed.iter().copied())?),
                _ => None,
            },
            fused,
            drawing: None,
            flags: None,
        }))
    }

    /// The windows of the same step ending in its drawing points (one more dual -> primal
    /// average: the drawing mesh of an even degree), for windows of degree 2 or 4 on dual
    /// input made with [`Drawing::Later`]: the fused drawing points ([`Fused::drawing`], made
    /// here from the kernel's masks) where the kernel makes the four children around a point,
    /// the kernel and the zone making only the children that the other points read. `None`
    /// for other windows or when no point is fused. The step run with them
    /// ([`super::LevelData::step`]) leaves primal data, each point with the bits of the drawing
    /// points of the whole step ([`super::LevelData::drawing_points`] with the coarse data).
    pub(crate) fn drawn(&self, coarse: &Level, fine: &Level) -> Result<Option<Windows>> {
        let Some(flags) = &self.flags else {
            return Ok(None);
        };
        let Some(fused) = Fused::drawing(coarse, self.degree, &self.masks, flags.tables())? else {
            return Ok(None);
        };
        let read = faces_read(coarse, fine, fused.rest())?;
        let masks =
            memory::collect((self.masks.iter().enumerate()).map(|(f, &m)| m & read.quad(f)))?;
        let zone = Zone::of(coarse, fine, self.averages, &masks, Some(&read))?;
        let nets = memory::collect(self.nets.iter().copied())?;
        let shares = shares(&masks, &nets, self.side)?;
        Ok(Some(Windows {
            degree: self.degree,
            averages: self.averages,
            primal: false,
            lo: self.lo,
            side: self.side,
            masks,
            nets,
            reach: self.reach,
            shares,
            zone,
            partial: false,
            last_vertices: None,
            fused: Some(fused),
            drawing: None,
            flags: None,
        }))
    }

    /// The fused drawing points of windows of degree 2 or 4 on dual input made with
    /// [`Drawing::Now`]; `None` for other windows or when no point is fused.
    pub(super) fn drawing(&self) -> Option<&Fused> {
        self.drawing.as_ref()
    }

    /// Whether the kernel and the zone make only some of the step's items
    /// ([`Windows::for_items`]): the kernel's output buffer must be initialised first.
    pub(super) fn partial(&self) -> bool {
        self.partial
    }

    /// The fine vertices an odd degree's last average makes, when not every one
    /// ([`Windows::for_items`]).
    pub(super) fn last_vertices(&self) -> Option<&[u32]> {
        self.last_vertices.as_deref()
    }

    /// The fused points of a step of degree 3 or 5, or of a drawn step of degree 2 or 4, if
    /// any ([`Fused`]).
    pub(super) fn fused(&self) -> Option<&Fused> {
        self.fused.as_ref()
    }

    /// The step's degree.
    pub(crate) fn degree(&self) -> u32 {
        self.degree
    }

    /// The averages the kernel makes (the step's degree, or one less for odd degrees).
    pub(super) fn averages(&self) -> u32 {
        self.averages
    }

    /// Whether the windows are for primal input.
    pub(super) fn primal(&self) -> bool {
        self.primal
    }

    /// What the passes still compute.
    pub(super) fn zone(&self) -> &Zone {
        &self.zone
    }

    /// Writes every kernel child into `out` (per fine face) from the coarse data `x` (per
    /// vertex or per face, as the windows were built for); the other children are left as they
    /// are. `out` must have a child per coarse corner (an [`Error::Internal`] otherwise: the
    /// buffers come from the crate).
    ///
    /// Not inlined: in a build where it was, LLVM lowered the step's zero fill of the fine
    /// vertices (`Vec::resize`) to a `memset` call, which callgrind counts by the byte (5.7M
    /// instructions a cached evaluation on its driver's sphere). Such lowering follows the
    /// inlining of the whole crate: compare counts of builds, not of functions.
    #[inline(never)]
    pub(super) fn apply<T: Scalar, const N: usize>(
        &self,
        x: &[Value<T, N>],
        out: &mut [MaybeUninit<Value<T, N>>],
    ) -> Result<()> {
        self.apply_on(x, out, wide_vectors())
    }

    /// [`Windows::apply`], in AVX2 vectors when `wide` and the processor has them.
    fn apply_on<T: Scalar, const N: usize>(
        &self,
        x: &[Value<T, N>],
        out: &mut [MaybeUninit<Value<T, N>>],
        wide: bool,
    ) -> Result<()> {
        if out.len() < 4 * self.masks.len() {
            return Err(Error::Internal(
                "regular windows: no room for the children".into(),
            ));
        }
        // What lets the kernel read `x` unchecked.
        if x.len() < self.reach {
            return Err(Error::Internal(
                "regular windows: less data than the nets read".into(),
            ));
        }
        // Up to four channels (a point) are padded to a vector of four lanes.
        match N <= LANES {
            true => self.apply_lanes::<T, N, LANES>(x, out, wide),
            false => self.apply_lanes::<T, N, N>(x, out, wide),
        }
    }

    /// [`Windows::apply`] on values of `L` lanes (`N` channels, then padding: [`lanes`]).
    fn apply_lanes<T: Scalar, const N: usize, const L: usize>(
        &self,
        x: &[Value<T, N>],
        out: &mut [MaybeUninit<Value<T, N>>],
        wide: bool,
    ) -> Result<()> {
        match (self.side, self.averages / 2 + 1) {
            (2, 2) => self.apply_with::<T, N, L, 2, 2>(x, out, wide),
            (3, 2) => self.apply_with::<T, N, L, 3, 2>(x, out, wide),
            (3, 3) => self.apply_with::<T, N, L, 3, 3>(x, out, wide),
            (4, 3) => self.apply_with::<T, N, L, 4, 3>(x, out, wide),
            (4, 4) => self.apply_with::<T, N, L, 4, 4>(x, out, wide),
            (5, 4) => self.apply_with::<T, N, L, 5, 4>(x, out, wide),
            (5, 5) => self.apply_with::<T, N, L, 5, 5>(x, out, wide),
            (6, 5) => self.apply_with::<T, N, L, 6, 5>(x, out, wide),
            _ => {
                return Err(Error::Internal(
                    "regular windows: a net of no kernel".into(),
                ))
            }
        }
        Ok(())
    }

    /// [`Windows::apply`] with the net's side `S` and the taps of a column `K` constants: each
    /// face's net is read row by row, each row filtered for both child columns (unless an
    /// earlier face of the chunk filtered it: [`Share`]), then the rows along the columns for
    /// both children of a child row at once.
    ///
    /// A child column weighs `K` consecutive coordinates of the net, the first `K` for column
    /// 0 and the last `K` for column 1 (the net spans both supports); the taps outside, of
    /// weight zero, are skipped. Adding `0 x` changed no bit of a sum of finite values (a sum
    /// from `+0` is never `-0`), and the data is finite (overflowed data fails the step's
    /// output check either way).
    fn apply_with<T: Scalar, const N: usize, const L: usize, const S: usize, const K: usize>(
        &self,
        x: &[Value<T, N>],
        out: &mut [MaybeUninit<Value<T, N>>],
        wide: bool,
    ) {
        debug_assert_eq!(self.side, S);
        let full = weights::<T, S>(self.averages, self.primal, self.lo);
        // Column p's taps start at coordinate p * o.
        let o = S - K;
        // In every lane: one multiply per tap and lane vector.
        let w: [[[T; L]; K]; 2] =
            std::array::from_fn(|p| std::array::from_fn(|t| [full[p][p * o + t]; L]));
        debug_assert!((0..2)
            .all(|p| (0..S)
                .all(|t| (p * o..p * o + K).contains(&t) || full[p][t] == T::from_f64(0.0))));
        let nf = self.masks.len();
        let wide = wide && wide_vectors();
        out[..4 * nf]
            .par_chunks_mut(4 * CHUNK)
            .enumerate()
            .for_each(|(chunk, children)| {
                #[cfg(target_arch = "x86_64")]
                if wide {
                    // SAFETY: `wide_vectors` found AVX2 on this processor.
                    return unsafe { self.chunk_avx2::<T, N, L, S, K>(chunk, children, x, &w) };
                }
                let _ = wide;
                self.chunk::<T, N, L, S, K, false>(chunk, children, x, &w)
            });
    }

    /// The children of the faces of `chunk` into `children` (its four per face) from `x`,
    /// with the weights `w` of the taps of each column ([`Windows::apply_with`]); `WIDE` (set
    /// by [`Windows::chunk_avx2`] alone) filters the rows of `f32` nets in explicit AVX2
    /// vectors ([`filter_row_avx2`]).
    #[inline(always)]
    fn chunk<
        T: Scalar,
        const N: usize,
        const L: usize,
        const S: usize,
        const K: usize,
        const WIDE: bool,
    >(
        &self,
        chunk: usize,
        children: &mut [MaybeUninit<Value<T, N>>],
        x: &[Value<T, N>],
        w: &[[[T; L]; K]; 2],
    ) {
        let o = S - K;
        // The filtered rows of the chunk's last faces (`rows[j][p]`: row j of the net
        // filtered for the child column p), by place in the chunk modulo their number.
        let mut kept = [[[[T::default(); L]; 2]; S]; SHARE_BACK + 1];
        // Per tap, both columns' weights side by side: one 8-lane load for `filter_row_avx2`.
        #[cfg(target_arch = "x86_64")]
        let paired: [[T; 8]; K] = std::array::from_fn(|t| std::array::from_fn(|l| w[l / 4][t][0]));
        for (i, children) in children.as_chunks_mut::<4>().0.iter_mut().enumerate() {
            let f = chunk * CHUNK + i;
            let mask = self.masks[f];
            if mask == 0 {
                continue;
            }
            let slot = i % (SHARE_BACK + 1);
            // The rows to filter here; the others are copied from the earlier face.
            let filtered = match Share(self.shares[f]).of() {
                None => 0..S,
                Some((back, below)) => {
                    let (earlier, rows) = two(&mut kept, (i - back) % (SHARE_BACK + 1), slot);
                    if below {
                        rows[SHARE_SHIFT..].copy_from_slice(&earlier[..S - SHARE_SHIFT]);
                        0..SHARE_SHIFT
                    } else {
                        rows[..S - SHARE_SHIFT].copy_from_slice(&earlier[SHARE_SHIFT..]);
                        S - SHARE_SHIFT..S
                    }
                }
            };
            let ids = &self.nets[f * S * S..(f + 1) * S * S];
            let rows = &mut kept[slot];
            let nets = ids[filtered.start * S..].chunks_exact(S);
            for (rows, ids) in rows[filtered].iter_mut().zip(nets) {
                #[cfg(target_arch = "x86_64")]
                if WIDE {
                    // SAFETY: `WIDE` is set in AVX2 code alone; every id of a net is below
                    // `reach`, and `apply` checked that `x` holds `reach` values.
                    if let Some(filtered) =
                        unsafe { filter_row_avx2::<T, N, L, S, K>(ids, x, &paired) }
                    {
                        *rows = filtered;
                        continue;
                    }
                }
                let row: [[T; L]; S] = std::array::from_fn(|t| {
                    // SAFETY: every id of a net is below `reach` ([`Windows::reach`]),
                    // and `apply` checked that `x` holds `reach` values.
                    lanes(unsafe { *x.get_unchecked(ids[t] as usize) })
                });
                let mut sums = [zero::<T, L>(); 2];
                for t in 0..K {
                    for (p, sum) in sums.iter_mut().enumerate() {
                        *sum = add(*sum, mul(w[p][t], row[p * o + t]));
                    }
                }
                *rows = sums;
            }
            // Child k of the face sits at column px, row py of its frame: both columns
            // of a child row at once, written in increasing k ([`put`]).
            for (py, written) in [(0, [(0, 0), (1, 1)]), (1, [(1, 2), (0, 3)])] {
                if mask & (1 << written[0].1 | 1 << written[1].1) == 0 {
                    continue;
                }
                #[cfg(target_arch = "x86_64")]
                // SAFETY: `WIDE` is set in AVX2 code alone.
                let wide = WIDE
                    .then(|| unsafe { column_sums_avx2::<T, L, S, K>(rows, &w[py], py * o) })
                    .flatten();
                #[cfg(not(target_arch = "x86_64"))]
                let wide = None;
                let sums = wide.unwrap_or_else(|| {
                    let mut sums = [zero::<T, L>(); 2];
                    for t in 0..K {
                        for (px, sum) in sums.iter_mut().enumerate() {
                            *sum = add(*sum, mul(w[py][t], rows[py * o + t][px]));
                        }
                    }
                    sums
                });
                for (px, k) in written {
                    if mask & (1 << k) != 0 {
                        put(children, k, sums[px]);
                    }
                }
            }
        }
    }

    /// [`Windows::chunk`] compiled for AVX2 (three-operand vectors, unaligned memory operands;
    /// no fused multiply-add, so the same bits).
    ///
    /// # Safety
    /// The processor must have AVX2.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    unsafe fn chunk_avx2<
        T: Scalar,
        const N: usize,
        const L: usize,
        const S: usize,
        const K: usize,
    >(
        &self,
        chunk: usize,
        children: &mut [MaybeUninit<Value<T, N>>],
        x: &[Value<T, N>],
        w: &[[[T; L]; K]; 2],
    ) {
        self.chunk::<T, N, L, S, K, true>(chunk, children, x, w)
    }
}

/// A row of a net (`ids`, `S` items of `x`) filtered for both child columns, as the portable
/// loop of [`Windows::chunk`] does (the same products and sums in the same order, lane by
/// lane), for `f32` values of up to four channels in four lanes; `None` for other values.
/// Both columns are one 8-lane vector: lanes 0-3 the item of tap `t` of column 0, lanes 4-7
/// that of column 1 (item `o + t`), each item read once by a masked load of its channels. The
/// padding lanes hold zeros, not the portable loop's copies: no child keeps them ([`put`]).
/// LLVM built each pair from the portable loop with broadcasts, shuffles, permutes and blends
/// (64 instructions a row of six items at degree 9, most of the kernel's). `paired[t]` is tap
/// `t`'s weight of column 0 four times, then column 1's.
///
/// # Safety
/// AVX2 must be enabled, and every id must be an item of `x`.
#[cfg(target_arch = "x86_64")]
#[inline(always)]
unsafe fn filter_row_avx2<
    T: Scalar,
    const N: usize,
    const L: usize,
    const S: usize,
    const K: usize,
>(
    ids: &[u32],
    x: &[Value<T, N>],
    paired: &[[T; 8]; K],
) -> Option<[[T; L]; 2]> {
    use std::arch::x86_64::*;
    if std::any::TypeId::of::<T>() != std::any::TypeId::of::<f32>() || L != 4 || N > 4 {
        return None;
    }
    let o = S - K;
    let on = |c: usize| if c < N { -1 } else { 0 };
    let base = x.as_ptr().cast::<f32>();
    // SAFETY: AVX2 is enabled (the caller's promise), and every id is an item of `x`, whose
    // `N` channels are `f32` (`T` is `f32`): the masked load reads those alone; `paired[t]`
    // is eight `f32`.
    unsafe {
        let mask = _mm_setr_epi32(on(0), on(1), on(2), on(3));
        let items: [__m128; S] =
            std::array::from_fn(|t| _mm_maskload_ps(base.add(N * ids[t] as usize), mask));
        let mut sum = _mm256_setzero_ps();
        for t in 0..K {
            let weights = _mm256_loadu_ps(paired[t].as_ptr().cast::<f32>());
            let pair = _mm256_set_m128(items[o + t], items[t]);
            sum = _mm256_add_ps(sum, _mm256_mul_ps(weights, pair));
        }
        let mut out = [[T::default(); L]; 2];
        _mm256_storeu_ps(out.as_mut_ptr().cast::<f32>(), sum);
        Some(out)
    }
}

/// The column sums of one child row (filtered rows `from..from + K` of `rows`, weights `w`)
/// for both child columns at once, as the portable loop of [`Windows::chunk`] does (the same
/// products and sums in the same order, lane by lane), for `f32` values in four lanes: one
/// 8-lane vector (column 0 in lanes 0-3, column 1 in lanes 4-7); `None` for other values, as
/// [`filter_row_avx2`].
///
/// # Safety
/// AVX2 must be enabled.
#[cfg(target_arch = "x86_64")]
#[inline(always)]
unsafe fn column_sums_avx2<T: Scalar, const L: usize, const S: usize, const K: usize>(
    rows: &[[[T; L]; 2]; S],
    w: &[[T; L]; K],
    from: usize,
) -> Option<[[T; L]; 2]> {
    use std::arch::x86_64::*;
    if std::any::TypeId::of::<T>() != std::any::TypeId::of::<f32>() || L != 4 {
        return None;
    }
    let rows = &rows[from..from + K];
    // SAFETY: AVX2 is enabled (the caller's promise); `T` is `f32` and `L` 4, so each row is
    // eight `f32` and each weight four.
    unsafe {
        let mut sum = _mm256_setzero_ps();
        for (row, w) in rows.iter().zip(w) {
            let weight = _mm256_set1_ps(*w.as_ptr().cast::<f32>());
            let row = _mm256_loadu_ps(row.as_ptr().cast::<f32>());
            sum = _mm256_add_ps(sum, _mm256_mul_ps(weight, row));
        }
        let mut sums = [[T::default(); L]; 2];
        _mm256_storeu_ps(sums.as_mut_ptr().cast::<f32>(), sum);
        Some(sums)
    }
}

/// Whether the processor has AVX2, for [`Windows::chunk_avx2`].
fn wide_vectors() -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        std::arch::is_x86_feature_detected!("avx2")
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        false
    }
}

/// Lanes of the kernel's vectors for values of up to as many channels (a point, or a point
/// and a weight): four `f32` fill an SSE register.
const LANES: usize = 4;

/// `value` in `L` lanes, its channels repeated past the `N` first. The padding lanes are
/// finite data, sums of which no child keeps ([`put`]); zeros there made every padding lane of
/// a filtered row the same constant, and LLVM, seeing it, split the row filter into two lanes
/// and a scalar.
#[inline(always)]
fn lanes<T: Scalar, const N: usize, const L: usize>(value: [T; N]) -> [T; L] {
    std::array::from_fn(|c| value[c % N])
}

/// Writes child `k` of a face, the first `N` lanes of `value`. Children 0 to 2 are written
/// whole, the lanes past `N` landing at the start of child `k + 1`, which is written after it:
/// by the kernel, which writes a face's children in increasing `k`, or else by the step's last
/// pass (every child the kernel does not write). Used, the padding lanes are computed with the
/// others (a vector operation each): otherwise LLVM splits a point into two lanes and a scalar,
/// which doubles the operations.
#[inline(always)]
fn put<T: Scalar, const N: usize, const L: usize>(
    children: &mut [MaybeUninit<Value<T, N>>; 4],
    k: usize,
    value: [T; L],
) {
    if N < L && L <= 2 * N && k < 3 {
        // SAFETY: the `L` values from child `k` end within the face's `4 N` (`k N + L <= 4 N`
        // for `k <= 2`, `L <= 2 N`), and `[T; N]` (so `MaybeUninit` of it) is `N` values of
        // `T` without padding; an unaligned write needs no more.
        unsafe {
            let at = children.as_mut_ptr().add(k).cast::<[T; L]>();
            at.write_unaligned(value);
        }
    } else {
        children[k].write(std::array::from_fn(|c| value[c]));
    }
}

/// `w * x`, lane by lane (the product that `mad` forms).
#[inline(always)]
fn mul<T: Scalar, const L: usize>(w: [T; L], x: [T; L]) -> [T; L] {
    std::array::from_fn(|c| w[c] * x[c])
}

/// `&items[i]` and `&mut items[j]` for `i != j`.
fn two<A>(items: &mut [A], i: usize, j: usize) -> (&A, &mut A) {
    debug_assert_ne!(i, j);
    if i < j {
        let (a, b) = items.split_at_mut(j);
        (&a[i], &mut b[0])
    } else {
        let (a, b) = items.split_at_mut(i);
        (&b[0], &mut a[j])
    }
}

/// Per coarse face with kernel children, an earlier face of its chunk, at most [`SHARE_BACK`]
/// back and with kernel children, whose net holds its rows but the last (or first)
/// [`SHARE_SHIFT`] ones, [`SHARE_SHIFT`] rows further along (module documentation). The
/// candidates come from two small tables keyed by a row's first id (the latest face whose row
/// `SHARE_SHIFT`, resp. row 0, starts with it): a few dozen instructions a face, where a scan
/// of every face back would cost hundreds. A collision only loses a share.
fn shares(masks: &[u8], nets: &[u32], side: usize) -> Result<Vec<u8>> {
    let n = side * side;
    let shift = SHARE_SHIFT * side;
    let mut shares: Vec<u8> = memory::zeroed(masks.len())?;
    if side <= SHARE_SHIFT {
        // Nets of two rows (two averages of primal input) have none in common.
        return Ok(shares);
    }
    shares
        .par_chunks_mut(CHUNK)
        .enumerate()
        .for_each(|(chunk, shares)| {
            // Place in the chunk plus one of the latest face whose row SHARE_SHIFT (`above`),
            // resp. row 0 (`below`), starts with an id of that hash; 0 for none.
            let mut above = [0u32; 1 << SHARE_KEY_BITS];
            let mut below = [0u32; 1 << SHARE_KEY_BITS];
            let key = |id: u32| (id.wrapping_mul(0x9e37_79b1) >> (32 - SHARE_KEY_BITS)) as usize;
            for (i, share) in shares.iter_mut().enumerate() {
                let h = chunk * CHUNK + i;
                if masks[h] == 0 {
                    continue;
                }
                let net = &nets[h * n..(h + 1) * n];
                let earlier = |latest: u32| {
                    let back = (i + 1).wrapping_sub(latest as usize);
                    (latest != 0 && back <= SHARE_BACK).then_some(back)
                };
                // Above the earlier face: this face's row j is its row j + SHARE_SHIFT.
                if let Some(back) = earlier(above[key(net[0])]) {
                    let other = &nets[(h - back) * n..(h - back + 1) * n];
                    if net[0] == other[shift] && net[..n - shift] == other[shift..] {
                        *share = back as u8;
                    }
                }
                if *share == 0 {
                    if let Some(back) = earlier(below[key(net[shift])]) {
                        let other = &nets[(h - back) * n..(h - back + 1) * n];
                        if net[shift] == other[0] && net[shift..] == other[..n - shift] {
                            *share = back as u8 | Share::BELOW;
                        }
                    }
                }
                above[key(net[shift])] = i as u32 + 1;
                below[key(net[0])] = i as u32 + 1;
            }
        });
    Ok(shares)
}

/// The grid of an even number of averages m on primal or dual input: where a face's net lies
/// and, per child, what of it must be a grid.
struct Geometry {
    /// Lowest coordinate of the net (vertices for primal input, cells for dual).
    lo: i32,
    /// Side of the net.
    side: usize,
    /// Cells of the walk along a side (3 or 5: cells `lo..=-lo` around the face's own).
    cells_side: usize,
    /// Per child `k`: the cells of its support (bit `cells_side * b + a` for cell `(lo + a,
    /// lo + b)`) and the grid vertices inside it (bit `(cells_side + 1) * j + i` for vertex
    /// `(lo + i, lo + j)`).
    cells: [u64; 4],
    inner: [u64; 4],
    /// The support of the child column (or row) p in net coordinates: first and last.
    support: [(i32, i32); 2],
}

impl Geometry {
    fn of(m: u32, primal: bool) -> Geometry {
        let m = m as i32;
        // The child at 4x = X (1 or 3) weighs a_k, k = (m + 1 + X - 4i) / 2 for the vertex at
        // i (primal input), k = (m - 1 + X - 4i) / 2 for the cell centred at i + 1/2 (dual).
        let shift = if primal { 1 } else { -1 };
        let support: [(i32, i32); 2] = std::array::from_fn(|p| {
            let x = 2 * p as i32 + 1;
            (
                ceil_div(x + shift - m - 2, 4),
                (m + shift + x).div_euclid(4),
            )
        });
        let (lo, hi) = (
            support[0].0.min(support[1].0),
            support[0].1.max(support[1].1),
        );
        let side = (hi - lo + 1) as usize;
        let cells_side = if primal { side - 1 } else { side };
        debug_assert_eq!(
            cells_side as i32,
            1 - 2 * lo,
            "cells centred on the face's own"
        );
        let mut g = Geometry {
            lo,
            side,
            cells_side,
            cells: [0; 4],
            inner: [0; 4],
            support,
        };
        for (k, (px, py)) in [(0, 0), (1, 0), (1, 1), (0, 1)].into_iter().enumerate() {
            // The cells of the support: for primal input those between its vertices.
            let span = |(s0, s1): (i32, i32)| if primal { (s0, s1 - 1) } else { (s0, s1) };
            let ((a0, a1), (b0, b1)) = (span(support[px]), span(support[py]));
            for b in b0..=b1 {
                for a in a0..=a1 {
                    g.cells[k] |= 1 << g.cell(a, b);
                }
            }
            for j in b0 + 1..=b1 {
                for i in a0 + 1..=a1 {
                    g.inner[k] |= 1 << g.vertex(i, j);
                }
            }
        }
        g
    }

    /// Bit of cell `(a, b)`.
    fn cell(&self, a: i32, b: i32) -> usize {
        (b - self.lo) as usize * self.cells_side + (a - self.lo) as usize
    }

    /// Bit of grid vertex `(i, j)`.
    fn vertex(&self, i: i32, j: i32) -> usize {
        (j - self.lo) as usize * (self.cells_side + 1) + (i - self.lo) as usize
    }

    /// The children of a face whose support is a grid ([`Windows::masks`]), from the bits of
    /// its cells that are placed and clean and of its grid vertices that can be inside a grid.
    fn mask(&self, cell_ok: u64, inner_ok: u64) -> u8 {
        let mut mask = 0;
        for k in 0..4 {
            if cell_ok & self.cells[k] == self.cells[k] && inner_ok & self.inner[k] == self.inner[k]
            {
                mask |= 1 << k;
            }
        }
        mask
    }
}

/// `ceil(a / b)` for `b > 0`.
fn ceil_div(a: i32, b: i32) -> i32 {
    -((-a).div_euclid(b))
}

/// The 1-D weights of the kernel for the two child columns over the net's `S` coordinates
/// (zero outside a column's support): `a_k = binom(m + 1, k) / 2^m`, exact in f32 for m <= 8
/// (numerators below 2^24).
fn weights<T: Scalar, const S: usize>(m: u32, primal: bool, lo: i32) -> [[T; S]; 2] {
    let g = Geometry::of(m, primal);
    let shift = if primal { 1 } else { -1 };
    let m = m as i32;
    let binom =
        |k: i32| -> f64 { (0..k).fold(1.0, |b, i| b * f64::from(m + 1 - i) / f64::from(i + 1)) };
    std::array::from_fn(|p| {
        let (s0, s1) = g.support[p];
        std::array::from_fn(|t| {
            let i = lo + t as i32;
            if i < s0 || i > s1 {
                return T::from_f64(0.0);
            }
            let k = (m + shift + 2 * p as i32 + 1 - 4 * i) / 2;
            T::from_f64(binom(k) / 2f64.powi(m))
        })
    })
}

/// The vertices, edges and faces of `coarse` from which a curve vertex of the step (`curves`)
/// is born (its old vertex, edge point or face point), each marked in a table of its own.
fn curve_parents(coarse: &Level, curves: &CurveNetwork) -> Result<[Vec<bool>; 3]> {
    let (nv, ne) = (coarse.num_vertices, coarse.num_edges());
    let mut marked = [
        memory::filled(nv, false)?,
        memory::filled(ne, false)?,
        memory::filled(coarse.num_faces(), false)?,
    ];
    for cv in curves.vertices() {
        let w = cv.vertex as usize;
        let (kind, at) = if w < nv {
            (0, w)
        } else if w < nv + ne {
            (1, w - nv)
        } else {
            (2, w - nv - ne)
        };
        marked[kind][at] = true;
    }
    Ok(marked)
}

/// What the classification reads of a level, once per step, over the faces and a dead face
/// `nf` after them, which stands for "no cell": a step across any of its sides lands on it
/// again, it is never clean and its corners are at vertex 0 (the id a net holds where no cell
/// is placed, which no child weighs), so placing a face's cells needs no test for a missing one.
#[derive(Debug)]
pub(super) struct Flags {
    /// Per vertex, whether it can be inside a grid (interior, manifold, of valence 4).
    grid_vertex: Vec<bool>,
    /// Per face (and the dead one, false), whether no curve vertex of the step is born from it
    /// (its face point, the edge points of its edges, its corners' old vertices: the 1-D
    /// scheme's blend is no tensor product).
    clean_face: Vec<bool>,
    /// Per corner, the corner across its outgoing edge ([`Level::twin_table`]), the dead
    /// face's first corner on a boundary or non-manifold edge and for the dead face's corners.
    twin: Vec<u32>,
    /// The level's corner vertices, then vertex 0 for the dead face's corners.
    verts: Vec<u32>,
    /// The dead face's first corner, `4 nf`.
    dead: u32,
}

impl Flags {
    pub(super) fn of(coarse: &Level, curves: &CurveNetwork) -> Result<Flags> {
        let (nv, nf) = (coarse.num_vertices, coarse.num_faces());
        let dead = 4 * nf as u32;
        let corner_edges = coarse.corner_edges();
        let twin = coarse.twin_table(dead, 4 * nf + 4)?;
        let (offsets, vertex_corners) = coarse.vertex_corner_table();
        let non_manifold = coarse.is_non_manifold();
        let grid_vertex = gather_hinted(nv, |v| {
            let corners = &vertex_corners[offsets[v] as usize..offsets[v + 1] as usize];
            corners.len() == 4
                && !(non_manifold && coarse.is_non_manifold_vertex(v))
                && corners.iter().all(|&c| twin[c as usize] != dead)
        })?;
        let clean_face = if curves.vertices().is_empty() {
            let mut clean = memory::filled(nf + 1, true)?;
            clean[nf] = false;
            clean
        } else {
            let [marked_vertex, marked_edge, marked_face] = curve_parents(coarse, curves)?;
            gather_hinted(nf + 1, |f| {
                f < nf
                    && !marked_face[f]
                    && (4 * f..4 * f + 4).all(|c| {
                        !marked_edge[corner_edges[c] as usize]
                            && !marked_vertex[coarse.corner_verts[c] as usize]
                    })
            })?
        };
        let mut verts = memory::with_capacity(4 * nf + 4)?;
        verts.extend_from_slice(&coarse.corner_verts);
        verts.extend([0; 4]);
        // What lets the walk read its tables unchecked ([`Tables`]); a level's tables always
        // hold it, so a failure is a bug, reported rather than read out of bounds. Largest
        // entries by folds without an early exit, which vectorize (a test per entry cost 1.6M
        // instructions of a new plan of level 3 on the callgrind driver's sphere).
        let largest = |table: &[u32]| table.iter().fold(0, |m, &x| m.max(x));
        let in_bounds = largest(&twin) <= dead
            && verts.len() == twin.len()
            && (largest(&verts) as usize) < nv
            && clean_face.len() == nf + 1;
        if !in_bounds {
            return Err(Error::Internal(
                "regular windows: a level's corner tables out of range".into(),
            ));
        }
        Ok(Flags {
            grid_vertex,
            clean_face,
            twin,
            verts,
            dead,
        })
    }
}

impl Flags {
    /// The tables as slices, which a walk holds in registers (read through `&Flags` they are
    /// loaded again after every store into a net).
    pub(super) fn tables(&self) -> Tables<'_> {
        Tables {
            twin: &self.twin,
            clean_face: &self.clean_face,
            verts: &self.verts,
            grid_vertex: &self.grid_vertex,
            dead: self.dead,
        }
    }
}

/// [`Flags`] borrowed, read unchecked by corners below `4 nf + 4`: a walk holds only such
/// corners (a face's first corner, entries of `twin`, which [`Flags::of`] checks are, and other
/// corners of their quads), and [`Flags::of`] checks that the vertices of `verts` are the
/// level's; unchecked reads halve the instructions of a walk.
#[derive(Clone, Copy)]
pub(super) struct Tables<'a> {
    twin: &'a [u32],
    clean_face: &'a [bool],
    verts: &'a [u32],
    grid_vertex: &'a [bool],
    dead: u32,
}

impl<'a> Tables<'a> {
    /// The twin of corner `c`.
    #[inline(always)]
    pub(super) fn twin(self, c: u32) -> u32 {
        read(self.twin, c as usize)
    }

    /// Whether the face of corner `c` is clean.
    #[inline(always)]
    pub(super) fn clean(self, c: u32) -> bool {
        read(self.clean_face, (c >> 2) as usize)
    }

    /// The vertex of corner `c`.
    #[inline(always)]
    pub(super) fn vertex(self, c: u32) -> u32 {
        read(self.verts, c as usize)
    }

    /// Whether vertex `v` of `verts` can be inside a grid.
    #[inline(always)]
    pub(super) fn grid(self, v: u32) -> bool {
        read(self.grid_vertex, v as usize)
    }

    /// The twin and vertex tables themselves, for a walk that reads them in vectors: `4 nf +
    /// 4` entries each, every twin below `4 nf + 4` and every vertex one of the level's (the
    /// bounds of [`read`]).
    pub(super) fn corner_tables(self) -> (&'a [u32], &'a [u32]) {
        (self.twin, self.verts)
    }
}

/// `table[i]` without a bound check, for the walk's reads ([`Tables`]): every corner it reaches
/// is below `4 nf + 4 = twin.len() = verts.len()` (twins point at most at the dead face), every
/// face below `nf + 1 = clean_face.len()`, every vertex of `verts` below `nv =
/// grid_vertex.len()`, as `Flags::of` checked once.
#[inline(always)]
fn read<T: Copy>(table: &[T], i: usize) -> T {
    debug_assert!(i < table.len());
    // SAFETY: the bounds above, checked by `Flags::of` before any walk.
    unsafe { *table.get_unchecked(i) }
}

/// The corner `k` steps after `c` in its quad (`c ^ 2` for two steps).
#[inline(always)]
pub(super) fn after(c: u32, k: u32) -> u32 {
    match k & 3 {
        0 => c,
        2 => c ^ 2,
        _ => (c & !3) | ((c + k) & 3),
    }
}

/// The masks and nets of every face for `C` cells along a side of the walk, primal or dual
/// input and nets of `N` ids ([`Windows::build`]).
fn classify<const C: usize, const PRIMAL: bool, const N: usize>(
    g: &Geometry,
    flags: &Flags,
    masks: &mut [MaybeUninit<u8>],
    nets: &mut [MaybeUninit<u32>],
) {
    debug_assert_eq!(g.side * g.side, N);
    const { assert!(Walk::<C, PRIMAL>::writes_whole_net(N)) };
    assert_eq!(nets.len(), N * masks.len(), "a net of N ids per face");
    nets.par_chunks_mut(N * CHUNK)
        .zip(masks.par_chunks_mut(CHUNK))
        .enumerate()
        .for_each(|(chunk, (nets, masks))| {
            let tables = flags.tables();
            for (i, (net, mask)) in nets.chunks_exact_mut(N).zip(masks.iter_mut()).enumerate() {
                let net = net.try_into().expect("a net of N ids");
                let bits = match place::<C, PRIMAL, N>(tables, chunk * CHUNK + i, net) {
                    // Every bit set: every child's support is a grid.
                    None => 0xf,
                    Some((cell_ok, inner_ok)) => g.mask(cell_ok, inner_ok),
                };
                mask.write(bits);
            }
        });
}

/// `$body(i)` for each `i` in `0..$n` (`$n` at most 36), written out one call after the
/// other: with the walk's tables constant, each call compiles to a few instructions, with no
/// loop and no table read (LLVM does not unroll the loops of the larger walks).
macro_rules! unrolled {
    ($n:expr, $body:expr) => {{
        let mut body = $body;
        unrolled!(@ $n, body; 0 1 2 3 4 5 6 7 8 9 10 11 12 13 14 15 16 17 18 19 20 21 22 23 24 25
            26 27 28 29 30 31 32 33 34 35);
    }};
    (@ $n:expr, $body:ident; $($i:literal)*) => {
        $(
            if $i < $n {
                $body($i);
            }
        )*
    };
}

/// The walk of [`place`] for `C` cells along a side as constant tables (so that the loops
/// over them unroll into straight code): cell `(a, b)`, `a` and `b` in `0..C`, is cell
/// `(a - C / 2, b - C / 2)` of the face's frame, at index `C * b + a`; grid vertex `(i, j)`,
/// `i` and `j` in `0..=C`, at index `(C + 1) * j + i` (the bits of [`Geometry`]).
struct Walk<const C: usize, const PRIMAL: bool>;

impl<const C: usize, const PRIMAL: bool> Walk<C, PRIMAL> {
    /// Each cell after the face's own with the cell it is placed from and the side of that
    /// cell it lies across (0 below, 1 right, 2 above, 3 left): along the face's row, then
    /// along each column.
    const STEPS: [(u8, u8, u8); 24] = {
        let h = C / 2;
        let mut steps = [(0, 0, 0); 24];
        let mut n = 0;
        let mut a = h + 1;
        while a < C {
            steps[n] = ((C * h + a) as u8, (C * h + a - 1) as u8, 1);
            (n, a) = (n + 1, a + 1);
        }
        let mut a = h;
        while a > 0 {
            a -= 1;
            steps[n] = ((C * h + a) as u8, (C * h + a + 1) as u8, 3);
            n += 1;
        }
        let mut a = 0;
        while a < C {
            let mut b = h + 1;
            while b < C {
                steps[n] = ((C * b + a) as u8, (C * (b - 1) + a) as u8, 2);
                (n, b) = (n + 1, b + 1);
            }
            let mut b = h;
            while b > 0 {
                b -= 1;
                steps[n] = ((C * b + a) as u8, (C * (b + 1) + a) as u8, 0);
                n += 1;
            }
            a += 1;
        }
        steps
    };

    /// The grid vertices read (all for primal input, whose net they are; the inner ones for
    /// dual input), each with the cell that names it and the corner of that cell at it: the
    /// cell at it towards the face's own, which lies in every support holding the vertex
    /// (supports are rectangles around the face's cell), so a vertex of an unplaced cell is
    /// in no support that can pass; and whether it is inside a support.
    const VERTICES: [(u8, u8, u8, bool); 36] = {
        let h = C / 2;
        let mut vertices = [(0, 0, 0, false); 36];
        let mut n = 0;
        let mut j = 0;
        while j <= C {
            let mut i = 0;
            while i <= C {
                let inner = i >= 1 && i < C && j >= 1 && j < C;
                if PRIMAL || inner {
                    let (x, y) = ((i > h) as usize, (j > h) as usize);
                    let k = match (x, y) {
                        (0, 0) => 0,
                        (1, 0) => 1,
                        (1, 1) => 2,
                        _ => 3,
                    };
                    let (at, cell) = ((C + 1) * j + i, C * (j - y) + i - x);
                    vertices[n] = (at as u8, cell as u8, k, inner);
                    n += 1;
                }
                i += 1;
            }
            j += 1;
        }
        vertices
    };

    /// Number of vertices read.
    const READ: usize = if PRIMAL {
        (C + 1) * (C + 1)
    } else {
        (C - 1) * (C - 1)
    };

    /// Whether the walk writes every id of a net of `N` ids: every cell is visited (the
    /// face's own, then each step's), and a dual net is its cells, a primal one its grid
    /// vertices, each named by a visited cell. [`classify`] writes the nets into uninitialised
    /// memory on this.
    const fn writes_whole_net(n: usize) -> bool {
        let own = C * (C / 2) + C / 2;
        let mut visited = [false; (MAX_SIDE - 1) * (MAX_SIDE - 1)];
        visited[own] = true;
        let mut s = 0;
        while s + 1 < C * C {
            visited[Self::STEPS[s].0 as usize] = true;
            s += 1;
        }
        // A dual net's ids are its cells; a primal net's, the grid vertices the visited cells name.
        let mut named = [false; MAX_SIDE * MAX_SIDE];
        let mut k = 0;
        while PRIMAL && k < Self::READ {
            let (at, cell, _, _) = Self::VERTICES[k];
            named[at as usize] = visited[cell as usize];
            k += 1;
        }
        let ids = if PRIMAL { (C + 1) * (C + 1) } else { C * C };
        let mut all = n == ids;
        let mut k = 0;
        while k < ids {
            all &= if PRIMAL { named[k] } else { visited[k] };
            k += 1;
        }
        all
    }
}

/// Places the cells of face `f`'s net as a walk across edges does (its own cell at `(0, 0)`
/// with its corner 0 at the cell's lower left; along its row, then along each column), writes
/// its net (grid vertices for primal input, the faces of the cells for dual, 0 where no cell is
/// placed) and returns what the classification needs, as [`Geometry`] numbers the bits: the
/// cells placed, of a clean face, and the inner grid vertices that can be inside a grid
/// (`None` when every one is, the common case on a mostly regular mesh). A
/// rectangle of placed cells whose inner vertices are all interior, manifold and of valence 4
/// is a grid (the walk's placement does not depend on the path inside it), so that is all a
/// child's support is checked for.
///
/// This is the first version's walk (kept in the tests as the reference, which every mask, net
/// and zone is checked against) with the same paths and the same rule for each step, so the
/// same cells, masks and nets: a missing cell is the dead face instead of `NONE` (a step from
/// it stays on it, as a step from `NONE` placed nothing; it is unclean, as an unplaced cell's
/// bit was 0; its face is 0 in a dual net, as `NONE` was), and a grid vertex of a dead cell is
/// vertex 0, whose bit may then be set where `NONE` left it clear, but only in supports that
/// hold the dead cell, whose cell bit fails them anyway.
#[inline(always)]
fn place<const C: usize, const PRIMAL: bool, const N: usize>(
    tables: Tables,
    f: usize,
    net: &mut [MaybeUninit<u32>; N],
) -> Option<(u64, u64)> {
    // Most faces of a mostly regular mesh read nothing but clean cells and grid vertices:
    // one AND a flag finds them, where a bit each (a shift, an OR and, the flags waiting
    // for the last, a spill to the stack) cost about a third of the walk. The others walk
    // again for the bits.
    if walk::<C, PRIMAL, N, false>(tables, f, net).0 != 0 {
        return None;
    }
    Some(walk::<C, PRIMAL, N, true>(tables, f, net))
}

/// The walk of [`place`]: with `BITS`, the bits it returns; without, `(1, 0)` when every
/// cell placed is clean and every inner grid vertex can be inside a grid (so every bit is
/// set), else `(0, 0)`. The net is written either way, the same.
#[inline(always)]
fn walk<const C: usize, const PRIMAL: bool, const N: usize, const BITS: bool>(
    tables: Tables,
    f: usize,
    net: &mut [MaybeUninit<u32>; N],
) -> (u64, u64) {
    // Cells are held as their corner at the lower left. The cell across side s of a cell with
    // corner c is across the edge of corner `after(c, s)`, whose twin is the new cell's corner
    // at its upper left for s = 1 (right), lower right for s = 3 (left), lower left for s = 2
    // (above) and upper right for s = 0 (below). Each cell is visited as soon as it is placed:
    // read after the whole walk, the cells of the larger walks stayed live together and
    // spilled to the stack.
    let mut cells = [0u32; (MAX_SIDE - 1) * (MAX_SIDE - 1)];
    let mut ok = if BITS { (0, 0) } else { (1, 0) };
    let own = C * (C / 2) + C / 2;
    cells[own] = 4 * f as u32;
    visit::<C, PRIMAL, N, BITS>(tables, own, cells[own], net, &mut ok);
    unrolled!(C * C - 1, |n: usize| {
        let (at, from, side) = Walk::<C, PRIMAL>::STEPS[n];
        let d = tables.twin(after(cells[from as usize], side as u32));
        cells[at as usize] = after(d, 6 - side as u32);
        visit::<C, PRIMAL, N, BITS>(tables, at as usize, cells[at as usize], net, &mut ok);
    });
    ok
}

/// What [`walk`] reads of cell `at` (with corner `c` at its lower left): whether it is clean
/// and, for dual input, its face in the net; then the grid vertices that it names
/// ([`Walk::VERTICES`]): their ids in the net for primal input and, for the inner ones,
/// whether they can be inside a grid. With `BITS` the flags are set as bits of `ok` (`ok.0`
/// the cells', `ok.1` the vertices'), without they are ANDed into `ok.0`. With `at` constant
/// (the walk is unrolled), the search of the vertices it names folds away.
#[inline(always)]
fn visit<const C: usize, const PRIMAL: bool, const N: usize, const BITS: bool>(
    tables: Tables,
    at: usize,
    c: u32,
    net: &mut [MaybeUninit<u32>; N],
    ok: &mut (u64, u64),
) {
    if BITS {
        ok.0 |= (tables.clean(c) as u64) << at;
    } else {
        ok.0 &= tables.clean(c) as u64;
    }
    if !PRIMAL {
        net[at].write(if c >= tables.dead { 0 } else { c >> 2 });
    }
    unrolled!(Walk::<C, PRIMAL>::READ, |n: usize| {
        let (vertex, cell, k, inner) = Walk::<C, PRIMAL>::VERTICES[n];
        if cell as usize == at {
            let v = tables.vertex(after(c, k as u32));
            if PRIMAL {
                net[vertex as usize].write(v);
            }
            if inner {
                if BITS {
                    ok.1 |= (tables.grid(v) as u64) << vertex;
                } else {
                    ok.0 &= tables.grid(v) as u64;
                }
            }
        }
    });
}

impl Zone {
    /// The zone of a step whose kernel makes `averages` (even) and writes the children of
    /// `masks` (module documentation of [`Windows`]).
    /// With `needed` (fine faces), only those children are made.
    fn of(
        coarse: &Level,
        fine: &Level,
        averages: u32,
        masks: &[u8],
        needed: Option<&Bits>,
    ) -> Result<Zone> {
        // The children the kernel leaves, counted first: the list is made fallibly at its size.
        let wanted = |f: usize| needed.map_or(0xf, |b| b.quad(f));
        let left: usize = (masks.iter().enumerate())
            .map(|(f, &m)| (wanted(f) & !m & 0xf).count_ones() as usize)
            .sum();
        let mut last = memory::with_capacity(left)?;
        for (f, &mask) in masks.iter().enumerate() {
            let left = wanted(f) & !mask & 0xf;
            if left == 0 {
                continue;
            }
            for k in 0..4 {
                if left & (1 << k) != 0 {
                    last.push((4 * f + k) as u32);
                }
            }
        }
        let mut passes = vec![last];
        // Backwards through the averages a = m..3: what each reads of the one before, marked
        // in a bitset (the lists are short next to the level on a mostly regular mesh).
        for a in (3..=averages).rev() {
            let items = passes.last().expect("the last pass");
            let read = if a % 2 == 1 {
                faces_read(coarse, fine, items)?
            } else {
                // Primal -> dual on the fine faces: they read their corners.
                let mut read = Bits::new(fine.num_vertices)?;
                for &f in items {
                    for &v in &fine.corner_verts[4 * f as usize..4 * f as usize + 4] {
                        read.set(v as usize);
                    }
                }
                read
            };
            passes.push(read.list()?);
        }
        // The first pass makes the children of whole coarse faces.
        let children = passes.pop().expect("the first pass's output");
        let mut first: Vec<u32> = memory::collect(children.iter().map(|&c| c >> 2))?;
        first.dedup();
        passes.reverse();
        Ok(Zone { first, passes })
    }
}

/// The fine faces that a dual -> primal average reads for the fine vertices `items`: the fine
/// faces around them, which are coarse corners.
fn faces_read(coarse: &Level, fine: &Level, items: &[u32]) -> Result<Bits> {
    let (nv, ne) = (coarse.num_vertices, coarse.num_edges());
    let mut read = Bits::new(fine.num_faces())?;
    let (offsets, vertex_corners) = coarse.vertex_corner_table();
    let edge_corners = coarse.edge_corners();
    for &w in items {
        let w = w as usize;
        if w < nv {
            let corners = offsets[w] as usize..offsets[w + 1] as usize;
            for &c in &vertex_corners[corners] {
                read.set(c as usize);
            }
        } else if w < nv + ne {
            for c in edge_corners[w - nv] {
                if c != NONE {
                    read.set(c as usize);
                    read.set(quad_next(c as usize));
                }
            }
        } else {
            read.set_quad(w - nv - ne);
        }
    }
    Ok(read)
}

/// A set of items of a level as bits: the list of those set comes out in increasing order
/// without a sort, for a pass over a word per 64 items.
pub(super) struct Bits(Vec<u64>);

impl Bits {
    /// The empty set of `n` items.
    pub(super) fn new(n: usize) -> Result<Bits> {
        Ok(Bits(memory::zeroed(n.div_ceil(64))?))
    }

    /// Adds item `i`.
    #[inline(always)]
    pub(super) fn set(&mut self, i: usize) {
        self.0[i / 64] |= 1 << (i % 64);
    }

    /// Whether item `i` is in the set.
    #[inline(always)]
    pub(super) fn contains(&self, i: usize) -> bool {
        self.0[i / 64] >> (i % 64) & 1 != 0
    }

    /// Items `4q..4q + 4` (never across a word).
    #[inline(always)]
    fn set_quad(&mut self, q: usize) {
        self.0[q / 16] |= 0xf << (4 * q % 64);
    }

    /// The bits of items `4q..4q + 4` (never across a word).
    #[inline(always)]
    fn quad(&self, q: usize) -> u8 {
        ((self.0[q / 16] >> (4 * q % 64)) & 0xf) as u8
    }

    fn list(&self) -> Result<Vec<u32>> {
        let n = self.0.iter().map(|w| w.count_ones() as usize).sum();
        let mut list = memory::with_capacity(n)?;
        for (i, &word) in self.0.iter().enumerate() {
            let mut word = word;
            while word != 0 {
                list.push(64 * i as u32 + word.trailing_zeros());
                word &= word - 1;
            }
        }
        Ok(list)
    }
}

#[cfg(test)]
pub(super) mod tests {
    use super::{Drawing, Windows};
    use crate::refinement::Refinement;
    use crate::step::LevelData;
    use crate::{Cage, Options, Rules};

    /// Options of the averaging rules of `degree`, three levels: the refinements the tests
    /// here take their steps from.
    fn averaging(degree: u32) -> Options {
        Options {
            degree,
            levels: 3,
            rules: Rules::Averaging,
            ..Options::default()
        }
    }

    /// [`cube_grid`]`(3)` refined three levels (degree 9): the steps that the kernel's tests
    /// build their windows on.
    fn refined_cube() -> Refinement {
        Refinement::new(&cube_grid(3).0, &averaging(9)).unwrap()
    }

    /// A cube whose faces are `k x k` grids (eight vertices of valence 3), with points pushed
    /// off the cube by a fixed pseudo-random amount.
    pub(in crate::step) fn cube_grid(k: usize) -> (Cage, Vec<[f64; 3]>) {
        let mut index = std::collections::HashMap::new();
        let mut points: Vec<[f64; 3]> = Vec::new();
        let mut indices = Vec::new();
        let mut seed = 12345u64;
        let mut noise = move || {
            seed = seed
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (seed >> 11) as f64 / (1u64 << 53) as f64 - 0.5
        };
        let mut id = |p: [i64; 3], points: &mut Vec<[f64; 3]>| -> u32 {
            *index.entry(p).or_insert_with(|| {
                let r = 0.1 * noise();
                points.push(p.map(|x| x as f64 * (1.0 + r)));
                points.len() as u32 - 1
            })
        };
        let k = k as i64;
        for axis in 0..3 {
            for sign in [-k, k] {
                for i in 0..k {
                    for j in 0..k {
                        let at = |a: i64, b: i64| {
                            let mut p = [0i64; 3];
                            p[axis] = sign;
                            p[(axis + 1) % 3] = 2 * a - k;
                            p[(axis + 2) % 3] = 2 * b - k;
                            p
                        };
                        let mut quad = [at(i, j), at(i + 1, j), at(i + 1, j + 1), at(i, j + 1)];
                        if sign < 0 {
                            quad.reverse();
                        }
                        for p in quad {
                            indices.push(id(p, &mut points));
                        }
                    }
                }
            }
        }
        let sizes = vec![4i64; indices.len() / 4];
        let indices: Vec<i64> = indices.iter().map(|&i| i as i64).collect();
        let cage = Cage::from_indices(points.len(), &sizes, &indices).unwrap();
        (cage, points)
    }

    /// An open `m x n` grid of quads with a crease across it and a pentagon and triangles in a
    /// corner: boundaries, a crease, corners and non-quad faces at level 0.
    pub(in crate::step) fn open_grid(m: usize, n: usize, sharpness: f32) -> (Cage, Vec<[f64; 3]>) {
        let at = |i: usize, j: usize| (j * (m + 1) + i) as u32;
        let mut sizes: Vec<i64> = Vec::new();
        let mut indices = Vec::new();
        for j in 0..n {
            for i in 0..m {
                if (i, j) == (0, 0) {
                    continue;
                }
                sizes.push(4);
                indices.extend([at(i, j), at(i + 1, j), at(i + 1, j + 1), at(i, j + 1)]);
            }
        }
        // Cell (0, 0) as two triangles.
        sizes.extend([3, 3]);
        indices.extend([at(0, 0), at(1, 0), at(1, 1), at(0, 0), at(1, 1), at(0, 1)]);
        let points: Vec<[f64; 3]> = (0..=n)
            .flat_map(|j| {
                (0..=m).map(move |i| {
                    let (x, y) = (i as f64, j as f64);
                    [x, y, (0.7 * x).sin() * (0.3 * y + 0.2).cos()]
                })
            })
            .collect();
        let crease: Vec<(i64, i64, f32)> = (2..m)
            .map(|i| (at(i, n / 2) as i64, at(i + 1, n / 2) as i64, sharpness))
            .collect();
        let indices: Vec<i64> = indices.iter().map(|&i| i as i64).collect();
        let cage = Cage::from_indices(points.len(), &sizes, &indices)
            .unwrap()
            .with_creases(&crease)
            .unwrap();
        (cage, points)
    }

    /// The classification as first written (a walk per face over tables of steps, with
    /// `NONE` for a missing cell, and the zone from sorted boolean tables): the reference that
    /// the tables of [`Windows::build`] must equal.
    mod reference {
        use super::super::{after, Geometry, Zone, MAX_SIDE};
        use crate::curves::CurveNetwork;
        use crate::topology::{quad_next, Level, NONE};

        /// Per face, its mask and its net (`None` without kernel children), and the zone.
        pub(super) type Classified = (Vec<(u8, Option<Vec<u32>>)>, Option<Zone>);

        pub(super) fn classify(
            coarse: &Level,
            fine: &Level,
            curves: &CurveNetwork,
            averages: u32,
            primal: bool,
        ) -> Classified {
            let g = Geometry::of(averages, primal);
            let (walk, namer) = walk_and_namer(&g, primal);
            let (nv, nf) = (coarse.num_vertices, coarse.num_faces());
            let [marked_vertex, marked_edge, marked_face] =
                crate::step::regular::curve_parents(coarse, curves).unwrap();
            let corner_edges = coarse.corner_edges();
            let twin = coarse.twin_corners().unwrap();
            let grid_vertex: Vec<bool> = (0..nv)
                .map(|v| {
                    let corners = coarse.corners_of_vertex(v);
                    corners.len() == 4
                        && !coarse.is_non_manifold_vertex(v)
                        && corners.iter().all(|&c| twin[c as usize] != NONE)
                })
                .collect();
            let clean_face: Vec<bool> = (0..nf)
                .map(|f| {
                    !marked_face[f]
                        && (4 * f..4 * f + 4).all(|c| {
                            !marked_edge[corner_edges[c] as usize]
                                && !marked_vertex[coarse.corner_verts[c] as usize]
                        })
                })
                .collect();
            let mut faces = Vec::new();
            let mut masks = Vec::new();
            for f in 0..nf {
                let mut cells = [NONE; MAX_SIDE * MAX_SIDE];
                let own = g.cell(0, 0);
                cells[own] = 4 * f as u32;
                let mut cell_ok = (clean_face[f] as u64) << own;
                for &(at, from, side) in &walk {
                    let base = cells[from as usize];
                    if base == NONE {
                        continue;
                    }
                    let d = twin[after(base, side as u32) as usize];
                    if d == NONE {
                        continue;
                    }
                    let placed = after(d, (6 - side as u32) % 4);
                    cells[at as usize] = placed;
                    cell_ok |= (clean_face[(placed >> 2) as usize] as u64) << at;
                }
                let mut vertex = [NONE; (MAX_SIDE + 1) * (MAX_SIDE + 1)];
                let mut inner_ok = 0u64;
                for &(at, cell, k) in &namer {
                    let (at, base) = (at as usize, cells[cell as usize]);
                    if base != NONE {
                        let v = coarse.corner_verts[after(base, k as u32) as usize];
                        vertex[at] = v;
                        inner_ok |= (grid_vertex[v as usize] as u64) << at;
                    }
                }
                let mask = g.mask(cell_ok, inner_ok);
                let net = (mask != 0).then(|| {
                    let ids: &[u32] = if primal { &vertex } else { &cells };
                    ids[..g.side * g.side]
                        .iter()
                        .map(|&x| match x {
                            NONE => 0,
                            x if primal => x,
                            base => base >> 2,
                        })
                        .collect()
                });
                masks.push(mask);
                faces.push((mask, net));
            }
            let zone = masks
                .iter()
                .any(|&m| m != 0)
                .then(|| zone(coarse, fine, averages, &masks));
            (faces, zone)
        }

        /// The walk (each cell after the first with the cell it is placed from and the side of
        /// that cell it lies across) and the namer of each grid vertex read (the cell at it
        /// towards the face's own, and that cell's corner at it).
        #[allow(clippy::type_complexity)]
        fn walk_and_namer(g: &Geometry, primal: bool) -> (Vec<(u8, u8, u8)>, Vec<(u8, u8, u8)>) {
            let lo = g.lo;
            let hi = lo + g.cells_side as i32 - 1;
            let mut walk = Vec::new();
            let mut step = |a: i32, b: i32, from: (i32, i32), side: u8| {
                walk.push((g.cell(a, b) as u8, g.cell(from.0, from.1) as u8, side));
            };
            for a in 1..=hi {
                step(a, 0, (a - 1, 0), 1);
            }
            for a in (lo..0).rev() {
                step(a, 0, (a + 1, 0), 3);
            }
            for a in lo..=hi {
                for b in 1..=hi {
                    step(a, b, (a, b - 1), 2);
                }
                for b in (lo..0).rev() {
                    step(a, b, (a, b + 1), 0);
                }
            }
            let inner = g.inner.iter().fold(0u64, |all, &k| all | k);
            let mut namer = Vec::new();
            for j in lo..=hi + 1 {
                for i in lo..=hi + 1 {
                    let at = g.vertex(i, j);
                    if !primal && inner & (1 << at) == 0 {
                        continue;
                    }
                    let (a, b) = (i - (i > 0) as i32, j - (j > 0) as i32);
                    let k = match (i - a, j - b) {
                        (0, 0) => 0,
                        (1, 0) => 1,
                        (1, 1) => 2,
                        _ => 3,
                    };
                    namer.push((at as u8, g.cell(a, b) as u8, k));
                }
            }
            (walk, namer)
        }

        fn zone(coarse: &Level, fine: &Level, averages: u32, masks: &[u8]) -> Zone {
            let (nv, ne) = (coarse.num_vertices, coarse.num_edges());
            let mut last = Vec::new();
            for (f, &mask) in masks.iter().enumerate() {
                for k in 0..4 {
                    if mask & (1 << k) == 0 {
                        last.push((4 * f + k) as u32);
                    }
                }
            }
            let mut passes = vec![last];
            for a in (3..=averages).rev() {
                let items = passes.last().unwrap();
                let read = if a % 2 == 1 {
                    let mut read = vec![false; fine.num_faces()];
                    let edge_corners = coarse.edge_corners();
                    for &w in items {
                        let w = w as usize;
                        if w < nv {
                            for &c in coarse.corners_of_vertex(w) {
                                read[c as usize] = true;
                            }
                        } else if w < nv + ne {
                            for c in edge_corners[w - nv] {
                                if c != NONE {
                                    read[c as usize] = true;
                                    read[quad_next(c as usize)] = true;
                                }
                            }
                        } else {
                            let g = w - nv - ne;
                            read[4 * g..4 * g + 4].fill(true);
                        }
                    }
                    read
                } else {
                    let mut read = vec![false; fine.num_vertices];
                    for &f in items {
                        for &v in &fine.corner_verts[4 * f as usize..4 * f as usize + 4] {
                            read[v as usize] = true;
                        }
                    }
                    read
                };
                passes.push(
                    (0..read.len() as u32)
                        .filter(|&i| read[i as usize])
                        .collect(),
                );
            }
            let children = passes.pop().unwrap();
            let mut first: Vec<u32> = children.iter().map(|&c| c >> 2).collect();
            first.dedup();
            passes.reverse();
            Zone { first, passes }
        }
    }

    /// [`Windows::build`] classifies every face as the reference does (the same kernel
    /// children, nets and zone) on every step of the test cages, for every number of averages
    /// the kernel makes and both kinds of input, the first step from a cage of quads included.
    #[test]
    fn classification_matches_the_reference() {
        let cages = [
            cube_grid(3),
            cube_grid(5),
            open_grid(7, 6, 10.0),
            open_grid(6, 7, 1.5),
        ];
        let (mut kernel_faces, mut cage_kernel_faces) = (0, 0);
        for (cage, _) in &cages {
            let options = averaging(4);
            let refinement = Refinement::new(cage, &options).unwrap();
            for j in 0..refinement.curve_networks().len() {
                let step = refinement.step(j);
                for degree in 4..=9 {
                    for primal in [true, false] {
                        let built = Windows::build(
                            step.coarse,
                            step.fine,
                            step.curves,
                            degree,
                            primal,
                            Drawing::Skip,
                        )
                        .unwrap();
                        if !step.coarse.all_quads() {
                            assert!(built.is_none(), "no kernel on a level with other faces");
                            continue;
                        }
                        let averages = degree - degree % 2;
                        let (faces, zone) = reference::classify(
                            step.coarse,
                            step.fine,
                            step.curves,
                            averages,
                            primal,
                        );
                        let Some(w) = built else {
                            assert!(zone.is_none(), "step {j} degree {degree}: no kernel child");
                            continue;
                        };
                        let zone = zone.expect("kernel children in both");
                        // With fused points the kernel makes only the children the others read
                        // (`kernel_matches_the_passes` checks that those are made).
                        let read = (w.fused()).map(|fused| {
                            super::faces_read(step.coarse, step.fine, fused.rest()).unwrap()
                        });
                        let n = w.side * w.side;
                        for (f, (mask, net)) in faces.iter().enumerate() {
                            let mask = mask & read.as_ref().map_or(0xf, |read| read.quad(f));
                            assert_eq!(w.masks[f], mask, "step {j} degree {degree} face {f}");
                            if let Some(net) = net {
                                assert_eq!(&w.nets[f * n..(f + 1) * n], &net[..]);
                                kernel_faces += 1;
                                cage_kernel_faces += usize::from(j == 0);
                            }
                        }
                        if read.is_none() {
                            assert_eq!(w.zone.first, zone.first);
                            assert_eq!(w.zone.passes, zone.passes);
                        }
                    }
                }
            }
        }
        assert!(
            kernel_faces > 1000,
            "{kernel_faces} faces with kernel children"
        );
        assert!(
            cage_kernel_faces > 10,
            "{cage_kernel_faces} cage faces with kernel children"
        );
    }

    /// [`crate::estimate`] counts the windows' tables (nets, masks, shares) of every step that
    /// has them, the first step from a cage of quads and the kernels of two averages included:
    /// its figure for a degree exceeds that of degree 1 (the same levels, no windows) by at
    /// least their bytes.
    #[test]
    fn the_estimate_counts_the_windows() {
        let cage = cube_grid(5).0;
        let mut counted = 0;
        for (degree, levels) in (2..=9).flat_map(|d| [(d, 1), (d, 2)]) {
            let options = Options {
                levels,
                ..averaging(degree)
            };
            let refinement = Refinement::new(&cage, &options).unwrap();
            let tables: usize = (0..refinement.curve_networks().len())
                .filter_map(|j| refinement.step(j).windows)
                .map(|w| {
                    let fused = w.fused().map_or(0, |f| {
                        4 * f.nets().len() + 2 * f.owned().len() + 4 * f.rest().len()
                    });
                    4 * w.nets.len() + w.masks.len() + w.shares.len() + fused
                })
                .sum();
            let bilinear = Options {
                degree: 1,
                ..options
            };
            let more = crate::estimate(&cage, &options).unwrap().bytes
                - crate::estimate(&cage, &bilinear).unwrap().bytes;
            assert!(
                more >= tables as u64,
                "degree {degree}, {levels} levels: {more} bytes estimated for {tables}"
            );
            counted += usize::from(levels == 1 && tables > 0);
        }
        assert!(counted >= 4, "{counted} cage steps with windows");
    }

    /// For every kernel, column 0 weighs the first `averages / 2 + 1` coordinates of the net
    /// and column 1 the last as many, none else: the taps `Windows::apply_with` keeps.
    #[test]
    fn columns_weigh_their_taps_only() {
        for averages in [4, 6, 8] {
            for primal in [true, false] {
                let g = super::Geometry::of(averages, primal);
                let k = averages as usize / 2 + 1;
                let w = super::weights::<f64, { super::MAX_SIDE }>(averages, primal, g.lo);
                let o = g.side - k;
                for (p, w) in w.iter().enumerate() {
                    for (t, &w) in w.iter().enumerate().take(g.side) {
                        let tap = (p * o..p * o + k).contains(&t);
                        assert_eq!(w != 0.0, tap, "{averages} {primal} column {p} at {t}");
                    }
                }
            }
        }
    }

    /// Windows made for some items give each of them the bits of the whole step, on every step
    /// past the cage of a cube and of a grid with a semi-sharp or sharp crease, for degrees 2
    /// to 9 (primal and dual data, with and without kernel children) and pseudo-random quarters
    /// of the items.
    #[test]
    fn windows_for_items_give_the_whole_steps_values() {
        let mut seed = 99u32;
        let mut next = move || {
            seed = seed.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
            seed >> 8
        };
        let (mut restricted, mut with_kernel) = (0, 0);
        for (cage, _) in [cube_grid(3), open_grid(7, 6, 1.5), open_grid(6, 7, 10.0)] {
            for degree in 2..=9 {
                let options = averaging(degree);
                let refinement = Refinement::new(&cage, &options).unwrap();
                let networks = refinement.curve_networks();
                for j in 1..networks.len() {
                    let step = refinement.step(j);
                    let (coarse, fine) = (step.coarse, step.fine);
                    let primal = degree % 2 == 1;
                    let items = match primal {
                        true => coarse.num_vertices,
                        false => coarse.num_faces(),
                    };
                    let values: Vec<[f64; 3]> = (0..items)
                        .map(|_| std::array::from_fn(|_| next() as f64 / (1 << 24) as f64))
                        .collect();
                    // The 1-D data read off the 2-D data, as the subdivision matrices do.
                    let curve: Vec<[f64; 3]> = match primal {
                        true => (networks[j - 1].vertices().iter())
                            .map(|cv| values[cv.vertex as usize])
                            .collect(),
                        false => (networks[j - 1].edges().iter())
                            .map(|ce| {
                                let c = coarse.edge_corners()[ce.edge as usize][0];
                                values[coarse.face_of(c as usize)]
                            })
                            .collect(),
                    };
                    let cage_points = vec![[0.0f64; 3]; refinement.cage_level().num_vertices];
                    let run = |step: &crate::step::Step| {
                        let mut data =
                            LevelData::on_level(&cage_points, primal, &values, curve.clone());
                        data.step(step).unwrap();
                        data.into_parts().0
                    };
                    let whole = run(&step);
                    let outputs = match primal {
                        true => fine.num_vertices,
                        false => fine.num_faces(),
                    };
                    let needed: Vec<u32> =
                        (0..outputs as u32).filter(|_| next() % 4 == 0).collect();
                    let own = step
                        .windows
                        .map(|w| {
                            Windows::build(
                                coarse,
                                fine,
                                step.curves,
                                degree,
                                w.primal,
                                Drawing::Skip,
                            )
                        })
                        .transpose()
                        .unwrap()
                        .flatten();
                    let had_kernel = own.is_some();
                    let Some(w) =
                        Windows::for_items(own, coarse, fine, degree, primal, &needed).unwrap()
                    else {
                        continue;
                    };
                    if !w.partial() {
                        continue;
                    }
                    let part = run(&crate::step::Step {
                        windows: Some(&w),
                        ..step
                    });
                    for &i in &needed {
                        let (a, b) = (whole[i as usize], part[i as usize]);
                        assert_eq!(
                            a.map(f64::to_bits),
                            b.map(f64::to_bits),
                            "degree {degree}, step {j}, item {i}"
                        );
                    }
                    restricted += 1;
                    with_kernel += usize::from(had_kernel);
                }
            }
        }
        assert!(
            restricted > 20 && with_kernel > 10,
            "{restricted} {with_kernel}"
        );
    }

    /// The kernel's children are bitwise the same in AVX2 vectors (the rows filtered by
    /// [`super::filter_row_avx2`]) and without, on every step of a refined cube for 2 to 9
    /// averages on primal and dual input.
    #[test]
    fn wide_vectors_give_the_same_children() {
        if !super::wide_vectors() {
            eprintln!("no AVX2 here: the AVX2 kernel is not compared");
            return;
        }
        let refinement = refined_cube();
        let mut seed = 7u32;
        let mut checked = 0;
        for j in 0..refinement.curve_networks().len() {
            let step = refinement.step(j);
            for degree in 2..=9 {
                for primal in [true, false] {
                    let Some(w) = Windows::build(
                        step.coarse,
                        step.fine,
                        step.curves,
                        degree,
                        primal,
                        Drawing::Skip,
                    )
                    .unwrap() else {
                        continue;
                    };
                    let x: Vec<[f32; 3]> = (0..w.reach)
                        .map(|_| {
                            std::array::from_fn(|_| {
                                seed = seed.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
                                (seed >> 8) as f32 / (1 << 24) as f32 - 0.5
                            })
                        })
                        .collect();
                    let outs: Vec<Vec<[f32; 3]>> = [false, true]
                        .map(|wide| {
                            let mut out =
                                vec![std::mem::MaybeUninit::new([0.0f32; 3]); 4 * w.masks.len()];
                            w.apply_on(&x, &mut out, wide).unwrap();
                            // SAFETY: every item was initialised before the kernel wrote some.
                            out.iter().map(|c| unsafe { c.assume_init() }).collect()
                        })
                        .into();
                    for (f, &mask) in w.masks.iter().enumerate() {
                        for k in (0..4).filter(|k| mask & (1 << k) != 0) {
                            let (a, b) = (outs[0][4 * f + k], outs[1][4 * f + k]);
                            assert_eq!(a.map(f32::to_bits), b.map(f32::to_bits));
                            checked += 1;
                        }
                    }
                }
            }
        }
        assert!(checked > 1000, "{checked} children compared");
    }

    /// Every share names an earlier kernel face of the chunk whose net holds the face's rows
    /// two rows along, and shares are found on refined levels (for 4, 6 and 8 averages).
    #[test]
    fn shares_hold_the_rows_they_reuse() {
        let refinement = refined_cube();
        let mut shared = 0;
        for j in 0..refinement.curve_networks().len() {
            let step = refinement.step(j);
            for degree in [4, 5, 7, 9] {
                let Some(w) = Windows::build(
                    step.coarse,
                    step.fine,
                    step.curves,
                    degree,
                    true,
                    Drawing::Skip,
                )
                .unwrap() else {
                    continue;
                };
                let (s, n) = (w.side, w.side * w.side);
                for (h, &share) in w.shares.iter().enumerate() {
                    let Some((back, below)) = super::Share(share).of() else {
                        continue;
                    };
                    let f = h - back;
                    assert!(w.masks[h] != 0 && w.masks[f] != 0);
                    assert_eq!(f / super::CHUNK, h / super::CHUNK, "within a chunk");
                    let (net, other) = (&w.nets[h * n..(h + 1) * n], &w.nets[f * n..(f + 1) * n]);
                    let shift = super::SHARE_SHIFT * s;
                    match below {
                        true => assert_eq!(net[shift..], other[..n - shift]),
                        false => assert_eq!(net[..n - shift], other[shift..]),
                    }
                    shared += 1;
                }
            }
        }
        assert!(shared > 100, "{shared} faces share rows");
    }

    /// The data after every step, by the kernel and the passes (`kernel`) or by the passes
    /// alone.
    fn run(
        refinement: &Refinement,
        points: &[[f64; 3]],
        degree: u32,
        kernel: bool,
    ) -> Vec<[f64; 3]> {
        let mut data = LevelData::new(points);
        for j in 0..refinement.curve_networks().len() {
            let step = refinement.step(j);
            if kernel {
                data.step(&step).unwrap();
            } else {
                data.average_by_passes(&step, degree);
            }
        }
        data.finish_parts().0
    }

    /// The largest difference of a coordinate between two runs' points (as many in each).
    fn largest_difference(a: &[[f64; 3]], b: &[[f64; 3]]) -> f64 {
        assert_eq!(a.len(), b.len());
        (a.iter().zip(b))
            .flat_map(|(a, b)| (0..3).map(move |k| (a[k] - b[k]).abs()))
            .fold(0.0, f64::max)
    }

    /// The kernel computes what the passes compute (f64, to 1e-12 of the cage's size) on
    /// closed and open cages, with irregular vertices, creases (sharp and semi-sharp), corners
    /// and non-quad faces, for every degree (those from 2 on do have kernel children, on
    /// primal and dual input).
    #[test]
    fn kernel_matches_the_passes() {
        let cages = [cube_grid(3), open_grid(7, 6, 10.0), open_grid(6, 7, 1.5)];
        for (cage, points) in &cages {
            for degree in 2..=9 {
                let options = averaging(degree);
                let refinement = Refinement::new(cage, &options).unwrap();
                let steps = refinement.curve_networks().len();
                let kernel_steps = (0..steps)
                    .filter(|&j| refinement.step(j).windows.is_some())
                    .count();
                assert_eq!(
                    kernel_steps > 0,
                    degree >= 2,
                    "degree {degree}: the kernel from 2 averages on"
                );
                let with = run(&refinement, points, degree, true);
                let without = run(&refinement, points, degree, false);
                let worst = largest_difference(&with, &without);
                assert!(
                    worst <= 1e-12 * 10.0,
                    "degree {degree}: kernel off by {worst:e}"
                );
                assert!(with.iter().flatten().all(|x| x.is_finite()));
            }
        }
    }

    /// A drawn last step (degrees 2 and 4: the drawing points fused where the kernel makes the
    /// four children around them, [`Windows::drawn`]) gives the drawing points of the passes
    /// alone (f64, to 1e-12 of the cage's size) on the cages of `kernel_matches_the_passes`,
    /// at one to three levels; most of the cube's points are fused.
    #[test]
    fn drawn_steps_match_the_passes() {
        use crate::step::Final;
        let cages = [cube_grid(3), open_grid(7, 6, 10.0), open_grid(6, 7, 1.5)];
        let mut drawn_steps = 0;
        for (i, (cage, points)) in cages.iter().enumerate() {
            for degree in [2, 4] {
                for levels in 1..=3 {
                    let options = Options {
                        levels,
                        ..averaging(degree)
                    };
                    let refinement = Refinement::new(cage, &options).unwrap();
                    let n = refinement.curve_networks().len();
                    let Some(drawn) = refinement.drawn_step().unwrap() else {
                        // The first step reads primal data: no drawn windows (and the open
                        // grid's first steps have no point to fuse).
                        assert!(levels == 1 || i > 0, "degree {degree}: no drawn step");
                        continue;
                    };
                    drawn_steps += 1;
                    let fused = drawn.windows.and_then(|w| w.fused()).unwrap();
                    if i == 0 && levels == 3 {
                        let rest = fused.rest().len();
                        let all = drawn.fine.num_vertices;
                        assert!(
                            rest < all / 10,
                            "degree {degree}: {rest} of {all} not fused"
                        );
                    }
                    let mut data = LevelData::new(points);
                    for j in 0..n - 1 {
                        data.step(&refinement.step(j)).unwrap();
                    }
                    data.step(&drawn).unwrap();
                    let with = data.finish_parts().0;
                    let mut passes = LevelData::new(points);
                    for j in 0..n {
                        passes.average_by_passes(&refinement.step(j), degree);
                    }
                    let Final::Primal(without) =
                        passes.finish(Some(&refinement.step(n - 1)), false)
                    else {
                        panic!("degree {degree}: the drawing mesh is primal");
                    };
                    let worst = largest_difference(&with, &without);
                    assert!(
                        worst <= 1e-12 * 10.0,
                        "cage {i}, degree {degree}, {levels} levels: drawn off by {worst:e}"
                    );
                }
            }
        }
        assert!(drawn_steps >= 8, "{drawn_steps} drawn steps");
    }

    /// A plan's drawn last step is made by the first run that draws the primal mesh, not with
    /// the plan: the limits' run (`run_parts`) reads the whole step and leaves it unmade, a
    /// plan for the dual mesh never makes it, and the run that makes it after the limits gives
    /// the bits of a run on a new plan.
    #[test]
    fn drawn_steps_are_made_when_first_drawn() {
        use crate::evaluate::{run, run_parts};
        use crate::options::OutputKind;
        use crate::step::{Final, Scratch};
        let (cage, points) = cube_grid(3);
        let drawn = |scratch: &Scratch, refinement: &Refinement| match run(
            refinement, scratch, &points, false,
        )
        .unwrap()
        {
            Final::Primal(points) => points,
            Final::Dual { .. } => panic!("the drawing mesh is primal"),
        };
        for degree in [2, 4] {
            let refinement = Refinement::new(&cage, &averaging(degree)).unwrap();
            assert!(
                !refinement.drawn_made(),
                "degree {degree}: made with the plan"
            );
            let scratch = Scratch::default();
            run_parts(&refinement, &scratch, &points).unwrap();
            assert!(
                !refinement.drawn_made(),
                "degree {degree}: made by the limits"
            );
            let after_limits = drawn(&scratch, &refinement);
            assert!(
                refinement.drawn_made(),
                "degree {degree}: not made when drawn"
            );
            let fresh = Refinement::new(&cage, &averaging(degree)).unwrap();
            let first = drawn(&Scratch::default(), &fresh);
            let bits = |p: &[[f64; 3]]| p.iter().flatten().map(|x| x.to_bits()).collect::<Vec<_>>();
            assert_eq!(bits(&after_limits), bits(&first), "degree {degree}");
            let options = Options {
                output: OutputKind::Dual,
                ..averaging(degree)
            };
            let dual = Refinement::new(&cage, &options).unwrap();
            assert!(
                dual.drawn_step().unwrap().is_none(),
                "degree {degree}: dual drawn"
            );
            run(&dual, &Scratch::default(), &points, true).unwrap();
            assert!(
                !dual.drawn_made(),
                "degree {degree}: made for the dual mesh"
            );
        }
    }
}
