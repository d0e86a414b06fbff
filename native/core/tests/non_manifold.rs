//! Issue 13 in the core, for every degree: a book of sheets on one line of edges (non-manifold
//! edges of k faces, each sheet oriented its own way) gives, sheet by sheet, the surface of
//! that sheet alone with the shared line an infinitely sharp boundary whose ends are corners;
//! the sheets meet bitwise along the shared curve; results do not depend on the thread count;
//! holes and boundary `none` leave faces out.

use bidegree::{subdivide, Boundary, Cage, Options, Rules};

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
        for (degree, rules) in (1..=9)
            .map(|d| (d, Rules::Averaging))
            .chain((1..=3).map(|d| (d, Rules::Classic)))
        {
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
fn a_book_is_the_same_on_any_number_of_threads() {
    let (book, points) = book(3);
    for degree in [2, 3, 4, 7] {
        let run = |threads: usize| {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap();
            pool.install(|| subdivide(&book, &points, 3, &options(degree, Rules::Averaging)))
                .unwrap()
                .1
        };
        let one = run(1);
        for threads in [2, 3] {
            assert!(
                one.iter()
                    .zip(run(threads))
                    .all(|(a, b)| a.to_bits() == b.to_bits()),
                "degree {degree}, {threads} threads"
            );
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
    let (plan, _) = subdivide(&book, &points, 3, &none).unwrap();
    assert_eq!(plan.num_output_faces(), 0);
    assert!(book.clone().with_holes(&[8]).is_err());
}
