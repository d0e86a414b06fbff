//! The plan: everything that depends only on topology and options, built once and reused for
//! any number of evaluations (a deforming mesh re-evaluates without topology work). It holds the
//! refined levels `M_0..M_L`, the curve network of every step (boundaries and creases, their
//! sharpness schedule, corners) and the output mesh.

use std::sync::{Arc, Mutex};

use crate::classic::{Catmark, Creasing};
use crate::error::{Error, Result};
use crate::evaluate::Scratch;
use crate::limit;
use crate::mesh::Cage;
use crate::output::OutputMesh;
use crate::topology::{Level, NONE};
use crate::{DEFAULT_MEMORY_BUDGET, INFINITELY_SHARP, MAX_DEGREE, MAX_LEVELS};

/// What is drawn at the last level.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum OutputKind {
    /// The drawing mesh: `M_L` with primal points (dual data gets one more dual -> primal
    /// average, the paper's drawing step). Every face is a quad when L >= 1.
    #[default]
    Primal,
    /// The true dual mesh: one point per face of `M_L`, one face per vertex of `M_L` (closed
    /// along boundaries by the boundary curve's 1-D points).
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
}

/// Which rules refine the levels.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Rules {
    /// Repeated averaging (Zorin-Schröder), any degree.
    #[default]
    Averaging,
    /// Classic rule sets (degrees 1 to 3): degree 3 Catmull-Clark exactly as OpenSubdiv's
    /// `catmark`, degree 2 the original Doo-Sabin weights, degree 1 bilinear (see
    /// [`crate::classic`]).
    Classic,
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
    /// Largest memory, in bytes, a request may need (estimated before any work).
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
            memory_budget: DEFAULT_MEMORY_BUDGET,
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

/// A vertex of the curve network in one step (in the fine level of the step).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CurveVertex {
    /// Vertex id in the fine level.
    pub vertex: u32,
    /// Its two curve edges (indices into the step's curve edges) if it is a curve vertex;
    /// `None` for a corner, which keeps its cage position.
    pub edges: Option<[u32; 2]>,
    /// How much the 1-D value replaces the 2-D centroid: 1 sharp, in (0, 1) a semi-sharp blend.
    pub weight: f64,
}

/// An edge of the curve network in one step (a half of a coarse curve edge).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CurveEdge {
    /// Edge id in the fine level.
    pub edge: u32,
    /// Its two ends, as indices into the step's curve vertices.
    pub ends: [u32; 2],
    /// Where replication takes its value: a cage vertex (first step), a curve vertex of the
    /// previous step (primal 1-D data) or a curve edge of the previous step (dual 1-D data).
    pub source: u32,
}

/// The curve network of one step `M_j -> M_{j+1}`.
#[derive(Debug, Clone, Default)]
pub struct Step {
    /// Curve vertices and corners, sorted by vertex id.
    pub curve_vertices: Vec<CurveVertex>,
    /// Curve edges.
    pub curve_edges: Vec<CurveEdge>,
}

/// Everything that depends only on topology and options; see the module documentation.
#[derive(Debug)]
pub struct Plan {
    options: Options,
    num_input_vertices: usize,
    isolated: Vec<u32>,
    vertex_map: Option<Vec<u32>>,
    levels: Vec<Level>,
    steps: Vec<Step>,
    catmark: Option<Catmark>,
    output: OutputMesh,
    scratch: Scratch,
    /// The cage (the limit extends the plan by further levels from it).
    cage: Cage,
    /// Limit stencils, built on first use (crate::limit).
    limit: Mutex<Option<Arc<limit::Stencils>>>,
}

fn check_options(options: &Options) -> Result<()> {
    if options.degree < 1 || options.degree > MAX_DEGREE {
        return Err(Error::DegreeOutOfRange {
            degree: options.degree as i64,
            max: MAX_DEGREE,
        });
    }
    if options.rules == Rules::Classic && options.degree > 3 {
        return Err(Error::InvalidInput(format!(
            "classic rules exist for degrees 1 to 3, not {}",
            options.degree
        )));
    }
    if options.levels > MAX_LEVELS {
        return Err(Error::LevelOutOfRange {
            levels: options.levels as i64,
            max: MAX_LEVELS,
        });
    }
    Ok(())
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
    bytes += level_bytes(v, e, c);
    for _ in 0..options.levels {
        (v, e, f, c) = (v + e + f, 2.0 * e + c, c, 4.0 * c);
        bytes += level_bytes(v, e, c);
    }
    // Evaluation keeps about three arrays of the larger of vertices and faces (f64 x 3).
    bytes += 3.0 * 24.0 * v.max(f);
    Ok(Estimate {
        vertices: v as u64,
        faces: f as u64,
        bytes: bytes.min(u64::MAX as f64) as u64,
    })
}

impl Plan {
    /// Builds the plan: validates the cage topology and the options, checks the memory budget,
    /// then refines the topology level by level and lays out the curve networks.
    pub fn new(cage: &Cage, options: &Options) -> Result<Plan> {
        in_pool(|| Plan::build(cage, options))
    }

    fn build(cage: &Cage, options: &Options) -> Result<Plan> {
        let est = estimate(cage, options)?;
        if est.bytes > options.memory_budget {
            return Err(Error::MemoryBudget {
                required: est.bytes,
                budget: options.memory_budget,
                faces: est.faces,
            });
        }
        if 4 * est.faces >= u32::MAX as u64 || est.vertices >= u32::MAX as u64 {
            return Err(Error::InvalidInput(format!(
                "{} output faces is more than 32-bit indices can address",
                est.faces
            )));
        }

        // Drop isolated vertices: they have no faces, so no place in the refined mesh.
        let n = cage.num_vertices();
        let mut used = vec![false; n];
        for &v in cage.face_vertices() {
            used[v as usize] = true;
        }
        let isolated: Vec<u32> = (0..n as u32).filter(|&v| !used[v as usize]).collect();
        let (vertex_map, compact_of) = if isolated.is_empty() {
            (None, None)
        } else {
            let map: Vec<u32> = (0..n as u32).filter(|&v| used[v as usize]).collect();
            let mut compact = vec![NONE; n];
            for (i, &v) in map.iter().enumerate() {
                compact[v as usize] = i as u32;
            }
            (Some(map), Some(compact))
        };
        let compact = |v: u32| compact_of.as_ref().map_or(v, |m| m[v as usize]);
        let num_vertices = n - isolated.len();
        let corner_verts: Vec<u32> = cage.face_vertices().iter().map(|&v| compact(v)).collect();
        let level0 = Level::from_cage(cage, num_vertices, corner_verts)?;

        // Curve edges of the cage: boundaries (infinitely sharp) and creases.
        let mut sharpness: Vec<f32> = (0..level0.num_edges())
            .map(|e| {
                if level0.is_boundary_edge(e) {
                    f32::INFINITY
                } else {
                    0.0
                }
            })
            .collect();
        if !cage.creases().is_empty() {
            let mut keys: Vec<(u64, u32)> = level0
                .edge_verts()
                .iter()
                .enumerate()
                .map(|(e, &[a, b])| (((a.min(b) as u64) << 32) | a.max(b) as u64, e as u32))
                .collect();
            keys.sort_unstable();
            for (i, crease) in cage.creases().iter().enumerate() {
                let (a, b) = (compact(crease.a), compact(crease.b));
                let key = ((a.min(b) as u64) << 32) | a.max(b) as u64;
                let at = keys.binary_search_by_key(&key, |k| k.0).map_err(|_| {
                    Error::CreaseNotAnEdge {
                        crease: i,
                        a: crease.a as usize,
                        b: crease.b as usize,
                    }
                })?;
                let e = keys[at].1 as usize;
                sharpness[e] = sharpness[e].max(sharp_or_inf(crease.sharpness));
            }
        }
        let mut tags: Vec<(u32, f32)> = cage
            .corners()
            .iter()
            .map(|c| (compact(c.vertex), sharp_or_inf(c.sharpness)))
            .collect();
        if options.boundary == Boundary::EdgeAndCorner {
            for v in 0..num_vertices {
                let corners = level0.corners_of_vertex(v);
                if corners.len() == 1 {
                    tags.push((v as u32, f32::INFINITY));
                }
            }
        }
        tags.sort_by(|x, y| x.0.cmp(&y.0).then(y.1.total_cmp(&x.1)));
        tags.dedup_by_key(|t| t.0);
        tags.retain(|t| t.1 > 0.0);

        let mut parents: Vec<Parent> = (0..level0.num_edges())
            .filter(|&e| sharpness[e] > 0.0)
            .map(|e| Parent {
                edge: e as u32,
                sharpness: sharpness[e],
                previous: NONE,
            })
            .collect();
        // Classic degree 3 evaluates through `Catmark`; every other scheme through the averages.
        let catmark_rules = options.rules == Rules::Classic && options.degree == 3;
        let mut levels = vec![level0];
        let mut steps: Vec<Step> = Vec::with_capacity(options.levels as usize);
        for j in 0..options.levels {
            // Evaluation reads the last level's faces only: its edges and vertex -> corner
            // table wait for first use (`Plan::levels`, `Level::corners_of_vertex`), unless the
            // dual output is built from them.
            let coarse = &levels[j as usize];
            let fine = if j + 1 == options.levels && options.output == OutputKind::Primal {
                let fine = coarse.refine_faces();
                if !catmark_rules {
                    // The averaging passes read it at every level.
                    fine.index_vertex_corners_from(coarse);
                }
                fine
            } else {
                coarse.refine()
            };
            let (step, next) = curve_step(
                &levels[j as usize],
                &parents,
                &tags,
                j,
                options.degree,
                steps.last(),
            );
            levels.push(fine);
            steps.push(step);
            parents = next;
        }

        let catmark =
            catmark_rules.then(|| Catmark::new(&levels, &sharpness, &tags, options.creasing));
        let mut plan = Plan {
            options: *options,
            num_input_vertices: n,
            isolated,
            vertex_map,
            levels,
            steps,
            catmark,
            output: OutputMesh::default(),
            scratch: Scratch::default(),
            cage: cage.clone(),
            limit: Mutex::default(),
        };
        plan.output = OutputMesh::build(&plan)?;
        Ok(plan)
    }

    /// The options the plan was built with.
    pub fn options(&self) -> &Options {
        &self.options
    }

    /// Number of vertices of the cage, isolated ones included (the length `evaluate` expects).
    pub fn num_input_vertices(&self) -> usize {
        self.num_input_vertices
    }

    /// Cage vertices that no face uses; they are dropped from the result.
    pub fn isolated_vertices(&self) -> &[u32] {
        &self.isolated
    }

    /// The refined levels `M_0..M_L`, every table built (the last level's edge and vertex ->
    /// corner tables are added on the first call).
    pub fn levels(&self) -> &[Level] {
        if let [.., parent, last] = self.levels.as_slice() {
            last.complete_from(parent);
        }
        &self.levels
    }

    /// The levels as built: the last one may still lack its edge tables (and, for the classic
    /// rules, its vertex -> corner table), which evaluation does not read.
    pub(crate) fn levels_as_built(&self) -> &[Level] {
        &self.levels
    }

    /// The curve network of each step.
    pub fn steps(&self) -> &[Step] {
        &self.steps
    }

    /// The classic Catmull-Clark sharpness and rules (classic rules at degree 3).
    pub fn catmark(&self) -> Option<&Catmark> {
        self.catmark.as_ref()
    }

    /// Map from the plan's vertex ids to the cage's (when isolated vertices were dropped).
    pub(crate) fn vertex_map(&self) -> Option<&[u32]> {
        self.vertex_map.as_deref()
    }

    /// Buffers kept between evaluations.
    pub(crate) fn scratch(&self) -> &Scratch {
        &self.scratch
    }

    /// The output mesh (topology only).
    pub(crate) fn cage(&self) -> &Cage {
        &self.cage
    }

    pub(crate) fn limit_cache(&self) -> &Mutex<Option<Arc<limit::Stencils>>> {
        &self.limit
    }

    pub(crate) fn output(&self) -> &OutputMesh {
        &self.output
    }

    /// True when the output is the true dual mesh.
    pub(crate) fn wants_dual(&self) -> bool {
        self.options.output == OutputKind::Dual && !self.steps.is_empty()
    }
}

/// Runs `work` on a thread of rayon's pool. A run of many short parallel loops started from
/// outside the pool hands every loop to the pool and waits for it (two thread wake-ups per
/// loop); started from inside, the loops split and join there.
pub(crate) fn in_pool<R: Send>(work: impl FnOnce() -> R + Send) -> R {
    if rayon::current_thread_index().is_some() {
        work()
    } else {
        rayon::scope(|_| work())
    }
}

/// Sharpness at or above [`INFINITELY_SHARP`] is infinite.
fn sharp_or_inf(s: f32) -> f32 {
    if s >= INFINITELY_SHARP {
        f32::INFINITY
    } else {
        s
    }
}

/// A curve edge of the coarse level of a step, with the sharpness it has in that step.
#[derive(Debug, Clone, Copy)]
struct Parent {
    edge: u32,
    sharpness: f32,
    /// Its index among the previous step's curve edges (`NONE` in the first step).
    previous: u32,
}

/// The curve vertices among the old vertices of a step, merged from `ends` (vertex, index of a
/// curve edge ending there, that edge's blend weight; sorted by vertex) and `tags` (tagged
/// vertex, its blend weight; sorted by vertex): a vertex on exactly two curve edges and not
/// tagged is a curve vertex on those edges, anything else a corner; the weight is the mean of
/// its edges' weights (at least the tag's, for a corner).
pub(crate) fn old_curve_vertices(
    ends: &[(u32, u32, f64)],
    tags: &[(u32, f64)],
) -> Vec<CurveVertex> {
    let mut curve_vertices = Vec::with_capacity(ends.len());
    let (mut i, mut t) = (0, 0);
    while i < ends.len() || t < tags.len() {
        let v = match (ends.get(i), tags.get(t)) {
            (Some(e), Some(tag)) => e.0.min(tag.0),
            (Some(e), None) => e.0,
            (None, Some(tag)) => tag.0,
            (None, None) => unreachable!(),
        };
        let start = i;
        while i < ends.len() && ends[i].0 == v {
            i += 1;
        }
        let tag = if t < tags.len() && tags[t].0 == v {
            t += 1;
            tags[t - 1].1
        } else {
            0.0
        };
        let group = &ends[start..i];
        let mean = if group.is_empty() {
            0.0
        } else {
            group.iter().map(|g| g.2).sum::<f64>() / group.len() as f64
        };
        curve_vertices.push(if group.len() == 2 && tag == 0.0 {
            CurveVertex {
                vertex: v,
                edges: Some([group[0].1, group[1].1]),
                weight: mean,
            }
        } else {
            CurveVertex {
                vertex: v,
                edges: None,
                weight: mean.max(tag),
            }
        });
    }
    curve_vertices
}

/// Lays out the curve network of step `j` (coarse level `coarse`): the halves of the coarse
/// curve edges, their vertices classified as curve vertices (two curve edges) or corners (one,
/// three or more, or tagged), with blend weights for semi-sharp creases. Returns the step and
/// the curve edges that stay curves in the next step.
fn curve_step(
    coarse: &Level,
    parents: &[Parent],
    tags: &[(u32, f32)],
    j: u32,
    degree: u32,
    previous: Option<&Step>,
) -> (Step, Vec<Parent>) {
    let nv = coarse.num_vertices as u32;
    let level = j as f32;
    // (vertex, curve edge index, weight) for every end of every new curve edge at an old vertex.
    let mut ends: Vec<(u32, u32, f64)> = Vec::with_capacity(2 * parents.len());
    let mut curve_edges = Vec::with_capacity(2 * parents.len());
    for (i, p) in parents.iter().enumerate() {
        let [a, b] = coarse.edge_verts()[p.edge as usize];
        let w = p.sharpness.min(1.0) as f64;
        for (k, end) in [a, b].into_iter().enumerate() {
            let index = (2 * i + k) as u32;
            ends.push((end, index, w));
            let source = match previous {
                None => end,
                Some(prev) if degree % 2 == 1 => {
                    prev.curve_vertices
                        .binary_search_by_key(&end, |cv| cv.vertex)
                        .expect("curve end in previous step") as u32
                }
                Some(_) => p.previous,
            };
            curve_edges.push(CurveEdge {
                edge: 2 * p.edge + k as u32,
                ends: [0, 0],
                source,
            });
        }
    }
    ends.sort_unstable_by(|x, y| x.0.cmp(&y.0).then(x.1.cmp(&y.1)));

    // Old vertices (ids < nv) in increasing order, merged with the tags; then edge points.
    let active_tags: Vec<(u32, f64)> = tags
        .iter()
        .filter(|t| t.1 > level)
        .map(|t| (t.0, (t.1 - level).min(1.0) as f64))
        .collect();
    let mut curve_vertices = old_curve_vertices(&ends, &active_tags);
    let first_mid = curve_vertices.len() as u32;
    for (i, p) in parents.iter().enumerate() {
        curve_vertices.push(CurveVertex {
            vertex: nv + p.edge,
            edges: Some([2 * i as u32, 2 * i as u32 + 1]),
            weight: p.sharpness.min(1.0) as f64,
        });
    }
    for (i, edge) in curve_edges.iter_mut().enumerate() {
        let p = &parents[i / 2];
        let old = coarse.edge_verts()[p.edge as usize][i % 2];
        let old_index = curve_vertices[..first_mid as usize]
            .binary_search_by_key(&old, |cv| cv.vertex)
            .expect("curve edge end is a curve vertex") as u32;
        let mid_index = first_mid + (i / 2) as u32;
        edge.ends = if i % 2 == 0 {
            [old_index, mid_index]
        } else {
            [mid_index, old_index]
        };
    }

    let next = parents
        .iter()
        .enumerate()
        .filter(|(_, p)| p.sharpness > 1.0)
        .flat_map(|(i, p)| {
            (0..2).map(move |k| Parent {
                edge: 2 * p.edge + k,
                sharpness: p.sharpness - 1.0,
                previous: (2 * i) as u32 + k,
            })
        })
        .collect();
    (
        Step {
            curve_vertices,
            curve_edges,
        },
        next,
    )
}
