//! The step primitive (the role of OpenSubdiv's `Far::PrimvarRefiner::Interpolate`): one
//! subdivision step `M_j -> M_{j+1}` of any rule set ([`Scheme`]) applied to the data of a
//! level, on a full level of a plan or on a partial level of the adaptive forest alike (a
//! partial level is a [`Level`] of some faces; values outside its exact region are computed
//! and ignored). Everything that evaluates data through levels calls it: [`crate::evaluate`]
//! (plans, and through them the limits), [`crate::adaptive`] and [`crate::analysis`].
//!
//! A step of the averaging rules is a replication followed by n centroid averages alternating
//! dual -> primal and primal -> dual (DESIGN.md §1), with the 1-D scheme run in lockstep on the
//! step's [`CurveNetwork`] (§2); classic Doo-Sabin adds its original weights
//! ([`doo_sabin`]), classic Catmull-Clark is one pass of OpenSubdiv's masks ([`catmark`]),
//! whose smooth points on a quad level are the fused sums of degree 3 ([`fused`]).
//! On a quad level (from 2 averages on), the fine faces whose support is a grid come from the
//! tensor B-spline of the whole step ([`regular`]: the regular windows), and the passes run only
//! over the zone around the others; at degrees 3 and 5 the fine vertices of a grid come straight
//! from the coarse ones, with no children in between, and at degrees 2 and 4 the drawing points
//! of a plan's last step and of the adaptive levels from the coarse faces ([`fused`]).
//! Every pass is a parallel gather in a fixed order, so the output is bitwise the same whatever
//! the number of threads, and the same on a partial level as on the full one wherever the
//! inputs of a value are present.
//!
//! Performance notes: a step over a quad level runs its replication and first two averages as
//! one pass over the coarse faces (nothing of the first average is stored but, on dual data,
//! the old vertices' points; bitwise the separate passes); the other passes gather through the
//! coarse level's tables, looked up once per pass ([`Tables`]) and, on quad levels, walked in
//! step with their output (`parallel::fill_zip`: a quarter fewer instructions than rayon's
//! per-item collect for cached averaging 4).
//! The dual -> primal average that ends every odd-degree step runs, on a quad level, in vectors
//! where the processor has AVX2 ([`wide`]: a value of up to four channels in one register, the
//! same sums; cached averaging 3 at level 3 23.5M -> 17.8M instructions, 9 48.9M -> 43.2M). The
//! working buffers come from a [`Scratch`] that a plan keeps between evaluations, so that a
//! cached re-evaluation pays page faults only for the array it returns; the two that the
//! windowed zone writes in part keep their length there, so a warm plan does not fill them
//! again ([`LevelData::partial`]). A cage of quads takes the quad paths and the regular windows
//! from its first step.

pub(crate) mod catmark;
mod doo_sabin;
mod fused;
mod regular;
mod wide;

pub(crate) use catmark::SmoothPoints;
pub(crate) use regular::{primal_input, Drawing, Windows};

use std::any::Any;
use std::borrow::Cow;
use std::fmt::Debug;
use std::mem::MaybeUninit;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Mutex;

use rayon::prelude::*;

use crate::curves::{CurveNetwork, CurveVertex, LevelSharpness};
use crate::error::{Error, Result};
use crate::parallel::{
    as_uninit, fill_zip, gather_sections, gather_zip, hinted_or_abort, scatter, scatter_uninit,
    with_capacity_hinted, CHUNK,
};
use crate::scalar::{add, reciprocal, scale, zero, Scalar, Value};
use crate::scheme::Scheme;
use crate::topology::{quad_next, Level, NONE};

/// What one step reads besides the data: its two levels, its curve network and, for the
/// classic Catmull-Clark rules, the sharpness and rules of both levels.
#[derive(Clone, Copy)]
pub(crate) struct Step<'a> {
    /// The rule set.
    pub scheme: Scheme,
    /// `M_j` (full or partial).
    pub coarse: &'a Level,
    /// `M_{j+1}`: its faces and vertex count are read (the faces-only last level of a plan
    /// will do).
    pub fine: &'a Level,
    /// The curve network of the step.
    pub curves: &'a CurveNetwork,
    /// Classic Catmull-Clark: sharpness and rules of `coarse` and `fine`.
    pub sharpness: Option<(&'a LevelSharpness, &'a LevelSharpness)>,
    /// The averaging rules: the step's regular windows, made with its topology (`None`: no
    /// kernel child). Windows made for the other kind of data (primal or dual) are made again
    /// for the data at hand.
    pub windows: Option<&'a Windows>,
    /// Classic Catmull-Clark on a quad level: its smooth points by the fused sums, made with
    /// its topology and sharpness (`None`: every point by its rule).
    pub smooth_points: Option<&'a catmark::SmoothPoints>,
}

/// The tables of a coarse level that a pass reads, looked up once per pass: the accessors of
/// [`Level`] check per call which tables the level has (a quad level has no face tables, the
/// edge tables sit behind a `OnceLock`), which cost a tenth of a cached evaluation's
/// instructions when done per vertex.
#[derive(Clone, Copy)]
pub(super) struct Tables<'a> {
    level: &'a Level,
    quads: bool,
    corner_verts: &'a [u32],
    edge_verts: &'a [[u32; 2]],
    edge_corners: &'a [[u32; 2]],
    corner_edges: &'a [u32],
    vertex_offsets: &'a [u32],
    vertex_corners: &'a [u32],
}

impl<'a> Tables<'a> {
    /// The tables of `level` (a level with its edge tables: every coarse level of a step).
    pub(super) fn of(level: &'a Level) -> Self {
        let (vertex_offsets, vertex_corners) = level.vertex_corner_table();
        Tables {
            level,
            // A cage of quads takes the quad paths too ([`Level::all_quads`]; the same sums in the
            // same order): cached averaging 9 from the 3,840-quad sphere spent 17 % of its
            // instructions in its first step on the general paths.
            quads: level.all_quads(),
            corner_verts: &level.corner_verts,
            edge_verts: level.edge_verts(),
            edge_corners: level.edge_corners(),
            corner_edges: level.corner_edges(),
            vertex_offsets,
            vertex_corners,
        }
    }

    /// [`Level::corners_of_vertex`].
    #[inline(always)]
    fn corners_of_vertex(&self, v: usize) -> &'a [u32] {
        &self.vertex_corners[self.vertex_offsets[v] as usize..self.vertex_offsets[v + 1] as usize]
    }

    /// The values of `x` (per vertex) at the four corners of quad `f`.
    #[inline(always)]
    fn at_corners<T: Scalar, const N: usize>(
        &self,
        x: &[Value<T, N>],
        f: usize,
    ) -> [Value<T, N>; 4] {
        std::array::from_fn(|k| x[self.corner_verts[4 * f + k] as usize])
    }

    /// [`Level::face_of`].
    #[inline(always)]
    fn face_of(&self, corner: usize) -> usize {
        if self.quads {
            corner >> 2
        } else {
            self.level.face_of(corner)
        }
    }

    /// [`Level::next`].
    #[inline(always)]
    fn next(&self, corner: usize) -> usize {
        if self.quads {
            quad_next(corner)
        } else {
            self.level.next(corner)
        }
    }

    /// [`Level::face_corners`].
    #[inline(always)]
    fn face_corners(&self, f: usize) -> std::ops::Range<usize> {
        if self.quads {
            4 * f..4 * f + 4
        } else {
            self.level.face_corners(f)
        }
    }
}

/// 1-D data on the curve network: per curve vertex (primal) or per curve edge (dual) of the
/// step that made the level, the cage points themselves before the first step, or (classic
/// Catmull-Clark, which has no 1-D scheme) the 2-D values at the curve vertices.
enum CurveData<T: Scalar, const N: usize> {
    Cage,
    Primal(Vec<Value<T, N>>),
    Dual(Vec<Value<T, N>>),
    OnVertices,
}

/// Buffers that evaluations through a plan leave behind for the next ones (so that a cached
/// re-evaluation does not pay page faults for its intermediate data): a few vectors of any
/// value type, behind a mutex that is held only to take or give one.
#[derive(Default)]
pub(crate) struct Scratch {
    /// The kept buffers, oldest first.
    pool: Mutex<Vec<Box<dyn Any + Send>>>,
    /// Buffers [`Scratch::kept`] allocated because none fitted: after [`Scratch::provision`]
    /// each is a buffer that a run dropped instead of giving back, and an infallible
    /// allocation (an abort when the address space runs out there).
    unprovisioned: AtomicUsize,
}

/// Buffers kept at most (the oldest go first): a windowed step holds four (its input, its
/// output, and the two that its zone writes in part), which are kept at the length of the
/// largest level between evaluations so that the partly written ones need no fill.
pub(crate) const SCRATCH_BUFFERS: usize = 4;

impl Debug for Scratch {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("Scratch")
    }
}

impl Scratch {
    /// An empty vector with room for `capacity` items: a kept one if it is large enough, the
    /// one with the fewest items (so that [`Scratch::take_longest`] finds the longer ones).
    pub(crate) fn take<V: Send + 'static>(&self, capacity: usize) -> Vec<V> {
        let mut v = self.kept(capacity, false);
        v.clear();
        v
    }

    /// A vector with room for `capacity` items, as long as a kept one is: the windowed step's
    /// buffers that its passes write in part need no fill up to that length (their items are
    /// values from an earlier evaluation, which those passes do not read).
    pub(crate) fn take_longest<V: Send + 'static>(&self, capacity: usize) -> Vec<V> {
        self.kept(capacity, true)
    }

    /// The kept vector of `V` with room for `capacity` items with the most (`longest`) or
    /// fewest items, as it was given, or a new empty one.
    fn kept<V: Send + 'static>(&self, capacity: usize, longest: bool) -> Vec<V> {
        let kept = {
            let mut pool = self.pool.lock().unwrap_or_else(|e| e.into_inner());
            let fitting = pool.iter().enumerate().filter_map(|(i, b)| {
                let v = b.downcast_ref::<Vec<V>>()?;
                (v.capacity() >= capacity).then_some((v.len(), i))
            });
            let chosen = match longest {
                true => fitting.max(),
                false => fitting.min(),
            };
            chosen.map(|(_, i)| pool.remove(i))
        };
        match kept.and_then(|b| b.downcast::<Vec<V>>().ok()) {
            Some(v) => *v,
            None => {
                if capacity > 0 {
                    self.unprovisioned.fetch_add(1, Ordering::Relaxed);
                }
                hinted_or_abort(capacity)
            }
        }
    }

    /// How many buffers are kept.
    #[cfg(test)]
    pub(crate) fn kept_buffers(&self) -> usize {
        self.pool.lock().unwrap_or_else(|e| e.into_inner()).len()
    }

    /// How many buffers were allocated outside [`Scratch::provision`] (see the field).
    #[cfg(test)]
    pub(crate) fn unprovisioned(&self) -> usize {
        self.unprovisioned.load(Ordering::Relaxed)
    }

    /// Makes sure `count` (at most [`SCRATCH_BUFFERS`]) buffers of `V` with room for
    /// `capacity` values are kept, allocating the missing ones fallibly: a run of steps takes
    /// at most two new buffers, so after this none of its allocations of the level's size can
    /// fail.
    pub(crate) fn provision<V: Send + 'static>(&self, capacity: usize, count: usize) -> Result<()> {
        let mut pool = self.pool.lock().unwrap_or_else(|e| e.into_inner());
        let fits = |b: &Box<dyn Any + Send>| {
            b.downcast_ref::<Vec<V>>()
                .is_some_and(|v| v.capacity() >= capacity)
        };
        let mut have = pool.iter().filter(|b| fits(b)).count();
        while have < count.min(SCRATCH_BUFFERS) {
            if pool.len() >= SCRATCH_BUFFERS {
                // The oldest buffer that does not fit goes.
                let other = pool.iter().position(|b| !fits(b)).unwrap_or(0);
                pool.remove(other);
            }
            pool.push(Box::new(with_capacity_hinted::<V>(capacity)?));
            have += 1;
        }
        Ok(())
    }

    /// Frees every kept buffer.
    pub(crate) fn clear(&self) {
        self.pool.lock().unwrap_or_else(|e| e.into_inner()).clear();
    }

    /// Keeps `v` for later evaluations.
    pub(crate) fn give<V: Send + 'static>(&self, v: Vec<V>) {
        if v.capacity() == 0 {
            return;
        }
        let mut pool = self.pool.lock().unwrap_or_else(|e| e.into_inner());
        if pool.len() >= SCRATCH_BUFFERS {
            pool.remove(0);
        }
        pool.push(Box::new(v));
    }
}

/// The data of a level on its way through the steps: 2-D data (per vertex when primal, per
/// face when dual) and the 1-D data on the curve network of the step that made the level. Two
/// buffers carry the 2-D data and are reused from pass to pass (a third, `spare`, where a rule
/// set needs its input after the averages).
pub(crate) struct LevelData<'a, T: Scalar, const N: usize> {
    /// The cage points (compacted numbering): corners keep these.
    cage: &'a [Value<T, N>],
    /// Primal data, valid when `primal`.
    vertices: Cow<'a, [Value<T, N>]>,
    /// Dual data, valid when not `primal`.
    faces: Cow<'a, [Value<T, N>]>,
    /// A free buffer.
    spare: Vec<Value<T, N>>,
    primal: bool,
    curve: CurveData<T, N>,
    /// Where new buffers come from (with room for the largest level), when given.
    scratch: Option<(&'a Scratch, usize)>,
}

/// A level's 2-D data (per vertex or per face) and 1-D data (per curve vertex or curve edge).
pub(crate) type Parts<T, const N: usize> = (Vec<Value<T, N>>, Vec<Value<T, N>>);

/// The data at the end of a run of steps.
pub(crate) enum Final<T: Scalar, const N: usize> {
    /// Per vertex.
    Primal(Vec<Value<T, N>>),
    /// Per face, and the 1-D values of the last step's curve edges.
    Dual {
        faces: Vec<Value<T, N>>,
        curve_edges: Vec<Value<T, N>>,
    },
}

impl<'a, T: Scalar, const N: usize> LevelData<'a, T, N> {
    /// The cage points as primal data on `M_0`.
    pub(crate) fn new(cage: &'a [Value<T, N>]) -> Self {
        LevelData {
            cage,
            vertices: Cow::Borrowed(cage),
            faces: Cow::Borrowed(&[]),
            spare: Vec::new(),
            primal: true,
            curve: CurveData::Cage,
            scratch: None,
        }
    }

    /// Data on a refined level: `values` per vertex (`primal`) or per face, `curve` per curve
    /// vertex or curve edge of the network of the step that made the level; `cage` holds the
    /// points that corners keep.
    pub(crate) fn on_level(
        cage: &'a [Value<T, N>],
        primal: bool,
        values: &'a [Value<T, N>],
        curve: Vec<Value<T, N>>,
    ) -> Self {
        let mut data = LevelData::new(cage);
        data.primal = primal;
        if primal {
            data.vertices = Cow::Borrowed(values);
            data.curve = CurveData::Primal(curve);
        } else {
            data.faces = Cow::Borrowed(values);
            data.curve = CurveData::Dual(curve);
        }
        data
    }

    /// New buffers come from `scratch`, with room for `capacity` values.
    pub(crate) fn with_scratch(mut self, scratch: &'a Scratch, capacity: usize) -> Self {
        self.scratch = Some((scratch, capacity));
        self
    }

    /// For a step run outside a plan (the adaptive partial levels, the analysis): new buffers
    /// come from `scratch`, first provisioned (fallibly) with the four buffers of the fine
    /// level's size that a step takes at most (a windowed step), so that the step's gathers
    /// never allocate.
    pub(crate) fn with_scratch_for(self, scratch: &'a Scratch, step: &Step) -> Result<Self> {
        let fine = step.fine;
        let capacity = fine.num_vertices.max(fine.num_faces());
        scratch.provision::<Value<T, N>>(capacity, SCRATCH_BUFFERS)?;
        Ok(self.with_scratch(scratch, capacity))
    }

    /// The 2-D data (per vertex or per face) and the 1-D data (per curve vertex or curve edge).
    pub(crate) fn into_parts(self) -> (Vec<Value<T, N>>, Vec<Value<T, N>>) {
        let curve = match self.curve {
            CurveData::Primal(c) | CurveData::Dual(c) => c,
            CurveData::Cage | CurveData::OnVertices => Vec::new(),
        };
        if self.primal {
            (self.vertices.into_owned(), curve)
        } else {
            (self.faces.into_owned(), curve)
        }
    }

    /// One step: the next level's data from this level's (see the module documentation).
    /// Fails only when regular windows made again for the other kind of data (see
    /// [`Step::windows`]) find no memory.
    pub(crate) fn step(&mut self, step: &Step) -> Result<()> {
        match step.scheme {
            Scheme::Averaging { degree } => self.average(step, degree)?,
            Scheme::Bilinear => self.average_by_passes(step, 1),
            Scheme::DooSabin => self.doo_sabin(step),
            Scheme::CatmullClark { creasing } => self.catmark(step, creasing)?,
        }
        Ok(())
    }

    /// The step of the averaging rules of `degree`: the regular items by the kernel, the
    /// others by the passes ([`regular`]).
    fn average(&mut self, step: &Step, degree: u32) -> Result<()> {
        let built;
        let windows = match step.windows {
            Some(w) if w.primal() != self.primal => {
                let (coarse, fine, curves) = (step.coarse, step.fine, step.curves);
                built = Windows::build(coarse, fine, curves, degree, self.primal, Drawing::Skip)?;
                built.as_ref()
            }
            kept => kept,
        };
        match windows {
            Some(w) => {
                debug_assert_eq!(w.degree(), degree);
                self.average_windowed(step, w)?;
            }
            None => self.average_by_passes(step, degree),
        }
        Ok(())
    }

    /// The step of the averaging rules of `degree` as replication and `degree` averages over
    /// every item.
    fn average_by_passes(&mut self, step: &Step, degree: u32) {
        // The fused first pass needs, on dual data, a buffer of our own for its old vertices.
        let fusable = self.primal || matches!(self.faces, Cow::Owned(_));
        let first = if fusable && degree >= 2 && step.coarse.all_quads() {
            self.first_average_to_dual(step);
            3
        } else {
            self.first_average(step);
            2
        };
        for a in first..=degree {
            if a % 2 == 1 {
                self.average_to_primal(step);
            } else {
                self.average_to_dual(step.fine, step.curves);
            }
        }
    }

    /// The step of the averaging rules with `windows` ([`regular`]): the fused first pass, the
    /// kernel, then the later averages up to the kernel's, each pass over the items of the
    /// windows' zone only; an odd degree's last average then runs over every vertex. The coarse
    /// data is read until the kernel has run; its buffer then serves the fine vertices.
    fn average_windowed(&mut self, step: &Step, windows: &Windows) -> Result<()> {
        let (coarse, fine, curves) = (step.coarse, step.fine, step.curves);
        let averages = windows.averages() as usize;
        let zone = windows.zone();
        let primal = self.primal;
        self.replicate_curves(curves);
        let t = Tables::of(coarse);
        let data = match primal {
            true => std::mem::replace(&mut self.vertices, Cow::Borrowed(&[])),
            false => std::mem::replace(&mut self.faces, Cow::Borrowed(&[])),
        };
        let x: &[Value<T, N>] = &data;
        let curve = self.curve_to_primal(curves, |w| first_point(&t, x, primal, w));
        let touched = touched_faces(&t, curves);
        let corner_edges = coarse.corner_edges();
        let children = Children {
            t,
            curves,
            curve: &curve,
            touched: &touched,
            nine: |f: usize| match primal {
                true => primal_nine(&t, x, f),
                false => {
                    let p = std::array::from_fn(|k| {
                        vertex_face_centroid(&t, x, t.corner_verts[4 * f + k] as usize)
                    });
                    (p, edge_face_means(&t, x, corner_edges, f), x[f])
                }
            },
        };
        let (n_faces, n_vertices) = (fine.num_faces(), fine.num_vertices);
        let spare = self.take_spare();
        // Of primal input, the face buffer holds the last step's dual data, dead now (dual
        // input was moved into `data`): dropped, it would leave the kept buffers one short,
        // and a later step would allocate anew (infallibly) every time.
        let dead = self.take_own_faces();
        let mut faces = self.partial([spare, dead], n_faces);
        // A kernel of two averages is the fused first pass's: that pass's children are output.
        let first_is_last = zone.passes.is_empty();
        if !first_is_last {
            initialised(&mut faces, n_faces);
            scatter(&mut faces[..n_faces], &zone.first, |f| children.of(f))?;
        }
        // The fine vertices' buffer, before the kernel's: that one is written whole, so the
        // longer kept buffers go to the partly written ones.
        let old = self.take_own_vertices();
        let mut vertices = self.partial([old, None], n_vertices);
        let fused = windows.fused();
        // With fused points and passes, the kernel's children go to the first pass's buffer
        // once the first dual -> primal pass has read it, before the last pass (below).
        let deferred = fused.is_some() && !first_is_last;
        // The kernel's output: every child written once, by the kernel or by the last pass;
        // with fused points, only the children the other fine vertices read, into a kept
        // buffer (the zone's).
        let mut out = match fused {
            Some(_) if first_is_last => {
                initialised(&mut faces, n_faces);
                let out = std::mem::take(&mut faces);
                faces = self.fresh();
                out
            }
            Some(_) => Vec::new(),
            None => {
                let mut out = self.fresh();
                out.clear();
                if out.capacity() < n_faces {
                    out = hinted_or_abort(n_faces);
                }
                if windows.partial() {
                    // Windows for some items leave the other children unwritten.
                    out.spare_capacity_mut()[..n_faces].fill(MaybeUninit::new(zero()));
                }
                out
            }
        };
        debug_assert_eq!(windows.primal(), primal);
        if !deferred {
            let children_out = match fused {
                // SAFETY: the kernel writes only values.
                Some(_) => unsafe { as_uninit(&mut out[..n_faces]) },
                None => &mut out.spare_capacity_mut()[..n_faces],
            };
            windows.apply(x, children_out)?;
            if first_is_last {
                // Every child of these faces, after the kernel: its writes spill into the next
                // child ([`regular`]'s `put`), which the pass then writes.
                scatter_uninit(children_out, &zone.first, |f| children.of(f))?;
            }
        }
        self.curve = CurveData::Dual(curve_to_dual(curves, &curve));
        let quarter = T::from_f64(0.25);
        for (pass, items) in zone.passes.iter().enumerate() {
            if pass % 2 == 0 {
                // Dual -> primal: the fine vertices from the fine faces around them.
                let f: &[Value<T, N>] = &faces[..n_faces];
                initialised(&mut vertices, n_vertices);
                scatter(&mut vertices[..n_vertices], items, |w| {
                    [primal_item(&t, f, w)]
                })?;
                let curve = self.blend_curves(curves, &mut vertices[..n_vertices]);
                self.curve = CurveData::Primal(curve);
            } else {
                // Primal -> dual: the fine faces from their corners.
                let v: &[Value<T, N>] = &vertices[..n_vertices];
                let (quads, _) = fine.corner_verts.as_chunks::<4>();
                let value = |g: usize| [corner_centroid(v, &quads[g], quarter)];
                if pass + 3 == averages && deferred {
                    // The first pass's children are read: the kernel's go there, then the last
                    // pass's (after the kernel, whose writes spill into the next child).
                    // SAFETY: the kernel writes only values.
                    windows.apply(x, unsafe { as_uninit(&mut faces[..n_faces]) })?;
                    scatter(&mut faces[..n_faces], items, value)?;
                    out = std::mem::take(&mut faces);
                } else if pass + 3 == averages {
                    scatter_uninit(&mut out.spare_capacity_mut()[..n_faces], items, value)?;
                } else {
                    scatter(&mut faces[..n_faces], items, value)?;
                }
                let CurveData::Primal(curve) = &self.curve else {
                    unreachable!("1-D data out of step")
                };
                self.curve = CurveData::Dual(curve_to_dual(curves, curve));
            }
        }
        if deferred && out.len() < n_faces {
            return Err(Error::Internal(
                "fused points: no last pass for the kernel's children".into(),
            ));
        }
        let mut intermediate = None;
        if let Some(fused) = fused {
            if deferred {
                // The passes' primal data keeps its buffer (a kept one, as long as the level:
                // the spare below), and the fine vertices get their own.
                let points = self.fresh();
                intermediate = Some(std::mem::replace(&mut vertices, points));
            }
            // After the passes: of points made for every item, each fine vertex is written
            // once, by the fused sums or by the last average below; of some, a kept buffer
            // holds the others.
            match fused.whole() {
                true => vertices.clear(),
                false => initialised(&mut vertices, n_vertices),
            }
            if vertices.capacity() < n_vertices {
                vertices = hinted_or_abort(n_vertices);
            }
            fused.apply(x, coarse, slots(&mut vertices, n_vertices))?;
        } else {
            // SAFETY: the kernel wrote its children and the last pass every other one (the
            // zone's last list is the complement of the kernel's children; a panic would have
            // unwound past here).
            unsafe { out.set_len(n_faces) };
        }
        // The coarse data's buffer is free now.
        if let (Cow::Owned(data), Some((scratch, _))) = (data, self.scratch) {
            scratch.give(data);
        }
        self.faces = Cow::Owned(out);
        // With the kernel's children in the first pass's buffer, that one is the output.
        self.spare = intermediate.unwrap_or(faces);
        self.primal = false;
        if let Some(fused) = fused {
            // The other fine vertices from the children around them.
            let f: &[Value<T, N>] = &self.faces;
            let rest = fused.rest();
            scatter_uninit(slots(&mut vertices, n_vertices), rest, |w| {
                [primal_item(&t, f, w)]
            })?;
            match fused.whole() {
                // SAFETY: every fine vertex is written, once, by the fused sums or the scatter
                // (`Fused::whole`; a panic would have unwound past here).
                true => unsafe { vertices.set_len(n_vertices) },
                false => vertices.truncate(n_vertices),
            }
            self.finish_primal(vertices, curves);
            return Ok(());
        }
        self.vertices = Cow::Owned(vertices);
        if windows.degree() % 2 == 1 {
            match windows.last_vertices() {
                Some(items) => self.average_to_primal_at(step, items)?,
                None => self.average_to_primal(step),
            }
        }
        Ok(())
    }

    /// Ends a run on the last step's levels: `want_dual` selects the kind (the drawing mesh
    /// wants primal data, the true dual mesh dual data; the average that converts dual data is
    /// the paper's drawing step). Buffers no longer needed go back to the scratch.
    pub(crate) fn finish(mut self, last: Option<&Step>, want_dual: bool) -> Final<T, N> {
        if let Some(step) = last {
            match (self.primal, want_dual) {
                (true, true) => self.average_to_dual(step.fine, step.curves),
                (false, false) => self.average_to_primal(step),
                _ => {}
            }
        }
        self.give_back_unused();
        if self.primal {
            return Final::Primal(self.vertices.into_owned());
        }
        let CurveData::Dual(curve_edges) = self.curve else {
            unreachable!("dual 1-D data")
        };
        Final::Dual {
            faces: self.faces.into_owned(),
            curve_edges,
        }
    }

    /// The 2-D and 1-D data as the steps left them ([`LevelData::into_parts`]), the buffers no
    /// longer needed going back to the scratch.
    pub(crate) fn finish_parts(mut self) -> Parts<T, N> {
        self.give_back_unused();
        self.into_parts()
    }

    /// Gives the spare buffer and the one of the other kind (faces of primal data, vertices of
    /// dual data) back to the scratch, when there is one.
    fn give_back_unused(&mut self) {
        let Some((scratch, _)) = self.scratch else {
            return;
        };
        scratch.give(std::mem::take(&mut self.spare));
        let other = match self.primal {
            true => std::mem::replace(&mut self.faces, Cow::Borrowed(&[])),
            false => std::mem::replace(&mut self.vertices, Cow::Borrowed(&[])),
        };
        if let Cow::Owned(v) = other {
            scratch.give(v);
        }
    }

    /// The drawing points of dual data (one more dual -> primal average with the 1-D values),
    /// leaving the data as it is. Given `coarse`, the data of the step's coarse level that
    /// `step` made this data from, the points that the step's drawn windows fuse
    /// ([`Windows::drawn`]) come from it by the same sums, with the bits of a plan's drawn
    /// last step (the adaptive levels' points are the uniform ones).
    pub(crate) fn drawing_points(
        &self,
        step: &Step,
        coarse: Option<&[Value<T, N>]>,
    ) -> Result<Vec<Value<T, N>>> {
        let n = step.fine.num_vertices;
        let mut out = with_capacity_hinted(n)?;
        let fused = match (coarse, step.windows) {
            (Some(x), Some(w)) => w.drawing().map(|f| (f, x)),
            _ => None,
        };
        match fused {
            Some((fused, _)) if !fused.whole() => {
                return Err(Error::Internal(
                    "drawing points: fused points made for some items".into(),
                ))
            }
            Some((fused, x)) => {
                fused.apply(x, step.coarse, &mut out.spare_capacity_mut()[..n])?;
                let t = Tables::of(step.coarse);
                let f: &[Value<T, N>] = &self.faces;
                scatter_uninit(&mut out.spare_capacity_mut()[..n], fused.rest(), |w| {
                    [primal_item(&t, f, w)]
                })?;
                // SAFETY: every fine vertex is written, once, by the fused sums or the scatter
                // (the drawing points of a whole step, `Fused::whole`, checked above; a panic
                // would have unwound past here).
                unsafe { out.set_len(n) };
            }
            None => self.gather_primal(step, &mut out),
        }
        self.blend_curves(step.curves, &mut out);
        Ok(out)
    }

    /// A buffer for a new array of values.
    fn fresh(&mut self) -> Vec<Value<T, N>> {
        if self.spare.capacity() > 0 {
            return std::mem::take(&mut self.spare);
        }
        match self.scratch {
            Some((scratch, capacity)) => scratch.take(capacity),
            None => Vec::new(),
        }
    }

    /// A buffer for data that a pass writes in part (the windowed step's zone, which reads only
    /// the items it writes), wanted `n` items long: the longest of the `free` ones and, when
    /// they are shorter, a kept one, so that [`initialised`] fills little or nothing once the
    /// buffers have been as long as the largest level. The others go back to the scratch (or,
    /// without one, the larger becomes the spare buffer).
    fn partial(&mut self, free: [Option<Vec<Value<T, N>>>; 2], n: usize) -> Vec<Value<T, N>> {
        let [a, b] = free;
        let kept = match self.scratch {
            Some((scratch, capacity)) if a.iter().chain(&b).all(|v| v.len() < n) => {
                Some(scratch.take_longest(capacity))
            }
            _ => None,
        };
        let mut candidates = [a, b, kept];
        candidates.sort_by_key(|v| std::cmp::Reverse(v.as_ref().map(Vec::len)));
        let [chosen, others @ ..] = candidates;
        for other in others.into_iter().flatten() {
            match self.scratch {
                Some((scratch, _)) => scratch.give(other),
                None if other.capacity() > self.spare.capacity() => self.spare = other,
                None => {}
            }
        }
        chosen.unwrap_or_default()
    }

    /// The spare buffer, if there is one.
    fn take_spare(&mut self) -> Option<Vec<Value<T, N>>> {
        Some(std::mem::take(&mut self.spare)).filter(|v| v.capacity() > 0)
    }

    /// The vertices' buffer when it is ours (outside the steps' data: the caller overwrites it).
    fn take_own_vertices(&mut self) -> Option<Vec<Value<T, N>>> {
        match std::mem::replace(&mut self.vertices, Cow::Borrowed(&[])) {
            Cow::Owned(v) => Some(v),
            Cow::Borrowed(_) => None,
        }
    }

    /// The faces' buffer when it is ours and has room (the caller overwrites it).
    fn take_own_faces(&mut self) -> Option<Vec<Value<T, N>>> {
        match std::mem::replace(&mut self.faces, Cow::Borrowed(&[])) {
            Cow::Owned(f) if f.capacity() > 0 => Some(f),
            _ => None,
        }
    }

    /// A buffer for new primal data: the old one when it is ours, else a fresh one.
    fn take_vertices(&mut self) -> Vec<Value<T, N>> {
        match std::mem::replace(&mut self.vertices, Cow::Borrowed(&[])) {
            Cow::Owned(v) => v,
            Cow::Borrowed(_) => self.fresh(),
        }
    }

    /// A buffer for new dual data: the face buffer when it has room, else a fresh one.
    fn take_faces(&mut self) -> Vec<Value<T, N>> {
        self.take_own_faces().unwrap_or_else(|| self.fresh())
    }

    /// Replication of the 1-D data: each curve half-edge takes the value of its parent.
    fn replicate_curves(&mut self, curves: &CurveNetwork) {
        let edges = curves.edges();
        let curve = match &self.curve {
            CurveData::Cage => edges.iter().map(|e| self.cage[e.source as usize]).collect(),
            CurveData::Primal(v) | CurveData::Dual(v) => {
                edges.iter().map(|e| v[e.source as usize]).collect()
            }
            CurveData::OnVertices => unreachable!("the averaging rules carry their 1-D data"),
        };
        self.curve = CurveData::Dual(curve);
    }

    /// The 1-D half of a dual -> primal average: curve vertices take the midpoint of their two
    /// curve edges, corners their cage point (or, cut off by a partial level, their 2-D value
    /// `two_d(vertex)`).
    fn curve_to_primal(
        &self,
        curves: &CurveNetwork,
        two_d: impl Fn(usize) -> Value<T, N>,
    ) -> Vec<Value<T, N>> {
        let CurveData::Dual(edge_values) = &self.curve else {
            unreachable!("1-D data out of step")
        };
        let half = T::from_f64(0.5);
        (curves.vertices().iter())
            .map(|cv| match cv.edges {
                Some([a, b]) => scale(add(edge_values[a as usize], edge_values[b as usize]), half),
                None if cv.pin != NONE => self.cage[cv.pin as usize],
                None => two_d(cv.vertex as usize),
            })
            .collect()
    }

    /// Curve vertices and corners of `vertices` (fresh 2-D centroids) take (a blend towards)
    /// their 1-D values, which are returned.
    fn blend_curves(
        &self,
        curves: &CurveNetwork,
        vertices: &mut [Value<T, N>],
    ) -> Vec<Value<T, N>> {
        let curve = self.curve_to_primal(curves, |w| vertices[w]);
        for (cv, &value) in curves.vertices().iter().zip(&curve) {
            blend(&mut vertices[cv.vertex as usize], value, cv);
        }
        curve
    }

    /// `vertices` (fresh 2-D centroids) with their curve vertices blended become the primal
    /// data.
    fn finish_primal(&mut self, mut vertices: Vec<Value<T, N>>, curves: &CurveNetwork) {
        let curve = self.blend_curves(curves, &mut vertices);
        self.vertices = Cow::Owned(vertices);
        self.curve = CurveData::Primal(curve);
        self.primal = true;
    }

    /// Replication followed by the first dual -> primal average, in closed form on the coarse
    /// level (the replicated face values are never stored): an old vertex takes its own point
    /// (primal) or the centroid of its faces (dual), an edge point the midpoint of its ends
    /// (primal) or of its faces (dual), a face point the centroid of its corners (primal) or its
    /// face's point (dual).
    fn first_average(&mut self, step: &Step) {
        let (coarse, fine) = (step.coarse, step.fine);
        self.replicate_curves(step.curves);
        let (nv, ne) = (coarse.num_vertices, coarse.num_edges());
        let sections = [nv, ne, fine.num_vertices - nv - ne];
        let t = Tables::of(coarse);
        if self.primal {
            let mut out = self.take_faces();
            let v: &[Value<T, N>] = &self.vertices;
            gather_sections(
                &mut out,
                sections,
                |w| v[w],
                |e| edge_midpoint(&t, v, e),
                |f| face_centroid(&t, v, f),
            );
            // The coarse primal buffer is free now: keep it for later passes.
            if let Cow::Owned(old) = std::mem::replace(&mut self.vertices, Cow::Borrowed(&[])) {
                self.faces = Cow::Owned(old);
            }
            self.finish_primal(out, step.curves);
        } else {
            let mut out = self.take_vertices();
            let f: &[Value<T, N>] = &self.faces;
            gather_sections(
                &mut out,
                sections,
                |w| vertex_face_centroid(&t, f, w),
                |e| edge_face_mean(&t, f, e),
                |face| f[face],
            );
            self.finish_primal(out, step.curves);
        }
    }

    /// Replication, the first dual -> primal and the first primal -> dual average of a step on a
    /// quad level, in one pass over the coarse faces: each computes the nine child points of its
    /// face in closed form (as [`LevelData::first_average`], never stored) and the centroids of
    /// its four child faces. Primal data gives the child points from the face's corners; dual
    /// data (which must be in a buffer of our own) from the face, its edge neighbours and the
    /// old vertices' points, computed once each into the tail of that buffer (it has room for
    /// a level of the plan). Faces next to curve vertices use the blended points. The result is
    /// bitwise that of the separate passes.
    fn first_average_to_dual(&mut self, step: &Step) {
        let (coarse, fine, curves) = (step.coarse, step.fine, step.curves);
        debug_assert!(coarse.all_quads());
        let primal = self.primal;
        self.replicate_curves(curves);
        let nv = coarse.num_vertices;
        let t = Tables::of(coarse);
        let curve = {
            let x: &[Value<T, N>] = if primal { &self.vertices } else { &self.faces };
            self.curve_to_primal(curves, |w| first_point(&t, x, primal, w))
        };
        let touched = touched_faces(&t, curves);
        let n = fine.num_faces();
        if primal {
            let mut out = self.take_faces();
            let v: &[Value<T, N>] = &self.vertices;
            let children = Children {
                t,
                curves,
                curve: &curve,
                touched: &touched,
                nine: |f: usize| primal_nine(&t, v, f),
            };
            child_face_centroids(&children, &mut out, n);
            self.faces = Cow::Owned(out);
        } else {
            let Cow::Owned(mut x) = std::mem::replace(&mut self.faces, Cow::Borrowed(&[])) else {
                unreachable!("the fused pass on dual data takes its own buffer")
            };
            let nf = x.len();
            x.resize(nf + nv, zero());
            let (data, old) = x.split_at_mut(nf);
            let data: &[Value<T, N>] = data;
            old.par_chunks_mut(CHUNK)
                .enumerate()
                .for_each(|(chunk, points)| {
                    for (i, p) in points.iter_mut().enumerate() {
                        *p = vertex_face_centroid(&t, data, chunk * CHUNK + i);
                    }
                });
            let old: &[Value<T, N>] = old;
            let corner_edges = coarse.corner_edges();
            let mut out = self.take_vertices();
            let children = Children {
                t,
                curves,
                curve: &curve,
                touched: &touched,
                nine: |f: usize| {
                    let p = t.at_corners(old, f);
                    (p, edge_face_means(&t, data, corner_edges, f), data[f])
                },
            };
            child_face_centroids(&children, &mut out, n);
            x.truncate(nf);
            self.vertices = Cow::Owned(x);
            self.faces = Cow::Owned(out);
        }
        self.curve = CurveData::Dual(curve_to_dual(curves, &curve));
        self.primal = false;
    }

    /// The dual -> primal centroids on `fine` into `out`, gathered through the coarse level's
    /// tables: face `c` of `fine` is corner `c` of `coarse`, so an old vertex's faces are its
    /// coarse corners, an edge point's faces the corners on its edge and their successors, a
    /// face point's faces the corners of its face.
    fn gather_primal(&self, step: &Step, out: &mut Vec<Value<T, N>>) {
        let coarse = step.coarse;
        let (nv, ne) = (coarse.num_vertices, coarse.num_edges());
        let f: &[Value<T, N>] = &self.faces;
        let t = Tables::of(coarse);
        if !t.quads {
            gather_sections(
                out,
                [nv, ne, step.fine.num_vertices - nv - ne],
                |w| vertex_corner_mean(&t, f, w),
                |e| edge_corner_mean(&t, f, t.edge_corners[e]),
                |face| {
                    let corners = t.face_corners(face);
                    let k = corners.len();
                    let sum = f[corners].iter().fold(zero(), |s, &x| add(s, x));
                    scale(sum, reciprocal(k))
                },
            );
            return;
        }
        // A quad level: the same sums, each section walking its table in step with the output.
        // The old vertices walk their offsets only to go through `fill_zip`: with the plain
        // `fill` LLVM stopped inlining this closure (cached averaging 4: +14 % instructions).
        let n = step.fine.num_vertices;
        out.clear();
        if out.capacity() < n {
            *out = hinted_or_abort(n);
        }
        let (olds, rest) = out.spare_capacity_mut()[..n].split_at_mut(nv);
        let (edges, faces) = rest.split_at_mut(ne);
        if wide::gather_primal(&t, f, wide::PrimalSections { olds, edges, faces }) {
            // SAFETY: the vectors initialised the first `n` items.
            unsafe { out.set_len(n) };
            return;
        }
        let (olds, rest) = out.spare_capacity_mut()[..n].split_at_mut(nv);
        let (edges, faces) = rest.split_at_mut(ne);
        fill_zip(olds, &t.vertex_offsets[..nv], |w, _| {
            vertex_corner_mean(&t, f, w)
        });
        let (quads, _) = f.as_chunks::<4>();
        fill_zip(edges, t.edge_corners, |_, &corners| {
            quad_edge_mean(quads, corners)
        });
        let quarter = T::from_f64(0.25);
        fill_zip(faces, &quads[..faces.len()], |_, q| quad_mean(q, quarter));
        // SAFETY: the three fills initialised the first `n` items (a panic would have unwound
        // past here).
        unsafe { out.set_len(n) };
    }

    /// Dual -> primal average on the fine level of `step`, with the 1-D half on its curves.
    fn average_to_primal(&mut self, step: &Step) {
        let mut out = self.vertex_buffer();
        self.gather_primal(step, &mut out);
        self.finish_primal(out, step.curves);
    }

    /// [`LevelData::average_to_primal`] on the fine vertices `items` (sorted) alone, for a
    /// caller that reads no other (the other vertices hold zeros or earlier values).
    fn average_to_primal_at(&mut self, step: &Step, items: &[u32]) -> Result<()> {
        let n = step.fine.num_vertices;
        let mut out = self.vertex_buffer();
        initialised(&mut out, n);
        out.truncate(n);
        let t = Tables::of(step.coarse);
        let f: &[Value<T, N>] = &self.faces;
        scatter(&mut out[..n], items, |w| [primal_item(&t, f, w)])?;
        self.finish_primal(out, step.curves);
        Ok(())
    }

    /// A buffer for the fine vertices of a dual -> primal average, which writes every vertex
    /// it keeps: a short kept buffer will do, the long ones stay for the windowed step's partly
    /// written buffers ([`LevelData::partial`]).
    fn vertex_buffer(&mut self) -> Vec<Value<T, N>> {
        match (self.scratch, self.take_own_vertices()) {
            (Some((scratch, capacity)), old) => {
                if let Some(old) = old {
                    scratch.give(old);
                }
                scratch.take(capacity)
            }
            (None, Some(old)) => old,
            (None, None) => self.fresh(),
        }
    }

    /// Primal -> dual average on `fine`: each face takes the centroid of its four corners, each
    /// curve edge the midpoint of its two ends.
    fn average_to_dual(&mut self, fine: &Level, curves: &CurveNetwork) {
        let quarter = T::from_f64(0.25);
        let mut out = self.take_faces();
        let v: &[Value<T, N>] = &self.vertices;
        let (quads, _) = fine.corner_verts.as_chunks::<4>();
        gather_zip(&mut out, &quads[..fine.num_faces()], |_, q| {
            corner_centroid(v, q, quarter)
        });
        self.faces = Cow::Owned(out);
        let dual = match &self.curve {
            CurveData::Primal(curve) => curve_to_dual(curves, curve),
            CurveData::OnVertices => {
                let curve: Vec<Value<T, N>> = (curves.vertices().iter())
                    .map(|cv| v[cv.vertex as usize])
                    .collect();
                curve_to_dual(curves, &curve)
            }
            CurveData::Cage | CurveData::Dual(_) => unreachable!("1-D data out of step"),
        };
        self.curve = CurveData::Dual(dual);
        self.primal = false;
    }
}

/// Fine vertex `w` after replication and the first dual -> primal average of primal (`primal`)
/// or dual data `x` of `coarse`, in closed form (the sections of [`LevelData::first_average`]).
#[inline]
fn first_point<T: Scalar, const N: usize>(
    t: &Tables,
    x: &[Value<T, N>],
    primal: bool,
    w: usize,
) -> Value<T, N> {
    let (nv, ne) = (t.level.num_vertices, t.level.num_edges());
    match (primal, w < nv, w < nv + ne) {
        (true, true, _) => x[w],
        (true, false, true) => edge_midpoint(t, x, w - nv),
        (true, false, false) => face_centroid(t, x, w - nv - ne),
        (false, true, _) => vertex_face_centroid(t, x, w),
        (false, false, true) => edge_face_mean(t, x, w - nv),
        (false, false, false) => x[w - nv - ne],
    }
}

/// The nine child points of coarse quad `f` from primal data `v` ([`Nine`]): its corners, the
/// midpoints of its edges, the centroid of its corners.
#[inline(always)]
fn primal_nine<T: Scalar, const N: usize>(
    t: &Tables,
    v: &[Value<T, N>],
    f: usize,
) -> ([Value<T, N>; 4], [Value<T, N>; 4], Value<T, N>) {
    let half = T::from_f64(0.5);
    let p = t.at_corners(v, f);
    let centre = scale(p.iter().fold(zero(), |s, &x| add(s, x)), reciprocal(4));
    let m = std::array::from_fn(|k| scale(add(p[k], p[(k + 1) & 3]), half));
    (p, m, centre)
}

/// Fine vertex `w` after a dual -> primal average of the fine faces' data `f` (one item of
/// [`LevelData::gather_primal`] on a quad level: the same sums in the same order).
#[inline(always)]
fn primal_item<T: Scalar, const N: usize>(t: &Tables, f: &[Value<T, N>], w: usize) -> Value<T, N> {
    let (nv, ne) = (t.level.num_vertices, t.edge_verts.len());
    if w < nv {
        vertex_corner_mean(t, f, w)
    } else if w < nv + ne {
        quad_edge_mean(f.as_chunks::<4>().0, t.edge_corners[w - nv])
    } else {
        let g = w - nv - ne;
        quad_mean(&f[4 * g..4 * g + 4], T::from_f64(0.25))
    }
}

/// The centroid of a fine quad from the primal data `v` at its corners `q` (a primal -> dual
/// average; `quarter` is 1/4 in `T`).
#[inline(always)]
fn corner_centroid<T: Scalar, const N: usize>(
    v: &[Value<T, N>],
    q: &[u32; 4],
    quarter: T,
) -> Value<T, N> {
    let s = add(
        add(v[q[0] as usize], v[q[1] as usize]),
        add(v[q[2] as usize], v[q[3] as usize]),
    );
    scale(s, quarter)
}

/// The mean of the four fine faces `q` of a coarse quad, at its face point (a dual -> primal
/// average; `quarter` is 1/4 in `T`).
#[inline(always)]
fn quad_mean<T: Scalar, const N: usize>(q: &[Value<T, N>], quarter: T) -> Value<T, N> {
    scale(q.iter().fold(zero(), |s, &x| add(s, x)), quarter)
}

/// The first `n` items of `buffer` to write: its items when it holds them (initialised; they
/// stay so: its callers write only values), else its spare room.
fn slots<V>(buffer: &mut Vec<V>, n: usize) -> &mut [MaybeUninit<V>] {
    match buffer.len() >= n {
        // SAFETY: the slots' writers (the fused points, `scatter_uninit`) write only values.
        true => unsafe { as_uninit(&mut buffer[..n]) },
        false => &mut buffer.spare_capacity_mut()[..n],
    }
}

/// `buffer` holds at least `n` initialised items (the pass after it writes some of them and
/// reads only those). Its items may be values of an earlier evaluation
/// ([`LevelData::partial`]): debug builds set them to NaN, so that a pass reading an item it
/// did not write shows in the results.
fn initialised<T: Scalar, const N: usize>(buffer: &mut Vec<Value<T, N>>, n: usize) {
    if cfg!(debug_assertions) {
        buffer.clear();
        buffer.resize(n, [T::from_f64(f64::NAN); N]);
    } else if buffer.len() < n {
        buffer.resize(n, zero());
    }
}

/// The coarse faces whose child faces have a curve vertex of `curves` among their corners
/// (empty when the step has none).
fn touched_faces(t: &Tables, curves: &CurveNetwork) -> Vec<bool> {
    let coarse = t.level;
    if curves.vertices().is_empty() {
        return Vec::new();
    }
    let (nv, ne) = (coarse.num_vertices, coarse.num_edges());
    let mut touched = vec![false; coarse.num_faces()];
    for cv in curves.vertices() {
        let w = cv.vertex as usize;
        if w < nv {
            for &c in t.corners_of_vertex(w) {
                touched[t.face_of(c as usize)] = true;
            }
        } else if w < nv + ne {
            for &c in &t.edge_corners[w - nv] {
                if c != NONE {
                    touched[t.face_of(c as usize)] = true;
                }
            }
        } else {
            touched[w - nv - ne] = true;
        }
    }
    touched
}

/// The second half of [`LevelData::first_average_to_dual`]: `out` becomes the `n` faces of
/// the fine level, four per coarse quad ([`Children::of`]). Each face is written once, in
/// parallel chunks (so a new buffer's pages are touched by both threads).
fn child_face_centroids<T: Scalar, const N: usize>(
    children: &Children<'_, T, N, impl Nine<T, N>>,
    out: &mut Vec<Value<T, N>>,
    n: usize,
) {
    out.clear();
    if out.capacity() < n {
        *out = hinted_or_abort(n);
    }
    out.spare_capacity_mut()[..n]
        .par_chunks_mut(4 * CHUNK)
        .enumerate()
        .for_each(|(chunk, faces)| {
            for (i, quad) in faces.chunks_exact_mut(4).enumerate() {
                let children = children.of(chunk * CHUNK + i);
                for (out, value) in quad.iter_mut().zip(children) {
                    out.write(value);
                }
            }
        });
    // SAFETY: the loop above wrote every one of the first `n` items (`n` is four times the
    // coarse faces; a panic would have unwound past here).
    unsafe { out.set_len(n) };
}

/// The nine child points of a coarse quad after replication and the first dual -> primal
/// average: its old vertices, the edge points of its corners' outgoing edges, its face point.
trait Nine<T: Scalar, const N: usize>:
    Fn(usize) -> ([Value<T, N>; 4], [Value<T, N>; 4], Value<T, N>) + Sync
{
}

impl<T: Scalar, const N: usize, F> Nine<T, N> for F where
    F: Fn(usize) -> ([Value<T, N>; 4], [Value<T, N>; 4], Value<T, N>) + Sync
{
}

/// What the fused first pass reads to make the four child faces of a coarse quad: the nine
/// child points `nine(f)`, which take their 1-D values `curve` where `touched`.
struct Children<'c, T: Scalar, const N: usize, F> {
    t: Tables<'c>,
    curves: &'c CurveNetwork,
    curve: &'c [Value<T, N>],
    touched: &'c [bool],
    nine: F,
}

impl<T: Scalar, const N: usize, F: Nine<T, N>> Children<'_, T, N, F> {
    /// The four child faces of coarse quad `f`, each the centroid of its corners among the
    /// nine child points.
    #[inline(always)]
    fn of(&self, f: usize) -> [Value<T, N>; 4] {
        let t = &self.t;
        let coarse = t.level;
        let (nv, ne) = (coarse.num_vertices, coarse.num_edges());
        let blended = |w: usize, mut p: Value<T, N>| -> Value<T, N> {
            if let Some(i) = self.curves.vertex_index(w as u32) {
                blend(
                    &mut p,
                    self.curve[i as usize],
                    &self.curves.vertices()[i as usize],
                );
            }
            p
        };
        let (mut p, mut m, mut centre) = (self.nine)(f);
        if self.touched.get(f).copied().unwrap_or(false) {
            let q = &t.corner_verts[4 * f..4 * f + 4];
            for k in 0..4 {
                p[k] = blended(q[k] as usize, p[k]);
                let e = coarse.corner_edges()[4 * f + k] as usize;
                m[k] = blended(nv + e, m[k]);
            }
            centre = blended(nv + ne + f, centre);
        }
        let quarter = T::from_f64(0.25);
        std::array::from_fn(|k| {
            let s = add(add(p[k], m[k]), add(centre, m[(k + 3) & 3]));
            scale(s, quarter)
        })
    }
}

/// The midpoint of coarse edge `e` from primal data `v` (its edge point after replication and
/// one average).
#[inline(always)]
fn edge_midpoint<T: Scalar, const N: usize>(
    t: &Tables,
    v: &[Value<T, N>],
    e: usize,
) -> Value<T, N> {
    let [a, b] = t.edge_verts[e];
    scale(add(v[a as usize], v[b as usize]), T::from_f64(0.5))
}

/// The centroid of the corners of coarse face `f` from primal data `v` (its face point after
/// replication and one average).
#[inline(always)]
fn face_centroid<T: Scalar, const N: usize>(
    t: &Tables,
    v: &[Value<T, N>],
    f: usize,
) -> Value<T, N> {
    let corners = t.face_corners(f);
    let k = corners.len();
    let sum = corners.fold(zero(), |s, c| add(s, v[t.corner_verts[c] as usize]));
    scale(sum, reciprocal(k))
}

/// The centroid of the faces at coarse vertex `w` from dual data `f` (its point after
/// replication and one average).
#[inline(always)]
fn vertex_face_centroid<T: Scalar, const N: usize>(
    t: &Tables,
    f: &[Value<T, N>],
    w: usize,
) -> Value<T, N> {
    let corners = t.corners_of_vertex(w);
    let sum = corners
        .iter()
        .fold(zero(), |s, &c| add(s, f[t.face_of(c as usize)]));
    scale(sum, reciprocal(corners.len()))
}

/// The mean of the faces of coarse edge `e` from dual data `f` (its edge point after
/// replication and one average).
#[inline(always)]
fn edge_face_mean<T: Scalar, const N: usize>(
    t: &Tables,
    f: &[Value<T, N>],
    e: usize,
) -> Value<T, N> {
    match t.edge_corners[e] {
        [c, NONE] => f[t.face_of(c as usize)],
        [c, d] => scale(
            add(f[t.face_of(c as usize)], f[t.face_of(d as usize)]),
            T::from_f64(0.5),
        ),
    }
}

/// [`edge_face_mean`] of the edges of coarse quad `f`'s corners, written out: through
/// `array::from_fn` LLVM left the closure out of line, a call per mean (cached averaging 2:
/// 54.1M instructions, 44.8M written out).
#[inline(always)]
fn edge_face_means<T: Scalar, const N: usize>(
    t: &Tables,
    x: &[Value<T, N>],
    corner_edges: &[u32],
    f: usize,
) -> [Value<T, N>; 4] {
    let mean = |k: usize| edge_face_mean(t, x, corner_edges[4 * f + k] as usize);
    [mean(0), mean(1), mean(2), mean(3)]
}

/// The centroid of the fine faces at old vertex `w` (they are its coarse corners: unlike
/// [`vertex_face_centroid`], `f` is dual data of the fine level) after a dual -> primal average.
#[inline(always)]
fn vertex_corner_mean<T: Scalar, const N: usize>(
    t: &Tables,
    f: &[Value<T, N>],
    w: usize,
) -> Value<T, N> {
    let corners = t.corners_of_vertex(w);
    let sum = corners.iter().fold(zero(), |s, &c| add(s, f[c as usize]));
    scale(sum, reciprocal(corners.len()))
}

/// The centroid of the fine faces at the edge point of a coarse edge with `corners` (the fine
/// faces of those corners and of their successors) from dual data `f` of the fine level.
#[inline(always)]
fn edge_corner_mean<T: Scalar, const N: usize>(
    t: &Tables,
    f: &[Value<T, N>],
    corners: [u32; 2],
) -> Value<T, N> {
    match corners {
        [c, NONE] => scale(add(f[c as usize], f[t.next(c as usize)]), T::from_f64(0.5)),
        [c, d] => {
            let (c, d) = (c as usize, d as usize);
            let s = add(add(f[c], f[t.next(c)]), add(f[d], f[t.next(d)]));
            scale(s, T::from_f64(0.25))
        }
    }
}

/// [`edge_corner_mean`] on a quad level, from dual data of the fine level as `quads` (the four
/// fine faces of each coarse quad): a corner and its successor are two faces of one quad, found
/// with one bounds check and no successor table.
#[inline(always)]
fn quad_edge_mean<T: Scalar, const N: usize>(
    quads: &[[Value<T, N>; 4]],
    corners: [u32; 2],
) -> Value<T, N> {
    let pair = |c: u32| {
        let (q, k) = (&quads[(c >> 2) as usize], (c & 3) as usize);
        add(q[k], q[(k + 1) & 3])
    };
    match corners {
        [c, NONE] => scale(pair(c), T::from_f64(0.5)),
        [c, d] => scale(add(pair(c), pair(d)), T::from_f64(0.25)),
    }
}

/// The 1-D half of a primal -> dual average: each curve edge takes the midpoint of its ends.
fn curve_to_dual<T: Scalar, const N: usize>(
    curves: &CurveNetwork,
    curve: &[Value<T, N>],
) -> Vec<Value<T, N>> {
    let half = T::from_f64(0.5);
    (curves.edges().iter())
        .map(|e| {
            scale(
                add(curve[e.ends[0] as usize], curve[e.ends[1] as usize]),
                half,
            )
        })
        .collect()
}

/// Sets a vertex to `w * curve + (1 - w) * centroid` (exactly the curve value when w = 1); a
/// corner without a cage point keeps its centroid.
#[inline]
fn blend<T: Scalar, const N: usize>(
    vertex: &mut Value<T, N>,
    curve: Value<T, N>,
    cv: &CurveVertex,
) {
    if cv.edges.is_none() && cv.pin == NONE {
        return;
    }
    let weight = cv.weight;
    if weight >= 1.0 {
        *vertex = curve;
    } else if weight > 0.0 {
        *vertex = add(
            scale(curve, T::from_f64(weight)),
            scale(*vertex, T::from_f64(1.0 - weight)),
        );
    }
}
