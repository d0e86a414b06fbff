//! The scheme against what follows from the paper (DESIGN.md §1-2): tensor-product
//! Lane-Riesenfeld on regular grids, the Doo-Sabin weights, boundaries and creases as the 1-D
//! scheme, corners, affine invariance, convex hull, symmetry and determinism.

mod common;

use bidegree::{subdivide, Boundary, FaceVaryingMode, Options, OutputKind, Plan};
use common::{cage, cube, grid, plan, torus, Random};

type P = [f64; 3];

/// One level of periodic 1-D Lane-Riesenfeld of degree n: replicate, then n passes of (1+z)/2.
fn lane_riesenfeld(points: &[P], degree: u32) -> Vec<P> {
    let mut u: Vec<P> = points.iter().flat_map(|&p| [p, p]).collect();
    for _ in 0..degree {
        u = average_periodic(&u);
    }
    u
}

/// One pass of (1+z)/2 on a closed polygon.
fn average_periodic(u: &[P]) -> Vec<P> {
    (0..u.len())
        .map(|i| mid(u[i], u[(i + 1) % u.len()]))
        .collect()
}

fn mid(a: P, b: P) -> P {
    [
        (a[0] + b[0]) / 2.0,
        (a[1] + b[1]) / 2.0,
        (a[2] + b[2]) / 2.0,
    ]
}

/// Applies a 1-D operator to every row and then every column of a periodic 2-D array.
fn tensor(grid: Vec<Vec<P>>, op: impl Fn(&[P]) -> Vec<P>) -> Vec<Vec<P>> {
    let rows: Vec<Vec<P>> = grid.iter().map(|r| op(r)).collect();
    let cols = rows[0].len();
    let transposed: Vec<Vec<P>> = (0..cols)
        .map(|c| rows.iter().map(|r| r[c]).collect())
        .collect();
    let done: Vec<Vec<P>> = transposed.iter().map(|c| op(c)).collect();
    (0..done[0].len())
        .map(|r| done.iter().map(|c| c[r]).collect())
        .collect()
}

fn as_points(flat: &[f64]) -> Vec<P> {
    flat.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect()
}

fn random_points(n: usize, seed: u64) -> Vec<f64> {
    let mut r = Random(seed);
    (0..3 * n).map(|_| r.next()).collect()
}

/// Asserts that two point sets are equal up to `tolerance`: same size, and every point of each
/// has a point of the other within the tolerance (max norm).
fn assert_same_sets(ours: Vec<P>, reference: Vec<P>, tolerance: f64, what: &str) {
    assert_eq!(ours.len(), reference.len(), "{what}: point counts");
    let nearest = |p: &P, set: &[P]| {
        set.iter()
            .map(|q| (0..3).map(|k| (p[k] - q[k]).abs()).fold(0.0, f64::max))
            .fold(f64::MAX, f64::min)
    };
    for (a, b, name) in [
        (&ours, &reference, "ours"),
        (&reference, &ours, "reference"),
    ] {
        for (i, p) in a.iter().enumerate() {
            let d = nearest(p, b);
            assert!(
                d <= tolerance,
                "{what}: {name} point {i} {p:?} is {d:e} from the other set"
            );
        }
    }
}

#[test]
fn regular_torus_is_tensor_product_lane_riesenfeld() {
    let (m, n) = (5, 6);
    let cage = torus(m, n);
    let points = random_points(m * n, 7);
    for degree in 1..=9 {
        for levels in 1..=2 {
            let (_, ours) = subdivide(
                &cage,
                &points,
                3,
                &Options {
                    degree,
                    levels,
                    ..Options::default()
                },
            )
            .unwrap();
            let mut reference: Vec<Vec<P>> = (0..m)
                .map(|a| {
                    (0..n)
                        .map(|b| {
                            let i = 3 * (a * n + b);
                            [points[i], points[i + 1], points[i + 2]]
                        })
                        .collect()
                })
                .collect();
            for _ in 0..levels {
                reference = tensor(reference, |row| lane_riesenfeld(row, degree));
            }
            if degree % 2 == 0 {
                // The drawing mesh of dual data: one more average in each direction.
                reference = tensor(reference, average_periodic);
            }
            let reference: Vec<P> = reference.into_iter().flatten().collect();
            assert_same_sets(
                as_points(&ours),
                reference,
                1e-12,
                &format!("degree {degree}, levels {levels}"),
            );
        }
    }
}

#[test]
fn doo_sabin_weights_on_a_k_gon() {
    // A closed k-gonal prism: the first step of degree 2 on its top face (face 0) is the paper's
    // k-gon rule, read off the dual output (one value per child face, child l = corner l).
    for k in 3..=8 {
        let mut faces = vec![(0..k).collect::<Vec<_>>(), (k..2 * k).rev().collect()];
        faces.extend((0..k).map(|i| vec![(i + 1) % k, i, k + i, k + (i + 1) % k]));
        let cage = cage(2 * k, &faces);
        let plan = Plan::new(
            &cage,
            &Options {
                degree: 2,
                levels: 1,
                output: OutputKind::Dual,
                ..Options::default()
            },
        )
        .unwrap();
        for i in 0..k {
            let mut impulse = vec![0.0f64; 2 * k];
            impulse[i] = 1.0;
            let out = plan.evaluate(&impulse, 1).unwrap();
            // Child face l of face 0 is corner l of the cage (the corner at vertex l).
            for (l, &weight) in out[..k].iter().enumerate() {
                let d = (i + k - l) % k;
                let expected = 1.0 / (4.0 * k as f64)
                    + if d == 0 { 0.5 } else { 0.0 }
                    + if d == 1 || d == k - 1 { 0.125 } else { 0.0 };
                assert!(
                    (weight - expected).abs() < 1e-15,
                    "k {k}: weight of p{i} in child {l} is {weight}, expected {expected}"
                );
            }
        }
    }
}

/// Indices of the boundary vertices of an output, walked from vertex `start` along boundary edges.
fn boundary_loop(plan: &Plan, start: u32) -> Vec<u32> {
    let level = plan.levels().last().unwrap();
    let mut next = std::collections::HashMap::new();
    for e in 0..level.num_edges() {
        if level.is_boundary_edge(e) {
            let c = level.edge_corners()[e][0] as usize;
            next.insert(level.corner_verts()[c], level.corner_verts()[level.next(c)]);
        }
    }
    let mut walk = vec![start];
    let mut v = next[&start];
    while v != start {
        walk.push(v);
        v = next[&v];
    }
    walk
}

#[test]
fn boundary_is_the_b_spline_of_the_boundary_polygon() {
    let (m, n) = (4, 3);
    let (cage, flat) = grid(m, n);
    let mut r = Random(11);
    let points: Vec<f64> = flat.iter().map(|x| x + 0.3 * r.next()).collect();
    // The boundary polygon of the grid, counter-clockwise from vertex 0.
    let plan0 = plan(&cage, 1, 0);
    let polygon: Vec<P> = boundary_loop(&plan0, 0)
        .iter()
        .map(|&v| as_points(&points)[v as usize])
        .collect();
    for degree in 1..=9 {
        let levels = 3;
        let plan = plan(&cage, degree, levels);
        let out = as_points(&plan.evaluate(&points, 3).unwrap());
        let ours: Vec<P> = boundary_loop(&plan, 0)
            .iter()
            .map(|&v| out[v as usize])
            .collect();
        let mut reference = polygon.clone();
        for _ in 0..levels {
            reference = lane_riesenfeld(&reference, degree);
        }
        if degree % 2 == 0 {
            reference = average_periodic(&reference);
        }
        assert_same_sets(
            ours,
            reference,
            1e-12,
            &format!("boundary, degree {degree}"),
        );
    }
}

#[test]
fn sharp_crease_reproduces_the_curve_and_corners_stay_put() {
    let (m, n) = (4, 5);
    let cage0 = torus(m, n);
    let points = random_points(m * n, 3);
    // A crease along the closed ring a = 0 (vertices 0..n).
    let ring: Vec<(i64, i64, f32)> = (0..n)
        .map(|b| (b as i64, ((b + 1) % n) as i64, f32::INFINITY))
        .collect();
    let creased = cage0.clone().with_creases(&ring).unwrap();
    let polygon: Vec<P> = (0..n).map(|b| as_points(&points)[b]).collect();
    for degree in 1..=6 {
        let levels = 2;
        let plan = plan(&creased, degree, levels);
        let out = as_points(&plan.evaluate(&points, 3).unwrap());
        // The crease's vertices at the last level: the old ring vertices and their descendants
        // along curve edges of the last step.
        let step = plan.curve_networks().last().unwrap();
        let ours: Vec<P> = step.curve_vertices().map(|v| out[v as usize]).collect();
        let mut reference = polygon.clone();
        for _ in 0..levels {
            reference = lane_riesenfeld(&reference, degree);
        }
        if degree % 2 == 0 {
            reference = average_periodic(&reference);
        }
        assert_same_sets(ours, reference, 1e-12, &format!("crease, degree {degree}"));
    }
    // Corners: tagged vertices and, in edge-and-corner mode, the grid's corners.
    let (grid_cage, flat) = grid(3, 3);
    let tagged = grid_cage
        .clone()
        .with_corners(&[(5, f32::INFINITY)])
        .unwrap();
    for degree in 1..=9 {
        for (cage, boundary, fixed) in [
            (&tagged, Boundary::EdgeOnly, vec![5]),
            (&grid_cage, Boundary::EdgeAndCorner, vec![0, 3, 12, 15]),
        ] {
            let plan = Plan::new(
                cage,
                &Options {
                    degree,
                    levels: 3,
                    boundary,
                    ..Options::default()
                },
            )
            .unwrap();
            let out = plan.evaluate(&flat, 3).unwrap();
            for v in fixed {
                assert_eq!(
                    &out[3 * v..3 * v + 3],
                    &flat[3 * v..3 * v + 3],
                    "degree {degree}: corner {v} moved"
                );
            }
        }
    }
}

#[test]
fn semi_sharp_crease_lies_between_smooth_and_sharp() {
    let (m, n) = (4, 5);
    let points = random_points(m * n, 5);
    let crease = |s: f32| torus(m, n).with_creases(&[(0, 1, s), (1, 2, s)]).unwrap();
    // Degrees 1 and 2 are left out: their first step has no average where a curve value can
    // differ from the centroid (old vertices keep their point, edge points are midpoints either
    // way), so a sharpness below 1 has no effect there; from the second step on it does.
    for degree in [3, 4, 5, 9] {
        let at = |s: f32| plan(&crease(s), degree, 3).evaluate(&points, 3).unwrap();
        let (smooth, half, sharp2, sharp) = (at(0.0), at(0.5), at(2.0), at(f32::INFINITY));
        // Vertex 1 (on the crease): sharpness 0.5 moves it part of the way.
        let dist = |a: &[f64], b: &[f64]| {
            (0..3)
                .map(|k| (a[3 + k] - b[3 + k]).powi(2))
                .sum::<f64>()
                .sqrt()
        };
        let (a, b) = (dist(&half, &smooth), dist(&half, &sharp));
        assert!(
            a > 1e-6 && b > 1e-6,
            "degree {degree}: {a} from smooth, {b} from sharp"
        );
        assert!(
            dist(&sharp2, &sharp) < dist(&smooth, &sharp),
            "degree {degree}"
        );
    }
}

#[test]
fn affine_invariance_convex_hull_and_symmetry() {
    let (cube, points) = cube();
    let (a, t) = (
        [[0.9, 0.2, -0.1], [0.3, 1.1, 0.4], [-0.2, 0.1, 0.8]],
        [1.5, -2.0, 0.25],
    );
    let map = |p: &[f64]| -> Vec<f64> {
        p.chunks_exact(3)
            .flat_map(|q| {
                (0..3).map(move |r| a[r][0] * q[0] + a[r][1] * q[1] + a[r][2] * q[2] + t[r])
            })
            .collect()
    };
    for degree in 1..=9 {
        let plan = plan(&cube, degree, 2);
        let out = plan.evaluate(&points, 3).unwrap();
        let moved = plan.evaluate(&map(&points), 3).unwrap();
        for (x, y) in map(&out).iter().zip(&moved) {
            assert!((x - y).abs() < 1e-12, "degree {degree}: affine invariance");
        }
        // Inside the convex hull: every linear functional is bounded by its cage maximum.
        for dir in [[1., 0., 0.], [1., 1., 0.], [1., 1., 1.], [-1., 2., 0.5]] {
            let f = |p: &[f64]| p[0] * dir[0] + p[1] * dir[1] + p[2] * dir[2];
            let cage_max = points.chunks_exact(3).map(f).fold(f64::MIN, f64::max);
            assert!(
                out.chunks_exact(3).all(|p| f(p) <= cage_max + 1e-12),
                "degree {degree}: convex hull"
            );
        }
        // The cube is symmetric under x -> -x: so is the result, as a point set.
        let mirrored: Vec<P> = as_points(&out)
            .iter()
            .map(|p| [-p[0], p[1], p[2]])
            .collect();
        assert_same_sets(
            as_points(&out),
            mirrored,
            1e-12,
            &format!("symmetry, degree {degree}"),
        );
    }
}

#[test]
fn bitwise_identical_for_any_thread_count() {
    let cage = torus(40, 30);
    let mut r = Random(9);
    let points: Vec<f32> = (0..3 * 1200).map(|_| r.next() as f32).collect();
    let creased = cage
        .with_creases(&[(0, 1, 2.5), (1, 2, f32::INFINITY)])
        .unwrap();
    for degree in [2, 3, 4, 9] {
        for output in [OutputKind::Primal, OutputKind::Dual] {
            let options = Options {
                degree,
                levels: 3,
                output,
                ..Options::default()
            };
            let run = |threads: usize| {
                let pool = rayon::ThreadPoolBuilder::new()
                    .num_threads(threads)
                    .build()
                    .unwrap();
                pool.install(|| subdivide(&creased, &points, 3, &options).unwrap().1)
            };
            let one = run(1);
            for threads in [2, 3, 8] {
                let many = run(threads);
                assert!(
                    one.iter()
                        .zip(&many)
                        .all(|(a, b)| a.to_bits() == b.to_bits()),
                    "degree {degree}, {threads} threads"
                );
            }
        }
    }
}

/// Face-varying values are interpolated linearly: values that are one per vertex, repeated at
/// each of its corners, come out as the bilinear (degree 1) refinement of those vertex values,
/// on triangles, quads and a pentagon, across boundaries, for 1 to 5 channels.
#[test]
fn face_varying_values_are_the_bilinear_refinement() {
    let mixed = cage(
        8,
        &[
            vec![0, 1, 2, 3, 4],
            vec![1, 5, 6, 2],
            vec![2, 6, 7],
            vec![2, 7, 3],
        ],
    );
    let (grid_cage, _) = grid(3, 2);
    let (cube_cage, _) = cube();
    for cage in [mixed, grid_cage, cube_cage] {
        for channels in 1..=5 {
            let mut r = Random(channels as u64);
            let per_vertex: Vec<f64> = (0..cage.num_vertices() * channels)
                .map(|_| r.next())
                .collect();
            let per_corner: Vec<f64> = cage
                .face_vertices()
                .iter()
                .flat_map(|&v| per_vertex[v as usize * channels..][..channels].to_vec())
                .collect();
            for levels in 0..=3 {
                let bilinear = plan(&cage, 1, levels);
                let at_vertices = bilinear.evaluate(&per_vertex, channels).unwrap();
                let at_corners = plan(&cage, 4, levels)
                    .evaluate_face_varying(&per_corner, channels, FaceVaryingMode::All, false)
                    .unwrap();
                let corners = bilinear.output_face_vertices();
                assert_eq!(at_corners.len(), corners.len() * channels);
                for (c, &v) in corners.iter().enumerate() {
                    for k in 0..channels {
                        let (fv, vv) = (
                            at_corners[c * channels + k],
                            at_vertices[v as usize * channels + k],
                        );
                        assert!((fv - vv).abs() < 1e-12, "corner {c}: {fv} vs {vv}");
                    }
                }
            }
        }
    }
}
