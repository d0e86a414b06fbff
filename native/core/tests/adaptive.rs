//! Adaptive subdivision: exact uniform points at every level, watertight triangles, tolerance 0
//! is uniform, and far fewer faces than uniform on a mostly flat cage.

mod common;

use std::collections::HashMap;

use bidegree::{
    margin_rings, subdivide_adaptive, subdivide_adaptive_with_data, subdivide_adaptive_with_margin,
    triangle_template, AdaptiveData, AdaptiveMesh, AdaptiveOptions, AdaptiveStage, Boundary, Cage,
    Error, FaceVaryingMode, Level, Options, Plan, Scalar,
};
use common::{cage, grid, Random, FACE_VARYING_MODES};

/// A closed pentagonal prism with a pyramid roof: a pentagon, quads and triangles, vertices of
/// valence 3, 4 and 5; points jittered so that refinement is uneven.
fn roofed_prism() -> (Cage, Vec<f64>) {
    let mut points = Vec::new();
    let mut rng = Random(7);
    for ring in 0..2 {
        for i in 0..5 {
            let a = 2.0 * std::f64::consts::PI * i as f64 / 5.0;
            let jitter = 0.15 * rng.next();
            points.extend([a.cos() * (1.0 + jitter), a.sin(), 1.5 * ring as f64]);
        }
    }
    points.extend([0.2, 0.1, 3.5]);
    let mut faces = vec![(0..5).rev().collect::<Vec<usize>>()];
    for i in 0..5 {
        let j = (i + 1) % 5;
        faces.push(vec![i, j, 5 + j, 5 + i]);
        faces.push(vec![5 + i, 5 + j, 10]);
    }
    (cage(11, &faces), points)
}

/// A closed cube with one corner pulled out (valence-3 vertices, all quads).
fn bumped_cube() -> (Cage, Vec<f64>) {
    let mut points: Vec<f64> = (0..8)
        .flat_map(|i| [(i & 1) as f64, ((i >> 1) & 1) as f64, ((i >> 2) & 1) as f64])
        .collect();
    points[21] += 0.8;
    let faces = vec![
        vec![0, 2, 3, 1],
        vec![4, 5, 7, 6],
        vec![0, 1, 5, 4],
        vec![2, 6, 7, 3],
        vec![0, 4, 6, 2],
        vec![1, 3, 7, 5],
    ];
    (cage(8, &faces), points)
}

/// An open grid in z = 0 with one vertex lifted: flat except for one bump.
fn bumped_grid(n: usize, height: f64) -> (Cage, Vec<f64>) {
    let (cage, mut points) = grid(n, n);
    let centre = (n / 2) * (n + 1) + n / 2;
    points[3 * centre + 2] = height;
    (cage, points)
}

fn options(degree: u32, max_level: u32, tolerance: f64) -> AdaptiveOptions {
    AdaptiveOptions {
        degree,
        max_level,
        tolerance,
        ..AdaptiveOptions::default()
    }
}

/// The uniform plan of `cage` at `levels` (averaging rules, primal output).
fn uniform_plan(cage: &Cage, degree: u32, levels: u32, boundary: Boundary) -> Plan {
    Plan::new(
        cage,
        &Options {
            degree,
            levels,
            boundary,
            ..Options::default()
        },
    )
    .unwrap()
}

/// Every vertex of the adaptive mesh is, bit for bit, the vertex of the same id of the uniform
/// drawing mesh at its level.
fn assert_uniform_points<T: Scalar>(
    cage: &Cage,
    points: &[T],
    degree: u32,
    boundary: Boundary,
    mesh: &AdaptiveMesh<T>,
) {
    let mut checked = 0;
    for level in 1..mesh.leaves_per_level.len() as u32 {
        let at: Vec<usize> = (0..mesh.vertex_level.len())
            .filter(|&i| mesh.vertex_level[i] == level)
            .collect();
        if at.is_empty() {
            continue;
        }
        let plan = uniform_plan(cage, degree, level, boundary);
        let uniform = plan.evaluate(points, 3).unwrap();
        for i in at {
            let u = mesh.vertex_id[i] as usize;
            for k in 0..3 {
                let (a, b) = (mesh.points[3 * i + k], uniform[3 * u + k]);
                assert!(
                    a.to_f64().to_bits() == b.to_f64().to_bits(),
                    "degree {degree}: vertex {u} of level {level}, channel {k}: {a:?} != {b:?}"
                );
            }
            checked += 1;
        }
    }
    assert_eq!(checked, mesh.vertex_level.len());
}

/// Every undirected edge is in exactly two triangles, once in each direction; no triangle
/// repeats a vertex; every vertex is used and vertex ids are unique.
fn assert_watertight<T>(mesh: &AdaptiveMesh<T>) {
    let mut edges: HashMap<(u32, u32), i32> = HashMap::new();
    for t in &mesh.triangles {
        assert!(
            t[0] != t[1] && t[1] != t[2] && t[2] != t[0],
            "degenerate {t:?}"
        );
        for k in 0..3 {
            *edges.entry((t[k], t[(k + 1) % 3])).or_default() += 1;
        }
    }
    for (&(a, b), &count) in &edges {
        assert_eq!(count, 1, "directed edge ({a}, {b}) used {count} times");
        assert_eq!(
            edges.get(&(b, a)),
            Some(&1),
            "edge ({a}, {b}) has no opposite: a crack or T-junction"
        );
    }
    let mut used = vec![false; mesh.vertex_level.len()];
    for t in &mesh.triangles {
        for &v in t {
            used[v as usize] = true;
        }
    }
    assert!(used.iter().all(|&u| u), "unused vertices");
    let mut ids: Vec<(u32, u64)> = mesh
        .vertex_level
        .iter()
        .zip(&mesh.vertex_id)
        .map(|(&l, &u)| (l, u))
        .collect();
    ids.sort_unstable();
    ids.dedup_by_key(|x| x.1);
    assert_eq!(ids.len(), mesh.vertex_id.len(), "a vertex id appears twice");
}

/// The vertex restriction criterion: leaves sharing a vertex (across an edge or at a corner)
/// differ by at most one level.
fn assert_restricted<T>(mesh: &AdaptiveMesh<T>) {
    let n = mesh.vertex_level.len();
    let (mut lo, mut hi) = (vec![u32::MAX; n], vec![0u32; n]);
    for (t, &level) in mesh.triangles.iter().zip(&mesh.triangle_level) {
        for &v in t {
            lo[v as usize] = lo[v as usize].min(level);
            hi[v as usize] = hi[v as usize].max(level);
        }
    }
    for v in 0..n {
        assert!(
            hi[v] - lo[v] <= 1,
            "vertex {v}: leaves of levels {} and {}",
            lo[v],
            hi[v]
        );
        assert_eq!(
            mesh.vertex_level[v], hi[v],
            "vertex {v} not drawn at its finest level"
        );
    }
}

fn levels_used<T>(mesh: &AdaptiveMesh<T>) -> usize {
    mesh.leaves_per_level.iter().filter(|&&n| n > 0).count()
}

#[test]
fn margin_follows_the_degree() {
    assert_eq!(
        (1..=12).map(margin_rings).collect::<Vec<_>>(),
        [2, 2, 2, 2, 4, 4, 4, 4, 6, 6, 6, 6]
    );
}

/// Index of the first vertex that differs from the uniform vertex of its level, if any.
fn first_difference(
    cage: &Cage,
    points: &[f64],
    degree: u32,
    mesh: &AdaptiveMesh<f64>,
) -> Option<usize> {
    let uniform: Vec<Vec<f64>> = (0..mesh.leaves_per_level.len() as u32)
        .map(|levels| {
            common::plan(cage, degree, levels)
                .evaluate(points, 3)
                .unwrap()
        })
        .collect();
    (0..mesh.vertex_id.len()).find(|&i| {
        let level = &uniform[mesh.vertex_level[i] as usize];
        let u = mesh.vertex_id[i] as usize;
        (0..3).any(|k| mesh.points[3 * i + k].to_bits() != level[3 * u + k].to_bits())
    })
}

/// The margin is not idle: without it the evaluation meets cut-off vertices (and says so, as an
/// internal error) or its points leave the uniform ones. (On this cage one ring is enough for
/// degrees 2-5, and degree 9 happens to need none: the restriction criterion and the measured
/// children already keep nodes around the refined ones. The documented margin is a sufficient
/// bound, not a minimal one.)
#[test]
fn smaller_margins_break_the_equality() {
    let (cage, points) = bumped_grid(16, 3.0);
    for degree in [2, 3, 4, 5, 9] {
        let options = options(degree, 4, 1e-4);
        let exact = subdivide_adaptive(&cage, &points, &options).unwrap();
        assert!(levels_used(&exact) >= 3);
        assert_eq!(first_difference(&cage, &points, degree, &exact), None);
        if degree == 9 {
            continue;
        }
        let exact = match subdivide_adaptive_with_margin(&cage, &points, &options, 0) {
            Err(Error::Internal(_)) => false,
            Err(e) => panic!("unexpected error {e}"),
            Ok(mesh) => first_difference(&cage, &points, degree, &mesh).is_none(),
        };
        assert!(!exact, "degree {degree}: no margin gave the uniform points");
    }
}

#[test]
fn templates_cover_the_quad_without_new_vertices() {
    for mask in 0..16u8 {
        let t = triangle_template(mask);
        let splits = mask.count_ones() as usize;
        // A polygon of 4 + splits vertices fans into 2 + splits triangles.
        assert_eq!(t.len(), 2 + splits, "mask {mask}");
        // Its boundary edges are exactly the quad's (split) edges, each once.
        let mut directed: HashMap<(u8, u8), i32> = HashMap::new();
        for tri in &t {
            for k in 0..3 {
                *directed.entry((tri[k], tri[(k + 1) % 3])).or_default() += 1;
            }
        }
        let ring: Vec<u8> = (0..8u8)
            .filter(|&p| p % 2 == 0 || mask & (1 << (p / 2)) != 0)
            .collect();
        for i in 0..ring.len() {
            let (a, b) = (ring[i], ring[(i + 1) % ring.len()]);
            assert_eq!(directed.get(&(a, b)), Some(&1), "mask {mask}: edge {a}-{b}");
            assert_eq!(directed.get(&(b, a)), None, "mask {mask}: edge {b}-{a}");
        }
    }
}

#[test]
fn adaptive_points_equal_uniform_points_bitwise() {
    let (prism, prism_points) = roofed_prism();
    let creased = prism
        .clone()
        .with_creases(&[(5, 6, 10.0), (6, 7, 2.5), (7, 8, 1.5), (0, 5, 0.5)])
        .unwrap()
        .with_corners(&[(8, 1.5), (2, 10.0)])
        .unwrap();
    let (open, open_points) = bumped_grid(6, 2.0);
    let open = open
        .with_creases(&[(8, 9, 10.0), (9, 10, 10.0), (10, 11, 1.5)])
        .unwrap();
    let cases: Vec<(&Cage, &[f64], Boundary, f64)> = vec![
        (&creased, &prism_points, Boundary::EdgeOnly, 0.003),
        (&open, &open_points, Boundary::EdgeOnly, 3e-4),
        (&open, &open_points, Boundary::EdgeAndCorner, 3e-4),
    ];
    for degree in [1, 2, 3, 4, 5, 9] {
        for &(cage, points, boundary, tolerance) in &cases {
            let options = AdaptiveOptions {
                boundary,
                ..options(degree, 4, tolerance)
            };
            let mesh = subdivide_adaptive(cage, points, &options).unwrap();
            // Degree 1 is bilinear: every node is its own bilinear patch, nothing refines.
            assert!(
                levels_used(&mesh) >= 2 || degree == 1,
                "degree {degree}: leaves {:?}",
                mesh.leaves_per_level
            );
            assert_uniform_points(cage, points, degree, boundary, &mesh);
            assert_restricted(&mesh);
        }
    }
    // Single precision follows the uniform single-precision evaluation.
    let points32: Vec<f32> = prism_points.iter().map(|&x| x as f32).collect();
    for degree in [3, 4] {
        let mesh = subdivide_adaptive(&creased, &points32, &options(degree, 4, 0.003)).unwrap();
        assert!(levels_used(&mesh) >= 2);
        assert_uniform_points(&creased, &points32, degree, Boundary::EdgeOnly, &mesh);
    }
}

#[test]
fn closed_cages_give_watertight_triangles() {
    let (prism, prism_points) = roofed_prism();
    let (cube, cube_points) = bumped_cube();
    for degree in [2, 3, 4, 9] {
        for (cage, points) in [(&prism, &prism_points), (&cube, &cube_points)] {
            let mut mixed = 0;
            for tolerance in [0.01, 0.003, 0.001, 3e-4] {
                let mesh =
                    subdivide_adaptive(cage, points, &options(degree, 5, tolerance)).unwrap();
                mixed += (levels_used(&mesh) >= 2) as usize;
                assert_watertight(&mesh);
                assert_restricted(&mesh);
                assert_eq!(mesh.face_origin.len(), mesh.triangles.len());
                assert!(mesh
                    .face_origin
                    .iter()
                    .all(|&f| (f as usize) < cage.num_faces()));
            }
            assert!(mixed >= 1, "degree {degree}: no adaptive case");
        }
    }
}

#[test]
fn tolerance_zero_is_uniform_level() {
    let (prism, points) = roofed_prism();
    for degree in [2, 3] {
        let level = 3;
        let mesh = subdivide_adaptive(&prism, &points, &options(degree, level, 0.0)).unwrap();
        let plan = Plan::new(
            &prism,
            &Options {
                degree,
                levels: level,
                ..Options::default()
            },
        )
        .unwrap();
        let uniform = plan.evaluate(&points, 3).unwrap();
        assert_eq!(mesh.num_leaves() as usize, plan.num_output_faces());
        assert_eq!(mesh.triangles.len(), 2 * plan.num_output_faces());
        assert_eq!(mesh.vertex_id.len(), plan.num_output_vertices());
        assert!(mesh.vertex_level.iter().all(|&l| l == level));
        for (i, &u) in mesh.vertex_id.iter().enumerate() {
            for k in 0..3 {
                assert_eq!(
                    mesh.points[3 * i + k].to_bits(),
                    uniform[3 * u as usize + k].to_bits()
                );
            }
        }
        // The triangles split the uniform quads along a diagonal.
        let offsets = plan.output_face_offsets();
        let verts = plan.output_face_vertices();
        let index: HashMap<u64, u32> = mesh
            .vertex_id
            .iter()
            .enumerate()
            .map(|(i, &u)| (u, i as u32))
            .collect();
        let mut quads: Vec<[u32; 3]> = (0..plan.num_output_faces())
            .flat_map(|f| {
                let q: Vec<u32> = verts[offsets[f] as usize..offsets[f + 1] as usize]
                    .iter()
                    .map(|&v| index[&(v as u64)])
                    .collect();
                [[q[0], q[1], q[2]], [q[0], q[2], q[3]]]
            })
            .collect();
        let mut triangles = mesh.triangles.clone();
        quads.sort_unstable();
        triangles.sort_unstable();
        assert_eq!(triangles, quads);
        assert_watertight(&mesh);
    }
}

#[test]
fn max_level_one_is_the_roots() {
    let (prism, points) = roofed_prism();
    for degree in [2, 3] {
        let mesh = subdivide_adaptive(&prism, &points, &options(degree, 1, 1e-3)).unwrap();
        assert_eq!(
            mesh.leaves_per_level,
            [0, prism.face_vertices().len() as u64]
        );
        assert_eq!(mesh.triangles.len(), 2 * prism.face_vertices().len());
        assert_watertight(&mesh);
        assert_uniform_points(&prism, &points, degree, Boundary::EdgeOnly, &mesh);
    }
}

#[test]
fn flat_cage_with_one_bump_needs_far_fewer_faces() {
    let (cage, points) = bumped_grid(16, 3.0);
    for degree in [3, 4] {
        let max_level = 4;
        let mesh = subdivide_adaptive(&cage, &points, &options(degree, max_level, 1e-4)).unwrap();
        let uniform_faces = 4u64.pow(max_level) * cage.num_faces() as u64;
        let ratio = mesh.num_leaves() as f64 / uniform_faces as f64;
        println!(
            "degree {degree}, max level {max_level}, tolerance 1e-4: {} leaves vs {} uniform faces, ratio {ratio:.4}; leaves per level {:?}",
            mesh.num_leaves(),
            uniform_faces,
            mesh.leaves_per_level
        );
        assert!(mesh.leaves_per_level[max_level as usize] > 0);
        assert!(ratio < 0.1, "ratio {ratio}");
        assert_uniform_points(&cage, &points, degree, Boundary::EdgeOnly, &mesh);
    }
}

#[test]
fn leaf_errors_are_measured_and_bounded_by_uniform() {
    let (cage, points) = bumped_grid(8, 2.0);
    let measured = |tolerance: f64| {
        subdivide_adaptive(
            &cage,
            &points,
            &AdaptiveOptions {
                measure_leaves: true,
                ..options(4, 3, tolerance)
            },
        )
        .unwrap()
    };
    let uniform = measured(0.0).max_error.unwrap();
    let adaptive = measured(1e-3).max_error.unwrap();
    assert!(uniform > 0.0 && adaptive > 0.0);
    assert!(adaptive >= uniform, "{adaptive} < {uniform}");
    assert!(subdivide_adaptive(&cage, &points, &options(4, 3, 1e-3))
        .unwrap()
        .max_error
        .is_none());
}

#[test]
fn invalid_requests_are_typed_errors() {
    let (cage, points) = bumped_grid(4, 1.0);
    let run = |o: AdaptiveOptions| subdivide_adaptive(&cage, &points, &o).unwrap_err();
    assert!(matches!(
        run(options(0, 3, 0.1)),
        Error::DegreeOutOfRange { .. }
    ));
    assert!(matches!(
        run(options(4, 0, 0.1)),
        Error::LevelOutOfRange { .. }
    ));
    assert!(matches!(
        run(options(4, 17, 0.1)),
        Error::LevelOutOfRange { .. }
    ));
    assert!(matches!(run(options(4, 3, -1.0)), Error::InvalidInput(_)));
    assert!(matches!(
        run(options(4, 3, f64::NAN)),
        Error::InvalidInput(_)
    ));
    assert!(matches!(
        run(AdaptiveOptions {
            memory_budget: 10_000,
            ..options(4, 6, 0.0)
        })
        .kind(),
        Error::MemoryBudget { .. }
    ));
    let short = &points[..points.len() - 3];
    assert!(matches!(
        subdivide_adaptive(&cage, short, &options(4, 3, 0.1)).unwrap_err(),
        Error::InvalidInput(_)
    ));
    let mut bad = points.clone();
    bad[4] = f64::INFINITY;
    assert!(matches!(
        subdivide_adaptive(&cage, &bad, &options(4, 3, 0.1)).unwrap_err(),
        Error::NonFinite { .. }
    ));
}

/// Random closed cages (a jittered 4 x 5 torus, the prism, the cube), random jitter,
/// random degrees, tolerances and levels: never an error, always watertight, restricted and
/// equal to the uniform points.
#[test]
fn random_cases_hold_every_property() {
    let mut rng = Random(2026);
    let (prism, prism_points) = roofed_prism();
    let (cube, cube_points) = bumped_cube();
    let torus = common::torus(4, 5);
    let mut mixed = 0;
    for case in 0..48 {
        let (cage, mut points) = match case % 3 {
            0 => (&prism, prism_points.clone()),
            1 => (&cube, cube_points.clone()),
            _ => {
                let points: Vec<f64> = (0..20)
                    .flat_map(|i| {
                        let (a, b) = (i / 5, i % 5);
                        let (u, v) = (
                            std::f64::consts::TAU * a as f64 / 4.0,
                            std::f64::consts::TAU * b as f64 / 5.0,
                        );
                        let r = 2.0 + 0.7 * v.cos();
                        [r * u.cos(), 0.7 * v.sin(), r * u.sin()]
                    })
                    .collect();
                (&torus, points)
            }
        };
        for p in points.iter_mut() {
            *p += 0.2 * (rng.next() - 0.5);
        }
        let degrees = [1, 2, 3, 4, 5, 6, 9];
        let degree = degrees[(rng.next() * degrees.len() as f64) as usize];
        let tolerance = [0.01, 0.003, 0.001, 3e-4][(rng.next() * 4.0) as usize];
        let max_level = 3 + (rng.next() * 2.0) as u32;
        let mesh = subdivide_adaptive(cage, &points, &options(degree, max_level, tolerance))
            .unwrap_or_else(|e| panic!("case {case} (degree {degree}): {e}"));
        mixed += (levels_used(&mesh) >= 2) as usize;
        assert_watertight(&mesh);
        assert_restricted(&mesh);
        assert_uniform_points(cage, &points, degree, Boundary::EdgeOnly, &mesh);
    }
    println!("{mixed} of 48 cases mixed levels");
    assert!(mixed >= 16, "only {mixed} cases mixed levels");
}

/// Issue 18 item 2: the budget covers the bookkeeping and the output too, and is checked before
/// each level's work. Tolerance 0 at level 16 is refused before any work (the result's size is
/// known); a tiny tolerance stops at the level whose estimate passes the budget. Both finish at
/// once (they ran past 9.5 GB before, or aborted under an address-space limit).
#[test]
fn adaptive_memory_budget_is_checked_before_the_work() {
    let (cage, points) = bumped_cube();
    let refused = |tolerance: f64, budget: u64| {
        let o = AdaptiveOptions {
            memory_budget: budget,
            ..options(4, 16, tolerance)
        };
        let e = subdivide_adaptive(&cage, &points, &o).unwrap_err();
        let Error::AdaptiveStopped { stage, error } = &e else {
            panic!("not an adaptive refusal: {e}");
        };
        match **error {
            Error::MemoryBudget {
                required,
                budget: b,
                ..
            } => {
                assert_eq!(b, budget);
                assert!(required > budget);
                (*stage, e.to_string())
            }
            ref other => panic!("not a budget error: {other}"),
        }
    };
    // Uniform level 16 of 24 roots: 24 * 4^15 leaves, far above the default 4 GiB: refused
    // before any work, and the message says so.
    let (stage, message) = refused(0.0, bidegree::DEFAULT_MEMORY_BUDGET);
    assert_eq!(stage, AdaptiveStage::BeforeTheWork, "{message}");
    assert!(
        message.starts_with(
            "adaptive subdivision refused before any work: the result would need about"
        ),
        "{message}"
    );
    // A tiny tolerance under 32 MiB: stopped at the first level whose estimate passes it,
    // after the coarser ones were made.
    let (stage, message) = refused(1e-14, 32 << 20);
    let AdaptiveStage::Level(level) = stage else {
        panic!("{message}");
    };
    assert!(level > 1, "{message}");
    assert!(
        message.contains(&format!("stopped before making level {level}")),
        "{message}"
    );
    // The same request under a budget that holds it succeeds (the checks refuse nothing that
    // fits).
    let o = AdaptiveOptions {
        memory_budget: 32 << 20,
        ..options(4, 4, 1e-14)
    };
    assert!(subdivide_adaptive(&cage, &points, &o).is_ok());
}

/// The bumped grid with a fin of 2 quads standing on two of its interior edges (edges of 3
/// faces: non-manifold, one of the fin's faces flipped against its neighbour) and a triangle
/// hanging from a grid corner by that vertex alone (a bowtie); the fin is bumped too.
fn finned_grid(n: usize) -> (Cage, Vec<f64>) {
    let (grid, mut points) = bumped_grid(n, 2.0);
    let id = |a: usize, b: usize| a * (n + 1) + b;
    let mut faces: Vec<Vec<usize>> = (0..grid.num_faces())
        .map(|f| {
            let o = grid.face_offsets();
            grid.face_vertices()[o[f] as usize..o[f + 1] as usize]
                .iter()
                .map(|&v| v as usize)
                .collect()
        })
        .collect();
    let base = (n + 1) * (n + 1);
    let line = [id(2, 1), id(2, 2), id(2, 3)];
    for (k, &v) in line.iter().enumerate() {
        let p = [points[3 * v], points[3 * v + 1], points[3 * v + 2]];
        points.extend([p[0] + 0.2 * k as f64, p[1], 1.0 + 0.4 * (k % 2) as f64]);
    }
    faces.push(vec![line[0], line[1], base + 1, base]);
    faces.push(vec![base + 2, base + 1, line[1], line[2]]);
    points.extend([-1.0, -0.5, 0.3, -0.5, -1.0, -0.3]);
    faces.push(vec![id(0, 0), base + 4, base + 3]);
    (common::cage(base + 5, &faces), points)
}

/// The value of every vertex of the uniform level `level` that the output has (`None` for a
/// vertex only holes use), from a plan whose output leaves holes out: its output faces are the
/// faces of `M_level` outside holes, in order.
fn uniform_by_level_vertex(plan: &Plan, values: &[f64], channels: usize) -> Vec<Option<Vec<f64>>> {
    let levels = plan.levels();
    let last = levels.last().unwrap();
    let t = levels.len() - 1;
    let origin_of = |f: usize| levels[0].face_of(f >> (2 * (t - 1)));
    let drawn: std::collections::HashSet<u32> = plan.output_face_origin().iter().copied().collect();
    let offsets = plan.output_face_offsets();
    let mut out = vec![None; last.num_vertices()];
    let mut i = 0;
    for f in 0..last.num_faces() {
        if !drawn.contains(&(origin_of(f) as u32)) {
            continue;
        }
        for k in 0..4 {
            let w = plan.output_face_vertices()[offsets[i] as usize + k] as usize;
            out[last.corner_verts()[4 * f + k] as usize] =
                Some(values[channels * w..channels * (w + 1)].to_vec());
        }
        i += 1;
    }
    assert_eq!(i, plan.num_output_faces());
    out
}

/// The uniform face-varying values at level `level`, per vertex of `M_level` and cage face:
/// every corner at that vertex in a face of that cage face has the same value (one side of a
/// seam), checked.
fn uniform_face_varying_by_vertex(
    plan: &Plan,
    values: &[f64],
    channels: usize,
) -> HashMap<(u32, u32), Vec<u64>> {
    let levels = plan.levels();
    let last = levels.last().unwrap();
    let t = levels.len() - 1;
    let drawn: std::collections::HashSet<u32> = plan.output_face_origin().iter().copied().collect();
    let mut out: HashMap<(u32, u32), Vec<u64>> = HashMap::new();
    let mut i = 0;
    for f in 0..last.num_faces() {
        let origin = levels[0].face_of(f >> (2 * (t - 1))) as u32;
        if !drawn.contains(&origin) {
            continue;
        }
        for k in 0..4 {
            let c = 4 * i + k;
            let bits: Vec<u64> = values[channels * c..channels * (c + 1)]
                .iter()
                .map(|x| x.to_bits())
                .collect();
            let key = (last.corner_verts()[4 * f + k], origin);
            let before = out.insert(key, bits.clone());
            assert!(
                before.is_none_or(|b| b == bits),
                "uniform corners at {key:?} differ"
            );
        }
        i += 1;
    }
    out
}

/// Adaptive points, per-vertex values (when carried: those of `x * x - 0.5 * x` per point
/// coordinate) and face-varying values against the uniform plans at every level the mesh uses
/// (holes left out there as here).
fn assert_uniform_data(
    cage: &Cage,
    points: &[f64],
    degree: u32,
    boundary: Boundary,
    mesh: &AdaptiveMesh<f64>,
    face_varying: &[(&[f64], usize, FaceVaryingMode)],
) {
    let channels = 3;
    let drawn: std::collections::HashSet<u32> = mesh.face_origin.iter().copied().collect();
    for level in 1..mesh.leaves_per_level.len() as u32 {
        if !mesh.vertex_level.contains(&level) {
            continue;
        }
        let plan = uniform_plan(cage, degree, level, boundary);
        let faces: std::collections::HashSet<u32> =
            plan.output_face_origin().iter().copied().collect();
        assert!(drawn.is_subset(&faces), "adaptive draws a hole");
        let uniform = uniform_by_level_vertex(&plan, &plan.evaluate(points, 3).unwrap(), 3);
        let squared: Vec<f64> = points.iter().map(|x| x * x - 0.5 * x).collect();
        let uniform_values =
            uniform_by_level_vertex(&plan, &plan.evaluate(&squared, 3).unwrap(), 3);
        for i in (0..mesh.vertex_level.len()).filter(|&i| mesh.vertex_level[i] == level) {
            let u = mesh.vertex_id[i] as usize;
            let want = uniform[u]
                .as_ref()
                .expect("an adaptive vertex is drawn uniformly");
            let values = uniform_values[u].as_ref().unwrap();
            for k in 0..channels {
                assert_eq!(
                    mesh.points[3 * i + k].to_bits(),
                    want[k].to_bits(),
                    "degree {degree}: vertex {u} of level {level}"
                );
                if !mesh.vertex_values.is_empty() {
                    assert_eq!(
                        mesh.vertex_values[3 * i + k].to_bits(),
                        values[k].to_bits(),
                        "degree {degree}: value of vertex {u} of level {level}"
                    );
                }
            }
        }
        for (set, &(values, width, mode)) in face_varying.iter().enumerate() {
            let uniform = plan
                .evaluate_face_varying(values, width, mode, false)
                .unwrap();
            let by_vertex = uniform_face_varying_by_vertex(&plan, &uniform, width);
            for (c, &v) in mesh.triangles.as_flattened().iter().enumerate() {
                let v = v as usize;
                if mesh.vertex_level[v] != level {
                    continue;
                }
                let key = (mesh.vertex_id[v] as u32, mesh.face_origin[c / 3]);
                let got: Vec<u64> = mesh.face_varying[set][width * c..width * (c + 1)]
                    .iter()
                    .map(|x| x.to_bits())
                    .collect();
                assert_eq!(
                    Some(&got),
                    by_vertex.get(&key),
                    "degree {degree}, {mode:?}: corner {c} at vertex {key:?} of level {level}"
                );
            }
        }
    }
}

#[test]
fn non_manifold_and_holed_cages_give_uniform_points_bitwise() {
    let (finned, finned_points) = finned_grid(6);
    let (grid, grid_points) = bumped_grid(6, 2.0);
    let holed = grid.clone().with_holes(&[7, 20]).unwrap();
    let finned_holed = finned.clone().with_holes(&[14, 36]).unwrap();
    let cases: Vec<(&str, &Cage, &[f64], Boundary)> = vec![
        ("finned", &finned, &finned_points, Boundary::EdgeOnly),
        (
            "finned corners",
            &finned,
            &finned_points,
            Boundary::EdgeAndCorner,
        ),
        ("holed", &holed, &grid_points, Boundary::EdgeOnly),
        (
            "finned holed",
            &finned_holed,
            &finned_points,
            Boundary::EdgeOnly,
        ),
        ("boundary none", &grid, &grid_points, Boundary::None),
    ];
    for degree in 1..=9 {
        for &(name, cage, points, boundary) in &cases {
            let options = AdaptiveOptions {
                boundary,
                ..options(degree, 3, if degree < 6 { 3e-3 } else { 5e-4 })
            };
            let squared: Vec<f64> = points.iter().map(|x| x * x - 0.5 * x).collect();
            let data = AdaptiveData {
                vertex_values: Some((&squared, 3)),
                face_varying: Vec::new(),
                ..Default::default()
            };
            let mesh = subdivide_adaptive_with_data(cage, points, &options, &data).unwrap();
            assert!(
                levels_used(&mesh) >= 2 || degree == 1,
                "{name}, degree {degree}: leaves {:?}",
                mesh.leaves_per_level
            );
            assert_uniform_data(cage, points, degree, boundary, &mesh, &[]);
            // Holes are left out: no triangle of a hole face.
            for &f in cage.holes() {
                assert!(!mesh.face_origin.contains(&f), "{name}: hole {f} drawn");
            }
            let plain = subdivide_adaptive(cage, points, &options).unwrap();
            assert_eq!(plain.points, mesh.points, "{name}: data changed the points");
        }
    }
}

/// UVs of the bumped grid with a seam down the middle (the right half shifted) and, in the
/// right half, another seam across (its top shifted too): a vertex with 3 values.
fn seamed_uvs(cage: &Cage, points: &[f64], n: usize) -> Vec<f64> {
    let o = cage.face_offsets();
    let mut uvs = Vec::new();
    for f in 0..cage.num_faces() {
        let (a, b) = (f / n, f % n);
        for &v in &cage.face_vertices()[o[f] as usize..o[f + 1] as usize] {
            let (x, y) = (points[3 * v as usize], points[3 * v as usize + 1]);
            let right = (b >= n / 2) as u32 as f64;
            let top = (b >= n / 2 && a >= n / 2) as u32 as f64;
            uvs.extend([0.1 * x + 0.7 * right + 0.01 * y * y, 0.1 * y + 0.4 * top]);
        }
    }
    uvs
}

#[test]
fn adaptive_face_varying_values_equal_uniform_ones_bitwise() {
    let n = 6;
    let (grid, points) = bumped_grid(n, 2.0);
    let grid = grid.with_creases(&[(8, 9, 10.0), (9, 10, 1.5)]).unwrap();
    let uvs = seamed_uvs(&grid, &points, n);
    for degree in 1..=9 {
        let sets: Vec<(&[f64], usize, FaceVaryingMode)> = FACE_VARYING_MODES
            .iter()
            .map(|&m| (&uvs[..], 2, m))
            .collect();
        let data = AdaptiveData {
            vertex_values: None,
            face_varying: sets.clone(),
            ..Default::default()
        };
        let tolerance = if degree < 6 { 3e-3 } else { 5e-4 };
        let mesh =
            subdivide_adaptive_with_data(&grid, &points, &options(degree, 3, tolerance), &data)
                .unwrap();
        assert!(levels_used(&mesh) >= 2 || degree == 1, "degree {degree}");
        assert_eq!(mesh.face_varying.len(), FACE_VARYING_MODES.len());
        for values in &mesh.face_varying {
            assert_eq!(values.len(), 2 * 3 * mesh.triangles.len());
        }
        assert_uniform_data(&grid, &points, degree, Boundary::EdgeOnly, &mesh, &sets);
        // Smooth and linear differ (from degree 2: degree 1 is bilinear in every mode).
        assert!(degree == 1 || mesh.face_varying[0] != mesh.face_varying[5]);
    }
    // A non-manifold, holed cage with UVs of 3 channels (a padded group) and 4 (two groups).
    let (finned, finned_points) = finned_grid(n);
    let finned = finned.with_holes(&[3]).unwrap();
    let corners = finned.face_vertices().len();
    let wide: Vec<f64> = (0..4 * corners)
        .map(|i| ((i * 7919) % 23) as f64 / 23.0)
        .collect();
    let uv3: Vec<f64> = (0..corners)
        .flat_map(|c| wide[4 * c..4 * c + 3].to_vec())
        .collect();
    for degree in [2, 3, 4] {
        let sets: Vec<(&[f64], usize, FaceVaryingMode)> = vec![
            (&uv3, 3, FaceVaryingMode::Boundaries),
            (&wide, 4, FaceVaryingMode::CornersPlus1),
        ];
        let data = AdaptiveData {
            vertex_values: None,
            face_varying: sets.clone(),
            ..Default::default()
        };
        let mesh =
            subdivide_adaptive_with_data(&finned, &finned_points, &options(degree, 3, 3e-3), &data)
                .unwrap();
        assert!(levels_used(&mesh) >= 2);
        assert_uniform_data(
            &finned,
            &finned_points,
            degree,
            Boundary::EdgeOnly,
            &mesh,
            &sets,
        );
    }
    // Bad data is a typed error.
    let short = AdaptiveData {
        vertex_values: None,
        face_varying: vec![(&uvs[1..], 2, FaceVaryingMode::None)],
        ..Default::default()
    };
    assert!(matches!(
        subdivide_adaptive_with_data(&grid, &points, &options(3, 3, 3e-3), &short),
        Err(Error::InvalidInput(_))
    ));
    let mut bad = uvs.clone();
    bad[5] = f64::NAN;
    let nan = AdaptiveData {
        vertex_values: None,
        face_varying: vec![(&bad, 2, FaceVaryingMode::None)],
        ..Default::default()
    };
    assert!(matches!(
        subdivide_adaptive_with_data(&grid, &points, &options(3, 3, 3e-3), &nan),
        Err(Error::NonFinite { .. })
    ));
}

#[test]
fn triangle_edges_know_their_cage_edge_and_sharpness() {
    let (finned, points) = finned_grid(6);
    let creased = finned
        .with_creases(&[(8, 9, 2.5), (9, 10, 10.0), (22, 23, 1.5)])
        .unwrap();
    for degree in [2, 3, 4] {
        let mesh = subdivide_adaptive(&creased, &points, &options(degree, 3, 3e-3)).unwrap();
        assert!(levels_used(&mesh) >= 2);
        assert_eq!(mesh.edge_origin.len(), 3 * mesh.triangles.len());
        let mut checked = 0;
        for level in 1..=3 {
            let plan = uniform_plan(&creased, degree, level, Boundary::EdgeOnly);
            assert_eq!(plan.cage_edges(), mesh.cage_edges);
            let sharpness = plan.output_edge_sharpness().unwrap();
            let uniform: HashMap<(u64, u64), usize> = (plan.output_edges().iter().enumerate())
                .map(|(e, &[a, b])| ((a.min(b) as u64, a.max(b) as u64), e))
                .collect();
            for (c, &v) in mesh.triangles.as_flattened().iter().enumerate() {
                if mesh.edge_level[c] != level {
                    continue;
                }
                let next = mesh.triangles[c / 3][(c % 3 + 1) % 3];
                let (a, b) = (mesh.vertex_id[v as usize], mesh.vertex_id[next as usize]);
                let Some(&e) = uniform.get(&(a.min(b), a.max(b))) else {
                    // A fan diagonal: no edge of the uniform level, inside a cage face.
                    assert_eq!(mesh.edge_origin[c], Level::NONE);
                    continue;
                };
                assert_eq!(
                    mesh.edge_origin[c],
                    plan.output_edge_origin().unwrap()[e],
                    "corner {c}"
                );
                assert_eq!(mesh.edge_sharpness[c], sharpness[e], "corner {c}");
                checked += (mesh.edge_origin[c] != Level::NONE) as usize;
            }
        }
        assert!(checked > 100, "{checked}");
        assert!(mesh.edge_sharpness.iter().any(|&s| s > 0.0 && s < 10.0));
    }
}

/// Vertex creases: each cage vertex's own output vertex knows it (`cage_vertex`, in the
/// user's numbering, past an isolated vertex the compaction drops) and the corner sharpness it
/// keeps at its level, and an infinitely sharp corner stays at its cage point.
#[test]
fn cage_vertices_know_their_corner_sharpness_at_their_level() {
    let (prism, prism_points) = roofed_prism();
    // The prism's vertices shifted by one: vertex 0 is in no face.
    let offsets = prism.face_offsets();
    let faces: Vec<Vec<usize>> = (offsets.windows(2))
        .map(|w| {
            (prism.face_vertices()[w[0] as usize..w[1] as usize].iter())
                .map(|&v| v as usize + 1)
                .collect()
        })
        .collect();
    let corners = [(3i64, 10.0f32), (6, 2.5), (9, 1.5)];
    let shifted = cage(12, &faces).with_corners(&corners).unwrap();
    let mut points = vec![9.0, 9.0, 9.0];
    points.extend_from_slice(&prism_points);
    for degree in 1..=5 {
        let mesh = subdivide_adaptive(&shifted, &points, &options(degree, 4, 0.003)).unwrap();
        assert!(levels_used(&mesh) >= 2 || degree == 1, "degree {degree}");
        assert_uniform_points(&shifted, &points, degree, Boundary::EdgeOnly, &mesh);
        let mut seen = [0; 12];
        for i in 0..mesh.vertex_id.len() {
            let (id, level, c) = (mesh.vertex_id[i], mesh.vertex_level[i], mesh.cage_vertex[i]);
            if id >= 11 {
                assert_eq!(c, Level::NONE, "degree {degree}: vertex {i} (uniform {id})");
                assert_eq!(mesh.vertex_sharpness[i], 0.0);
                continue;
            }
            assert_eq!(c as u64, id + 1, "degree {degree}: vertex {i}");
            seen[c as usize] += 1;
            let given = corners
                .iter()
                .find(|k| k.0 == c as i64)
                .map_or(0.0, |k| k.1);
            let kept = if given >= 10.0 {
                10.0
            } else {
                (given - level as f32).max(0.0)
            };
            assert_eq!(
                mesh.vertex_sharpness[i].to_bits(),
                kept.to_bits(),
                "degree {degree}: cage vertex {c} at level {level}"
            );
            if given >= 10.0 {
                let at = &mesh.points[3 * i..3 * i + 3];
                assert_eq!(
                    at,
                    &points[3 * c as usize..3 * c as usize + 3],
                    "degree {degree}"
                );
            }
        }
        assert_eq!(
            seen,
            [0, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1],
            "degree {degree}"
        );
    }
}

/// Face-varying values given OpenSubdiv's way (values and one index per cage corner): the
/// indices are the topology, uniform and adaptive; bad indices are typed errors.
#[test]
fn indexed_face_varying_values_follow_their_indices() {
    let n = 4;
    let (grid, mut points) = grid(n, n);
    points[3 * 12 + 2] = 1.0;
    let corners = grid.face_vertices();
    let nv = grid.num_vertices();
    // One value per vertex, twice: corners right of x = 2 take the second copy there.
    let chart: Vec<f64> = (0..nv)
        .flat_map(|v| {
            let (x, y) = (points[3 * v], points[3 * v + 1]);
            [x / 4.0 + 0.2 * y * y / 16.0, y / 4.0 + 0.1 * x * x / 16.0]
        })
        .collect();
    let values: Vec<f64> = chart.iter().chain(&chart).copied().collect();
    let cut: Vec<u32> = (0..corners.len())
        .map(|c| {
            let v = corners[c] as usize;
            let right = (c / 4) % n >= 2;
            if right && points[3 * v] == 2.0 {
                (nv + v) as u32
            } else {
                v as u32
            }
        })
        .collect();
    let welded: Vec<u32> = corners.to_vec();
    let per_corner = |indices: &[u32], shift: f64| -> Vec<f64> {
        (indices.iter())
            .flat_map(|&i| {
                let s = if i as usize >= nv { shift } else { 0.0 };
                [values[2 * i as usize] + s, values[2 * i as usize + 1]]
            })
            .collect()
    };
    let plan = uniform_plan(&grid, 3, 2, Boundary::EdgeOnly);
    let mode = FaceVaryingMode::Boundaries;
    let seam = plan
        .evaluate_face_varying_indexed(&values, 2, &cut, mode, false)
        .unwrap();
    let joined = plan
        .evaluate_face_varying_indexed(&values, 2, &welded, mode, false)
        .unwrap();
    // Equal coordinates under one index are the weld by value; under two, a seam.
    let by_value = plan
        .evaluate_face_varying(&per_corner(&cut, 0.0), 2, mode, false)
        .unwrap();
    assert_eq!(joined, by_value);
    assert!(seam.iter().zip(&joined).any(|(a, b)| (a - b).abs() > 1e-4));
    // The cut as distinct values welded by value is the same face-varying mesh, bitwise.
    let mut moved = values.clone();
    for x in moved[2 * nv..].iter_mut().step_by(2) {
        *x += 1.0;
    }
    assert_eq!(
        plan.evaluate_face_varying_indexed(&moved, 2, &cut, mode, false)
            .unwrap(),
        plan.evaluate_face_varying(&per_corner(&cut, 1.0), 2, mode, false)
            .unwrap()
    );
    // Adaptive: the same topology through the forest.
    let cut_values = per_corner(&cut, 0.0);
    let data = AdaptiveData {
        face_varying: vec![(&cut_values[..], 2, mode)],
        face_varying_indices: vec![Some(&cut[..])],
        ..Default::default()
    };
    let plain = AdaptiveData {
        face_varying: vec![(&cut_values[..], 2, mode)],
        ..Default::default()
    };
    let opts = options(3, 3, 3e-3);
    let indexed = subdivide_adaptive_with_data(&grid, &points, &opts, &data).unwrap();
    let welded_mesh = subdivide_adaptive_with_data(&grid, &points, &opts, &plain).unwrap();
    assert_eq!(indexed.points, welded_mesh.points);
    assert_ne!(indexed.face_varying[0], welded_mesh.face_varying[0]);
    // Typed errors.
    let bad = |r: bidegree::Result<Vec<f64>>| assert!(matches!(r, Err(Error::InvalidInput(_))));
    bad(plan.evaluate_face_varying_indexed(&values[..20], 2, &cut, mode, false));
    bad(plan.evaluate_face_varying_indexed(&values, 2, &cut[1..], mode, false));
    bad(plan.evaluate_face_varying_indexed(&values[1..], 2, &cut, mode, false));
    let short = AdaptiveData {
        face_varying: vec![(&cut_values[..], 2, mode)],
        face_varying_indices: vec![Some(&cut[1..])],
        ..Default::default()
    };
    assert!(matches!(
        subdivide_adaptive_with_data(&grid, &points, &opts, &short),
        Err(Error::InvalidInput(_))
    ));
}

/// The output is bitwise the same whatever the number of threads: every parallel pass (the
/// partial levels, the decisions, the triangle output) works in fixed chunks. The case is large
/// enough for several chunks of leaves and of faces.
#[test]
fn output_does_not_depend_on_the_threads() {
    let (cage, points) = bumped_grid(16, 3.0);
    for degree in [3, 4] {
        let options = options(degree, 5, 1e-6);
        let run = |threads| {
            rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap()
                .install(|| subdivide_adaptive(&cage, &points, &options).unwrap())
        };
        let one = run(1);
        assert!(one.num_leaves() > 8192, "{} leaves", one.num_leaves());
        let three = run(3);
        let bits = |m: &AdaptiveMesh<f64>| m.points.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        assert_eq!(bits(&one), bits(&three), "degree {degree}: points");
        assert_eq!(one, three, "degree {degree}");
    }
}
