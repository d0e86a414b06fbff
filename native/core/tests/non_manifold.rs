//! Issue 13 in the core, for every degree: a book of sheets on one line of edges (non-manifold
//! edges of k faces, each sheet oriented its own way) gives, sheet by sheet, the surface of
//! that sheet alone with the shared line an infinitely sharp boundary whose ends are corners;
//! the sheets meet bitwise along the shared curve; results do not depend on the thread count;
//! holes and boundary `none` leave faces out. The same for the limits (positions and normals)
//! and the dual output: sheet by sheet those of the sheet alone, and with holes those of the
//! whole cage at what is drawn.

mod common;

use bidegree::{subdivide, Boundary, Cage, Error, Options, OutputKind, Plan, Rules};
use proptest::prelude::*;

/// Sheet `i` of the book: a 2 x 2 grid of quads whose first column is the shared line
/// (vertices 0, 1, 2) and whose other 6 vertices are its own, at angle `i` around the line.
/// Returns the faces (vertex ids of the book) and the points of the book's own vertices.
fn sheet(i: usize, flipped: bool) -> (Vec<[u32; 4]>, Vec<[f64; 3]>) {
    let own = |col: usize, row: usize| (3 + 6 * i + 2 * row + (col - 1)) as u32;
    let id = |col: usize, row: usize| if col == 0 { row as u32 } else { own(col, row) };
    let mut faces = Vec::new();
    for row in 0..2 {
        for col in 0..2 {
            let mut f = [
                id(col, row),
                id(col + 1, row),
                id(col + 1, row + 1),
                id(col, row + 1),
            ];
            if flipped {
                f.reverse();
            }
            faces.push(f);
        }
    }
    let angle = 0.4 + 2.1 * i as f64;
    let (c, s) = (angle.cos(), angle.sin());
    let mut points = Vec::new();
    for row in 0..3 {
        for col in 1..3 {
            let r = col as f64 * (1.0 + 0.1 * i as f64) + 0.05 * row as f64;
            let bump = 0.3 * ((row * col + i) % 3) as f64;
            points.push([
                r * c - bump * s,
                r * s + bump * c,
                row as f64 + 0.1 * col as f64,
            ]);
        }
    }
    (faces, points)
}

/// The shared line, slightly bent so that its 1-D scheme does something.
const LINE: [[f64; 3]; 3] = [[0.0, 0.0, 0.0], [0.1, -0.05, 1.0], [0.0, 0.1, 2.2]];

/// Whether sheet `i` of a book of `k` is flipped. Unflipped sheets all run the shared edges the
/// same way, so two of them disagree on orientation (a non-manifold edge of 2 faces); with more
/// sheets, sheet 1 is flipped so that the shared edges have faces running both ways. (Flipping
/// one of 2 sheets would make the book a manifold surface, smooth across the line.)
fn flipped(i: usize, k: usize) -> bool {
    i == 1 && k > 2
}

/// A book of `k` sheets as a cage and its points.
fn book(k: usize) -> (Cage, Vec<f64>) {
    let mut faces = Vec::new();
    let mut points: Vec<f64> = LINE.iter().flatten().copied().collect();
    for i in 0..k {
        let (f, p) = sheet(i, flipped(i, k));
        faces.extend(f);
        points.extend(p.iter().flatten());
    }
    (cage(&faces, points.len() / 3), points)
}

fn cage(faces: &[[u32; 4]], num_vertices: usize) -> Cage {
    let indices: Vec<i64> = faces.iter().flatten().map(|&v| v as i64).collect();
    Cage::from_indices(num_vertices, &vec![4; faces.len()], &indices).unwrap()
}

/// Sheet `i` alone, renumbered (line first, then its own vertices), with the shared line's
/// ends as infinitely sharp corners (they are non-manifold corners in the book).
fn sheet_alone(i: usize, k: usize) -> (Cage, Vec<f64>) {
    let (faces, own) = sheet(i, flipped(i, k));
    let local = |v: u32| if v < 3 { v } else { v - 6 * i as u32 };
    let faces: Vec<[u32; 4]> = faces.iter().map(|f| f.map(local)).collect();
    let mut points: Vec<f64> = LINE.iter().flatten().copied().collect();
    points.extend(own.iter().flatten());
    // The line's ends are non-manifold corners in the book. Its middle vertex is a curve vertex
    // when it has more faces than edges (k > 2: OpenSubdiv's exception), and a corner in a book
    // of 2 (4 faces, 4 edges), as every non-manifold vertex.
    let corners: &[(i64, f32)] = if k == 2 {
        &[(0, 10.0), (1, 10.0), (2, 10.0)]
    } else {
        &[(0, 10.0), (2, 10.0)]
    };
    let cage = cage(&faces, 9).with_corners(corners).unwrap();
    (cage, points)
}

/// The output points at every corner of the output faces whose cage face is in `faces`.
fn corner_points(plan: &bidegree::Plan, points: &[f64], faces: std::ops::Range<u32>) -> Vec<u64> {
    let origin = plan.output_face_origin();
    let offsets = plan.output_face_offsets();
    let verts = plan.output_face_vertices();
    let mut out = Vec::new();
    for f in 0..origin.len() {
        if faces.contains(&origin[f]) {
            for &v in &verts[offsets[f] as usize..offsets[f + 1] as usize] {
                out.extend(
                    points[3 * v as usize..3 * v as usize + 3]
                        .iter()
                        .map(|x| x.to_bits()),
                );
            }
        }
    }
    out
}

fn options(degree: u32, rules: Rules) -> Options {
    Options {
        degree,
        levels: 2,
        rules,
        ..Options::default()
    }
}

#[test]
fn each_sheet_of_a_book_is_that_sheet_alone_at_every_degree() {
    for k in [2, 3, 4] {
        let (book, points) = book(k);
        for (degree, rules) in schemes() {
            let (plan, refined) = subdivide(&book, &points, 3, &options(degree, rules)).unwrap();
            for i in 0..k {
                let (alone, alone_points) = sheet_alone(i, k);
                let (plan_alone, refined_alone) =
                    subdivide(&alone, &alone_points, 3, &options(degree, rules)).unwrap();
                let faces = 4 * i as u32..4 * i as u32 + 4;
                assert_eq!(
                    corner_points(&plan, &refined, faces),
                    corner_points(&plan_alone, &refined_alone, 0..4),
                    "{k} sheets, sheet {i}, degree {degree}, {rules:?}"
                );
            }
            // The shared line's refined points are one set of vertices, used by every sheet.
            let line: Vec<u32> = (0..3).collect();
            for v in line {
                assert!(plan.output_face_vertices().contains(&v));
            }
        }
    }
}

#[test]
fn holes_and_boundary_none_leave_faces_out() {
    let (book, points) = book(2);
    let whole = subdivide(&book, &points, 3, &options(3, Rules::Averaging)).unwrap();
    let holed = book.clone().with_holes(&[0, 5]).unwrap();
    let (plan, _) = subdivide(&holed, &points, 3, &options(3, Rules::Averaging)).unwrap();
    assert_eq!(plan.num_output_faces(), whole.0.num_output_faces() - 2 * 16);
    assert!(plan.output_face_origin().iter().all(|&f| f != 0 && f != 5));
    // Boundary none on a sheet: every face touches the boundary, so everything is a hole.
    let none = Options {
        boundary: Boundary::None,
        ..options(3, Rules::Classic)
    };
    let (plan, refined) = subdivide(&book, &points, 3, &none).unwrap();
    assert_eq!(plan.num_output_faces(), 0);
    // ... and no vertex either (it once gave every vertex of M_L).
    assert_eq!(plan.num_output_vertices(), 0);
    assert!(refined.is_empty());
    assert!(plan.limit_positions(&points, 3).unwrap().is_empty());
    assert!(book.clone().with_holes(&[8]).is_err());
}

/// Every scheme: the averaging rules at every degree and the classic rules (whose limits are
/// degree 3's only).
fn schemes() -> impl Iterator<Item = (u32, Rules)> {
    (1..=9)
        .map(|d| (d, Rules::Averaging))
        .chain((1..=3).map(|d| (d, Rules::Classic)))
}

/// The output faces of `plan`, each as the bits of its corners' points, with their cage faces.
fn faces_as_points(plan: &Plan, points: &[f64]) -> Vec<(u32, Vec<u64>)> {
    let offsets = plan.output_face_offsets();
    let verts = plan.output_face_vertices();
    (0..plan.num_output_faces())
        .map(|f| {
            let corners = &verts[offsets[f] as usize..offsets[f + 1] as usize];
            let bits = corners
                .iter()
                .flat_map(|&v| points[3 * v as usize..3 * v as usize + 3].iter())
                .map(|x| x.to_bits())
                .collect();
            (plan.output_face_origin()[f], bits)
        })
        .collect()
}

/// For each output vertex of `part` (the output of a cage with holes) and each of its output
/// corners, the vertex and corner of `whole` (the same cage without holes) it is: the faces of
/// `part` are those of `whole` whose cage face is not a hole, in the same order and with the
/// same corners.
fn correspondence(part: &Plan, whole: &Plan, holes: &[u32]) -> (Vec<u32>, Vec<u32>) {
    let kept: Vec<usize> = (0..whole.num_output_faces())
        .filter(|&f| !holes.contains(&whole.output_face_origin()[f]))
        .collect();
    assert_eq!(kept.len(), part.num_output_faces());
    let (po, wo) = (part.output_face_offsets(), whole.output_face_offsets());
    let (pv, wv) = (part.output_face_vertices(), whole.output_face_vertices());
    let mut vertex = vec![u32::MAX; part.num_output_vertices()];
    let mut corner = Vec::new();
    for (f, &g) in kept.iter().enumerate() {
        let size = (po[f + 1] - po[f]) as usize;
        assert_eq!(size, (wo[g + 1] - wo[g]) as usize);
        for i in 0..size {
            let (c, d) = (po[f] as usize + i, wo[g] as usize + i);
            assert!(vertex[pv[c] as usize] == u32::MAX || vertex[pv[c] as usize] == wv[d]);
            vertex[pv[c] as usize] = wv[d];
            corner.push(d as u32);
        }
    }
    assert!(
        vertex.iter().all(|&v| v != u32::MAX),
        "every vertex is used"
    );
    (vertex, corner)
}

/// Rows `rows` (3 values each) of `values`, as bits.
fn rows(values: &[f64], rows: &[u32]) -> Vec<u64> {
    rows.iter()
        .flat_map(|&r| values[3 * r as usize..3 * r as usize + 3].iter())
        .map(|x| x.to_bits())
        .collect()
}

/// Cages with holes for the limits and the dual output: the book of 3 with a hole in two
/// sheets (one at the shared line, one away from it), and a 6 x 5 grid with a hole inside and
/// one at its boundary, points lifted so that nothing is planar.
fn holed_cages() -> Vec<(&'static str, Cage, Vec<f64>, Vec<u32>)> {
    let (book, book_points) = book(3);
    let (grid, mut grid_points) = common::grid(6, 5);
    for (i, p) in grid_points.chunks_mut(3).enumerate() {
        p[2] = 0.3 * ((i * 7) % 5) as f64 - 0.1 * p[0];
    }
    vec![
        ("book", book, book_points, vec![0, 7]),
        ("grid", grid, grid_points, vec![13, 24]),
    ]
}

fn with_holes(cage: &Cage, holes: &[u32]) -> Cage {
    let holes: Vec<i64> = holes.iter().map(|&f| f as i64).collect();
    cage.clone().with_holes(&holes).unwrap()
}

/// Holes change no rule: the limit positions (every scheme with limits) and the limit normals
/// (averaging rules) of a cage with holes are, bitwise, those of the whole cage at the vertices
/// and corners of the faces drawn.
#[test]
fn limits_with_holes_are_those_of_the_whole_surface() {
    for (name, cage, points, holes) in holed_cages() {
        let holed = with_holes(&cage, &holes);
        for (degree, rules) in schemes().filter(|&(d, r)| r == Rules::Averaging || d == 3) {
            let what = format!("{name}, degree {degree}, {rules:?}");
            let options = options(degree, rules);
            let whole = Plan::new(&cage, &options).unwrap();
            let part = Plan::new(&holed, &options).unwrap();
            assert!(part.num_output_faces() < whole.num_output_faces(), "{what}");
            let (vertex, corner) = correspondence(&part, &whole, &holes);
            let ours = part.limit_positions(&points, 3).unwrap();
            let theirs = whole.limit_positions(&points, 3).unwrap();
            assert_eq!(ours.len(), 3 * part.num_output_vertices(), "{what}");
            let all: Vec<u32> = (0..vertex.len() as u32).collect();
            assert_eq!(rows(&ours, &all), rows(&theirs, &vertex), "{what}");
            if rules == Rules::Averaging {
                let (positions, normals) = part.limit_surface(&points).unwrap();
                let (whole_positions, whole_normals) = whole.limit_surface(&points).unwrap();
                assert_eq!(
                    rows(&positions, &all),
                    rows(&whole_positions, &vertex),
                    "{what}"
                );
                let corners: Vec<u32> = (0..corner.len() as u32).collect();
                assert_eq!(normals.len(), 3 * corner.len(), "{what}");
                assert_eq!(
                    rows(&normals, &corners),
                    rows(&whole_normals, &corner),
                    "{what}"
                );
            }
        }
    }
    // Boundary none: the kept faces' limits are the edge-only surface's.
    let (grid, points) = common::grid(6, 5);
    let none = Options {
        boundary: Boundary::None,
        ..options(4, Rules::Averaging)
    };
    let part = Plan::new(&grid, &none).unwrap();
    let whole = Plan::new(&grid, &options(4, Rules::Averaging)).unwrap();
    let ring: Vec<u32> = (0..30)
        .filter(|&f| f / 5 == 0 || f / 5 == 5 || f % 5 == 0 || f % 5 == 4)
        .collect();
    let (vertex, _) = correspondence(&part, &whole, &ring);
    let all: Vec<u32> = (0..vertex.len() as u32).collect();
    assert_eq!(
        rows(&part.limit_positions(&points, 3).unwrap(), &all),
        rows(&whole.limit_positions(&points, 3).unwrap(), &vertex)
    );
}

/// The limit of a book, sheet by sheet, is the limit of that sheet alone (positions at the
/// corners of the sheet's faces, and, averaging rules, the normals there, one per sheet along
/// the shared curve; bitwise, but for the last bit on a flipped sheet): the sheets meet exactly
/// along the shared curve in the limit, whose vertices are one set of output vertices.
#[test]
fn each_sheet_of_a_book_has_the_limit_of_that_sheet_alone() {
    for k in [2, 3, 4] {
        let (book, points) = book(k);
        for (degree, rules) in schemes().filter(|&(d, r)| r == Rules::Averaging || d == 3) {
            let what = format!("{k} sheets, degree {degree}, {rules:?}");
            let plan = Plan::new(&book, &options(degree, rules)).unwrap();
            let surface = |plan: &Plan, points: &[f64]| {
                if rules == Rules::Averaging {
                    plan.limit_surface(points).unwrap()
                } else {
                    (plan.limit_positions(points, 3).unwrap(), Vec::new())
                }
            };
            let (positions, normals) = surface(&plan, &points);
            for i in 0..k {
                let (alone, alone_points) = sheet_alone(i, k);
                let plan_alone = Plan::new(&alone, &options(degree, rules)).unwrap();
                let (alone_positions, alone_normals) = surface(&plan_alone, &alone_points);
                let faces = 4 * i as u32..4 * i as u32 + 4;
                let exact = !flipped(i, k);
                assert_same(
                    &corner_points(&plan, &positions, faces.clone()),
                    &corner_points(&plan_alone, &alone_positions, 0..4),
                    exact,
                    &format!("{what}, sheet {i}: positions"),
                );
                if rules == Rules::Averaging {
                    assert_same(
                        &corner_values(&plan, &normals, faces),
                        &corner_values(&plan_alone, &alone_normals, 0..4),
                        exact,
                        &format!("{what}, sheet {i}: normals"),
                    );
                }
            }
        }
    }
}

/// `ours == theirs` (bits of f64), or within 1e-14 when not `exact`: a flipped sheet alone runs
/// the shared curve the other way, and its symmetric 1-D mask sums the same terms in the other
/// order (the last bit may differ).
fn assert_same(ours: &[u64], theirs: &[u64], exact: bool, what: &str) {
    if exact {
        assert_eq!(ours, theirs, "{what}");
    } else {
        let gap = (ours.iter().zip(theirs))
            .map(|(&a, &b)| (f64::from_bits(a) - f64::from_bits(b)).abs())
            .fold(0.0, f64::max);
        assert!(ours.len() == theirs.len() && gap < 1e-14, "{what}: {gap:e}");
    }
}

/// The per-corner values (3 each) at every corner of the output faces whose cage face is in
/// `faces`, as bits.
fn corner_values(plan: &Plan, values: &[f64], faces: std::ops::Range<u32>) -> Vec<u64> {
    let origin = plan.output_face_origin();
    let offsets = plan.output_face_offsets();
    (0..origin.len())
        .filter(|&f| faces.contains(&origin[f]))
        .flat_map(|f| offsets[f] as usize..offsets[f + 1] as usize)
        .flat_map(|c| values[3 * c..3 * c + 3].iter().map(|x| x.to_bits()))
        .collect()
}

fn dual(degree: u32, rules: Rules) -> Options {
    Options {
        output: OutputKind::Dual,
        ..options(degree, rules)
    }
}

/// The dual output of a book, sheet by sheet, is the dual output of that sheet alone: one dual
/// face per sheet at each vertex of the shared curve, closed by the curve's 1-D points, which
/// every sheet shares (the same output vertices), bitwise at every degree.
#[test]
fn each_sheet_of_a_book_has_the_dual_of_that_sheet_alone() {
    for k in [2, 3, 4] {
        let (book, points) = book(k);
        for (degree, rules) in schemes() {
            let what = format!("{k} sheets, degree {degree}, {rules:?}");
            let (plan, refined) = subdivide(&book, &points, 3, &dual(degree, rules)).unwrap();
            let faces = faces_as_points(&plan, &refined);
            let (mut sheets, mut vertices) = (0, 0);
            for i in 0..k {
                let (alone, alone_points) = sheet_alone(i, k);
                let (plan_alone, refined_alone) =
                    subdivide(&alone, &alone_points, 3, &dual(degree, rules)).unwrap();
                let mut ours: Vec<Vec<u64>> = (faces.iter())
                    .filter(|(o, _)| (4 * i as u32..4 * i as u32 + 4).contains(o))
                    .map(|(_, bits)| bits.clone())
                    .collect();
                let mut theirs: Vec<Vec<u64>> = (faces_as_points(&plan_alone, &refined_alone))
                    .into_iter()
                    .map(|(_, bits)| bits)
                    .collect();
                // The faces' order follows the vertices of `M_L`, whose numbering along the
                // shared line depends on which sheet gives its edges their direction.
                ours.sort();
                theirs.sort();
                assert!(ours == theirs, "{what}, sheet {i}");
                sheets += theirs.len();
                vertices += plan_alone.num_output_vertices();
            }
            assert_eq!(sheets, plan.num_output_faces(), "{what}");
            // The shared curve's 1-D points (one per half of its 2 edges at level 2) are one
            // set of output vertices, which every sheet uses.
            assert_eq!(plan.num_output_vertices() + (k - 1) * 8, vertices, "{what}");
        }
    }
}

/// A dual face is left out when some face of its fan is from a hole: the dual output of a cage
/// with holes is, face by face and bitwise, the dual output of the whole cage without the faces
/// that have a face point of a hole face among their corners.
#[test]
fn the_dual_output_leaves_out_the_faces_that_reach_into_a_hole() {
    for (name, cage, points, holes) in holed_cages() {
        let holed = with_holes(&cage, &holes);
        for (degree, rules) in schemes() {
            let what = format!("{name}, degree {degree}, {rules:?}");
            // The cage face of each face of M_L (its face points are the dual's first points).
            let drawing = Plan::new(&cage, &options(degree, rules)).unwrap();
            let level_face_origin = drawing.output_face_origin();
            let (whole, whole_points) = subdivide(&cage, &points, 3, &dual(degree, rules)).unwrap();
            let (part, part_points) = subdivide(&holed, &points, 3, &dual(degree, rules)).unwrap();
            let offsets = whole.output_face_offsets();
            let verts = whole.output_face_vertices();
            let expected: Vec<(u32, Vec<u64>)> = (0..whole.num_output_faces())
                .filter(|&f| {
                    verts[offsets[f] as usize..offsets[f + 1] as usize]
                        .iter()
                        .all(|&v| {
                            level_face_origin
                                .get(v as usize)
                                .is_none_or(|o| !holes.contains(o))
                        })
                })
                .map(|f| faces_as_points(&whole, &whole_points)[f].clone())
                .collect();
            assert!(expected.len() < whole.num_output_faces(), "{what}");
            assert_eq!(faces_as_points(&part, &part_points), expected, "{what}");
            let used: std::collections::BTreeSet<u32> =
                part.output_face_vertices().iter().copied().collect();
            assert_eq!(
                used.len(),
                part.num_output_vertices(),
                "{what}: unused vertices"
            );
            // Every edge keeps its cage edge (the halves of the boundary edges).
            assert_eq!(
                part.output_edge_origin().unwrap().len(),
                part.output_edges().len()
            );
            assert_eq!(
                part.output_edge_sharpness().unwrap().len(),
                part.output_edges().len()
            );
        }
    }
}

/// Both outputs and the limits of a book and of cages with holes are the same bits on any
/// number of threads.
#[test]
fn results_are_the_same_on_any_number_of_threads() {
    let mut cases = holed_cages();
    let (book, points) = book(3);
    cases.push(("book without holes", book, points, Vec::new()));
    for (name, cage, points, holes) in cases {
        let cage = with_holes(&cage, &holes);
        for degree in [2, 3, 4, 7] {
            let run = |threads: usize| {
                let pool = rayon::ThreadPoolBuilder::new()
                    .num_threads(threads)
                    .build()
                    .unwrap();
                pool.install(|| {
                    let (dual, refined) =
                        subdivide(&cage, &points, 3, &dual(degree, Rules::Averaging)).unwrap();
                    let (plan, primal) =
                        subdivide(&cage, &points, 3, &options(degree, Rules::Averaging)).unwrap();
                    let (positions, normals) = plan.limit_surface(&points).unwrap();
                    let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
                    (
                        bits(&primal),
                        bits(&refined),
                        dual.output_face_vertices().to_vec(),
                        bits(&positions),
                        bits(&normals),
                    )
                })
            };
            let one = run(1);
            for threads in [2, 3] {
                assert!(
                    one == run(threads),
                    "{name}, degree {degree}, {threads} threads"
                );
            }
        }
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(300))]

    /// Polygon soups (non-manifold, flipped, repeated vertices) with holes: the dual output and
    /// the limits either work or are refused with a typed error, and what they give has the
    /// output's shape (the fuzz run found the dual output's panics on such cages).
    #[test]
    fn soups_with_holes_give_dual_outputs_and_limits_or_typed_errors(
        faces in prop::collection::vec(prop::collection::vec(0u32..7, 3..6), 1..7),
        holes in prop::collection::vec(0i64..7, 0..3),
        points in prop::collection::vec(-5.0f64..5.0, 21),
        degree in 1u32..6,
        levels in 0u32..3,
        classic in any::<bool>(),
    ) {
        let sizes: Vec<i64> = faces.iter().map(|f| f.len() as i64).collect();
        let indices: Vec<i64> = faces.iter().flatten().map(|&v| v as i64).collect();
        let holes: Vec<i64> = holes.into_iter().filter(|&h| (h as usize) < faces.len()).collect();
        let Ok(cage) = Cage::from_indices(7, &sizes, &indices).and_then(|c| c.with_holes(&holes))
        else {
            return Ok(());
        };
        let rules = if classic { Rules::Classic } else { Rules::Averaging };
        let base = Options { degree, levels, rules, ..Options::default() };
        let typed = |e: &Error| !matches!(e, Error::Internal(_));
        let dual = Options { output: OutputKind::Dual, ..base };
        match subdivide(&cage, &points, 3, &dual) {
            Ok((plan, out)) => {
                let n = plan.num_output_vertices();
                prop_assert_eq!(out.len(), 3 * n);
                prop_assert!(out.iter().all(|x| x.is_finite()));
                prop_assert!(plan.output_face_vertices().iter().all(|&v| (v as usize) < n));
                prop_assert_eq!(plan.output_edge_origin().unwrap().len(), plan.output_edges().len());
            }
            Err(e) => prop_assert!(typed(&e), "{e}"),
        }
        let Ok(plan) = Plan::new(&cage, &base) else {
            return Ok(());
        };
        match plan.limit_positions(&points, 3) {
            Ok(limit) => prop_assert_eq!(limit.len(), 3 * plan.num_output_vertices()),
            Err(e) => prop_assert!(typed(&e), "{e}"),
        }
        match plan.limit_surface(&points) {
            Ok((positions, normals)) => {
                prop_assert_eq!(positions.len(), 3 * plan.num_output_vertices());
                prop_assert_eq!(normals.len(), 3 * plan.output_face_vertices().len());
            }
            Err(e) => prop_assert!(typed(&e), "{e}"),
        }
    }
}

/// A cube whose edge 1-2 is split by vertex 8, which then lies on two faces only (an interior
/// vertex of valence 2), its points jittered so that nothing is symmetric.
fn split_cube() -> (Cage, Vec<f64>) {
    let faces: [&[i64]; 6] = [
        &[0, 3, 2, 8, 1],
        &[4, 5, 6, 7],
        &[0, 1, 5, 4],
        &[1, 8, 2, 6, 5],
        &[2, 3, 7, 6],
        &[3, 0, 4, 7],
    ];
    let sizes: Vec<i64> = faces.iter().map(|f| f.len() as i64).collect();
    let indices: Vec<i64> = faces.iter().flat_map(|f| f.iter().copied()).collect();
    let mut points = Vec::new();
    for v in 0..8 {
        let (x, y, z) = ((v & 1) ^ ((v >> 1) & 1), (v >> 1) & 1, v >> 2);
        points.extend([x as f64, y as f64, z as f64]);
    }
    points.extend([1.08, 0.5, 0.03]);
    for (i, p) in points.iter_mut().enumerate() {
        *p += 0.07 * ((i * 7 + 3) % 5) as f64 - 0.1;
    }
    (Cage::from_indices(9, &sizes, &indices).unwrap(), points)
}

/// The point of vertex 8 of the output (the cage's vertices keep their ids).
fn at_8(values: &[f64]) -> [f64; 3] {
    [values[24], values[25], values[26]]
}

fn distance(a: [f64; 3], b: [f64; 3]) -> f64 {
    (0..3).map(|i| (a[i] - b[i]).powi(2)).sum::<f64>().sqrt()
}

#[test]
fn limits_at_a_vertex_of_valence_2_are_the_limit_of_the_refined_points() {
    let (cage, points) = split_cube();
    for (degree, rules) in schemes().filter(|&(d, r)| r == Rules::Averaging || d == 3) {
        let what = format!("degree {degree}, {rules:?}");
        let plan = |levels: u32| {
            let o = Options {
                levels,
                ..options(degree, rules)
            };
            Plan::new(&cage, &o).unwrap()
        };
        let limit = |levels: u32| at_8(&plan(levels).limit_positions(&points, 3).unwrap());
        // The limit is the same whatever the level it is taken from (an exact mask, not an
        // approximation by the refined point).
        let lim = limit(1);
        for levels in [2, 3] {
            let d = distance(lim, limit(levels));
            assert!(
                d < 1e-12,
                "{what}: the limit from level {levels} is {d:e} away"
            );
        }
        // The refined points converge to it (by 1/4 per level: the subdominant eigenvalue).
        let gap = |levels: u32| distance(lim, at_8(&plan(levels).evaluate(&points, 3).unwrap()));
        let (g4, g5, g6) = (gap(4), gap(5), gap(6));
        assert!(
            g5 <= 0.3 * g4 && g6 <= 0.3 * g5 && g6 < 1e-3,
            "{what}: refined points at levels 4, 5, 6 are {g4:e}, {g5:e}, {g6:e} from the limit"
        );
        if degree == 1 || rules == Rules::Classic {
            continue;
        }
        // Normals at its corners: unit vectors, pointing out of the cube.
        let p = plan(2);
        let (positions, normals) = p.limit_surface(&points).unwrap();
        let centre = [0.5, 0.5, 0.5];
        let v = at_8(&positions);
        for c in 0..p.output_face_vertices().len() {
            if p.output_face_vertices()[c] != 8 {
                continue;
            }
            let n = [normals[3 * c], normals[3 * c + 1], normals[3 * c + 2]];
            let length = distance(n, [0.0; 3]);
            let outward: f64 = (0..3).map(|i| n[i] * (v[i] - centre[i])).sum();
            assert!(
                (length - 1.0).abs() < 1e-9 && outward > 0.0,
                "{what}: normal {n:?} at corner {c}"
            );
        }
    }
}

#[test]
fn at_valence_2_the_eigenvalue_after_1_is_a_quarter_three_times_over() {
    // Why the limit has no tangent masks there (`analysis::vertex_masks`): mode 1 is real at
    // valence 2 and its double leading eigenvalue 1/4 is also mode 0's second one, so three
    // terms decay alike after the limit point (a cone, not a plane).
    for degree in 2..=9 {
        let blocks = bidegree::analysis::subdivision_matrix(degree, 2)
            .unwrap()
            .block_eigenvalues()
            .unwrap();
        let near = |z: &bidegree::analysis::C64| (z.re - 0.25).abs() < 1e-9 && z.im.abs() < 1e-9;
        let (b0, b1) = (&blocks[0], &blocks[1]);
        assert!((b0[0].re - 1.0).abs() < 1e-9, "degree {degree}: {b0:?}");
        assert!(
            near(&b0[1]) && near(&b1[0]) && near(&b1[1]),
            "degree {degree}"
        );
        let rest = b0[2..].iter().chain(&b1[2..]).map(|z| z.norm());
        assert!(rest.fold(0.0, f64::max) < 0.25 - 1e-6, "degree {degree}");
        // And the masks: a position summing to 1, no tangents.
        let masks = bidegree::analysis::vertex_masks(degree, 2).unwrap();
        assert!((masks.position.iter().sum::<f64>() - 1.0).abs() < 1e-12);
        assert!(masks.tangents.iter().all(Vec::is_empty));
    }
}
