//! Arbitrary input never panics: any polygon soup (non-manifold edges, flipped faces, repeated
//! vertices, zero-area faces, holes, isolated vertices), crease and corner list, degree, level
//! count and boundary rule either subdivides or is refused with a typed error, through the plan,
//! the limits and adaptive subdivision.

use bidegree::{
    subdivide, subdivide_adaptive, AdaptiveOptions, Boundary, Cage, Options, OutputKind, Plan,
    Rules,
};
use proptest::prelude::*;

type Soup = (usize, Vec<Vec<i64>>, Vec<(i64, i64, f32)>, Vec<f64>);

/// Polygon soups: mostly valid indices and sizes, sometimes not.
fn soup() -> impl Strategy<Value = Soup> {
    (3usize..9).prop_flat_map(|n| {
        let index = prop_oneof![20 => 0i64..n as i64, 1 => -2i64..(n as i64 + 2)];
        let face = (
            prop_oneof![20 => 3usize..6, 1 => 0usize..3],
            prop::collection::vec(index.clone(), 6),
        )
            .prop_map(|(size, indices)| indices[..size].to_vec());
        let faces = prop::collection::vec(face, 1..7);
        let creases = prop::collection::vec((index.clone(), index, 0.0f32..12.0), 0..3);
        let points = prop::collection::vec(-5.0f64..5.0, 3 * n);
        (Just(n), faces, creases, points)
    })
}

/// Books: `sheets` strips of quads on one line of `len` vertices (3+ faces on each of its
/// edges, a non-manifold edge), some sheets flipped, maybe a zero-area sheet (its points on
/// the line) and a triangle with a repeated vertex hung on the line.
fn book() -> impl Strategy<Value = Soup> {
    (2usize..5, 2usize..5, any::<u8>(), any::<bool>()).prop_flat_map(
        |(sheets, len, flips, flat)| {
            let n = len * (sheets + 1);
            let mut faces = Vec::new();
            for s in 0..sheets {
                let off = |i: usize| (len * (s + 1) + i) as i64;
                for i in 0..len - 1 {
                    let mut f = vec![i as i64, (i + 1) as i64, off(i + 1), off(i)];
                    if flips >> s & 1 == 1 {
                        f.reverse();
                    }
                    faces.push(f);
                }
            }
            if flat {
                faces.push(vec![0, 1, 1, len as i64]);
            }
            let index = 0i64..n as i64;
            let creases = prop::collection::vec((index.clone(), index, 0.0f32..12.0), 0..3);
            let points = prop::collection::vec(-5.0f64..5.0, 3 * n).prop_map(move |mut p| {
                if flat {
                    // The last sheet's far row on the line: zero-area faces.
                    let last = len * sheets;
                    for i in 0..len {
                        for k in 0..3 {
                            p[3 * (last + i) + k] = p[3 * i + k];
                        }
                    }
                }
                p
            });
            (Just(n), Just(faces), creases, points)
        },
    )
}

/// Valid closed meshes: an m x n torus with random creases and corners.
fn torus() -> impl Strategy<Value = Soup> {
    (3usize..6, 3usize..6).prop_flat_map(|(m, n)| {
        let id = move |a: usize, b: usize| ((a % m) * n + (b % n)) as i64;
        let faces: Vec<Vec<i64>> = (0..m)
            .flat_map(|a| {
                (0..n).map(move |b| vec![id(a, b), id(a + 1, b), id(a + 1, b + 1), id(a, b + 1)])
            })
            .collect();
        let crease = (0..m, 0..n, any::<bool>(), 0.0f32..12.0).prop_map(move |(a, b, down, s)| {
            if down {
                (id(a, b), id(a + 1, b), s)
            } else {
                (id(a, b), id(a, b + 1), s)
            }
        });
        let creases = prop::collection::vec(crease, 0..4);
        let points = prop::collection::vec(-5.0f64..5.0, 3 * m * n);
        (Just(m * n), Just(faces), creases, points)
    })
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(400))]

    #[test]
    fn arbitrary_input_is_subdivided_or_refused(
        (n, faces, creases, points) in prop_oneof![2 => soup(), 2 => book(), 1 => torus()],
        degree in 0u32..12,
        levels in 0u32..4,
        dual in any::<bool>(),
        boundary in 0u8..3,
        classic in prop::bool::weighted(0.2),
        holes in prop::collection::vec(-1i64..8, 0..3),
        corners in prop::collection::vec((-1i64..12, 0.0f32..12.0), 0..3),
        limit in prop::bool::weighted(0.3),
        adaptive in prop::bool::weighted(0.1),
    ) {
        let sizes: Vec<i64> = faces.iter().map(|f| f.len() as i64).collect();
        let indices: Vec<i64> = faces.iter().flatten().copied().collect();
        let boundary = [Boundary::EdgeOnly, Boundary::EdgeAndCorner, Boundary::None][boundary as usize];
        let options = Options {
            degree,
            levels,
            output: if dual { OutputKind::Dual } else { OutputKind::Primal },
            boundary,
            rules: if classic { Rules::Classic } else { Rules::Averaging },
            ..Options::default()
        };
        let cage = Cage::from_indices(n, &sizes, &indices)
            .and_then(|cage| cage.with_creases(&creases))
            .and_then(|cage| cage.with_corners(&corners))
            .and_then(|cage| cage.with_holes(&holes));
        let Ok(cage) = cage else {
            return Ok(());
        };
        if let Ok((plan, out)) = subdivide(&cage, &points, 3, &options) {
            prop_assert_eq!(out.len(), 3 * plan.num_output_vertices());
            prop_assert!(out.iter().all(|x| x.is_finite()));
            // (Every face may be a hole: then there are no output vertices and no faces.)
            let vertices = plan.num_output_vertices();
            prop_assert!(plan.output_face_vertices().iter().all(|&v| (v as usize) < vertices));
            if limit {
                if let Ok(at) = plan.limit_positions(&points, 3) {
                    prop_assert_eq!(at.len(), 3 * plan.num_output_vertices());
                }
                if let Ok((at, normals)) = plan.limit_surface(&points) {
                    prop_assert_eq!(at.len(), 3 * plan.num_output_vertices());
                    prop_assert_eq!(normals.len(), 3 * plan.output_face_vertices().len());
                }
            }
        }
        if adaptive {
            let options = AdaptiveOptions {
                degree,
                max_level: levels.max(1),
                tolerance: 0.01,
                boundary,
                ..AdaptiveOptions::default()
            };
            if let Ok(mesh) = subdivide_adaptive(&cage, &points, &options) {
                prop_assert!(mesh.points.iter().all(|x| x.is_finite()));
            }
        }
    }
}

/// A corner on a vertex that no face uses has no place in the surface: it is left out, and the
/// result is the one without it, for every degree and rule set, both outputs, the limits and
/// adaptive subdivision (it used to panic with an index out of bounds, issue 18).
#[test]
fn a_corner_on_an_isolated_vertex_is_left_out() {
    let points = [0.0, 0.0, 0.0, 1.0, 0.0, 0.2, 0.0, 1.0, 0.4, 5.0, 5.0, 5.0];
    let plain = Cage::from_indices(4, &[3], &[0, 1, 2]).unwrap();
    let cornered = plain.clone().with_corners(&[(3, 2.0)]).unwrap();
    let schemes = (1..=9)
        .map(|d| (d, Rules::Averaging))
        .chain((1..=3).map(|d| (d, Rules::Classic)));
    for (degree, rules) in schemes {
        for output in [OutputKind::Primal, OutputKind::Dual] {
            for levels in 0..=2 {
                let options = Options {
                    degree,
                    levels,
                    output,
                    rules,
                    ..Options::default()
                };
                let what = format!("degree {degree} {rules:?} {output:?} levels {levels}");
                let (a, b) = (Plan::new(&plain, &options), Plan::new(&cornered, &options));
                let (a, b) = match (a, b) {
                    (Ok(a), Ok(b)) => (a, b),
                    (Err(x), Err(y)) => {
                        assert_eq!(x, y, "{what}");
                        continue;
                    }
                    (a, b) => panic!("{what}: {:?} against {:?}", a.err(), b.err()),
                };
                assert_eq!(b.isolated_vertices(), &[3], "{what}");
                assert_eq!(
                    a.evaluate(&points, 3).unwrap(),
                    b.evaluate(&points, 3).unwrap(),
                    "{what}"
                );
                assert_eq!(
                    a.limit_positions(&points, 3),
                    b.limit_positions(&points, 3),
                    "{what}"
                );
                assert_eq!(a.limit_surface(&points), b.limit_surface(&points), "{what}");
            }
        }
        if rules == Rules::Averaging {
            let options = AdaptiveOptions {
                degree,
                max_level: 2,
                tolerance: 0.0,
                ..AdaptiveOptions::default()
            };
            assert_eq!(
                subdivide_adaptive(&plain, &points, &options).unwrap(),
                subdivide_adaptive(&cornered, &points, &options).unwrap(),
                "adaptive degree {degree}"
            );
        }
    }
}
