//! The curve features of a refinement (DESIGN.md §2): boundaries, creases and corners with
//! their sharpness, read once from the cage ([`CageFeatures`]) and laid out on the levels in
//! the two forms the rule sets consult:
//! - [`CurveNetwork`]: the curve edges and curve vertices of one step, with the semi-sharp blend
//!   weights and where the 1-D scheme's replication reads (the averaging rules, bilinear,
//!   Doo-Sabin, and the drawing and dual output of every scheme). The same construction serves
//!   the full levels of a plan and the partial levels of the adaptive forest
//!   ([`CurveNetwork::restrict`]).
//! - [`LevelSharpness`]: the sharpness of every edge and vertex of a level and the vertex rules
//!   (the classic Catmull-Clark rules, as OpenSubdiv's `Vtr` keeps them).
//!
//! Sharpness is in the one convention of [`crate::scheme`]: 0 smooth,
//! [`crate::INFINITELY_SHARP`] sharp at every level; boundary edges are infinitely sharp.

use crate::error::{Error, Result};
use crate::memory;
use crate::mesh::{Cage, INFINITELY_SHARP};
use crate::options::{Boundary, Creasing};
use crate::parallel::gather_hinted;
use crate::scheme::catmark::{subdivide_edge_sharpness, vertex_rule, VertexRule};
use crate::scheme::{corner_weight, curve_weight, decrement, is_curve_vertex, is_sharp};

/// True for the sharpness of an infinitely sharp crease.
fn is_infinite(s: f32) -> bool {
    s >= INFINITELY_SHARP
}
use crate::topology::{Level, NONE};

/// A curve edge of a level with its sharpness there.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Curve {
    /// Edge id in the level.
    pub edge: u32,
    /// Its sharpness at this level (positive).
    pub sharpness: f32,
}

/// The curve features of the cage, on the cage level `M_0`: every curve edge (boundaries,
/// non-manifold edges and creases) with its sharpness, the tagged vertices (corners) and the
/// hole faces.
#[derive(Debug, Clone, Default)]
pub(crate) struct CageFeatures {
    /// Sharpness of every edge of `M_0` (0 smooth).
    pub edge_sharpness: Vec<f32>,
    /// Tagged vertices of `M_0` and their sharpness, sorted by vertex, positive.
    pub corners: Vec<(u32, f32)>,
    /// The faces that are holes (the cage's, and with [`Boundary::None`] the faces at the
    /// boundary), sorted; they are refined and shape their neighbours, but are not drawn.
    pub holes: Vec<u32>,
}

impl CageFeatures {
    /// Reads the features of `cage` on its level `level0`, whose vertex `compact(v)` is cage
    /// vertex `v` (`NONE` for an isolated vertex, which has no place in the surface: a corner
    /// there is left out). Boundary and non-manifold edges are infinitely sharp (OpenSubdiv's
    /// `sharpenNonManFeatures`); a non-manifold vertex is an infinitely sharp corner, except
    /// inside a line of non-manifold edges (exactly two of them, no boundary edge, more faces
    /// than edges), where it is a curve vertex. With [`Boundary::EdgeAndCorner`] every vertex of
    /// a single face is a corner; with [`Boundary::None`] the faces at a vertex on a boundary
    /// edge that the user did not crease infinitely are holes. Fails when a crease is not an
    /// edge of the mesh.
    pub(crate) fn new(
        cage: &Cage,
        level0: &Level,
        compact: impl Fn(u32) -> u32,
        boundary: Boundary,
    ) -> Result<CageFeatures> {
        let mut edge_sharpness = vec![0.0f32; level0.num_edges()];
        if !cage.creases().is_empty() {
            let key = |a: u32, b: u32| ((a.min(b) as u64) << 32) | a.max(b) as u64;
            let mut keys: Vec<(u64, u32)> = level0
                .edge_verts()
                .iter()
                .enumerate()
                .map(|(e, &[a, b])| (key(a, b), e as u32))
                .collect();
            // The first edge of a pair (OpenSubdiv's `findEdge`) takes the crease.
            keys.sort_unstable();
            for (i, crease) in cage.creases().iter().enumerate() {
                let (a, b) = (compact(crease.a), compact(crease.b));
                let k = key(a, b);
                let at = keys.partition_point(|x| x.0 < k);
                if keys.get(at).is_none_or(|x| x.0 != k) {
                    return Err(Error::CreaseNotAnEdge {
                        crease: i,
                        a: crease.a as usize,
                        b: crease.b as usize,
                    });
                }
                let e = keys[at].1 as usize;
                edge_sharpness[e] = edge_sharpness[e].max(crease.sharpness);
            }
        }
        let mut holes: Vec<u32> = cage.holes().to_vec();
        if boundary == Boundary::None {
            for v in 0..level0.num_vertices {
                let open = level0.vertex_edges(v).any(|e| {
                    level0.is_boundary_edge(e as usize) && !is_infinite(edge_sharpness[e as usize])
                });
                if open {
                    holes.extend(
                        (level0.corners_of_vertex(v).iter())
                            .map(|&c| level0.face_of(c as usize) as u32),
                    );
                }
            }
        }
        holes.sort_unstable();
        holes.dedup();
        for (e, s) in edge_sharpness.iter_mut().enumerate() {
            if level0.is_boundary_edge(e) || level0.is_non_manifold_edge(e) {
                *s = INFINITELY_SHARP;
            }
        }
        let mut corners: Vec<(u32, f32)> = cage
            .corners()
            .iter()
            .map(|c| (compact(c.vertex), c.sharpness))
            .filter(|c| c.0 != NONE)
            .collect();
        for &v in &level0.nm_vertices {
            let v = v as usize;
            let (mut edges, mut nm, mut open) = (0, 0, 0);
            for e in level0.vertex_edges(v) {
                edges += 1;
                nm += level0.is_non_manifold_edge(e as usize) as usize;
                open += level0.is_boundary_edge(e as usize) as usize;
            }
            let inside_line = nm == 2 && open == 0 && level0.corners_of_vertex(v).len() > edges;
            if !inside_line {
                corners.push((v as u32, INFINITELY_SHARP));
            }
        }
        if boundary == Boundary::EdgeAndCorner {
            for v in 0..level0.num_vertices {
                if level0.corners_of_vertex(v).len() == 1 {
                    corners.push((v as u32, INFINITELY_SHARP));
                }
            }
        }
        corners.sort_by(|x, y| x.0.cmp(&y.0).then(y.1.total_cmp(&x.1)));
        corners.dedup_by_key(|t| t.0);
        corners.retain(|t| is_sharp(t.1));
        Ok(CageFeatures {
            edge_sharpness,
            corners,
            holes,
        })
    }

    /// The curve edges of `M_0`, in edge order.
    pub(crate) fn curves(&self) -> Vec<Curve> {
        (self.edge_sharpness.iter().enumerate())
            .filter(|(_, &s)| is_sharp(s))
            .map(|(e, &sharpness)| Curve {
                edge: e as u32,
                sharpness,
            })
            .collect()
    }
}

/// A vertex of the curve network of one step (in the fine level of the step).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct CurveVertex {
    /// Vertex id in the fine level.
    pub vertex: u32,
    /// Its two curve edges (indices into the step's curve edges) if it is a curve vertex;
    /// `None` for a corner.
    pub edges: Option<[u32; 2]>,
    /// How much the 1-D value replaces the 2-D centroid: 1 sharp, in (0, 1) a semi-sharp blend.
    pub weight: f64,
    /// For a corner, the cage vertex whose point it keeps; `NONE` for a curve vertex, and for a
    /// corner that only a partial level makes one (a curve vertex cut off from one of its curve
    /// edges, outside the exact region), which keeps its 2-D value.
    pub pin: u32,
}

/// An edge of the curve network of one step (a half of a curve edge of the coarse level).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct CurveEdge {
    /// Edge id in the fine level.
    pub edge: u32,
    /// Its two ends, as indices into the step's curve vertices.
    pub ends: [u32; 2],
    /// Where replication takes its value: a cage vertex (first step), a curve vertex of the
    /// previous step (primal 1-D data) or a curve edge of the previous step (dual 1-D data).
    pub source: u32,
    /// Sharpness of the coarse curve edge it is a half of, in this step.
    pub sharpness: f32,
}

/// The curve network of one step `M_j -> M_{j+1}`: the halves of the coarse level's curve
/// edges (boundaries and creases that are still sharp) and their vertices, each a curve vertex
/// (on two curve edges, the 1-D scheme runs through it) or a corner (keeps its cage point).
#[derive(Debug, Clone, Default)]
pub struct CurveNetwork {
    vertices: Vec<CurveVertex>,
    edges: Vec<CurveEdge>,
}

impl CurveNetwork {
    /// Lays out the network of the step from `coarse` (level `level`): `curves` are the coarse
    /// level's curve edges with their sharpness (sorted by edge), `corners` its tagged vertices
    /// with their cage sharpness (sorted by vertex), `previous` the network of the step that
    /// made `coarse` (`None` for the cage level), `primal` whether the 1-D data between steps is
    /// primal (odd degrees), and `pin(v)` the cage vertex of coarse vertex `v` (or `NONE`).
    /// [`Error::Internal`] when the curves do not continue the previous step's network (a curve
    /// edge whose end or parent is not one of its items).
    pub(crate) fn build(
        coarse: &Level,
        curves: &[Curve],
        corners: &[(u32, f32)],
        level: u32,
        previous: Option<&CurveNetwork>,
        primal: bool,
        pin: impl Fn(u32) -> u32,
    ) -> Result<CurveNetwork> {
        let nv = coarse.num_vertices as u32;
        // (vertex, curve edge index, weight) for every end of every new curve edge at an old
        // vertex.
        let mut ends: Vec<(u32, u32, f64)> = Vec::with_capacity(2 * curves.len());
        let mut edges = Vec::with_capacity(2 * curves.len());
        for (i, c) in curves.iter().enumerate() {
            let [a, b] = coarse.edge_verts()[c.edge as usize];
            let w = curve_weight(c.sharpness);
            for (k, end) in [a, b].into_iter().enumerate() {
                let index = (2 * i + k) as u32;
                ends.push((end, index, w));
                let source = match previous {
                    None => Some(end),
                    Some(p) if primal => p.vertex_index(end),
                    Some(p) => p.edge_index(c.edge),
                }
                .ok_or_else(|| {
                    Error::Internal(format!(
                        "curve edge {} of step {level}: its ends and parent must be curve items \
                         of the previous step",
                        c.edge
                    ))
                })?;
                edges.push(CurveEdge {
                    edge: 2 * c.edge + k as u32,
                    ends: [0, 0],
                    source,
                    sharpness: c.sharpness,
                });
            }
        }
        ends.sort_unstable_by(|x, y| x.0.cmp(&y.0).then(x.1.cmp(&y.1)));

        // Old vertices (ids < nv) in increasing order, merged with the corners; then edge
        // points.
        let active: Vec<(u32, f64)> = corners
            .iter()
            .filter_map(|&(v, s)| corner_weight(s, level).map(|w| (v, w)))
            .collect();
        let mut vertices = old_curve_vertices(&ends, &active, pin);
        let first_mid = vertices.len() as u32;
        for (i, c) in curves.iter().enumerate() {
            vertices.push(CurveVertex {
                vertex: nv + c.edge,
                edges: Some([2 * i as u32, 2 * i as u32 + 1]),
                weight: curve_weight(c.sharpness),
                pin: NONE,
            });
        }
        for (i, edge) in edges.iter_mut().enumerate() {
            let c = &curves[i / 2];
            let old = coarse.edge_verts()[c.edge as usize][i % 2];
            let old_index = vertices[..first_mid as usize]
                .binary_search_by_key(&old, |cv| cv.vertex)
                .map_err(|_| {
                    Error::Internal(format!(
                        "curve edge {} of step {level}: its end {old} must be a curve vertex",
                        c.edge
                    ))
                })? as u32;
            let mid_index = first_mid + (i / 2) as u32;
            edge.ends = if i % 2 == 0 {
                [old_index, mid_index]
            } else {
                [mid_index, old_index]
            };
        }
        Ok(CurveNetwork { vertices, edges })
    }

    /// The curve edges of the fine level that are still sharp in the next step (halves of the
    /// sharper edges, their sharpness one level down), sorted by edge.
    pub(crate) fn next_curves(&self) -> Vec<Curve> {
        self.edges
            .iter()
            .map(|e| Curve {
                edge: e.edge,
                sharpness: decrement(e.sharpness),
            })
            .filter(|c| is_sharp(c.sharpness))
            .collect()
    }

    /// The network restricted to the part of its fine level a partial level keeps:
    /// `vertex_map` and `edge_map` give each fine vertex's and edge's new id (`NONE` if
    /// dropped). Returns the restricted network (ids renumbered; references to dropped items
    /// become `NONE`) and the indices of the kept curve vertices and curve edges, by which the
    /// 1-D data is restricted alike.
    pub(crate) fn restrict(
        &self,
        vertex_map: &[u32],
        edge_map: &[u32],
    ) -> (CurveNetwork, Vec<u32>, Vec<u32>) {
        let kept_vertices: Vec<u32> = (0..self.vertices.len() as u32)
            .filter(|&i| vertex_map[self.vertices[i as usize].vertex as usize] != NONE)
            .collect();
        let kept_edges: Vec<u32> = (0..self.edges.len() as u32)
            .filter(|&i| edge_map[self.edges[i as usize].edge as usize] != NONE)
            .collect();
        let index_of = |kept: &[u32], i: u32| kept.binary_search(&i).map_or(NONE, |at| at as u32);
        let vertices = kept_vertices
            .iter()
            .map(|&i| {
                let cv = self.vertices[i as usize];
                CurveVertex {
                    vertex: vertex_map[cv.vertex as usize],
                    edges: cv.edges.map(|e| e.map(|x| index_of(&kept_edges, x))),
                    ..cv
                }
            })
            .collect();
        let edges = kept_edges
            .iter()
            .map(|&i| {
                let ce = self.edges[i as usize];
                CurveEdge {
                    edge: edge_map[ce.edge as usize],
                    ends: ce.ends.map(|x| index_of(&kept_vertices, x)),
                    ..ce
                }
            })
            .collect();
        (CurveNetwork { vertices, edges }, kept_vertices, kept_edges)
    }

    /// The curve vertices and corners, sorted by vertex id.
    pub(crate) fn vertices(&self) -> &[CurveVertex] {
        &self.vertices
    }

    /// The curve edges, sorted by edge id.
    pub(crate) fn edges(&self) -> &[CurveEdge] {
        &self.edges
    }

    /// The index of fine vertex `v` among the curve vertices, if it is one.
    #[inline]
    pub(crate) fn vertex_index(&self, v: u32) -> Option<u32> {
        self.vertices
            .binary_search_by_key(&v, |cv| cv.vertex)
            .ok()
            .map(|i| i as u32)
    }

    /// The index of fine edge `e` among the curve edges, if it is one.
    #[inline]
    pub(crate) fn edge_index(&self, e: u32) -> Option<u32> {
        self.edges
            .binary_search_by_key(&e, |ce| ce.edge)
            .ok()
            .map(|i| i as u32)
    }

    /// Ids (in the fine level of the step) of the vertices on the network, curve vertices and
    /// corners, in increasing order.
    pub fn curve_vertices(&self) -> impl ExactSizeIterator<Item = u32> + '_ {
        self.vertices.iter().map(|cv| cv.vertex)
    }

    /// Ids (in the fine level of the step) of the vertices of the network that are corners
    /// (they keep their cage point), in increasing order.
    pub fn corners(&self) -> impl Iterator<Item = u32> + '_ {
        self.vertices
            .iter()
            .filter(|cv| cv.edges.is_none())
            .map(|cv| cv.vertex)
    }

    /// Ids (in the fine level of the step) of the curve edges, in increasing order.
    pub fn curve_edges(&self) -> impl ExactSizeIterator<Item = u32> + '_ {
        self.edges.iter().map(|ce| ce.edge)
    }
}

/// The curve vertices among the old vertices of a step, merged from `ends` (vertex, index of a
/// curve edge ending there, that edge's blend weight; sorted by vertex) and `corners` (tagged
/// vertex, its blend weight; sorted by vertex): the classification of
/// [`is_curve_vertex`]; the weight is the mean of its edges' weights (at least the tag's, for a
/// corner).
fn old_curve_vertices(
    ends: &[(u32, u32, f64)],
    corners: &[(u32, f64)],
    pin: impl Fn(u32) -> u32,
) -> Vec<CurveVertex> {
    let mut out = Vec::with_capacity(ends.len());
    let (mut i, mut t) = (0, 0);
    loop {
        let v = match (ends.get(i), corners.get(t)) {
            (Some(e), Some(tag)) => e.0.min(tag.0),
            (Some(e), None) => e.0,
            (None, Some(tag)) => tag.0,
            (None, None) => break,
        };
        let start = i;
        while i < ends.len() && ends[i].0 == v {
            i += 1;
        }
        let tag = if t < corners.len() && corners[t].0 == v {
            t += 1;
            corners[t - 1].1
        } else {
            0.0
        };
        let group = &ends[start..i];
        let mean = if group.is_empty() {
            0.0
        } else {
            group.iter().map(|g| g.2).sum::<f64>() / group.len() as f64
        };
        out.push(if is_curve_vertex(group.len(), tag > 0.0) {
            CurveVertex {
                vertex: v,
                edges: Some([group[0].1, group[1].1]),
                weight: mean,
                pin: NONE,
            }
        } else {
            CurveVertex {
                vertex: v,
                edges: None,
                weight: mean.max(tag),
                pin: pin(v),
            }
        });
    }
    out
}

/// Sharpness and vertex rules of one level for the classic Catmull-Clark rules (OpenSubdiv's
/// `Vtr` sharpness and tags). Empty tables mean "all smooth" (no sharp edge or vertex).
#[derive(Debug, Clone, Default)]
pub(crate) struct LevelSharpness {
    /// Sharpness of each edge (empty: all zero).
    edges: Vec<f32>,
    /// Sharpness of each vertex (empty: all zero).
    vertices: Vec<f32>,
    /// Rule of each vertex (empty: all smooth).
    rules: Vec<VertexRule>,
}

/// Up to this valence the per-vertex sharpness lists live on the stack.
const STACK_VALENCE: usize = 32;

impl LevelSharpness {
    /// The sharpness and rules of `M_0` from the cage's features.
    pub(crate) fn cage(level0: &Level, features: &CageFeatures) -> Result<LevelSharpness> {
        let mut first = LevelSharpness::default();
        if features.edge_sharpness.iter().any(|&s| is_sharp(s)) {
            first.edges = features.edge_sharpness.clone();
        }
        if !features.corners.is_empty() {
            first.vertices = vec![0.0; level0.num_vertices];
            for &(v, s) in &features.corners {
                first.vertices[v as usize] = s;
            }
        }
        first.classify(level0)?;
        Ok(first)
    }

    /// Sharpness and rules of `fine` from those of `coarse` (this): halves of sharp edges
    /// decrease (uniform or Chaikin, per end), interior edges are smooth, old vertices decrease,
    /// new vertices are smooth.
    pub(crate) fn refine(&self, coarse: &Level, fine: &Level, creasing: Creasing) -> Result<Self> {
        let mut next = LevelSharpness::default();
        let ne = coarse.num_edges();
        if !self.edges.is_empty() {
            next.edges = gather_hinted(fine.num_edges(), |child| {
                if child >= 2 * ne {
                    return 0.0;
                }
                let e = child / 2;
                let s = self.edges[e];
                if s <= 0.0 {
                    return 0.0;
                }
                match creasing {
                    Creasing::Uniform => decrement(s),
                    Creasing::Chaikin => {
                        let v = coarse.edge_verts()[e][child & 1] as usize;
                        self.with_edge_sharpness(coarse, v, None, |p, _| {
                            subdivide_edge_sharpness(s, p, creasing)
                        })
                    }
                }
            })?;
            if next.edges.iter().all(|&s| s <= 0.0) {
                next.edges = Vec::new();
            }
        }
        if !self.vertices.is_empty() {
            let nv = coarse.num_vertices;
            next.vertices = gather_hinted(fine.num_vertices, |w| {
                if w < nv {
                    decrement(self.vertices[w])
                } else {
                    0.0
                }
            })?;
            if next.vertices.iter().all(|&s| s <= 0.0) {
                next.vertices = Vec::new();
            }
        }
        next.classify_from(coarse, fine)?;
        Ok(next)
    }

    /// The rules of `fine` (this table's level) from its sharpness, counting the sharp edges
    /// at each vertex on `coarse`: the only edges of `fine` that can be sharp are the halves of
    /// coarse edges, half `2e + k` running from end `k` of edge `e` to its edge point. So the
    /// fine level's own edge and vertex -> corner tables are not needed (a plan's last level
    /// does not have them; building them cost more than the rest of its sharpness).
    fn classify_from(&mut self, coarse: &Level, fine: &Level) -> Result<()> {
        if self.edges.is_empty() && self.vertices.is_empty() {
            self.rules = Vec::new();
            return Ok(());
        }
        let mut sharp = memory::filled(fine.num_vertices, 0u32)?;
        if !self.edges.is_empty() {
            let nv = coarse.num_vertices;
            for (e, ends) in coarse.edge_verts().iter().enumerate() {
                for (k, &v) in ends.iter().enumerate() {
                    if is_sharp(self.edges[2 * e + k]) {
                        sharp[v as usize] += 1;
                        sharp[nv + e] += 1;
                    }
                }
            }
        }
        let this = &*self;
        self.rules = gather_hinted(fine.num_vertices, |w| {
            vertex_rule(this.vertex(w), sharp[w] as usize)
        })?;
        Ok(())
    }

    /// True when no edge or vertex of the level is sharp.
    #[inline]
    pub(crate) fn is_smooth(&self) -> bool {
        self.rules.is_empty()
    }

    /// True when no edge of the level is sharp.
    #[inline]
    pub(crate) fn has_sharp_edges(&self) -> bool {
        !self.edges.is_empty()
    }

    /// Sharpness of edge `e`.
    #[inline]
    pub(crate) fn edge(&self, e: usize) -> f32 {
        if self.edges.is_empty() {
            0.0
        } else {
            self.edges[e]
        }
    }

    /// Sharpness of vertex `v`.
    #[inline]
    pub(crate) fn vertex(&self, v: usize) -> f32 {
        if self.vertices.is_empty() {
            0.0
        } else {
            self.vertices[v]
        }
    }

    /// Rule of vertex `v`.
    #[inline]
    pub(crate) fn rule(&self, v: usize) -> VertexRule {
        if self.rules.is_empty() {
            VertexRule::Smooth
        } else {
            self.rules[v]
        }
    }

    /// Rules from the sharpness tables.
    fn classify(&mut self, level: &Level) -> Result<()> {
        if self.edges.is_empty() && self.vertices.is_empty() {
            self.rules = Vec::new();
            return Ok(());
        }
        let this = &*self;
        let rules = gather_hinted(level.num_vertices, |v| {
            let sharp = level
                .vertex_edges(v)
                .filter(|&e| is_sharp(this.edge(e as usize)))
                .count();
            vertex_rule(this.vertex(v), sharp)
        })?;
        self.rules = rules;
        Ok(())
    }

    /// Calls `f` with the sharpness of the edges at `v` (in [`Level::vertex_edges`] order) at
    /// this level and, when `child` is given, of their halves at `v` one level down.
    pub(crate) fn with_edge_sharpness<R>(
        &self,
        level: &Level,
        v: usize,
        child: Option<&LevelSharpness>,
        f: impl FnOnce(&[f32], &[f32]) -> R,
    ) -> R {
        let k = level.vertex_edges(v).count();
        let fill = |p: &mut [f32], c: &mut [f32]| {
            for (i, e) in level.vertex_edges(v).enumerate() {
                p[i] = self.edge(e as usize);
                if let Some(child) = child {
                    c[i] = child.edge(level.child_half(e, v as u32) as usize);
                }
            }
        };
        if k <= STACK_VALENCE {
            let (mut p, mut c) = ([0.0f32; STACK_VALENCE], [0.0f32; STACK_VALENCE]);
            fill(&mut p[..k], &mut c[..k]);
            f(&p[..k], &c[..k])
        } else {
            let (mut p, mut c) = (vec![0.0f32; k], vec![0.0f32; k]);
            fill(&mut p, &mut c);
            f(&p, &c)
        }
    }
}
