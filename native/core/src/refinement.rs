//! The refinement of a cage for one scheme (the role of OpenSubdiv's `Far::TopologyRefiner`):
//! everything that depends only on topology and options, built once and read by every
//! evaluation: the compaction of the cage's vertices (isolated ones dropped), the levels
//! `M_0..M_L`, the curve network of every step and, for the classic Catmull-Clark rules, the
//! sharpness and rules of every level. It owns no cache of the layers above: the output mesh,
//! the evaluation buffers and the limit stencils belong to [`crate::Plan`], which is built on
//! top of it (so that nothing here needs those layers).

use std::borrow::Cow;
use std::sync::OnceLock;

use crate::curves::{CageFeatures, CurveNetwork, LevelSharpness};
use crate::error::{Error, Result};
use crate::memory;
use crate::mesh::Cage;
use crate::options::{estimate, Options, OutputKind};
use crate::parallel::in_pool;
use crate::scheme::Scheme;
use crate::step::{Drawing, SmoothPoints, Step, Windows};
use crate::topology::{Level, NONE};

/// The refined topology of a cage for one scheme; see the module documentation.
#[derive(Debug)]
pub(crate) struct Refinement {
    options: Options,
    scheme: Scheme,
    num_input_vertices: usize,
    isolated: Vec<u32>,
    /// Cage vertex of each vertex of `M_0`, when isolated vertices were dropped.
    vertex_map: Option<Vec<u32>>,
    /// The cage (limits refine it further).
    cage: Cage,
    features: CageFeatures,
    levels: Vec<Level>,
    networks: Vec<CurveNetwork>,
    /// Classic Catmull-Clark: sharpness and rules of `M_0..M_L` (empty otherwise).
    sharpness: Vec<LevelSharpness>,
    /// The averaging rules: the regular windows of each step (`None` where the kernel has
    /// nothing to do).
    windows: Vec<Option<Windows>>,
    /// Degrees 2 and 4 drawn as the primal mesh: the last step's windows ending in the fused
    /// drawing points ([`Windows::drawn`]), which a run that wants primal data takes for that
    /// step (`None` when no point is fused). Made on the first such run: the limits and the
    /// dual mesh read the whole step, and a plan used for them alone (the add-on's default,
    /// limit positions) never pays for them (2026-12-07, callgrind driver, 3,840-quad sphere at
    /// level 3, one thread: the dual grid was 26.8M of the 103.0M of a new plan of averaging 4
    /// and its first evaluation; a new plan's first `limit_surface` 345.1M -> 312.8M).
    drawn: OnceLock<Option<Windows>>,
    /// Classic Catmull-Clark: per step from a quad level, its smooth points by the fused sums
    /// (`None` on other levels and where none is fused; empty for other rules).
    smooth_points: Vec<Option<SmoothPoints>>,
}

impl Refinement {
    /// Validates the cage topology and the options, checks the memory budget, then refines the
    /// topology level by level and lays out the curve features.
    pub(crate) fn new(cage: &Cage, options: &Options) -> Result<Refinement> {
        in_pool(|| Refinement::build(cage, options))
    }

    fn build(cage: &Cage, options: &Options) -> Result<Refinement> {
        let est = estimate(cage, options)?;
        memory::check_request(est.bytes, est.faces, options.memory_budget)?;
        if 4 * est.faces >= u32::MAX as u64 || est.vertices >= u32::MAX as u64 {
            return Err(Error::InvalidInput(format!(
                "{} output faces is more than 32-bit indices can address",
                est.faces
            )));
        }
        let scheme = Scheme::new(options);

        // Drop isolated vertices: they have no faces, so no place in the refined mesh.
        let n = cage.num_vertices();
        let mut used = memory::zeroed::<bool>(n)?;
        for &v in cage.face_vertices() {
            used[v as usize] = true;
        }
        let isolated: Vec<u32> = (0..n as u32).filter(|&v| !used[v as usize]).collect();
        let (vertex_map, compact_of) = if isolated.is_empty() {
            (None, None)
        } else {
            let map: Vec<u32> = (0..n as u32).filter(|&v| used[v as usize]).collect();
            let mut compact = memory::filled(n, NONE)?;
            for (i, &v) in map.iter().enumerate() {
                compact[v as usize] = i as u32;
            }
            (Some(map), Some(compact))
        };
        let compact = |v: u32| compact_of.as_ref().map_or(v, |m| m[v as usize]);
        let num_vertices = n - isolated.len();
        let corner_verts = memory::collect(cage.face_vertices().iter().map(|&v| compact(v)))?;
        let level0 = Level::from_cage(cage, num_vertices, corner_verts)?;
        let features = CageFeatures::new(cage, &level0, compact, options.boundary)?;

        let mut curves = features.curves();
        let cage_vertices = level0.num_vertices as u32;
        let pin = |v: u32| if v < cage_vertices { v } else { NONE };
        let mut levels = vec![level0];
        let mut networks: Vec<CurveNetwork> = Vec::with_capacity(options.levels as usize);
        for j in 0..options.levels {
            // Evaluation reads the last level's faces only: its edges and vertex -> corner
            // table wait for first use (`Refinement::levels`, `Level::corners_of_vertex`),
            // unless the dual output is built from them.
            let coarse = &levels[j as usize];
            let fine = if j + 1 == options.levels && options.output == OutputKind::Primal {
                let fine = coarse.refine_faces()?;
                if !scheme.uses_sharpness() {
                    // The averaging passes read it at every level.
                    fine.index_vertex_corners_from(coarse)?;
                }
                fine
            } else {
                coarse.refine()?
            };
            let network = CurveNetwork::build(
                coarse,
                &curves,
                &features.corners,
                j,
                networks.last(),
                scheme.is_primal(),
                pin,
            )?;
            curves = network.next_curves();
            levels.push(fine);
            networks.push(network);
        }

        let sharpness = if let Scheme::CatmullClark { creasing } = scheme {
            let mut tables = vec![LevelSharpness::cage(&levels[0], &features)?];
            for j in 1..levels.len() {
                let next = tables[j - 1].refine(&levels[j - 1], &levels[j], creasing)?;
                tables.push(next);
            }
            tables
        } else {
            Vec::new()
        };
        // The drawing mesh of an even degree: the last step's windows keep what makes its
        // drawing points.
        let steps = networks.len();
        let draw = |j: usize| match j + 1 == steps && options.output != OutputKind::Dual {
            true => Drawing::Later,
            false => Drawing::Skip,
        };
        let windows = match scheme {
            Scheme::Averaging { degree } => (0..steps)
                .map(|j| {
                    let (coarse, fine) = (&levels[j], &levels[j + 1]);
                    Windows::of_step(coarse, fine, &networks[j], degree, j, draw(j))
                })
                .collect::<Result<Vec<_>>>()?,
            _ => Vec::new(),
        };
        let smooth_points = match scheme {
            Scheme::CatmullClark { .. } => (0..steps)
                .map(|j| SmoothPoints::of(&levels[j], &sharpness[j]))
                .collect::<Result<Vec<_>>>()?,
            _ => Vec::new(),
        };
        Ok(Refinement {
            options: *options,
            scheme,
            num_input_vertices: n,
            isolated,
            vertex_map,
            cage: cage.clone(),
            features,
            levels,
            networks,
            sharpness,
            windows,
            drawn: OnceLock::new(),
            smooth_points,
        })
    }

    /// The options the refinement was built with.
    pub(crate) fn options(&self) -> &Options {
        &self.options
    }

    /// The rule set.
    pub(crate) fn scheme(&self) -> Scheme {
        self.scheme
    }

    /// Number of vertices of the cage, isolated ones included.
    pub(crate) fn num_input_vertices(&self) -> usize {
        self.num_input_vertices
    }

    /// Cage vertices that no face uses; they are dropped from the result.
    pub(crate) fn isolated_vertices(&self) -> &[u32] {
        &self.isolated
    }

    /// The cage.
    pub(crate) fn cage(&self) -> &Cage {
        &self.cage
    }

    /// The cage's curve features on `M_0`.
    pub(crate) fn features(&self) -> &CageFeatures {
        &self.features
    }

    /// Per-vertex values of the cage (in the cage's numbering) in the numbering of `M_0`.
    pub(crate) fn compact<'v, V: Copy>(&self, values: &'v [V]) -> Cow<'v, [V]> {
        match &self.vertex_map {
            None => Cow::Borrowed(values),
            Some(map) => Cow::Owned(map.iter().map(|&v| values[v as usize]).collect()),
        }
    }

    /// The cage vertex (the user's numbering) of vertex `v` of `M_0`.
    pub(crate) fn cage_vertex(&self, v: u32) -> u32 {
        self.vertex_map.as_ref().map_or(v, |map| map[v as usize])
    }

    /// The refined levels `M_0..M_L`, every table built (the last level's edge and vertex ->
    /// corner tables are added on the first call). Panics if an allocation is refused there;
    /// paths that return a `Result` use [`Refinement::try_levels`].
    pub(crate) fn levels(&self) -> &[Level] {
        self.try_levels()
            .unwrap_or_else(|e| panic!("the last level's tables: {e}"))
    }

    /// [`Refinement::levels`], a refused allocation an error.
    pub(crate) fn try_levels(&self) -> Result<&[Level]> {
        self.complete_levels()?;
        Ok(&self.levels)
    }

    /// Completes the last level's tables ([`Refinement::levels`] does it on first use, and
    /// panics if an allocation is refused there).
    pub(crate) fn complete_levels(&self) -> Result<()> {
        match self.levels.as_slice() {
            [.., parent, last] => last.complete_from(parent),
            _ => Ok(()),
        }
    }

    /// The levels as built: the last one may still lack its edge tables (and, for the classic
    /// Catmull-Clark rules, its vertex -> corner table), which evaluation does not read.
    pub(crate) fn levels_as_built(&self) -> &[Level] {
        &self.levels
    }

    /// The cage level `M_0` (complete: refinement and the curve features read its edges).
    pub(crate) fn cage_level(&self) -> &Level {
        &self.levels[0]
    }

    /// The last level `M_L` as built.
    pub(crate) fn last_level(&self) -> &Level {
        // `levels` is private, starts as `vec![level0]` in `build` and never shrinks.
        self.levels.last().expect("a refinement has its cage level")
    }

    /// The curve network of the last step; its absence (a refinement of no levels) is an
    /// internal error naming `what` needed it.
    pub(crate) fn last_network(&self, what: &str) -> Result<&CurveNetwork> {
        self.networks
            .last()
            .ok_or_else(|| Error::Internal(format!("{what} needs a refined level, and has none")))
    }

    /// The curve network of each step.
    pub(crate) fn curve_networks(&self) -> &[CurveNetwork] {
        &self.networks
    }

    /// Step `j` (`M_j -> M_{j+1}`) as the step primitive reads it.
    pub(crate) fn step(&self, j: usize) -> Step<'_> {
        Step {
            scheme: self.scheme,
            coarse: &self.levels[j],
            fine: &self.levels[j + 1],
            curves: &self.networks[j],
            sharpness: (!self.sharpness.is_empty())
                .then(|| (&self.sharpness[j], &self.sharpness[j + 1])),
            windows: self.windows.get(j).and_then(Option::as_ref),
            smooth_points: self.smooth_points.get(j).and_then(Option::as_ref),
        }
    }

    /// The last step ending in its drawing points ([`Refinement::drawn`], made on the first
    /// call), when a run that wants primal data takes one: it leaves primal data, which no
    /// step reads. `None` for the dual output, other schemes and degrees, or when no point is
    /// fused.
    pub(crate) fn drawn_step(&self) -> Result<Option<Step<'_>>> {
        let Some(last) = self.networks.len().checked_sub(1) else {
            return Ok(None);
        };
        let drawn = match self.drawn.get() {
            Some(drawn) => drawn,
            None => {
                let made = match self.windows.get(last) {
                    Some(Some(w)) => w.drawn(&self.levels[last], &self.levels[last + 1])?,
                    _ => None,
                };
                // Another run may have made them first: the same windows.
                self.drawn.get_or_init(|| made)
            }
        };
        Ok(drawn.as_ref().map(|drawn| Step {
            windows: Some(drawn),
            ..self.step(last)
        }))
    }

    /// Whether the drawn last step's windows have been made (tests: on the first run that
    /// draws the primal mesh, where some point is fused).
    #[cfg(test)]
    pub(crate) fn drawn_made(&self) -> bool {
        matches!(self.drawn.get(), Some(Some(_)))
    }

    /// Sharpness and rules of level `j` (classic Catmull-Clark only).
    pub(crate) fn sharpness(&self, j: usize) -> Option<&LevelSharpness> {
        self.sharpness.get(j)
    }

    /// True when the output is the true dual mesh.
    pub(crate) fn wants_dual(&self) -> bool {
        self.options.output == OutputKind::Dual && !self.networks.is_empty()
    }
}
